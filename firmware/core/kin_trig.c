/* Sines and cosines of blocks of angles (kin_trig.h).
 *
 * Each angle is reduced to r = x - k pi/2 with |r| <= pi/4 (pi/2 in two parts, each
 * product with k subtracted in one fused multiply-add), the sine and cosine of r come
 * from their Taylor series (on |r| <= pi/4 the first omitted terms are below 1e-17
 * of the result), and the quadrant k mod 4 swaps and negates them. Every step is the
 * same arithmetic for every angle: no branches, no integer conversions, so the
 * compiler may put several angles in one vector register. */
#include "kin_trig.h"
#include "kin_trig_block.h"

#include <math.h>

static void sincos_libm(int32_t n, const double *x, double *sn, double *cs)
{
    for (int32_t i = 0; i < n; i++) {
        sn[i] = sin(x[i]);
        cs[i] = cos(x[i]);
    }
}

#if KIN_TRIG_BLOCK_CODE
void kin_sincos_libm_at(const double *x, double *sn, double *cs)
{
    sincos_libm(1, x, sn, cs);
}

/* One block as two 128-bit halves side by side: measured faster than one 256-bit chain
 * (the trident's four angles); several blocks go 256 bits wide (a snake's links). */
__attribute__((target("arch=x86-64-v3,prefer-vector-width=128"), optimize("fp-contract=fast")))
static void sincos_narrow(const double *restrict x, double *restrict sn, double *restrict cs)
{
    for (int32_t i = 0; i < KIN_TRIG_BLOCK; i++) {
        kin_sincos_lane(x[i], sn + i, cs + i);
    }
}

__attribute__((target("arch=x86-64-v3"), optimize("fp-contract=fast")))
static void sincos_wide(int32_t n, const double *restrict x, double *restrict sn,
                        double *restrict cs)
{
    for (int32_t i = 0; i < KIN_TRIG_PADDED(n); i++) {
        kin_sincos_lane(x[i], sn + i, cs + i);
    }
}
#endif

int kin_trig_block_ok(void)
{
#if KIN_TRIG_BLOCK_CODE
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
    return 0;
#endif
}

void kin_sincos(int32_t n, const double *restrict x, double *restrict sn, double *restrict cs)
{
#if KIN_TRIG_BLOCK_CODE
    if (kin_trig_block_ok()) {
        if (n <= KIN_TRIG_BLOCK) {
            sincos_narrow(x, sn, cs);
        } else {
            sincos_wide(n, x, sn, cs);
        }
        /* angles too large for the reduction, and non-finite ones: libm's */
        for (int32_t i = 0; i < n; i++) {
            if (!(fabs(x[i]) <= KIN_TRIG_REDUCE_MAX)) {
                sincos_libm(1, x + i, sn + i, cs + i);
            }
        }
        return;
    }
#endif
    sincos_libm(n, x, sn, cs);
}
