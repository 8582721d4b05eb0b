/* See mcu_systick.h. The rules: ARMv7-M architecture manual B3.3 (and systick.py). */
#include "mcu_systick.h"

#include <math.h>

#include "mcu_nvic.h"

#define ENABLE (1u << 0)
#define TICKINT (1u << 1)
#define CLKSOURCE (1u << 2)
#define COUNTFLAG (1u << 16)
#define CSR 0x0u
#define CVR 0x8u

double mcu_systick_tick_s(const mcu_systick *s)
{
    double hz = (s->csr & CLKSOURCE) ? s->hclk_hz : s->hclk_hz / 8.0;
    return 1.0 / hz;
}

uint32_t mcu_systick_value(const mcu_systick *s, double now)
{
    if (!(s->csr & ENABLE)) {
        return s->value;
    }
    /* a millionth of a count short counts as there, as the machine rounds its stops */
    int64_t steps = (int64_t)floor((now - s->anchor) / mcu_systick_tick_s(s) + 1e-6);
    if (steps <= (int64_t)s->value) {
        return (uint32_t)((int64_t)s->value - steps);
    }
    if (s->rvr == 0) {
        return 0;
    }
    return s->rvr - (uint32_t)((steps - (int64_t)s->value - 1) % ((int64_t)s->rvr + 1));
}

void mcu_systick_rearm(mcu_systick *s)
{
    s->armed = 0;
    if (!(s->csr & ENABLE)) {
        return;
    }
    uint32_t steps;
    if (s->value) {
        steps = s->value;
    } else if (s->rvr) {
        steps = s->rvr + 1u;
    } else {
        return; /* RVR 0: the counter stays at 0, no exception */
    }
    s->zero_at = s->anchor + (double)steps * mcu_systick_tick_s(s);
    s->armed = 1;
}

void mcu_systick_zero(mcu_systick *s)
{
    double t = s->zero_at;
    s->armed = 0;
    s->fired++;
    s->csr |= COUNTFLAG;
    if ((s->csr & TICKINT) && s->nvic != 0) {
        mcu_nvic_pend((mcu_nvic *)s->nvic, s->exception);
    }
    s->anchor = t;
    s->value = 0;
    mcu_systick_rearm(s);
}

int mcu_systick_read(mcu_systick *s, double now, uint64_t offset, unsigned size,
                     uint64_t *value)
{
    if (size != 4) {
        return 0;
    }
    if (offset == CSR) {
        *value = s->csr;
        s->csr &= ~COUNTFLAG;
        return 1;
    }
    if (offset == CVR) {
        *value = mcu_systick_value(s, now);
        return 1;
    }
    return 0;
}
