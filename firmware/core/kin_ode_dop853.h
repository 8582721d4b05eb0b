/* Internal to the kinematic core: the Dormand-Prince 8(5,3) step of kin_ode.c as an inline
 * template over its right-hand side, so that a caller can compile the step with its model
 * inlined (kin_ode.h's step hook) and kin_ode.c the generic one, from the same code. */
#ifndef SNAKEBOT_KIN_ODE_DOP853_H
#define SNAKEBOT_KIN_ODE_DOP853_H

#include "kin_ode.h"

#include <math.h>

/* f at (t, y), counted; the time of a failure kept. Not checked for NaN here: a
 * non-finite derivative makes the step's error estimate (Dormand-Prince) or its result
 * (RK4) non-finite, which is checked once per step instead of once per evaluation. */
static inline __attribute__((always_inline)) int kin_ode_eval(kin_ode *ode, kin_rhs_fn f,
                                                              double t, const double *y,
                                                              double *dy)
{
    ode->stats->evals++;
    const int rc = f(ode->ctx, t, y, dy);
    if (rc != KIN_OK) {
        ode->stats->t_fail = t;
    }
    return rc;
}

/* ---- Dormand-Prince 8(5,3) (Hairer, Norsett & Wanner, Solving ODEs I, II.10; the
 * coefficients of their DOP853 code) ---- */

#define DOP853_STAGES 12
static const double D8_C[DOP853_STAGES] = {
    0.0, 0.526001519587677318785587544488e-01, 0.789002279381515978178381316732e-01,
    0.118350341907227396726757197510, 0.281649658092772603273242802490,
    0.333333333333333333333333333333, 0.25, 0.307692307692307692307692307692,
    0.651282051282051282051282051282, 0.6, 0.857142857142857142857142857142, 1.0};
/* Row s: the weights of k1..ks in stage s + 1 (zeros included: the loops stay simple,
 * and the right-hand side costs far more than these few multiplications). */
static const double D8_A[DOP853_STAGES][DOP853_STAGES - 1] = {
    {0},
    {5.26001519587677318785587544488e-2},
    {1.97250569845378994544595329183e-2, 5.91751709536136983633785987549e-2},
    {2.95875854768068491816892993775e-2, 0.0, 8.87627564304205475450678981324e-2},
    {2.41365134159266685502369798665e-1, 0.0, -8.84549479328286085344864962717e-1,
     9.24834003261792003115737966543e-1},
    {3.7037037037037037037037037037e-2, 0.0, 0.0, 1.70828608729473871279604482173e-1,
     1.25467687566822425016691814123e-1},
    {3.7109375e-2, 0.0, 0.0, 1.70252211019544039314978060272e-1,
     6.02165389804559606850219397283e-2, -1.7578125e-2},
    {3.70920001185047927108779319836e-2, 0.0, 0.0, 1.70383925712239993810214054705e-1,
     1.07262030446373284651809199168e-1, -1.53194377486244017527936158236e-2,
     8.27378916381402288758473766002e-3},
    {6.24110958716075717114429577812e-1, 0.0, 0.0, -3.36089262944694129406857109825,
     -8.68219346841726006818189891453e-1, 2.75920996994467083049415600797e1,
     2.01540675504778934086186788979e1, -4.34898841810699588477366255144e1},
    {4.77662536438264365890433908527e-1, 0.0, 0.0, -2.48811461997166764192642586468,
     -5.90290826836842996371446475743e-1, 2.12300514481811942347288949897e1,
     1.52792336328824235832596922938e1, -3.32882109689848629194453265587e1,
     -2.03312017085086261358222928593e-2},
    {-9.3714243008598732571704021658e-1, 0.0, 0.0, 5.18637242884406370830023853209,
     1.09143734899672957818500254654, -8.14978701074692612513997267357,
     -1.85200656599969598641566180701e1, 2.27394870993505042818970056734e1,
     2.49360555267965238987089396762, -3.0467644718982195003823669022},
    {0.227331014751653820792359768449e1, 0.0, 0.0, -1.05344954667372501984066689879e1,
     -2.00087205822486249909675718444, -1.79589318631187989172765950534e1,
     2.79488845294199600508499808837e1, -2.85899827713502369474065508674,
     -8.87285693353062954433549289258, 1.23605671757943030647266201528e1,
     6.43392746015763530355970484046e-1}};
/* The eighth-order solution's weights. */
static const double D8_B[DOP853_STAGES] = {
    5.42937341165687622380535766363e-2, 0.0, 0.0, 0.0, 0.0,
    4.45031289275240888144113950566, 1.89151789931450038304281599044,
    -5.8012039600105847814672114227, 3.1116436695781989440891606237e-1,
    -1.52160949662516078556178806805e-1, 2.01365400804030348374776537501e-1,
    4.47106157277725905176885569043e-2};
/* The fifth-order error estimate's weights; the third-order one is B minus BHH. */
static const double D8_E5[DOP853_STAGES] = {
    0.1312004499419488073250102996e-1, 0.0, 0.0, 0.0, 0.0,
    -0.1225156446376204440720569753e+1, -0.4957589496572501915214079952,
    0.1664377182454986536961530415e+1, -0.3503288487499736816886487290,
    0.3341791187130174790297318841, 0.8192320648511571246570742613e-1,
    -0.2235530786388629525884427845e-1};
#define D8_BHH1 0.244094488188976377952755905512
#define D8_BHH9 0.733846688281611857341361741547
#define D8_BHH12 0.220588235294117647058823529412e-1

/* One attempted step from (t, y), k1 = f(t, y) in ode->k1, as a kin_step_fn (kin_ode.h)
 * does it, for n states and the right-hand side f (counted in ode->stats as kin_ode's own
 * evaluations are). Inlined with n a constant (kin_ode.c, for the common sizes), so that
 * the loops over the state unroll and the zero weights drop out at compile time; and
 * with f a constant, so that f is inlined too (a caller's step for its own model). */
static inline __attribute__((always_inline)) int kin_dop853_step(kin_ode *ode, const int32_t n,
                                                                 kin_rhs_fn f, const double *y,
                                                                 double t, double h,
                                                                 double *y1, double *k_end,
                                                                 double *e)
{
    double k[DOP853_STAGES][KIN_MAX_STATE], tmp[KIN_MAX_STATE];
    int rc;
    if (ode->times != NULL) { /* distinct stage times: c2 .. c12 */
        double stage_t[DOP853_STAGES - 1];
        for (int32_t s = 1; s < DOP853_STAGES; s++) {
            stage_t[s - 1] = t + D8_C[s] * h;
        }
        ode->times(ode->ctx, stage_t, DOP853_STAGES - 1);
    }
    for (int32_t i = 0; i < n; i++) {
        k[0][i] = ode->k1[i];
    }
    /* Stage s: y + h sum_j a_sj k_j, the stages before the last one summed first, one at a
     * time across the state, zero weights skipped; the newest stage then adds in one
     * multiply and one add, all that waits for the right-hand side just evaluated. The
     * loops over stages and weights are unrolled (GCC left them loops): each weight is
     * then a constant, and the zero ones and their tests are gone at compile time. */
#pragma GCC unroll 12
    for (int32_t s = 1; s < DOP853_STAGES; s++) {
        double acc[KIN_MAX_STATE];
        for (int32_t i = 0; i < n; i++) {
            acc[i] = 0.0;
        }
#pragma GCC unroll 12
        for (int32_t j = 0; j < s - 1; j++) {
            const double a = D8_A[s][j];
            for (int32_t i = 0; a != 0.0 && i < n; i++) {
                acc[i] += a * k[j][i];
            }
        }
        const double h_last = h * D8_A[s][s - 1];
        for (int32_t i = 0; i < n; i++) {
            tmp[i] = (y[i] + h * acc[i]) + h_last * k[s - 1][i];
        }
        if ((rc = kin_ode_eval(ode, f, t + D8_C[s] * h, tmp, k[s])) != KIN_OK) {
            return rc;
        }
    }
    double sum[KIN_MAX_STATE], err5[KIN_MAX_STATE];
    for (int32_t i = 0; i < n; i++) {
        sum[i] = D8_B[0] * k[0][i];
        err5[i] = D8_E5[0] * k[0][i];
    }
#pragma GCC unroll 12
    for (int32_t j = 1; j < DOP853_STAGES; j++) {
        const double b = D8_B[j], e = D8_E5[j];
        for (int32_t i = 0; (b != 0.0 || e != 0.0) && i < n; i++) {
            sum[i] += b * k[j][i];
            err5[i] += e * k[j][i];
        }
    }
    double e5 = 0.0, e3 = 0.0;
    for (int32_t i = 0; i < n; i++) {
        const double err3 = sum[i] - D8_BHH1 * k[0][i] - D8_BHH9 * k[8][i] - D8_BHH12 * k[11][i];
        y1[i] = y[i] + h * sum[i];
        const double sc = ode->opt.atol + ode->opt.rtol * fmax(fabs(y[i]), fabs(y1[i]));
        e5 += (err5[i] / sc) * (err5[i] / sc);
        e3 += (err3 / sc) * (err3 / sc);
    }
    const double denom = e5 + 0.01 * e3;
    *e = denom > 0.0 ? fabs(h) * e5 / sqrt(denom * n) : (denom == 0.0 ? 0.0 : NAN);
    if (*e <= 1.0) {
        return kin_ode_eval(ode, f, t + h, y1, k_end);
    }
    return KIN_OK;
}

#endif
