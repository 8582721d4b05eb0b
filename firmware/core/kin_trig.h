/* Internal to the kinematic core: sines and cosines of several angles at once.
 *
 * The right-hand sides need the sine and cosine of a handful of angles per evaluation
 * (the heading, each link or arm, the input phase); one call per angle to libm was
 * about half of an evaluation's time. kin_sincos() works on a block of angles with
 * the same straight-line code for each, so that a compiler can evaluate several in
 * one vector register. */
#ifndef SNAKEBOT_KIN_TRIG_H
#define SNAKEBOT_KIN_TRIG_H

#include <stdint.h>

/* cffi:begin */
/* Angles per block: callers' arrays hold a multiple of this (the entries past n are
 * evaluated and ignored), so that the block loop has no remainder to handle apart. */
#define KIN_TRIG_BLOCK 4

/* sn[i] = sin(x[i]), cs[i] = cos(x[i]) for i < n, rounded to the block size
 * (n_padded = KIN_TRIG_BLOCK * ceil(n / KIN_TRIG_BLOCK) entries may be read and written).
 * Within 2 ulp of libm's values; angles beyond |x| = 2^19 pi / 2 and non-finite ones
 * are passed to libm. */
void kin_sincos(int32_t n, const double *restrict x, double *restrict sn,
                double *restrict cs);
/* cffi:end */

/* kin_sincos's signature: what the generated velocities (kin_gen.h) take their sines by. */
typedef void (*kin_sincos_fn)(int32_t n, const double *restrict x, double *restrict sn,
                              double *restrict cs);

/* Round a count up to whole blocks (the length of the arrays kin_sincos uses). */
#define KIN_TRIG_PADDED(n) ((((n) + KIN_TRIG_BLOCK - 1) / KIN_TRIG_BLOCK) * KIN_TRIG_BLOCK)

#endif
