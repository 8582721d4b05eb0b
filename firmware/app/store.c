/* Table store: a 12-byte record header, then the table.
 *   0  magic "SNKS"   4  length (u16)   6  0xFFFF   8  CRC-32 of the table
 * The magic is written last, so a record cut short by a reset is never taken for one. */
#include "store.h"

#include <stddef.h>
#include <stdint.h>

#include "board.h"
#include "crc32.h"

#if BOARD_HAS_FLASH_STORE

#include "hal_flash.h"

#define STORE_MAGIC 0x534B4E53UL /* "SNKS" little-endian */
#define HEADER_BYTES 12U

static const hal_flash_region_t region = {BOARD_STORE_BASE, BOARD_STORE_SIZE,
                                          BOARD_FLASH_PAGE_SIZE};

typedef char store_holds_a_table[BOARD_STORE_SIZE >= HEADER_BYTES + CTL_MAX_TABLE_BYTES ? 1 : -1];

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put_le32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

bool store_load(ctl_device *ctl)
{
    const uint8_t *rec = (const uint8_t *)BOARD_STORE_BASE;
    uint32_t len = (uint32_t)rec[4] | (uint32_t)rec[5] << 8;
    if (le32(rec) != STORE_MAGIC || len == 0U || len > CTL_MAX_TABLE_BYTES) {
        return false;
    }
    const uint8_t *table = rec + HEADER_BYTES;
    if (crc32_compute(table, len) != le32(rec + 8)) {
        return false;
    }
    return ctl_load_table(ctl, table, len);
}

bool store_save(const ctl_device *ctl)
{
    size_t len = 0;
    const uint8_t *table = ctl_active_table(ctl, &len);
    if (table == NULL || len == 0U || len > CTL_MAX_TABLE_BYTES) {
        return false;
    }
    uint8_t header[HEADER_BYTES];
    put_le32(header, 0xFFFFFFFFUL); /* magic: later */
    header[4] = (uint8_t)len;
    header[5] = (uint8_t)(len >> 8);
    header[6] = 0xFF;
    header[7] = 0xFF;
    put_le32(header + 8, crc32_compute(table, len));
    if (hal_flash_erase(&region, 0, HEADER_BYTES + (uint32_t)len) != HAL_FLASH_OK ||
        hal_flash_write(&region, 4, header + 4, HEADER_BYTES - 4U) != HAL_FLASH_OK ||
        hal_flash_write(&region, HEADER_BYTES, table, (uint32_t)len) != HAL_FLASH_OK) {
        return false;
    }
    put_le32(header, STORE_MAGIC);
    return hal_flash_write(&region, 0, header, 4) == HAL_FLASH_OK;
}

#else

bool store_load(ctl_device *ctl)
{
    (void)ctl;
    return false;
}

bool store_save(const ctl_device *ctl)
{
    (void)ctl;
    return false;
}

#endif
