/* libFuzzer target: the controller's PC-link device and control loop
 * (firmware/core/ctl_device.c with the parser, gait tables, player, safety and bus master
 * behind it), driven the way the firmware's main loop drives it.
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
#include <zlib.h>

#include "ctl_device.h"
#include "dxl_packet.h"
#include "dxl_parser.h"
#include "gt_table.h"
#include "prog_limits.h"
#include "prog_run.h"

#include "fuzz_check.h"

/* Steps per input: the evolved corpus's programs have a median of 20 and a 90th percentile
 * of 128; a cap keeps the long tail from dominating the run time (docs/reliability.md). */
#define MAX_STEPS 128
#define NO_READ 0xFFu
/* The device's tables: the QEMU board's capacity (a CRC or a validation costs up to that
 * much after a change), in an arena of twice that, so no upload displaces the active
 * table (the checks below hold that a table is never lost). */
#define FUZZ_CAPACITY 2048u
#define FUZZ_ARENA (2u * FUZZ_CAPACITY)
#define STAGING (d->active + FUZZ_ARENA - FUZZ_CAPACITY)

/* ---- the input --------------------------------------------------------------------------- */

typedef struct {
    const uint8_t *p;
    size_t n;
} src;

static uint8_t u8(src *s)
{
    if (s->n == 0) return 0;
    s->n--;
    return *s->p++;
}

static uint16_t u16(src *s)
{
    uint16_t lo = u8(s);
    return (uint16_t)(lo | ((uint16_t)u8(s) << 8));
}

static void bytes(src *s, uint8_t *out, size_t n)
{
    size_t have = n < s->n ? n : s->n;
    memcpy(out, s->p, have);
    memset(out + have, 0, n - have); /* missing bytes read as 0 */
    s->p += have;
    s->n -= have;
}

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

/* CRC-32 as the host works it out, by zlib's crc32 (the same IEEE 802.3 CRC): an
 * implementation independent of the core's crc32.c, and uninstrumented, so checking the
 * registers' Table CRC against it costs a small part of the core's bytewise loop. */
static uint32_t crc_of(const uint8_t *p, size_t n)
{
    return (uint32_t)crc32(0uL, p, (uInt)n);
}

/* Store the CRC a table or a program carries at its offset 12: gt_crc()'s (bytes 0..11,
 * then 16 on), worked out as crc_of() does rather than by the instrumented core. */
#if PROG_CRC_OFFSET != GT_CRC_OFFSET
#error "seal() puts a program's CRC where a table's goes"
#endif
static void seal(uint8_t *t, size_t len)
{
    uLong crc = crc32(0uL, t, GT_CRC_OFFSET);
    crc = crc32(crc, t + GT_CRC_OFFSET + 4u, (uInt)(len - GT_CRC_OFFSET - 4u));
    for (unsigned b = 0; b < 4; b++) t[GT_CRC_OFFSET + b] = (uint8_t)(crc >> (8 * b));
}

/* ---- the gait library: a store in RAM, kept across power cycles as flash would be ------------ */

#define KNOWN_FLAGS                                                                           \
    (CTL_ERROR_FLAGS_UPLOAD_LENGTH | CTL_ERROR_FLAGS_UPLOAD_CRC | CTL_ERROR_FLAGS_UPLOAD_LAYOUT | \
     CTL_ERROR_FLAGS_UPLOAD_TOO_BIG | CTL_ERROR_FLAGS_SERVO_ERROR | CTL_ERROR_FLAGS_BUS_LOSS |    \
     CTL_ERROR_FLAGS_LINK_LOSS | CTL_ERROR_FLAGS_REFUSED | CTL_ERROR_FLAGS_LIMITS |               \
     CTL_ERROR_FLAGS_PROGRAM | CTL_ERROR_FLAGS_LIBRARY)
#define LIB_SLOTS 3u

static struct {
    uint8_t kind; /* 0: empty */
    uint8_t name[CTL_SLOT_NAME_SIZE];
    uint16_t len;
    uint32_t crc; /* worked out once, when stored: the core asks for it on every look */
    uint8_t bytes[FUZZ_CAPACITY];
} library[LIB_SLOTS];

/* A store or delete that, like the CM-530's, writes in the background: put and remove
 * only begin it (LIBRARY_STORING), and it ends after `ticks` control ticks, when the slot
 * changes and ctl_library_stored() reports. The blob is read where the core left it (the
 * staging area) only at the end, so a core that let the staging area change meanwhile
 * stores other bytes than it accepted, which the CRC taken at the start catches. A power
 * cut meanwhile leaves the slot as it was. */
static bool background; /* whether the next put or remove writes in the background */
static struct {
    uint8_t ticks; /* 0: nothing under way */
    uint8_t total;
    bool remove;
    uint8_t slot, kind;
    uint8_t name[CTL_SLOT_NAME_SIZE];
    const uint8_t *data;
    uint16_t len;
    uint32_t crc;
} writing;

static void lib_get(uint8_t slot, lib_slot *out, const uint8_t **data)
{
    CHECK(slot < LIB_SLOTS); /* the core asks only for slots the store has */
    if (library[slot].kind == 0) return;
    out->status = CTL_SLOT_STATUS_OK;
    out->kind = library[slot].kind;
    out->len = library[slot].len;
    out->crc = library[slot].crc;
    memcpy(out->name, library[slot].name, sizeof out->name);
    *data = library[slot].bytes;
}

/* The slot now keeps data[0..len), whose CRC-32 is crc. */
static void lib_keep(uint8_t slot, uint8_t kind, const uint8_t *name, const uint8_t *data,
                     uint16_t len, uint32_t crc)
{
    library[slot].kind = kind;
    memcpy(library[slot].name, name, CTL_SLOT_NAME_SIZE);
    library[slot].len = len;
    library[slot].crc = crc;
    memcpy(library[slot].bytes, data, len);
}

static uint8_t lib_put(uint8_t slot, uint8_t kind, const uint8_t *name, const uint8_t *data,
                       uint16_t len)
{
    CHECK(slot < LIB_SLOTS && kind != 0 && kind != CTL_UPLOAD_COMMIT_LIMITS);
    CHECK(len > 0 && len <= FUZZ_CAPACITY);
    for (size_t i = 0; i < CTL_SLOT_NAME_SIZE; i++) {
        CHECK(name[i] == 0 || (name[i] >= 0x20 && name[i] <= 0x7e)); /* names were checked */
    }
    if (kind == CTL_UPLOAD_COMMIT_TABLE) {
        gt_info info;
        CHECK(gt_validate(data, len, &info) == GT_OK); /* only whole tables are kept as such */
    }
    CHECK(writing.ticks == 0); /* one flash write at a time */
    if (background) {
        writing.remove = false;
        writing.slot = slot;
        writing.kind = kind;
        memcpy(writing.name, name, CTL_SLOT_NAME_SIZE);
        writing.data = data;
        writing.len = len;
        writing.crc = crc_of(data, len);
        writing.ticks = writing.total;
        return CTL_UPLOAD_RESULT_LIBRARY_STORING;
    }
    lib_keep(slot, kind, name, data, len, crc_of(data, len));
    return CTL_UPLOAD_RESULT_OK;
}

static uint8_t lib_remove(uint8_t slot)
{
    CHECK(slot < LIB_SLOTS);
    CHECK(writing.ticks == 0);
    if (background) {
        writing.remove = true;
        writing.slot = slot;
        writing.ticks = writing.total;
        return CTL_UPLOAD_RESULT_LIBRARY_STORING;
    }
    library[slot].kind = 0;
    return CTL_UPLOAD_RESULT_OK;
}

static uint8_t fuzz_lib_saving(uint8_t *percent)
{
    if (writing.ticks == 0) return CTL_STORE_STATE_IDLE;
    if (percent != NULL) *percent = (uint8_t)(100u * (writing.total - writing.ticks) / writing.total);
    return CTL_STORE_STATE_LIBRARY;
}

/* A control tick of the background write: at the last, the slot changes. */
static void lib_write_tick(void)
{
    if (writing.ticks == 0 || --writing.ticks > 0) return;
    if (writing.remove) {
        library[writing.slot].kind = 0;
    } else {
        CHECK(crc_of(writing.data, writing.len) == writing.crc); /* staging kept as accepted */
        lib_keep(writing.slot, writing.kind, writing.name, writing.data, writing.len,
                 writing.crc);
    }
    ctl_library_stored(d, CTL_UPLOAD_RESULT_OK);
}

static const lib_store fuzz_library = {.slots = LIB_SLOTS,
                                       .memory = CTL_LIBRARY_MEMORY_RAM,
                                       .capacity = FUZZ_CAPACITY,
                                       .get = lib_get,
                                       .put = lib_put,
                                       .remove = lib_remove,
                                       .saving = fuzz_lib_saving};

/* Whether table[0..len) is what a library slot keeps as a table. */
static bool in_library(const uint8_t *table, uint16_t len)
{
    for (unsigned k = 0; k < LIB_SLOTS; k++) {
        if (library[k].kind == CTL_UPLOAD_COMMIT_TABLE && library[k].len == len &&
            memcmp(library[k].bytes, table, len) == 0) {
            return true;
        }
    }
    return false;
}

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

/* ---- gait tables ------------------------------------------------------------------------------ */

static void put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

/* A valid table from the input: joints 1..18, frames within the 2 KB, unique IDs. */
static size_t make_table(src *s, uint8_t *t)
{
    uint8_t joints = (uint8_t)(u8(s) % CTL_MAX_JOINTS + 1u);
    size_t per_frame = 2u * joints;
    size_t room = (FUZZ_CAPACITY - GT_HEADER_SIZE - (size_t)GT_JOINT_SIZE * joints) /
                  per_frame;
    uint16_t frames = (uint16_t)(u8(s) % (room < 40 ? room : 40) + 1u);
    uint16_t period = (uint16_t)(u16(s) % 1000u + 1u);
    uint8_t flags = u8(s) & GT_FLAG_LOOP;
    memset(t, 0, GT_HEADER_SIZE);
    t[0] = 'S';
    t[1] = 'N';
    t[2] = 'K';
    t[3] = 'G';
    t[4] = GT_VERSION;
    t[5] = joints;
    t[6] = flags;
    put16(t + 8, period);
    put16(t + 10, frames);
    uint16_t lo[CTL_MAX_JOINTS];
    uint16_t hi[CTL_MAX_JOINTS];
    uint8_t first_id = u8(s);
    for (uint8_t j = 0; j < joints; j++) {
        uint8_t *rec = t + GT_HEADER_SIZE + GT_JOINT_SIZE * j;
        uint16_t a = u16(s) % 1024u;
        uint16_t b = u16(s) % 1024u;
        lo[j] = a < b ? a : b;
        hi[j] = a < b ? b : a;
        rec[0] = (uint8_t)((first_id + j) % (GT_MAX_ID + 1u));
        rec[1] = 0;
        put16(rec + 2, lo[j]);
        put16(rec + 4, hi[j]);
    }
    uint8_t *f = t + GT_HEADER_SIZE + GT_JOINT_SIZE * joints;
    for (uint16_t k = 0; k < frames; k++) {
        for (uint8_t j = 0; j < joints; j++) {
            uint16_t span = (uint16_t)(hi[j] - lo[j] + 1u);
            put16(f, (uint16_t)(lo[j] + u16(s) % span));
            f += 2;
        }
    }
    size_t len = (size_t)(f - t);
    seal(t, len);
    /* valid by construction: upload() checks that a sound upload of it lands */
    return len;
}

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
    bool busy = writing.ticks > 0; /* no tick passes during the upload */
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

/* A program from the input (protocol/program.md): 1..4 joints with limits around a zero
 * tick, up to 4 frames, 2 periodic blocks and 6 segments of any kind with fields from
 * the input, most of them beyond what the joints allow; its CRC made right. */
static size_t make_program(src *s, uint8_t *t)
{
    uint8_t joints = (uint8_t)(u8(s) % 4u + 1u);
    uint8_t segments = (uint8_t)(u8(s) % 6u + 1u);
    uint8_t blocks = (uint8_t)(u8(s) % 3u);
    uint16_t frames = (uint16_t)(u8(s) % 5u);
    memset(t, 0, PROG_HEADER_SIZE);
    memcpy(t, "SNKP", 4);
    t[4] = PROG_VERSION;
    t[5] = joints;
    t[6] = segments;
    t[7] = blocks;
    put16(t + 8, (uint16_t)(u8(s) % 100u + 1u));
    put16(t + 10, frames);
    uint8_t *p = t + PROG_HEADER_SIZE;
    uint16_t lo[4];
    uint16_t hi[4];
    uint8_t first_id = u8(s);
    for (uint8_t j = 0; j < joints; j++, p += PROG_JOINT_SIZE) {
        uint16_t a = u16(s) % 1024u;
        uint16_t b = u16(s) % 1024u;
        lo[j] = a < b ? a : b;
        hi[j] = a < b ? b : a;
        p[0] = (uint8_t)((first_id + j) % (GT_MAX_ID + 1u));
        p[1] = u8(s) & PROG_JOINT_REVERSE;
        put16(p + 2, (uint16_t)(lo[j] + u16(s) % (hi[j] - lo[j] + 1u)));
        put16(p + 4, lo[j]);
        put16(p + 6, hi[j]);
    }
    for (uint8_t k = 0; k < segments; k++, p += PROG_SEGMENT_SIZE) {
        memset(p, 0, PROG_SEGMENT_SIZE);
        p[0] = (uint8_t)(u8(s) % 3u + 1u);
        if (p[0] == PROG_KIND_TABLE && frames == 0) p[0] = PROG_KIND_SERPENOID;
        if (p[0] == PROG_KIND_PERIODIC && blocks == 0) p[0] = PROG_KIND_SERPENOID;
        if (p[0] == PROG_KIND_TABLE) {
            uint16_t first = (uint16_t)(u8(s) % frames);
            put16(p + 2, first);
            put16(p + 4, (uint16_t)(u8(s) % (frames - first) + 1u));
            put16(p + 6, (uint16_t)(u8(s) % 4u + 1u));
        } else if (p[0] == PROG_KIND_SERPENOID) {
            for (unsigned f = 0; f < 4; f++) put16(p + 2 + 2 * f, u16(s));
            put16(p + 10, (uint16_t)(u8(s) % 50u + 1u));
        } else {
            put16(p + 2, (uint16_t)(u8(s) % blocks));
            put16(p + 4, u16(s));
            put16(p + 6, (uint16_t)(u8(s) % 50u + 1u));
        }
    }
    for (size_t k = 0; k < (size_t)blocks * joints * 3u; k++, p += 2) {
        int16_t v = (int16_t)u16(s);
        uint8_t shift = u8(s) % 16u;
        put16(p, (uint16_t)(v / (1 << shift))); /* any size, mostly small */
    }
    for (uint16_t f = 0; f < frames; f++) {
        for (uint8_t j = 0; j < joints; j++, p += 2) {
            put16(p, (uint16_t)(lo[j] + u16(s) % (hi[j] - lo[j] + 1u)));
        }
    }
    size_t len = (size_t)(p - t);
    seal(t, len);
    return len;
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
    bool busy = writing.ticks > 0; /* no tick passes during the upload */
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
    lib_write_tick(); /* as the firmware steps its flash write after the tick's bus work */
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

/* How the bus answers the awaited READ: always read whole from the input, whatever the
 * device sends (so a program's later steps do not shift with the device's behaviour). */
typedef struct {
    uint8_t how;      /* 0 silence, 1 reply, 2 echo + reply, 3 damaged, 4 other servo, 5 raw */
    uint8_t data[8];  /* the telemetry block */
    uint8_t error;
    uint8_t flip_at;  /* damaged: which byte (from the ID on) and which bit */
    uint8_t flip_bit;
    uint8_t pieces;   /* how the bytes are split into UART reads */
    uint8_t raw_len;
    uint8_t raw[64];
} bus_answer_t;

static void read_answer(src *s, bus_answer_t *a)
{
    a->how = u8(s) % 6u;
    bytes(s, a->data, sizeof a->data);
    a->error = u8(s) & 0x7Fu;
    a->flip_at = u8(s);
    a->flip_bit = u8(s) % 8u;
    a->pieces = u8(s);
    a->raw_len = u8(s) % (uint8_t)sizeof a->raw;
    bytes(s, a->raw, a->raw_len);
}

/* The bytes that come back for the READ `read`. */
static size_t make_reply(const bus_answer_t *a, const dxl_event *read, uint8_t *rx, size_t cap,
                         int *damaged_at)
{
    size_t n = 0;
    *damaged_at = -1;
    switch (a->how) {
    case 0: return 0; /* silence: a timeout */
    case 1:           /* the reply */
    case 2:           /* the echo of the READ, then the reply (one-wire adapter) */
        if (a->how == 2) {
            memcpy(rx, read->raw, read->raw_len);
            n = read->raw_len;
        }
        return n + dxl_status(rx + n, cap - n, read->id, a->error, a->data, sizeof a->data);
    case 3: /* the reply with one bit flipped */
        n = dxl_status(rx, cap, read->id, a->error, a->data, sizeof a->data);
        *damaged_at = (int)(2u + a->flip_at % (n - 2));
        rx[*damaged_at] ^= (uint8_t)(1u << a->flip_bit);
        return n;
    case 4: /* a reply from another servo */
        return dxl_status(rx, cap, (uint8_t)(read->id ^ 1u), a->error, a->data, sizeof a->data);
    default: /* whatever the input says */
        memcpy(rx, a->raw, a->raw_len);
        return a->raw_len;
    }
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
    writing.ticks = 0; /* a library write cut short leaves its slot as it was */
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

/* ---- the program ------------------------------------------------------------------------------- */

/* The steps that reach the device only through pc_bytes(), which checks everything after
 * each event; the bytes that make no event change only the parser, which check_all() does
 * not look at. Checking again at the end of such a step would find what the last event's
 * check found. Every other step (ticks, the bus, power, buttons) is checked at its end. */
#define PC_ONLY_STEPS                                                                        \
    ((1u << 0) | (1u << 1) | (1u << 2) | (1u << 3) | (1u << 4) | (1u << 5) | (1u << 6) |      \
     (1u << 7) | (1u << 8) | (1u << 12) | (1u << 15) | (1u << 17))

static void step(src *s)
{
    uint8_t op = u8(s) % 18u;
    uint8_t buf[256];
    switch (op) {
    case 0: { /* raw bytes */
        size_t n = u8(s);
        bytes(s, buf, n);
        pc_bytes(buf, n, NULL);
        break;
    }
    case 1: { /* any well-formed packet */
        uint8_t sel = u8(s);
        uint8_t id = sel < 160 ? ctl_id(d) : sel < 200 ? DXL_BROADCAST_ID : u8(s);
        if (id == 0xFF) id = DXL_BROADCAST_ID;
        uint8_t inst = u8(s);
        static const uint8_t common[] = {DXL_INST_PING, DXL_INST_READ, DXL_INST_WRITE,
                                         DXL_INST_SYNC_WRITE, DXL_INST_RESET,
                                         DXL_INST_REG_WRITE};
        if (inst < 200) inst = common[inst % sizeof common];
        size_t n = u8(s) % 80u;
        bytes(s, buf, n);
        pc_packet(id, inst, buf, n);
        break;
    }
    case 2: { /* a WRITE of registers */
        uint8_t addr = u8(s);
        size_t n = u8(s) % 12u + 1u;
        bytes(s, buf, n);
        write_to_me(addr, buf, n);
        break;
    }
    case 3: { /* a roster record in the servo window */
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
        break;
    }
    case 4: upload(s); break;
    case 5: { /* commit whatever is staged, with its true CRC */
        uint16_t len = (uint16_t)(u16(s) % (FUZZ_CAPACITY + 8u));
        uint32_t crc = len <= FUZZ_CAPACITY ? crc_of(STAGING, len) : 0;
        commit_with(len, crc);
        break;
    }
    case 6: { /* a command */
        uint8_t cmd = u8(s) % 7u; /* NONE..LIBRARY_PLAY */
        write_to_me(CTL_COMMAND, &cmd, 1);
        break;
    }
    case 7: { /* a joint count, or a small roster for the serpenoid */
        uint8_t n = u8(s) % (CTL_MAX_JOINTS + 1u);
        write_to_me(CTL_JOINT_COUNT, &n, 1);
        break;
    }
    case 8: pc_packet(ctl_id(d), DXL_INST_RESET, NULL, 0); break;
    case 9: { /* time passes: a control tick */
        uint8_t sel = u8(s);
        uint32_t dt = sel < 200 ? sel % 40u : sel < 250 ? u16(s) : (uint32_t)u16(s) << 16;
        do_tick(dt);
        break;
    }
    case 10: bus_send(); break;
    case 11: { /* the rest of this tick's bus schedule, every READ answered at once */
        bus_answer_t a;
        read_answer(s, &a);
        for (unsigned k = 0; k < 4; k++) { /* at most torque, goals, READ */
            bus_send();
            bus_answer(&a);
        }
        CHECK(d->bus.step == 3); /* the schedule always ends */
        break;
    }
    case 13: { /* the reply (or silence) for the READ in flight */
        bus_answer_t a;
        read_answer(s, &a);
        bus_answer(&a);
        break;
    }
    case 12: { /* a playback register, with a value in or near its range */
        static const uint8_t knobs[] = {CTL_SPEED_SCALE, CTL_STEERING_OFFSET, CTL_LOOP,
                                        CTL_SERP_AMPLITUDE, CTL_SERP_OMEGA, CTL_SERP_DELTA,
                                        CTL_SERP_PHI0, CTL_SAFE_ACTION, CTL_BUS_LOSS_LIMIT,
                                        CTL_SERVO_ERROR_MASK, CTL_LINK_TIMEOUT};
        uint8_t addr = knobs[u8(s) % sizeof knobs];
        uint8_t v[2];
        put16(v, u16(s));
        bool one_byte = addr == CTL_LOOP || (addr >= CTL_SAFE_ACTION && addr <= CTL_LINK_TIMEOUT);
        write_to_me(addr, v, one_byte ? 1 : 2);
        break;
    }
    case 14: { /* operands read in order (argument evaluation order is unspecified) */
        uint8_t damage = u8(s);
        uint8_t where = u8(s);
        power_cycle(damage, where, u8(s));
        break;
    }
    case 15: { /* a library operation on a slot (maybe one the library lacks) */
        uint8_t sel = u8(s);
        background = (sel & 4u) != 0; /* a store or delete that takes 1..8 ticks */
        if (writing.ticks == 0) writing.total = (uint8_t)(1u + (sel >> 3) % 8u);
        uint8_t page[CTL_STORE_KIND + 1 - CTL_WINDOW_PAGE];
        memset(page, 0, sizeof page);
        page[0] = CTL_PAGE_LIBRARY;
        page[CTL_LIBRARY_SLOT - CTL_WINDOW_PAGE] = u8(s) % (LIB_SLOTS + 1u);
        bytes(s, page + (CTL_STORE_NAME - CTL_WINDOW_PAGE), CTL_STORE_NAME_SIZE);
        page[CTL_STORE_KIND - CTL_WINDOW_PAGE] = (uint8_t)(1u + u8(s) % 3u);
        /* Window Page, then every field up to Store Kind, in one packet */
        write_to_me(CTL_WINDOW_PAGE, page, CTL_STORE_KIND + 1u - CTL_WINDOW_PAGE);
        if (sel % 3u == 0u) {
            uint8_t cmd = CTL_COMMAND_LIBRARY_PLAY;
            bool busy = writing.ticks > 0;
            uint8_t state = ctl_state(d);
            uint16_t len = d->active_len;
            if (!write_to_me(CTL_COMMAND, &cmd, 1) && busy) {
                CHECK(ctl_state(d) == state && d->active_len == len); /* refused: STORE_BUSY */
            }
        } else {
            uint16_t len = (uint16_t)(u16(s) % (FUZZ_CAPACITY + 8u));
            uint32_t crc = len <= FUZZ_CAPACITY ? crc_of(STAGING, len) : 0;
            commit_as(len, crc,
                      sel % 3u == 1u ? CTL_UPLOAD_COMMIT_LIBRARY_STORE
                                     : CTL_UPLOAD_COMMIT_LIBRARY_DELETE);
        }
        break;
    }
    case 16: { /* the robot's buttons, held for a control tick */
        now_ms += u8(s) % 20u;
        uint8_t leds = ctl_buttons(d, u8(s), now_ms);
        CHECK((leds & ~(CTL_LEDS_SLOT_1 | CTL_LEDS_SLOT_2 | CTL_LEDS_SLOT_4 | CTL_LEDS_PLAY)) == 0);
        CHECK(d->lib.panel.slot < LIB_SLOTS);
        break;
    }
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
    for (unsigned k = 0; k < LIB_SLOTS; k++) library[k].kind = 0; /* the rest is read only when set */
    writing.ticks = 0;
    background = false;
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
