/* The hardware as the application sees it: the two serial lines and the start-up facts.
 * platform.c wires the HAL to the board's description (board.h). */
#ifndef SNAKEBOT_PLATFORM_H
#define SNAKEBOT_PLATFORM_H

#include <stdint.h>

#include "hal_clock.h"
#include "hal_usart.h"

/* Why the MCU last reset (from RCC_CSR; 0 where the emulator does not model it). */
#define PLATFORM_RESET_PIN 0x01U
#define PLATFORM_RESET_POWER 0x02U
#define PLATFORM_RESET_SOFTWARE 0x04U /* includes a fault, see hal_startup.c */
#define PLATFORM_RESET_WATCHDOG 0x08U

typedef struct {
    hal_clocks_t clocks;
    uint8_t reset_cause; /* PLATFORM_RESET_* bits */
} platform_info_t;

/* The Dynamixel bus (half duplex) and the PC link. */
extern hal_usart_t platform_bus;
extern hal_usart_t platform_pc;

/* Clock, pins, SysTick, both USARTs, then the watchdog. Call first thing in main(). */
void platform_init(void);

/* What platform_init() found. */
const platform_info_t *platform_info(void);

/* The main loop's share of the drivers' work; call every iteration. */
void platform_service(void);

/* Sleep until the next interrupt if `idle` (nothing buffered to process; a transmission
 * under way wakes it with its own interrupts); always feeds the watchdog. The SysTick
 * interrupt bounds the sleep to 1 ms. */
void platform_idle(int idle);

#endif
