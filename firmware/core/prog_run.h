/* Controller programs (layout and semantics: protocol/program.md): a list of segments,
 * each playing part of the program's own table, running the serpenoid, or running a
 * periodic-input block, checked as a whole before it becomes active and then stepped one
 * program step (period ms) at a time into one goal per joint.
 *
 * Joint angles stay continuous across segment boundaries: every segment's goals get a
 * per-joint carry, fixed for the segment, equal to where the previous segment would have
 * gone next (its generator one step past its end, plus its own carry) minus where this
 * segment's generator starts. The carry is kept in 1/16 tick, so the rounding it adds
 * stays far below a tick.
 *
 * Portable: no heap, no floating point; everything works on the blob's bytes in place. */
#ifndef SNAKEBOT_PROG_RUN_H
#define SNAKEBOT_PROG_RUN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "gt_table.h"

/* cffi:begin */
/* "SNKP" read as a little-endian uint32. */
#define PROG_MAGIC 1347112531
#define PROG_VERSION 1
#define PROG_HEADER_SIZE 16
#define PROG_CRC_OFFSET 12
#define PROG_JOINT_SIZE 8
#define PROG_SEGMENT_SIZE 12
/* Bytes per joint in a periodic block: offset rate, sine and cosine amplitude (int16). */
#define PROG_PERIODIC_JOINT_SIZE 6
/* The longest program step: longer ones would overflow the phase arithmetic. */
#define PROG_MAX_PERIOD_MS 1000
/* Joint record flag: the joint angle grows as the tick falls. */
#define PROG_JOINT_REVERSE 1
/* Carry resolution: goals are worked out in 1/PROG_CARRY_ONE tick. */
#define PROG_CARRY_SHIFT 4

#define PROG_KIND_TABLE 1
#define PROG_KIND_SERPENOID 2
#define PROG_KIND_PERIODIC 3

/* prog_validate() results: 0 or an Upload Result code 40..59, in check order. */
#define PROG_OK 0
#define PROG_ERR_TRUNCATED 40
#define PROG_ERR_MAGIC 41
#define PROG_ERR_VERSION 42
#define PROG_ERR_JOINT_COUNT 43
#define PROG_ERR_SEGMENT_COUNT 44
#define PROG_ERR_PERIOD 45
#define PROG_ERR_TOO_BIG 46
#define PROG_ERR_TRAILING 47
#define PROG_ERR_CRC 48
#define PROG_ERR_JOINT 49
#define PROG_ERR_FRAME_RANGE 50
#define PROG_ERR_SEGMENT 51
#define PROG_ERR_OUT_OF_RANGE 52
#define PROG_ERR_TOO_FAST 53

/* Where a running program is: segment, step within it, the milliseconds towards the next
 * step, and each joint's carry in 1/16 tick. */
typedef struct {
    uint16_t step;
    uint16_t acc_ms;
    uint8_t segment;
    uint8_t done;
    int16_t carry[CTL_MAX_JOINTS];
} prog_cursor;

/* Check len bytes as a complete program that fits in capacity bytes; PROG_OK or the first
 * failure's code. A failure in a segment stores its index in *bad_segment (if not NULL). */
uint8_t prog_validate(const uint8_t *blob, size_t len, size_t capacity, uint8_t *bad_segment);
/* Total bytes a program's header says it has (0 if shorter than a header). */
size_t prog_size(const uint8_t *blob, size_t len);
/* Joint count / segment count / step period of a validated program. */
uint8_t prog_joint_count(const uint8_t *blob);
uint8_t prog_segment_count(const uint8_t *blob);
uint16_t prog_period_ms(const uint8_t *blob);
/* Servo ID of joint j of a validated program. */
uint8_t prog_joint_id(const uint8_t *blob, uint8_t j);
/* Program start: segment 0, step 0, no carry. */
void prog_start(prog_cursor *c);
/* The goals (ticks, one per joint) at the cursor; valid blobs only. */
void prog_goals(const uint8_t *blob, const prog_cursor *c, uint16_t *goals);
/* Advance by steps program steps, entering later segments as their turn comes; false once
 * the program has ended (the cursor then stays on the last step of the last segment). */
bool prog_advance(const uint8_t *blob, prog_cursor *c, uint32_t steps);
/* Advance by dt_ms of time (whole steps of the period; the rest is kept); as prog_advance. */
bool prog_tick(const uint8_t *blob, prog_cursor *c, uint32_t dt_ms);
/* cffi:end */

#endif
