/* SysTick: a 1 ms tick counter, the firmware's only time base. */
#ifndef SNAKEBOT_HAL_SYSTICK_H
#define SNAKEBOT_HAL_SYSTICK_H

#include <stdint.h>

/* Start SysTick at 1 kHz from the core clock (hclk_hz) with the given priority (0..15). */
void hal_systick_init(uint32_t hclk_hz, unsigned priority);

/* Milliseconds since hal_systick_init(); wraps after 49 days (compare with subtraction). */
uint32_t hal_millis(void);

/* Microseconds since hal_systick_init(), from the tick count and SysTick's down-counter;
 * wraps after 71 minutes (compare with subtraction). */
uint32_t hal_micros(void);

/* The SysTick interrupt body: call it from SysTick_Handler. */
void hal_systick_isr(void);

#endif
