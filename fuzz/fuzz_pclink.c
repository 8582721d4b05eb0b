/* libFuzzer target: the controller's PC-link device and control loop
 * (firmware/core/ctl_*.c with the parser, gait tables, player, safety and bus master
 * behind it), driven the way the firmware's main loop drives it. The gait library's store
 * is pclink_store_model.c; the tables, programs and bus replies built from the input are
 * pclink_builders.c.
 *
 * The input is a program: each step takes an opcode byte and its operands from the
 * input (missing bytes read as 0). Steps: raw bytes on the PC link; a well-formed packet
 * (right checksum) with any ID, instruction and parameters; register and servo-window
 * WRITEs; a gait table built from the input and uploaded chunk by chunk as the host does
 * (optionally damaged or cut short) and committed; a commit of whatever is staged with its
 * true CRC (so gait-table validation sees arbitrary bytes); a program (protocol/program.md)
 * built from the input, optionally damaged (its own CRC made right again or not), uploaded
 * and committed as PROGRAM; commands; RESET; the passage of
 * time and a control tick; the device's next bus packet; the reply to the READ in flight
 * (correct, damaged, echoed, garbage, or none), possibly after PC packets changed the
 * roster; a whole tick's bus schedule; a playback register; a power cycle (the table the
 * store kept is loaded again, or rejected if its bytes went bad); a gait-library store,
 * delete or play through the Library page (on a three-slot library in RAM that survives
 * power cycles; a store or delete may, as on the CM-530, write in the background over a
 * few control ticks, and a power cut then leaves the slot as it was); the robot's buttons for a tick (speed, steering, serpenoid, safety settings).
 * fuzz/seeds.py writes seed programs in this language (fuzz/corpus/fuzz_pclink/seed-*). PC packets, ticks and bus transactions interleave freely, as they do
 * in the firmware's main loop.
 *
 * Invariants, checked after every step (violations abort, which libFuzzer reports):
 *  - every reply is one well-formed status packet from the controller's ID at the time
 *    the packet arrived, within the caller's buffer; nothing answers a broadcast or
 *    another ID; Status Return Level is honoured; READ returns the length asked for;
 *  - PC Packets + PC Errors count every parser event exactly once;
 *  - the active table (or program) always validates and its registers (size, CRC)
 *    describe it; it never disappears, and it changes only by a commit that reported OK
 *    with exactly the staged bytes; a program commit reports what prog_validate finds;
 *  - State always says what the player is doing;
 *  - every bus packet is a well-formed instruction; a READ is the telemetry READ of one
 *    servo with the right reply length; goals go out only after a tick that was moving,
 *    each within the limits in force for its joint at that tick (the table header's in
 *    table mode, the program's joint records in program mode, the roster's in serpenoid
 *    mode) and never past 1023; entering SAFE with
 *    Safe Action TORQUE_OFF sends the broadcast torque-off next;
 *  - each telemetry READ the device sends ends as exactly one read or one timeout, and a
 *    correct reply is taken as a read with its values mirrored in that servo's slot; no
 *    slot ever shows what another servo said (the roster may change mid-READ);
 *  - while a library write runs in the background, no chunk, commit or play lands (each
 *    is refused STORE_BUSY), the store is never asked for a second write, and the blob it
 *    reads from the staging area at the end is the one it accepted;
 *  - every loop in the harness is bounded (a stuck parser or bus schedule aborts). */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ctl_device.h"
#include "dxl_packet.h"
#include "dxl_parser.h"
#include "gt_table.h"
#include "prog_limits.h"
#include "prog_run.h"

#include "fuzz_check.h"
#include "pclink_builders.h"
#include "pclink_common.h"
#include "pclink_store_model.h"

/* Steps per input: the evolved corpus's programs have a median of 20 and a 90th percentile
 * of 128; a cap keeps the long tail from dominating the run time (docs/reliability.md). */
#define MAX_STEPS 128
#define NO_READ 0xFFu
#define STAGING (d->active + FUZZ_ARENA - FUZZ_CAPACITY)

/* ---- the world around the device ----------------------------------------------------------- */

static ctl_device *d;
static uint32_t now_ms;

/* What the last control tick decided, for checking the goals sent after it. */
static struct {
    bool valid;          /* a tick has happened since the goals were last sent */
    bool moving;         /* the state was PLAYING or SERPENOID when the tick began */
    bool entered_safe;   /* the tick entered SAFE with Safe Action TORQUE_OFF */
    bool pc_since;       /* a PC packet was handled since the tick */
    uint8_t count;
    uint8_t id[CTL_MAX_JOINTS];
    uint16_t lo[CTL_MAX_JOINTS];
    uint16_t hi[CTL_MAX_JOINTS];
} tick;

static uint16_t reg16(uint8_t addr)
{
    return (uint16_t)(d->regs[addr] | (d->regs[addr + 1] << 8));
}

static uint32_t reg32(uint8_t addr)
{
    return (uint32_t)d->regs[addr] | ((uint32_t)d->regs[addr + 1] << 8) |
           ((uint32_t)d->regs[addr + 2] << 16) | ((uint32_t)d->regs[addr + 3] << 24);
}

/* ---- invariants ---------------------------------------------------------------------------- */

/* One well-formed packet filling buf[0..n), returned as an event: header, an ID that is
 * not FF, LEN = n - 4, the checksum (what a parser reports for exactly these bytes, and
 * nothing else), checked in place rather than fed through a parser byte by byte. */
static dxl_event parse_one(const uint8_t *buf, size_t n)
{
    CHECK(n >= 6 && n <= DXL_MAX_PACKET);
    CHECK(buf[0] == DXL_HEADER_BYTE && buf[1] == DXL_HEADER_BYTE && buf[2] != DXL_HEADER_BYTE);
    CHECK(buf[3] == n - 4u && dxl_checksum(buf + 2, n - 3u) == buf[n - 1u]);
    dxl_event ev = {DXL_EVENT_PACKET, buf[2], buf[4], (uint8_t)(n - 6u), buf + 5, buf,
                    (uint16_t)n};
    return ev;
}

static void check_reply(const uint8_t *out, size_t n, size_t cap, uint8_t from_id)
{
    if (n == 0) return;
    CHECK(n <= cap && n <= CTL_PC_REPLY_MAX);
    dxl_event ev = parse_one(out, n);
    CHECK(ev.id == from_id && from_id <= DXL_MAX_ID);
    CHECK((ev.code & 0x80u) == 0); /* only defined error bits */
}

static struct {
    uint16_t len;
    uint8_t bytes[FUZZ_CAPACITY];
} snapshot, flash; /* the active table as last seen; what the app would have persisted */

#define KNOWN_FLAGS                                                                           \
    (CTL_ERROR_FLAGS_UPLOAD_LENGTH | CTL_ERROR_FLAGS_UPLOAD_CRC | CTL_ERROR_FLAGS_UPLOAD_LAYOUT | \
     CTL_ERROR_FLAGS_UPLOAD_TOO_BIG | CTL_ERROR_FLAGS_SERVO_ERROR | CTL_ERROR_FLAGS_BUS_LOSS |    \
     CTL_ERROR_FLAGS_LINK_LOSS | CTL_ERROR_FLAGS_REFUSED | CTL_ERROR_FLAGS_LIMITS |               \
     CTL_ERROR_FLAGS_PROGRAM | CTL_ERROR_FLAGS_LIBRARY)

/* What validating the snapshot's bytes gave, so the checks after every step recompute it
 * (a CRC and a validation of up to 2 KB) only when the active table's bytes change. */
static struct {
    bool known;
    bool program; /* the bytes are a program, not a table */
    uint32_t crc;
    gt_info info;
} facts;

static bool is_program(const uint8_t *blob, size_t len)
{
    return len >= 4 && blob[0] == 'S' && blob[1] == 'N' && blob[2] == 'K' && blob[3] == 'P';
}

static void take_snapshot(void)
{
    snapshot.len = d->active_len;
    memcpy(snapshot.bytes, d->active, d->active_len);
    facts.known = false;
}

static void check_state(void)
{
    uint8_t state = ctl_state(d);
    uint8_t mode = play_mode(&d->player);
    CHECK(state <= CTL_STATE_SAFE);
    CHECK((state == CTL_STATE_PLAYING) == (mode == PLAY_MODE_TABLE || mode == PLAY_MODE_PROGRAM));
    CHECK((state == CTL_STATE_SERPENOID) == (mode == PLAY_MODE_SERPENOID));
    if (state == CTL_STATE_PLAYING) CHECK(d->active_len > 0);
    CHECK((ctl_error_flags(d) & ~(uint16_t)KNOWN_FLAGS) == 0);
    CHECK(d->regs[CTL_JOINT_COUNT] <= CTL_MAX_JOINTS);
    CHECK(bus_roster_count(&d->bus) == d->regs[CTL_JOINT_COUNT]);
    CHECK(d->staged_end <= d->capacity && d->capacity <= FUZZ_CAPACITY);
    /* the window only ever shows a servo page or a described one */
    uint8_t page = d->regs[CTL_WINDOW_PAGE];
    CHECK(page < CTL_SERVO_PAGES || page == CTL_PAGE_PROGRAM || page == CTL_PAGE_LIBRARY ||
          page == CTL_PAGE_UPLOAD_DATA_2 || page == CTL_PAGE_LIMITS);
    CHECK(d->refusal <= CTL_REFUSAL_REASON_SPEED);
    /* a serpenoid runs only within the limits (it never relies on clamping) */
    if (ctl_state(d) == CTL_STATE_SERPENOID) {
        CHECK(prog_check_serpenoid(d->roster, d->regs[CTL_JOINT_COUNT],
                                   (uint16_t)reg16(CTL_SERP_AMPLITUDE),
                                   (int16_t)reg16(CTL_SERP_OMEGA), (int16_t)reg16(CTL_SERP_PHI0),
                                   (int16_t)reg16(CTL_STEERING_OFFSET),
                                   (uint16_t)reg16(CTL_SPEED_SCALE)) == CTL_REFUSAL_REASON_NONE);
    }
}

/* The active table after any step: valid, described by its registers, and changed only
 * by a successful commit of exactly the staged bytes, or by playing a library slot that
 * keeps exactly those bytes as a table (which the app need not persist). */
static void check_table(void)
{
    bool changed = d->active_len != snapshot.len ||
                   memcmp(d->active, snapshot.bytes, d->active_len) != 0;
    if (d->active_len > 0) {
        CHECK(d->active_len <= FUZZ_CAPACITY);
        if (changed || !facts.known) {
            facts.program = is_program(d->active, d->active_len);
            if (facts.program) {
                CHECK(prog_validate(d->active, d->active_len, d->capacity, NULL) == PROG_OK);
                facts.info.joint_count = prog_joint_count(d->active);
                facts.info.frame_count = 0; /* what the registers show for a program */
            } else {
                CHECK(gt_validate(d->active, d->active_len, &facts.info) == GT_OK);
            }
            facts.crc = crc_of(d->active, d->active_len);
            facts.known = true;
        }
        CHECK(reg16(CTL_TABLE_SIZE) == d->active_len);
        CHECK(reg32(CTL_TABLE_CRC) == facts.crc);
        CHECK(d->regs[CTL_TABLE_JOINTS] == facts.info.joint_count);
        CHECK(reg16(CTL_TABLE_FRAMES) == facts.info.frame_count);
    } else {
        CHECK(reg16(CTL_TABLE_SIZE) == 0);
    }
    if (snapshot.len > 0) CHECK(d->active_len > 0); /* a table is never lost */
    if (changed) {
        bool persist = true;
        if (in_library(d->active, d->active_len)) {
            persist = ctl_table_changed(d); /* only if a commit in the same step asked */
        } else {
            CHECK(d->regs[CTL_UPLOAD_RESULT] == GT_OK);
            CHECK(memcmp(d->active, STAGING, d->active_len) == 0);
            CHECK(reg16(CTL_UPLOAD_LENGTH) == d->active_len);
            CHECK(ctl_table_changed(d)); /* and the app is told to persist it */
        }
        take_snapshot();
        facts.known = d->active_len > 0; /* worked out above for exactly these bytes */
        if (persist) flash = snapshot; /* as the firmware's store_save() does */
    }
}

static void check_bus(void);

static void check_all(void)
{
    check_state();
    check_table();
    check_bus();
}

/* ---- the PC link ---------------------------------------------------------------------------- */

/* Poll after every byte, as the firmware's pclink does; check replies and counters. The
 * bytes the parser shows could not make a poll report anything (dxl_parser_feed_quiet:
 * the middle of a packet) go in without one; fuzz_dxl_parser holds that to the rule. */
static void pc_bytes(const uint8_t *buf, size_t n, size_t *last_reply_len)
{
    uint8_t out[CTL_PC_REPLY_MAX];
    /* Only an event (a poll that returns true) changes the counters or the ID, so they are
     * read again after each event rather than before every poll of every byte. */
    uint16_t packets = reg16(CTL_PC_PACKETS);
    uint16_t errors = reg16(CTL_PC_ERRORS);
    uint8_t id_before = ctl_id(d);
    for (size_t i = 0; i < n; i++) {
        i += dxl_parser_feed_quiet(&d->pc, buf + i, n - i);
        if (i == n) break;
        CHECK(ctl_pc_feed(d, buf[i])); /* never full when polled after every byte */
        for (unsigned rounds = 0;; rounds++) {
            CHECK(rounds <= DXL_MAX_PACKET + 1u);
            size_t cap = sizeof out;
            size_t got = 0xDEAD;
            if (!ctl_pc_poll(d, now_ms, out, cap, &got)) {
                CHECK(got == 0);
                break;
            }
            check_reply(out, got, cap, id_before);
            tick.pc_since = true;
            if (last_reply_len != NULL) *last_reply_len = got;
            uint16_t dp = (uint16_t)(reg16(CTL_PC_PACKETS) - packets);
            uint16_t de = (uint16_t)(reg16(CTL_PC_ERRORS) - errors);
            bool reset_to_defaults = reg16(CTL_PC_PACKETS) == 0 && reg16(CTL_PC_ERRORS) == 0;
            CHECK((dp == 1 && de == 0) || (dp == 0 && de == 1) || reset_to_defaults);
            check_all();
            packets = reg16(CTL_PC_PACKETS);
            errors = reg16(CTL_PC_ERRORS);
            id_before = ctl_id(d);
        }
    }
}

/* Whether a good packet starts inside pkt (after its header) and ends before pkt does:
 * the PC link does not wait on what may be a false header, so it takes that one first
 * (dxl_parser_skip_to_hidden) and drops the start of pkt. */
static bool hides_packet(const uint8_t *pkt, size_t n)
{
    /* memchr is not instrumented: a byte-by-byte loop here cost a fifth of the run time */
    const uint8_t *q = pkt + 1;
    while (q + 4 < pkt + n && (q = memchr(q, DXL_HEADER_BYTE, (size_t)(pkt + n - 4 - q)))) {
        size_t i = (size_t)(q++ - pkt);
        if (pkt[i + 1] != DXL_HEADER_BYTE || pkt[i + 2] == DXL_HEADER_BYTE ||
            pkt[i + 3] < DXL_MIN_LEN_FIELD || pkt[i + 3] > DXL_MAX_LEN_FIELD) {
            continue;
        }
        size_t end = i + pkt[i + 3] + 4u;
        if (end < n && dxl_checksum(pkt + i + 2, end - i - 3) == pkt[end - 1]) return true;
    }
    return false;
}

/* A well-formed packet; checks whether and how it was answered. Returns whether it hid
 * another (hides_packet), so that it may not have landed as sent. */
static bool pc_packet(uint8_t id, uint8_t inst, const uint8_t *params, size_t nparams)
{
    uint8_t pkt[DXL_MAX_PACKET];
    size_t n = dxl_encode(pkt, sizeof pkt, id, inst, params, nparams);
    if (n == 0) return false;
    /* The host pauses before a transaction; after 100 ms of silence the firmware drops a
     * partial packet (pclink.c), so the packet is parsed from a clean start. */
    if (dxl_parser_pending(&d->pc) > 0) dxl_parser_reset(&d->pc);
    uint8_t me = ctl_id(d);
    uint8_t level = d->regs[CTL_STATUS_RETURN_LEVEL];
    size_t reply_len = SIZE_MAX; /* no event at all would leave this */
    if (hides_packet(pkt, n)) {
        pc_bytes(pkt, n, NULL); /* the hidden one is taken first: nothing to predict */
        return true;
    }
    pc_bytes(pkt, n, &reply_len);
    CHECK(reply_len != SIZE_MAX); /* a well-formed packet is always parsed */
    bool to_me = id == me;
    if (!to_me) {
        CHECK(reply_len == 0); /* broadcast or another device: silence */
        return false;
    }
    switch (inst) {
    case DXL_INST_PING: CHECK(reply_len == 6); break;
    case DXL_INST_READ:
        if (level == 0) CHECK(reply_len == 0);
        else if (nparams == 2 && params[1] > 0 && params[0] + params[1] <= 256 &&
                 params[1] <= DXL_MAX_PARAMS)
            CHECK(reply_len == params[1] + 6u);
        else CHECK(reply_len == 6); /* the error status */
        break;
    case DXL_INST_SYNC_WRITE: CHECK(reply_len == 0); break;
    default: CHECK(reply_len == (level >= 2 ? 6 : 0)); break;
    }
    return false;
}

/* A WRITE to the controller's ID; whether its packet hid another, so that it may not
 * have landed. */
static bool write_to_me(uint8_t addr, const uint8_t *data, size_t n)
{
    uint8_t params[1 + DXL_MAX_PARAMS];
    if (n > DXL_MAX_PARAMS - 1) n = DXL_MAX_PARAMS - 1;
    params[0] = addr;
    memcpy(params + 1, data, n);
    return pc_packet(ctl_id(d), DXL_INST_WRITE, params, n + 1);
}

/* ---- uploads ----------------------------------------------------------------------------------- */

static bool commit_as(uint16_t len, uint32_t crc, uint8_t what)
{
    uint8_t c[7];
    put16(c, len);
    c[2] = (uint8_t)crc;
    c[3] = (uint8_t)(crc >> 8);
    c[4] = (uint8_t)(crc >> 16);
    c[5] = (uint8_t)(crc >> 24);
    c[6] = what;
    return write_to_me(CTL_UPLOAD_LENGTH, c, sizeof c);
}

static void commit_with(uint16_t len, uint32_t crc)
{
    commit_as(len, crc, CTL_UPLOAD_COMMIT_TABLE);
}

/* Upload as the host does: 64-byte chunks at Upload Offset, then the commit. Faults from
 * the input: a chunk skipped or damaged, the upload cut after some chunk, a wrong CRC; or
 * a table damaged before it is sent (header, limits, IDs, frames), with its own CRC made
 * right again or not, and sent correctly: then the commit must report exactly what
 * gt_validate finds, and only a table that still validates may become active. */
static void upload(src *s)
{
    static uint8_t t[FUZZ_CAPACITY];
    size_t len = make_table(s, t);
    uint8_t fault = u8(s);
    uint8_t where = u8(s);
    uint8_t flip = (uint8_t)(u8(s) | 1u);
    int expect = GT_OK;
    bool busy = store_model_busy(); /* no tick passes during the upload */
    if (fault == 5 || fault == 6) {
        t[where % len] ^= flip;
        if (fault == 6) seal(t, len); /* the table's own CRC agrees with the damage */
        gt_info info;
        expect = gt_validate(t, len, &info);
    }
    size_t chunks = (len + CTL_UPLOAD_WINDOW - 1) / CTL_UPLOAD_WINDOW;
    size_t victim = where % chunks;
    for (size_t k = 0; k < chunks; k++) {
        uint8_t data[2 + CTL_UPLOAD_WINDOW];
        size_t at = k * CTL_UPLOAD_WINDOW;
        size_t n = len - at < CTL_UPLOAD_WINDOW ? len - at : CTL_UPLOAD_WINDOW;
        put16(data, (uint16_t)at);
        memcpy(data + 2, t + at, n);
        if (k == victim && fault == 1) continue;                 /* chunk lost */
        if (k == victim && fault == 2) data[2 + where % n] ^= 0x10; /* chunk damaged */
        if (k == victim && fault == 3) return;                   /* upload cut here */
        write_to_me(CTL_UPLOAD_OFFSET, data, n + 2);
    }
    uint32_t crc = crc_of(t, len);
    if (fault == 4) crc ^= 1u;
    (void)commit_as((uint16_t)len, crc, CTL_UPLOAD_COMMIT_TABLE);
    if (busy) { /* a library store reads the staging area: no chunk or commit lands */
        CHECK(d->regs[CTL_UPLOAD_RESULT] == CTL_UPLOAD_RESULT_STORE_BUSY);
        return;
    }
    if (fault == 5 || fault == 6) {
        CHECK(d->regs[CTL_UPLOAD_RESULT] == expect);
        if (expect != GT_OK) CHECK(memcmp(d->active, t, len) != 0 || d->active_len != len);
    }
    bool sound = fault == 0 || fault > 6 || ((fault == 5 || fault == 6) && expect == GT_OK);
    if (sound) {
        /* a whole, correct upload to a listening controller always lands */
        CHECK(d->regs[CTL_UPLOAD_RESULT] == GT_OK);
        CHECK(d->active_len == len && memcmp(d->active, t, len) == 0);
    }
    if (fault == 1 || fault == 2 || fault == 4) {
        /* a damaged upload is refused (CRC-32 catches the flipped bit), a lost chunk only
         * passes if the staging area already held those very bytes */
        CHECK(d->regs[CTL_UPLOAD_RESULT] != GT_OK || memcmp(STAGING, t, len) == 0);
        if (fault != 1) CHECK(d->regs[CTL_UPLOAD_RESULT] != GT_OK);
    }
}

/* Upload a program from the input (optionally with one byte damaged, its CRC made right
 * again or not) whole, and commit it as PROGRAM: the commit must report what
 * prog_validate finds (or OUTSIDE_ROBOT_LIMITS for a sound one the robot's limits do not
 * cover), and only a program that validates may become active. */
static void upload_program(src *s)
{
    static uint8_t t[FUZZ_CAPACITY];
    size_t len = make_program(s, t);
    uint8_t fault = u8(s) % 3u;
    uint8_t where = u8(s);
    uint8_t flip = (uint8_t)(u8(s) | 1u);
    if (fault != 0) t[where % len] ^= flip;
    if (fault == 2) seal(t, len);
    uint8_t expect = prog_validate(t, len, d->capacity, NULL);
    bool busy = store_model_busy(); /* no tick passes during the upload */
    bool hidden = false; /* a chunk carried what parses as a packet of its own */
    for (size_t at = 0; at < len; at += CTL_UPLOAD_WINDOW) {
        uint8_t data[2 + CTL_UPLOAD_WINDOW];
        size_t n = len - at < CTL_UPLOAD_WINDOW ? len - at : CTL_UPLOAD_WINDOW;
        put16(data, (uint16_t)at);
        memcpy(data + 2, t + at, n);
        hidden |= write_to_me(CTL_UPLOAD_OFFSET, data, n + 2);
    }
    hidden |= commit_as((uint16_t)len, crc_of(t, len), CTL_UPLOAD_COMMIT_PROGRAM);
    /* a packet that did not land as sent leaves nothing to predict (check_table still
     * holds the active program to prog_validate) */
    if (hidden) return;
    uint8_t result = d->regs[CTL_UPLOAD_RESULT];
    if (busy) { /* a library store reads the staging area: no chunk or commit lands */
        CHECK(result == CTL_UPLOAD_RESULT_STORE_BUSY);
        return;
    }
    if (expect == PROG_OK) {
        bool limited = bus_limits_count(&d->bus) > 0;
        CHECK(result == PROG_OK || (limited && result == CTL_UPLOAD_RESULT_OUTSIDE_ROBOT_LIMITS));
    } else {
        CHECK(result == expect);
    }
    if (result == PROG_OK) CHECK(d->active_len == len && memcmp(d->active, t, len) == 0);
}

/* ---- time, ticks and the bus ------------------------------------------------------------------- */

static void do_tick(uint32_t dt)
{
    now_ms += dt;
    uint8_t before = ctl_state(d);
    ctl_tick(d, now_ms);
    lib_write_tick(d); /* as the firmware steps its flash write after the tick's bus work */
    uint8_t after = ctl_state(d);
    const play_state *p = &d->player;
    tick.valid = true;
    tick.pc_since = false;
    tick.moving = before == CTL_STATE_PLAYING || before == CTL_STATE_SERPENOID;
    tick.entered_safe = before != CTL_STATE_SAFE && after == CTL_STATE_SAFE &&
                        d->regs[CTL_SAFE_ACTION] == CTL_SAFE_ACTION_TORQUE_OFF;
    tick.count = d->out_count;
    CHECK(tick.count <= CTL_MAX_JOINTS);
    if (!tick.moving) CHECK(tick.count == 0);
    bool table_mode = before == CTL_STATE_PLAYING;
    /* check_all() after the last step validated the active table and kept what it found */
    if (table_mode) CHECK(facts.known && d->active_len == snapshot.len);
    const gt_info info = facts.info;
    for (uint8_t j = 0; j < tick.count; j++) {
        tick.id[j] = p->out_id[j];
        if (table_mode && facts.program) {
            CHECK(p->table == d->active);
            CHECK(tick.count == prog_joint_count(d->active));
            prog_joint pj = prog_joint_at(d->active, j);
            CHECK(tick.id[j] == pj.id);
            tick.lo[j] = pj.min;
            tick.hi[j] = pj.max;
        } else if (table_mode) {
            CHECK(p->table == d->active); /* the player reads the active table itself */
            CHECK(tick.count == info.joint_count);
            CHECK(tick.id[j] == gt_joint_id(d->active, &info, j));
            tick.lo[j] = gt_joint_min(d->active, &info, j);
            tick.hi[j] = gt_joint_max(d->active, &info, j);
        } else {
            const play_joint *r = &d->roster[j];
            CHECK(tick.id[j] == r->id);
            tick.lo[j] = r->min > AX12_POSITION_MAX ? AX12_POSITION_MAX : r->min;
            tick.hi[j] = r->max > AX12_POSITION_MAX ? AX12_POSITION_MAX : r->max;
            if (tick.hi[j] < tick.lo[j]) tick.hi[j] = tick.lo[j]; /* min > max: pinned */
        }
    }
}

static void check_goals(const dxl_event *ev)
{
    CHECK(tick.valid && tick.moving);
    CHECK(ev->nparams == 2u + 5u * tick.count);
    for (uint8_t j = 0; j < tick.count; j++) {
        const uint8_t *b = ev->params + 2 + 5 * j;
        uint16_t goal = (uint16_t)(b[1] | (b[2] << 8));
        CHECK(b[0] == tick.id[j]);
        CHECK(goal <= AX12_POSITION_MAX);
        CHECK(goal >= tick.lo[j] && goal <= tick.hi[j]);
    }
    tick.valid = false; /* one goals packet per tick */
}

/* The READ in flight, as the harness knows it. */
static struct {
    bool pending;
    dxl_event ev;             /* the READ (raw points into `raw`) */
    uint8_t raw[8];
    uint8_t slot;
    uint16_t reads_issued;    /* telemetry READs the device has sent (wraps) */
    uint8_t slot_id[CTL_MAX_JOINTS];    /* per roster slot: the servo of the reply taken */
    uint16_t slot_pos[CTL_MAX_JOINTS];  /* and the position it carried */
} rd;

/* The telemetry reply a receiver finds first in rx[0..n) for servo `id`: the earliest
 * complete 14-byte status packet from it with the right length and checksum. */
static const uint8_t *find_reply(const uint8_t *rx, size_t n, uint8_t id)
{
    for (size_t i = 0; i + BUS_REPLY_BYTES <= n; i++) {
        const uint8_t *w = rx + i;
        if (w[0] == 0xFF && w[1] == 0xFF && w[2] == id && w[3] == BUS_TELEMETRY_LENGTH + 2 &&
            dxl_checksum(w + 2, BUS_REPLY_BYTES - 3) == w[BUS_REPLY_BYTES - 1])
            return w;
    }
    return NULL;
}

/* The device's next bus packet, checked; a READ stays in flight for bus_answer(). */
static void bus_send(void)
{
    uint8_t tx[CTL_BUS_TX_MAX + 8];
    uint8_t reply_len = 0xEE;
    memset(tx, 0xCC, sizeof tx);
    size_t n = ctl_bus_next(d, tx, CTL_BUS_TX_MAX, &reply_len);
    bool torque_off_due = tick.entered_safe && !tick.pc_since; /* a command may change it */
    tick.entered_safe = false;
    rd.pending = false; /* the device closed any READ before sending again */
    if (n == 0) {
        CHECK(reply_len == 0);
        CHECK(!torque_off_due);
        return;
    }
    CHECK(n <= CTL_BUS_TX_MAX);
    CHECK(tx[n] == 0xCC); /* nothing written past the packet */
    dxl_event ev = parse_one(tx, n);
    if (torque_off_due) {
        CHECK(ev.id == DXL_BROADCAST_ID && ev.code == DXL_INST_WRITE && ev.nparams == 2);
        CHECK(ev.params[0] == 24 && ev.params[1] == 0); /* AX-12 Torque Enable = 0 */
    }
    if (ev.code == DXL_INST_SYNC_WRITE) {
        CHECK(ev.id == DXL_BROADCAST_ID && reply_len == 0);
        CHECK(ev.nparams >= 2 && ev.params[1] > 0 && (ev.nparams - 2) % (ev.params[1] + 1u) == 0);
        if (ev.params[0] == 30) check_goals(&ev); /* AX-12 Goal Position */
        else CHECK(ev.params[0] == 24 && ev.params[1] == 1); /* torque on */
        return;
    }
    if (ev.code == DXL_INST_WRITE) {
        CHECK(ev.id == DXL_BROADCAST_ID && reply_len == 0);
        CHECK(ev.params[0] == 24); /* only torque off is written this way */
        return;
    }
    /* the telemetry READ */
    CHECK(ev.code == DXL_INST_READ && ev.id <= DXL_MAX_ID && n == sizeof rd.raw);
    CHECK(ev.nparams == 2 && ev.params[0] == BUS_TELEMETRY_ADDRESS &&
          ev.params[1] == BUS_TELEMETRY_LENGTH);
    CHECK(reply_len == BUS_REPLY_BYTES);
    CHECK(d->bus.awaiting != NO_READ && d->bus.awaiting < bus_roster_count(&d->bus));
    CHECK(d->bus.ids[d->bus.awaiting] == ev.id);
    memcpy(rd.raw, tx, n);
    rd.ev = ev;
    rd.ev.raw = rd.raw;
    rd.ev.params = rd.raw + 5;
    rd.slot = d->bus.awaiting;
    rd.pending = true;
    rd.reads_issued++;
}

/* The answer to the READ in flight (whatever happened on the PC link meanwhile), then the
 * end of its reply window. */
static void bus_answer(const bus_answer_t *a)
{
    if (!rd.pending) {
        ctl_bus_rx_done(d); /* a window with nothing awaited: harmless */
        return;
    }
    rd.pending = false;
    bool same = d->bus.awaiting == rd.slot && d->bus.ids[rd.slot] == rd.ev.id; /* still awaited */
    uint16_t reads = bus_reads(&d->bus);
    uint16_t timeouts = bus_timeouts(&d->bus);
    uint16_t errors = bus_errors(&d->bus);

    uint8_t rx[96];
    int damaged_at;
    size_t got = make_reply(a, &rd.ev, rx, sizeof rx, &damaged_at);
    bool correct = a->how == 1 || a->how == 2;
    /* in pieces, as the UART delivers them */
    size_t at = 0;
    bool done = false;
    for (unsigned k = 0; at < got && !done; k++) {
        size_t piece = (a->pieces + 7u * k) % 16u + 1u;
        if (piece > got - at) piece = got - at;
        done = ctl_bus_rx(d, rx + at, piece);
        at += piece;
    }
    ctl_bus_rx_done(d);
    CHECK(d->bus.awaiting == NO_READ);
    uint16_t dr = (uint16_t)(bus_reads(&d->bus) - reads);
    uint16_t dt = (uint16_t)(bus_timeouts(&d->bus) - timeouts);
    if (!same) {
        CHECK(dr == 0 && dt == 0); /* the READ was closed already; nothing is filed now */
        return;
    }
    CHECK(dr + dt == 1); /* exactly one outcome per READ */
    CHECK(done == (dr == 1));
    if (correct) CHECK(done);
    if (damaged_at >= 0) {
        /* a damaged reply is never taken; past its header it counts as a bus error too */
        CHECK(dt == 1);
        CHECK((uint16_t)(bus_errors(&d->bus) - errors) == (damaged_at >= 4 ? 1u : 0u));
    }
    if (correct) {
        const bus_servo *sv = bus_servo_at(&d->bus, rd.slot);
        uint16_t pos = (uint16_t)(a->data[0] | (a->data[1] << 8));
        CHECK(sv != NULL && sv->missed == 0 && sv->position == pos && sv->error == a->error);
    }
    if (dr == 1) { /* what was taken is a real reply of this servo, in the bytes given */
        const uint8_t *w = find_reply(rx, at, rd.ev.id);
        const bus_servo *sv = bus_servo_at(&d->bus, rd.slot);
        CHECK(w != NULL && sv != NULL);
        CHECK(sv->position == (uint16_t)(w[5] | (w[6] << 8)) && sv->error == w[4]);
        rd.slot_id[rd.slot] = rd.ev.id;
        rd.slot_pos[rd.slot] = sv->position;
    } else {
        CHECK(find_reply(rx, at, rd.ev.id) == NULL || !same); /* a good reply is never missed */
    }
}

/* Every READ the device sent ends as one read or one timeout (or is still in flight), and
 * each roster slot's mirror holds what its own servo last said. */
static void check_bus(void)
{
    const bus_master *b = &d->bus;
    bool open = b->awaiting != NO_READ && !b->taken;
    CHECK((uint16_t)(bus_reads(b) + bus_timeouts(b) + (open ? 1u : 0u)) == rd.reads_issued);
    for (uint8_t k = 0; k < b->count; k++) {
        const bus_servo *sv = &b->servo[k];
        if (sv->fresh) CHECK(rd.slot_id[k] == b->ids[k] && sv->position == rd.slot_pos[k]);
    }
}

/* ---- power ------------------------------------------------------------------------------------ */

/* The MCU resets: a fresh device (zeroed RAM) that loads what the store kept, as main()
 * does. With `damage` odd, one byte of the stored table went bad: it must not load. */
static void power_cycle(uint8_t damage, uint8_t where, uint8_t flip)
{
    bool bad = (damage & 1u) != 0 && flash.len > 0;
    if (bad) flash.bytes[where % flash.len] ^= (uint8_t)(flip | 1u);
    store_model_power_cut(); /* a library write cut short leaves its slot as it was */
    memset(d, 0, sizeof *d);
    ctl_init(d);
    ctl_set_tables(d, FUZZ_ARENA, FUZZ_CAPACITY);
    ctl_set_library(d, &fuzz_library);
    bool loaded = flash.len > 0 && ctl_load_table(d, flash.bytes, flash.len);
    CHECK(loaded == (flash.len > 0 && !bad)); /* a whole table always comes back */
    if (loaded) {
        CHECK(d->active_len == flash.len && memcmp(d->active, flash.bytes, flash.len) == 0);
        CHECK(ctl_table_changed(d));
    } else {
        CHECK(d->active_len == 0);
        flash.len = 0; /* the store is empty now */
    }
    take_snapshot();
    memset(&tick, 0, sizeof tick);
    memset(&rd, 0, sizeof rd);
}

/* ---- the steps --------------------------------------------------------------------------------- */

/* 0: raw bytes on the PC link. */
static void step_raw_bytes(src *s)
{
    uint8_t buf[256];
    size_t n = u8(s);
    bytes(s, buf, n);
    pc_bytes(buf, n, NULL);
}

/* 1: any well-formed packet: mostly to the controller, else broadcast or any ID; mostly
 * a common instruction, else any. */
static void step_any_packet(src *s)
{
    uint8_t params[80];
    uint8_t sel = u8(s);
    uint8_t id = sel < 160 ? ctl_id(d) : sel < 200 ? DXL_BROADCAST_ID : u8(s);
    if (id == 0xFF) id = DXL_BROADCAST_ID;
    uint8_t inst = u8(s);
    static const uint8_t common[] = {DXL_INST_PING, DXL_INST_READ, DXL_INST_WRITE,
                                     DXL_INST_SYNC_WRITE, DXL_INST_RESET,
                                     DXL_INST_REG_WRITE};
    if (inst < 200) inst = common[inst % sizeof common];
    size_t n = u8(s) % sizeof params;
    bytes(s, params, n);
    pc_packet(id, inst, params, n);
}

/* 2: a WRITE of 1..12 bytes of registers anywhere. */
static void step_write_registers(src *s)
{
    uint8_t data[12];
    uint8_t addr = u8(s);
    size_t n = u8(s) % sizeof data + 1u;
    bytes(s, data, n);
    write_to_me(addr, data, n);
}

/* 3: a roster record in the servo window. */
static void step_roster_record(src *s)
{
    uint8_t data[1 + CTL_SERVO_RECORD_SIZE];
    uint8_t slot = u8(s) % CTL_SERVO_RECORDS;
    /* Window Page, written in the same packet: a servo page, or now and then one of
     * the pages from 16 on (described ones refuse writes to read-only fields, others
     * are refused outright) */
    uint8_t pick = u8(s);
    data[0] = pick < 240 ? pick % CTL_SERVO_PAGES : (uint8_t)(CTL_PAGE_PROGRAM + pick - 240);
    bytes(s, data + 1, 8);
    put16(data + 1 + CTL_REC_ZERO_TICK, u16(s) % 1024u);
    put16(data + 1 + CTL_REC_MIN_TICK, u16(s) % 1024u);
    put16(data + 1 + CTL_REC_MAX_TICK, u16(s) % 1024u);
    data[1 + CTL_REC_REVERSE] &= 1u;
    if (slot == 0) {
        write_to_me(CTL_WINDOW_PAGE, data, 1 + 8);
    } else {
        write_to_me(CTL_WINDOW_PAGE, data, 1);
        write_to_me((uint8_t)(CTL_SERVO_WINDOW + slot * CTL_SERVO_RECORD_SIZE), data + 1, 8);
    }
}

/* 5: commit whatever is staged, with its true CRC. */
static void step_commit_staged(src *s)
{
    uint16_t len = (uint16_t)(u16(s) % (FUZZ_CAPACITY + 8u));
    uint32_t crc = len <= FUZZ_CAPACITY ? crc_of(STAGING, len) : 0;
    commit_with(len, crc);
}

/* 6: a command. */
static void step_command(src *s)
{
    uint8_t cmd = u8(s) % 7u; /* NONE..LIBRARY_PLAY */
    write_to_me(CTL_COMMAND, &cmd, 1);
}

/* 7: a joint count, or a small roster for the serpenoid. */
static void step_joint_count(src *s)
{
    uint8_t n = u8(s) % (CTL_MAX_JOINTS + 1u);
    write_to_me(CTL_JOINT_COUNT, &n, 1);
}

/* 9: time passes (mostly a little, now and then a lot): a control tick. */
static void step_tick(src *s)
{
    uint8_t sel = u8(s);
    uint32_t dt = sel < 200 ? sel % 40u : sel < 250 ? u16(s) : (uint32_t)u16(s) << 16;
    do_tick(dt);
}

/* 11: the rest of this tick's bus schedule, every READ answered at once. */
static void step_bus_schedule(src *s)
{
    bus_answer_t a;
    read_answer(s, &a);
    for (unsigned k = 0; k < 4; k++) { /* at most torque, goals, READ */
        bus_send();
        bus_answer(&a);
    }
    CHECK(d->bus.step == 3); /* the schedule always ends */
}

/* 12: a playback register, with a value in or near its range. */
static void step_playback_register(src *s)
{
    static const uint8_t knobs[] = {CTL_SPEED_SCALE, CTL_STEERING_OFFSET, CTL_LOOP,
                                    CTL_SERP_AMPLITUDE, CTL_SERP_OMEGA, CTL_SERP_DELTA,
                                    CTL_SERP_PHI0, CTL_SAFE_ACTION, CTL_BUS_LOSS_LIMIT,
                                    CTL_SERVO_ERROR_MASK, CTL_LINK_TIMEOUT};
    uint8_t addr = knobs[u8(s) % sizeof knobs];
    uint8_t v[2];
    put16(v, u16(s));
    bool one_byte = addr == CTL_LOOP || (addr >= CTL_SAFE_ACTION && addr <= CTL_LINK_TIMEOUT);
    write_to_me(addr, v, one_byte ? 1 : 2);
}

/* 13: the reply (or silence) for the READ in flight. */
static void step_bus_reply(src *s)
{
    bus_answer_t a;
    read_answer(s, &a);
    bus_answer(&a);
}

/* 14: a power cycle, maybe with the stored table damaged. */
static void step_power_cycle(src *s)
{
    /* operands read in order (argument evaluation order is unspecified) */
    uint8_t damage = u8(s);
    uint8_t where = u8(s);
    power_cycle(damage, where, u8(s));
}

/* Step 15's play of the library slot the page shows: refused, with nothing changed, while
 * a background write runs. */
static void library_play(void)
{
    uint8_t cmd = CTL_COMMAND_LIBRARY_PLAY;
    bool busy = store_model_busy();
    uint8_t state = ctl_state(d);
    uint16_t len = d->active_len;
    if (!write_to_me(CTL_COMMAND, &cmd, 1) && busy) {
        CHECK(ctl_state(d) == state && d->active_len == len); /* refused: STORE_BUSY */
    }
}

/* 15: a library operation on a slot (maybe one the library lacks): the Library page
 * filled in, then a play, or a store or delete of what is staged (with its true CRC). */
static void step_library(src *s)
{
    uint8_t sel = u8(s);
    /* a store or delete that takes 1..8 ticks */
    store_model_plan((sel & 4u) != 0, (uint8_t)(1u + (sel >> 3) % 8u));
    uint8_t page[CTL_STORE_KIND + 1 - CTL_WINDOW_PAGE];
    memset(page, 0, sizeof page);
    page[0] = CTL_PAGE_LIBRARY;
    page[CTL_LIBRARY_SLOT - CTL_WINDOW_PAGE] = u8(s) % (LIB_SLOTS + 1u);
    bytes(s, page + (CTL_STORE_NAME - CTL_WINDOW_PAGE), CTL_STORE_NAME_SIZE);
    page[CTL_STORE_KIND - CTL_WINDOW_PAGE] = (uint8_t)(1u + u8(s) % 3u);
    /* Window Page, then every field up to Store Kind, in one packet */
    write_to_me(CTL_WINDOW_PAGE, page, CTL_STORE_KIND + 1u - CTL_WINDOW_PAGE);
    if (sel % 3u == 0u) {
        library_play();
    } else {
        uint16_t len = (uint16_t)(u16(s) % (FUZZ_CAPACITY + 8u));
        uint32_t crc = len <= FUZZ_CAPACITY ? crc_of(STAGING, len) : 0;
        commit_as(len, crc,
                  sel % 3u == 1u ? CTL_UPLOAD_COMMIT_LIBRARY_STORE
                                 : CTL_UPLOAD_COMMIT_LIBRARY_DELETE);
    }
}

/* 16: the robot's buttons, held for a control tick. */
static void step_buttons(src *s)
{
    now_ms += u8(s) % 20u;
    uint8_t leds = ctl_buttons(d, u8(s), now_ms);
    CHECK((leds & ~(CTL_LEDS_SLOT_1 | CTL_LEDS_SLOT_2 | CTL_LEDS_SLOT_4 | CTL_LEDS_PLAY)) == 0);
    CHECK(d->lib.panel.slot < LIB_SLOTS);
}

/* ---- the program ------------------------------------------------------------------------------- */

/* The steps that reach the device only through pc_bytes(), which checks everything after
 * each event; the bytes that make no event change only the parser, which check_all() does
 * not look at. Checking again at the end of such a step would find what the last event's
 * check found. Every other step (ticks, the bus, power, buttons) is checked at its end. */
#define PC_ONLY_STEPS                                                                        \
    ((1u << 0) | (1u << 1) | (1u << 2) | (1u << 3) | (1u << 4) | (1u << 5) | (1u << 6) |      \
     (1u << 7) | (1u << 8) | (1u << 12) | (1u << 15) | (1u << 17))

/* One step: an opcode, then its operands (fuzz/seeds.py writes them in this order). */
static void step(src *s)
{
    uint8_t op = u8(s) % 18u;
    switch (op) {
    case 0: step_raw_bytes(s); break;
    case 1: step_any_packet(s); break;
    case 2: step_write_registers(s); break;
    case 3: step_roster_record(s); break;
    case 4: upload(s); break;
    case 5: step_commit_staged(s); break;
    case 6: step_command(s); break;
    case 7: step_joint_count(s); break;
    case 8: pc_packet(ctl_id(d), DXL_INST_RESET, NULL, 0); break;
    case 9: step_tick(s); break;
    case 10: bus_send(); break;
    case 11: step_bus_schedule(s); break;
    case 12: step_playback_register(s); break;
    case 13: step_bus_reply(s); break;
    case 14: step_power_cycle(s); break;
    case 15: step_library(s); break;
    case 16: step_buttons(s); break;
    case 17: upload_program(s); break;
    default: CHECK(0);
    }
    if (((PC_ONLY_STEPS >> op) & 1u) == 0) check_all();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    src s = {data, size};
    static ctl_device *fresh; /* the device as ctl_init() leaves it after power-on */
    if (d == NULL) { /* one device for the whole run: a fresh allocation per input cost */
        /* exact size: ASan catches a write past the end */
        d = malloc(ctl_device_bytes(FUZZ_ARENA));
        fresh = malloc(ctl_device_bytes(FUZZ_ARENA));
        CHECK(d != NULL && fresh != NULL && ctl_device_size() == sizeof(ctl_device));
        memset(fresh, 0, sizeof *fresh); /* the MCU's .bss */
        ctl_init(fresh);
        ctl_set_tables(fresh, FUZZ_ARENA, FUZZ_CAPACITY);
    }
    /* every input starts from power-on: a copy of the initialised device rather than
     * ctl_init() again, which rebuilt every register's default (power_cycle() still runs
     * ctl_init() itself, so its coverage stays in the runs) */
    memcpy(d, fresh, sizeof *d);
    store_model_reset();
    ctl_set_library(d, &fuzz_library);
    now_ms = (uint32_t)u16(&s) << 16; /* any starting time, including near the wrap */
    memset(&tick, 0, sizeof tick);
    memset(&rd, 0, sizeof rd);
    snapshot.len = 0;
    facts.known = false;
    flash.len = 0;
    check_all();
    for (unsigned k = 0; k < MAX_STEPS && s.n > 0; k++) step(&s);
    return 0;
}
