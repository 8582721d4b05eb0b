/* Bus transactions as a state machine, one step per main-loop pass. */
#include "busport.h"

#include <stddef.h>

#include "board.h"
#include "hal_systick.h"
#include "platform.h"

typedef char bus_tx_ring_holds_a_packet[BOARD_BUS_TX_RING >= CTL_BUS_TX_MAX ? 1 : -1];

typedef enum { BP_IDLE, BP_NEXT, BP_SENDING, BP_AWAIT } busport_state_t;

static busport_state_t state = BP_IDLE;
static uint8_t tx[CTL_BUS_TX_MAX];
static uint8_t reply_len;
static uint32_t deadline_us;
static busport_stats_t stats;

void busport_init(void)
{
    state = BP_IDLE;
}

void busport_begin(void)
{
    state = BP_NEXT;
}

bool busport_idle(void)
{
    return state == BP_IDLE;
}

static bool next_packet(ctl_device *ctl)
{
    size_t n = ctl_bus_next(ctl, tx, sizeof tx, &reply_len);
    if (n == 0U) {
        state = BP_IDLE;
        return true;
    }
    hal_usart_flush_rx(&platform_bus); /* a late reply to an earlier READ is not this one's */
    if (!hal_usart_send(&platform_bus, tx, n)) {
        stats.refused++;
        if (reply_len > 0U) {
            ctl_bus_rx_done(ctl); /* counts as a timeout: nothing was asked */
        }
        return true;
    }
    stats.packets++;
    state = BP_SENDING;
    return true;
}

bool busport_poll(ctl_device *ctl)
{
    switch (state) {
    case BP_NEXT:
        return next_packet(ctl);
    case BP_SENDING:
        if (!hal_usart_tx_done(&platform_bus)) {
            return false;
        }
        if (reply_len == 0U) {
            state = BP_NEXT;
        } else {
            deadline_us = hal_micros() + BOARD_BUS_REPLY_TIMEOUT_US;
            state = BP_AWAIT;
        }
        return true;
    case BP_AWAIT: {
        uint8_t chunk[32];
        size_t n = hal_usart_read(&platform_bus, chunk, sizeof chunk);
        if (n > 0U) {
            if (ctl_bus_rx(ctl, chunk, n)) {
                ctl_bus_rx_done(ctl);
                state = BP_NEXT;
            }
            return true;
        }
        if ((int32_t)(hal_micros() - deadline_us) >= 0) {
            stats.timeouts++;
            ctl_bus_rx_done(ctl);
            state = BP_NEXT;
            return true;
        }
        return false;
    }
    case BP_IDLE:
    default:
        return false;
    }
}

const busport_stats_t *busport_stats(void)
{
    return &stats;
}
