/* The gait library as the controller shows it (protocol/library.md): the Library window
 * page (17), the library's Upload Commit values and Command, and the robot's button panel,
 * on a store the app provides (lib_store: flash on the CM-530, an alias of the active
 * table on QEMU), so the core itself stays free of hardware. ctl_device owns one and calls
 * in from its register, commit and command code. */
#ifndef SNAKEBOT_LIB_REGS_H
#define SNAKEBOT_LIB_REGS_H

#include <stdbool.h>
#include <stdint.h>

#include "ctl_table.h"
#include "lib_panel.h"

struct ctl_device;

/* cffi:begin */
/* A slot as the store reports it. */
typedef struct {
    uint8_t status;  /* CTL_SLOT_STATUS_* */
    uint8_t kind;    /* the Upload Commit value the blob is committed with; 0 if empty */
    uint16_t len;    /* bytes */
    uint32_t crc;    /* CRC-32 of the blob */
    uint8_t name[16]; /* CTL_SLOT_NAME_SIZE bytes, zero-padded */
} lib_slot;

/* What the app's store does. Results are CTL_UPLOAD_RESULT_OK or _LIBRARY_*. */
typedef struct {
    uint8_t slots;     /* how many slots (at most CTL_MAX_LIBRARY_SLOTS) */
    uint8_t memory;    /* where they are kept: CTL_LIBRARY_MEMORY_RAM or _FLASH */
    uint32_t capacity; /* bytes a slot takes */
    /* Slot `slot` (< slots) into *out; *data = where an OK slot's blob lies. */
    void (*get)(uint8_t slot, lib_slot *out, const uint8_t **data);
    uint8_t (*put)(uint8_t slot, uint8_t kind, const uint8_t *name, const uint8_t *data,
                   uint16_t len);
    uint8_t (*remove)(uint8_t slot);
    /* What the store writes to flash in the background, a step per control tick
     * (CTL_STORE_STATE_*), and how far (*percent, 0..100); NULL: it never does. put and
     * remove may start such a write and return CTL_UPLOAD_RESULT_LIBRARY_STORING; its
     * outcome then comes through ctl_library_stored(). */
    uint8_t (*saving)(uint8_t *percent);
} lib_store;

typedef struct {
    const lib_store *store; /* NULL: no library */
    lib_panel_t panel;
    uint8_t slot;       /* Library Slot */
    uint8_t store_kind; /* Store Kind */
    uint8_t result;     /* Library Result */
    uint8_t buttons;    /* held through the Buttons register */
    uint8_t leds;       /* LEDs */
    uint16_t offset;    /* Slot Offset */
    uint8_t name[16];   /* Store Name */
} lib_device;

/* The controller's side (ctl_state.c), declared here where lib_store is (the cffi
 * declarations are read header by header, in name order: lib_regs.h after lib_panel.h,
 * ctl_device.h before both). */
/* The gait library's store, kept by the app; NULL: none. */
void ctl_set_library(struct ctl_device *d, const lib_store *store);
/* Each control tick: the buttons held (CTL_BUTTONS_*, undebounced) go to the library
 * panel, which may play or stop a slot; returns the LEDs to light (CTL_LEDS_*). */
uint8_t ctl_buttons(struct ctl_device *d, uint8_t held, uint32_t now_ms);
/* The outcome of a library store or delete the store ran in the background (after its
 * put or remove returned CTL_UPLOAD_RESULT_LIBRARY_STORING): Library Result, and Upload
 * Result if it still reads LIBRARY_STORING; a failure raises Error Flags LIBRARY. */
void ctl_library_stored(struct ctl_device *d, uint8_t result);
/* cffi:end */

/* No store, nothing picked; registers at their defaults. */
void lib_init(lib_device *l, const lib_store *store);
/* Slot Library Slot as the store has it now, and where its blob lies if it is OK (read
 * once per READ of the page: not kept, for RAM's sake). */
void lib_shown(const lib_device *l, lib_slot *out, const uint8_t **data);
/* The value of the Library page's numeric field at absolute address `addr`; `shown` (or
 * NULL: an empty slot) gives the slot's fields. */
uint32_t lib_page_value(const lib_device *l, const lib_slot *shown, uint8_t addr);
/* The byte at absolute address `addr` of the window showing the Library page, with
 * `shown` and `data` from lib_shown(). */
uint8_t lib_page_byte(const lib_device *l, const lib_slot *shown, const uint8_t *data,
                      uint8_t addr);
/* A write of data[0..n) at `start` onto the Library page, fields already known writable
 * and in their static range: false if it picks a slot the library does not have; with
 * `apply`, carried out. */
bool lib_page_write(lib_device *l, uint8_t start, const uint8_t *data, uint16_t n, bool apply);
/* What the store writes to flash now (CTL_STORE_STATE_*) and how far (*percent, if not
 * NULL); `table_pending`: a committed table the app has not begun to save yet counts as
 * TABLE, on a store that saves in the background. */
uint8_t lib_saving(const lib_device *l, bool table_pending, uint8_t *percent);
/* Upload Commit LIBRARY_STORE of data[0..len) (checked by the caller) and
 * LIBRARY_DELETE: the result (STORE_BUSY while the store writes, `table_pending` as for
 * lib_saving; LIBRARY_STORING once it has begun to), also kept as Library Result. */
uint8_t lib_store_blob(lib_device *l, bool table_pending, const uint8_t *data, uint16_t len);
uint8_t lib_delete(lib_device *l, bool table_pending);
/* The blob slot `slot` would play (a whole table): CTL_UPLOAD_RESULT_OK and *data, *len,
 * *crc, or why not (STORE_BUSY while the store writes, see lib_saving: a play would
 * replace the table a save reads, or land on the staged blob a store reads). */
uint8_t lib_playable(const lib_device *l, uint8_t slot, bool table_pending,
                     const uint8_t **data, uint16_t *len, uint32_t *crc);
/* Keep `result` as Library Result; true if it is a failure (Error Flags LIBRARY):
 * LIBRARY_STORING is not. */
bool lib_note(lib_device *l, uint8_t result);

#endif
