/* The emulated Cortex-M3's exception state and decisions (snakebot.sim.mcu.nvic keeps the
 * registers, this the state they act on): which exceptions are pending, enabled and active,
 * the priority and group of each, the execution priority at each nesting level, and the
 * CPU's exception entry, return and tail-chaining done from unicorn's hooks without a
 * Python call. A device interrupt pends, an exception returns and the next one is taken
 * thousands of times per emulated second (every byte on a USART): in Python, those calls
 * cost more than the instructions of the handlers they start.
 * Host-side only: never compiled into the firmware. */
#ifndef SNAKEBOT_MCU_NVIC_H
#define SNAKEBOT_MCU_NVIC_H

#include <stdint.h>

#include "mcu_count.h"

/* cffi:begin */
#define MCU_NVIC_EXCEPTIONS 76 /* 16 system exceptions and the STM32F103's 60 interrupts */
#define MCU_NVIC_NONE 256      /* the execution priority with nothing active */

typedef struct {
    uint64_t pending[2];  /* bit per exception number: 0..63, then 64.. */
    uint64_t enabled;     /* bit per device interrupt */
    uint64_t lines;       /* bit per device interrupt: its peripheral's line is high */
    uint64_t always;      /* the system exceptions that need no enable (bits of pending[0]) */
    int16_t priority[MCU_NVIC_EXCEPTIONS];
    int16_t group[MCU_NVIC_EXCEPTIONS];  /* the preemption part under PRIGROUP */
    uint8_t active[MCU_NVIC_EXCEPTIONS];  /* exception numbers, outermost first */
    int16_t level[MCU_NVIC_EXCEPTIONS + 1];  /* execution priority (PRIMASK aside) per depth */
    uint32_t depth;       /* exceptions active */
    int32_t running;      /* level[depth] */
    uint32_t vtor;
    uint64_t entries;     /* exceptions taken */
    int primask_reg;      /* unicorn's register id of PRIMASK */
    mcu_counter *counter; /* the CPU's (NULL: no CPU; a pend only records) */
    mcu_exceptions *x;
    /* what failed inside a hook (the CPU stopped there; the Python side says what) */
    int32_t error;        /* an MCU_EXC_* other than MCU_EXC_OK, or 0 */
    int32_t error_in;     /* MCU_NVIC_ENTRY or MCU_NVIC_RETURN */
    int32_t error_exception;  /* the exception an entry failed for */
    uint32_t fault;       /* unicorn's interrupt number of a CPU exception (0: none) */
} mcu_nvic;

#define MCU_NVIC_ENTRY 1
#define MCU_NVIC_RETURN 2

/* The pending, enabled exception that would be taken first (lowest priority number, then
 * lowest exception number), or -1. */
int mcu_nvic_best(const mcu_nvic *n);
/* The exception to take now (`best`: mcu_nvic_best's, or -1 to find it), or -1: one whose
 * group is below the execution priority, which PRIMASK raises to 0. */
int mcu_nvic_takeable(const mcu_nvic *n, int primask, int best);
/* An exception may have become takeable: the CPU's hooks are told, and a running CPU
 * stops before its next instruction when one is pending. */
void mcu_nvic_changed(mcu_nvic *n);
/* Whether any exception is pending (enabled or not). */
int mcu_nvic_any_pending(const mcu_nvic *n);
void mcu_nvic_pend(mcu_nvic *n, int exception);
/* A device interrupt's line: high pends it unless it is pending or active already. */
void mcu_nvic_set_line(mcu_nvic *n, int irq, int level);
/* The execution priority at every depth again, from `active` and `group`. */
void mcu_nvic_rerun(mcu_nvic *n);
void mcu_nvic_activate(mcu_nvic *n, int exception);
/* The innermost handler returns (a line still high pends it again); its number, or -1. */
int mcu_nvic_deactivate(mcu_nvic *n);
/* Enter every exception that may preempt now (the last one entered runs first); how many,
 * or -1 if an entry failed (error, error_in and error_exception say which). */
int mcu_nvic_take(void *uc, mcu_nvic *n);
/* unicorn's interrupt hook (data: the mcu_nvic): a branch to EXC_RETURN returns from the
 * handler and takes what is then due (tail-chaining); any other CPU exception, and a
 * failed return or entry, stops the CPU with `fault` or `error` set. */
void mcu_nvic_interrupt(void *uc, uint32_t intno, void *data);
void *mcu_nvic_interrupt_hook(void);
/* cffi:end */

/* After an unmasking instruction with something pending (mcu_count.c): take it before the
 * next instruction, or stop the CPU where an IT block may be under way; how many taken. */
int mcu_nvic_after_unmask(void *uc, mcu_nvic *n);

#endif
