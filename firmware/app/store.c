/* Table store: the committed table as a record of store_slots (two slots, so a power cut
 * while saving leaves the previous table). */
#include "store.h"

#include <stddef.h>
#include <stdint.h>

#include "board.h"

#if BOARD_HAS_FLASH_STORE

#include "store_slots.h"

static const hal_flash_region_t region = {BOARD_STORE_BASE, BOARD_STORE_SIZE,
                                          BOARD_FLASH_PAGE_SIZE};
static const hal_flash_region_t limits_region = {BOARD_LIMITS_STORE_BASE,
                                                 BOARD_LIMITS_STORE_SIZE, BOARD_FLASH_PAGE_SIZE};

/* Each slot is half the region, in whole pages, and must hold a header and a table. */
typedef char store_slot_holds_a_table[(BOARD_STORE_SIZE / 2U) % BOARD_FLASH_PAGE_SIZE == 0U &&
                                              BOARD_STORE_SIZE / 2U >=
                                                  STORE_SLOTS_HEADER_BYTES + BOARD_TABLE_CAPACITY
                                          ? 1
                                          : -1];

/* Half-words a save programs per control tick: at 40-70 us each (tPROG, the F103's
 * datasheet), 64 stall the CPU for at most 4.5 ms of the 10 ms tick; a 32 KB table then
 * takes 256 ticks of programming after its 17 page erases (a tick each, 20-40 ms). */
#define STORE_SAVE_HALFWORDS 64U

/* The one flash write under way (writing: CTL_STORE_STATE_*): the committed table's save
 * (job.write alone) or a library store or delete (all of job). One at a time: the core
 * refuses a library operation while either runs, and a commit while a library store
 * does (lib_regs.h). */
static store_lib_job_t job;
static uint8_t writing;
/* A table committed while a library store ran: saved once the store ends. (The core
 * refuses commits during a library store, so this is a belt to those braces.) */
static bool table_waiting;

/* A library store's outcome as Upload Result. */
static uint8_t library_result(store_lib_status_t st)
{
    switch (st) {
    case STORE_LIB_OK: return CTL_UPLOAD_RESULT_OK;
    case STORE_LIB_BAD_SLOT: return CTL_UPLOAD_RESULT_LIBRARY_BAD_SLOT;
    case STORE_LIB_BAD_BLOB: return CTL_UPLOAD_RESULT_BAD_LENGTH;
    default: return CTL_UPLOAD_RESULT_LIBRARY_FLASH;
    }
}

typedef char limits_slot_holds_the_limits[(BOARD_LIMITS_STORE_SIZE / 2U) % BOARD_FLASH_PAGE_SIZE ==
                                                      0U &&
                                                  BOARD_LIMITS_STORE_SIZE / 2U >=
                                                      STORE_SLOTS_HEADER_BYTES + CTL_LIMITS_BLOB_MAX
                                              ? 1
                                              : -1];

#if BOARD_HAS_FLASH_LIBRARY
#define LIB_AREAS_BASE (BOARD_LIB_DIR_BASE + BOARD_LIB_DIR_SIZE)
#define LIB_AREAS_SIZE ((STORE_LIB_SLOTS + 1U) * BOARD_LIB_AREA_SIZE)
static const store_lib_t library = {
    {BOARD_LIB_DIR_BASE, BOARD_LIB_DIR_SIZE, BOARD_FLASH_PAGE_SIZE},
    {LIB_AREAS_BASE, LIB_AREAS_SIZE, BOARD_FLASH_PAGE_SIZE},
    BOARD_LIB_AREA_SIZE,
};

/* The library fills the flash from its directory to the limits' store, in whole pages,
 * and an area holds anything the staging area can. */
typedef char library_fits_below_the_limits
    [LIB_AREAS_BASE + LIB_AREAS_SIZE == BOARD_LIMITS_STORE_BASE &&
             BOARD_LIB_AREA_SIZE % BOARD_FLASH_PAGE_SIZE == 0U &&
             BOARD_LIB_DIR_SIZE / 2U >= STORE_SLOTS_HEADER_BYTES + STORE_LIB_DIR_BYTES &&
             BOARD_LIB_AREA_SIZE >= BOARD_TABLE_CAPACITY
         ? 1
         : -1];

const store_lib_t *store_library(void)
{
    return &library;
}

uint8_t store_library_begin(uint8_t slot, uint8_t kind, const uint8_t *name,
                            const uint8_t *data, uint16_t len)
{
    if (writing != CTL_STORE_STATE_IDLE) {
        return CTL_UPLOAD_RESULT_STORE_BUSY;
    }
    store_lib_status_t st = kind == STORE_LIB_KIND_EMPTY
                                ? store_lib_begin_delete(&job, &library, slot)
                                : store_lib_begin_put(&job, &library, slot, kind, name, data, len);
    if (st != STORE_LIB_OK) {
        return library_result(st);
    }
    writing = CTL_STORE_STATE_LIBRARY;
    return CTL_UPLOAD_RESULT_LIBRARY_STORING;
}
#else
const store_lib_t *store_library(void)
{
    return NULL;
}
#endif

bool store_load(ctl_device *ctl)
{
    store_record_t rec;
    /* the limits first: a table beyond them must not load */
    if (store_slots_newest(&limits_region, &rec)) {
        (void)ctl_load_limits(ctl, (const uint8_t *)(BOARD_LIMITS_STORE_BASE + rec.offset),
                              rec.len);
    }
    if (!store_slots_newest(&region, &rec)) {
        return false;
    }
    /* Flash is memory-mapped: the table is used where it lies. */
    return ctl_load_table(ctl, (const uint8_t *)(BOARD_STORE_BASE + rec.offset), rec.len);
}

void store_save_begin(const ctl_device *ctl)
{
    if (writing == CTL_STORE_STATE_LIBRARY) {
        table_waiting = true;
        return;
    }
    size_t len = 0;
    const uint8_t *table = ctl_active_table(ctl, &len);
    writing = table != NULL &&
                      store_slots_begin(&job.write, &region, table, (uint32_t)len) == HAL_FLASH_OK
                  ? CTL_STORE_STATE_TABLE
                  : CTL_STORE_STATE_IDLE;
}

bool store_save_step(ctl_device *ctl)
{
    if (writing == CTL_STORE_STATE_TABLE) {
        size_t len = 0;
        const uint8_t *table = ctl_active_table(ctl, &len);
        /* dropped (an upload landed on it): what is left to write is not that table */
        if (table != job.write.data || len != job.write.len ||
            !store_slots_step(&job.write, STORE_SAVE_HALFWORDS)) {
            writing = CTL_STORE_STATE_IDLE;
        }
    } else if (writing == CTL_STORE_STATE_LIBRARY && !store_lib_step(&job, STORE_SAVE_HALFWORDS)) {
        writing = CTL_STORE_STATE_IDLE;
        ctl_library_stored(ctl, library_result((store_lib_status_t)job.status));
        if (table_waiting) {
            table_waiting = false;
            store_save_begin(ctl);
        }
    }
    return writing != CTL_STORE_STATE_IDLE;
}

uint8_t store_saving(uint8_t *percent)
{
    *percent = writing == CTL_STORE_STATE_TABLE     ? store_slots_progress(&job.write)
               : writing == CTL_STORE_STATE_LIBRARY ? store_lib_progress(&job)
                                                    : 0U;
    return writing;
}

bool store_save_limits(const ctl_device *ctl)
{
    uint8_t blob[CTL_LIMITS_BLOB_MAX];
    size_t len = ctl_robot_limits(ctl, blob, sizeof blob);
    if (len == 0U) {
        return false;
    }
    return store_slots_save(&limits_region, blob, (uint32_t)len) == HAL_FLASH_OK;
}

#else

const store_lib_t *store_library(void)
{
    return NULL;
}

bool store_load(ctl_device *ctl)
{
    (void)ctl;
    return false;
}

void store_save_begin(const ctl_device *ctl)
{
    (void)ctl;
}

bool store_save_step(ctl_device *ctl)
{
    (void)ctl;
    return false;
}

uint8_t store_saving(uint8_t *percent)
{
    *percent = 0;
    return CTL_STORE_STATE_IDLE;
}


bool store_save_limits(const ctl_device *ctl)
{
    (void)ctl;
    return false;
}

#endif
