/* The PC-link fuzz target's builders (pclink_builders.c): gait tables and programs made
 * from the input, sealed with their CRC as the host does, and the bus's answers to the
 * device's telemetry READ. Each reads its operands from the input in a fixed order, so a
 * program's later steps do not shift with what the device does (fuzz/seeds.py mirrors
 * that order). */
#ifndef SNAKEBOT_FUZZ_PCLINK_BUILDERS_H
#define SNAKEBOT_FUZZ_PCLINK_BUILDERS_H

#include <stddef.h>
#include <stdint.h>

#include "dxl_parser.h"

#include "pclink_common.h"

/* Store the CRC a table or a program carries at its offset 12 (see pclink_builders.c). */
void seal(uint8_t *t, size_t len);

/* A valid table from the input in t[0..FUZZ_CAPACITY); returns its length. */
size_t make_table(src *s, uint8_t *t);

/* A program from the input in t[0..FUZZ_CAPACITY), its CRC made right; returns its
 * length. */
size_t make_program(src *s, uint8_t *t);

/* How the bus answers the awaited READ: always read whole from the input, whatever the
 * device sends (so a program's later steps do not shift with the device's behaviour). */
typedef struct {
    uint8_t how;      /* 0 silence, 1 reply, 2 echo + reply, 3 damaged, 4 other servo, 5 raw */
    uint8_t data[8];  /* the telemetry block */
    uint8_t error;
    uint8_t flip_at;  /* damaged: which byte (from the ID on) and which bit */
    uint8_t flip_bit;
    uint8_t pieces;   /* how the bytes are split into UART reads */
    uint8_t raw_len;
    uint8_t raw[64];
} bus_answer_t;

void read_answer(src *s, bus_answer_t *a);

/* The bytes that come back in rx[0..cap) for the READ `read`; *damaged_at is the byte
 * flipped (how 3), else -1. */
size_t make_reply(const bus_answer_t *a, const dxl_event *read, uint8_t *rx, size_t cap,
                  int *damaged_at);

#endif
