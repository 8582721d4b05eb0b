/* Keeps the committed gait table across power cycles, in the flash pages the board sets
 * aside (BOARD_STORE_BASE), as a store_slots record: a power cut during a save leaves the
 * previous table. Boards without a flash store (qemu) keep it in RAM only:
 * there these do nothing. */
#ifndef SNAKEBOT_STORE_H
#define SNAKEBOT_STORE_H

#include <stdbool.h>

#include "ctl_device.h"

/* At start-up: make the stored table active if there is a valid one. */
bool store_load(ctl_device *ctl);

/* After a commit: write the active table (blocks for the erase and programming, about
 * 100 ms; the PC link may lose bytes meanwhile, since the F103 stalls while its flash is
 * busy). */
bool store_save(const ctl_device *ctl);

#endif
