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
}

void bus_set_roster(bus_master *b, const uint8_t *ids, uint8_t count)
{
    if (count > CTL_MAX_JOINTS) count = CTL_MAX_JOINTS;
    for (uint8_t k = 0; k < count; k++) {
        if (k >= b->count || b->ids[k] != ids[k]) {
            bus_servo zero = {0};
            b->servo[k] = zero;
            b->ids[k] = ids[k];
        }
    }
    b->count = count;
    if (b->next >= count) b->next = 0;
    /* A READ in flight whose servo has left its slot ends here, counted as unanswered
     * (against no servo): its reply, if it still comes, must not be filed under another. */
    if (b->awaiting != NO_READ &&
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
        } else if (step == STEP_READ && b->count > 0) {
            uint8_t k = b->next;
            b->next = (uint8_t)((k + 1u) % b->count);
            n = dxl_read(out, cap, b->ids[k], BUS_TELEMETRY_ADDRESS, BUS_TELEMETRY_LENGTH);
            if (n > 0) {
                b->awaiting = k;
                b->awaiting_id = b->ids[k];
                b->taken = 0;
                b->corrupt = 0;
                b->rx_len = 0;
                txn->kind = BUS_TXN_READ;
                txn->id = b->ids[k];
                txn->reply_len = BUS_REPLY_BYTES;
            }
        }
        if (n > 0) return n;
    }
    return 0;
}

static uint16_t rd16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}

static void take_reply(bus_master *b, const uint8_t *packet)
{
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

/* Look for FF FF id LEN=10 ERR d0..d7 CHK anywhere in what has come back. */
static bool scan(bus_master *b)
{
    for (uint8_t i = 0; i + BUS_REPLY_BYTES <= b->rx_len; i++) {
        const uint8_t *p = b->rx + i;
        if (p[0] != 0xFFu || p[1] != 0xFFu || p[2] != b->awaiting_id || p[3] != REPLY_LEN_FIELD) {
            continue;
        }
        if (dxl_checksum(p + 2, BUS_REPLY_BYTES - 3) != p[BUS_REPLY_BYTES - 1]) {
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
        if (b->rx_len >= BUS_REPLY_BYTES && scan(b)) return true;
    }
    return false;
}

void bus_rx_done(bus_master *b)
{
    if (b->awaiting == NO_READ) return;
    if (!b->taken) {
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
