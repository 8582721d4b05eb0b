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

#include "ctl_table.h"
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
/* Carry resolution: goals are worked out in 1/2^PROG_CARRY_SHIFT tick. */
#define PROG_CARRY_SHIFT 4

#define PROG_KIND_TABLE 1
#define PROG_KIND_SERPENOID 2
#define PROG_KIND_PERIODIC 3

/* Where a running program is: segment, step within it, the time towards the next step
 * (ms * 256: time runs at the speed scale, 1/256), and each joint's carry in 1/16 tick. */
typedef struct {
    uint32_t acc_q8;
    uint16_t step;
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
/* Joint j's record of a validated program. */
typedef struct {
    uint8_t id;
    uint8_t reverse; /* 1: the joint angle grows as the tick falls */
    uint16_t zero;   /* tick at angle 0 */
    uint16_t min;
    uint16_t max;
} prog_joint;
prog_joint prog_joint_at(const uint8_t *blob, uint8_t j);
/* Program start: segment 0, step 0, no carry. */
void prog_start(prog_cursor *c);
/* The goals (ticks, one per joint) at the cursor, plus the steering offset (ticks,
 * negated for reversed joints), clamped to the joints' limits; valid blobs only. */
void prog_goals(const uint8_t *blob, const prog_cursor *c, int16_t steering, uint16_t *goals);
/* Whether the segment at the cursor is a SERPENOID one; if so its A (mrad) and omega
 * (mrad/s) in *amp_mrad and *omega_mrad_s (the live steering's slew needs its speed). */
bool prog_serpenoid_at(const uint8_t *blob, const prog_cursor *c, uint16_t *amp_mrad,
                       int16_t *omega_mrad_s);
/* Advance by steps program steps, entering later segments as their turn comes; false once
 * the program has ended (the cursor then stays on the last step of the last segment). */
bool prog_advance(const uint8_t *blob, prog_cursor *c, uint32_t steps);
/* Advance by dt_ms of time run at speed_scale / 256 (whole steps of the period; the rest
 * is kept); as prog_advance. */
bool prog_tick(const uint8_t *blob, prog_cursor *c, uint32_t dt_ms, uint16_t speed_scale);
/* cffi:end */

/* prog_validate() results, in check order: the controller's Upload Result codes
 * (CTL_UPLOAD_RESULT_PROGRAM_*, from controller.json). */
#define PROG_OK CTL_UPLOAD_RESULT_OK
#define PROG_ERR_TRUNCATED CTL_UPLOAD_RESULT_PROGRAM_TRUNCATED
#define PROG_ERR_MAGIC CTL_UPLOAD_RESULT_PROGRAM_BAD_MAGIC
#define PROG_ERR_VERSION CTL_UPLOAD_RESULT_PROGRAM_BAD_VERSION
#define PROG_ERR_JOINT_COUNT CTL_UPLOAD_RESULT_PROGRAM_BAD_JOINT_COUNT
#define PROG_ERR_SEGMENT_COUNT CTL_UPLOAD_RESULT_PROGRAM_BAD_SEGMENT_COUNT
#define PROG_ERR_PERIOD CTL_UPLOAD_RESULT_PROGRAM_BAD_PERIOD
#define PROG_ERR_TOO_BIG CTL_UPLOAD_RESULT_PROGRAM_TOO_BIG
#define PROG_ERR_TRAILING CTL_UPLOAD_RESULT_PROGRAM_TRAILING_BYTES
#define PROG_ERR_CRC CTL_UPLOAD_RESULT_PROGRAM_CRC_MISMATCH
#define PROG_ERR_JOINT CTL_UPLOAD_RESULT_PROGRAM_BAD_JOINT
#define PROG_ERR_FRAME_RANGE CTL_UPLOAD_RESULT_PROGRAM_FRAME_OUT_OF_LIMITS
#define PROG_ERR_SEGMENT CTL_UPLOAD_RESULT_PROGRAM_BAD_SEGMENT
#define PROG_ERR_OUT_OF_RANGE CTL_UPLOAD_RESULT_PROGRAM_OUT_OF_RANGE
#define PROG_ERR_TOO_FAST CTL_UPLOAD_RESULT_PROGRAM_TOO_FAST

#endif
