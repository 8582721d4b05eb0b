/* The PC link: Protocol 1.0 packets in from USART3, answers out. Bytes go from the
 * receive ring into the controller device (ctl_device, firmware/core), its answers into
 * the transmit ring. */
#ifndef SNAKEBOT_PCLINK_H
#define SNAKEBOT_PCLINK_H

#include <stdbool.h>
#include <stdint.h>

#include "ctl_device.h"

/* A gap longer than this between bytes of one packet drops the partial packet, as a
 * Dynamixel device does (e-Manual: 100 ms). Without it, a stray header promising a long
 * packet would swallow the host's next instructions until 250 bytes had arrived. */
#define PCLINK_GAP_MS 100U

typedef struct {
    uint16_t gap_resets; /* partial packets dropped after PCLINK_GAP_MS */
    uint16_t tx_dropped; /* answers that did not fit the transmit ring */
} pclink_stats_t;

void pclink_init(void);

/* Drain the receive ring into the device and queue its answers. True if it did work. */
bool pclink_poll(ctl_device *ctl, uint32_t now_ms);

const pclink_stats_t *pclink_stats(void);

#endif
