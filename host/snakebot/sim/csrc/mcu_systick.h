/* The emulated Cortex-M3's SysTick (snakebot.sim.mcu.systick keeps its registers here):
 * the counter worked out from the time, its reads (CSR, CVR), and the step to zero that
 * sets COUNTFLAG, pends the exception and reloads, timed by the instruction counter as
 * the USARTs' frames are (mcu_usart.h). The firmware's millisecond tick and its reads of
 * the counter (every servo byte it times) would otherwise stop the CPU for Python.
 * Host-side only: never compiled into the firmware. */
#ifndef SNAKEBOT_MCU_SYSTICK_H
#define SNAKEBOT_MCU_SYSTICK_H

#include <stdint.h>

/* cffi:begin */
typedef struct {
    uint32_t csr;      /* ENABLE, TICKINT, CLKSOURCE, COUNTFLAG */
    uint32_t rvr;
    uint32_t value;    /* the counter when stopped, or at `anchor` while it runs */
    double anchor;     /* the time (s) `value` was taken at */
    double hclk_hz;    /* the processor clock */
    uint32_t armed;    /* the step to zero is due at zero_at */
    double zero_at;
    uint64_t fired;    /* steps to zero */
    void *nvic;        /* the mcu_nvic the exception pends in (NULL: the model's event
                        * and pend do it; nothing is timed in C) */
    int32_t exception; /* its exception number */
} mcu_systick;

/* One count's time (s): HCLK or HCLK/8 (CLKSOURCE). */
double mcu_systick_tick_s(const mcu_systick *s);
/* The counter at time `now`. */
uint32_t mcu_systick_value(const mcu_systick *s, double now);
/* When the counter next steps to zero from `anchor` and `value` (armed), or not at all. */
void mcu_systick_rearm(mcu_systick *s);
/* The step to zero at zero_at: COUNTFLAG, the exception with TICKINT, reload. */
void mcu_systick_zero(mcu_systick *s);
/* cffi:end */

/* A word read of CSR or CVR at `offset` from SysTick's base (1, with *value), else 0. */
int mcu_systick_read(mcu_systick *s, double now, uint64_t offset, unsigned size,
                     uint64_t *value);

#endif
