/* Register access for the HAL: every driver reads and writes the MCU through these four
 * functions and never dereferences an address itself.
 *
 * On the target they are volatile loads and stores that compile to single instructions.
 * Built with -DHAL_HOST_TEST (host unit tests), they are left undefined here and the test
 * supplies them, backed by a model of the peripheral, so a driver's logic (timeouts,
 * key sequences, error paths) runs on the host against that model. */
#ifndef SNAKEBOT_HAL_IO_H
#define SNAKEBOT_HAL_IO_H

#include <stdint.h>

#ifdef HAL_HOST_TEST

uint32_t hal_io_read32(uint32_t addr);
void hal_io_write32(uint32_t addr, uint32_t value);
uint16_t hal_io_read16(uint32_t addr);
void hal_io_write16(uint32_t addr, uint16_t value);

#else

static inline uint32_t hal_io_read32(uint32_t addr)
{
    return *(volatile uint32_t *)addr;
}

static inline void hal_io_write32(uint32_t addr, uint32_t value)
{
    *(volatile uint32_t *)addr = value;
}

static inline uint16_t hal_io_read16(uint32_t addr)
{
    return *(volatile uint16_t *)addr;
}

static inline void hal_io_write16(uint32_t addr, uint16_t value)
{
    *(volatile uint16_t *)addr = value;
}

#endif

/* Read-modify-write helpers: clear the bits in `clear`, then set the bits in `set`. */
static inline void hal_io_modify32(uint32_t addr, uint32_t clear, uint32_t set)
{
    hal_io_write32(addr, (hal_io_read32(addr) & ~clear) | set);
}

#endif
