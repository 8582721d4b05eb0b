/* Private to the controller device's own files (firmware/core/ctl_*.c), which share the
 * one public header ctl_device.h: the register descriptors, the small register accessors
 * every part uses, and the functions one part calls in another.
 *
 *   ctl_device.c   the PC link: packets in, each instruction dispatched; life cycle
 *   ctl_regs.c     the control table: descriptors, defaults, READ and WRITE
 *   ctl_pages.c    the window: servo-record pages (the roster) and the described pages
 *   ctl_upload.c   the upload window, Upload Commit, the active table, RESET
 *   ctl_state.c    State and Error Flags, commands and refusals, buttons, the tick
 */
#ifndef SNAKEBOT_CTL_DEVICE_INTERNAL_H
#define SNAKEBOT_CTL_DEVICE_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ctl_device.h"

/* ---- register descriptors (from the generated X-macros) ---------------------------- */

typedef struct {
    uint8_t addr; /* register address, or offset in a servo record */
    uint8_t size;
    uint8_t access;
    uint8_t is_signed;
    int32_t min; /* write range (not checked for 4-byte registers: full range) */
    int32_t max;
    int32_t def;
} field;

/* One descriptor, from a row of CTL_REGISTERS, CTL_SERVO_FIELDS or CTL_PAGE_FIELDS. */
#define CTL_FIELD(a, s, acc, lo, hi, sg, dflt) \
    {a, s, acc, sg, (int32_t)(lo), (int32_t)(hi), (int32_t)(dflt)},

#define WINDOW_END (CTL_SERVO_WINDOW + CTL_SERVO_RECORDS * CTL_SERVO_RECORD_SIZE)

/* ---- register accessors ---------------------------------------------------------------- */

/* Little-endian fields of `size` bytes (in ctl_regs.c). */
uint32_t ctl_get_le(const uint8_t *p, uint8_t size);
void ctl_put_le(uint8_t *p, uint8_t size, uint32_t v);

static inline uint32_t reg(const ctl_device *d, uint8_t addr, uint8_t size)
{
    return ctl_get_le(d->regs + addr, size);
}

static inline void set_reg(ctl_device *d, uint8_t addr, uint8_t size, uint32_t v)
{
    ctl_put_le(d->regs + addr, size, v);
}

/* The byte at addr after the write of data[0..n) at start. */
static inline uint8_t byte_after(const ctl_device *d, uint16_t addr, uint8_t start,
                                 const uint8_t *data, size_t n)
{
    return (addr >= start && addr < start + n) ? data[addr - start] : d->regs[addr];
}

static inline uint8_t joint_count(const ctl_device *d)
{
    return (uint8_t)reg(d, CTL_JOINT_COUNT, 1);
}

static inline uint8_t state(const ctl_device *d)
{
    return d->regs[CTL_STATE];
}

/* ---- ctl_regs.c: the control table --------------------------------------------------- */

bool ctl_in_range(const field *f, uint32_t raw);
uint32_t ctl_value_after(const ctl_device *d, uint8_t addr, uint8_t size, uint8_t start,
                         const uint8_t *data, size_t n);
void ctl_defaults(ctl_device *d);
uint8_t ctl_write_bytes(ctl_device *d, uint8_t start, const uint8_t *data, size_t n,
                        uint32_t now_ms);
void ctl_refresh(ctl_device *d);
void ctl_read_bytes(ctl_device *d, uint8_t start, uint8_t n, uint8_t *out);

/* ---- ctl_pages.c: the window ------------------------------------------------------------ */

void ctl_sync_bus_roster(ctl_device *d);
void ctl_record_read(const ctl_device *d, uint8_t k, uint8_t *rec);
void ctl_record_write(play_joint *roster, uint8_t k, const uint8_t *rec);
void ctl_roster_defaults(ctl_device *d);
uint16_t ctl_top_tick(void);
bool ctl_check_record(const ctl_device *d, uint8_t slot, uint8_t page, uint8_t start,
                      const uint8_t *data, size_t n, uint8_t *rec);
const field *ctl_page_field_at(uint8_t page, uint8_t offset);
uint32_t ctl_page_value(const ctl_device *d, uint8_t page, uint8_t addr);
uint8_t ctl_write_window(ctl_device *d, uint8_t start, const uint8_t *data, size_t n,
                         bool apply);

/* ---- ctl_upload.c: uploads, commits and the active table ------------------------------ */

bool ctl_is_program(const uint8_t *blob, size_t len);
bool ctl_active_is_program(const ctl_device *d);
bool ctl_within_robot(const ctl_device *d, uint8_t id, uint16_t min, uint16_t max);
uint8_t ctl_check_table(const ctl_device *d, const uint8_t *table, size_t len, gt_info *info);
bool ctl_program_fits(const ctl_device *d, const uint8_t *blob);
uint8_t ctl_load_active(ctl_device *d, const uint8_t *blob, size_t len, uint32_t crc,
                        uint8_t what);
void ctl_commit(ctl_device *d, uint8_t what);
uint8_t ctl_stage_chunk(ctl_device *d, uint8_t start, const uint8_t *data, size_t n,
                        bool apply);
void ctl_reset_device(ctl_device *d);

/* ---- ctl_state.c: state machine and safety ---------------------------------------------- */

void ctl_raise_flags(ctl_device *d, uint16_t flags);
void ctl_stop_motion(ctl_device *d);
void ctl_command(ctl_device *d, uint8_t cmd, uint32_t now_ms);
uint8_t ctl_serpenoid_fits_after(const ctl_device *d, uint8_t start, const uint8_t *data,
                                 size_t n);

#endif
