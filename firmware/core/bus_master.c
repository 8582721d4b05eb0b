#include "bus_master.h"

#include "ax12_table.h"
#include "dxl_packet.h"

#define NO_READ 0xFFu
#define STEP_TORQUE 0u
#define STEP_GOALS 1u
#define STEP_READ 2u
#define STEP_DONE 3u
#define REPLY_LEN_FIELD (BUS_TELEMETRY_LENGTH + 2)
/* Where register ``reg`` sits in the telemetry reply's data. */
#define TELEMETRY_AT(reg) ((reg) - BUS_TELEMETRY_ADDRESS)
/* The status packet: FF FF id len err, the data, checksum. */
typedef char bus_reply_bytes_match[(BUS_REPLY_BYTES == BUS_TELEMETRY_LENGTH + 6) ? 1 : -1];
/* What the pending reply answers, and the data bytes its status packet carries. */
#define AWAIT_TELEMETRY 0u
#define AWAIT_LIMITS 1u
#define AWAIT_ACK 2u
#define AWAIT_AUDIT 3u
#define AWAIT_TORQUE 4u
#define AWAIT_AUDIT_TORQUE 5u
/* A status packet: FF FF ID LEN ERR, the data, CHK. */
#define STATUS_OVERHEAD (BUS_REPLY_BYTES - BUS_TELEMETRY_LENGTH)
#define LIMITS_BYTES (AX12_CW_ANGLE_LIMIT_SIZE + AX12_CCW_ANGLE_LIMIT_SIZE)
/* Steps of the limits check of one servo: its angle limits, then its Torque Limit. */
#define LIM_READ 0u
#define LIM_WRITE 1u
#define LIM_VERIFY 2u
#define LIM_T_READ 3u
#define LIM_T_WRITE 4u
#define LIM_T_VERIFY 5u

static uint8_t await_data_bytes(uint8_t kind)
{
    if (kind == AWAIT_TELEMETRY) return BUS_TELEMETRY_LENGTH;
    if (kind == AWAIT_ACK) return 0u;
    if (kind == AWAIT_TORQUE || kind == AWAIT_AUDIT_TORQUE) return AX12_TORQUE_LIMIT_SIZE;
    return LIMITS_BYTES;
}

static bool has_torque(const bus_master *b)
{
    return b->lim_torque != BUS_TORQUE_LIMIT_NONE;
}

static bool is_audit(uint8_t kind)
{
    return kind == AWAIT_AUDIT || kind == AWAIT_AUDIT_TORQUE;
}

static bool torque_phase(const bus_master *b)
{
    return b->lim_phase >= LIM_T_READ;
}

size_t bus_master_size(void)
{
    return sizeof(bus_master);
}

void bus_init(bus_master *b)
{
    bus_master zero = {0};
    *b = zero;
    b->awaiting = NO_READ;
    b->step = STEP_DONE;
    b->lim_torque = BUS_TORQUE_LIMIT_NONE;
}

void bus_set_roster(bus_master *b, const uint8_t *ids, uint8_t count)
{
    if (count > CTL_MAX_JOINTS) count = CTL_MAX_JOINTS;
    bool changed = count != b->count;
    for (uint8_t k = 0; k < count; k++) {
        if (k >= b->count || b->ids[k] != ids[k]) {
            bus_servo zero = {0};
            b->servo[k] = zero;
            b->ids[k] = ids[k];
            changed = true;
        }
    }
    b->count = count;
    if (b->next >= count) b->next = 0;
    /* a servo may have been swapped for another with other angle limits */
    if (changed) bus_recheck_limits(b);
    /* A READ in flight whose servo has left its slot ends here, counted as unanswered
     * (against no servo): its reply, if it still comes, must not be filed under another. */
    if (b->awaiting != NO_READ && b->awaiting_kind == AWAIT_TELEMETRY &&
        (b->awaiting >= count || b->ids[b->awaiting] != b->awaiting_id)) {
        if (!b->taken) {
            b->timeouts++;
            if (b->corrupt) b->errors++;
        }
        b->awaiting = NO_READ;
        b->rx_len = 0;
    }
}

void bus_request_torque(bus_master *b, uint8_t request)
{
    b->torque = request;
}

void bus_begin_tick(bus_master *b)
{
    if (b->awaiting != NO_READ) bus_rx_done(b);
    b->step = STEP_TORQUE;
}

static size_t torque_packet(bus_master *b, const uint8_t *ids, uint8_t count, uint8_t *out,
                            size_t cap)
{
    uint8_t request = b->torque;
    b->torque = BUS_TORQUE_NONE;
    if (request == BUS_TORQUE_OFF) {
        uint8_t off = 0;
        return dxl_write(out, cap, DXL_BROADCAST_ID, AX12_TORQUE_ENABLE, &off, 1);
    }
    if (request == BUS_TORQUE_ON && count > 0) {
        uint8_t on[CTL_MAX_JOINTS];
        for (uint8_t k = 0; k < count; k++) on[k] = 1;
        return dxl_sync_write(out, cap, AX12_TORQUE_ENABLE, 1, ids, on, count);
    }
    return 0;
}

static size_t goals_packet(const uint8_t *ids, const uint16_t *goals, const uint16_t *speeds,
                           uint8_t count, uint8_t *out, size_t cap)
{
    uint8_t data[4 * CTL_MAX_JOINTS];
    for (uint8_t k = 0; k < count; k++) {
        data[4 * k + 0] = (uint8_t)(goals[k] & 0xFFu);
        data[4 * k + 1] = (uint8_t)(goals[k] >> 8);
        data[4 * k + 2] = (uint8_t)(speeds[k] & 0xFFu);
        data[4 * k + 3] = (uint8_t)(speeds[k] >> 8);
    }
    return dxl_sync_write(out, cap, AX12_GOAL_POSITION, 4, ids, data, count);
}

static void await_reply(bus_master *b, uint8_t slot, uint8_t id, uint8_t kind, bus_txn *txn)
{
    b->awaiting = slot;
    b->awaiting_id = id;
    b->awaiting_kind = kind;
    b->taken = 0;
    b->corrupt = 0;
    b->rx_len = 0;
    txn->kind = BUS_TXN_READ;
    txn->id = id;
    txn->reply_len = (uint8_t)(STATUS_OVERHEAD + await_data_bytes(kind));
}

static bool limits_pending(const bus_master *b)
{
    return b->lim_next < b->lim_count;
}

/* Whether this tick's READ belongs to the limits check: every other tick while it runs
 * (every tick when there is no roster to poll). */
static bool limits_turn(bus_master *b)
{
    if (!limits_pending(b)) return false;
    b->lim_turn ^= 1u;
    return b->lim_turn != 0 || b->count == 0;
}

/* Whether this tick's READ re-reads one verified servo's angle limits (the audit). */
static bool audit_turn(bus_master *b)
{
    if (b->lim_count == 0 || limits_pending(b) || b->lim_failed) return false;
    if (++b->lim_audit_wait < BUS_LIMIT_AUDIT_TICKS) return false;
    b->lim_audit_wait = 0;
    return true;
}

/* A READ of servo slot k's angle limits (torque false) or Torque Limit, awaited as kind. */
static size_t limits_read_packet(bus_master *b, uint8_t k, bool torque, uint8_t kind,
                                 uint8_t *out, size_t cap, bus_txn *txn)
{
    uint8_t id = b->lim_id[k];
    size_t n = torque ? dxl_read(out, cap, id, AX12_TORQUE_LIMIT, AX12_TORQUE_LIMIT_SIZE)
                      : dxl_read(out, cap, id, AX12_CW_ANGLE_LIMIT, LIMITS_BYTES);
    if (n > 0) await_reply(b, k, id, kind, txn);
    return n;
}

static size_t audit_packet(bus_master *b, uint8_t *out, size_t cap, bus_txn *txn)
{
    uint8_t k = (uint8_t)(b->lim_audit_k % b->lim_count);
    bool torque = b->lim_audit_torque != 0;
    return limits_read_packet(b, k, torque, torque ? AWAIT_AUDIT_TORQUE : AWAIT_AUDIT, out,
                              cap, txn);
}

/* The next step of the limits check: READ the angle limits or Torque Limit, or WRITE the
 * robot's. */
static size_t limits_packet(bus_master *b, uint8_t *out, size_t cap, bus_txn *txn)
{
    uint8_t k = b->lim_next;
    uint8_t id = b->lim_id[k];
    bool torque = torque_phase(b);
    if (b->lim_phase == LIM_WRITE || b->lim_phase == LIM_T_WRITE) {
        uint16_t first = torque ? b->lim_torque : b->lim_min[k];
        uint8_t data[LIMITS_BYTES] = {(uint8_t)(first & 0xFFu), (uint8_t)(first >> 8),
                                      (uint8_t)(b->lim_max[k] & 0xFFu),
                                      (uint8_t)(b->lim_max[k] >> 8)};
        size_t n = torque ? dxl_write(out, cap, id, AX12_TORQUE_LIMIT, data,
                                      AX12_TORQUE_LIMIT_SIZE)
                          : dxl_write(out, cap, id, AX12_CW_ANGLE_LIMIT, data, LIMITS_BYTES);
        if (n > 0) {
            if (!torque) b->lim_writes++; /* EEPROM writes; Torque Limit is RAM */
            await_reply(b, k, id, AWAIT_ACK, txn);
        }
        return n;
    }
    return limits_read_packet(b, k, torque, torque ? AWAIT_TORQUE : AWAIT_LIMITS, out, cap,
                              txn);
}

size_t bus_next(bus_master *b, const uint8_t *ids, const uint16_t *goals,
                const uint16_t *speeds, uint8_t count, uint8_t *out, size_t cap, bus_txn *txn)
{
    txn->kind = BUS_TXN_WRITE;
    txn->id = DXL_BROADCAST_ID;
    txn->reply_len = 0;
    if (count > CTL_MAX_JOINTS) count = CTL_MAX_JOINTS;
    if (b->awaiting != NO_READ) bus_rx_done(b);
    while (b->step != STEP_DONE) {
        uint8_t step = b->step++;
        size_t n = 0;
        if (step == STEP_TORQUE && b->torque != BUS_TORQUE_NONE) {
            n = torque_packet(b, count > 0 ? ids : b->ids, count > 0 ? count : b->count, out, cap);
        } else if (step == STEP_GOALS && count > 0) {
            n = goals_packet(ids, goals, speeds, count, out, cap);
        } else if (step == STEP_READ && limits_turn(b)) {
            n = limits_packet(b, out, cap, txn);
        } else if (step == STEP_READ && audit_turn(b)) {
            n = audit_packet(b, out, cap, txn);
        } else if (step == STEP_READ && b->count > 0) {
            uint8_t k = b->next;
            b->next = (uint8_t)((k + 1u) % b->count);
            n = dxl_read(out, cap, b->ids[k], BUS_TELEMETRY_ADDRESS, BUS_TELEMETRY_LENGTH);
            if (n > 0) await_reply(b, k, b->ids[k], AWAIT_TELEMETRY, txn);
        }
        if (n > 0) return n;
    }
    return 0;
}

static uint16_t rd16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}

/* The check of servo lim_next is over (verified, or failed): on to the next one. */
static void limits_advance(bus_master *b, bool failed)
{
    if (failed) b->lim_failed = 1;
    b->lim_next++;
    b->lim_phase = LIM_READ;
    b->lim_tries = 0;
    b->lim_silent = 0;
}


/* Whether data (the reply to a READ of slot k's Torque Limit, or of its angle limits)
 * holds the robot's. */
static bool holds(const bus_master *b, uint8_t k, bool torque, const uint8_t *data)
{
    if (torque) return rd16(data) == b->lim_torque;
    return rd16(data) == b->lim_min[k] && rd16(data + 2) == b->lim_max[k];
}

/* A READ of the angle limits (data[0..4)) or Torque Limit (data[0..2)) came back. */
static void limits_read(bus_master *b, const uint8_t *data)
{
    bool torque = torque_phase(b);
    uint8_t first = torque ? LIM_T_READ : LIM_READ;
    b->lim_silent = 0;
    if (holds(b, b->lim_next, torque, data)) {
        if (torque || !has_torque(b)) {
            limits_advance(b, false);
        } else {
            b->lim_phase = LIM_T_READ; /* angle limits verified: now its Torque Limit */
            b->lim_tries = 0;
        }
    } else if (b->lim_phase == first) {
        b->lim_phase = first + 1u; /* differs: write once, then read back */
    } else if (++b->lim_tries >= BUS_LIMIT_TRIES) {
        limits_advance(b, true); /* written again and again, never taken */
    } else {
        b->lim_phase = first + 1u;
    }
}

/* The pending limits transaction is over: answered (data), or not (NULL). */
static void limits_done(bus_master *b, const uint8_t *data)
{
    if (b->awaiting != b->lim_next || !limits_pending(b)) return; /* the check restarted */
    if (b->awaiting_kind == AWAIT_ACK) {
        /* the read back decides, acknowledged or not */
        b->lim_phase = torque_phase(b) ? LIM_T_VERIFY : LIM_VERIFY;
    } else if (data != NULL) {
        limits_read(b, data);
    } else if (++b->lim_silent >= BUS_LIMIT_SILENT) {
        limits_advance(b, true); /* the same READ is sent again meanwhile */
    }
}

/* An audit READ came back with data: on to this servo's Torque Limit or the next servo,
 * or, if what it read changed, check it (and the servos after it) again. */
static void audit_done(bus_master *b, const uint8_t *data)
{
    uint8_t k = b->awaiting;
    bool torque = b->awaiting_kind == AWAIT_AUDIT_TORQUE;
    if (k >= b->lim_count || limits_pending(b) || b->lim_id[k] != b->awaiting_id) return;
    b->lim_audit_torque = 0;
    if (holds(b, k, torque, data)) {
        if (!torque && has_torque(b)) b->lim_audit_torque = 1;
        else b->lim_audit_k = (uint8_t)((k + 1u) % b->lim_count);
        return;
    }
    b->lim_next = k;
    b->lim_phase = torque ? LIM_T_WRITE : LIM_WRITE;
    b->lim_tries = 0;
    b->lim_silent = 0;
}

static void take_reply(bus_master *b, const uint8_t *packet)
{
    if (b->awaiting_kind != AWAIT_TELEMETRY) {
        b->taken = 1;
        if (is_audit(b->awaiting_kind)) audit_done(b, packet + 5);
        else limits_done(b, packet + 5);
        return;
    }
    bus_servo *s = &b->servo[b->awaiting];
    const uint8_t *data = packet + 5;
    s->error = packet[4];
    if (s->error != 0 && s->error_count < 0xFFu) s->error_count++;
    s->position = rd16(data + TELEMETRY_AT(AX12_PRESENT_POSITION));
    s->speed = rd16(data + TELEMETRY_AT(AX12_PRESENT_SPEED));
    s->load = rd16(data + TELEMETRY_AT(AX12_PRESENT_LOAD));
    s->voltage = data[TELEMETRY_AT(AX12_PRESENT_VOLTAGE)];
    s->temperature = data[TELEMETRY_AT(AX12_PRESENT_TEMPERATURE)];
    s->missed = 0;
    s->fresh = 1;
    b->taken = 1;
    b->reads++;
}

/* Look for FF FF id LEN ERR data CHK anywhere in what has come back (LEN = data + 2). */
static bool scan(bus_master *b)
{
    uint8_t ndata = await_data_bytes(b->awaiting_kind);
    uint8_t bytes = (uint8_t)(STATUS_OVERHEAD + ndata);
    for (uint8_t i = 0; i + bytes <= b->rx_len; i++) {
        const uint8_t *p = b->rx + i;
        if (p[0] != 0xFFu || p[1] != 0xFFu || p[2] != b->awaiting_id || p[3] != ndata + 2u) {
            continue;
        }
        if (dxl_checksum(p + 2, bytes - 3u) != p[bytes - 1u]) {
            b->corrupt = 1;
            continue;
        }
        take_reply(b, p);
        return true;
    }
    return false;
}

bool bus_rx(bus_master *b, const uint8_t *data, size_t len)
{
    if (b->awaiting == NO_READ || b->taken) return b->taken != 0;
    for (size_t i = 0; i < len; i++) {
        if (b->rx_len == BUS_RX_BUFFER) { /* keep the newest bytes */
            for (uint8_t k = 1; k < BUS_RX_BUFFER; k++) b->rx[k - 1] = b->rx[k];
            b->rx_len--;
        }
        b->rx[b->rx_len++] = data[i];
        if (scan(b)) return true;
    }
    return false;
}

void bus_rx_done(bus_master *b)
{
    if (b->awaiting == NO_READ) return;
    if (b->awaiting_kind != AWAIT_TELEMETRY) {
        /* an unanswered audit READ is asked again at the next audit */
        if (!b->taken && !is_audit(b->awaiting_kind)) limits_done(b, NULL);
    } else if (!b->taken) {
        bus_servo *s = &b->servo[b->awaiting];
        if (s->timeout_count < 0xFFu) s->timeout_count++;
        if (s->missed < 0xFFu) s->missed++;
        b->timeouts++;
        if (b->corrupt) b->errors++;
    }
    b->awaiting = NO_READ;
    b->rx_len = 0;
}

void bus_clear_faults(bus_master *b)
{
    for (uint8_t k = 0; k < CTL_MAX_JOINTS; k++) {
        b->servo[k].error = 0;
        b->servo[k].missed = 0;
    }
}

void bus_set_limits(bus_master *b, const uint8_t *ids, const uint16_t *mins,
                    const uint16_t *maxs, uint8_t count)
{
    if (count > CTL_MAX_JOINTS) count = CTL_MAX_JOINTS;
    for (uint8_t k = 0; k < count; k++) {
        b->lim_id[k] = ids[k];
        b->lim_min[k] = mins[k];
        b->lim_max[k] = maxs[k];
    }
    b->lim_count = count;
    b->lim_torque = BUS_TORQUE_LIMIT_NONE;
    bus_recheck_limits(b);
}

void bus_set_torque_limit(bus_master *b, uint16_t torque)
{
    b->lim_torque = torque;
    bus_recheck_limits(b);
}

uint16_t bus_torque_limit(const bus_master *b)
{
    return b->lim_torque;
}

void bus_recheck_limits(bus_master *b)
{
    /* a reply still due belongs to the old check: it must not count for the new one */
    if (b->awaiting != NO_READ && b->awaiting_kind != AWAIT_TELEMETRY) {
        b->awaiting = NO_READ;
        b->rx_len = 0;
    }
    b->lim_next = 0;
    b->lim_phase = LIM_READ;
    b->lim_tries = 0;
    b->lim_silent = 0;
    b->lim_failed = 0;
    b->lim_audit_torque = 0;
}

uint8_t bus_limits_state(const bus_master *b)
{
    if (b->lim_count == 0) return CTL_LIMITS_STATE_NONE;
    if (limits_pending(b)) return CTL_LIMITS_STATE_APPLYING;
    return b->lim_failed ? CTL_LIMITS_STATE_FAILED : CTL_LIMITS_STATE_VERIFIED;
}

uint8_t bus_limits_count(const bus_master *b)
{
    return b->lim_count;
}

bool bus_limits_of(const bus_master *b, uint8_t id, uint16_t *min, uint16_t *max)
{
    for (uint8_t k = 0; k < b->lim_count; k++) {
        if (b->lim_id[k] == id) {
            *min = b->lim_min[k];
            *max = b->lim_max[k];
            return true;
        }
    }
    return false;
}

uint16_t bus_limit_writes(const bus_master *b)
{
    return b->lim_writes;
}

uint8_t bus_roster_count(const bus_master *b)
{
    return b->count;
}

const bus_servo *bus_servo_at(const bus_master *b, uint8_t k)
{
    return k < b->count ? &b->servo[k] : NULL;
}

uint16_t bus_reads(const bus_master *b)
{
    return b->reads;
}

uint16_t bus_timeouts(const bus_master *b)
{
    return b->timeouts;
}

uint16_t bus_errors(const bus_master *b)
{
    return b->errors;
}
