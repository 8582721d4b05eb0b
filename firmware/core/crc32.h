/* CRC-32 (IEEE 802.3, reflected, poly 0xEDB88320): the checksum of gait tables.
 * Incremental, so a table can be checked as its chunks arrive. */
#ifndef SNAKEBOT_CRC32_H
#define SNAKEBOT_CRC32_H

#include <stddef.h>
#include <stdint.h>

/* cffi:begin */
/* Start value for crc32_update(). */
#define CRC32_INIT 0xFFFFFFFF
/* Feed len bytes into a running CRC; start from CRC32_INIT. */
uint32_t crc32_update(uint32_t state, const uint8_t *data, size_t len);
/* Turn a running CRC into the final checksum (the same value zlib.crc32 gives). */
uint32_t crc32_final(uint32_t state);
/* One-shot CRC-32 of a buffer. */
uint32_t crc32_compute(const uint8_t *data, size_t len);
/* cffi:end */

#endif
