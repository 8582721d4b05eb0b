/* The controller's window (protocol/controller.md): Window Page picks what its bytes
 * show, a page of servo records (the roster) or one of the described pages beyond them
 * (Program, Limits, Library, ...). Reads and writes of the window come here from
 * ctl_regs.c. */
#include "ctl_device_internal.h"

#include "dxl_packet.h"

/* ---- field descriptors (from the generated X-macros) -------------------------------- */

/* A field of a described window page (offset from CTL_SERVO_WINDOW in f.addr). */
typedef struct {
    uint8_t page;
    field f;
} page_field;

#define PAGE_FIELD(pg, a, s, acc, lo, hi, sg, dflt) {pg, CTL_FIELD(a, s, acc, lo, hi, sg, dflt)},
static const field servo_fields[] = {CTL_SERVO_FIELDS(CTL_FIELD)};
static const page_field page_fields[] = {CTL_PAGE_FIELDS(PAGE_FIELD)};
#undef PAGE_FIELD
#define N_SERVO_FIELDS (sizeof servo_fields / sizeof servo_fields[0])
#define N_PAGE_FIELDS (sizeof page_fields / sizeof page_fields[0])

/* ---- roster and servo window --------------------------------------------------------- */

void ctl_sync_bus_roster(ctl_device *d)
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
void ctl_record_read(const ctl_device *d, uint8_t k, uint8_t *rec)
{
    const play_joint *j = &d->roster[k];
    for (uint8_t i = 0; i < CTL_SERVO_RECORD_SIZE; i++) rec[i] = 0;
    rec[CTL_REC_ID] = j->id;
    rec[CTL_REC_REVERSE] = j->reverse;
    ctl_put_le(rec + CTL_REC_ZERO_TICK, 2, j->zero);
    ctl_put_le(rec + CTL_REC_MIN_TICK, 2, j->min);
    ctl_put_le(rec + CTL_REC_MAX_TICK, 2, j->max);
    if (k >= joint_count(d)) return;
    ctl_put_le(rec + CTL_REC_GOAL_POSITION, 2, last_goal(d, j->id));
    const bus_servo *s = bus_servo_at(&d->bus, k);
    if (s == NULL) return;
    ctl_put_le(rec + CTL_REC_PRESENT_POSITION, 2, s->position);
    ctl_put_le(rec + CTL_REC_PRESENT_SPEED, 2, s->speed);
    ctl_put_le(rec + CTL_REC_PRESENT_LOAD, 2, s->load);
    rec[CTL_REC_PRESENT_VOLTAGE] = s->voltage;
    rec[CTL_REC_PRESENT_TEMPERATURE] = s->temperature;
    rec[CTL_REC_SERVO_ERROR] = s->error;
    rec[CTL_REC_ERROR_COUNT] = s->error_count;
    rec[CTL_REC_TIMEOUT_COUNT] = s->timeout_count;
}

void ctl_record_write(play_joint *roster, uint8_t k, const uint8_t *rec)
{
    play_joint *j = &roster[k];
    j->id = rec[CTL_REC_ID];
    j->reverse = rec[CTL_REC_REVERSE];
    j->zero = (uint16_t)ctl_get_le(rec + CTL_REC_ZERO_TICK, 2);
    j->min = (uint16_t)ctl_get_le(rec + CTL_REC_MIN_TICK, 2);
    j->max = (uint16_t)ctl_get_le(rec + CTL_REC_MAX_TICK, 2);
}

void ctl_roster_defaults(ctl_device *d)
{
    uint8_t rec[CTL_SERVO_RECORD_SIZE] = {0};
    for (size_t i = 0; i < N_SERVO_FIELDS; i++) {
        ctl_put_le(rec + servo_fields[i].addr, servo_fields[i].size, (uint32_t)servo_fields[i].def);
    }
    for (uint8_t k = 0; k < CTL_MAX_JOINTS; k++) ctl_record_write(d->roster, k, rec);
}

/* The highest position tick: the servo window's Max Tick range says it. */
uint16_t ctl_top_tick(void)
{
    for (size_t i = 0; i < N_SERVO_FIELDS; i++) {
        if (servo_fields[i].addr == CTL_REC_MAX_TICK) return (uint16_t)servo_fields[i].max;
    }
    return 0;
}

/* Check the servo-window part of a write; the record k as it would become goes to rec. */
bool ctl_check_record(const ctl_device *d, uint8_t slot, uint8_t page, uint8_t start,
                      const uint8_t *data, size_t n, uint8_t *rec)
{
    uint16_t base = (uint16_t)(CTL_SERVO_WINDOW + slot * CTL_SERVO_RECORD_SIZE);
    ctl_record_read(d, (uint8_t)(page * CTL_SERVO_RECORDS + slot), rec);
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
        if (!ctl_in_range(sf, ctl_get_le(rec + sf->addr, sf->size))) return false;
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
const field *ctl_page_field_at(uint8_t page, uint8_t offset)
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
uint32_t ctl_page_value(const ctl_device *d, uint8_t page, uint8_t addr)
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
            if (play_finished(&d->player) && ctl_active_is_program(d)) {
                return CTL_PROGRAM_STATE_DONE;
            }
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
        const field *f = ctl_page_field_at(page, (uint8_t)(a - CTL_SERVO_WINDOW));
        if (f == NULL || (f->access & CTL_ACCESS_W) == 0) return DXL_ERR_RANGE;
        uint8_t at = (uint8_t)(CTL_SERVO_WINDOW + f->addr);
        if (f->size > 4) { /* a byte string: any bytes */
            a = (uint16_t)(at + f->size - 1u);
            continue;
        }
        uint8_t now[4];
        ctl_put_le(now, f->size, ctl_page_value(d, page, at));
        for (uint8_t i = 0; i < f->size; i++) {
            uint16_t b = (uint16_t)(at + i);
            if (b >= start && b < end) now[i] = data[b - start];
        }
        uint32_t value = ctl_get_le(now, f->size);
        if (!ctl_in_range(f, value)) return DXL_ERR_RANGE;
        a = (uint16_t)(at + f->size - 1u);
    }
    if (page == CTL_PAGE_LIBRARY && !lib_page_write(&d->lib, start, data, (uint16_t)n, apply)) {
        return DXL_ERR_RANGE;
    }
    return 0;
}

uint8_t ctl_write_window(ctl_device *d, uint8_t start, const uint8_t *data, size_t n, bool apply)
{
    uint8_t page = byte_after(d, CTL_WINDOW_PAGE, start, data, n);
    if (!page_known(page)) return DXL_ERR_RANGE;
    if (start + n <= CTL_SERVO_WINDOW) return 0;
    if (page == CTL_PAGE_UPLOAD_DATA_2) return 0; /* table bytes: ctl_stage_chunk checks them */
    if (page >= CTL_SERVO_PAGES) return write_page(d, page, start, data, n, apply);
    for (uint8_t slot = 0; slot < CTL_SERVO_RECORDS; slot++) {
        uint16_t base = (uint16_t)(CTL_SERVO_WINDOW + slot * CTL_SERVO_RECORD_SIZE);
        if (base >= start + n || base + CTL_SERVO_RECORD_SIZE <= start) continue;
        uint8_t rec[CTL_SERVO_RECORD_SIZE];
        if (!ctl_check_record(d, slot, page, start, data, n, rec)) return DXL_ERR_RANGE;
        if (!ctl_within_robot(d, rec[CTL_REC_ID], (uint16_t)ctl_get_le(rec + CTL_REC_MIN_TICK, 2),
                              (uint16_t)ctl_get_le(rec + CTL_REC_MAX_TICK, 2))) {
            return DXL_ERR_RANGE;
        }
        if (apply) ctl_record_write(d->roster, (uint8_t)(page * CTL_SERVO_RECORDS + slot), rec);
    }
    return 0;
}
