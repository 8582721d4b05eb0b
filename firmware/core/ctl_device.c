#include "ctl_device.h"

#include <string.h>

#include "crc32.h"
#include "dxl_packet.h"
#include "play_safety.h"
#include "prog_limits.h"
#include "prog_run.h"

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

/* A field of a described window page (offset from CTL_SERVO_WINDOW in f.addr). */
typedef struct {
    uint8_t page;
    field f;
} page_field;

#define FIELD(a, s, acc, lo, hi, sg, dflt) {a, s, acc, sg, (int32_t)(lo), (int32_t)(hi), (int32_t)(dflt)},
#define PAGE_FIELD(pg, a, s, acc, lo, hi, sg, dflt) {pg, FIELD(a, s, acc, lo, hi, sg, dflt)},
static const field registers[] = {CTL_REGISTERS(FIELD)};
static const field servo_fields[] = {CTL_SERVO_FIELDS(FIELD)};
static const page_field page_fields[] = {CTL_PAGE_FIELDS(PAGE_FIELD)};
#undef PAGE_FIELD
#undef FIELD
#define N_REGISTERS (sizeof registers / sizeof registers[0])
#define N_SERVO_FIELDS (sizeof servo_fields / sizeof servo_fields[0])
#define N_PAGE_FIELDS (sizeof page_fields / sizeof page_fields[0])

#define WINDOW_END (CTL_SERVO_WINDOW + CTL_SERVO_RECORDS * CTL_SERVO_RECORD_SIZE)
#define UPLOAD_FLAGS                                                                 \
    (CTL_ERROR_FLAGS_UPLOAD_LENGTH | CTL_ERROR_FLAGS_UPLOAD_CRC |                     \
     CTL_ERROR_FLAGS_UPLOAD_LAYOUT | CTL_ERROR_FLAGS_UPLOAD_TOO_BIG)

static uint32_t get_le(const uint8_t *p, uint8_t size)
{
    uint32_t v = 0;
    for (uint8_t i = size; i > 0; i--) v = (v << 8) | p[i - 1];
    return v;
}

static void put_le(uint8_t *p, uint8_t size, uint32_t v)
{
    for (uint8_t i = 0; i < size; i++) {
        p[i] = (uint8_t)(v & 0xFFu);
        v >>= 8;
    }
}

static uint32_t reg(const ctl_device *d, uint8_t addr, uint8_t size)
{
    return get_le(d->regs + addr, size);
}

static void set_reg(ctl_device *d, uint8_t addr, uint8_t size, uint32_t v)
{
    put_le(d->regs + addr, size, v);
}

/* The byte at addr after the write of data[0..n) at start. */
static uint8_t byte_after(const ctl_device *d, uint16_t addr, uint8_t start, const uint8_t *data,
                          size_t n)
{
    return (addr >= start && addr < start + n) ? data[addr - start] : d->regs[addr];
}

static uint32_t value_after(const ctl_device *d, uint8_t addr, uint8_t size, uint8_t start,
                            const uint8_t *data, size_t n)
{
    uint8_t bytes[4] = {0};
    for (uint8_t i = 0; i < size && i < 4; i++) {
        bytes[i] = byte_after(d, (uint16_t)(addr + i), start, data, n);
    }
    return get_le(bytes, size);
}

static int32_t as_value(uint32_t raw, const field *f)
{
    if (f->is_signed && f->size < 4) {
        uint32_t sign = 1u << (8u * f->size - 1u);
        return (int32_t)(raw ^ sign) - (int32_t)sign;
    }
    return (int32_t)raw;
}

static bool in_range(const field *f, uint32_t raw)
{
    if (f->size >= 4) return true;
    int32_t v = as_value(raw, f);
    return v >= f->min && v <= f->max;
}

/* ---- roster and servo window --------------------------------------------------------- */

static uint8_t joint_count(const ctl_device *d)
{
    return (uint8_t)reg(d, CTL_JOINT_COUNT, 1);
}

static void sync_bus_roster(ctl_device *d)
{
    uint8_t ids[CTL_MAX_JOINTS];
    uint8_t n = joint_count(d);
    for (uint8_t k = 0; k < n; k++) ids[k] = d->roster[k].id;
    bus_set_roster(&d->bus, ids, n);
}

static uint16_t last_goal(const ctl_device *d, uint8_t id)
{
    for (uint8_t j = 0; j < play_out_count(&d->player); j++) {
        if (play_out_id(&d->player, j) == id) return play_out_goal(&d->player, j);
    }
    return 0;
}

/* The 21 bytes of roster joint k as the servo window shows them. */
static void record_read(const ctl_device *d, uint8_t k, uint8_t *rec)
{
    const play_joint *j = &d->roster[k];
    for (uint8_t i = 0; i < CTL_SERVO_RECORD_SIZE; i++) rec[i] = 0;
    rec[CTL_REC_ID] = j->id;
    rec[CTL_REC_REVERSE] = j->reverse;
    put_le(rec + CTL_REC_ZERO_TICK, 2, j->zero);
    put_le(rec + CTL_REC_MIN_TICK, 2, j->min);
    put_le(rec + CTL_REC_MAX_TICK, 2, j->max);
    if (k >= joint_count(d)) return;
    put_le(rec + CTL_REC_GOAL_POSITION, 2, last_goal(d, j->id));
    const bus_servo *s = bus_servo_at(&d->bus, k);
    if (s == NULL) return;
    put_le(rec + CTL_REC_PRESENT_POSITION, 2, s->position);
    put_le(rec + CTL_REC_PRESENT_SPEED, 2, s->speed);
    put_le(rec + CTL_REC_PRESENT_LOAD, 2, s->load);
    rec[CTL_REC_PRESENT_VOLTAGE] = s->voltage;
    rec[CTL_REC_PRESENT_TEMPERATURE] = s->temperature;
    rec[CTL_REC_SERVO_ERROR] = s->error;
    rec[CTL_REC_ERROR_COUNT] = s->error_count;
    rec[CTL_REC_TIMEOUT_COUNT] = s->timeout_count;
}

static void record_write(play_joint *roster, uint8_t k, const uint8_t *rec)
{
    play_joint *j = &roster[k];
    j->id = rec[CTL_REC_ID];
    j->reverse = rec[CTL_REC_REVERSE];
    j->zero = (uint16_t)get_le(rec + CTL_REC_ZERO_TICK, 2);
    j->min = (uint16_t)get_le(rec + CTL_REC_MIN_TICK, 2);
    j->max = (uint16_t)get_le(rec + CTL_REC_MAX_TICK, 2);
}

static void roster_defaults(ctl_device *d)
{
    uint8_t rec[CTL_SERVO_RECORD_SIZE] = {0};
    for (size_t i = 0; i < N_SERVO_FIELDS; i++) {
        put_le(rec + servo_fields[i].addr, servo_fields[i].size, (uint32_t)servo_fields[i].def);
    }
    for (uint8_t k = 0; k < CTL_MAX_JOINTS; k++) record_write(d->roster, k, rec);
}

/* ---- state changes --------------------------------------------------------------------- */

static uint8_t state(const ctl_device *d)
{
    return d->regs[CTL_STATE];
}

static void set_state(ctl_device *d, uint8_t s)
{
    d->regs[CTL_STATE] = s;
}

static void raise_flags(ctl_device *d, uint16_t flags)
{
    set_reg(d, CTL_ERROR_FLAGS, 2, reg(d, CTL_ERROR_FLAGS, 2) | flags);
}

static bool moving(const ctl_device *d)
{
    return state(d) == CTL_STATE_PLAYING || state(d) == CTL_STATE_SERPENOID;
}

static void enter_safe(ctl_device *d, uint16_t faults)
{
    raise_flags(d, faults);
    if (state(d) == CTL_STATE_SAFE) return;
    play_stop(&d->player);
    set_state(d, CTL_STATE_SAFE);
    if (reg(d, CTL_SAFE_ACTION, 1) == CTL_SAFE_ACTION_TORQUE_OFF) {
        bus_request_torque(&d->bus, BUS_TORQUE_OFF);
    }
}

static void stop_motion(ctl_device *d)
{
    if (moving(d)) set_state(d, CTL_STATE_IDLE);
    play_stop(&d->player);
}

static void defaults(ctl_device *d)
{
    memset(d->regs, 0, CTL_CONTROL_TABLE_BYTES);
    for (size_t i = 0; i < N_REGISTERS; i++) {
        const field *f = &registers[i];
        if (f->size <= 4 && (f->access & CTL_ACCESS_R) != 0) {
            put_le(d->regs + f->addr, f->size, (uint32_t)f->def);
        }
    }
    roster_defaults(d);
    play_stop(&d->player);
    d->staged_end = 0;
    d->refusal = CTL_REFUSAL_REASON_NONE;
}

/* Mirror the active table's header into the registers, and the roster from it. */
static void show_table(ctl_device *d, const gt_info *info, uint32_t crc)
{
    set_reg(d, CTL_TABLE_SIZE, 2, info->size);
    set_reg(d, CTL_TABLE_CRC, 4, crc);
    set_reg(d, CTL_TABLE_JOINTS, 1, info->joint_count);
    set_reg(d, CTL_TABLE_FLAGS, 1, info->flags);
    set_reg(d, CTL_TABLE_FRAMES, 2, info->frame_count);
    set_reg(d, CTL_TABLE_PERIOD, 2, info->frame_period_ms);
    set_reg(d, CTL_LOOP, 1, (info->flags & GT_FLAG_LOOP) ? 1u : 0u);
    set_reg(d, CTL_JOINT_COUNT, 1, info->joint_count);
    for (uint8_t j = 0; j < info->joint_count; j++) {
        d->roster[j].id = gt_joint_id(d->active, info, j);
        d->roster[j].min = gt_joint_min(d->active, info, j);
        d->roster[j].max = gt_joint_max(d->active, info, j);
    }
    sync_bus_roster(d);
}

/* The staging area: the arena's last `capacity` bytes. */
static uint8_t *staging(ctl_device *d)
{
    return d->active + (d->arena_size - d->capacity);
}

/* Whether the player reads the active table's bytes (a table or a program plays). */
static bool table_in_use(const ctl_device *d)
{
    uint8_t mode = play_mode(&d->player);
    return mode == PLAY_MODE_TABLE || mode == PLAY_MODE_PROGRAM;
}

/* Whether the active table reaches into the staging area while it plays: then no chunk
 * can be staged (stage_chunk refuses them) and no commit can take staged bytes. */
static bool staging_blocked(ctl_device *d)
{
    return table_in_use(d) && staging(d) < d->active + d->active_len;
}

/* Copy blob[0..len) (a table or a program) to the arena's start, motion stopped. The copy
 * runs forward, so the staging area, higher up in the arena, may overlap its destination:
 * staged bytes the copy overwrote are gone (a repeated commit finds the upload
 * INCOMPLETE). */
static void store_active(ctl_device *d, const uint8_t *blob, size_t len)
{
    stop_motion(d);
    for (size_t i = 0; i < len; i++) d->active[i] = blob[i];
    if (staging(d) < d->active + len) d->staged_end = 0;
    d->active_len = (uint16_t)len;
    d->table_changed = 1;
}

/* Make table[0..len) active; `info` is what gt_validate found for it. */
static void activate(ctl_device *d, const uint8_t *table, size_t len, uint32_t crc,
                     const gt_info *info)
{
    store_active(d, table, len);
    show_table(d, info, crc);
}

/* Whether blob[0..len) is a program (protocol/program.md) rather than a table. */
static bool is_program(const uint8_t *blob, size_t len)
{
    return len >= 4 && get_le(blob, 4) == PROG_MAGIC;
}

static bool active_is_program(const ctl_device *d)
{
    return is_program(d->active, d->active_len);
}

/* Mirror the active program into the table registers, and its joints into the roster. */
static void show_program(ctl_device *d, uint32_t crc)
{
    const uint8_t *blob = d->active;
    uint8_t n = prog_joint_count(blob);
    set_reg(d, CTL_TABLE_SIZE, 2, d->active_len);
    set_reg(d, CTL_TABLE_CRC, 4, crc);
    set_reg(d, CTL_TABLE_JOINTS, 1, n);
    set_reg(d, CTL_TABLE_FLAGS, 1, 0);
    set_reg(d, CTL_TABLE_FRAMES, 2, 0);
    set_reg(d, CTL_TABLE_PERIOD, 2, prog_period_ms(blob));
    set_reg(d, CTL_LOOP, 1, 0);
    set_reg(d, CTL_JOINT_COUNT, 1, n);
    for (uint8_t j = 0; j < n; j++) {
        prog_joint pj = prog_joint_at(blob, j);
        play_joint *r = &d->roster[j];
        r->id = pj.id;
        r->reverse = pj.reverse;
        r->zero = pj.zero;
        r->min = pj.min;
        r->max = pj.max;
    }
    sync_bus_roster(d);
}

static uint16_t upload_flag(uint8_t result)
{
    if ((result >= CTL_UPLOAD_RESULT_LIBRARY_NONE &&
         result <= CTL_UPLOAD_RESULT_LIBRARY_NOT_PLAYABLE) ||
        result == CTL_UPLOAD_RESULT_STORE_BUSY) {
        return CTL_ERROR_FLAGS_LIBRARY;
    }
    if (result == CTL_UPLOAD_RESULT_LIBRARY_STORING) return 0; /* begun, not failed */
    switch (result) {
    case GT_ERR_TRUNCATED:
    case GT_ERR_TRAILING:
    case PROG_ERR_TRUNCATED:
    case PROG_ERR_TRAILING:
    case CTL_UPLOAD_RESULT_BAD_LENGTH:
    case CTL_UPLOAD_RESULT_INCOMPLETE:
    case CTL_UPLOAD_RESULT_NO_ROOM_WHILE_PLAYING: return CTL_ERROR_FLAGS_UPLOAD_LENGTH;
    case GT_ERR_CRC:
    case PROG_ERR_CRC:
    case CTL_UPLOAD_RESULT_TRANSFER_CRC: return CTL_ERROR_FLAGS_UPLOAD_CRC;
    case PROG_ERR_TOO_BIG:
    case GT_ERR_TOO_BIG: return CTL_ERROR_FLAGS_UPLOAD_TOO_BIG;
    case PROG_ERR_JOINT:
    case PROG_ERR_FRAME_RANGE:
    case PROG_ERR_SEGMENT:
    case PROG_ERR_OUT_OF_RANGE:
    case PROG_ERR_TOO_FAST: return CTL_ERROR_FLAGS_PROGRAM;
    default: return CTL_ERROR_FLAGS_UPLOAD_LAYOUT;
    }
}

/* Whether joint limits [min, max] of servo id lie within the robot's (always, when no
 * robot limits are set). */
static bool within_robot(const ctl_device *d, uint8_t id, uint16_t min, uint16_t max)
{
    if (bus_limits_count(&d->bus) == 0) return true;
    uint16_t lo, hi;
    return bus_limits_of(&d->bus, id, &lo, &hi) && min >= lo && max <= hi;
}

/* A table's joint limits (its frames lie within them: gt_validate) within the robot's. */
static bool table_fits(const ctl_device *d, const uint8_t *table, const gt_info *info)
{
    for (uint8_t j = 0; j < info->joint_count; j++) {
        if (!within_robot(d, gt_joint_id(table, info, j), gt_joint_min(table, info, j),
                          gt_joint_max(table, info, j))) {
            return false;
        }
    }
    return true;
}

static uint8_t check_table(const ctl_device *d, const uint8_t *table, size_t len, gt_info *info)
{
    uint8_t result = (uint8_t)gt_validate(table, len, info);
    if (result == GT_OK && !table_fits(d, table, info)) {
        result = CTL_UPLOAD_RESULT_OUTSIDE_ROBOT_LIMITS;
    }
    return result;
}

/* A validated program's joint limits within the robot's. */
static bool program_fits(const ctl_device *d, const uint8_t *blob)
{
    for (uint8_t j = 0; j < prog_joint_count(blob); j++) {
        prog_joint pj = prog_joint_at(blob, j);
        if (!within_robot(d, pj.id, pj.min, pj.max)) return false;
    }
    return true;
}

/* A program checked (prog_validate), then its joints' limits against the robot's. */
static uint8_t check_program(const ctl_device *d, const uint8_t *blob, size_t len)
{
    uint8_t result = prog_validate(blob, len, d->capacity, NULL);
    if (result == PROG_OK && !program_fits(d, blob)) {
        result = CTL_UPLOAD_RESULT_OUTSIDE_ROBOT_LIMITS;
    }
    return result;
}

/* Check blob[0..len) as what the commit says (a program, else a table) and make it
 * active; 0 (OK) or the refusal code. */
static uint8_t load_active(ctl_device *d, const uint8_t *blob, size_t len, uint32_t crc,
                           uint8_t what)
{
    gt_info info;
    uint8_t result;
    if (what == CTL_UPLOAD_COMMIT_PROGRAM) {
        result = check_program(d, blob, len);
        if (result == PROG_OK) {
            store_active(d, blob, len);
            show_program(d, crc);
        }
    } else {
        result = check_table(d, blob, len, &info);
        if (result == GT_OK) activate(d, blob, len, crc, &info);
    }
    return result;
}

/* The highest position tick: the servo window's Max Tick range says it. */
static uint16_t top_tick(void)
{
    for (size_t i = 0; i < N_SERVO_FIELDS; i++) {
        if (servo_fields[i].addr == CTL_REC_MAX_TICK) return (uint16_t)servo_fields[i].max;
    }
    return 0;
}

/* Robot limits as staged: a count N (1..18), then N records of servo ID, min tick, max
 * tick (u8, u16, u16); IDs distinct, min < max <= the top position tick; then, if the
 * blob is 2 bytes longer, the robot's Torque Limit (u16) within the servo's range. */
static uint8_t apply_limits(ctl_device *d, const uint8_t *blob, size_t len)
{
    uint8_t n = len > 0 ? blob[0] : 0u;
    size_t records = 1u + CTL_LIMITS_RECORD * n;
    if (n == 0 || n > CTL_MAX_JOINTS ||
        (len != records && len != records + CTL_LIMITS_TORQUE)) {
        return CTL_UPLOAD_RESULT_BAD_ROBOT_LIMITS;
    }
    uint16_t torque = BUS_TORQUE_LIMIT_NONE;
    if (len > records) {
        torque = (uint16_t)get_le(blob + records, CTL_LIMITS_TORQUE);
        /* one unsigned comparison: below the minimum wraps above the span (and a
         * minimum of 0 needs no comparison a compiler would call always false) */
        if ((uint16_t)(torque - AX12_TORQUE_LIMIT_MIN) >
            AX12_TORQUE_LIMIT_MAX - AX12_TORQUE_LIMIT_MIN) {
            return CTL_UPLOAD_RESULT_BAD_ROBOT_LIMITS;
        }
    }
    uint8_t ids[CTL_MAX_JOINTS];
    uint16_t mins[CTL_MAX_JOINTS], maxs[CTL_MAX_JOINTS];
    for (uint8_t k = 0; k < n; k++) {
        const uint8_t *r = blob + 1 + CTL_LIMITS_RECORD * k;
        ids[k] = r[0];
        mins[k] = (uint16_t)get_le(r + 1, 2);
        maxs[k] = (uint16_t)get_le(r + 3, 2);
        if (ids[k] > DXL_MAX_ID || mins[k] >= maxs[k] || maxs[k] > top_tick()) {
            return CTL_UPLOAD_RESULT_BAD_ROBOT_LIMITS;
        }
        for (uint8_t i = 0; i < k; i++) {
            if (ids[i] == ids[k]) return CTL_UPLOAD_RESULT_BAD_ROBOT_LIMITS;
        }
    }
    stop_motion(d);
    bus_set_limits(&d->bus, ids, mins, maxs, n);
    bus_set_torque_limit(&d->bus, torque);
    /* the serpenoid's clamps stay within the robot's limits */
    for (uint8_t k = 0; k < CTL_MAX_JOINTS; k++) {
        play_joint *j = &d->roster[k];
        uint16_t lo, hi;
        if (!bus_limits_of(&d->bus, j->id, &lo, &hi)) continue;
        if (j->min < lo) j->min = lo;
        if (j->max > hi) j->max = hi;
    }
    d->limits_changed = 1;
    return GT_OK;
}

__attribute__((weak)) uint8_t ctl_firmware_check(uint32_t len, uint32_t crc)
{
    (void)len;
    (void)crc;
    return CTL_UPLOAD_RESULT_FIRMWARE_UNAVAILABLE;
}

static void commit(ctl_device *d, uint8_t what)
{
    uint32_t len = reg(d, CTL_UPLOAD_LENGTH, 2);
    uint32_t crc = reg(d, CTL_UPLOAD_CRC, 4);
    uint8_t result;
    if (what == CTL_UPLOAD_COMMIT_FIRMWARE_CHECK) { /* checks the flash, not the staging */
        d->regs[CTL_UPLOAD_RESULT] = ctl_firmware_check(len, crc);
        return;
    }
    if (lib_saving(&d->lib, false, NULL) == CTL_STORE_STATE_LIBRARY) {
        /* the staging area is the library store's until it ends */
        result = CTL_UPLOAD_RESULT_STORE_BUSY;
    } else if (what == CTL_UPLOAD_COMMIT_LIBRARY_DELETE) {
        result = lib_delete(&d->lib, d->table_changed != 0); /* takes no staged bytes */
    } else if (staging_blocked(d)) {
        result = CTL_UPLOAD_RESULT_NO_ROOM_WHILE_PLAYING; /* nothing could be staged */
    } else if (len == 0 || len > d->capacity) {
        result = CTL_UPLOAD_RESULT_BAD_LENGTH;
    } else if (len > d->staged_end) {
        result = CTL_UPLOAD_RESULT_INCOMPLETE;
    } else if (crc32_compute(staging(d), len) != crc) {
        result = CTL_UPLOAD_RESULT_TRANSFER_CRC;
    } else if (what == CTL_UPLOAD_COMMIT_LIMITS) {
        result = apply_limits(d, staging(d), len);
    } else if (what == CTL_UPLOAD_COMMIT_LIBRARY_STORE) {
        /* a table or a program is checked as its own commit would check it before it is
         * kept */
        gt_info info;
        result = d->lib.store_kind == CTL_UPLOAD_COMMIT_TABLE
                     ? check_table(d, staging(d), len, &info)
                 : d->lib.store_kind == CTL_UPLOAD_COMMIT_PROGRAM
                     ? check_program(d, staging(d), len)
                     : CTL_UPLOAD_RESULT_OK;
        if (result == GT_OK) {
            result = lib_store_blob(&d->lib, d->table_changed != 0, staging(d), (uint16_t)len);
        }
    } else {
        result = load_active(d, staging(d), len, crc, what);
    }
    set_reg(d, CTL_ERROR_FLAGS, 2, reg(d, CTL_ERROR_FLAGS, 2) & ~(uint32_t)UPLOAD_FLAGS);
    if (result != GT_OK) raise_flags(d, upload_flag(result));
    if ((what == CTL_UPLOAD_COMMIT_LIBRARY_STORE || what == CTL_UPLOAD_COMMIT_LIBRARY_DELETE) &&
        lib_note(&d->lib, result)) {
        raise_flags(d, CTL_ERROR_FLAGS_LIBRARY);
    }
    d->regs[CTL_UPLOAD_RESULT] = result;
}

/* The servos hold the robot's limits, or none are set. */
static bool limits_ready(const ctl_device *d)
{
    uint8_t s = bus_limits_state(&d->bus);
    return s == CTL_LIMITS_STATE_NONE || s == CTL_LIMITS_STATE_VERIFIED;
}

static bool roster_ok(const ctl_device *d)
{
    uint8_t n = joint_count(d);
    if (n == 0) return false;
    for (uint8_t k = 0; k < n; k++) {
        const play_joint *j = &d->roster[k];
        if (j->min > j->max || !within_robot(d, j->id, j->min, j->max)) return false;
    }
    return true;
}

/* Why PLAY cannot run now (CTL_REFUSAL_REASON_*; NONE: it can). */
static uint8_t play_refusal(const ctl_device *d)
{
    gt_info info;
    if (state(d) == CTL_STATE_SAFE) return CTL_REFUSAL_REASON_SAFE_STATE;
    if (d->active_len == 0 || active_is_program(d)) return CTL_REFUSAL_REASON_NO_TABLE;
    if (!limits_ready(d)) return CTL_REFUSAL_REASON_LIMITS_NOT_VERIFIED;
    /* robot limits set after the table may be narrower than its own */
    if (check_table(d, d->active, d->active_len, &info) != GT_OK) {
        return CTL_REFUSAL_REASON_TABLE_OUTSIDE_LIMITS;
    }
    return CTL_REFUSAL_REASON_NONE;
}

/* Why PROGRAM_RUN cannot run now (CTL_REFUSAL_REASON_*; NONE: it can). */
static uint8_t program_refusal(const ctl_device *d)
{
    if (state(d) == CTL_STATE_SAFE) return CTL_REFUSAL_REASON_SAFE_STATE;
    if (!active_is_program(d)) return CTL_REFUSAL_REASON_NO_TABLE;
    if (!limits_ready(d)) return CTL_REFUSAL_REASON_LIMITS_NOT_VERIFIED;
    /* robot limits set after the program may be narrower than its joints' (the program
     * itself was validated when it became active and has not changed since) */
    if (!program_fits(d, d->active)) return CTL_REFUSAL_REASON_TABLE_OUTSIDE_LIMITS;
    return CTL_REFUSAL_REASON_NONE;
}

/* Whether the serpenoid, as its registers and the roster stand, stays within the roster's
 * limits and the servo's speed: a refusal reason (NONE: it does). */
static uint8_t serpenoid_fits(const ctl_device *d)
{
    return prog_check_serpenoid(d->roster, joint_count(d), (uint16_t)reg(d, CTL_SERP_AMPLITUDE, 2),
                                (int16_t)reg(d, CTL_SERP_OMEGA, 2), (int16_t)reg(d, CTL_SERP_PHI0, 2),
                                (int16_t)reg(d, CTL_STEERING_OFFSET, 2),
                                (uint16_t)reg(d, CTL_SPEED_SCALE, 2));
}

/* Why SERPENOID cannot run now (CTL_REFUSAL_REASON_*; NONE: it can). */
static uint8_t serpenoid_refusal(const ctl_device *d)
{
    if (state(d) == CTL_STATE_SAFE) return CTL_REFUSAL_REASON_SAFE_STATE;
    if (joint_count(d) == 0) return CTL_REFUSAL_REASON_EMPTY_ROSTER;
    if (!roster_ok(d)) return CTL_REFUSAL_REASON_BAD_JOINT_LIMITS;
    if (!limits_ready(d)) return CTL_REFUSAL_REASON_LIMITS_NOT_VERIFIED;
    return serpenoid_fits(d);
}

static void command(ctl_device *d, uint8_t cmd, uint32_t now_ms);

/* Make library slot `slot`'s table active, without it counting as a new table to persist
 * (it is kept in the library already), and PLAY it. */
static void library_play(ctl_device *d, uint8_t slot, uint32_t now_ms)
{
    const uint8_t *blob = NULL;
    uint16_t len = 0;
    uint32_t crc = 0;
    uint8_t result = lib_playable(&d->lib, slot, d->table_changed != 0, &blob, &len, &crc);
    if (result == CTL_UPLOAD_RESULT_OK && len > d->capacity) result = CTL_UPLOAD_RESULT_BAD_LENGTH;
    bool program = result == CTL_UPLOAD_RESULT_OK && is_program(blob, len);
    if (result == CTL_UPLOAD_RESULT_OK && blob != d->active) {
        uint8_t pending = d->table_changed;
        result = load_active(d, blob, len, crc,
                             program ? CTL_UPLOAD_COMMIT_PROGRAM : CTL_UPLOAD_COMMIT_TABLE);
        d->table_changed = pending; /* kept in the library already, not a new table */
    }
    if (lib_note(&d->lib, result)) {
        raise_flags(d, CTL_ERROR_FLAGS_LIBRARY | CTL_ERROR_FLAGS_REFUSED);
        return;
    }
    command(d, program ? CTL_COMMAND_PROGRAM_RUN : CTL_COMMAND_PLAY, now_ms);
}

static void command(ctl_device *d, uint8_t cmd, uint32_t now_ms)
{
    bool started = false;
    uint8_t why = CTL_REFUSAL_REASON_NONE;
    switch (cmd) {
    case CTL_COMMAND_PLAY:
        why = play_refusal(d);
        if (why != CTL_REFUSAL_REASON_NONE) break;
        started = play_start_table(&d->player, d->active, d->active_len, now_ms);
        if (started) set_state(d, CTL_STATE_PLAYING);
        else why = CTL_REFUSAL_REASON_NO_TABLE;
        break;
    case CTL_COMMAND_SERPENOID:
        why = serpenoid_refusal(d);
        if (why != CTL_REFUSAL_REASON_NONE) break;
        started = play_start_serpenoid(&d->player, joint_count(d), now_ms);
        if (started) set_state(d, CTL_STATE_SERPENOID);
        else why = CTL_REFUSAL_REASON_EMPTY_ROSTER;
        break;
    case CTL_COMMAND_LIBRARY_PLAY: library_play(d, d->lib.slot, now_ms); return;
    case CTL_COMMAND_PROGRAM_RUN:
        why = program_refusal(d);
        if (why != CTL_REFUSAL_REASON_NONE) break;
        play_start_program(&d->player, d->active, now_ms);
        set_state(d, CTL_STATE_PLAYING);
        started = true;
        break;
    case CTL_COMMAND_STOP: stop_motion(d); return;
    case CTL_COMMAND_CLEAR:
        set_reg(d, CTL_ERROR_FLAGS, 2, 0);
        bus_clear_faults(&d->bus);
        if (bus_limits_state(&d->bus) == CTL_LIMITS_STATE_FAILED) bus_recheck_limits(&d->bus);
        if (state(d) == CTL_STATE_SAFE) set_state(d, CTL_STATE_IDLE);
        return;
    default: return;
    }
    d->refusal = why;
    if (!started) {
        raise_flags(d, CTL_ERROR_FLAGS_REFUSED);
        return;
    }
    d->last_link_ms = now_ms;
    bus_request_torque(&d->bus, BUS_TORQUE_ON);
}

void ctl_set_library(ctl_device *d, const lib_store *store)
{
    lib_init(&d->lib, store);
}

void ctl_library_stored(ctl_device *d, uint8_t result)
{
    if (lib_note(&d->lib, result)) raise_flags(d, CTL_ERROR_FLAGS_LIBRARY);
    if (d->regs[CTL_UPLOAD_RESULT] == CTL_UPLOAD_RESULT_LIBRARY_STORING) {
        d->regs[CTL_UPLOAD_RESULT] = result;
    }
}

uint8_t ctl_buttons(ctl_device *d, uint8_t held, uint32_t now_ms)
{
    uint8_t slots = d->lib.store != NULL ? d->lib.store->slots : 0u;
    uint8_t action = lib_panel_tick(&d->lib.panel, held | d->lib.buttons, slots, moving(d));
    if (action == LIB_PANEL_STOP) command(d, CTL_COMMAND_STOP, now_ms);
    if (action == LIB_PANEL_PLAY) library_play(d, d->lib.panel.slot, now_ms);
    d->lib.leds = lib_panel_leds(&d->lib.panel, moving(d));
    return d->lib.leds;
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

/* Check the servo-window part of a write; the record k as it would become goes to rec. */
static bool check_record(const ctl_device *d, uint8_t slot, uint8_t page, uint8_t start,
                         const uint8_t *data, size_t n, uint8_t *rec)
{
    uint16_t base = (uint16_t)(CTL_SERVO_WINDOW + slot * CTL_SERVO_RECORD_SIZE);
    record_read(d, (uint8_t)(page * CTL_SERVO_RECORDS + slot), rec);
    bool touched[CTL_SERVO_RECORD_SIZE] = {false};
    for (uint8_t i = 0; i < CTL_SERVO_RECORD_SIZE; i++) {
        uint16_t addr = (uint16_t)(base + i);
        if (addr >= start && addr < start + n) {
            rec[i] = data[addr - start];
            touched[i] = true;
        }
    }
    for (size_t f = 0; f < N_SERVO_FIELDS; f++) {
        const field *sf = &servo_fields[f];
        bool hit = false;
        for (uint8_t i = 0; i < sf->size; i++) hit = hit || touched[sf->addr + i];
        if (!hit) continue;
        if ((sf->access & CTL_ACCESS_W) == 0) return false;
        if (!in_range(sf, get_le(rec + sf->addr, sf->size))) return false;
    }
    return true;
}

/* ---- window pages beyond the servo records --------------------------------------------- */

static bool page_known(uint8_t page)
{
    if (page < CTL_SERVO_PAGES) return true;
    for (size_t i = 0; i < N_PAGE_FIELDS; i++) {
        if (page_fields[i].page == page) return true;
    }
    return false;
}

/* The field of described page `page` holding window byte `offset`, or NULL. */
static const field *page_field_at(uint8_t page, uint8_t offset)
{
    for (size_t i = 0; i < N_PAGE_FIELDS; i++) {
        const field *f = &page_fields[i].f;
        if (page_fields[i].page == page && offset >= f->addr && offset < f->addr + f->size) {
            return f;
        }
    }
    return NULL;
}

/* The value field `addr` (absolute) of described page `page` shows. */
static uint32_t page_value(const ctl_device *d, uint8_t page, uint8_t addr)
{
    if (page == CTL_PAGE_LIBRARY) return lib_page_value(&d->lib, NULL, addr);
    if (page == CTL_PAGE_LIMITS && addr == CTL_ROBOT_TORQUE_LIMIT) {
        return bus_torque_limit(&d->bus);
    }
    if (page == CTL_PAGE_PROGRAM) {
        switch (addr) {
        case CTL_TABLE_CAPACITY: return d->capacity;
        case CTL_MAX_SEGMENTS: return CTL_MAX_PROGRAM_SEGMENTS;
        case CTL_REFUSAL_REASON: return d->refusal;
        case CTL_BOARD: return d->board;
        case CTL_LIBRARY_MEMORY:
            return d->lib.store != NULL ? d->lib.store->memory : CTL_LIBRARY_MEMORY_NONE;
        case CTL_STORE_STATE: return lib_saving(&d->lib, d->table_changed != 0, NULL);
        case CTL_STORE_PROGRESS: {
            uint8_t percent = 0;
            (void)lib_saving(&d->lib, d->table_changed != 0, &percent);
            return percent;
        }
        case CTL_PROGRAM_SEGMENT: return play_program_segment(&d->player);
        case CTL_PROGRAM_STATE:
            if (play_mode(&d->player) == PLAY_MODE_PROGRAM) return CTL_PROGRAM_STATE_RUNNING;
            if (play_finished(&d->player) && active_is_program(d)) return CTL_PROGRAM_STATE_DONE;
            return CTL_PROGRAM_STATE_IDLE;
        default: return 0;
        }
    }
    return 0;
}

/* Check (apply: and apply) the part of a write of data[0..n) at start that falls on the
 * window while it shows described page `page`: every byte in a writable field, each
 * field touched in range as it would become. */
static uint8_t write_page(ctl_device *d, uint8_t page, uint8_t start, const uint8_t *data,
                          size_t n, bool apply)
{
    uint16_t end = (uint16_t)(start + n);
    uint16_t a = start > CTL_SERVO_WINDOW ? start : CTL_SERVO_WINDOW;
    for (; a < end && a < WINDOW_END; a++) {
        const field *f = page_field_at(page, (uint8_t)(a - CTL_SERVO_WINDOW));
        if (f == NULL || (f->access & CTL_ACCESS_W) == 0) return DXL_ERR_RANGE;
        uint8_t at = (uint8_t)(CTL_SERVO_WINDOW + f->addr);
        if (f->size > 4) { /* a byte string: any bytes */
            a = (uint16_t)(at + f->size - 1u);
            continue;
        }
        uint8_t now[4];
        put_le(now, f->size, page_value(d, page, at));
        for (uint8_t i = 0; i < f->size; i++) {
            uint16_t b = (uint16_t)(at + i);
            if (b >= start && b < end) now[i] = data[b - start];
        }
        uint32_t value = get_le(now, f->size);
        if (!in_range(f, value)) return DXL_ERR_RANGE;
        a = (uint16_t)(at + f->size - 1u);
    }
    if (page == CTL_PAGE_LIBRARY && !lib_page_write(&d->lib, start, data, (uint16_t)n, apply)) {
        return DXL_ERR_RANGE;
    }
    return 0;
}

static uint8_t write_window(ctl_device *d, uint8_t start, const uint8_t *data, size_t n, bool apply)
{
    uint8_t page = byte_after(d, CTL_WINDOW_PAGE, start, data, n);
    if (!page_known(page)) return DXL_ERR_RANGE;
    if (start + n <= CTL_SERVO_WINDOW) return 0;
    if (page == CTL_PAGE_UPLOAD_DATA_2) return 0; /* table bytes: stage_chunk checks them */
    if (page >= CTL_SERVO_PAGES) return write_page(d, page, start, data, n, apply);
    for (uint8_t slot = 0; slot < CTL_SERVO_RECORDS; slot++) {
        uint16_t base = (uint16_t)(CTL_SERVO_WINDOW + slot * CTL_SERVO_RECORD_SIZE);
        if (base >= start + n || base + CTL_SERVO_RECORD_SIZE <= start) continue;
        uint8_t rec[CTL_SERVO_RECORD_SIZE];
        if (!check_record(d, slot, page, start, data, n, rec)) return DXL_ERR_RANGE;
        if (!within_robot(d, rec[CTL_REC_ID], (uint16_t)get_le(rec + CTL_REC_MIN_TICK, 2),
                          (uint16_t)get_le(rec + CTL_REC_MAX_TICK, 2))) {
            return DXL_ERR_RANGE;
        }
        if (apply) record_write(d->roster, (uint8_t)(page * CTL_SERVO_RECORDS + slot), rec);
    }
    return 0;
}

/* serpenoid_fits() with the registers and the roster as the write of data[0..n) at start
 * (already range-checked) would leave them. */
static uint8_t serpenoid_fits_after(const ctl_device *d, uint8_t start, const uint8_t *data,
                                    size_t n)
{
    uint8_t count = (uint8_t)value_after(d, CTL_JOINT_COUNT, 1, start, data, n);
    uint8_t page = byte_after(d, CTL_WINDOW_PAGE, start, data, n);
    uint16_t amp = (uint16_t)value_after(d, CTL_SERP_AMPLITUDE, 2, start, data, n);
    int16_t phi0 = (int16_t)value_after(d, CTL_SERP_PHI0, 2, start, data, n);
    int16_t steering = (int16_t)value_after(d, CTL_STEERING_OFFSET, 2, start, data, n);
    /* one joint at a time, its record as the write would leave it (no roster copy: the
     * PC link's deepest path is this one) */
    for (uint8_t k = 0; k < count && k < CTL_MAX_JOINTS; k++) {
        play_joint j = d->roster[k];
        if (page < CTL_SERVO_PAGES && k / CTL_SERVO_RECORDS == page) {
            uint8_t rec[CTL_SERVO_RECORD_SIZE];
            (void)check_record(d, k % CTL_SERVO_RECORDS, page, start, data, n, rec);
            record_write(&j, 0, rec);
        }
        if (!prog_joint_fits(&j, amp, phi0, steering)) return CTL_REFUSAL_REASON_AMPLITUDE;
    }
    if (!prog_speed_fits(amp, (int16_t)value_after(d, CTL_SERP_OMEGA, 2, start, data, n),
                         (uint16_t)value_after(d, CTL_SPEED_SCALE, 2, start, data, n))) {
        return CTL_REFUSAL_REASON_SPEED;
    }
    return CTL_REFUSAL_REASON_NONE;
}

/* ---- upload chunks ------------------------------------------------------------------------ */

/* The staging byte that byte `a` of a write fills, or -1: Upload Data byte i fills
 * staging[offset + i] and, while the window shows page Upload Data 2, window byte i goes on
 * at staging[offset + CTL_UPLOAD_DATA_SIZE + i], so one WRITE at Upload Offset running
 * through Window Page into the window carries one long chunk. */
static int32_t staging_at(uint32_t offset, uint8_t page, uint16_t a)
{
    if (a >= CTL_UPLOAD_DATA && a < CTL_UPLOAD_DATA + CTL_UPLOAD_DATA_SIZE) {
        return (int32_t)(offset + (a - CTL_UPLOAD_DATA));
    }
    if (page == CTL_PAGE_UPLOAD_DATA_2 && a >= CTL_UPLOAD_DATA_MORE &&
        a < CTL_UPLOAD_DATA_MORE + CTL_UPLOAD_DATA_MORE_SIZE) {
        return (int32_t)(offset + CTL_UPLOAD_DATA_SIZE + (a - CTL_UPLOAD_DATA_MORE));
    }
    return -1;
}

/* The active table gives way to an upload staged over it: no table (the registers say
 * so); the roster stays as it was. */
static void drop_active(ctl_device *d)
{
    d->active_len = 0;
    set_reg(d, CTL_TABLE_SIZE, 2, 0);
    set_reg(d, CTL_TABLE_CRC, 4, 0);
    set_reg(d, CTL_TABLE_JOINTS, 1, 0);
    set_reg(d, CTL_TABLE_FLAGS, 1, 0);
    set_reg(d, CTL_TABLE_FRAMES, 2, 0);
    set_reg(d, CTL_TABLE_PERIOD, 2, 0);
}

/* Check (apply: and stage) the table bytes a write of data[0..n) at start carries: they
 * must end inside the board's capacity (else UPLOAD_LENGTH and RANGE, nothing staged),
 * and may land on the active table's bytes (when the arena is less than twice the
 * capacity) only while no table plays (else Upload Result NO_ROOM_WHILE_PLAYING,
 * UPLOAD_LENGTH and RANGE); landing there drops the active table. A chunk at offset 0
 * starts an upload; the others extend what was staged. */
static uint8_t stage_chunk(ctl_device *d, uint8_t start, const uint8_t *data, size_t n,
                           bool apply)
{
    uint32_t offset = value_after(d, CTL_UPLOAD_OFFSET, 2, start, data, n);
    uint8_t page = byte_after(d, CTL_WINDOW_PAGE, start, data, n);
    uint8_t *stage = staging(d);
    int32_t lo = -1, hi = -1; /* the staging bytes filled: lo..hi, contiguous */
    for (uint16_t a = start; a < start + n; a++) {
        int32_t at = staging_at(offset, page, a);
        if (at < 0) continue;
        if (lo < 0) lo = at;
        hi = at;
        if (apply) stage[at] = data[a - start];
    }
    if (lo < 0) return 0;
    bool over_active = stage + lo < d->active + d->active_len;
    if (!apply && (uint32_t)hi >= d->capacity) {
        raise_flags(d, CTL_ERROR_FLAGS_UPLOAD_LENGTH);
        return DXL_ERR_RANGE;
    }
    if (!apply && lib_saving(&d->lib, false, NULL) == CTL_STORE_STATE_LIBRARY) {
        /* a library store reads the staged blob until it ends */
        d->regs[CTL_UPLOAD_RESULT] = CTL_UPLOAD_RESULT_STORE_BUSY;
        raise_flags(d, CTL_ERROR_FLAGS_LIBRARY);
        return DXL_ERR_RANGE;
    }
    if (!apply && over_active && table_in_use(d)) {
        d->regs[CTL_UPLOAD_RESULT] = CTL_UPLOAD_RESULT_NO_ROOM_WHILE_PLAYING;
        raise_flags(d, CTL_ERROR_FLAGS_UPLOAD_LENGTH);
        return DXL_ERR_RANGE;
    }
    if (apply && over_active) drop_active(d);
    if (apply && lo == 0) d->staged_end = (uint16_t)(hi + 1);
    else if (apply && hi + 1 > d->staged_end) d->staged_end = (uint16_t)(hi + 1);
    return 0;
}

/* Range-check then apply a write of data[0..n) at start: all of it, or nothing. */
static uint8_t write_bytes(ctl_device *d, uint8_t start, const uint8_t *data, size_t n,
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
        if (f->addr != CTL_UPLOAD_DATA && /* its bytes: stage_chunk checks them */
            !in_range(f, value_after(d, f->addr, f->size, start, data, n))) {
            return DXL_ERR_RANGE;
        }
        a = last;
    }
    if (write_window(d, start, data, n, false) != 0) return DXL_ERR_RANGE;
    if (stage_chunk(d, start, data, n, false) != 0) return DXL_ERR_RANGE;
    /* a running serpenoid's live parameters and roster change only within the limits */
    if (state(d) == CTL_STATE_SERPENOID) {
        uint8_t why = serpenoid_fits_after(d, start, data, n);
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
            continue; /* stage_chunk stages it */
        } else if (a == CTL_COMMAND) {
            cmd = v;
        } else if (a == CTL_UPLOAD_COMMIT) {
            do_commit = v;
        } else {
            d->regs[a] = v;
        }
    }
    stage_chunk(d, start, data, n, true);
    write_window(d, start, data, n, true);
    sync_bus_roster(d);
    if (do_commit != CTL_UPLOAD_COMMIT_NONE) commit(d, do_commit);
    if (cmd != 0) command(d, cmd, now_ms);
    return 0;
}

/* ---- READ ------------------------------------------------------------------------------- */

static void refresh(ctl_device *d)
{
    set_reg(d, CTL_PLAY_FRAME, 2, play_frame_index(&d->player));
    set_reg(d, CTL_BUS_READS, 2, bus_reads(&d->bus));
    set_reg(d, CTL_BUS_TIMEOUTS, 2, bus_timeouts(&d->bus));
    set_reg(d, CTL_BUS_ERRORS, 2, bus_errors(&d->bus));
    d->regs[CTL_LIMITS_COUNT] = bus_limits_count(&d->bus);
    d->regs[CTL_LIMITS_STATE] = bus_limits_state(&d->bus);
}

static void read_bytes(ctl_device *d, uint8_t start, uint8_t n, uint8_t *out)
{
    refresh(d);
    uint8_t page = d->regs[CTL_WINDOW_PAGE]; /* a known page: writes check it */
    lib_slot slot_shown;
    const uint8_t *slot_data = NULL;
    if (page == CTL_PAGE_LIBRARY) lib_shown(&d->lib, &slot_shown, &slot_data);
    uint8_t rec[CTL_SERVO_RECORD_SIZE];
    int16_t shown = -1;
    for (uint16_t i = 0; i < n; i++) {
        uint16_t a = (uint16_t)(start + i);
        if (a >= CTL_SERVO_WINDOW && a < WINDOW_END && page >= CTL_SERVO_PAGES) {
            const field *f = page_field_at(page, (uint8_t)(a - CTL_SERVO_WINDOW));
            uint8_t at = f ? (uint8_t)(CTL_SERVO_WINDOW + f->addr) : 0u;
            if (page == CTL_PAGE_LIBRARY) {
                out[i] = lib_page_byte(&d->lib, &slot_shown, slot_data, (uint8_t)a);
            } else {
                bool shows = f != NULL && (f->access & CTL_ACCESS_R) != 0; /* not a data window */
                out[i] = shows ? (uint8_t)(page_value(d, page, at) >> (8u * (a - at))) : 0u;
            }
        } else if (a >= CTL_SERVO_WINDOW && a < WINDOW_END) {
            uint8_t slot = (uint8_t)((a - CTL_SERVO_WINDOW) / CTL_SERVO_RECORD_SIZE);
            if (shown != slot) {
                record_read(d, (uint8_t)(page * CTL_SERVO_RECORDS + slot), rec);
                shown = slot;
            }
            out[i] = rec[(a - CTL_SERVO_WINDOW) % CTL_SERVO_RECORD_SIZE];
        } else {
            out[i] = d->regs[a];
        }
    }
}

/* RESET: registers and roster to their defaults, motion stopped, errors cleared; the
 * active table stays (and the roster follows it again). */
static void reset_device(ctl_device *d)
{
    defaults(d);
    bus_clear_faults(&d->bus);
    if (active_is_program(d)) {
        if (check_program(d, d->active, d->active_len) == PROG_OK) {
            show_program(d, crc32_compute(d->active, d->active_len));
        }
    } else if (d->active_len > 0) {
        /* The active table was validated when it became active, and its bytes have not
         * changed since (a chunk staged over them drops it): its header says the rest.
         * Only the robot's limits, which may have changed since, are checked again. */
        gt_info info;
        if (gt_describe(d->active, d->active_len, &info) == GT_OK &&
            table_fits(d, d->active, &info)) {
            show_table(d, &info, crc32_compute(d->active, d->active_len));
        }
    }
    sync_bus_roster(d);
}

/* ---- packets ----------------------------------------------------------------------------- */

static size_t reply(uint8_t *out, size_t cap, uint8_t id, uint8_t error, size_t ndata)
{
    /* the data is already at out + 5 */
    if (cap < ndata + 6) return 0;
    out[0] = DXL_HEADER_BYTE;
    out[1] = DXL_HEADER_BYTE;
    out[2] = id;
    out[3] = (uint8_t)(ndata + 2);
    out[4] = error;
    out[5 + ndata] = dxl_checksum(out + 2, ndata + 3);
    return ndata + 6;
}

static void sync_write(ctl_device *d, const uint8_t *p, size_t n, uint32_t now_ms)
{
    if (n < 2 || p[1] == 0) return;
    size_t block = (size_t)p[1] + 1u;
    if ((n - 2) % block != 0) return;
    for (size_t at = 2; at + block <= n; at += block) {
        if (p[at] == d->regs[CTL_ID]) {
            write_bytes(d, p[0], p + at + 1, p[1], now_ms);
            return;
        }
    }
}

size_t ctl_handle_packet(ctl_device *d, uint8_t id, uint8_t instruction, const uint8_t *params,
                         size_t nparams, uint32_t now_ms, uint8_t *out, size_t cap)
{
    uint8_t me = d->regs[CTL_ID];
    bool broadcast = id == DXL_BROADCAST_ID;
    if (!broadcast && id != me) return 0;
    d->last_link_ms = now_ms;
    uint8_t level = d->regs[CTL_STATUS_RETURN_LEVEL];
    uint8_t error = 0;
    size_t ndata = 0;
    bool answer = !broadcast && level >= 2;
    switch (instruction) {
    case DXL_INST_PING:
        answer = !broadcast;
        break;
    case DXL_INST_READ:
        answer = !broadcast && level >= 1;
        if (nparams != 2) {
            error = DXL_ERR_INSTRUCTION;
        } else if (params[1] == 0 || (size_t)params[0] + params[1] > CTL_CONTROL_TABLE_BYTES ||
                   params[1] > DXL_MAX_PARAMS) {
            error = DXL_ERR_RANGE;
        } else if (answer) {
            if (cap < (size_t)params[1] + 6) return 0;
            read_bytes(d, params[0], params[1], out + 5);
            ndata = params[1];
        }
        break;
    case DXL_INST_WRITE:
        error = nparams < 2 ? DXL_ERR_INSTRUCTION
                            : write_bytes(d, params[0], params + 1, nparams - 1, now_ms);
        break;
    case DXL_INST_SYNC_WRITE:
        if (broadcast) sync_write(d, params, nparams, now_ms);
        return 0;
    case DXL_INST_RESET: {
        size_t n = answer ? reply(out, cap, me, 0, 0) : 0;
        reset_device(d);
        return n;
    }
    default:
        error = DXL_ERR_INSTRUCTION;
        break;
    }
    return answer ? reply(out, cap, me, error, ndata) : 0;
}

/* ---- public ---------------------------------------------------------------------------- */

size_t ctl_device_size(void)
{
    return sizeof(ctl_device);
}

void ctl_init(ctl_device *d)
{
    play_init(&d->player);
    bus_init(&d->bus);
    dxl_parser_reset(&d->pc);
    defaults(d);
    d->last_link_ms = 0;
    d->active_len = 0;
    d->out_count = 0;
    d->table_changed = 0;
    d->limits_changed = 0;
    d->arena_size = 0;
    d->capacity = 0;
    d->board = CTL_BOARD_NONE;
    lib_init(&d->lib, NULL);
}

void ctl_set_board(ctl_device *d, uint8_t board)
{
    d->board = board;
}

size_t ctl_device_bytes(size_t arena)
{
    return sizeof(ctl_device) + arena;
}

void ctl_set_tables(ctl_device *d, size_t arena, uint16_t capacity)
{
    stop_motion(d);
    if (d->active_len > 0) drop_active(d);
    d->staged_end = 0;
    d->arena_size = (uint16_t)(arena < 0xFFFFu ? arena : 0xFFFFu);
    ctl_set_capacity(d, capacity);
}

void ctl_set_capacity(ctl_device *d, uint16_t bytes)
{
    uint16_t most = d->arena_size < CTL_MAX_TABLE_BYTES ? d->arena_size : CTL_MAX_TABLE_BYTES;
    d->capacity = bytes < most ? bytes : most;
    d->staged_end = 0; /* the staging area moved */
}

bool ctl_load_table(ctl_device *d, const uint8_t *table, size_t len)
{
    if (len == 0 || len > d->capacity) return false;
    uint8_t what = is_program(table, len) ? CTL_UPLOAD_COMMIT_PROGRAM : CTL_UPLOAD_COMMIT_TABLE;
    return load_active(d, table, len, crc32_compute(table, len), what) == GT_OK;
}

bool ctl_load_limits(ctl_device *d, const uint8_t *blob, size_t len)
{
    return apply_limits(d, blob, len) == GT_OK;
}

size_t ctl_robot_limits(const ctl_device *d, uint8_t *out, size_t cap)
{
    uint8_t n = bus_limits_count(&d->bus);
    uint16_t torque = bus_torque_limit(&d->bus);
    size_t records = 1u + CTL_LIMITS_RECORD * n;
    size_t len = records + (torque != BUS_TORQUE_LIMIT_NONE ? CTL_LIMITS_TORQUE : 0u);
    if (n == 0 || cap < len) return 0;
    out[0] = n;
    for (uint8_t k = 0; k < n; k++) {
        uint8_t *r = out + 1 + CTL_LIMITS_RECORD * k;
        r[0] = d->bus.lim_id[k];
        put_le(r + 1, 2, d->bus.lim_min[k]);
        put_le(r + 3, 2, d->bus.lim_max[k]);
    }
    if (len > records) put_le(out + records, CTL_LIMITS_TORQUE, torque);
    return len;
}

bool ctl_limits_changed(ctl_device *d)
{
    bool changed = d->limits_changed != 0;
    d->limits_changed = 0;
    return changed;
}

bool ctl_pc_feed(ctl_device *d, uint8_t byte)
{
    return dxl_parser_feed(&d->pc, byte);
}

bool ctl_pc_poll(ctl_device *d, uint32_t now_ms, uint8_t *out, size_t cap, size_t *out_len)
{
    dxl_event ev;
    *out_len = 0;
    if (!dxl_parser_poll(&d->pc, &ev)) {
        /* A false header (noise, a damaged LEN) must not hold back the host's packets
         * behind it until its LEN is made up: the host would wait in vain, and a trickle
         * of noise keeps the line from ever going quiet for the gap reset. */
        if (!dxl_parser_skip_to_hidden(&d->pc)) return false;
        set_reg(d, CTL_PC_ERRORS, 2, reg(d, CTL_PC_ERRORS, 2) + 1u);
        return true;
    }
    if (ev.kind == DXL_EVENT_PACKET) {
        set_reg(d, CTL_PC_PACKETS, 2, reg(d, CTL_PC_PACKETS, 2) + 1u);
        *out_len = ctl_handle_packet(d, ev.id, ev.code, ev.params, ev.nparams, now_ms, out, cap);
    } else {
        set_reg(d, CTL_PC_ERRORS, 2, reg(d, CTL_PC_ERRORS, 2) + 1u);
    }
    return true;
}

void ctl_tick(ctl_device *d, uint32_t now_ms)
{
    uint8_t errors[CTL_MAX_JOINTS];
    uint8_t missed[CTL_MAX_JOINTS];
    uint8_t n = bus_roster_count(&d->bus);
    for (uint8_t k = 0; k < n; k++) {
        const bus_servo *s = bus_servo_at(&d->bus, k);
        errors[k] = s->error;
        missed[k] = s->missed;
    }
    uint16_t faults = play_safety_check(errors, missed, n, d->regs[CTL_SERVO_ERROR_MASK],
                                        d->regs[CTL_BUS_LOSS_LIMIT], moving(d),
                                        now_ms - d->last_link_ms, d->regs[CTL_LINK_TIMEOUT]);
    if (faults != 0) enter_safe(d, faults);
    if (bus_limits_state(&d->bus) == CTL_LIMITS_STATE_FAILED) raise_flags(d, CTL_ERROR_FLAGS_LIMITS);

    play_params params;
    params.speed_scale = (uint16_t)reg(d, CTL_SPEED_SCALE, 2);
    params.steering = (int16_t)reg(d, CTL_STEERING_OFFSET, 2);
    params.loop = d->regs[CTL_LOOP];
    params.amp_mrad = (uint16_t)reg(d, CTL_SERP_AMPLITUDE, 2);
    params.omega_mrad_s = (int16_t)reg(d, CTL_SERP_OMEGA, 2);
    params.delta_mrad = (int16_t)reg(d, CTL_SERP_DELTA, 2);
    params.phi0_mrad = (int16_t)reg(d, CTL_SERP_PHI0, 2);
    d->out_count = play_tick(&d->player, &params, d->roster, joint_count(d), now_ms);
    if (moving(d) && play_mode(&d->player) == PLAY_MODE_IDLE) set_state(d, CTL_STATE_IDLE);
    refresh(d);
    bus_begin_tick(&d->bus);
}

size_t ctl_bus_next(ctl_device *d, uint8_t *out, size_t cap, uint8_t *reply_len)
{
    bus_txn txn;
    const play_state *p = &d->player;
    size_t n = bus_next(&d->bus, p->out_id, p->out_goal, p->out_speed, d->out_count, out, cap,
                        &txn);
    *reply_len = n > 0 ? txn.reply_len : 0;
    return n;
}

bool ctl_bus_rx(ctl_device *d, const uint8_t *data, size_t len)
{
    return bus_rx(&d->bus, data, len);
}

void ctl_bus_rx_done(ctl_device *d)
{
    bus_rx_done(&d->bus);
}

uint8_t ctl_state(const ctl_device *d)
{
    return state(d);
}

uint16_t ctl_error_flags(const ctl_device *d)
{
    return (uint16_t)reg(d, CTL_ERROR_FLAGS, 2);
}

uint8_t ctl_id(const ctl_device *d)
{
    return d->regs[CTL_ID];
}

bool ctl_table_changed(ctl_device *d)
{
    bool changed = d->table_changed != 0;
    d->table_changed = 0;
    return changed;
}

const uint8_t *ctl_active_table(const ctl_device *d, size_t *len)
{
    *len = d->active_len;
    return d->active_len ? d->active : NULL;
}
