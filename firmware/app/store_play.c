#include "store_play.h"

#include <stdbool.h>
#include <stddef.h>

#include "board_api.h"
#include "lib_panel.h"
#include "store.h"

static lib_panel_t panel;

void store_play_init(void)
{
    lib_panel_init(&panel);
    board_leds(lib_panel_leds(&panel, false));
}

static bool moving(const ctl_device *ctl)
{
    uint8_t s = ctl_state(ctl);
    return s == CTL_STATE_PLAYING || s == CTL_STATE_SERPENOID;
}

/* Make the slot's table the active one: false if it holds no table that loads. */
static bool load_slot(ctl_device *ctl, const store_lib_t *lib, uint8_t slot)
{
    store_lib_entry_t e;
    if (store_lib_entry(lib, slot, &e) != STORE_LIB_OK || e.kind != CTL_UPLOAD_COMMIT_TABLE ||
        !ctl_load_table(ctl, (const uint8_t *)(uintptr_t)e.addr, e.len)) {
        return false;
    }
    (void)ctl_table_changed(ctl); /* already in flash: nothing to persist */
    return true;
}

void store_play_tick(ctl_device *ctl, uint32_t now_ms)
{
    const store_lib_t *lib = store_library();
    uint8_t slots = lib != NULL ? STORE_LIB_SLOTS : 1U;
    uint8_t action = lib_panel_tick(&panel, board_buttons(), slots, moving(ctl));
    if (action == LIB_PANEL_STOP) {
        ctl_command(ctl, CTL_COMMAND_STOP, now_ms);
    } else if (action == LIB_PANEL_PLAY) {
        if (lib == NULL || load_slot(ctl, lib, panel.slot)) {
            ctl_command(ctl, CTL_COMMAND_PLAY, now_ms);
        }
    }
    board_leds(lib_panel_leds(&panel, moving(ctl)));
}
