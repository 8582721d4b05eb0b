/* The emulated STM32F103's GPIO output latch in C (snakebot.sim.mcu.gpio keeps ODR here):
 * BSRR writes, which the firmware makes around every bus packet to turn the half-duplex
 * buffer, IDR reads, with which it polls its buttons every tick, and the receive enable a board derives from two of its pins (a USART's
 * rx_listens, mcu_count.h), kept current here.
 * Host-side only: never compiled into the firmware. */
#ifndef SNAKEBOT_MCU_GPIO_H
#define SNAKEBOT_MCU_GPIO_H

#include <stdint.h>

#include "mcu_count.h"

/* cffi:begin */
/* The pins changed (ODR or the outputs mask): the linked USART's rx_listens again. */
void mcu_gpio_changed(mcu_fast_io *f);
/* A read the C side serves (1, the register in *value), or 0: the model's. */
int mcu_gpio_read(const mcu_fast_io *f, uint64_t offset, unsigned size, uint64_t *value);
/* cffi:end */

/* A write the C side serves (1), or 0: the model's. */
int mcu_gpio_write(mcu_fast_io *f, uint64_t offset, unsigned size, uint64_t value);

#endif
