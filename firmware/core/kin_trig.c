/* Sines and cosines of blocks of angles (kin_trig.h).
 *
 * Each angle is reduced to r = x - k pi/2 with |r| <= pi/4 (pi/2 in three parts whose
 * first two products with k are exact for |k| < 2^20), the sine and cosine of r come
 * from their Taylor series (on |r| <= pi/4 the first omitted terms are below 1e-17
 * of the result), and the quadrant k mod 4 swaps and negates them. Every step is the
 * same arithmetic for every angle: no branches, no integer conversions, so the
 * compiler may put several angles in one vector register. */
#include "kin_trig.h"

#include <math.h>

/* Host builds may ask for a second copy of kin_sincos compiled for x86-64-v3 CPUs (AVX2:
 * four angles per instruction), chosen once at load time (an ifunc): the module stays
 * portable while using the wider vector unit where there is one. */
#if defined(KIN_TRIG_CLONES) && defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) \
    && defined(__linux__)
#define KIN_TRIG_TARGETS \
    __attribute__((target_clones("arch=x86-64-v3", "default"), optimize("fp-contract=fast")))
#else
#define KIN_TRIG_TARGETS
#endif

#define TWO_OVER_PI 0.63661977236758134308
/* pi/2 = PIO2_1 + PIO2_2 + PIO2_3: the first two have 33 significant bits, so k PIO2_1
 * and k PIO2_2 are exact for |k| < 2^20. */
#define PIO2_1 1.57079632673412561417e+00
#define PIO2_2 6.07710050630396597660e-11
#define PIO2_3 2.02226624871116645580e-21
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

KIN_TRIG_TARGETS
void kin_sincos(int32_t n, const double *restrict x, double *restrict sn, double *restrict cs)
{
    int large = 0;
    for (int32_t i = 0; i < KIN_TRIG_PADDED(n); i++) {
        const double k = (x[i] * TWO_OVER_PI + ROUNDER) - ROUNDER;
        const double r = ((x[i] - k * PIO2_1) - k * PIO2_2) - k * PIO2_3;
        /* quadrant k mod 4, as one of -2, -1, 0, 1, 2 (-2 and 2 alike) */
        const double quad = k - 4.0 * ((k * 0.25 + ROUNDER) - ROUNDER);
        const double z = r * r, z2 = z * z, z4 = z2 * z2;
        /* Estrin's scheme: the terms in parallel, not one long chain of Horner steps */
        const double ps = (S3 + S5 * z) + z2 * (S7 + S9 * z) + z4 * ((S11 + S13 * z) + z2 * S15);
        const double pc = (C2 + C4 * z) + z2 * (C6 + C8 * z)
                          + z4 * ((C10 + C12 * z) + z2 * (C14 + C16 * z));
        const double s = r + (r * z) * ps;
        const double c = 1.0 + z * pc;
        const int odd = quad == 1.0 || quad == -1.0;
        const double s_base = odd ? c : s;
        const double c_base = odd ? s : c;
        /* sin(r + k pi/2) is -sin(r) for k = 2, -cos(r) for k = 3 (-1); cos(r + k pi/2)
         * is -sin(r) for k = 1 and -cos(r) for k = 2 */
        sn[i] = (quad < 0.0 || quad > 1.5) ? -s_base : s_base;
        cs[i] = (quad > 0.5 || quad < -1.5) ? -c_base : c_base;
        large |= !(fabs(x[i]) <= REDUCE_MAX);
    }
    for (int32_t i = 0; large && i < n; i++) {
        if (!(fabs(x[i]) <= REDUCE_MAX)) {
            sn[i] = sin(x[i]);
            cs[i] = cos(x[i]);
        }
    }
}
