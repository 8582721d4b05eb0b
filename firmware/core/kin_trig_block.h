/* Internal to the kinematic core: the block sine and cosine's code (kin_trig.c) for
 * callers that inline it into their own functions compiled for x86-64-v3 (an integrator's
 * step with its right-hand side), and whether this CPU runs such code. */
#ifndef SNAKEBOT_KIN_TRIG_BLOCK_H
#define SNAKEBOT_KIN_TRIG_BLOCK_H

#include "kin_trig.h"

#include <math.h>

/* Host builds (KIN_TRIG_DISPATCH, GCC on x86-64 Linux) compile the block code for
 * x86-64-v3 CPUs (AVX2 and FMA: four angles per instruction) and use it where the CPU
 * has them, libm elsewhere: the module stays portable, and the block code is only used
 * where it is faster (with two angles per SSE2 instruction it was slower than libm).
 * Other builds, the firmware's among them, use libm. */
#if defined(KIN_TRIG_DISPATCH) && defined(__GNUC__) && !defined(__clang__) \
    && defined(__x86_64__) && defined(__linux__)
#define KIN_TRIG_BLOCK_CODE 1
#else
#define KIN_TRIG_BLOCK_CODE 0
#endif

#if KIN_TRIG_BLOCK_CODE
#define TWO_OVER_PI 0.63661977236758134308
/* pi/2 = PIO2_HI + PIO2_LO to about 2^-107: x - k PIO2_HI in one fused multiply-add is
 * x - k pi/2 to within half an ulp of r plus k 2^-107. */
#define PIO2_HI 1.5707963267948966
#define PIO2_LO 6.123233995736766e-17
/* Largest |x| reduced here (k below 2^19); beyond, libm. */
#define KIN_TRIG_REDUCE_MAX 823549.6
/* Adding and subtracting 1.5 * 2^52 rounds a double below 2^51 to the nearest
 * integer in the current (round-to-nearest) mode. */
#define ROUNDER 6755399441055744.0

/* Taylor coefficients (-1)^j / (2j+1)! and (-1)^j / (2j)!: exact quotients of integers
 * that doubles hold exactly, so each is the correctly rounded value. */
#define S3 (-1.0 / 6.0)
#define S5 (1.0 / 120.0)
#define S7 (-1.0 / 5040.0)
#define S9 (1.0 / 362880.0)
#define S11 (-1.0 / 39916800.0)
#define S13 (1.0 / 6227020800.0)
#define S15 (-1.0 / 1307674368000.0)
#define C2 (-1.0 / 2.0)
#define C4 (1.0 / 24.0)
#define C6 (-1.0 / 720.0)
#define C8 (1.0 / 40320.0)
#define C10 (-1.0 / 3628800.0)
#define C12 (1.0 / 479001600.0)
#define C14 (-1.0 / 87178291200.0)
#define C16 (1.0 / 20922789888000.0)

/* One angle, inlined into each loop over a block (which then evaluates several at once).
 * Only doubles here: an int would make the compiler pair two vectors of doubles with
 * one of ints, and a block of four too short for its vector code. */
static inline __attribute__((always_inline)) void kin_sincos_lane(double x, double *sn, double *cs)
{
    const double k = fma(x, TWO_OVER_PI, ROUNDER) - ROUNDER;
    const double r = fma(-k, PIO2_LO, fma(-k, PIO2_HI, x));
    /* quadrant k mod 4, as one of -2, -1, 0, 1, 2 (-2 and 2 alike) */
    const double quad = k - 4.0 * ((k * 0.25 + ROUNDER) - ROUNDER);
    const double z = r * r, z2 = z * z, z4 = z2 * z2;
    /* Estrin's scheme: the terms in parallel, not one long chain of Horner steps */
    const double ps = (S3 + S5 * z) + z2 * (S7 + S9 * z) + z4 * ((S11 + S13 * z) + z2 * S15);
    const double pc = (C2 + C4 * z) + z2 * (C6 + C8 * z)
                      + z4 * ((C10 + C12 * z) + z2 * (C14 + C16 * z));
    const double s = r + (r * z) * ps;
    const double c = 1.0 + z * pc;
    const double s_base = (quad == 1.0 || quad == -1.0) ? c : s;
    const double c_base = (quad == 1.0 || quad == -1.0) ? s : c;
    /* sin(r + k pi/2) is -sin(r) for k = 2, -cos(r) for k = 3 (-1); cos(r + k pi/2)
     * is -sin(r) for k = 1 and -cos(r) for k = 2 */
    *sn = (quad < 0.0 || quad > 1.5) ? -s_base : s_base;
    *cs = (quad > 0.5 || quad < -1.5) ? -c_base : c_base;
}

/* the lane's constants are its own: not for the includer */
#undef TWO_OVER_PI
#undef PIO2_HI
#undef PIO2_LO
#undef ROUNDER
#undef S3
#undef S5
#undef S7
#undef S9
#undef S11
#undef S13
#undef S15
#undef C2
#undef C4
#undef C6
#undef C8
#undef C10
#undef C12
#undef C14
#undef C16

/* sin and cos of *x by libm: for an angle the lanes do not reduce (beyond
 * KIN_TRIG_REDUCE_MAX, or not finite). */
void kin_sincos_libm_at(const double *x, double *sn, double *cs);

/* kin_sincos of n angles (the same values), inline: for functions compiled for x86-64-v3
 * (FMA) with fp-contract=fast, called only where kin_trig_block_ok(). */
static inline __attribute__((always_inline)) void kin_sincos_block(int32_t n,
                                                                   const double *restrict x,
                                                                   double *restrict sn,
                                                                   double *restrict cs)
{
    for (int32_t i = 0; i < KIN_TRIG_PADDED(n); i++) {
        kin_sincos_lane(x[i], sn + i, cs + i);
    }
    for (int32_t i = 0; i < n; i++) {
        if (!(fabs(x[i]) <= KIN_TRIG_REDUCE_MAX)) {
            kin_sincos_libm_at(x + i, sn + i, cs + i);
        }
    }
}
#endif

/* 1 where this build and CPU run the block code (AVX2 and FMA), else 0. */
int kin_trig_block_ok(void);

#endif
