/* The emulated STM32F103's instruction counter (snakebot.sim.mcu.cpu): a unicorn code hook
 * that counts every executed instruction and stops the CPU when the count reaches a limit,
 * so the emulator knows the exact time of every register access and can run the CPU up to
 * the next peripheral event and no further. Called by unicorn for each instruction, it has
 * to be native code: a Python callback there would run a hundred times slower.
 * Host-side only: never compiled into the firmware. */
#ifndef SNAKEBOT_MCU_COUNT_H
#define SNAKEBOT_MCU_COUNT_H

#include <stdint.h>

/* cffi:begin */
typedef struct {
    uint64_t count;    /* instructions executed since the machine was made */
    uint64_t limit;    /* stop before the instruction that would make count exceed this */
    void *stop;        /* unicorn's uc_emu_stop, as a plain function address */
    uint32_t stops;    /* times the limit stopped the CPU */
} mcu_counter;

void mcu_count_instruction(void *uc, uint64_t address, uint32_t size, void *counter);
/* cffi:end */

#endif
