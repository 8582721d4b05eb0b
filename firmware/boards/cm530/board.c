/* CM-530 board set-up: clock and pins. */
#include "board.h"

#include "board_api.h"
#include "hal_gpio.h"
#include "hal_io.h"

static const hal_pin_t buttons[] = BOARD_BUTTON_PINS;
static const hal_pin_t leds[] = BOARD_LED_PINS;

hal_clocks_t board_clock_init(void)
{
    return hal_clock_init(BOARD_HSE_HZ, BOARD_PLL_MUL);
}

void board_pins_init(void)
{
    cm530_io_init();
    hal_io_modify32(HAL_RCC_APB2ENR, 0, HAL_RCC_APB2ENR_IOPAEN | HAL_RCC_APB2ENR_IOPCEN);
    for (unsigned i = 0; i < sizeof buttons / sizeof buttons[0]; i++) {
        hal_gpio_write(buttons[i], true); /* pull-up */
        hal_gpio_config(buttons[i], HAL_GPIO_INPUT_PULL);
    }
    for (unsigned i = 0; i < sizeof leds / sizeof leds[0]; i++) {
        hal_gpio_write(leds[i], true); /* off */
        hal_gpio_config(leds[i], HAL_GPIO_OUTPUT_PP_50MHZ);
    }
}

uint8_t board_buttons(void)
{
    uint8_t held = 0;
    for (unsigned i = 0; i < sizeof buttons / sizeof buttons[0]; i++) {
        if (buttons[i].port != 0U && !hal_gpio_read(buttons[i])) {
            held |= (uint8_t)(1U << i);
        }
    }
    return held;
}

void board_leds(uint8_t on)
{
    for (unsigned i = 0; i < sizeof leds / sizeof leds[0]; i++) {
        hal_gpio_write(leds[i], ((on >> i) & 1U) == 0U);
    }
}
