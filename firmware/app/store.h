/* Keeps the committed gait table across power cycles, in the flash pages the board sets
 * aside (BOARD_STORE_BASE), as a store_slots record: a power cut during a save leaves the
 * previous table. The robot's limits likewise, in their own pages
 * (BOARD_LIMITS_STORE_BASE). Boards without a flash store (qemu) keep it in RAM only:
 * there these do nothing. */
#ifndef SNAKEBOT_STORE_H
#define SNAKEBOT_STORE_H

#include <stdbool.h>

#include "ctl_device.h"
#include "store_lib.h"

/* At start-up: the stored robot's limits, then the stored table (if it fits them), if
 * there are valid ones. */
bool store_load(ctl_device *ctl);

/* After a commit: start writing the active table to flash (replacing a save under way);
 * store_save_step() does the work. */
void store_save_begin(const ctl_device *ctl);

/* Once per control tick, with the bus idle: the next step of the flash write under way
 * (the table save, or a library store or delete), bounded (STORE_SAVE_HALFWORDS;
 * docs/hardware.md has the figures): the F103 stalls while its flash is busy, so a step
 * holds up the loop for at most one page erase (20-40 ms) and the PC link may lose bytes
 * meanwhile. A table save whose table an upload dropped ends without touching the
 * previous record; a library store's outcome goes to the core (ctl_library_stored). True
 * while a write is under way. */
bool store_save_step(ctl_device *ctl);

/* What is being written (CTL_STORE_STATE_*) and how far (*percent, 0..100): the library
 * store's `saving` (lib_regs.h). */
uint8_t store_saving(uint8_t *percent);

/* On a board with a flash library: begin storing data[0..len) as library slot `slot`
 * (kind STORE_LIB_KIND_EMPTY: begin emptying it). CTL_UPLOAD_RESULT_LIBRARY_STORING once
 * begun (store_save_step() runs it), STORE_BUSY while another write runs, or why not. */
uint8_t store_library_begin(uint8_t slot, uint8_t kind, const uint8_t *name,
                            const uint8_t *data, uint16_t len);

/* After the robot's limits were set: write them to their own store (blocks likewise). */
bool store_save_limits(const ctl_device *ctl);

/* The board's gait library in flash; NULL on boards without one (qemu). */
const store_lib_t *store_library(void);

#endif
