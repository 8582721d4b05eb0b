/* The emulated STM32F103's USARTs (snakebot.sim.mcu.usart) in C where the firmware's
 * interrupt handlers reach them for every byte: a DR read, a DR write behind the byte being
 * sent, a CR1 write switching an interrupt on or off, and the interrupt line they move.
 * The shift register's timing, the far end and anything unusual stay in the Python model,
 * which keeps its state in the same mcu_fast_io (mcu_count.h).
 * Host-side only: never compiled into the firmware. */
#ifndef SNAKEBOT_MCU_USART_H
#define SNAKEBOT_MCU_USART_H

#include <stdint.h>

#include "mcu_count.h"

/* cffi:begin */
/* The interrupt line again from SR and CR1 (TXEIE and TXE, TCIE and TC, RXNEIE and RXNE or
 * ORE), told to the NVIC when high or changed. */
void mcu_usart_update_irq(mcu_fast_io *f);
/* cffi:end */

/* An access the C side serves (1, with *value for a read), or 0: the model's. */
int mcu_usart_read(mcu_fast_io *f, uint64_t offset, unsigned size, uint64_t *value);
int mcu_usart_write(mcu_fast_io *f, uint64_t offset, unsigned size, uint64_t value);

#endif
