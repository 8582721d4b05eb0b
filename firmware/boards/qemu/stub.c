/* Boot stub for the qemu board, standing in for the ROBOTIS bootloader: at reset it
 * checks that an application sits at BOARD_APP_BASE (a stack pointer inside RAM, a Thumb
 * reset address inside flash after the stub), points VTOR at the application's vector
 * table, loads its stack pointer and jumps to its reset handler. No application: it
 * sleeps. It uses no RAM of its own (no .data or .bss). */
#include <stdint.h>

#include "board.h"
#include "hal_io.h"
#include "hal_regs.h"

#define RAM_BASE 0x20000000UL
#define FLASH_END (BOARD_STUB_BASE + 128UL * 1024UL)

void stub_reset(void);
void stub_halt(void);

__attribute__((section(".isr_vector"), used))
const uintptr_t stub_vectors[4] = {
    RAM_BASE + BOARD_RAM_SIZE,
    (uintptr_t)stub_reset,
    (uintptr_t)stub_halt, /* NMI */
    (uintptr_t)stub_halt, /* HardFault */
};

__attribute__((noreturn)) void stub_halt(void)
{
    for (;;) {
        __asm__ volatile("wfi");
    }
}

__attribute__((noreturn)) void stub_reset(void)
{
    uint32_t sp = hal_io_read32(BOARD_APP_BASE);
    uint32_t pc = hal_io_read32(BOARD_APP_BASE + 4U);
    int sp_ok = sp > RAM_BASE && sp <= RAM_BASE + BOARD_RAM_SIZE && (sp & 3U) == 0U;
    int pc_ok = pc > BOARD_APP_BASE && pc < FLASH_END && (pc & 1U) == 1U;
    if (!sp_ok || !pc_ok) {
        stub_halt();
    }
    hal_io_write32(HAL_SCB_VTOR, BOARD_APP_BASE);
    __asm__ volatile("dsb\n\t"
                     "isb\n\t"
                     "msr msp, %0\n\t"
                     "bx %1\n\t" ::"r"(sp),
                     "r"(pc)
                     : "memory");
    __builtin_unreachable();
}
