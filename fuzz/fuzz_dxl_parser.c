/* libFuzzer target: the streaming Protocol 1.0 parser (firmware/core/dxl_parser.c).
 *
 * Input byte 0 picks how the stream is delivered: how many bytes go in between polls
 * (1..8, or "until the parser refuses a byte"), whether a reset happens at a point
 * chosen by byte 1, and whether each drain ends, as the PC link's does, by looking for a
 * packet hidden behind a false header (dxl_parser_skip_to_hidden), and then whether
 * bytes go in through dxl_parser_feed_quiet where it takes them. The rest of the input is the byte stream. Byte 0 = 0xFF instead
 * selects the encoder round trip (see round_trip()).
 *
 * Oracle: an independent reference of the resynchronisation rule over a flat array
 * (protocol/README.md; the same rule snakebot.formats.protocol.parser follows). Every event the
 * parser reports must equal the reference's next event byte for byte, in the same order,
 * whenever the bytes are polled, and the bytes it holds back must be the reference's; a
 * hidden packet is taken exactly when the reference finds one, and the same one; each
 * byte dxl_parser_feed_quiet takes is one after which the reference, polled and hunting,
 * has nothing to report.
 * Besides: after a refused byte, polling always frees room (no deadlock); an event's pointers stay
 * inside the parser; a reported packet has a valid length and checksum. Any violation
 * aborts (a crash for libFuzzer). */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dxl_packet.h"
#include "dxl_parser.h"

#include "fuzz_check.h"

#define MAX_STREAM 65536

/* ---- the reference: the rule, literally, over every byte fed so far ------------------- */

typedef struct {
    uint8_t bytes[MAX_STREAM];
    uint8_t sum[MAX_STREAM + 1]; /* sum[k]: bytes[0..k) added up, mod 256 (sum[0] = 0) */
    size_t pos; /* first unconsumed byte */
    size_t end; /* bytes fed */
} ref_parser;

typedef struct {
    uint8_t kind;
    size_t start;
    size_t len;
} ref_event;

static uint8_t ref_sum(const uint8_t *b, size_t n)
{
    unsigned sum = 0;
    for (size_t i = 0; i < n; i++) sum += b[i];
    return (uint8_t)(~sum & 0xFFu);
}

static void ref_push(ref_parser *r, uint8_t byte)
{
    r->sum[r->end + 1] = (uint8_t)(r->sum[r->end] + byte);
    r->bytes[r->end++] = byte;
}

/* The next event, or false when more bytes are needed. */
static bool ref_next(ref_parser *r, ref_event *ev)
{
    const uint8_t *b = r->bytes;
    for (;;) {
        size_t avail = r->end - r->pos;
        /* (1) hunt for FF FF; a lone trailing FF stays */
        if (avail >= 2 && !(b[r->pos] == 0xFF && b[r->pos + 1] == 0xFF)) {
            r->pos++;
            continue;
        }
        if (avail < 2) {
            if (avail == 1 && b[r->pos] != 0xFF) r->pos++;
            return false;
        }
        /* (2) FF FF FF: the last two FFs are the header */
        if (avail >= 3 && b[r->pos + 2] == 0xFF) {
            r->pos++;
            continue;
        }
        if (avail < 4) return false;
        /* (3) the length byte */
        size_t len = b[r->pos + 3];
        if (len < 2 || len + 4 > DXL_MAX_PACKET) {
            ev->kind = DXL_EVENT_BAD_LENGTH;
            ev->start = r->pos;
            ev->len = 4;
            r->pos++;
            return true;
        }
        /* (4) the whole candidate, then its checksum */
        if (avail < len + 4) return false;
        ev->start = r->pos;
        ev->len = len + 4;
        if (ref_sum(b + r->pos + 2, len + 1) != b[r->pos + len + 3]) {
            ev->kind = DXL_EVENT_BAD_CHECKSUM;
            r->pos++;
        } else {
            ev->kind = DXL_EVENT_PACKET;
            r->pos += len + 4;
        }
        return true;
    }
}

/* dxl_parser_skip_to_hidden's rule, literally: the first later header among the bytes held
 * back where a whole packet with a good checksum starts; the bytes before it are dropped. */
static bool ref_skip(ref_parser *r)
{
    const uint8_t *b = r->bytes;
    for (size_t i = r->pos + 1; i + 4 <= r->end; i++) {
        /* memchr (not instrumented) finds the next 0xFF: this runs after every drain */
        const uint8_t *ff = memchr(b + i, 0xFF, r->end - 3 - i);
        if (ff == NULL) break;
        i = (size_t)(ff - b);
        if (b[i + 1] != 0xFF || b[i + 2] == 0xFF) continue;
        size_t len = b[i + 3];
        if (len < 2 || len + 4 > DXL_MAX_PACKET || i + len + 4 > r->end) continue;
        /* the checksum from the running sums: this runs after every drain */
        if ((uint8_t)~(r->sum[i + len + 3] - r->sum[i + 2]) == b[i + len + 3]) {
            r->pos = i;
            return true;
        }
    }
    return false;
}

/* ---- comparing the parser with the reference --------------------------------------------- */

static dxl_parser parser;
static ref_parser ref;
static bool hunt; /* drains end with dxl_parser_skip_to_hidden */

static void check_event(const dxl_event *ev, const ref_event *want)
{
    const uint8_t *lo = parser.storage;
    const uint8_t *hi = parser.storage + sizeof parser.storage;
    CHECK(ev->kind == want->kind);
    CHECK(ev->raw_len == want->len);
    CHECK(ev->raw != NULL && ev->raw >= lo && ev->raw + ev->raw_len <= hi);
    CHECK(memcmp(ev->raw, ref.bytes + want->start, want->len) == 0);
    CHECK(ev->raw[0] == 0xFF && ev->raw[1] == 0xFF && ev->raw[2] != 0xFF);
    CHECK(ev->id == ev->raw[2]);
    if (ev->kind == DXL_EVENT_PACKET) {
        uint8_t len = ev->raw[3];
        CHECK(len >= DXL_MIN_LEN_FIELD && len <= DXL_MAX_LEN_FIELD);
        CHECK(ev->raw_len == len + 4u);
        CHECK(ev->code == ev->raw[4]);
        CHECK(ev->nparams == len - 2u);
        CHECK(ev->params == ev->raw + 5);
        CHECK(dxl_checksum(ev->raw + 2, len + 1u) == ev->raw[len + 3u]);
    } else if (ev->kind == DXL_EVENT_BAD_CHECKSUM) {
        CHECK(ev->code == ev->raw[4] && ev->nparams == 0 && ev->params == NULL);
    } else {
        CHECK(ev->kind == DXL_EVENT_BAD_LENGTH);
        CHECK(ev->code == 0 && ev->nparams == 0 && ev->params == NULL);
    }
}

/* Poll until the parser has nothing more; returns the events seen. */
static unsigned drain(void)
{
    dxl_event ev;
    ref_event want;
    unsigned n = 0;
    for (;;) {
        while (dxl_parser_poll(&parser, &ev)) {
            CHECK(ref_next(&ref, &want)); /* the parser saw an event the reference did not */
            check_event(&ev, &want);
            n++;
            CHECK(n <= 2u * DXL_MAX_PACKET + 2u); /* bounded: at most one event per byte held */
        }
        CHECK(!ref_next(&ref, &want)); /* the reference had an event the parser did not report */
        if (!hunt) break;
        bool took = dxl_parser_skip_to_hidden(&parser);
        CHECK(took == ref_skip(&ref)); /* and then the same bytes are held (below, or next poll) */
        CHECK(dxl_parser_pending(&parser) == ref.end - ref.pos);
        if (!took) break;
    }
    CHECK(dxl_parser_pending(&parser) == ref.end - ref.pos);
    CHECK(dxl_parser_pending(&parser) <= DXL_MAX_PACKET);
    return n;
}

static void feed(uint8_t byte)
{
    if (!dxl_parser_feed(&parser, byte)) {
        CHECK(dxl_parser_pending(&parser) == DXL_MAX_PACKET);
        drain();
        CHECK(dxl_parser_pending(&parser) < DXL_MAX_PACKET); /* polling always frees room */
        CHECK(dxl_parser_feed(&parser, byte));
    }
    ref_push(&ref, byte);
}

/* ---- mode 2: every packet the encoder builds parses back as itself ----------------------- */

static void round_trip(const uint8_t *data, size_t size)
{
    uint8_t out[DXL_MAX_PACKET + 8];
    if (size < 3) return;
    uint8_t id = data[0];
    uint8_t code = data[1];
    size_t nparams = size - 2 > DXL_MAX_PARAMS + 4 ? DXL_MAX_PARAMS + 4 : size - 2;
    size_t cap = (size_t)data[2] + 6u; /* sometimes too small on purpose */
    if (cap > sizeof out) cap = sizeof out;
    size_t n = dxl_encode(out, cap, id, code, data + 2, nparams);
    bool fits = id <= DXL_BROADCAST_ID && nparams <= DXL_MAX_PARAMS && nparams + 6 <= cap;
    CHECK((n != 0) == fits);
    if (n == 0) return;
    CHECK(n == nparams + 6);
    dxl_parser p;
    dxl_event ev;
    dxl_parser_reset(&p);
    for (size_t i = 0; i < n; i++) CHECK(dxl_parser_feed(&p, out[i]));
    CHECK(dxl_parser_poll(&p, &ev));
    CHECK(ev.kind == DXL_EVENT_PACKET && ev.id == id && ev.code == code);
    CHECK(ev.nparams == nparams && memcmp(ev.params, data + 2, nparams) == 0);
    CHECK(!dxl_parser_poll(&p, &ev));
    CHECK(dxl_parser_pending(&p) == 0);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2) return 0;
    if (data[0] == 0xFF) {
        round_trip(data + 1, size - 1);
        return 0;
    }
    uint8_t mode = data[0];
    unsigned burst = (mode & 0x07u) + 1u; /* bytes between polls */
    bool greedy = (mode & 0x08u) != 0;    /* poll only when a byte is refused */
    bool with_reset = (mode & 0x10u) != 0;
    hunt = (mode & 0x20u) != 0;
    bool quiet = hunt && (mode & 0x40u) != 0; /* as a receiver that polls every byte may */
    size_t reset_at = data[1];
    const uint8_t *stream = data + 2;
    size_t n = size - 2;
    if (n > MAX_STREAM) n = MAX_STREAM;

    dxl_parser_reset(&parser);
    ref.pos = ref.end = 0; /* the bytes themselves need no clearing */
    for (size_t i = 0; i < n; i++) {
        if (with_reset && i == reset_at) {
            dxl_parser_reset(&parser);
            ref.pos = ref.end;
            CHECK(dxl_parser_pending(&parser) == 0);
        }
        if (quiet) {
            size_t upto = with_reset && reset_at > i && reset_at < n ? reset_at : n;
            size_t k = dxl_parser_feed_quiet(&parser, stream + i, upto - i);
            CHECK(k <= upto - i);
            for (size_t j = 0; j < k; j++) {
                ref_event want;
                ref_push(&ref, stream[i + j]);
                CHECK(!ref_next(&ref, &want) && !ref_skip(&ref)); /* nothing was due */
            }
            CHECK(dxl_parser_pending(&parser) == ref.end - ref.pos);
            i += k;
            if (i == upto) {
                i--; /* the reset (or the end) comes next */
                continue;
            }
        }
        feed(stream[i]);
        if (!greedy && (i + 1) % burst == 0) drain();
    }
    drain();
    return 0;
}
