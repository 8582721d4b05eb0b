/* The CM-530's I/O set-up (see cm530_io.h). */
#include "cm530_io.h"

#include "hal_gpio.h"
#include "hal_io.h"

void cm530_io_init(void)
{
    hal_io_modify32(HAL_RCC_APB2ENR, 0,
                    HAL_RCC_APB2ENR_AFIOEN | HAL_RCC_APB2ENR_IOPBEN | HAL_RCC_APB2ENR_USART1EN);
    hal_io_modify32(HAL_RCC_APB1ENR, 0, HAL_RCC_APB1ENR_USART3EN);
    /* JTAG off (SWD stays, for a debugger) frees PB4 for the bus direction; USART1 moves
     * to PB6/PB7. */
    hal_io_modify32(HAL_AFIO_MAPR, HAL_AFIO_MAPR_SWJ_MASK,
                    HAL_AFIO_MAPR_SWJ_NOJTAG | HAL_AFIO_MAPR_USART1_REMAP);

    const hal_pin_t bus_tx = {HAL_GPIOB_BASE, 6};
    const hal_pin_t bus_rx = {HAL_GPIOB_BASE, 7};
    const hal_pin_t pc_tx = {HAL_GPIOB_BASE, 10};
    const hal_pin_t pc_rx = {HAL_GPIOB_BASE, 11};
    hal_gpio_config(bus_tx, HAL_GPIO_AF_PP_50MHZ);
    hal_gpio_write(bus_rx, true); /* pull-up */
    hal_gpio_config(bus_rx, HAL_GPIO_INPUT_PULL);
    hal_gpio_config(pc_tx, HAL_GPIO_AF_PP_50MHZ);
    hal_gpio_write(pc_rx, true);
    hal_gpio_config(pc_rx, HAL_GPIO_INPUT_PULL);
}
