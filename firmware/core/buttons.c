#include "buttons.h"

void buttons_init(buttons_t *b)
{
    b->held = 0;
    b->cnt0 = 0;
    b->cnt1 = 0;
}

uint8_t buttons_scan(buttons_t *b, uint8_t raw)
{
    /* Buttons whose sample differs from their debounced state count up; the others
     * start again from 0. A counter at 3 that differs once more (the fourth scan in a
     * row: BUTTONS_DEBOUNCE_SCANS) flips the state, and wraps to 0 by itself. */
    uint8_t differ = (uint8_t)(raw ^ b->held);
    uint8_t flip = (uint8_t)(differ & b->cnt0 & b->cnt1);
    b->cnt1 = (uint8_t)((b->cnt1 ^ b->cnt0) & differ);
    b->cnt0 = (uint8_t)(~b->cnt0 & differ);
    b->held ^= flip;
    return (uint8_t)(flip & b->held);
}
