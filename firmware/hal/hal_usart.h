/* USART driver: interrupt-driven receive and transmit rings, and half-duplex direction
 * control for the Dynamixel bus (the line returns to receive only after TC, when the
 * last stop bit has left the pin, not at TXE, when the last byte merely left the buffer).
 *
 * The interrupt handler moves bytes between the data register and the rings; the main
 * loop reads and writes the rings. hal_usart_service() does the same work by polling,
 * for QEMU's USART model, which raises no TXE/TC interrupts (it completes every write at
 * once), and costs nothing on the real chip, where the interrupt usually got there first. */
#ifndef SNAKEBOT_HAL_USART_H
#define SNAKEBOT_HAL_USART_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal_gpio.h"
#include "hal_ring.h"

typedef struct {
    /* configuration, filled in statically (designated initializers) before hal_usart_init();
     * rings from HAL_RING_STORAGE buffers via HAL_RING_INIT */
    uint32_t base;        /* HAL_USARTx_BASE */
    uint8_t irq;          /* HAL_IRQ_USARTx */
    hal_pin_t tx_enable;  /* high while transmitting (port 0: none) */
    hal_pin_t rx_enable;  /* high while receiving (port 0: none) */
    hal_ring_t rx;
    hal_ring_t tx;
    /* state */
    volatile bool transmitting; /* line turned to transmit; cleared after the final TC */
    /* counters, for diagnostics (wrap around) */
    volatile uint16_t rx_overruns; /* a byte arrived before the previous one was read */
    volatile uint16_t rx_errors;   /* framing, noise or parity error on a received byte */
    volatile uint16_t rx_dropped;  /* receive ring full */
    volatile uint16_t rx_ignored;  /* arrived while this side was transmitting (echo) */
} hal_usart_t;

/* Set up 8N1 at `baud` from the peripheral clock `pclk_hz`, enable receive interrupts at
 * NVIC priority `priority`, and leave the line receiving. The peripheral's clock and its
 * pins must already be configured. */
void hal_usart_init(hal_usart_t *u, uint32_t pclk_hz, uint32_t baud, unsigned priority);

/* Change the baud rate (waits for a transmission in progress to finish first). */
void hal_usart_set_baud(hal_usart_t *u, uint32_t pclk_hz, uint32_t baud);

/* The baud rate the hardware really produces for a requested one (BRR rounding). */
uint32_t hal_usart_actual_baud(uint32_t pclk_hz, uint32_t baud);

/* Move up to `cap` received bytes into `buf`; returns how many. */
size_t hal_usart_read(hal_usart_t *u, uint8_t *buf, size_t cap);

/* Queue `len` bytes for sending, all or none: false (nothing queued) when the transmit
 * ring lacks room. Turns a half-duplex line to transmit. */
bool hal_usart_send(hal_usart_t *u, const uint8_t *data, size_t len);

/* Free space in the transmit ring. */
size_t hal_usart_tx_free(const hal_usart_t *u);

/* True when everything queued has left the pin and the line is back to receive. */
bool hal_usart_tx_done(const hal_usart_t *u);

/* Forget received bytes not read yet. */
void hal_usart_flush_rx(hal_usart_t *u);

/* Polling half of the driver: feed the transmitter, turn the line around after TC.
 * Call from the main loop. */
void hal_usart_service(hal_usart_t *u);
/* The same, writing at most `max` bytes to the data register (a USART without baud
 * timing, as QEMU's, takes every byte at once: its caller paces it). */
void hal_usart_service_bytes(hal_usart_t *u, uint32_t max);

/* The interrupt body: call from USARTx_IRQHandler. */
void hal_usart_isr(hal_usart_t *u);

#endif
