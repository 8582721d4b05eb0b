/* The gait library's store as the controller core sees it (lib_store, core/lib_regs.h),
 * and the robot's buttons and LEDs fed through the core's library panel each control tick.
 * On a board with a flash library (the CM-530) the store is app/store_lib.c; on one without
 * (QEMU: its flash is ROM and its 8 KB of RAM are spoken for) the library has one slot
 * that aliases the active table: storing a table there makes it the active table, and the
 * slot empties once another table is made active. */
#ifndef SNAKEBOT_STORE_PLAY_H
#define SNAKEBOT_STORE_PLAY_H

#include <stdint.h>

#include "ctl_device.h"

/* Give `ctl` the board's library (once, at start-up). */
void store_play_init(ctl_device *ctl);

/* One control tick of the buttons and LEDs. Playing a slot replaces the active table
 * without persisting it; a save of the table it replaced that is still under way then
 * ends without touching the stored table (store.h). */
void store_play_tick(ctl_device *ctl, uint32_t now_ms);

#endif
