/* GPIO, STM32F1 style (a 4-bit mode/configuration field per pin). */
#ifndef SNAKEBOT_HAL_GPIO_H
#define SNAKEBOT_HAL_GPIO_H

#include <stdbool.h>
#include <stdint.h>

/* A pin: its port's base address (HAL_GPIOx_BASE) and number 0..15. port 0 = no pin. */
typedef struct {
    uint32_t port;
    uint8_t pin;
} hal_pin_t;

/* Pin configurations: CNF[1:0] << 2 | MODE[1:0] (RM0008 table 20). */
typedef enum {
    HAL_GPIO_INPUT_ANALOG = 0x0,
    HAL_GPIO_INPUT_FLOATING = 0x4,
    HAL_GPIO_INPUT_PULL = 0x8,      /* pull-up or pull-down, chosen by the ODR bit */
    HAL_GPIO_OUTPUT_PP_50MHZ = 0x3,
    HAL_GPIO_OUTPUT_OD_50MHZ = 0x7,
    HAL_GPIO_AF_PP_50MHZ = 0xB,
    HAL_GPIO_AF_OD_50MHZ = 0xF
} hal_gpio_mode_t;

/* Configure a pin (its port clock must already run). Does nothing for port 0. */
void hal_gpio_config(hal_pin_t p, hal_gpio_mode_t mode);

/* Drive an output high or low (one atomic BSRR write). Does nothing for port 0. */
void hal_gpio_write(hal_pin_t p, bool high);

/* Read a pin's input level. */
bool hal_gpio_read(hal_pin_t p);

#endif
