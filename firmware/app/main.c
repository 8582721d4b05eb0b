/* CM-530 controller firmware: the main loop. Interrupt handlers only move bytes between
 * the USARTs and ring buffers; everything else happens here, in order, every pass:
 * the PC link, the control tick (player, safety, bus schedule), the bus transactions,
 * a bounded step of the flash write under way (a newly committed table's save, a library
 * store or delete), the drivers' polled work, then
 * sleep until the next interrupt if there was nothing to do. */
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

/* The controller, followed by its table arena (the active table and the staging area,
 * sized by the board). */
static union {
    ctl_device d;
    uint8_t bytes[sizeof(ctl_device) + BOARD_TABLE_ARENA];
} ctl;

int main(void)
{
    platform_init();
    ctl_init(&ctl.d);
    ctl_set_tables(&ctl.d, BOARD_TABLE_ARENA, BOARD_TABLE_CAPACITY);
    (void)store_load(&ctl.d);
    (void)ctl_table_changed(&ctl.d); /* loading from the store is not a change to store */
    (void)ctl_limits_changed(&ctl.d);
    ctl_set_board(&ctl.d, BOARD_ID);
    pclink_init();
    busport_init();
    store_play_init(&ctl.d);

    uint32_t next_tick = hal_millis();
    bool flash_due = false; /* this tick's step of a flash write is still to run */
    for (;;) {
        uint32_t now = hal_millis();
        bool worked = pclink_poll(&ctl.d, now);
        bool ticked = false;
        if (busport_idle() && (int32_t)(now - next_tick) >= 0) {
            ticked = true;
            ctl_tick(&ctl.d, now);
            busport_begin();
            next_tick += BOARD_CONTROL_TICK_MS;
            if ((int32_t)(now - next_tick) >= 0) {
                next_tick = now + BOARD_CONTROL_TICK_MS; /* fell behind: skip, do not burst */
            }
            flash_due = true;
            worked = true;
        }
        worked |= busport_poll(&ctl.d);
        if (ctl_table_changed(&ctl.d)) {
            store_save_begin(&ctl.d);
        }
        /* one bounded step per tick, once the bus is quiet: the CPU stalls while the flash
         * is busy, and a servo's reply must not arrive meanwhile */
        if (flash_due && busport_idle()) {
            flash_due = false;
            (void)store_save_step(&ctl.d);
        }
        if (ctl_limits_changed(&ctl.d)) {
            (void)store_save_limits(&ctl.d);
        }
        if (ticked) {
            store_play_tick(&ctl.d, now); /* the buttons, see store_play.h */
        }
        platform_service();
        platform_idle(!worked);
    }
}
