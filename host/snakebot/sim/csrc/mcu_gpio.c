/* See mcu_gpio.h. The registers: RM0008 section 9.2 (and gpio.py). */
#include "mcu_gpio.h"

#define IDR 0x08u
#define BSRR 0x10u

void mcu_gpio_changed(mcu_fast_io *f)
{
    mcu_fast_io *rx = (mcu_fast_io *)f->rx_usart;
    if (rx == 0) {
        return;
    }
    uint32_t high = f->listen_high, low = f->listen_low, out = f->outputs, odr = f->value;
    rx->rx_listens = (out & high) == high && (odr & high) == high && (out & low) == low &&
                     (odr & low) == 0;
}

int mcu_gpio_write(mcu_fast_io *f, uint64_t offset, unsigned size, uint64_t value)
{
    /* the model's when its clock is off, someone listens to the pins, or the bytes a
     * USART started in C are still to be handed on (they go out with the pins before) */
    if (!f->second_on || f->python_only || size != 4 || f->counter->undrained) {
        return 0;
    }
    if (offset != BSRR) {
        return 0; /* ODR and BRR too are the model's (the firmware sets pins through BSRR) */
    }
    uint32_t v = (uint32_t)value;
    f->value = ((f->value & ~(v >> 16)) | v) & 0xFFFFu; /* set wins over reset */
    mcu_gpio_changed(f);
    return 1;
}

int mcu_gpio_read(const mcu_fast_io *f, uint64_t offset, unsigned size, uint64_t *value)
{
    /* the model's when its clock is off, a pin is driven from outside, or the bytes a
     * USART started in C are still to be handed on (they go first) */
    if (offset != IDR || size != 4 || !f->second_on || f->driven || f->counter->undrained) {
        return 0;
    }
    *value = f->value & (f->outputs | f->pulls); /* an output reads what it drives */
    return 1;
}
