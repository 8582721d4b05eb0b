/* Single-producer single-consumer byte ring, safe between one interrupt handler and the
 * main loop without masking interrupts: the producer only writes `head`, the consumer only
 * writes `tail`, and both are free-running 16-bit counters (aligned halfword stores are
 * atomic on the Cortex-M3). The capacity is a power of two, at most 32768. */
#ifndef SNAKEBOT_HAL_RING_H
#define SNAKEBOT_HAL_RING_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct {
    uint8_t *buf;
    uint16_t mask;          /* capacity - 1 */
    volatile uint16_t head; /* next slot to write; producer only */
    volatile uint16_t tail; /* next slot to read; consumer only */
} hal_ring_t;

/* Keeps the compiler from moving buffer accesses across an index update. */
#define HAL_RING_BARRIER() __asm__ volatile("" ::: "memory")

/* Define the storage and an initializer for a ring of `size` bytes (a power of two). */
#define HAL_RING_STORAGE(name, size)                                                    \
    static uint8_t name[(size)];                                                        \
    typedef char name##_size_must_be_power_of_two[((size) & ((size)-1)) == 0 ? 1 : -1]
#define HAL_RING_INIT(storage) {(storage), (uint16_t)(sizeof(storage) - 1U), 0U, 0U}

static inline size_t hal_ring_count(const hal_ring_t *r)
{
    return (uint16_t)(r->head - r->tail);
}

static inline size_t hal_ring_free(const hal_ring_t *r)
{
    return (size_t)r->mask + 1U - hal_ring_count(r);
}

static inline bool hal_ring_put(hal_ring_t *r, uint8_t byte)
{
    uint16_t head = r->head;
    if ((uint16_t)(head - r->tail) > r->mask) {
        return false;
    }
    r->buf[head & r->mask] = byte;
    HAL_RING_BARRIER();
    r->head = (uint16_t)(head + 1U);
    return true;
}

static inline bool hal_ring_get(hal_ring_t *r, uint8_t *byte)
{
    uint16_t tail = r->tail;
    if (tail == r->head) {
        return false;
    }
    *byte = r->buf[tail & r->mask];
    HAL_RING_BARRIER();
    r->tail = (uint16_t)(tail + 1U);
    return true;
}

/* Consumer side: forget everything buffered. */
static inline void hal_ring_clear(hal_ring_t *r)
{
    r->tail = r->head;
}

#endif
