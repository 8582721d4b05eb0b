#include "lib_panel.h"

typedef char slot_bits_below_the_playing_led[(1U << LIB_PANEL_LED_SLOT_BITS) ==
                                                     LIB_PANEL_LED_PLAYING
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
    if (pressed & BUTTON_U) {
        p->slot = (uint8_t)((p->slot + 1U) % slots);
    }
    if (pressed & BUTTON_D) {
        p->slot = (uint8_t)((p->slot + slots - 1U) % slots);
    }
    if (pressed & BUTTON_START) {
        return playing ? LIB_PANEL_STOP : LIB_PANEL_PLAY;
    }
    return LIB_PANEL_NOTHING;
}

uint8_t lib_panel_leds(const lib_panel_t *p, bool playing)
{
    uint8_t leds = (uint8_t)(p->slot & (LIB_PANEL_LED_PLAYING - 1U));
    return playing ? (uint8_t)(leds | LIB_PANEL_LED_PLAYING) : leds;
}
