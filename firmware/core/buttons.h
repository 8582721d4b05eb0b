/* Debounced push buttons, scanned once a control tick. The board reads its pins into a
 * mask of the buttons held down (CTL_BUTTONS_*: the Buttons register's bits), whatever
 * their electrical level; a change
 * counts once it has been seen on BUTTONS_DEBOUNCE_SCANS scans in a row, so contact
 * bounce shorter than that (3 ticks: 30 ms at the 10 ms tick) is ignored. Each button
 * has its own 2-bit counter, kept "vertically" (bit k of cnt0/cnt1 is button k's counter),
 * so the scan is a handful of bitwise operations for all of them at once. */
#ifndef SNAKEBOT_BUTTONS_H
#define SNAKEBOT_BUTTONS_H

#include <stdint.h>

/* cffi:begin */
/* Scans in a row a change must last to count. */
#define BUTTONS_DEBOUNCE_SCANS 4

typedef struct {
    uint8_t held; /* debounced: the buttons down */
    uint8_t cnt0; /* per-button scan counters, low bits */
    uint8_t cnt1; /* and high bits */
} buttons_t;

/* All released. */
void buttons_init(buttons_t *b);
/* One scan of `raw` (CTL_BUTTONS_* held now, undebounced); returns the buttons that have just
 * become pressed (debounced), each once per press. */
uint8_t buttons_scan(buttons_t *b, uint8_t raw);
/* cffi:end */

#endif
