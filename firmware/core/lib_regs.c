#include "lib_regs.h"

#include <stddef.h>

typedef char slot_names_fit[sizeof(((lib_slot *)0)->name) == CTL_SLOT_NAME_SIZE &&
                                    sizeof(((lib_device *)0)->name) == CTL_STORE_NAME_SIZE
                                ? 1
                                : -1];

void lib_init(lib_device *l, const lib_store *store)
{
    l->store = store;
    lib_panel_init(&l->panel);
    l->slot = 0;
    l->store_kind = CTL_UPLOAD_COMMIT_TABLE;
    l->result = CTL_UPLOAD_RESULT_OK;
    l->buttons = 0;
    l->leds = 0;
    l->offset = 0;
    for (size_t i = 0; i < sizeof l->name; i++) l->name[i] = 0;
}

static uint8_t slots(const lib_device *l)
{
    if (l->store == NULL) return 0;
    return l->store->slots < CTL_MAX_LIBRARY_SLOTS ? l->store->slots : CTL_MAX_LIBRARY_SLOTS;
}

static void empty(lib_slot *s)
{
    s->status = CTL_SLOT_STATUS_EMPTY;
    s->kind = 0;
    s->len = 0;
    s->crc = 0;
    for (size_t i = 0; i < sizeof s->name; i++) s->name[i] = 0;
}

/* Slot `slot` from the store (empty if there is no such slot). */
static void fetch(const lib_device *l, uint8_t slot, lib_slot *out, const uint8_t **data)
{
    empty(out);
    *data = NULL;
    if (slot < slots(l)) l->store->get(slot, out, data);
}

void lib_shown(const lib_device *l, lib_slot *out, const uint8_t **data)
{
    fetch(l, l->slot, out, data);
}

uint32_t lib_page_value(const lib_device *l, const lib_slot *shown, uint8_t addr)
{
    if (shown == NULL) {
        static const lib_slot none = {CTL_SLOT_STATUS_EMPTY, 0, 0, 0, {0}};
        shown = &none;
    }
    switch (addr) {
    case CTL_LIBRARY_SLOTS: return slots(l);
    case CTL_SLOT_CAPACITY: return l->store != NULL ? l->store->capacity : 0u;
    case CTL_LIBRARY_SLOT: return l->slot;
    case CTL_SLOT_STATUS: return shown->status;
    case CTL_SLOT_KIND: return shown->kind;
    case CTL_SLOT_LENGTH: return shown->len;
    case CTL_SLOT_CRC: return shown->crc;
    case CTL_STORE_KIND: return l->store_kind;
    case CTL_LIBRARY_RESULT: return l->result;
    case CTL_BUTTONS: return l->panel.keys.held;
    case CTL_PANEL_SLOT: return l->panel.slot;
    case CTL_LEDS: return l->leds;
    case CTL_SLOT_OFFSET: return l->offset;
    default: return 0;
    }
}

/* The Library page's fields: (offset, size), from the generated description. */
#define LIB_FIELD(pg, off, size, acc, lo, hi, sg, dflt) {pg, off, size},
static const struct {
    uint8_t page, offset, size;
} fields[] = {CTL_PAGE_FIELDS(LIB_FIELD)};
#undef LIB_FIELD

uint8_t lib_page_byte(const lib_device *l, const lib_slot *shown, const uint8_t *data,
                      uint8_t addr)
{
    if (addr >= CTL_SLOT_DATA && addr < CTL_SLOT_DATA + CTL_SLOT_DATA_SIZE) {
        uint32_t at = (uint32_t)l->offset + (uint32_t)(addr - CTL_SLOT_DATA);
        bool there = data != NULL && shown->status == CTL_SLOT_STATUS_OK && at < shown->len;
        return there ? data[at] : 0u;
    }
    if (addr >= CTL_SLOT_NAME && addr < CTL_SLOT_NAME + CTL_SLOT_NAME_SIZE) {
        return shown->name[addr - CTL_SLOT_NAME];
    }
    if (addr >= CTL_STORE_NAME && addr < CTL_STORE_NAME + CTL_STORE_NAME_SIZE) {
        return l->name[addr - CTL_STORE_NAME];
    }
    for (size_t i = 0; i < sizeof fields / sizeof fields[0]; i++) {
        uint8_t at = (uint8_t)(CTL_SERVO_WINDOW + fields[i].offset);
        if (fields[i].page == CTL_PAGE_LIBRARY && addr >= at && addr < at + fields[i].size) {
            return (uint8_t)(lib_page_value(l, shown, at) >> (8u * (addr - at)));
        }
    }
    return 0;
}

/* The byte a write of data[0..n) at start leaves at addr (`keep` where it does not reach). */
static uint8_t after(uint8_t start, const uint8_t *data, uint16_t n, uint16_t addr, uint8_t keep)
{
    return addr >= start && addr < start + n ? data[addr - start] : keep;
}

bool lib_page_write(lib_device *l, uint8_t start, const uint8_t *data, uint16_t n, bool apply)
{
    uint8_t slot = after(start, data, n, CTL_LIBRARY_SLOT, l->slot);
    if (slot >= slots(l) && slot != l->slot) return false;
    if (!apply) return true;
    for (uint16_t i = 0; i < CTL_STORE_NAME_SIZE; i++) {
        l->name[i] = after(start, data, n, (uint16_t)(CTL_STORE_NAME + i), l->name[i]);
    }
    l->store_kind = after(start, data, n, CTL_STORE_KIND, l->store_kind);
    l->buttons = after(start, data, n, CTL_BUTTONS, l->buttons);
    l->offset = (uint16_t)(after(start, data, n, CTL_SLOT_OFFSET, (uint8_t)l->offset) |
                           after(start, data, n, CTL_SLOT_OFFSET + 1u, (uint8_t)(l->offset >> 8))
                               << 8);
    l->slot = slot;
    return true;
}

bool lib_note(lib_device *l, uint8_t result)
{
    l->result = result;
    return result != CTL_UPLOAD_RESULT_OK && result != CTL_UPLOAD_RESULT_LIBRARY_STORING;
}

uint8_t lib_saving(const lib_device *l, bool table_pending, uint8_t *percent)
{
    uint8_t done = 0;
    uint8_t state = CTL_STORE_STATE_IDLE;
    if (l->store != NULL && l->store->saving != NULL) {
        state = l->store->saving(&done);
        if (state == CTL_STORE_STATE_IDLE && table_pending) state = CTL_STORE_STATE_TABLE;
    }
    if (percent != NULL) *percent = state == CTL_STORE_STATE_IDLE ? 0u : done;
    return state;
}

/* Printable ASCII, then zero bytes only (an empty name is allowed). */
static bool name_ok(const uint8_t *name)
{
    bool ended = false;
    for (size_t i = 0; i < CTL_STORE_NAME_SIZE; i++) {
        if (name[i] == 0) {
            ended = true;
        } else if (ended || name[i] < 0x20 || name[i] > 0x7e) {
            return false;
        }
    }
    return true;
}

/* Why slot operations cannot run now (OK: they can). */
static uint8_t slot_problem(const lib_device *l)
{
    if (slots(l) == 0) return CTL_UPLOAD_RESULT_LIBRARY_NONE;
    if (l->slot >= slots(l)) return CTL_UPLOAD_RESULT_LIBRARY_BAD_SLOT;
    return CTL_UPLOAD_RESULT_OK;
}

uint8_t lib_store_blob(lib_device *l, bool table_pending, const uint8_t *data, uint16_t len)
{
    uint8_t r = slot_problem(l);
    if (r == CTL_UPLOAD_RESULT_OK && !name_ok(l->name)) r = CTL_UPLOAD_RESULT_LIBRARY_BAD_NAME;
    if (r == CTL_UPLOAD_RESULT_OK && l->store_kind == CTL_UPLOAD_COMMIT_LIMITS) {
        r = CTL_UPLOAD_RESULT_LIBRARY_BAD_KIND; /* the limits have their own store */
    }
    if (r == CTL_UPLOAD_RESULT_OK && len > l->store->capacity) {
        r = CTL_UPLOAD_RESULT_BAD_LENGTH;
    }
    if (r == CTL_UPLOAD_RESULT_OK && lib_saving(l, table_pending, NULL) != CTL_STORE_STATE_IDLE) {
        r = CTL_UPLOAD_RESULT_STORE_BUSY; /* one flash write at a time */
    }
    if (r == CTL_UPLOAD_RESULT_OK) r = l->store->put(l->slot, l->store_kind, l->name, data, len);
    lib_note(l, r);
    return r;
}

uint8_t lib_delete(lib_device *l, bool table_pending)
{
    uint8_t r = slot_problem(l);
    if (r == CTL_UPLOAD_RESULT_OK && lib_saving(l, table_pending, NULL) != CTL_STORE_STATE_IDLE) {
        r = CTL_UPLOAD_RESULT_STORE_BUSY;
    }
    if (r == CTL_UPLOAD_RESULT_OK) r = l->store->remove(l->slot);
    lib_note(l, r);
    return r;
}

uint8_t lib_playable(const lib_device *l, uint8_t slot, bool table_pending,
                     const uint8_t **data, uint16_t *len, uint32_t *crc)
{
    if (slots(l) == 0) return CTL_UPLOAD_RESULT_LIBRARY_NONE;
    if (slot >= slots(l)) return CTL_UPLOAD_RESULT_LIBRARY_BAD_SLOT;
    if (lib_saving(l, table_pending, NULL) != CTL_STORE_STATE_IDLE) {
        return CTL_UPLOAD_RESULT_STORE_BUSY;
    }
    lib_slot s;
    fetch(l, slot, &s, data);
    if (s.status == CTL_SLOT_STATUS_EMPTY) return CTL_UPLOAD_RESULT_LIBRARY_EMPTY;
    if (s.status != CTL_SLOT_STATUS_OK || *data == NULL) return CTL_UPLOAD_RESULT_LIBRARY_DAMAGED;
    if (s.kind != CTL_UPLOAD_COMMIT_TABLE && s.kind != CTL_UPLOAD_COMMIT_PROGRAM) {
        return CTL_UPLOAD_RESULT_LIBRARY_NOT_PLAYABLE;
    }
    *len = s.len;
    *crc = s.crc;
    return CTL_UPLOAD_RESULT_OK;
}
