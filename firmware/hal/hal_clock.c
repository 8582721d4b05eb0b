/* Clock tree set-up for the STM32F103 (RM0008 section 7). */
#include "hal_clock.h"

#include <stdbool.h>

#include "hal_io.h"
#include "hal_regs.h"

#define HSI_HZ 8000000UL

/* Poll until (reg & mask) == want, at most HAL_CLOCK_READY_POLLS times. */
static bool wait_bits(uint32_t reg, uint32_t mask, uint32_t want)
{
    for (uint32_t n = 0; n < HAL_CLOCK_READY_POLLS; n++) {
        if ((hal_io_read32(reg) & mask) == want) {
            return true;
        }
    }
    return false;
}

static void set_flash_latency(uint32_t hclk_hz)
{
    uint32_t ws = hclk_hz > 48000000UL ? 2U : (hclk_hz > 24000000UL ? 1U : 0U);
    hal_io_write32(HAL_FLASH_ACR, HAL_FLASH_ACR_PRFTBE | HAL_FLASH_ACR_LATENCY(ws));
}

/* Select the HSI as SYSCLK and wait until the switch status says it is in use: only then
 * may the PLL be stopped (the hardware ignores PLLON = 0 while the PLL drives SYSCLK). */
static bool switch_to_hsi(void)
{
    hal_io_modify32(HAL_RCC_CFGR, HAL_RCC_CFGR_SW_MASK, HAL_RCC_CFGR_SW_HSI);
    return wait_bits(HAL_RCC_CFGR, HAL_RCC_CFGR_SWS_MASK, HAL_RCC_CFGR_SWS_HSI);
}

/* Stop the PLL and wait until it reports unlocked: its source and multiplier can be
 * written only then (writes while it runs are ignored). */
static bool stop_pll(void)
{
    hal_io_modify32(HAL_RCC_CR, HAL_RCC_CR_PLLON, 0);
    return wait_bits(HAL_RCC_CR, HAL_RCC_CR_PLLRDY, 0);
}

/* Run the PLL from the source already selected in CFGR and switch SYSCLK to it. */
static bool start_pll_and_switch(void)
{
    hal_io_modify32(HAL_RCC_CR, 0, HAL_RCC_CR_PLLON);
    if (!wait_bits(HAL_RCC_CR, HAL_RCC_CR_PLLRDY, HAL_RCC_CR_PLLRDY)) {
        (void)stop_pll();
        return false;
    }
    hal_io_modify32(HAL_RCC_CFGR, HAL_RCC_CFGR_SW_MASK, HAL_RCC_CFGR_SW_PLL);
    if (!wait_bits(HAL_RCC_CFGR, HAL_RCC_CFGR_SWS_MASK, HAL_RCC_CFGR_SWS_PLL)) {
        if (switch_to_hsi()) {
            (void)stop_pll();
        }
        return false;
    }
    return true;
}

/* Prescalers, PLL source and multiplier in one write; SW stays on HSI for now. */
static void configure_cfgr(uint32_t pll_src, unsigned pll_mul)
{
    hal_io_modify32(HAL_RCC_CFGR,
                    HAL_RCC_CFGR_SW_MASK | HAL_RCC_CFGR_HPRE_MASK | HAL_RCC_CFGR_PPRE1_MASK |
                        HAL_RCC_CFGR_PPRE2_MASK | HAL_RCC_CFGR_PLLSRC_HSE |
                        HAL_RCC_CFGR_PLLXTPRE | HAL_RCC_CFGR_PLLMUL_MASK,
                    HAL_RCC_CFGR_SW_HSI | HAL_RCC_CFGR_PPRE1_DIV2 | pll_src |
                        HAL_RCC_CFGR_PLLMUL(pll_mul));
}

static hal_clocks_t tree(uint32_t sysclk_hz, hal_clock_source_t source)
{
    hal_clocks_t c;
    c.sysclk_hz = sysclk_hz;
    c.hclk_hz = sysclk_hz;
    /* APB1 may not exceed 36 MHz: it is divided by 2 whenever the PLL runs. */
    c.pclk1_hz = source == HAL_CLOCK_HSI ? sysclk_hz : sysclk_hz / 2U;
    c.pclk2_hz = sysclk_hz;
    c.source = source;
    return c;
}

/* The fallback when SYSCLK cannot be moved back to the HSI (it never reported the switch;
 * no working chip does this): the clock the previous owner left keeps running, as it is
 * configured, since the PLL driving it can be neither stopped nor reprogrammed. Only the
 * bus prescalers, which may change at any time, are set to ours; the flash gets the
 * most wait states, right for any SYSCLK. */
static hal_clocks_t keep_found_clock(uint32_t hse_hz)
{
    set_flash_latency(UINT32_MAX);
    hal_io_modify32(HAL_RCC_CFGR,
                    HAL_RCC_CFGR_HPRE_MASK | HAL_RCC_CFGR_PPRE1_MASK | HAL_RCC_CFGR_PPRE2_MASK,
                    HAL_RCC_CFGR_PPRE1_DIV2);
    uint32_t cfgr = hal_io_read32(HAL_RCC_CFGR);
    if ((cfgr & HAL_RCC_CFGR_SWS_MASK) != HAL_RCC_CFGR_SWS_PLL) {
        return tree(hse_hz, HAL_CLOCK_HSE_PLL); /* SWS = HSE: the crystal, undivided */
    }
    uint32_t mul = ((cfgr & HAL_RCC_CFGR_PLLMUL_MASK) >> 18) + 2U;
    mul = mul > 16U ? 16U : mul; /* the last code also means x16 */
    if (!(cfgr & HAL_RCC_CFGR_PLLSRC_HSE)) {
        return tree(HSI_HZ / 2U * mul, HAL_CLOCK_HSI_PLL);
    }
    uint32_t in = (cfgr & HAL_RCC_CFGR_PLLXTPRE) ? hse_hz / 2U : hse_hz;
    return tree(in * mul, HAL_CLOCK_HSE_PLL);
}

hal_clocks_t hal_clock_init(uint32_t hse_hz, unsigned pll_mul)
{
    if (pll_mul < 2U) {
        pll_mul = 2U;
    } else if (pll_mul > 16U) {
        pll_mul = 16U;
    }

    /* Start from a known state: running on the HSI, PLL off. A bootloader may have left
     * the PLL running as SYSCLK (and the crystal on): SYSCLK must have left the PLL before
     * the PLL is stopped, and the PLL must be stopped before it is configured. */
    hal_io_modify32(HAL_RCC_CR, 0, HAL_RCC_CR_HSION);
    (void)wait_bits(HAL_RCC_CR, HAL_RCC_CR_HSIRDY, HAL_RCC_CR_HSIRDY);
    if (!switch_to_hsi()) {
        return keep_found_clock(hse_hz);
    }
    hal_io_modify32(HAL_RCC_CR, HAL_RCC_CR_HSEBYP, 0);
    if (stop_pll()) {
        /* 1. The crystal. Wait states go up before the clock does. */
        hal_io_modify32(HAL_RCC_CR, 0, HAL_RCC_CR_HSEON);
        if (wait_bits(HAL_RCC_CR, HAL_RCC_CR_HSERDY, HAL_RCC_CR_HSERDY)) {
            uint32_t sysclk = hse_hz * pll_mul;
            set_flash_latency(sysclk);
            configure_cfgr(HAL_RCC_CFGR_PLLSRC_HSE, pll_mul);
            if (start_pll_and_switch()) {
                return tree(sysclk, HAL_CLOCK_HSE_PLL);
            }
        }
        hal_io_modify32(HAL_RCC_CR, HAL_RCC_CR_HSEON, 0);

        /* 2. No crystal: HSI/2 x16 = 64 MHz, the most the HSI path can give. The PLL is
         * configured again only if it stopped after the failed attempt. */
        if (wait_bits(HAL_RCC_CR, HAL_RCC_CR_PLLRDY, 0)) {
            set_flash_latency(HSI_HZ / 2U * 16U);
            configure_cfgr(0, 16U);
            if (start_pll_and_switch()) {
                return tree(HSI_HZ / 2U * 16U, HAL_CLOCK_HSI_PLL);
            }
        }
    }

    /* 3. Stay on the HSI, every bus undivided. (The PLL's settings are left alone: it may
     * still be running, and then they cannot be written.) */
    hal_io_modify32(HAL_RCC_CFGR, HAL_RCC_CFGR_PPRE1_MASK, 0);
    set_flash_latency(HSI_HZ);
    return tree(HSI_HZ, HAL_CLOCK_HSI);
}
