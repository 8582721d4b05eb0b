#include "store_lib.h"

#include <stddef.h>

#include "crc32.h"
#include "hal_io.h"
#include "store_slots.h"

#define E_KIND 0U
#define E_AREA 1U
#define E_LEN 2U
#define E_CRC 4U
#define E_NAME 8U
#define AREAS (STORE_LIB_SLOTS + 1U)

__attribute__((weak)) void store_lib_pause(void)
{
}

uint32_t store_lib_capacity(const store_lib_t *lib)
{
    return lib->area_size < 0xFFFFU ? lib->area_size : 0xFFFFU;
}

/* Flash bytes [addr, addr + len) into out (addr even). */
static void read_bytes(uint32_t addr, uint8_t *out, uint32_t len)
{
    for (uint32_t i = 0; i < len; i += 2U) {
        uint16_t hw = hal_io_read16(addr + i);
        out[i] = (uint8_t)hw;
        if (i + 1U < len) {
            out[i + 1U] = (uint8_t)(hw >> 8);
        }
    }
}

/* The committed directory into dir; an absent one reads as all slots empty. */
static void load_dir(const store_lib_t *lib, uint8_t dir[STORE_LIB_DIR_BYTES])
{
    store_record_t rec;
    if (store_slots_newest(&lib->dir, &rec) && rec.len == STORE_LIB_DIR_BYTES) {
        read_bytes(lib->dir.base + rec.offset, dir, STORE_LIB_DIR_BYTES);
    } else {
        for (uint32_t i = 0; i < STORE_LIB_DIR_BYTES; i++) {
            dir[i] = 0;
        }
    }
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) {
        p[i] = (uint8_t)(v >> (8 * i));
    }
}

/* An entry that is in use and points inside the library; anything else counts as empty. */
static bool entry_used(const store_lib_t *lib, const uint8_t *e)
{
    uint32_t len = (uint32_t)e[E_LEN] | (uint32_t)e[E_LEN + 1U] << 8;
    return e[E_KIND] != STORE_LIB_KIND_EMPTY && e[E_AREA] < AREAS && len != 0U &&
           len <= store_lib_capacity(lib);
}

store_lib_status_t store_lib_entry(const store_lib_t *lib, uint8_t slot, store_lib_entry_t *out)
{
    if (slot >= STORE_LIB_SLOTS) {
        return STORE_LIB_BAD_SLOT;
    }
    uint8_t dir[STORE_LIB_DIR_BYTES];
    load_dir(lib, dir);
    const uint8_t *e = dir + slot * STORE_LIB_ENTRY_BYTES;
    if (!entry_used(lib, e)) {
        return STORE_LIB_EMPTY;
    }
    out->kind = e[E_KIND];
    out->len = (uint16_t)(e[E_LEN] | e[E_LEN + 1U] << 8);
    out->crc = get32(e + E_CRC);
    out->addr = lib->areas.base + e[E_AREA] * lib->area_size;
    for (uint32_t i = 0; i < STORE_LIB_NAME_MAX; i++) {
        out->name[i] = e[E_NAME + i];
    }
    return store_slots_flash_crc(out->addr, out->len) == out->crc ? STORE_LIB_OK : STORE_LIB_DAMAGED;
}

/* Write dir as the new committed directory. */
static store_lib_status_t save_dir(const store_lib_t *lib, const uint8_t *dir)
{
    return store_slots_save(&lib->dir, dir, STORE_LIB_DIR_BYTES) == HAL_FLASH_OK
               ? STORE_LIB_OK
               : STORE_LIB_FLASH;
}

/* An area no used entry points at, starting after the slot's current one so that writes
 * wander over all areas rather than wearing one. There are AREAS > STORE_LIB_SLOTS. */
static uint8_t free_area(const store_lib_t *lib, const uint8_t *dir, uint8_t after)
{
    bool taken[AREAS] = {false};
    for (uint32_t s = 0; s < STORE_LIB_SLOTS; s++) {
        const uint8_t *e = dir + s * STORE_LIB_ENTRY_BYTES;
        if (entry_used(lib, e)) {
            taken[e[E_AREA]] = true;
        }
    }
    uint8_t a = after;
    for (uint32_t n = 0; n < AREAS; n++) {
        a = (uint8_t)((a + 1U) % AREAS);
        if (!taken[a]) {
            break;
        }
    }
    return a;
}

store_lib_status_t store_lib_put(const store_lib_t *lib, uint8_t slot, uint8_t kind,
                                 const uint8_t *name, const uint8_t *data, uint32_t len)
{
    if (slot >= STORE_LIB_SLOTS) {
        return STORE_LIB_BAD_SLOT;
    }
    if (kind == STORE_LIB_KIND_EMPTY || data == NULL || len == 0U ||
        len > store_lib_capacity(lib) || name == NULL) {
        return STORE_LIB_BAD_BLOB;
    }
    uint8_t dir[STORE_LIB_DIR_BYTES];
    load_dir(lib, dir);
    uint8_t *e = dir + slot * STORE_LIB_ENTRY_BYTES;
    uint8_t area = free_area(lib, dir, entry_used(lib, e) ? e[E_AREA] : (uint8_t)slot);
    uint32_t offset = area * lib->area_size;
    /* The data first, into an area nothing committed refers to; then the directory. A
     * page at a time, with a pause after each for the board (a 32 KB blob holds the CPU
     * for over a second, longer than the watchdog waits). */
    uint32_t page = lib->areas.page_size;
    for (uint32_t at = 0; at < len; at += page) {
        uint32_t n = len - at < page ? len - at : page;
        if (hal_flash_erase(&lib->areas, offset + at, n) != HAL_FLASH_OK ||
            hal_flash_write(&lib->areas, offset + at, data + at, n) != HAL_FLASH_OK) {
            return STORE_LIB_FLASH;
        }
        store_lib_pause();
    }
    e[E_KIND] = kind;
    e[E_AREA] = area;
    e[E_LEN] = (uint8_t)len;
    e[E_LEN + 1U] = (uint8_t)(len >> 8);
    put32(e + E_CRC, crc32_compute(data, len));
    for (uint32_t i = 0; i < STORE_LIB_NAME_MAX; i++) {
        e[E_NAME + i] = name[i];
    }
    return save_dir(lib, dir);
}

store_lib_status_t store_lib_delete(const store_lib_t *lib, uint8_t slot)
{
    if (slot >= STORE_LIB_SLOTS) {
        return STORE_LIB_BAD_SLOT;
    }
    uint8_t dir[STORE_LIB_DIR_BYTES];
    load_dir(lib, dir);
    uint8_t *e = dir + slot * STORE_LIB_ENTRY_BYTES;
    if (!entry_used(lib, e)) {
        return STORE_LIB_OK;
    }
    for (uint32_t i = 0; i < STORE_LIB_ENTRY_BYTES; i++) {
        e[i] = 0;
    }
    return save_dir(lib, dir);
}
