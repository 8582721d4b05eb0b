/* PC link: receive ring -> ctl_device -> transmit ring. */
#include "pclink.h"

#include <stddef.h>

#include "board.h"
#include "dxl_parser.h"
#include "platform.h"

typedef char pc_tx_ring_holds_a_reply[BOARD_PC_TX_RING >= CTL_PC_REPLY_MAX ? 1 : -1];

static uint8_t reply[CTL_PC_REPLY_MAX];
static uint32_t last_byte_ms;
static pclink_stats_t stats;

void pclink_init(void)
{
    last_byte_ms = 0;
}

static void answer_all(ctl_device *ctl, uint32_t now_ms)
{
    size_t n;
    while (ctl_pc_poll(ctl, now_ms, reply, sizeof reply, &n)) {
        if (n > 0U && !hal_usart_send(&platform_pc, reply, n)) {
            stats.tx_dropped++;
        }
    }
}

bool pclink_poll(ctl_device *ctl, uint32_t now_ms)
{
    uint8_t chunk[32];
    size_t n;
    bool worked = false;
    /* At most one ring's worth per pass: a host that never stops sending must not keep
     * the main loop from its control tick. */
    for (size_t taken = 0; taken < BOARD_PC_RX_RING &&
                           (n = hal_usart_read(&platform_pc, chunk, sizeof chunk)) > 0U;
         taken += n) {
        worked = true;
        last_byte_ms = now_ms;
        for (size_t i = 0; i < n; i++) {
            /* Polling after every byte keeps the parser below its limit, so the feed
             * always succeeds; the loop is bounded by that all the same. */
            for (int tries = 0; tries < 2 && !ctl_pc_feed(ctl, chunk[i]); tries++) {
                answer_all(ctl, now_ms);
            }
            answer_all(ctl, now_ms);
        }
    }
    /* The device's parser is the one inside ctl_device (public in ctl_device.h). */
    if (dxl_parser_pending(&ctl->pc) > 0U && (uint32_t)(now_ms - last_byte_ms) > PCLINK_GAP_MS) {
        dxl_parser_reset(&ctl->pc);
        stats.gap_resets++;
    }
    return worked;
}

const pclink_stats_t *pclink_stats(void)
{
    return &stats;
}
