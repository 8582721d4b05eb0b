/* The PC-link fuzz target's gait library: a store of LIB_SLOTS slots in RAM that survives
 * the target's power cycles as flash would, and may, like the CM-530's, write in the
 * background over a few control ticks (pclink_store_model.c). */
#ifndef SNAKEBOT_FUZZ_PCLINK_STORE_MODEL_H
#define SNAKEBOT_FUZZ_PCLINK_STORE_MODEL_H

#include <stdbool.h>
#include <stdint.h>

#include "ctl_device.h"

#define LIB_SLOTS 3u

/* The store the device is given (ctl_set_library). */
extern const lib_store fuzz_library;

/* Every slot empty, nothing being written, the next write in the foreground: each input
 * starts so. */
void store_model_reset(void);
/* How the next put or remove runs: in the background over `ticks` control ticks (the
 * count is kept while a write is under way), or at once. */
void store_model_plan(bool in_background, uint8_t ticks);
/* Whether a background write is under way. */
bool store_model_busy(void);
/* Power is cut: a background write under way is lost, its slot left as it was. */
void store_model_power_cut(void);
/* A control tick of the background write; at its last, the slot changes and the store
 * tells the device d (ctl_library_stored). */
void lib_write_tick(ctl_device *d);
/* Whether table[0..len) is what a library slot keeps as a table. */
bool in_library(const uint8_t *table, uint16_t len);

#endif
