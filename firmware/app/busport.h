/* The Dynamixel bus side of the main loop: runs the bus master's transactions for one
 * control tick on USART1 without blocking. For each packet the core produces: send it
 * (the driver turns the half-duplex line), wait for the last stop bit, and if a status
 * packet is expected, feed received bytes to the core until it has the reply or the
 * reply window (BOARD_BUS_REPLY_TIMEOUT_US) closes. */
#ifndef SNAKEBOT_BUSPORT_H
#define SNAKEBOT_BUSPORT_H

#include <stdbool.h>
#include <stdint.h>

#include "ctl_device.h"

typedef struct {
    uint16_t packets;   /* packets sent */
    uint16_t timeouts;  /* reply windows that closed without a complete reply */
    uint16_t refused;   /* packets that did not fit the transmit ring (a bug if ever > 0) */
} busport_stats_t;

void busport_init(void);

/* Start the transactions of a tick (call right after ctl_tick()). */
void busport_begin(void);

/* Advance; true if it did work. */
bool busport_poll(ctl_device *ctl);

/* True when the tick's transactions are all done. */
bool busport_idle(void);

const busport_stats_t *busport_stats(void);

#endif
