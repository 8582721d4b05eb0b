/* See mcu_count.h. */
#include "mcu_count.h"
#include "mcu_gpio.h"
#include "mcu_nvic.h"
#include "mcu_systick.h"
#include "mcu_usart.h"

double mcu_time_at(const mcu_counter *c, uint64_t count)
{
    return c->t0 + (double)(count - c->c0) / c->hz;
}

double mcu_now(const mcu_counter *c)
{
    return mcu_time_at(c, c->count);
}

#define SITE_BIT(address) (((address) >> 1) & (MCU_SITE_WORDS * 64u - 1u))

static int maybe_site(const mcu_counter *c, uint64_t address)
{
    uint32_t bit = (uint32_t)SITE_BIT(address);
    return (int)(c->site_bits[bit >> 6] >> (bit & 63u) & 1u);
}

void mcu_watch_site(mcu_counter *c, uint32_t address)
{
    uint32_t bit = SITE_BIT(address);
    c->site_bits[bit >> 6] |= (uint64_t)1 << (bit & 63u);
}

typedef int (*mcu_stop_fn)(void *uc);
typedef int (*mcu_wfi_fn)(uint64_t address);

static void count_at_limit_or_site(void *uc, uint64_t address, uint32_t size,
                                   mcu_counter *c) __attribute__((noinline));

void mcu_count_instruction(void *uc, uint64_t address, uint32_t size, void *counter)
{
    /* the usual case, under the limit and at no watched site, with nothing to save: a
     * leaf of a few instructions (it runs for every instruction the CPU executes) */
    mcu_counter *c = (mcu_counter *)counter;
    uint64_t count = c->count;
    if (__builtin_expect(count < c->limit && count < c->event_count, 1) && !maybe_site(c, address)) {
        c->count = count + 1;
        return;
    }
    count_at_limit_or_site(uc, address, size, c);
}

void *mcu_count_hook(void)
{
    return (void *)&mcu_count_instruction;
}

static void count_at_limit_or_site(void *uc, uint64_t address, uint32_t size, mcu_counter *c)
{
    if (c->count >= c->event_count && mcu_timed_in_hook(uc, c)) {
        return; /* an exception was entered: this instruction runs on its return */
    }
    if (c->count >= c->limit && c->pending == 0 && mcu_time_at(c, c->count) < c->stop_at) {
        c->limit = c->count + 1; /* short of stop_at by a rounding (see mcu_count.h) */
    }
    if (c->take_next && c->count < c->limit) {
        c->take_next = 0;
        mcu_timed_plan(c); /* event_count back to the timed events' */
        if (c->nvic != 0 && mcu_nvic_after_unmask(uc, (mcu_nvic *)c->nvic) > 0) {
            return; /* this instruction runs on the handler's return */
        }
    }
    if (c->count >= c->limit) {
        /* the hook runs before the instruction: stopping here leaves it unexecuted */
        c->stops++;
        ((mcu_stop_fn)c->stop)(uc);
        return;
    }
    c->count++;
    if (!maybe_site(c, address)) {
        return;
    }
    for (uint32_t i = 0; i < c->sites; i++) {
        if (c->site_address[i] != address) {
            continue;
        }
        if (c->site_kind[i] == MCU_SITE_WFI) {
            if (c->n_timed && mcu_timed_sleep(uc, c, address)) {
                return; /* woken by a timed event, inside the run */
            }
            if (((mcu_wfi_fn)c->on_wfi)(address) != 0) {
                return; /* the CPU stops: no later site's hook runs, as in unicorn */
            }
        } else {
            mcu_after_unmask(uc, address, size, c);
        }
    }
}

/* Hooked on the instruction after each `cpsie i` / `msr primask`: with an exception
 * pending, the NVIC (mcu_nvic_after_unmask) takes it before this instruction, which then
 * runs on the return (the counter's hook, called first, has counted it: uncounted here);
 * without an NVIC, stop before it so the machine can take the exception. */
void mcu_after_unmask(void *uc, uint64_t address, uint32_t size, void *counter)
{
    (void)address;
    (void)size;
    mcu_counter *c = (mcu_counter *)counter;
    if (!c->pending || c->limit <= c->count) {
        return;
    }
    if (c->nvic == 0) {
        c->limit = c->count;
        c->stop_at = 0.0;
        return;
    }
    c->count--;
    if (mcu_nvic_after_unmask(uc, (mcu_nvic *)c->nvic) == 0) {
        c->count++; /* nothing taken: the instruction runs now */
    }
}

typedef uint64_t (*mcu_read_fn)(void *uc, uint64_t offset, unsigned size, void *data);
typedef void (*mcu_write_fn)(void *uc, uint64_t offset, unsigned size, uint64_t value,
                             void *data);

uint64_t mcu_io_read(void *uc, uint64_t offset, unsigned size, void *io)
{
    mcu_fast_io *f = (mcu_fast_io *)io;
    if (f->kind == MCU_IO_USART_SR && offset == 0 && size == 4) {
        f->armed = 3;
        return f->value;
    }
    if (f->kind == MCU_IO_USART_SR && f->second_on && offset == f->second_offset && size == 4) {
        return f->second;
    }
    uint64_t value;
    if (f->kind == MCU_IO_USART_SR && mcu_usart_read(f, offset, size, &value)) {
        return value;
    }
    if (f->kind == MCU_IO_GPIO && mcu_gpio_read(f, offset, size, &value)) {
        return value;
    }
    if (f->kind == MCU_IO_SCS && f->systick != 0 && offset >= MCU_SCS_SYSTICK &&
        mcu_systick_read((mcu_systick *)f->systick, mcu_now(f->counter),
                         offset - MCU_SCS_SYSTICK, size, &value)) {
        return value;
    }
    return ((mcu_read_fn)f->read_fallback)(uc, offset, size, 0);
}

void mcu_io_write(void *uc, uint64_t offset, unsigned size, uint64_t value, void *io)
{
    mcu_fast_io *f = (mcu_fast_io *)io;
    if (f->kind == MCU_IO_IWDG_KR && offset == 0 && size == 4 && f->running &&
        (value & 0xFFFFu) == 0xAAAAu) {
        double now = mcu_now(f->counter);
        if (f->feeds > 0 && now - f->last_feed > f->largest_gap) {
            f->largest_gap = now - f->last_feed;
        }
        f->last_feed = now;
        f->feeds++;
        return;
    }
    if (f->kind == MCU_IO_USART_SR && mcu_usart_write(f, offset, size, value)) {
        return;
    }
    if (f->kind == MCU_IO_GPIO && mcu_gpio_write(f, offset, size, value)) {
        return;
    }
    ((mcu_write_fn)f->write_fallback)(uc, offset, size, value, 0);
}

typedef int (*mcu_reg_batch_fn)(void *uc, const int *regs, void **vals, int count);
typedef int (*mcu_mem_fn)(void *uc, uint64_t address, void *bytes, uint64_t size);

#define XPSR_ALIGNED (1u << 9)
#define XPSR_IPSR 0x1FFu
#define XPSR_THUMB (1u << 24)
#define EXC_RETURN_HANDLER 0xFFFFFFF1u
#define EXC_RETURN_THREAD_MSP 0xFFFFFFF9u
#define FRAME_LR 5
#define FRAME_PC 6
#define FRAME_XPSR 7

static int frame_access(void *uc, mcu_exceptions *x, uint32_t *values, int write)
{
    void *ptrs[9];
    int ids[9];
    for (int i = 0; i < 8; i++) {
        ids[i] = x->frame[i];
        ptrs[i] = &values[i];
    }
    ids[8] = x->sp;
    ptrs[8] = &values[8];
    mcu_reg_batch_fn fn = (mcu_reg_batch_fn)(write ? x->reg_write_batch : x->reg_read_batch);
    return fn(uc, ids, ptrs, 9);
}

static uint32_t word_le(const uint8_t *b)
{
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

int mcu_exception_enter(void *uc, mcu_exceptions *x, uint32_t exception, uint32_t vtor,
                        uint32_t ipsr)
{
    uint32_t v[9] = {0};
    uint8_t frame[32];
    uint8_t vector[4];
    if (frame_access(uc, x, v, 0) != 0) {
        return MCU_EXC_MEMORY;
    }
    uint32_t sp = v[8];
    uint32_t xpsr = (v[FRAME_XPSR] & ~XPSR_IPSR) | (ipsr & XPSR_IPSR);
    if (sp & 4u) {
        sp -= 4u;
        xpsr |= XPSR_ALIGNED;
    } else {
        xpsr &= ~XPSR_ALIGNED;
    }
    v[FRAME_XPSR] = xpsr;
    sp -= 32u;
    for (int i = 0; i < 8; i++) {
        for (int k = 0; k < 4; k++) {
            frame[4 * i + k] = (uint8_t)(v[i] >> (8 * k));
        }
    }
    if (((mcu_mem_fn)x->mem_read)(uc, vtor + 4u * exception, vector, 4) != 0) {
        return MCU_EXC_MEMORY;
    }
    x->handler = word_le(vector);
    if (!(x->handler & 1u)) {
        return MCU_EXC_NOT_THUMB;
    }
    if (((mcu_mem_fn)x->mem_write)(uc, sp, frame, 32) != 0) {
        return MCU_EXC_MEMORY;
    }
    v[8] = sp;
    v[FRAME_LR] = ipsr ? EXC_RETURN_HANDLER : EXC_RETURN_THREAD_MSP;
    v[FRAME_XPSR] = XPSR_THUMB;
    v[FRAME_PC] = x->handler | 1u; /* bit 0: stay in Thumb state */
    /* only sp, lr, xpsr and pc change: write those four */
    void *ptrs[4] = {&v[8], &v[FRAME_LR], &v[FRAME_XPSR], &v[FRAME_PC]};
    int ids[4] = {x->sp, x->frame[FRAME_LR], x->frame[FRAME_XPSR], x->frame[FRAME_PC]};
    if (((mcu_reg_batch_fn)x->reg_write_batch)(uc, ids, ptrs, 4) != 0) {
        return MCU_EXC_MEMORY;
    }
    if (sp < x->lowest_sp) {
        x->lowest_sp = sp;
    }
    return MCU_EXC_OK;
}

int mcu_exception_return(void *uc, mcu_exceptions *x)
{
    uint32_t v[9] = {0};
    uint8_t frame[32];
    int ids[2] = {x->frame[FRAME_PC], x->sp};
    void *ptrs[2] = {&x->exc_return, &v[8]};
    if (((mcu_reg_batch_fn)x->reg_read_batch)(uc, ids, ptrs, 2) != 0) {
        return MCU_EXC_MEMORY;
    }
    x->exc_return |= 1u;
    if (x->exc_return != EXC_RETURN_HANDLER && x->exc_return != EXC_RETURN_THREAD_MSP) {
        return MCU_EXC_BAD_RETURN;
    }
    uint32_t sp = v[8];
    if (((mcu_mem_fn)x->mem_read)(uc, sp, frame, 32) != 0) {
        return MCU_EXC_MEMORY;
    }
    for (int i = 0; i < 8; i++) {
        v[i] = word_le(&frame[4 * i]);
    }
    uint32_t xpsr = v[FRAME_XPSR];
    v[8] = sp + 32u + ((xpsr & XPSR_ALIGNED) ? 4u : 0u);
    v[FRAME_XPSR] = (xpsr & ~(XPSR_IPSR | XPSR_ALIGNED)) | XPSR_THUMB;
    v[FRAME_PC] |= 1u; /* Thumb: unicorn takes bit 0 of a written PC as the state */
    return frame_access(uc, x, v, 1) == 0 ? MCU_EXC_OK : MCU_EXC_MEMORY;
}

typedef int (*mcu_reg_fn)(void *uc, int reg, void *value);
typedef int (*mcu_start_fn)(void *uc, uint64_t begin, uint64_t until, uint64_t timeout,
                            uint64_t count);

uint32_t mcu_reg(void *uc, mcu_exceptions *x, int reg)
{
    uint32_t value = 0;
    if (((mcu_reg_fn)x->reg_read)(uc, reg, &value) != 0) {
        return 0;
    }
    return value;
}

int mcu_keep_pc(void *uc, mcu_exceptions *x)
{
    uint32_t pc = mcu_reg(uc, x, x->frame[FRAME_PC]) | 1u;
    return ((mcu_reg_fn)x->reg_write)(uc, x->frame[FRAME_PC], &pc);
}

int mcu_run(void *uc, mcu_exceptions *x, mcu_counter *c, uint64_t instructions)
{
    c->limit = c->count + instructions;
    c->take_next = 0; /* the machine took what was due before this run */
    mcu_timed_plan(c);
    uint32_t pc = mcu_reg(uc, x, x->frame[FRAME_PC]) | 1u;
    c->running = 1;
    int status = ((mcu_start_fn)x->emu_start)(uc, pc, 0, 0, 0);
    c->running = 0;
    return status;
}

int mcu_maybe_in_it_block(void *uc, mcu_exceptions *x)
{
    uint32_t pc = mcu_reg(uc, x, x->frame[FRAME_PC]) & ~1u;
    uint8_t before[16];
    if (pc < sizeof before ||
        ((mcu_mem_fn)x->mem_read)(uc, pc - sizeof before, before, sizeof before) != 0) {
        return 1;
    }
    for (unsigned i = 0; i < sizeof before; i += 2) {
        /* IT: 0xBF00 | firstcond << 4 | mask, mask not 0 (0xBFx0 are hints) */
        if (before[i + 1] == 0xBFu && (before[i] & 0x0Fu) != 0u) {
            return 1;
        }
    }
    return 0;
}
