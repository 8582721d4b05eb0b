/* What the PC-link fuzz target's files share (fuzz_pclink.c, pclink_store_model.c,
 * pclink_builders.c): the device's table sizes, the input reader, and the small byte
 * helpers. The reader and crc_of() take no part in coverage (harness_ignore.txt). */
#ifndef SNAKEBOT_FUZZ_PCLINK_COMMON_H
#define SNAKEBOT_FUZZ_PCLINK_COMMON_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <zlib.h>

/* The device's tables: the QEMU board's capacity (a CRC or a validation costs up to that
 * much after a change), in an arena of twice that, so no upload displaces the active
 * table (the checks hold that a table is never lost). */
#define FUZZ_CAPACITY 2048u
#define FUZZ_ARENA (2u * FUZZ_CAPACITY)

/* ---- the input --------------------------------------------------------------------------- */

typedef struct {
    const uint8_t *p;
    size_t n;
} src;

static inline uint8_t u8(src *s)
{
    if (s->n == 0) return 0;
    s->n--;
    return *s->p++;
}

static inline uint16_t u16(src *s)
{
    uint16_t lo = u8(s);
    return (uint16_t)(lo | ((uint16_t)u8(s) << 8));
}

static inline void bytes(src *s, uint8_t *out, size_t n)
{
    size_t have = n < s->n ? n : s->n;
    memcpy(out, s->p, have);
    memset(out + have, 0, n - have); /* missing bytes read as 0 */
    s->p += have;
    s->n -= have;
}

/* ---- bytes ------------------------------------------------------------------------------- */

static inline void put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

/* CRC-32 as the host works it out, by zlib's crc32 (the same IEEE 802.3 CRC): an
 * implementation independent of the core's crc32.c, and uninstrumented, so checking the
 * registers' Table CRC against it costs a small part of the core's bytewise loop. */
static inline uint32_t crc_of(const uint8_t *p, size_t n)
{
    return (uint32_t)crc32(0uL, p, (uInt)n);
}

#endif
