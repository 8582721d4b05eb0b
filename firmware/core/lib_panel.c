#include "lib_panel.h"

/* The slot LEDs count in binary up to the PLAY LED, enough for every slot. */
#define SLOT_LEDS (CTL_LEDS_SLOT_1 | CTL_LEDS_SLOT_2 | CTL_LEDS_SLOT_4)
typedef char slot_leds_show_every_slot[SLOT_LEDS + 1 >= CTL_MAX_LIBRARY_SLOTS &&
                                               SLOT_LEDS + 1 == CTL_LEDS_PLAY
                                           ? 1
                                           : -1];

void lib_panel_init(lib_panel_t *p)
{
    buttons_init(&p->keys);
    p->slot = 0;
}

uint8_t lib_panel_tick(lib_panel_t *p, uint8_t raw, uint8_t slots, bool playing)
{
    uint8_t pressed = buttons_scan(&p->keys, raw);
    if (slots == 0U) {
        p->slot = 0;
        return LIB_PANEL_NOTHING;
    }
    if (p->slot >= slots) {
        p->slot = 0;
    }
    if (pressed & CTL_BUTTONS_U) {
        p->slot = (uint8_t)((p->slot + 1U) % slots);
    }
    if (pressed & CTL_BUTTONS_D) {
        p->slot = (uint8_t)((p->slot + slots - 1U) % slots);
    }
    if (pressed & CTL_BUTTONS_START) {
        return playing ? LIB_PANEL_STOP : LIB_PANEL_PLAY;
    }
    return LIB_PANEL_NOTHING;
}

uint8_t lib_panel_leds(const lib_panel_t *p, bool playing)
{
    uint8_t leds = (uint8_t)(p->slot & SLOT_LEDS);
    return playing ? (uint8_t)(leds | CTL_LEDS_PLAY) : leds;
}
