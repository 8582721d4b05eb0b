/* Sines and cosines of blocks of angles (kin_trig.h).
 *
 * Each angle is reduced to r = x - k pi/2 with |r| <= pi/4 (pi/2 in two parts, each
 * product with k subtracted in one fused multiply-add), the sine and cosine of r come
 * from their Taylor series (on |r| <= pi/4 the first omitted terms are below 1e-17
 * of the result), and the quadrant k mod 4 swaps and negates them. Every step is the
 * same arithmetic for every angle: no branches, no integer conversions, so the
 * compiler may put several angles in one vector register. */
#include "kin_trig.h"

#include <math.h>

/* Host builds (KIN_TRIG_DISPATCH, GCC on x86-64 Linux) compile the block code for
 * x86-64-v3 CPUs (AVX2 and FMA: four angles per instruction) and use it where the CPU
 * has them, libm elsewhere: the module stays portable, and the block code is only used
 * where it is faster (with two angles per SSE2 instruction it was slower than libm).
 * Other builds, the firmware's among them, use libm. */
#if defined(KIN_TRIG_DISPATCH) && defined(__GNUC__) && !defined(__clang__) \
    && defined(__x86_64__) && defined(__linux__)
#define BLOCK_CODE 1
#else
#define BLOCK_CODE 0
#endif

static void sincos_libm(int32_t n, const double *x, double *sn, double *cs)
{
    for (int32_t i = 0; i < n; i++) {
        sn[i] = sin(x[i]);
        cs[i] = cos(x[i]);
    }
}

#if BLOCK_CODE
#define TWO_OVER_PI 0.63661977236758134308
/* pi/2 = PIO2_HI + PIO2_LO to about 2^-107: x - k PIO2_HI in one fused multiply-add is
 * x - k pi/2 to within half an ulp of r plus k 2^-107. */
#define PIO2_HI 1.5707963267948966
#define PIO2_LO 6.123233995736766e-17
/* Largest |x| reduced here (k below 2^19); beyond, libm. */
#define REDUCE_MAX 823549.6
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

/* One angle, inlined into each vector loop below (which then evaluates several at once).
 * Only doubles here: an int would make the compiler pair two vectors of doubles with
 * one of ints, and a block of four too short for its vector code. */
static inline __attribute__((always_inline)) void sincos_lane(double x, double *sn, double *cs)
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

/* Angles too large for the reduction above, and non-finite ones: libm's. */
static void sincos_large(int32_t n, const double *x, double *sn, double *cs)
{
    for (int32_t i = 0; i < n; i++) {
        if (!(fabs(x[i]) <= REDUCE_MAX)) {
            sincos_libm(1, x + i, sn + i, cs + i);
        }
    }
}

/* One block as two 128-bit halves side by side: measured faster than one 256-bit chain
 * (the trident's four angles); several blocks go 256 bits wide (a snake's links). */
__attribute__((target("arch=x86-64-v3,prefer-vector-width=128"), optimize("fp-contract=fast")))
static void sincos_narrow(const double *restrict x, double *restrict sn, double *restrict cs)
{
    for (int32_t i = 0; i < KIN_TRIG_BLOCK; i++) {
        sincos_lane(x[i], sn + i, cs + i);
    }
}

__attribute__((target("arch=x86-64-v3"), optimize("fp-contract=fast")))
static void sincos_wide(int32_t n, const double *restrict x, double *restrict sn,
                        double *restrict cs)
{
    for (int32_t i = 0; i < KIN_TRIG_PADDED(n); i++) {
        sincos_lane(x[i], sn + i, cs + i);
    }
}
#endif

void kin_sincos(int32_t n, const double *restrict x, double *restrict sn, double *restrict cs)
{
#if BLOCK_CODE
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
        if (n <= KIN_TRIG_BLOCK) {
            sincos_narrow(x, sn, cs);
        } else {
            sincos_wide(n, x, sn, cs);
        }
        sincos_large(n, x, sn, cs);
        return;
    }
#endif
    sincos_libm(n, x, sn, cs);
}
