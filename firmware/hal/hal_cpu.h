/* Cortex-M3 core helpers: interrupt masking, sleep, NVIC lines, vector table, reset. */
#ifndef SNAKEBOT_HAL_CPU_H
#define SNAKEBOT_HAL_CPU_H

#include <stdint.h>

#include "hal_io.h"
#include "hal_regs.h"

#ifdef HAL_HOST_TEST
/* Host unit tests run single-threaded; "interrupts" are calls the test makes itself. */
static inline uint32_t hal_irq_save(void)
{
    return 0;
}
static inline void hal_irq_restore(uint32_t primask)
{
    (void)primask;
}
#else
/* Mask interrupts; returns the previous PRIMASK so critical sections can nest. */
static inline uint32_t hal_irq_save(void)
{
    uint32_t primask;
    __asm__ volatile("mrs %0, primask\n\tcpsid i" : "=r"(primask)::"memory");
    return primask;
}

/* Restore the PRIMASK returned by hal_irq_save(). */
static inline void hal_irq_restore(uint32_t primask)
{
    __asm__ volatile("msr primask, %0" ::"r"(primask) : "memory");
}

#endif /* HAL_HOST_TEST */

static inline void hal_irq_enable_all(void)
{
    __asm__ volatile("cpsie i" ::: "memory");
}

/* Sleep until an interrupt is pending. Call with interrupts masked (hal_irq_save) after
 * checking there is no work: a pending interrupt still wakes the core, so an event that
 * arrives between the check and the sleep is not missed. */
static inline void hal_wait_for_interrupt(void)
{
    __asm__ volatile("dsb\n\twfi" ::: "memory");
}

/* Enable one NVIC line with a priority 0 (highest) .. 15 (lowest). */
static inline void hal_nvic_enable(unsigned irq, unsigned priority)
{
    uint32_t ipr = HAL_NVIC_IPR_BASE + (irq & ~3U);
    unsigned shift = 8U * (irq & 3U);
    uint32_t prio = (uint32_t)(priority << (8U - HAL_NVIC_PRIO_BITS)) & 0xFFU;
    hal_io_modify32(ipr, 0xFFUL << shift, prio << shift);
    hal_io_write32(HAL_NVIC_ICPR(irq / 32U), 1UL << (irq % 32U));
    hal_io_write32(HAL_NVIC_ISER(irq / 32U), 1UL << (irq % 32U));
}

static inline void hal_nvic_disable(unsigned irq)
{
    hal_io_write32(HAL_NVIC_ICER(irq / 32U), 1UL << (irq % 32U));
}

/* Point the core at a vector table (must be 128-byte aligned for 60 IRQs + 16 entries
 * rounded up to a power of two: 512 bytes on the F103). */
static inline void hal_set_vector_table(uint32_t addr)
{
    hal_io_write32(HAL_SCB_VTOR, addr);
    __asm__ volatile("dsb\n\tisb" ::: "memory");
}

/* Reset the whole MCU (does not return). */
__attribute__((noreturn)) static inline void hal_system_reset(void)
{
    __asm__ volatile("dsb" ::: "memory");
    hal_io_write32(HAL_SCB_AIRCR, HAL_SCB_AIRCR_KEY | HAL_SCB_AIRCR_SYSRESETREQ);
    for (;;) {
        __asm__ volatile("nop");
    }
}

#endif
