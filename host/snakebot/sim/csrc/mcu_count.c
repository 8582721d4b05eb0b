/* See mcu_count.h. */
#include "mcu_count.h"

typedef int (*mcu_stop_fn)(void *uc);

void mcu_count_instruction(void *uc, uint64_t address, uint32_t size, void *counter)
{
    (void)address;
    (void)size;
    mcu_counter *c = (mcu_counter *)counter;
    if (c->count >= c->limit) {
        /* the hook runs before the instruction: stopping here leaves it unexecuted */
        c->stops++;
        ((mcu_stop_fn)c->stop)(uc);
        return;
    }
    c->count++;
}

/* Hooked on the instruction after each `cpsie i` / `msr primask`: with an exception
 * pending, stop before it so the machine can take the exception (Python decides). */
void mcu_after_unmask(void *uc, uint64_t address, uint32_t size, void *counter)
{
    (void)uc;
    (void)address;
    (void)size;
    mcu_counter *c = (mcu_counter *)counter;
    if (c->pending && c->limit > c->count) {
        c->limit = c->count;
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
    return ((mcu_read_fn)f->read_fallback)(uc, offset, size, 0);
}

void mcu_io_write(void *uc, uint64_t offset, unsigned size, uint64_t value, void *io)
{
    mcu_fast_io *f = (mcu_fast_io *)io;
    if (f->kind == MCU_IO_IWDG_KR && offset == 0 && size == 4 && f->running &&
        (value & 0xFFFFu) == 0xAAAAu) {
        const mcu_counter *c = f->counter;
        double now = c->t0 + (double)(c->count - c->c0) / c->hz;
        if (f->feeds > 0 && now - f->last_feed > f->largest_gap) {
            f->largest_gap = now - f->last_feed;
        }
        f->last_feed = now;
        f->feeds++;
        return;
    }
    ((mcu_write_fn)f->write_fallback)(uc, offset, size, value, 0);
}
