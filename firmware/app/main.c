/* CM-530 controller firmware: the main loop. Interrupt handlers only move bytes between
 * the USARTs and ring buffers; everything else happens here, in order, every pass:
 * the PC link, the control tick (player, safety, bus schedule), the bus transactions,
 * persisting a newly committed table, the drivers' polled work, then sleep until the
 * next interrupt if there was nothing to do. */
#include <stdbool.h>
#include <stdint.h>

#include "board.h"
#include "busport.h"
#include "ctl_device.h"
#include "hal_systick.h"
#include "pclink.h"
#include "platform.h"
#include "store.h"
#include "store_play.h"

static ctl_device ctl;

int main(void)
{
    platform_init();
    ctl_init(&ctl);
    ctl_set_capacity(&ctl, BOARD_TABLE_CAPACITY);
    (void)store_load(&ctl);
    (void)ctl_table_changed(&ctl); /* loading from the store is not a change to store */
    (void)ctl_limits_changed(&ctl);
    ctl_set_board(&ctl, BOARD_ID);
    pclink_init();
    busport_init();
    store_play_init(&ctl);

    uint32_t next_tick = hal_millis();
    for (;;) {
        uint32_t now = hal_millis();
        bool worked = pclink_poll(&ctl, now);
        bool ticked = false;
        if (busport_idle() && (int32_t)(now - next_tick) >= 0) {
            ticked = true;
            ctl_tick(&ctl, now);
            busport_begin();
            next_tick += BOARD_CONTROL_TICK_MS;
            if ((int32_t)(now - next_tick) >= 0) {
                next_tick = now + BOARD_CONTROL_TICK_MS; /* fell behind: skip, do not burst */
            }
            worked = true;
        }
        worked |= busport_poll(&ctl);
        if (ctl_table_changed(&ctl)) {
            (void)store_save(&ctl);
        }
        if (ctl_limits_changed(&ctl)) {
            (void)store_save_limits(&ctl);
        }
        if (ticked) {
            store_play_tick(&ctl, now); /* the buttons: after persisting, see store_play.h */
        }
        platform_service();
        platform_idle(!worked);
    }
}
