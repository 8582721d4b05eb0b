/* The gait library on the robot itself: the CM-530's U and D buttons pick a slot (wrapping
 * round), START plays the picked slot or stops what plays, and the LEDs show the slot
 * number in binary and whether something plays. Fed each control tick with the board's
 * button mask; what to do comes back as an action for the app to carry out. */
#ifndef SNAKEBOT_LIB_PANEL_H
#define SNAKEBOT_LIB_PANEL_H

#include <stdbool.h>
#include <stdint.h>

#include "buttons.h"
#include "ctl_table.h"

/* cffi:begin */
#define LIB_PANEL_NOTHING 0
#define LIB_PANEL_PLAY 1
#define LIB_PANEL_STOP 2

typedef struct {
    buttons_t keys;
    uint8_t slot; /* the slot picked, 0 .. slots - 1 */
} lib_panel_t;

/* Released buttons, slot 0 picked. */
void lib_panel_init(lib_panel_t *p);
/* One control tick: `raw` = the CTL_BUTTONS_* held now, `slots` = how many slots there are,
 * `playing` = whether a gait plays. Returns LIB_PANEL_PLAY (play p->slot),
 * LIB_PANEL_STOP or LIB_PANEL_NOTHING. */
uint8_t lib_panel_tick(lib_panel_t *p, uint8_t raw, uint8_t slots, bool playing);
/* The LEDs to light (CTL_LEDS_*: the slot number in binary, PLAY while playing). */
uint8_t lib_panel_leds(const lib_panel_t *p, bool playing);
/* cffi:end */

#endif
