/* What every board provides (firmware/boards/<board>/board.c), and all the application
 * (firmware/app) may ask of one: the contract between the two. Board facts that are plain
 * numbers (pins, memory, baud rates) live as macros in that board's board.h. */
#ifndef SNAKEBOT_BOARD_API_H
#define SNAKEBOT_BOARD_API_H

#include <stdint.h>

#include "hal_clock.h"

/* Bring up the clock tree; the result holds the frequencies really in effect. */
hal_clocks_t board_clock_init(void);

/* Enable the peripheral clocks, remaps and pin modes the firmware uses (the Dynamixel
 * bus, the PC link). The direction pins are configured by the USART driver. */
void board_pins_init(void);

/* The buttons held down now, as a CTL_BUTTONS_* mask (the Buttons register); undebounced. */
uint8_t board_buttons(void);

/* Light the LEDs whose CTL_LEDS_* bits are set in `on`, darken the others. */
void board_leds(uint8_t on);

#endif
