#include "store_slots.h"

#include <stddef.h>

#include "crc32.h"
#include "hal_io.h"

#define MAGIC 0x534B4E53UL /* "SNKS" little-endian */
#define OFF_MAGIC 0U
#define OFF_SEQ 4U
#define OFF_LEN 8U
#define OFF_CRC 12U

static uint32_t slot_size(const hal_flash_region_t *r)
{
    /* Whole pages per slot, so erasing one slot never touches the other. */
    return (r->size / 2U) & ~(r->page_size - 1U);
}

uint32_t store_slots_capacity(const hal_flash_region_t *r)
{
    uint32_t s = slot_size(r);
    return s > STORE_SLOTS_HEADER_BYTES ? s - STORE_SLOTS_HEADER_BYTES : 0U;
}

uint32_t store_slots_flash_crc(uint32_t addr, uint32_t len)
{
    uint32_t crc = CRC32_INIT;
    for (uint32_t i = 0; i < len; i += 2U) {
        uint16_t hw = hal_io_read16(addr + i);
        uint8_t bytes[2] = {(uint8_t)hw, (uint8_t)(hw >> 8)};
        crc = crc32_update(crc, bytes, (i + 1U < len) ? 2U : 1U);
    }
    return crc32_final(crc);
}

static uint16_t read16(const hal_flash_region_t *r, uint32_t offset)
{
    return hal_io_read16(r->base + offset);
}

static uint32_t read32(const hal_flash_region_t *r, uint32_t offset)
{
    return (uint32_t)read16(r, offset) | (uint32_t)read16(r, offset + 2U) << 16;
}

/* The record in the slot at `slot`, if it is whole. */
static bool slot_record(const hal_flash_region_t *r, uint32_t slot, store_record_t *out)
{
    if (read32(r, slot + OFF_MAGIC) != MAGIC) {
        return false;
    }
    uint32_t len = read16(r, slot + OFF_LEN);
    if (len == 0U || len > store_slots_capacity(r)) {
        return false;
    }
    uint32_t data = slot + STORE_SLOTS_HEADER_BYTES;
    if (store_slots_flash_crc(r->base + data, len) != read32(r, slot + OFF_CRC)) {
        return false;
    }
    out->offset = data;
    out->len = len;
    out->seq = read32(r, slot + OFF_SEQ);
    return true;
}

/* Index (0 or 1) of the slot holding the newest record, or -1 if neither is valid. */
static int newest_slot(const hal_flash_region_t *r, store_record_t *out)
{
    store_record_t rec[2];
    bool ok[2];
    for (int i = 0; i < 2; i++) {
        ok[i] = slot_record(r, (uint32_t)i * slot_size(r), &rec[i]);
    }
    int best = -1;
    if (ok[0] && ok[1]) {
        best = (int32_t)(rec[1].seq - rec[0].seq) > 0 ? 1 : 0;
    } else if (ok[0] || ok[1]) {
        best = ok[0] ? 0 : 1;
    }
    if (best >= 0) {
        *out = rec[best];
    }
    return best;
}

bool store_slots_newest(const hal_flash_region_t *r, store_record_t *out)
{
    return newest_slot(r, out) >= 0;
}

static void put_le32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) {
        p[i] = (uint8_t)(v >> (8 * i));
    }
}

hal_flash_status_t store_slots_save(const hal_flash_region_t *r, const uint8_t *data,
                                    uint32_t len)
{
    if (data == NULL || len == 0U || len > store_slots_capacity(r) || len > 0xFFFFU) {
        return HAL_FLASH_ERR_RANGE;
    }
    store_record_t newest;
    int keep = newest_slot(r, &newest);
    uint32_t seq = keep >= 0 ? newest.seq + 1U : 1U;
    uint32_t slot = (keep == 0 ? 1U : 0U) * slot_size(r);

    uint8_t header[STORE_SLOTS_HEADER_BYTES];
    put_le32(header + OFF_MAGIC, MAGIC);
    put_le32(header + OFF_SEQ, seq);
    header[OFF_LEN] = (uint8_t)len;
    header[OFF_LEN + 1U] = (uint8_t)(len >> 8);
    header[OFF_LEN + 2U] = 0xFF;
    header[OFF_LEN + 3U] = 0xFF;
    put_le32(header + OFF_CRC, crc32_compute(data, len));

    /* Everything but the magic, then the magic: until its last half-word is programmed
     * the slot does not count, and the other slot still holds the previous record. */
    hal_flash_status_t st = hal_flash_erase(r, slot, STORE_SLOTS_HEADER_BYTES + len);
    if (st == HAL_FLASH_OK) {
        st = hal_flash_write(r, slot + OFF_SEQ, header + OFF_SEQ,
                             STORE_SLOTS_HEADER_BYTES - OFF_SEQ);
    }
    if (st == HAL_FLASH_OK) {
        st = hal_flash_write(r, slot + STORE_SLOTS_HEADER_BYTES, data, len);
    }
    if (st == HAL_FLASH_OK) {
        st = hal_flash_write(r, slot + OFF_MAGIC, header + OFF_MAGIC, 4U);
    }
    store_record_t check;
    if (st == HAL_FLASH_OK && (newest_slot(r, &check) != (int)(slot != 0U) || check.seq != seq)) {
        st = HAL_FLASH_ERR_VERIFY;
    }
    return st;
}
