/* USART for the STM32F1 (RM0008 section 27), 8N1, interrupt driven. */
#include "hal_usart.h"

#include "hal_cpu.h"
#include "hal_io.h"
#include "hal_regs.h"

#define CR1_BASE (HAL_USART_CR1_UE | HAL_USART_CR1_TE | HAL_USART_CR1_RE | HAL_USART_CR1_RXNEIE)

/* How long hal_usart_set_baud() waits for a transmission to drain (polls). */
#define DRAIN_POLLS 200000UL

static void line_receive(hal_usart_t *u)
{
    hal_gpio_write(u->tx_enable, false);
    hal_gpio_write(u->rx_enable, true);
}

static void line_transmit(hal_usart_t *u)
{
    hal_gpio_write(u->rx_enable, false);
    hal_gpio_write(u->tx_enable, true);
}

uint32_t hal_usart_actual_baud(uint32_t pclk_hz, uint32_t baud)
{
    if (baud == 0U) {
        return 0U;
    }
    uint32_t brr = (pclk_hz + baud / 2U) / baud;
    return brr == 0U ? 0U : pclk_hz / brr;
}

static void write_brr(hal_usart_t *u, uint32_t pclk_hz, uint32_t baud)
{
    /* BRR holds USARTDIV in 12.4 fixed point; with 16x oversampling that is pclk / baud. */
    uint32_t brr = baud == 0U ? 0xFFFFU : (pclk_hz + baud / 2U) / baud;
    if (brr < 16U) {
        brr = 16U;
    } else if (brr > 0xFFFFU) {
        brr = 0xFFFFU;
    }
    hal_io_write32(HAL_USART_BRR(u->base), brr);
}

void hal_usart_init(hal_usart_t *u, uint32_t pclk_hz, uint32_t baud, unsigned priority)
{
    hal_nvic_disable(u->irq);
    hal_gpio_config(u->tx_enable, HAL_GPIO_OUTPUT_PP_50MHZ);
    hal_gpio_config(u->rx_enable, HAL_GPIO_OUTPUT_PP_50MHZ);
    line_receive(u);

    hal_io_write32(HAL_USART_CR1(u->base), 0);
    hal_io_write32(HAL_USART_CR2(u->base), 0); /* 1 stop bit */
    hal_io_write32(HAL_USART_CR3(u->base), 0); /* no flow control, no DMA */
    write_brr(u, pclk_hz, baud);
    u->rx.head = u->rx.tail = 0U;
    u->tx.head = u->tx.tail = 0U;
    u->transmitting = false;
    hal_io_write32(HAL_USART_CR1(u->base), CR1_BASE);
    /* Discard whatever sat in the receiver before we were listening. */
    (void)hal_io_read32(HAL_USART_SR(u->base));
    (void)hal_io_read32(HAL_USART_DR(u->base));
    hal_nvic_enable(u->irq, priority);
}

void hal_usart_set_baud(hal_usart_t *u, uint32_t pclk_hz, uint32_t baud)
{
    for (uint32_t n = 0; n < DRAIN_POLLS && !hal_usart_tx_done(u); n++) {
        hal_usart_service(u);
    }
    uint32_t primask = hal_irq_save();
    uint32_t cr1 = hal_io_read32(HAL_USART_CR1(u->base));
    hal_io_write32(HAL_USART_CR1(u->base), cr1 & ~HAL_USART_CR1_UE);
    write_brr(u, pclk_hz, baud);
    hal_io_write32(HAL_USART_CR1(u->base), cr1);
    hal_irq_restore(primask);
}

size_t hal_usart_read(hal_usart_t *u, uint8_t *buf, size_t cap)
{
    size_t n = 0;
    while (n < cap && hal_ring_get(&u->rx, &buf[n])) {
        n++;
    }
    return n;
}

size_t hal_usart_tx_free(const hal_usart_t *u)
{
    return hal_ring_free(&u->tx);
}

bool hal_usart_tx_done(const hal_usart_t *u)
{
    return !u->transmitting;
}

void hal_usart_flush_rx(hal_usart_t *u)
{
    hal_ring_clear(&u->rx);
}

bool hal_usart_send(hal_usart_t *u, const uint8_t *data, size_t len)
{
    if (len == 0U) {
        return true;
    }
    if (len > hal_ring_free(&u->tx)) {
        return false;
    }
    for (size_t i = 0; i < len; i++) {
        (void)hal_ring_put(&u->tx, data[i]);
    }
    uint32_t primask = hal_irq_save();
    if (!u->transmitting) {
        u->transmitting = true;
        line_transmit(u);
    }
    hal_io_modify32(HAL_USART_CR1(u->base), 0, HAL_USART_CR1_TXEIE);
    hal_irq_restore(primask);
    return true;
}

/* The ring is empty and TC is set: the last stop bit is out. Back to receive. */
static void finish_transmit(hal_usart_t *u)
{
    hal_io_modify32(HAL_USART_CR1(u->base), HAL_USART_CR1_TXEIE | HAL_USART_CR1_TCIE, 0);
    line_receive(u);
    u->transmitting = false;
}

/* One step of the transmitter given a fresh SR value: feed a byte on TXE, or, once the
 * ring has run dry, wait for TC. Returns true if it wrote a byte. Interrupts masked. */
static bool transmit_step(hal_usart_t *u, uint32_t sr)
{
    if (!u->transmitting) {
        return false;
    }
    uint8_t byte;
    if ((sr & HAL_USART_SR_TXE) && hal_ring_get(&u->tx, &byte)) {
        /* Reading SR (done by the caller) then writing DR clears TC. */
        hal_io_write32(HAL_USART_DR(u->base), byte);
        return true;
    }
    if (hal_ring_count(&u->tx) == 0U) {
        if (sr & HAL_USART_SR_TC) {
            finish_transmit(u);
        } else {
            hal_io_modify32(HAL_USART_CR1(u->base), HAL_USART_CR1_TXEIE, HAL_USART_CR1_TCIE);
        }
    }
    return false;
}

void hal_usart_service_bytes(hal_usart_t *u, uint32_t max)
{
    /* Only this (main-loop) side sets `transmitting`: seen clear, there is nothing to feed,
     * and the critical section is skipped. */
    if (max == 0U || !u->transmitting) {
        return;
    }
    uint32_t primask = hal_irq_save();
    /* Feed while the hardware takes bytes: one on a real USART, all of them in QEMU. The
     * ring bounds the loop. */
    for (uint32_t n = 0; n < max && transmit_step(u, hal_io_read32(HAL_USART_SR(u->base)));
         n++) {
    }
    hal_irq_restore(primask);
}

void hal_usart_service(hal_usart_t *u)
{
    hal_usart_service_bytes(u, UINT32_MAX);
}

void hal_usart_isr(hal_usart_t *u)
{
    uint32_t sr = hal_io_read32(HAL_USART_SR(u->base));
    if (sr & (HAL_USART_SR_RXNE | HAL_USART_SR_ORE)) {
        /* Reading DR after SR clears RXNE and the error flags together. */
        uint8_t byte = (uint8_t)hal_io_read32(HAL_USART_DR(u->base));
        if (sr & HAL_USART_SR_ORE) {
            u->rx_overruns++;
        }
        if (sr & (HAL_USART_SR_FE | HAL_USART_SR_NE | HAL_USART_SR_PE)) {
            u->rx_errors++;
        }
        if (sr & HAL_USART_SR_RXNE) {
            if (u->transmitting && u->tx_enable.port != 0U) {
                u->rx_ignored++; /* a half-duplex line hears itself; not ours to keep */
            } else if (!hal_ring_put(&u->rx, byte)) {
                u->rx_dropped++;
            }
        }
    }
    uint32_t cr1 = hal_io_read32(HAL_USART_CR1(u->base));
    if (cr1 & (HAL_USART_CR1_TXEIE | HAL_USART_CR1_TCIE)) {
        (void)transmit_step(u, sr);
    }
}
