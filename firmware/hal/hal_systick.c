/* SysTick at 1 kHz (ARMv7-M architecture manual, B3.3). */
#include "hal_systick.h"

#include "hal_io.h"
#include "hal_regs.h"

static volatile uint32_t ticks_ms;
static uint32_t reload_value;
static uint32_t cycles_per_us;

void hal_systick_init(uint32_t hclk_hz, unsigned priority)
{
    uint32_t reload = hclk_hz / 1000U - 1U;
    if (reload > HAL_SYST_RVR_MAX) {
        reload = HAL_SYST_RVR_MAX;
    }
    reload_value = reload;
    cycles_per_us = hclk_hz / 1000000U;
    if (cycles_per_us == 0U) {
        cycles_per_us = 1U;
    }
    hal_io_write32(HAL_SYST_CSR, 0);
    hal_io_write32(HAL_SYST_RVR, reload);
    hal_io_write32(HAL_SYST_CVR, 0);
    hal_io_modify32(HAL_SCB_SHPR3, 0xFFUL << 24,
                    ((uint32_t)(priority << (8U - HAL_NVIC_PRIO_BITS)) & 0xFFU) << 24);
    hal_io_write32(HAL_SYST_CSR,
                   HAL_SYST_CSR_CLKSOURCE | HAL_SYST_CSR_TICKINT | HAL_SYST_CSR_ENABLE);
}

uint32_t hal_millis(void)
{
    return ticks_ms; /* one aligned 32-bit load: atomic on the Cortex-M3 */
}

uint32_t hal_micros(void)
{
    /* The counter runs down from reload_value; a wrap between the two reads shows as a
     * changed tick count, and the pair is read again. */
    uint32_t ms;
    uint32_t count;
    do {
        ms = ticks_ms;
        count = hal_io_read32(HAL_SYST_CVR);
    } while (ms != ticks_ms);
    uint32_t elapsed = (reload_value - (count & HAL_SYST_RVR_MAX)) / cycles_per_us;
    return ms * 1000U + (elapsed < 1000U ? elapsed : 999U);
}

void hal_systick_isr(void)
{
    ticks_ms++;
}
