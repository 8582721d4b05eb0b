/* The PC-link fuzz target's builders (pclink_builders.h). */
#include "pclink_builders.h"

#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <zlib.h>

#include "ctl_device.h"
#include "dxl_packet.h"
#include "gt_table.h"
#include "prog_run.h"

#include "pclink_common.h"

/* ---- sealing ------------------------------------------------------------------------- */

/* Store the CRC a table or a program carries at its offset 12: gt_crc()'s (bytes 0..11,
 * then 16 on), worked out as crc_of() does rather than by the instrumented core. */
#if PROG_CRC_OFFSET != GT_CRC_OFFSET
#error "seal() puts a program's CRC where a table's goes"
#endif
void seal(uint8_t *t, size_t len)
{
    uLong crc = crc32(0uL, t, GT_CRC_OFFSET);
    crc = crc32(crc, t + GT_CRC_OFFSET + 4u, (uInt)(len - GT_CRC_OFFSET - 4u));
    for (unsigned b = 0; b < 4; b++) t[GT_CRC_OFFSET + b] = (uint8_t)(crc >> (8 * b));
}

/* ---- gait tables --------------------------------------------------------------------- */

/* A valid table from the input: joints 1..18, frames within the 2 KB, unique IDs. */
size_t make_table(src *s, uint8_t *t)
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

/* ---- programs ------------------------------------------------------------------------ */

/* A program from the input (protocol/program.md): 1..4 joints with limits around a zero
 * tick, up to 4 frames, 2 periodic blocks and 6 segments of any kind with fields from
 * the input, most of them beyond what the joints allow; its CRC made right. */
size_t make_program(src *s, uint8_t *t)
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

/* ---- the bus's answers --------------------------------------------------------------- */

void read_answer(src *s, bus_answer_t *a)
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
size_t make_reply(const bus_answer_t *a, const dxl_event *read, uint8_t *rx, size_t cap,
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
