/* The PC-link fuzz target's gait library (pclink_store_model.h): a store in RAM, kept
 * across power cycles as flash would be. Its checks hold the core to what a store may be
 * asked: only slots it has, only whole tables kept as tables, one flash write at a time,
 * and the staging area left as it was accepted until a background write ends. */
#include "pclink_store_model.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "gt_table.h"

#include "fuzz_check.h"
#include "pclink_common.h"

static struct {
    uint8_t kind; /* 0: empty */
    uint8_t name[CTL_SLOT_NAME_SIZE];
    uint16_t len;
    uint32_t crc; /* worked out once, when stored: the core asks for it on every look */
    uint8_t bytes[FUZZ_CAPACITY];
} library[LIB_SLOTS];

/* A store or delete that, like the CM-530's, writes in the background: put and remove
 * only begin it (LIBRARY_STORING), and it ends after `ticks` control ticks, when the slot
 * changes and ctl_library_stored() reports. The blob is read where the core left it (the
 * staging area) only at the end, so a core that let the staging area change meanwhile
 * stores other bytes than it accepted, which the CRC taken at the start catches. A power
 * cut meanwhile leaves the slot as it was. */
static bool background; /* whether the next put or remove writes in the background */
static struct {
    uint8_t ticks; /* 0: nothing under way */
    uint8_t total;
    bool remove;
    uint8_t slot, kind;
    uint8_t name[CTL_SLOT_NAME_SIZE];
    const uint8_t *data;
    uint16_t len;
    uint32_t crc;
} writing;

static void lib_get(uint8_t slot, lib_slot *out, const uint8_t **data)
{
    CHECK(slot < LIB_SLOTS); /* the core asks only for slots the store has */
    if (library[slot].kind == 0) return;
    out->status = CTL_SLOT_STATUS_OK;
    out->kind = library[slot].kind;
    out->len = library[slot].len;
    out->crc = library[slot].crc;
    memcpy(out->name, library[slot].name, sizeof out->name);
    *data = library[slot].bytes;
}

/* The slot now keeps data[0..len), whose CRC-32 is crc. */
static void lib_keep(uint8_t slot, uint8_t kind, const uint8_t *name, const uint8_t *data,
                     uint16_t len, uint32_t crc)
{
    library[slot].kind = kind;
    memcpy(library[slot].name, name, CTL_SLOT_NAME_SIZE);
    library[slot].len = len;
    library[slot].crc = crc;
    memcpy(library[slot].bytes, data, len);
}

static uint8_t lib_put(uint8_t slot, uint8_t kind, const uint8_t *name, const uint8_t *data,
                       uint16_t len)
{
    CHECK(slot < LIB_SLOTS && kind != 0 && kind != CTL_UPLOAD_COMMIT_LIMITS);
    CHECK(len > 0 && len <= FUZZ_CAPACITY);
    for (size_t i = 0; i < CTL_SLOT_NAME_SIZE; i++) {
        CHECK(name[i] == 0 || (name[i] >= 0x20 && name[i] <= 0x7e)); /* names were checked */
    }
    if (kind == CTL_UPLOAD_COMMIT_TABLE) {
        gt_info info;
        CHECK(gt_validate(data, len, &info) == GT_OK); /* only whole tables are kept as such */
    }
    CHECK(writing.ticks == 0); /* one flash write at a time */
    if (background) {
        writing.remove = false;
        writing.slot = slot;
        writing.kind = kind;
        memcpy(writing.name, name, CTL_SLOT_NAME_SIZE);
        writing.data = data;
        writing.len = len;
        writing.crc = crc_of(data, len);
        writing.ticks = writing.total;
        return CTL_UPLOAD_RESULT_LIBRARY_STORING;
    }
    lib_keep(slot, kind, name, data, len, crc_of(data, len));
    return CTL_UPLOAD_RESULT_OK;
}

static uint8_t lib_remove(uint8_t slot)
{
    CHECK(slot < LIB_SLOTS);
    CHECK(writing.ticks == 0);
    if (background) {
        writing.remove = true;
        writing.slot = slot;
        writing.ticks = writing.total;
        return CTL_UPLOAD_RESULT_LIBRARY_STORING;
    }
    library[slot].kind = 0;
    return CTL_UPLOAD_RESULT_OK;
}

static uint8_t fuzz_lib_saving(uint8_t *percent)
{
    if (writing.ticks == 0) return CTL_STORE_STATE_IDLE;
    if (percent != NULL) *percent = (uint8_t)(100u * (writing.total - writing.ticks) / writing.total);
    return CTL_STORE_STATE_LIBRARY;
}

/* A control tick of the background write: at the last, the slot changes. */
void lib_write_tick(ctl_device *d)
{
    if (writing.ticks == 0 || --writing.ticks > 0) return;
    if (writing.remove) {
        library[writing.slot].kind = 0;
    } else {
        CHECK(crc_of(writing.data, writing.len) == writing.crc); /* staging kept as accepted */
        lib_keep(writing.slot, writing.kind, writing.name, writing.data, writing.len,
                 writing.crc);
    }
    ctl_library_stored(d, CTL_UPLOAD_RESULT_OK);
}

const lib_store fuzz_library = {.slots = LIB_SLOTS,
                                .memory = CTL_LIBRARY_MEMORY_RAM,
                                .capacity = FUZZ_CAPACITY,
                                .get = lib_get,
                                .put = lib_put,
                                .remove = lib_remove,
                                .saving = fuzz_lib_saving};

/* Whether table[0..len) is what a library slot keeps as a table. */
bool in_library(const uint8_t *table, uint16_t len)
{
    for (unsigned k = 0; k < LIB_SLOTS; k++) {
        if (library[k].kind == CTL_UPLOAD_COMMIT_TABLE && library[k].len == len &&
            memcmp(library[k].bytes, table, len) == 0) {
            return true;
        }
    }
    return false;
}

void store_model_reset(void)
{
    for (unsigned k = 0; k < LIB_SLOTS; k++) library[k].kind = 0; /* the rest is read only when set */
    writing.ticks = 0;
    background = false;
}

void store_model_plan(bool in_background, uint8_t ticks)
{
    background = in_background;
    if (writing.ticks == 0) writing.total = ticks;
}

bool store_model_busy(void)
{
    return writing.ticks > 0;
}

void store_model_power_cut(void)
{
    writing.ticks = 0; /* a library write cut short leaves its slot as it was */
}
