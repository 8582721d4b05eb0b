/* Independent watchdog: resets the MCU when the main loop stops feeding it. Clocked by the
 * ~40 kHz LSI (30-60 kHz over temperature and parts), so timeouts are approximate. Once
 * started it cannot be stopped. QEMU's stm32vldiscovery models no IWDG: there, starting
 * and feeding are harmless no-ops and a hung loop is not caught. */
#ifndef SNAKEBOT_HAL_IWDG_H
#define SNAKEBOT_HAL_IWDG_H

#include <stdint.h>

/* The longest timeout: reload 4095 at the /256 prescaler. */
#define HAL_IWDG_MAX_MS 26208UL

/* Start the watchdog with a nominal timeout of `timeout_ms` (1..HAL_IWDG_MAX_MS; longer is
 * clamped). */
void hal_iwdg_start(uint32_t timeout_ms);

/* Reload the counter: call at least once per timeout. */
void hal_iwdg_feed(void);

#endif
