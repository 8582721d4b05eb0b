/* The controller as a device on the PC link: packets in, status packets out, each
 * instruction dispatched to the control table (ctl_regs.c), and the device's life
 * cycle and links. The rest lives in ctl_regs.c (registers), ctl_pages.c (the window),
 * ctl_upload.c (uploads, commits, the active table) and ctl_state.c (state machine and
 * safety), which share ctl_device_internal.h. */
#include "ctl_device_internal.h"

#include "dxl_packet.h"

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
            ctl_write_bytes(d, p[0], p + at + 1, p[1], now_ms);
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
            ctl_read_bytes(d, params[0], params[1], out + 5);
            ndata = params[1];
        }
        break;
    case DXL_INST_WRITE:
        error = nparams < 2 ? DXL_ERR_INSTRUCTION
                            : ctl_write_bytes(d, params[0], params + 1, nparams - 1, now_ms);
        break;
    case DXL_INST_SYNC_WRITE:
        if (broadcast) sync_write(d, params, nparams, now_ms);
        return 0;
    case DXL_INST_RESET: {
        size_t n = answer ? reply(out, cap, me, 0, 0) : 0;
        ctl_reset_device(d);
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
    ctl_defaults(d);
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

uint8_t ctl_id(const ctl_device *d)
{
    return d->regs[CTL_ID];
}
