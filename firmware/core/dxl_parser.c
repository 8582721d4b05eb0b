#include "dxl_parser.h"

#include <string.h>

/* Compile-time checks: the storage holds the ring twice, and a window of a whole packet
 * starting at any slot stays inside it. */
typedef char dxl_parser_storage_check[
    (sizeof(((dxl_parser *)0)->storage) == DXL_PARSER_STORAGE
     && DXL_PARSER_STORAGE == 2 * DXL_PARSER_RING && DXL_PARSER_RING == 256
     && DXL_MAX_PACKET < DXL_PARSER_RING) ? 1 : -1];

/* The i-th unconsumed byte (i < count <= DXL_MAX_PACKET < DXL_PARSER_RING). */
static uint8_t at(const dxl_parser *p, uint16_t i)
{
    return p->storage[(uint8_t)(p->start + i)];
}

/* `waiting` when the bytes a hunt looked at hold no candidate short of bytes. */
#define NO_CANDIDATE UINT8_MAX

static void drop(dxl_parser *p, uint16_t n)
{
    p->start = (uint8_t)(p->start + n);
    p->count = (uint16_t)(p->count - n);
    p->hunted = p->hunted > n ? (uint16_t)(p->hunted - n) : 0u;
    /* The stretch known to hold no candidate that may yet complete moves down with the
     * bytes; with the first such candidate dropped (or now at the front) nothing is known. */
    if (p->waiting != NO_CANDIDATE) {
        p->waiting = p->waiting > n ? (uint8_t)(p->waiting - n) : 0u;
    }
}

void dxl_parser_reset(dxl_parser *p)
{
    p->start = 0;
    p->waiting = 0;
    p->count = 0;
    p->hunted = 0;
}

bool dxl_parser_feed(dxl_parser *p, uint8_t byte)
{
    if (p->count >= DXL_MAX_PACKET) {
        return false;
    }
    uint8_t slot = (uint8_t)(p->start + p->count);
    p->storage[slot] = byte;
    p->storage[slot + DXL_PARSER_RING] = byte;
    p->count++;
    return true;
}

uint16_t dxl_parser_pending(const dxl_parser *p)
{
    return p->count;
}

/* Fill *ev for the candidate at the front of the buffer (raw_len <= count). */
static void report(const dxl_parser *p, dxl_event *ev, uint8_t kind, uint16_t raw_len)
{
    const uint8_t *raw = &p->storage[p->start]; /* start + raw_len <= 255 + 250 < 512 */
    ev->kind = kind;
    ev->id = raw[2];
    ev->code = kind == DXL_EVENT_BAD_LENGTH ? 0 : raw[4];
    ev->nparams = kind == DXL_EVENT_PACKET ? (uint8_t)(raw[3] - 2u) : 0;
    ev->params = kind == DXL_EVENT_PACKET ? &raw[5] : NULL;
    ev->raw = raw;
    ev->raw_len = raw_len;
}

bool dxl_parser_poll(dxl_parser *p, dxl_event *ev)
{
    /* (1) find FF FF at the front; keep a lone trailing FF */
    while (p->count >= 2 && !(at(p, 0) == DXL_HEADER_BYTE && at(p, 1) == DXL_HEADER_BYTE)) {
        drop(p, 1);
    }
    if (p->count < 2) {
        if (p->count == 1 && at(p, 0) != DXL_HEADER_BYTE) {
            drop(p, 1);
        }
        return false;
    }
    /* (2) in a run of FFs, the last two are the header */
    while (p->count >= 3 && at(p, 2) == DXL_HEADER_BYTE) {
        drop(p, 1);
    }
    if (p->count < 4) {
        return false;
    }
    /* (3) a possible length? */
    uint8_t len = at(p, 3);
    if (len < DXL_MIN_LEN_FIELD || len > DXL_MAX_LEN_FIELD) {
        report(p, ev, DXL_EVENT_BAD_LENGTH, 4);
        drop(p, 1);
        return true;
    }
    uint16_t total = (uint16_t)(len + 4u);
    if (p->count < total) {
        return false;
    }
    /* (4) the checksum, over ID .. last param */
    uint8_t sum = 0;
    for (uint16_t i = 2; i + 1u < total; i++) {
        sum = (uint8_t)(sum + at(p, i));
    }
    uint8_t expected = (uint8_t)~sum;
    if (expected != at(p, (uint16_t)(total - 1u))) {
        report(p, ev, DXL_EVENT_BAD_CHECKSUM, total);
        drop(p, 1);
        return true;
    }
    report(p, ev, DXL_EVENT_PACKET, total);
    drop(p, total);
    return true;
}

/* What starts at a header byte b[i] (i + 3 < count) for dxl_parser_skip_to_hidden. */
#define NOT_A_PACKET 0 /* and never will be: no header or LEN, or checked and found bad */
#define SHORT 1        /* a candidate still short of bytes */
#define GOOD 2         /* a whole packet with a good checksum */

static uint8_t candidate_at(const dxl_parser *p, const uint8_t *b, uint16_t i)
{
    if (b[i + 1u] != DXL_HEADER_BYTE || b[i + 2u] == DXL_HEADER_BYTE) {
        return NOT_A_PACKET;
    }
    uint8_t len = b[i + 3u];
    if (len < DXL_MIN_LEN_FIELD || len > DXL_MAX_LEN_FIELD) {
        return NOT_A_PACKET;
    }
    uint16_t end = (uint16_t)(i + len + 4u);
    if (end > p->count) {
        return SHORT;
    }
    if (end <= p->hunted) {
        return NOT_A_PACKET; /* already checked */
    }
    uint8_t expected = dxl_checksum(&b[i + 2u], (size_t)len + 1u);
    return expected == b[end - 1u] ? GOOD : NOT_A_PACKET;
}

bool dxl_parser_skip_to_hidden(dxl_parser *p)
{
    if (p->count < 5u) { /* FF FF at index 1 or later, with its LEN */
        p->hunted = p->count;
        return false;
    }
    /* The unconsumed bytes are contiguous in storage (each byte is stored twice). */
    const uint8_t *b = &p->storage[p->start];
    uint16_t limit = (uint16_t)(p->count - 3u); /* a header needs 4 bytes to say its LEN */
    /* The last hunt looked at 1 .. hunted - 4, and the first candidate there still short
     * of bytes starts at `waiting`: before that nothing can complete, so a packet arriving
     * byte by byte costs a step per byte here, not a pass over all of it (which is why a
     * plain loop serves: memchr's call cost more than the byte or two it looked at). */
    uint16_t seen = p->hunted > 3u ? (uint16_t)(p->hunted - 3u) : 0u;
    uint16_t from = p->waiting < seen ? p->waiting : seen;
    uint8_t first = NO_CANDIDATE;
    for (uint16_t i = from > 1u ? from : 1u; i < limit; i++) {
        if (b[i] != DXL_HEADER_BYTE) {
            continue;
        }
        uint8_t found = candidate_at(p, b, i);
        if (found == GOOD) {
            drop(p, i);
            return true;
        }
        if (found == SHORT && first == NO_CANDIDATE) {
            first = (uint8_t)i;
        }
    }
    p->hunted = p->count;
    p->waiting = first;
    return false;
}

size_t dxl_parser_feed_quiet(dxl_parser *p, const uint8_t *bytes, size_t n)
{
    /* Right after a hunt that found nothing (hunted == count) and left no candidate short
     * of bytes, with a whole header in front whose packet is still short: until its last
     * byte, only a header byte (in the last three held, not yet looked at as a start, or
     * among the new ones) could begin anything a poll or a hunt would report. */
    if (p->hunted != p->count || p->waiting != NO_CANDIDATE || p->count < 5u) {
        return 0;
    }
    if (at(p, 0) != DXL_HEADER_BYTE || at(p, 1) != DXL_HEADER_BYTE ||
        at(p, 2) == DXL_HEADER_BYTE) {
        return 0;
    }
    uint8_t len = at(p, 3);
    uint16_t total = (uint16_t)(len + 4u);
    if (len < DXL_MIN_LEN_FIELD || len > DXL_MAX_LEN_FIELD || p->count >= total) {
        return 0;
    }
    for (uint16_t i = (uint16_t)(p->count - 3u); i < p->count; i++) {
        if (at(p, i) == DXL_HEADER_BYTE) {
            return 0;
        }
    }
    size_t k = (size_t)(total - 1u - p->count); /* the last byte goes the usual way */
    if (k > n) {
        k = n;
    }
    const uint8_t *header = k > 0 ? memchr(bytes, DXL_HEADER_BYTE, k) : NULL;
    if (header != NULL) {
        k = (size_t)(header - bytes);
    }
    /* in at most two runs (the ring wraps), each in both of its places */
    uint8_t slot = (uint8_t)(p->start + p->count);
    size_t to_wrap = (size_t)(DXL_PARSER_RING - slot);
    size_t run = to_wrap < k ? to_wrap : k;
    memcpy(&p->storage[slot], bytes, run);
    memcpy(&p->storage[slot + DXL_PARSER_RING], bytes, run);
    memcpy(&p->storage[0], bytes + run, k - run);
    memcpy(&p->storage[DXL_PARSER_RING], bytes + run, k - run);
    p->count = (uint16_t)(p->count + k); /* still below total <= DXL_MAX_PACKET */
    /* as a hunt after each of them would have left it (it looked at nothing new) */
    p->hunted = p->count;
    return k;
}
