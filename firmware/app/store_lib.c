#include "store_lib.h"

#include <stddef.h>

#include "hal_io.h"

#define E_KIND 0U
#define E_AREA 1U
#define E_LEN 2U
#define E_CRC 4U
#define E_NAME 8U
#define AREAS (STORE_LIB_SLOTS + 1U)

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

/* The job's stages, in order. */
enum { S_AREA, S_DIR, S_DONE };

/* Commit job->dir: the directory's steps from now on. */
static void begin_dir(store_lib_job_t *job)
{
    job->stage = S_DIR;
    if (store_slots_begin(&job->write, &job->lib->dir, job->dir, STORE_LIB_DIR_BYTES) !=
        HAL_FLASH_OK) {
        job->stage = S_DONE; /* cannot happen: the board checks the directory fits */
        job->status = STORE_LIB_FLASH;
    }
}

/* The committed directory into job->dir, and slot `slot`'s entry in it (NULL: no slot). */
static uint8_t *begin(store_lib_job_t *job, const store_lib_t *lib, uint8_t slot)
{
    job->lib = lib;
    job->stage = S_DONE;
    job->status = STORE_LIB_BAD_SLOT;
    if (slot >= STORE_LIB_SLOTS) {
        return NULL;
    }
    job->status = STORE_LIB_OK;
    load_dir(lib, job->dir);
    return job->dir + slot * STORE_LIB_ENTRY_BYTES;
}

store_lib_status_t store_lib_begin_put(store_lib_job_t *job, const store_lib_t *lib, uint8_t slot,
                                       uint8_t kind, const uint8_t *name, const uint8_t *data,
                                       uint32_t len)
{
    uint8_t *e = begin(job, lib, slot);
    if (e == NULL) {
        return STORE_LIB_BAD_SLOT;
    }
    if (kind == STORE_LIB_KIND_EMPTY || data == NULL || len == 0U ||
        len > store_lib_capacity(lib) || name == NULL) {
        job->status = STORE_LIB_BAD_BLOB;
        return STORE_LIB_BAD_BLOB;
    }
    /* The data first, into an area nothing committed refers to; then the directory. */
    uint8_t area = free_area(lib, job->dir, entry_used(lib, e) ? e[E_AREA] : (uint8_t)slot);
    if (store_slots_begin_bare(&job->write, &lib->areas, area * lib->area_size, data, len) !=
        HAL_FLASH_OK) {
        job->status = STORE_LIB_BAD_BLOB;
        return STORE_LIB_BAD_BLOB;
    }
    e[E_KIND] = kind;
    e[E_AREA] = area;
    e[E_LEN] = (uint8_t)len;
    e[E_LEN + 1U] = (uint8_t)(len >> 8);
    put32(e + E_CRC, job->write.expect);
    for (uint32_t i = 0; i < STORE_LIB_NAME_MAX; i++) {
        e[E_NAME + i] = name[i];
    }
    job->stage = S_AREA;
    return STORE_LIB_OK;
}

store_lib_status_t store_lib_begin_delete(store_lib_job_t *job, const store_lib_t *lib,
                                          uint8_t slot)
{
    uint8_t *e = begin(job, lib, slot);
    if (e == NULL) {
        return STORE_LIB_BAD_SLOT;
    }
    if (entry_used(lib, e)) {
        for (uint32_t i = 0; i < STORE_LIB_ENTRY_BYTES; i++) {
            e[i] = 0;
        }
        begin_dir(job);
    }
    return STORE_LIB_OK;
}

bool store_lib_step(store_lib_job_t *job, uint32_t halfwords)
{
    if (job->stage == S_DONE) {
        return false;
    }
    if (!store_slots_step(&job->write, halfwords)) {
        if (job->write.status != HAL_FLASH_OK) {
            job->status = STORE_LIB_FLASH; /* the committed directory is untouched */
            job->stage = S_DONE;
        } else if (job->stage == S_AREA) {
            begin_dir(job);
        } else {
            job->stage = S_DONE;
        }
    }
    return job->stage != S_DONE;
}

uint8_t store_lib_progress(const store_lib_job_t *job)
{
    /* the area is nearly all the work; the directory is a page and 192 bytes */
    switch (job->stage) {
    case S_AREA: return (uint8_t)(store_slots_progress(&job->write) * 9U / 10U);
    case S_DIR: return (uint8_t)(90U + store_slots_progress(&job->write) / 10U);
    default: return 100U;
    }
}

/* Run job to its end. */
static store_lib_status_t finish(store_lib_job_t *job, store_lib_status_t st)
{
    while (st == STORE_LIB_OK && store_lib_step(job, 0xFFFFFFFFU)) {
    }
    return st == STORE_LIB_OK ? (store_lib_status_t)job->status : st;
}

store_lib_status_t store_lib_put(const store_lib_t *lib, uint8_t slot, uint8_t kind,
                                 const uint8_t *name, const uint8_t *data, uint32_t len)
{
    store_lib_job_t job;
    return finish(&job, store_lib_begin_put(&job, lib, slot, kind, name, data, len));
}

store_lib_status_t store_lib_delete(const store_lib_t *lib, uint8_t slot)
{
    store_lib_job_t job;
    return finish(&job, store_lib_begin_delete(&job, lib, slot));
}
