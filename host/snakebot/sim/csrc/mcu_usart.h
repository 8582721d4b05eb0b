/* The emulated STM32F103's USARTs (snakebot.sim.mcu.usart) in C where the firmware's
 * interrupt handlers reach them for every byte: a DR read, a DR write behind the byte being
 * sent, a CR1 write switching an interrupt on or off, and the interrupt line they move;
 * and the end of each frame the shift register sends (TXE and the next byte from TDR, or
 * TC), timed by the instruction counter as the model's scheduled event would be, so a
 * byte behind another costs no stop of the CPU and no Python call. The start of a shift
 * from idle, the far end and anything unusual stay in the Python model, which keeps its
 * state in the same mcu_fast_io (mcu_count.h) and hands on the bytes logged here.
 * Host-side only: never compiled into the firmware. */
#ifndef SNAKEBOT_MCU_USART_H
#define SNAKEBOT_MCU_USART_H

#include <stdint.h>

#include "mcu_count.h"

/* cffi:begin */
/* The interrupt line again from SR and CR1 (TXEIE and TXE, TCIE and TC, RXNEIE and RXNE or
 * ORE), told to the NVIC when high or changed. */
void mcu_usart_update_irq(mcu_fast_io *f);
/* The counter's timed events (the shift registers of the USARTs in counter->timed): when
 * the earliest is due (a time; a negative number if none), and its count again after the
 * clock moved or a shift register started (event_count). */
double mcu_timed_next(const mcu_counter *c);
void mcu_timed_plan(mcu_counter *c);
/* Run every timed event due by `now` (each at its own time, as the scheduler would): 1 if
 * a model has to look now (a TC with stop_on_idle, a full log), else 0. */
int mcu_timed_run(mcu_counter *c, double now);
/* cffi:end */

/* From the counting hook, before the instruction at the count: run the events due, and take
 * an exception they pend there; 1 if one was taken (the instruction waits for its return). */
int mcu_timed_in_hook(void *uc, mcu_counter *c);
/* A wfi with nothing to wake the CPU and the machine's next event (stop_at) later than a
 * timed one: time jumps from timed event to timed event until one wakes the CPU (1: then
 * the wfi is done and the exception taken) or the model has to look (0). */
int mcu_timed_sleep(void *uc, mcu_counter *c, uint64_t address);

/* An access the C side serves (1, with *value for a read), or 0: the model's. */
int mcu_usart_read(mcu_fast_io *f, uint64_t offset, unsigned size, uint64_t *value);
int mcu_usart_write(mcu_fast_io *f, uint64_t offset, unsigned size, uint64_t value);

#endif
