/* The gait library on the robot: each control tick, the board's buttons go to the
 * library panel (core/lib_panel.h) and its LEDs show the slot picked. START plays the
 * picked slot's gait table (loaded from the flash library, checked against its CRC and
 * the robot's limits) or stops. A board without a flash library (qemu) has one slot:
 * the active table. */
#ifndef SNAKEBOT_STORE_PLAY_H
#define SNAKEBOT_STORE_PLAY_H

#include <stdint.h>

#include "ctl_device.h"

void store_play_init(void);

/* One control tick of the panel. Call it after anything the PC link committed has been
 * persisted: playing a slot replaces the active table without persisting it. */
void store_play_tick(ctl_device *ctl, uint32_t now_ms);

#endif
