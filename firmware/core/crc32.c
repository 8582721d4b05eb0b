#include "crc32.h"

/* Bitwise rather than table-driven: 1 KB of flash saved matters more on the CM-530
 * than speed, since tables are checked once per upload. */
uint32_t crc32_update(uint32_t state, const uint8_t *data, size_t len)
{
    for (size_t i = 0; i < len; i++) {
        state ^= data[i];
        for (int bit = 0; bit < 8; bit++) {
            uint32_t mask = (uint32_t)(-(int32_t)(state & 1u));
            state = (state >> 1) ^ (0xEDB88320u & mask);
        }
    }
    return state;
}

uint32_t crc32_final(uint32_t state)
{
    return state ^ 0xFFFFFFFFu;
}

uint32_t crc32_compute(const uint8_t *data, size_t len)
{
    return crc32_final(crc32_update(CRC32_INIT, data, len));
}
