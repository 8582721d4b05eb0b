/* The controller's control table on the PC link (protocol/controller.md): the stored
 * registers' descriptors and defaults, and READ and WRITE of any range of it. A WRITE is
 * range-checked whole, then applied whole; the parts that fall on the window (ctl_pages.c)
 * or carry upload bytes (ctl_upload.c) are checked and applied there, and a command or a
 * commit it carries runs last (ctl_state.c, ctl_upload.c). */
#include "ctl_device_internal.h"

#include <string.h>

#include "dxl_packet.h"

/* ---- register descriptors (from the generated X-macros) ---------------------------- */

static const field registers[] = {CTL_REGISTERS(CTL_FIELD)};
#define N_REGISTERS (sizeof registers / sizeof registers[0])

uint32_t ctl_get_le(const uint8_t *p, uint8_t size)
{
    uint32_t v = 0;
    for (uint8_t i = size; i > 0; i--) v = (v << 8) | p[i - 1];
    return v;
}

void ctl_put_le(uint8_t *p, uint8_t size, uint32_t v)
{
    for (uint8_t i = 0; i < size; i++) {
        p[i] = (uint8_t)(v & 0xFFu);
        v >>= 8;
    }
}

uint32_t ctl_value_after(const ctl_device *d, uint8_t addr, uint8_t size, uint8_t start,
                         const uint8_t *data, size_t n)
{
    uint8_t bytes[4] = {0};
    for (uint8_t i = 0; i < size && i < 4; i++) {
        bytes[i] = byte_after(d, (uint16_t)(addr + i), start, data, n);
    }
    return ctl_get_le(bytes, size);
}

static int32_t as_value(uint32_t raw, const field *f)
{
    if (f->is_signed && f->size < 4) {
        uint32_t sign = 1u << (8u * f->size - 1u);
        return (int32_t)(raw ^ sign) - (int32_t)sign;
    }
    return (int32_t)raw;
}

bool ctl_in_range(const field *f, uint32_t raw)
{
    if (f->size >= 4) return true;
    int32_t v = as_value(raw, f);
    return v >= f->min && v <= f->max;
}

void ctl_defaults(ctl_device *d)
{
    memset(d->regs, 0, CTL_CONTROL_TABLE_BYTES);
    for (size_t i = 0; i < N_REGISTERS; i++) {
        const field *f = &registers[i];
        if (f->size <= 4 && (f->access & CTL_ACCESS_R) != 0) {
            ctl_put_le(d->regs + f->addr, f->size, (uint32_t)f->def);
        }
    }
    ctl_roster_defaults(d);
    play_stop(&d->player);
    d->staged_end = 0;
    d->refusal = CTL_REFUSAL_REASON_NONE;
}

/* ---- WRITE ------------------------------------------------------------------------------ */

static const field *register_at(uint8_t addr)
{
    for (size_t i = 0; i < N_REGISTERS; i++) {
        if (addr >= registers[i].addr && addr < registers[i].addr + registers[i].size) {
            return &registers[i];
        }
    }
    return NULL;
}

/* Range-check then apply a write of data[0..n) at start: all of it, or nothing. */
uint8_t ctl_write_bytes(ctl_device *d, uint8_t start, const uint8_t *data, size_t n,
                        uint32_t now_ms)
{
    if (n == 0 || start + n > CTL_CONTROL_TABLE_BYTES) return DXL_ERR_RANGE;
    uint16_t end = (uint16_t)(start + n);
    /* every byte must belong to a writable register or the servo window; each register
     * touched is range-checked as it would become (so a write of half a register is too) */
    for (uint16_t a = start; a < end; a++) {
        if (a >= CTL_SERVO_WINDOW && a < WINDOW_END) continue;
        const field *f = register_at((uint8_t)a);
        if (f == NULL || (f->access & CTL_ACCESS_W) == 0) return DXL_ERR_RANGE;
        /* the register's bytes this write touches are a..last: one check covers them */
        uint16_t f_end = (uint16_t)(f->addr + f->size);
        uint16_t last = (uint16_t)((f_end < end ? f_end : end) - 1u);
        if (f->addr != CTL_UPLOAD_DATA && /* its bytes: ctl_stage_chunk checks them */
            !ctl_in_range(f, ctl_value_after(d, f->addr, f->size, start, data, n))) {
            return DXL_ERR_RANGE;
        }
        a = last;
    }
    if (ctl_write_window(d, start, data, n, false) != 0) return DXL_ERR_RANGE;
    if (ctl_stage_chunk(d, start, data, n, false) != 0) return DXL_ERR_RANGE;
    /* a running serpenoid's live parameters and roster change only within the limits */
    if (state(d) == CTL_STATE_SERPENOID) {
        uint8_t why = ctl_serpenoid_fits_after(d, start, data, n);
        if (why != CTL_REFUSAL_REASON_NONE) {
            d->refusal = why;
            return DXL_ERR_RANGE;
        }
    }

    /* apply */
    uint8_t cmd = 0;
    uint8_t do_commit = CTL_UPLOAD_COMMIT_NONE;
    for (uint16_t a = start; a < end; a++) {
        uint8_t v = data[a - start];
        if (a >= CTL_SERVO_WINDOW && a < WINDOW_END) continue;
        if (a >= CTL_UPLOAD_DATA && a < CTL_UPLOAD_DATA + CTL_UPLOAD_DATA_SIZE) {
            continue; /* ctl_stage_chunk stages it */
        } else if (a == CTL_COMMAND) {
            cmd = v;
        } else if (a == CTL_UPLOAD_COMMIT) {
            do_commit = v;
        } else {
            d->regs[a] = v;
        }
    }
    ctl_stage_chunk(d, start, data, n, true);
    ctl_write_window(d, start, data, n, true);
    ctl_sync_bus_roster(d);
    if (do_commit != CTL_UPLOAD_COMMIT_NONE) ctl_commit(d, do_commit);
    if (cmd != 0) ctl_command(d, cmd, now_ms);
    return 0;
}

/* ---- READ ------------------------------------------------------------------------------- */

void ctl_refresh(ctl_device *d)
{
    set_reg(d, CTL_PLAY_FRAME, 2, play_frame_index(&d->player));
    set_reg(d, CTL_BUS_READS, 2, bus_reads(&d->bus));
    set_reg(d, CTL_BUS_TIMEOUTS, 2, bus_timeouts(&d->bus));
    set_reg(d, CTL_BUS_ERRORS, 2, bus_errors(&d->bus));
    d->regs[CTL_LIMITS_COUNT] = bus_limits_count(&d->bus);
    d->regs[CTL_LIMITS_STATE] = bus_limits_state(&d->bus);
}

void ctl_read_bytes(ctl_device *d, uint8_t start, uint8_t n, uint8_t *out)
{
    ctl_refresh(d);
    uint8_t page = d->regs[CTL_WINDOW_PAGE]; /* a known page: writes check it */
    lib_slot slot_shown;
    const uint8_t *slot_data = NULL;
    if (page == CTL_PAGE_LIBRARY) lib_shown(&d->lib, &slot_shown, &slot_data);
    uint8_t rec[CTL_SERVO_RECORD_SIZE];
    int16_t shown = -1;
    for (uint16_t i = 0; i < n; i++) {
        uint16_t a = (uint16_t)(start + i);
        if (a >= CTL_SERVO_WINDOW && a < WINDOW_END && page >= CTL_SERVO_PAGES) {
            const field *f = ctl_page_field_at(page, (uint8_t)(a - CTL_SERVO_WINDOW));
            uint8_t at = f ? (uint8_t)(CTL_SERVO_WINDOW + f->addr) : 0u;
            if (page == CTL_PAGE_LIBRARY) {
                out[i] = lib_page_byte(&d->lib, &slot_shown, slot_data, (uint8_t)a);
            } else {
                bool shows = f != NULL && (f->access & CTL_ACCESS_R) != 0; /* not a data window */
                out[i] = shows ? (uint8_t)(ctl_page_value(d, page, at) >> (8u * (a - at))) : 0u;
            }
        } else if (a >= CTL_SERVO_WINDOW && a < WINDOW_END) {
            uint8_t slot = (uint8_t)((a - CTL_SERVO_WINDOW) / CTL_SERVO_RECORD_SIZE);
            if (shown != slot) {
                ctl_record_read(d, (uint8_t)(page * CTL_SERVO_RECORDS + slot), rec);
                shown = slot;
            }
            out[i] = rec[(a - CTL_SERVO_WINDOW) % CTL_SERVO_RECORD_SIZE];
        } else {
            out[i] = d->regs[a];
        }
    }
}
