/* A record store in flash that survives a power cut at any instant: the region is split
 * into two slots, each holding at most one record
 *
 *     0  magic "SNKS"   4  sequence number (u32)   8  length (u16)   10  0xFFFF
 *    12  CRC-32 of the data   16  the data
 *
 * A save erases and writes the slot that does NOT hold the newest record, and programs
 * the magic last; the newest valid record (magic, length and CRC all right, highest
 * sequence number) is the one loaded. A cut during a save therefore leaves either the
 * previous record (the new one has no magic or a wrong CRC) or the new one, never
 * neither. Flash is read with hal_io_read16 like everything the HAL touches, so the store
 * runs on the host against the flash register model too. */
#ifndef SNAKEBOT_STORE_SLOTS_H
#define SNAKEBOT_STORE_SLOTS_H

#include <stdbool.h>
#include <stdint.h>

#include "hal_flash.h"

#define STORE_SLOTS_HEADER_BYTES 16U

typedef struct {
    uint32_t offset; /* where the data starts, from the region's base */
    uint32_t len;    /* bytes of data */
    uint32_t seq;    /* sequence number: higher (mod 2^32) is newer */
} store_record_t;

/* The largest record the region takes (the region must be an even number of pages). */
uint32_t store_slots_capacity(const hal_flash_region_t *r);

/* The newest valid record into *out; false if there is none. */
bool store_slots_newest(const hal_flash_region_t *r, store_record_t *out);

/* CRC-32 of the flash bytes [addr, addr + len) (addr even), read half-word by half-word. */
uint32_t store_slots_flash_crc(uint32_t addr, uint32_t len);

/* Write data[0..len) as a new record in the slot not holding the newest one (all of
 * store_slots_begin() and store_slots_step() at once). */
hal_flash_status_t store_slots_save(const hal_flash_region_t *r, const uint8_t *data,
                                    uint32_t len);

/* The same save, a bounded step at a time, so that a large record never holds up the
 * control loop for long: the caller runs one step per control tick, and may abandon the
 * job at any point (the half-written slot has no magic: the previous record stays).
 * Order: find the newest record (reading one slot per step), erase the other slot a page
 * per step, program the data, then the header but the magic, then the magic, then read
 * the new record back. data[0..len) must not change meanwhile: if the bytes programmed
 * do not have the CRC the data had at the start, the magic is never written and the job
 * ends in HAL_FLASH_ERR_VERIFY. */
typedef struct {
    const hal_flash_region_t *r;
    const uint8_t *data;
    uint32_t len;
    uint32_t slot;   /* while finding: the newest record's slot + 1 (0: none); then the
                      * offset of the slot being written */
    uint32_t seq;    /* while finding: the newest record's; then the new record's */
    uint32_t done;   /* the phase's progress: slots read, slot bytes erased, data bytes
                      * programmed */
    uint32_t expect; /* CRC-32 of data[0..len) when the save began */
    uint32_t crc;    /* CRC-32 state of the data bytes programmed so far */
    uint8_t phase;   /* internal */
    uint8_t status;  /* hal_flash_status_t: the first failure, else OK */
    uint8_t bare;    /* store_slots_begin_bare(): no record, only the data */
} store_slots_job_t;

/* Start saving data[0..len): HAL_FLASH_OK, or HAL_FLASH_ERR_RANGE (nothing to do). */
hal_flash_status_t store_slots_begin(store_slots_job_t *job, const hal_flash_region_t *r,
                                     const uint8_t *data, uint32_t len);
/* The same steps for bare data (a library blob): erase the pages of r covering
 * [offset, offset + len) (offset page-aligned) a page per step, program data[0..len)
 * there, then read it back; HAL_FLASH_ERR_VERIFY if the bytes programmed or read back do
 * not have the CRC the data had at the start (job->expect). No header, no magic: what
 * refers to the data is written after it, by the caller. */
hal_flash_status_t store_slots_begin_bare(store_slots_job_t *job, const hal_flash_region_t *r,
                                          uint32_t offset, const uint8_t *data, uint32_t len);
/* One step: the CRC of one slot read, or one page erased, or at most max(halfwords, 6)
 * half-words programmed. True while steps remain; then job->status tells the outcome. */
bool store_slots_step(store_slots_job_t *job, uint32_t halfwords);
/* How far the job is, 0..100: erasing counts for the first half, programming for the
 * second (100 once the data is programmed). */
uint8_t store_slots_progress(const store_slots_job_t *job);

#endif
