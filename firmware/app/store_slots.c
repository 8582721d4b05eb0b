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

/* The phases of a save, in order. */
enum { P_FIND, P_ERASE, P_DATA, P_HEADER, P_MAGIC, P_VERIFY, P_DONE };

/* Aim job at writing data[0..len) (checked by the caller), from phase `phase`. */
static void start(store_slots_job_t *job, const hal_flash_region_t *r, const uint8_t *data,
                  uint32_t len, uint8_t phase)
{
    job->r = r;
    job->data = data;
    job->len = len;
    job->slot = 0;
    job->seq = 0;
    job->done = 0;
    job->expect = crc32_compute(data, len);
    job->crc = CRC32_INIT;
    job->phase = phase;
    job->status = HAL_FLASH_OK;
    job->bare = 0;
}

hal_flash_status_t store_slots_begin(store_slots_job_t *job, const hal_flash_region_t *r,
                                     const uint8_t *data, uint32_t len)
{
    job->phase = P_DONE;
    job->status = HAL_FLASH_ERR_RANGE;
    if (data == NULL || len == 0U || len > store_slots_capacity(r) || len > 0xFFFFU) {
        return HAL_FLASH_ERR_RANGE;
    }
    start(job, r, data, len, P_FIND);
    return HAL_FLASH_OK;
}

hal_flash_status_t store_slots_begin_bare(store_slots_job_t *job, const hal_flash_region_t *r,
                                          uint32_t offset, const uint8_t *data, uint32_t len)
{
    job->phase = P_DONE;
    job->status = HAL_FLASH_ERR_RANGE;
    if (data == NULL || len == 0U || len > 0xFFFFU || offset % r->page_size != 0U ||
        offset > r->size || len > r->size - offset) {
        return HAL_FLASH_ERR_RANGE;
    }
    start(job, r, data, len, P_ERASE);
    job->slot = offset;
    job->bare = 1;
    return HAL_FLASH_OK;
}

/* P_FIND: read slot job->done; once both are read, aim at the one not holding the newest. */
static void find_step(store_slots_job_t *job)
{
    const hal_flash_region_t *r = job->r;
    store_record_t rec;
    uint32_t i = job->done++;
    if (slot_record(r, i * slot_size(r), &rec) &&
        (job->slot == 0U || (int32_t)(rec.seq - job->seq) > 0)) {
        job->slot = i + 1U;
        job->seq = rec.seq;
    }
    if (job->done == 2U) {
        uint32_t keep = job->slot; /* 0: none, else the newest's slot + 1 */
        job->seq = keep != 0U ? job->seq + 1U : 1U;
        job->slot = (keep == 1U ? 1U : 0U) * slot_size(r);
        job->done = 0;
        job->phase = P_ERASE;
    }
}

/* Bytes before the data in the slot being written: a record's header, or none. */
static uint32_t header_bytes(const store_slots_job_t *job)
{
    return job->bare ? 0U : STORE_SLOTS_HEADER_BYTES;
}

/* P_DATA: program up to `bytes` more of the data, adding them to the running CRC. */
static hal_flash_status_t data_step(store_slots_job_t *job, uint32_t bytes)
{
    uint32_t n = job->len - job->done;
    if (n > bytes) {
        n = bytes;
    }
    hal_flash_status_t st = hal_flash_write(job->r, job->slot + header_bytes(job) + job->done,
                                            job->data + job->done, n);
    if (st == HAL_FLASH_OK) {
        job->crc = crc32_update(job->crc, job->data + job->done, n);
        job->done += n;
    }
    return st;
}

/* P_HEADER: everything but the magic, if the bytes programmed are the data as it began
 * (bare data: only that check). */
static hal_flash_status_t header_step(store_slots_job_t *job)
{
    if (crc32_final(job->crc) != job->expect) {
        return HAL_FLASH_ERR_VERIFY; /* the data changed under the save */
    }
    if (job->bare) {
        return HAL_FLASH_OK;
    }
    uint8_t header[STORE_SLOTS_HEADER_BYTES];
    put_le32(header + OFF_SEQ, job->seq);
    header[OFF_LEN] = (uint8_t)job->len;
    header[OFF_LEN + 1U] = (uint8_t)(job->len >> 8);
    header[OFF_LEN + 2U] = 0xFF;
    header[OFF_LEN + 3U] = 0xFF;
    put_le32(header + OFF_CRC, job->expect);
    return hal_flash_write(job->r, job->slot + OFF_SEQ, header + OFF_SEQ,
                           STORE_SLOTS_HEADER_BYTES - OFF_SEQ);
}

bool store_slots_step(store_slots_job_t *job, uint32_t halfwords)
{
    const hal_flash_region_t *r = job->r;
    hal_flash_status_t st = HAL_FLASH_OK;
    uint8_t magic[4];
    store_record_t check;
    switch (job->phase) {
    case P_FIND: find_step(job); break;
    case P_ERASE:
        st = hal_flash_erase(r, job->slot + job->done, 1U);
        job->done += r->page_size;
        if (job->done >= header_bytes(job) + job->len) {
            job->done = 0;
            job->phase = P_DATA;
        }
        break;
    case P_DATA:
        st = data_step(job, halfwords > 0x7FFFFFFFU ? 0xFFFFFFFEU : 2U * halfwords);
        if (job->done == job->len) {
            job->phase = P_HEADER;
        }
        break;
    case P_HEADER:
        st = header_step(job);
        job->phase = job->bare ? P_VERIFY : P_MAGIC;
        break;
    case P_MAGIC:
        /* until its last half-word is programmed the slot does not count, and the other
         * slot still holds the previous record */
        put_le32(magic, MAGIC);
        st = hal_flash_write(r, job->slot + OFF_MAGIC, magic, 4U);
        job->phase = P_VERIFY;
        break;
    case P_VERIFY:
        if (job->bare ? store_slots_flash_crc(r->base + job->slot, job->len) != job->expect
                      : !slot_record(r, job->slot, &check) || check.seq != job->seq) {
            st = HAL_FLASH_ERR_VERIFY;
        }
        job->phase = P_DONE;
        break;
    default: return false;
    }
    if (st != HAL_FLASH_OK) {
        job->status = (uint8_t)st;
        job->phase = P_DONE;
    }
    return job->phase != P_DONE;
}

uint8_t store_slots_progress(const store_slots_job_t *job)
{
    switch (job->phase) {
    case P_FIND: return 0U;
    case P_ERASE: return (uint8_t)(50U * job->done / (header_bytes(job) + job->len));
    case P_DATA: return (uint8_t)(50U + 50U * job->done / job->len);
    default: return 100U;
    }
}

hal_flash_status_t store_slots_save(const hal_flash_region_t *r, const uint8_t *data,
                                    uint32_t len)
{
    store_slots_job_t job;
    hal_flash_status_t st = store_slots_begin(&job, r, data, len);
    while (st == HAL_FLASH_OK && store_slots_step(&job, 0xFFFFFFFFU)) {
    }
    return st == HAL_FLASH_OK ? (hal_flash_status_t)job.status : st;
}
