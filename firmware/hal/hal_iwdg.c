/* Independent watchdog (RM0008 section 19). */
#include "hal_iwdg.h"

#include "hal_io.h"
#include "hal_regs.h"

#define LSI_HZ 40000UL
#define UPDATE_POLLS 100000UL /* PR/RLR updates take ~5 LSI cycles; bounded for emulators */

void hal_iwdg_start(uint32_t timeout_ms)
{
    /* Smallest prescaler 4 << pr (pr 0..6) whose 12-bit reload covers the timeout. */
    uint32_t pr = 0;
    uint32_t reload = 0;
    if (timeout_ms > HAL_IWDG_MAX_MS) {
        timeout_ms = HAL_IWDG_MAX_MS;
    }
    for (pr = 0; pr <= 6U; pr++) {
        uint32_t div = 4UL << pr;
        reload = (timeout_ms * (LSI_HZ / 1000UL) + div - 1U) / div;
        if (reload <= 0xFFFU) {
            break;
        }
    }
    if (pr > 6U) {
        pr = 6U;
        reload = 0xFFFU;
    }
    if (reload == 0U) {
        reload = 1U;
    }
    hal_io_write32(HAL_IWDG_KR, HAL_IWDG_KEY_START); /* the LSI starts with the watchdog */
    hal_io_write32(HAL_IWDG_KR, HAL_IWDG_KEY_ACCESS);
    hal_io_write32(HAL_IWDG_PR, pr);
    hal_io_write32(HAL_IWDG_RLR, reload);
    for (uint32_t n = 0; n < UPDATE_POLLS; n++) {
        if ((hal_io_read32(HAL_IWDG_SR) & (HAL_IWDG_SR_PVU | HAL_IWDG_SR_RVU)) == 0U) {
            break;
        }
    }
    hal_io_write32(HAL_IWDG_KR, HAL_IWDG_KEY_RELOAD);
}

void hal_iwdg_feed(void)
{
    hal_io_write32(HAL_IWDG_KR, HAL_IWDG_KEY_RELOAD);
}
