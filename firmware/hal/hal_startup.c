/* Start-up for the STM32F103: the vector table and the reset handler.
 *
 * The table is placed first in the image by the linker script (section .isr_vector). The
 * reset handler points VTOR at this table itself, so the image runs the same whether it
 * was entered from the reset vector or from a bootloader that jumped to it (the ROBOTIS
 * bootloader on the CM-530, the boot stub on the qemu board). Interrupt handlers are weak:
 * a board or the app defines the ones it uses; any other interrupt, and every fault,
 * resets the MCU (RCC_CSR then reports a software reset).
 *
 * Built with -DHAL_HOST_TEST only hal_quiet_interrupts() is compiled, for the host tests
 * against a register model. */
#include <stdint.h>

#include "hal_cpu.h"
#include "hal_image.h"

void hal_quiet_interrupts(void);

/* NVIC enable and pending registers hold 32 lines each. */
#define HAL_NVIC_WORDS ((HAL_IRQ_COUNT + 31U) / 32U)

/* Silence every interrupt source the previous owner of the CPU may have left armed: the
 * ROBOTIS bootloader's state at the jump is undocumented. A line left enabled and pending
 * would fire as soon as interrupts are enabled, reach hal_unexpected_irq and reset the
 * MCU, which would enter the bootloader and then this image again: a boot loop. SysTick
 * is stopped and a tick already pending dropped for the same reason. Out of line, so the
 * firmware tests can check in the image that it runs before interrupts are enabled. */
__attribute__((noinline)) void hal_quiet_interrupts(void)
{
    hal_io_write32(HAL_SYST_CSR, 0);
    hal_io_write32(HAL_SCB_ICSR, HAL_SCB_ICSR_PENDSTCLR | HAL_SCB_ICSR_PENDSVCLR);
    for (uint32_t n = 0; n < HAL_NVIC_WORDS; n++) {
        hal_io_write32(HAL_NVIC_ICER(n), UINT32_MAX);
    }
    /* Disabled first: a disabled line cannot fire even if its peripheral pends it again.
     * Then the pending bits go, so a line a driver enables later starts clean. */
    for (uint32_t n = 0; n < HAL_NVIC_WORDS; n++) {
        hal_io_write32(HAL_NVIC_ICPR(n), UINT32_MAX);
    }
}

#ifndef HAL_HOST_TEST

extern uint32_t _sidata; /* .data initial values in flash */
extern uint32_t _sdata, _edata;
extern uint32_t _sbss, _ebss;
extern uint32_t _estack;

/* Free RAM between .bss and the live stack is filled with this at reset, so the stack's
 * high-water mark can be read from memory later (a debugger, or QEMU's monitor). */
#define HAL_STACK_PAINT 0x5AC3A55AUL

int main(void);
void Reset_Handler(void);
void hal_reset_continue(void);

void hal_unexpected_irq(void)
{
    hal_system_reset();
}

#define WEAK_DEFAULT __attribute__((weak, alias("hal_unexpected_irq")))

void NMI_Handler(void) WEAK_DEFAULT;
void HardFault_Handler(void) WEAK_DEFAULT;
void MemManage_Handler(void) WEAK_DEFAULT;
void BusFault_Handler(void) WEAK_DEFAULT;
void UsageFault_Handler(void) WEAK_DEFAULT;
void SVC_Handler(void) WEAK_DEFAULT;
void DebugMon_Handler(void) WEAK_DEFAULT;
void PendSV_Handler(void) WEAK_DEFAULT;
void SysTick_Handler(void) WEAK_DEFAULT;
void USART1_IRQHandler(void) WEAK_DEFAULT;
void USART2_IRQHandler(void) WEAK_DEFAULT;
void USART3_IRQHandler(void) WEAK_DEFAULT;
void UART4_IRQHandler(void) WEAK_DEFAULT;
void UART5_IRQHandler(void) WEAK_DEFAULT;

typedef void (*hal_vector_t)(void);

/* 16 system entries, then the device interrupts; unused ones reset. */
__attribute__((section(".isr_vector"), used))
const hal_vector_t hal_vector_table[16 + HAL_IRQ_COUNT] = {
    [0] = (hal_vector_t)(uintptr_t)&_estack,
    [1] = Reset_Handler,
    [2] = NMI_Handler,
    [3] = HardFault_Handler,
    [4] = MemManage_Handler,
    [5] = BusFault_Handler,
    [6] = UsageFault_Handler,
    [HAL_IMAGE_INFO_VECTOR] = (hal_vector_t)(uintptr_t)&hal_image_info, /* reserved entry */
    [11] = SVC_Handler,
    [12] = DebugMon_Handler,
    [14] = PendSV_Handler,
    [15] = SysTick_Handler,
    [16 + 0 ... 16 + HAL_IRQ_USART1 - 1] = hal_unexpected_irq,
    [16 + HAL_IRQ_USART1] = USART1_IRQHandler,
    [16 + HAL_IRQ_USART2] = USART2_IRQHandler,
    [16 + HAL_IRQ_USART3] = USART3_IRQHandler,
    [16 + HAL_IRQ_USART3 + 1 ... 16 + HAL_IRQ_UART4 - 1] = hal_unexpected_irq,
    [16 + HAL_IRQ_UART4] = UART4_IRQHandler,
    [16 + HAL_IRQ_UART5] = UART5_IRQHandler,
    [16 + HAL_IRQ_UART5 + 1 ... 16 + HAL_IRQ_COUNT - 1] = hal_unexpected_irq,
};

/* Entered with whatever stack the previous owner of the CPU left: set ours first, before
 * any C code touches the stack. */
__attribute__((naked, noreturn)) void Reset_Handler(void)
{
    __asm__ volatile("ldr r0, =_estack\n\t"
                     "msr msp, r0\n\t"
                     "b hal_reset_continue\n\t");
}

__attribute__((noreturn, used)) void hal_reset_continue(void)
{
    hal_set_vector_table((uint32_t)(uintptr_t)hal_vector_table);
    const uint32_t *src = &_sidata;
    for (uint32_t *dst = &_sdata; dst < &_edata;) {
        *dst++ = *src++;
    }
    for (uint32_t *dst = &_sbss; dst < &_ebss;) {
        *dst++ = 0;
    }
    uint32_t *sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    for (uint32_t *dst = &_ebss; dst < sp - 16;) { /* stay clear of this frame */
        *dst++ = HAL_STACK_PAINT;
    }
    hal_quiet_interrupts();
    hal_irq_enable_all(); /* a bootloader may have left interrupts masked */
    (void)main();
    hal_system_reset();
}

#endif /* HAL_HOST_TEST */
