/* The active table (or program) and how it changes: the upload window's chunks staged in
 * the table arena, Upload Commit (a table, a program, the robot's limits, the gait
 * library's store and delete, the firmware check), loads from flash, and RESET, which
 * shows the active table again (protocol/controller.md). */
#include "ctl_device_internal.h"

#include "crc32.h"
#include "dxl_packet.h"
#include "prog_run.h"

#define UPLOAD_FLAGS                                                                 \
    (CTL_ERROR_FLAGS_UPLOAD_LENGTH | CTL_ERROR_FLAGS_UPLOAD_CRC |                     \
     CTL_ERROR_FLAGS_UPLOAD_LAYOUT | CTL_ERROR_FLAGS_UPLOAD_TOO_BIG)

/* ---- the active table --------------------------------------------------------------------- */

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
    ctl_sync_bus_roster(d);
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
 * can be staged (ctl_stage_chunk refuses them) and no commit can take staged bytes. */
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
    ctl_stop_motion(d);
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
bool ctl_is_program(const uint8_t *blob, size_t len)
{
    return len >= 4 && ctl_get_le(blob, 4) == PROG_MAGIC;
}

bool ctl_active_is_program(const ctl_device *d)
{
    return ctl_is_program(d->active, d->active_len);
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
    ctl_sync_bus_roster(d);
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
bool ctl_within_robot(const ctl_device *d, uint8_t id, uint16_t min, uint16_t max)
{
    if (bus_limits_count(&d->bus) == 0) return true;
    uint16_t lo, hi;
    return bus_limits_of(&d->bus, id, &lo, &hi) && min >= lo && max <= hi;
}

/* A table's joint limits (its frames lie within them: gt_validate) within the robot's. */
static bool table_fits(const ctl_device *d, const uint8_t *table, const gt_info *info)
{
    for (uint8_t j = 0; j < info->joint_count; j++) {
        if (!ctl_within_robot(d, gt_joint_id(table, info, j), gt_joint_min(table, info, j),
                              gt_joint_max(table, info, j))) {
            return false;
        }
    }
    return true;
}

uint8_t ctl_check_table(const ctl_device *d, const uint8_t *table, size_t len, gt_info *info)
{
    uint8_t result = (uint8_t)gt_validate(table, len, info);
    if (result == GT_OK && !table_fits(d, table, info)) {
        result = CTL_UPLOAD_RESULT_OUTSIDE_ROBOT_LIMITS;
    }
    return result;
}

/* A validated program's joint limits within the robot's. */
bool ctl_program_fits(const ctl_device *d, const uint8_t *blob)
{
    for (uint8_t j = 0; j < prog_joint_count(blob); j++) {
        prog_joint pj = prog_joint_at(blob, j);
        if (!ctl_within_robot(d, pj.id, pj.min, pj.max)) return false;
    }
    return true;
}

/* A program checked (prog_validate), then its joints' limits against the robot's. */
static uint8_t check_program(const ctl_device *d, const uint8_t *blob, size_t len)
{
    uint8_t result = prog_validate(blob, len, d->capacity, NULL);
    if (result == PROG_OK && !ctl_program_fits(d, blob)) {
        result = CTL_UPLOAD_RESULT_OUTSIDE_ROBOT_LIMITS;
    }
    return result;
}

/* Check blob[0..len) as what the commit says (a program, else a table) and make it
 * active; 0 (OK) or the refusal code. */
uint8_t ctl_load_active(ctl_device *d, const uint8_t *blob, size_t len, uint32_t crc,
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
        result = ctl_check_table(d, blob, len, &info);
        if (result == GT_OK) activate(d, blob, len, crc, &info);
    }
    return result;
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
        torque = (uint16_t)ctl_get_le(blob + records, CTL_LIMITS_TORQUE);
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
        mins[k] = (uint16_t)ctl_get_le(r + 1, 2);
        maxs[k] = (uint16_t)ctl_get_le(r + 3, 2);
        if (ids[k] > DXL_MAX_ID || mins[k] >= maxs[k] || maxs[k] > ctl_top_tick()) {
            return CTL_UPLOAD_RESULT_BAD_ROBOT_LIMITS;
        }
        for (uint8_t i = 0; i < k; i++) {
            if (ids[i] == ids[k]) return CTL_UPLOAD_RESULT_BAD_ROBOT_LIMITS;
        }
    }
    ctl_stop_motion(d);
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

void ctl_commit(ctl_device *d, uint8_t what)
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
                     ? ctl_check_table(d, staging(d), len, &info)
                 : d->lib.store_kind == CTL_UPLOAD_COMMIT_PROGRAM
                     ? check_program(d, staging(d), len)
                     : CTL_UPLOAD_RESULT_OK;
        if (result == GT_OK) {
            result = lib_store_blob(&d->lib, d->table_changed != 0, staging(d), (uint16_t)len);
        }
    } else {
        result = ctl_load_active(d, staging(d), len, crc, what);
    }
    set_reg(d, CTL_ERROR_FLAGS, 2, reg(d, CTL_ERROR_FLAGS, 2) & ~(uint32_t)UPLOAD_FLAGS);
    if (result != GT_OK) ctl_raise_flags(d, upload_flag(result));
    if ((what == CTL_UPLOAD_COMMIT_LIBRARY_STORE || what == CTL_UPLOAD_COMMIT_LIBRARY_DELETE) &&
        lib_note(&d->lib, result)) {
        ctl_raise_flags(d, CTL_ERROR_FLAGS_LIBRARY);
    }
    d->regs[CTL_UPLOAD_RESULT] = result;
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
uint8_t ctl_stage_chunk(ctl_device *d, uint8_t start, const uint8_t *data, size_t n,
                        bool apply)
{
    uint32_t offset = ctl_value_after(d, CTL_UPLOAD_OFFSET, 2, start, data, n);
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
        ctl_raise_flags(d, CTL_ERROR_FLAGS_UPLOAD_LENGTH);
        return DXL_ERR_RANGE;
    }
    if (!apply && lib_saving(&d->lib, false, NULL) == CTL_STORE_STATE_LIBRARY) {
        /* a library store reads the staged blob until it ends */
        d->regs[CTL_UPLOAD_RESULT] = CTL_UPLOAD_RESULT_STORE_BUSY;
        ctl_raise_flags(d, CTL_ERROR_FLAGS_LIBRARY);
        return DXL_ERR_RANGE;
    }
    if (!apply && over_active && table_in_use(d)) {
        d->regs[CTL_UPLOAD_RESULT] = CTL_UPLOAD_RESULT_NO_ROOM_WHILE_PLAYING;
        ctl_raise_flags(d, CTL_ERROR_FLAGS_UPLOAD_LENGTH);
        return DXL_ERR_RANGE;
    }
    if (apply && over_active) drop_active(d);
    if (apply && lo == 0) d->staged_end = (uint16_t)(hi + 1);
    else if (apply && hi + 1 > d->staged_end) d->staged_end = (uint16_t)(hi + 1);
    return 0;
}

/* RESET: registers and roster to their defaults, motion stopped, errors cleared; the
 * active table stays (and the roster follows it again). */
void ctl_reset_device(ctl_device *d)
{
    ctl_defaults(d);
    bus_clear_faults(&d->bus);
    if (ctl_active_is_program(d)) {
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
    ctl_sync_bus_roster(d);
}

/* ---- public ---------------------------------------------------------------------------- */

void ctl_set_tables(ctl_device *d, size_t arena, uint16_t capacity)
{
    ctl_stop_motion(d);
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
    uint8_t what = ctl_is_program(table, len) ? CTL_UPLOAD_COMMIT_PROGRAM : CTL_UPLOAD_COMMIT_TABLE;
    return ctl_load_active(d, table, len, crc32_compute(table, len), what) == GT_OK;
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
        ctl_put_le(r + 1, 2, d->bus.lim_min[k]);
        ctl_put_le(r + 3, 2, d->bus.lim_max[k]);
    }
    if (len > records) ctl_put_le(out + records, CTL_LIMITS_TORQUE, torque);
    return len;
}

bool ctl_limits_changed(ctl_device *d)
{
    bool changed = d->limits_changed != 0;
    d->limits_changed = 0;
    return changed;
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
