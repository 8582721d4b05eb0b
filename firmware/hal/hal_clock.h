/* System clock: 72 MHz from the 8 MHz HSE through the PLL, with bounded waits and a
 * fallback to the internal 8 MHz HSI when the crystal does not start (a dead crystal,
 * or an emulator that models no RCC and reads every ready bit as 0). */
#ifndef SNAKEBOT_HAL_CLOCK_H
#define SNAKEBOT_HAL_CLOCK_H

#include <stdint.h>

typedef enum {
    HAL_CLOCK_HSE_PLL = 0, /* the crystal through the PLL: the intended configuration */
    HAL_CLOCK_HSI_PLL = 1, /* crystal missing: HSI/2 through the PLL */
    HAL_CLOCK_HSI = 2      /* the PLL did not lock either: HSI directly, 8 MHz */
} hal_clock_source_t;

typedef struct {
    uint32_t sysclk_hz;
    uint32_t hclk_hz;  /* AHB, the core and SysTick */
    uint32_t pclk1_hz; /* APB1: USART2..5 */
    uint32_t pclk2_hz; /* APB2: USART1 */
    hal_clock_source_t source;
} hal_clocks_t;

/* How many times a ready bit is polled before the driver gives up on it. At the 8 MHz
 * reset clock one poll is about 0.5 us, so this is ~25 ms: ten times the HSE's worst
 * start-up time in the datasheet. */
#ifndef HAL_CLOCK_READY_POLLS
#define HAL_CLOCK_READY_POLLS 50000UL
#endif

/* Configure the clock tree for sysclk = hse_hz * pll_mul (72 MHz from 8 MHz x9), AHB /1,
 * APB2 /1, APB1 /2, flash wait states to match. Falls back as described above; the
 * result says what was achieved. Call once, at start-up, from the reset clock or from
 * whatever clock tree a bootloader left (the PLL may still drive SYSCLK). */
hal_clocks_t hal_clock_init(uint32_t hse_hz, unsigned pll_mul);

#endif
