#include "store_play.h"

#include <stdbool.h>
#include <stddef.h>

#include "board.h"
#include "board_api.h"
#include "crc32.h"
#include "store.h"

#if BOARD_HAS_FLASH_STORE && BOARD_HAS_FLASH_LIBRARY

static void flash_get(uint8_t slot, lib_slot *out, const uint8_t **data)
{
    store_lib_entry_t e;
    store_lib_status_t st = store_lib_entry(store_library(), slot, &e);
    if (st != STORE_LIB_OK && st != STORE_LIB_DAMAGED) {
        return; /* left empty */
    }
    out->status = st == STORE_LIB_OK ? CTL_SLOT_STATUS_OK : CTL_SLOT_STATUS_DAMAGED;
    out->kind = e.kind;
    out->len = e.len;
    out->crc = e.crc;
    for (size_t i = 0; i < sizeof out->name; i++) {
        out->name[i] = e.name[i];
    }
    *data = st == STORE_LIB_OK ? (const uint8_t *)(uintptr_t)e.addr : NULL;
}

static uint8_t flash_put(uint8_t slot, uint8_t kind, const uint8_t *name, const uint8_t *data,
                         uint16_t len)
{
    return store_library_begin(slot, kind, name, data, len);
}

static uint8_t flash_remove(uint8_t slot)
{
    return store_library_begin(slot, STORE_LIB_KIND_EMPTY, NULL, NULL, 0);
}

static const lib_store library = {.slots = STORE_LIB_SLOTS,
                                  .memory = CTL_LIBRARY_MEMORY_FLASH,
                                  .capacity = BOARD_LIB_AREA_SIZE,
                                  .get = flash_get,
                                  .put = flash_put,
                                  .remove = flash_remove,
                                  .saving = store_saving};

void store_play_init(ctl_device *ctl)
{
    ctl_set_library(ctl, &library);
}

#else

/* The one slot: what was stored, and the CRC of the table it made active. */
static ctl_device *alias_ctl;
static uint8_t alias_kind;
static uint32_t alias_crc;
static uint8_t alias_name[CTL_SLOT_NAME_SIZE];

static void alias_get(uint8_t slot, lib_slot *out, const uint8_t **data)
{
    size_t len = 0;
    const uint8_t *active = ctl_active_table(alias_ctl, &len);
    if (slot != 0U || alias_kind == 0U || active == NULL ||
        crc32_compute(active, len) != alias_crc) {
        return; /* left empty: another table is active now */
    }
    out->status = CTL_SLOT_STATUS_OK;
    out->kind = alias_kind;
    out->len = (uint16_t)len;
    out->crc = alias_crc;
    for (size_t i = 0; i < sizeof out->name; i++) {
        out->name[i] = alias_name[i];
    }
    *data = active;
}

static uint8_t alias_put(uint8_t slot, uint8_t kind, const uint8_t *name, const uint8_t *data,
                         uint16_t len)
{
    if (slot != 0U) {
        return CTL_UPLOAD_RESULT_LIBRARY_BAD_SLOT;
    }
    if (kind != CTL_UPLOAD_COMMIT_TABLE) {
        return CTL_UPLOAD_RESULT_LIBRARY_BAD_KIND; /* only the active table's buffer */
    }
    if (!ctl_load_table(alias_ctl, data, len)) {
        return CTL_UPLOAD_RESULT_LIBRARY_NOT_PLAYABLE;
    }
    alias_kind = kind;
    alias_crc = crc32_compute(data, len);
    for (size_t i = 0; i < sizeof alias_name; i++) {
        alias_name[i] = name[i];
    }
    return CTL_UPLOAD_RESULT_OK;
}

static uint8_t alias_remove(uint8_t slot)
{
    if (slot != 0U) {
        return CTL_UPLOAD_RESULT_LIBRARY_BAD_SLOT;
    }
    alias_kind = 0;
    return CTL_UPLOAD_RESULT_OK;
}

/* No background writes: QEMU keeps the library in RAM (saving NULL: Store State IDLE). */
static const lib_store library = {.slots = 1U,
                                  .memory = CTL_LIBRARY_MEMORY_RAM,
                                  .capacity = BOARD_TABLE_CAPACITY,
                                  .get = alias_get,
                                  .put = alias_put,
                                  .remove = alias_remove,
                                  .saving = NULL};

void store_play_init(ctl_device *ctl)
{
    alias_ctl = ctl;
    ctl_set_library(ctl, &library);
}

#endif

void store_play_tick(ctl_device *ctl, uint32_t now_ms)
{
    board_leds(ctl_buttons(ctl, board_buttons(), now_ms));
}
