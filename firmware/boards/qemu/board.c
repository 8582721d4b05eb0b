/* qemu board set-up: the CM-530's pins and clock code, on QEMU's stm32vldiscovery. */
#include "board.h"

#include "board_api.h"
#include "hal_gpio.h"
#include "hal_io.h"
#include "hal_regs.h"

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
    /* The CM-530's set-up, unchanged (QEMU ignores it). */
    hal_io_modify32(HAL_RCC_APB2ENR, 0,
                    HAL_RCC_APB2ENR_AFIOEN | HAL_RCC_APB2ENR_IOPBEN | HAL_RCC_APB2ENR_USART1EN);
    hal_io_modify32(HAL_RCC_APB1ENR, 0, HAL_RCC_APB1ENR_USART3EN);
    hal_io_modify32(HAL_AFIO_MAPR, HAL_AFIO_MAPR_SWJ_MASK,
                    HAL_AFIO_MAPR_SWJ_NOJTAG | HAL_AFIO_MAPR_USART1_REMAP);

    const hal_pin_t bus_tx = {HAL_GPIOB_BASE, 6};
    const hal_pin_t bus_rx = {HAL_GPIOB_BASE, 7};
    const hal_pin_t pc_tx = {HAL_GPIOB_BASE, 10};
    const hal_pin_t pc_rx = {HAL_GPIOB_BASE, 11};
    hal_gpio_config(bus_tx, HAL_GPIO_AF_PP_50MHZ);
    hal_gpio_write(bus_rx, true);
    hal_gpio_config(bus_rx, HAL_GPIO_INPUT_PULL);
    hal_gpio_config(pc_tx, HAL_GPIO_AF_PP_50MHZ);
    hal_gpio_write(pc_rx, true);
    hal_gpio_config(pc_rx, HAL_GPIO_INPUT_PULL);
}
