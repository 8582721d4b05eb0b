/* GPIO for the STM32F1 (RM0008 section 9). */
#include "hal_gpio.h"

#include "hal_io.h"
#include "hal_regs.h"

void hal_gpio_config(hal_pin_t p, hal_gpio_mode_t mode)
{
    if (p.port == 0U || p.pin > 15U) {
        return;
    }
    uint32_t reg = p.pin < 8U ? HAL_GPIO_CRL(p.port) : HAL_GPIO_CRH(p.port);
    unsigned shift = 4U * (p.pin & 7U);
    hal_io_modify32(reg, 0xFUL << shift, ((uint32_t)mode & 0xFU) << shift);
}

void hal_gpio_write(hal_pin_t p, bool high)
{
    if (p.port == 0U || p.pin > 15U) {
        return;
    }
    hal_io_write32(HAL_GPIO_BSRR(p.port), high ? (1UL << p.pin) : (1UL << (p.pin + 16U)));
}

bool hal_gpio_read(hal_pin_t p)
{
    if (p.port == 0U || p.pin > 15U) {
        return false;
    }
    return (hal_io_read32(HAL_GPIO_IDR(p.port)) >> p.pin) & 1U;
}
