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
