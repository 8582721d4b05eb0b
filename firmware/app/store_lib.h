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
#include "store_slots.h"

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

/* A store or delete under way, run a bounded step at a time (store_lib_step) so that a
 * 32 KB blob never holds up the control loop: the blob's area a page erase or a run of
 * half-words per step (store_slots' bare steps), then the directory as a store_slots
 * record (its steps). A job abandoned at any step, or cut by a power failure, leaves the
 * committed directory, hence every slot, as it was. */
typedef struct {
    const store_lib_t *lib;
    store_slots_job_t write;          /* the area's, then the directory's */
    uint8_t dir[STORE_LIB_DIR_BYTES]; /* the directory to commit */
    uint8_t stage;                    /* internal */
    uint8_t status;                   /* store_lib_status_t, once no steps remain */
} store_lib_job_t;

/* Start storing data[0..len) as slot `slot` with the given kind and name
 * (STORE_LIB_NAME_MAX bytes, zero-padded), replacing what it held: STORE_LIB_OK and the
 * job to step, or why not (nothing written). data[0..len) must stay as it is until the
 * job ends (if it changes, the job ends in STORE_LIB_FLASH and nothing changed). */
store_lib_status_t store_lib_begin_put(store_lib_job_t *job, const store_lib_t *lib, uint8_t slot,
                                       uint8_t kind, const uint8_t *name, const uint8_t *data,
                                       uint32_t len);
/* Start emptying slot `slot` (a job with no steps if it is empty already). */
store_lib_status_t store_lib_begin_delete(store_lib_job_t *job, const store_lib_t *lib,
                                          uint8_t slot);
/* One step, as store_slots_step() bounds it. True while steps remain; then job->status
 * tells the outcome. */
bool store_lib_step(store_lib_job_t *job, uint32_t halfwords);
/* How far the job is, 0..100. */
uint8_t store_lib_progress(const store_lib_job_t *job);

/* The same, all steps at once (tests and tools; the firmware steps). */
store_lib_status_t store_lib_put(const store_lib_t *lib, uint8_t slot, uint8_t kind,
                                 const uint8_t *name, const uint8_t *data, uint32_t len);
store_lib_status_t store_lib_delete(const store_lib_t *lib, uint8_t slot);

#endif
