/* Gait tables (layout: protocol/gait_table.md): validation and frame access over the
 * table's bytes, wherever they live (staging RAM, active RAM, flash). No copies made. */
#ifndef SNAKEBOT_GT_TABLE_H
#define SNAKEBOT_GT_TABLE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ax12_table.h"
#include "ctl_table.h"

/* The controller's limits, from host/snakebot/facts/devices/data/controller.json
 * (published as CTL_MAX_*). */
#define GT_MAX_JOINTS CTL_MAX_JOINTS
#define GT_MAX_TABLE_BYTES CTL_MAX_TABLE_BYTES

/* cffi:begin */
/* "SNKG" read as a little-endian uint32. */
#define GT_MAGIC 1196117587
#define GT_VERSION 1
#define GT_HEADER_SIZE 16
#define GT_CRC_OFFSET 12
#define GT_JOINT_SIZE 6
#define GT_FLAG_LOOP 1
#define GT_MAX_ID 253

/* gt_validate() results, in check order (protocol/gait_table.md, "Validation order"). */
#define GT_OK 0
#define GT_ERR_TRUNCATED 1
#define GT_ERR_MAGIC 2
#define GT_ERR_VERSION 3
#define GT_ERR_JOINT_COUNT 4
#define GT_ERR_FLAGS 5
#define GT_ERR_PERIOD 6
#define GT_ERR_FRAME_COUNT 7
#define GT_ERR_TOO_BIG 8
#define GT_ERR_TRAILING 9
#define GT_ERR_CRC 10
#define GT_ERR_JOINT_ID 11
#define GT_ERR_LIMITS 12
#define GT_ERR_FRAME_RANGE 13

/* What the header of a valid table says. */
typedef struct {
    uint16_t size;            /* bytes: 16 + 6 J + 2 J F */
    uint16_t frame_period_ms; /* 1..65535 */
    uint16_t frame_count;     /* F >= 1 */
    uint8_t joint_count;      /* J, 1..GT_MAX_JOINTS */
    uint8_t flags;            /* GT_FLAG_LOOP */
    uint32_t crc;             /* the table CRC stored at offset 12 */
} gt_info;

/* Check len bytes as a complete table; GT_OK fills *info (zeroed otherwise). */
int gt_validate(const uint8_t *table, size_t len, gt_info *info);
/* Only the header checks of gt_validate() (no CRC, limits or frames), filling *info the
 * same way: for a table validated before whose bytes have not changed since. */
int gt_describe(const uint8_t *table, size_t len, gt_info *info);
/* One line of text for a gt_validate() result. */
const char *gt_strerror(int status);
/* The table CRC of len (>= 16) bytes: CRC-32 of bytes 0..11 then 16..len-1. */
uint32_t gt_crc(const uint8_t *table, size_t len);
/* Joint j's servo ID / min tick / max tick (0 if j is out of range). */
uint8_t gt_joint_id(const uint8_t *table, const gt_info *info, uint8_t joint);
uint16_t gt_joint_min(const uint8_t *table, const gt_info *info, uint8_t joint);
uint16_t gt_joint_max(const uint8_t *table, const gt_info *info, uint8_t joint);
/* Goal of joint j in frame f, in ticks (0 if either is out of range). */
uint16_t gt_frame(const uint8_t *table, const gt_info *info, uint16_t frame, uint8_t joint);
/* cffi:end */

/* The highest tick a joint limit may take: the servo's (generated from its description). */
#define GT_MAX_TICK AX12_POSITION_MAX

#endif
