/* See mcu_nvic.h. */
#include "mcu_nvic.h"

#define SYSTEM_EXCEPTIONS 16
#define EXCP_EXCEPTION_EXIT 8 /* unicorn's (QEMU's) interrupt number for EXC_RETURN */
#define XPSR_IPSR 0x1FFu

typedef int (*nvic_stop_fn)(void *uc);

static uint64_t eligible(const mcu_nvic *n, int word)
{
    if (word == 0) {
        return n->pending[0] & (n->enabled << SYSTEM_EXCEPTIONS | n->always);
    }
    return n->pending[1] & (n->enabled >> (64 - SYSTEM_EXCEPTIONS));
}

int mcu_nvic_best(const mcu_nvic *n)
{
    int best = -1;
    for (int word = 0; word < 2; word++) {
        uint64_t bits = eligible(n, word);
        while (bits) {
            int exception = 64 * word + __builtin_ctzll(bits);
            bits &= bits - 1;
            if (best < 0 || n->priority[exception] < n->priority[best]) {
                best = exception;
            }
        }
    }
    return best;
}

int mcu_nvic_takeable(const mcu_nvic *n, int primask, int best)
{
    int exception = best < 0 ? mcu_nvic_best(n) : best;
    if (exception < 0) {
        return -1;
    }
    int running = n->running;
    if (primask && running > 0) {
        running = 0;
    }
    return n->group[exception] < running ? exception : -1;
}

int mcu_nvic_any_pending(const mcu_nvic *n)
{
    return (n->pending[0] | n->pending[1]) != 0;
}

void mcu_nvic_changed(mcu_nvic *n)
{
    mcu_counter *c = n->counter;
    if (c == 0) {
        return;
    }
    c->pending = 1;
    if (c->running && mcu_nvic_best(n) >= 0) {
        /* taken before the next instruction, from the counting hook, as after an unmask
         * (mcu_count.c; the CPU stops there instead inside an IT block) */
        c->take_next = 1;
        c->event_count = c->count;
    }
}

void mcu_nvic_pend(mcu_nvic *n, int exception)
{
    n->pending[exception >> 6] |= 1ull << (exception & 63);
    mcu_nvic_changed(n);
}

void mcu_nvic_set_line(mcu_nvic *n, int irq, int level)
{
    uint64_t bit = 1ull << irq;
    if (!level) {
        n->lines &= ~bit;
        return;
    }
    n->lines |= bit;
    int exception = SYSTEM_EXCEPTIONS + irq;
    for (uint32_t i = 0; i < n->depth; i++) {
        if (n->active[i] == exception) {
            return;
        }
    }
    if (!(n->pending[exception >> 6] >> (exception & 63) & 1u)) {
        mcu_nvic_pend(n, exception);
    }
}

void mcu_nvic_rerun(mcu_nvic *n)
{
    int running = MCU_NVIC_NONE;
    n->level[0] = (int16_t)running;
    for (uint32_t i = 0; i < n->depth; i++) {
        if (n->group[n->active[i]] < running) {
            running = n->group[n->active[i]];
        }
        n->level[i + 1] = (int16_t)running;
    }
    n->running = running;
}

void mcu_nvic_activate(mcu_nvic *n, int exception)
{
    n->pending[exception >> 6] &= ~(1ull << (exception & 63));
    n->active[n->depth++] = (uint8_t)exception;
    n->entries++;
    if (n->group[exception] < n->running) {
        n->running = n->group[exception];
    }
    n->level[n->depth] = (int16_t)n->running;
}

int mcu_nvic_deactivate(mcu_nvic *n)
{
    if (n->depth == 0) {
        return -1;
    }
    int exception = n->active[--n->depth];
    n->running = n->level[n->depth];
    int irq = exception - SYSTEM_EXCEPTIONS;
    if (irq >= 0 && n->lines >> irq & 1u) {
        mcu_nvic_pend(n, exception); /* level-sensitive: still asserted */
    }
    return exception;
}

static int enter(void *uc, mcu_nvic *n, int exception)
{
    uint32_t ipsr = n->depth ? n->active[n->depth - 1] & XPSR_IPSR : 0;
    int status = mcu_exception_enter(uc, n->x, (uint32_t)exception, n->vtor, ipsr);
    if (status != MCU_EXC_OK) {
        n->error = status;
        n->error_in = MCU_NVIC_ENTRY;
        n->error_exception = exception;
        return -1;
    }
    mcu_nvic_activate(n, exception);
    return 0;
}

static void note_pending(mcu_nvic *n)
{
    if (n->counter != 0) {
        n->counter->pending = mcu_nvic_any_pending(n) ? 1 : 0;
    }
}

int mcu_nvic_take(void *uc, mcu_nvic *n)
{
    int taken = 0;
    for (;;) {
        int exception = mcu_nvic_best(n);
        if (exception >= 0) { /* no register read for nothing to take */
            int primask = mcu_reg(uc, n->x, n->primask_reg) & 1u;
            exception = mcu_nvic_takeable(n, primask, exception);
        }
        if (exception < 0) {
            note_pending(n);
            return taken;
        }
        if (enter(uc, n, exception) != 0) {
            return -1;
        }
        taken++;
    }
}

static void stop(void *uc, mcu_nvic *n)
{
    ((nvic_stop_fn)n->counter->stop)(uc);
}

void mcu_nvic_interrupt(void *uc, uint32_t intno, void *data)
{
    mcu_nvic *n = (mcu_nvic *)data;
    if (intno != EXCP_EXCEPTION_EXIT) {
        n->fault = intno;
        stop(uc, n);
        return;
    }
    /* the return (and a tail-chained entry) done here: writing PC from a hook makes
     * unicorn go on from there without leaving emu_start */
    int status = MCU_EXC_BAD_RETURN;
    if (n->depth) {
        status = mcu_exception_return(uc, n->x);
    } else {
        n->x->exc_return = mcu_reg(uc, n->x, n->x->frame[6]) | 1u;
    }
    if (status != MCU_EXC_OK) {
        n->error = status;
        n->error_in = MCU_NVIC_RETURN;
        stop(uc, n);
        return;
    }
    mcu_nvic_deactivate(n);
    int exception = mcu_nvic_best(n);
    if (exception >= 0) { /* PRIMASK read only for something to take */
        int primask = mcu_reg(uc, n->x, n->primask_reg) & 1u;
        exception = mcu_nvic_takeable(n, primask, exception);
        if (exception >= 0 && enter(uc, n, exception) != 0) {
            stop(uc, n);
            return;
        }
    }
    note_pending(n);
}

void *mcu_nvic_interrupt_hook(void)
{
    return (void *)&mcu_nvic_interrupt;
}

int mcu_nvic_after_unmask(void *uc, mcu_nvic *n)
{
    mcu_counter *c = n->counter;
    if (mcu_maybe_in_it_block(uc, n->x)) {
        /* taken when the CPU stops, with unicorn's IT state exact */
        if (c->count < c->limit) {
            c->limit = c->count;
        }
        if (c->stop_at > 0.0) {
            c->stop_at = 0.0;
        }
        return 0;
    }
    int taken = mcu_nvic_take(uc, n);
    if (taken < 0) {
        stop(uc, n);
        return 0;
    }
    if (taken > 0) {
        mcu_keep_pc(uc, n->x);
    }
    return taken;
}
