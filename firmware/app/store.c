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
                                                  STORE_SLOTS_HEADER_BYTES + CTL_MAX_TABLE_BYTES
                                          ? 1
                                          : -1];

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
             BOARD_LIB_AREA_SIZE >= CTL_MAX_TABLE_BYTES
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

bool store_save(const ctl_device *ctl)
{
    size_t len = 0;
    const uint8_t *table = ctl_active_table(ctl, &len);
    if (table == NULL || len == 0U || len > CTL_MAX_TABLE_BYTES) {
        return false;
    }
    return store_slots_save(&region, table, (uint32_t)len) == HAL_FLASH_OK;
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

bool store_save(const ctl_device *ctl)
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
