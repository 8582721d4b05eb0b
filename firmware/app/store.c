/* Table store: the committed table as a record of store_slots (two slots, so a power cut
 * while saving leaves the previous table). */
#include "store.h"

#include <stddef.h>
#include <stdint.h>

#include "board.h"

#if BOARD_HAS_FLASH_STORE

#include "hal_iwdg.h"
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

/* The table save under way, if any (job.status tells how the last one ended). */
static store_slots_job_t job;
static bool saving;

typedef char limits_slot_holds_the_limits[(BOARD_LIMITS_STORE_SIZE / 2U) % BOARD_FLASH_PAGE_SIZE ==
                                                      0U &&
                                                  BOARD_LIMITS_STORE_SIZE / 2U >=
                                                      STORE_SLOTS_HEADER_BYTES + CTL_LIMITS_BLOB_MAX
                                              ? 1
                                              : -1];

#if BOARD_HAS_FLASH_LIBRARY
/* A library store blocks the main loop page by page: the watchdog is fed between them. */
void store_lib_pause(void)
{
    hal_iwdg_feed();
}

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
    size_t len = 0;
    const uint8_t *table = ctl_active_table(ctl, &len);
    saving = table != NULL &&
             store_slots_begin(&job, &region, table, (uint32_t)len) == HAL_FLASH_OK;
}

bool store_save_step(const ctl_device *ctl)
{
    size_t len = 0;
    const uint8_t *table = ctl_active_table(ctl, &len);
    if (saving && (table != job.data || len != job.len)) {
        saving = false; /* dropped or replaced: what is left to write is not that table */
    }
    if (saving) {
        saving = store_slots_step(&job, STORE_SAVE_HALFWORDS);
    }
    return saving;
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

bool store_save_step(const ctl_device *ctl)
{
    (void)ctl;
    return false;
}

bool store_save_limits(const ctl_device *ctl)
{
    (void)ctl;
    return false;
}

#endif
