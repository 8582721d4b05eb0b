/* The gait library in flash: STORE_LIB_SLOTS named slots, each holding one blob (a gait
 * table or a program, told apart by its kind byte), that survive power-off. Layout and
 * power-cut argument: protocol/library.md. In short, copy-on-write:
 *
 *  - STORE_LIB_SLOTS + 1 data areas of equal size; a blob is written into an area that
 *    the directory does not reference (there is always one), only the pages it needs are
 *    erased;
 *  - the directory (per slot: kind, area, length, CRC-32, name) is one store_slots record,
 *    so replacing it is atomic: a power cut leaves the previous directory or the new one.
 *
 * A store or delete therefore never touches an area a committed directory entry points
 * at: every other slot stays intact, and the slot being written is the old or the new
 * one. Flash is read through hal_io_read16 (as store_slots does), so this runs on the
 * host against the flash register model. */
#ifndef SNAKEBOT_STORE_LIB_H
#define SNAKEBOT_STORE_LIB_H

#include <stdbool.h>
#include <stdint.h>

#include "ctl_table.h"
#include "hal_flash.h"

#define STORE_LIB_SLOTS CTL_MAX_LIBRARY_SLOTS
#define STORE_LIB_NAME_MAX CTL_SLOT_NAME_SIZE
/* Bytes of one directory entry: kind, area, length (u16), CRC-32 (u32), name. */
#define STORE_LIB_ENTRY_BYTES (8U + STORE_LIB_NAME_MAX)
#define STORE_LIB_DIR_BYTES (STORE_LIB_SLOTS * STORE_LIB_ENTRY_BYTES)
/* Kind 0 marks an empty slot; any other kind is the caller's (table, program, ...). */
#define STORE_LIB_KIND_EMPTY 0U

/* Where a board keeps its library. */
typedef struct {
    hal_flash_region_t dir;   /* two slots of whole pages for the directory record */
    hal_flash_region_t areas; /* STORE_LIB_SLOTS + 1 areas of area_size bytes, in order */
    uint32_t area_size;       /* whole pages */
} store_lib_t;

typedef enum {
    STORE_LIB_OK = 0,
    STORE_LIB_EMPTY = 1,     /* the slot holds nothing */
    STORE_LIB_DAMAGED = 2,   /* the slot's data no longer matches its CRC (e.g. erased) */
    STORE_LIB_BAD_SLOT = 3,  /* slot index out of range */
    STORE_LIB_BAD_BLOB = 4,  /* kind 0, length 0, larger than an area, or no name */
    STORE_LIB_FLASH = 5      /* the flash driver failed (a half-written area is unused) */
} store_lib_status_t;

typedef struct {
    uint8_t kind;
    uint16_t len;
    uint32_t crc;
    uint32_t addr; /* where the blob lies (memory-mapped flash) */
    uint8_t name[STORE_LIB_NAME_MAX]; /* zero-padded */
} store_lib_entry_t;

/* Bytes a slot takes at most. */
uint32_t store_lib_capacity(const store_lib_t *lib);

/* Slot `slot`'s entry into *out; STORE_LIB_OK only if its data checks against its CRC
 * (then out->addr holds it). *out is filled for DAMAGED too (name, kind, length). */
store_lib_status_t store_lib_entry(const store_lib_t *lib, uint8_t slot, store_lib_entry_t *out);

/* Store data[0..len) as slot `slot` with the given kind and name (STORE_LIB_NAME_MAX
 * bytes, zero-padded), replacing what it held. Blocks while flash is erased and
 * programmed (up to about 0.1 s a page: 1.8 s for 32 KB), calling store_lib_pause()
 * after each page. */
store_lib_status_t store_lib_put(const store_lib_t *lib, uint8_t slot, uint8_t kind,
                                 const uint8_t *name, const uint8_t *data, uint32_t len);

/* Called between the pages store_lib_put() writes; the board's feeds the watchdog (the
 * default, weak, does nothing). */
void store_lib_pause(void);

/* Empty slot `slot` (a no-op, OK, if it is empty already). */
store_lib_status_t store_lib_delete(const store_lib_t *lib, uint8_t slot);

#endif
