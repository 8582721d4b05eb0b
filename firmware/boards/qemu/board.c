/* qemu board set-up: the CM-530's pins and clock code, on QEMU's stm32vldiscovery. */
#include "board.h"

#include "board_api.h"

hal_clocks_t board_clock_init(void)
{
    /* Runs the real clock code: QEMU's RCC reads 0, so this exercises the HSE timeout and
     * the fallback, and reports HAL_CLOCK_HSI. The machine's clock is fixed, though. */
    hal_clocks_t c = hal_clock_init(BOARD_HSE_HZ, BOARD_PLL_MUL);
    c.sysclk_hz = BOARD_EMULATED_HCLK_HZ;
    c.hclk_hz = BOARD_EMULATED_HCLK_HZ;
    c.pclk1_hz = BOARD_EMULATED_HCLK_HZ;
    c.pclk2_hz = BOARD_EMULATED_HCLK_HZ;
    return c;
}

void board_pins_init(void)
{
    cm530_io_init(); /* the CM-530's wiring, unchanged: QEMU ignores it */
}

uint8_t board_buttons(void)
{
    return 0; /* QEMU models no GPIO (its pins read 0, which would be every button held) */
}

void board_leds(uint8_t on)
{
    (void)on;
}
