/* Fixed-step RK4, adaptive Dormand-Prince 5(4) and 8(5,3) (Hairer, Norsett & Wanner,
 * Solving ODEs I, II.4-II.5 and II.10: coefficients, error norms, step-size control,
 * initial step). */
#include "kin_ode.h"

#include <math.h>

/* The default step budget of a call: a base plus a number per second of its span, so
 * that a call that cannot finish (a right-hand side that switches faster than the
 * tolerance can follow, as wheels that stick and slip in turn near concurrent axles)
 * fails in bounded time, a few seconds, instead of after a million steps. Adaptive calls
 * of smooth gaits attempt some 600 steps per second at the predictions' rtol 1e-10. */
#define DEFAULT_MAX_STEPS 1000000
#define DEFAULT_STEPS_BASE 10000.0
#define DEFAULT_STEPS_PER_S 20000.0
#define SAFETY 0.9
#define FAC_MIN 0.2
#define FAC_MAX 5.0
/* Proportional-integral step control (Gustafsson; the stabilisation of Hairer's codes):
 * the new step also leans on the previous step's error (weight beta, per method), which
 * damps the oscillation of step sizes around the tolerance that ends in rejected steps. */
#define LOG_ERR_PREV_MIN (-9.210340371976184) /* log(1e-4) */

static int all_finite(const double *v, int32_t n)
{
    for (int32_t i = 0; i < n; i++) {
        if (!isfinite(v[i])) {
            return 0;
        }
    }
    return 1;
}

/* f at (t, y). Not checked for NaN here: a non-finite derivative makes the step's
 * error estimate (Dormand-Prince) or its result (RK4) non-finite, which is checked once
 * per step instead of once per evaluation. */
static int eval(kin_ode *ode, double t, const double *y, double *dy)
{
    ode->stats->evals++;
    const int rc = ode->f(ode->ctx, t, y, dy);
    if (rc != KIN_OK) {
        ode->stats->t_fail = t;
    }
    return rc;
}

int kin_ode_init(kin_ode *ode, int32_t n, kin_rhs_fn f, void *ctx, const kin_options *opt,
                 kin_stats *stats, double span)
{
    if (ode == NULL || f == NULL || opt == NULL || stats == NULL || n < 1 || n > KIN_MAX_STATE
        || !(span >= 0.0) || !isfinite(span)) {
        return KIN_EINVAL;
    }
    ode->n = n;
    ode->f = f;
    ode->times = NULL;
    ode->smooth = NULL;
    ode->ctx = ctx;
    ode->opt = *opt;
    ode->stats = stats;
    ode->have_k1 = 0;
    ode->log_err_prev = LOG_ERR_PREV_MIN;
    if (opt->method == KIN_RK4) {
        if (!(opt->h > 0.0) || !isfinite(opt->h)) {
            return KIN_EINVAL;
        }
    } else if (opt->method == KIN_DOPRI5 || opt->method == KIN_DOP853) {
        if (!(opt->rtol >= 0.0) || !(opt->atol >= 0.0) || opt->rtol + opt->atol <= 0.0
            || !isfinite(opt->rtol + opt->atol) || opt->h < 0.0 || opt->h_min < 0.0) {
            return KIN_EINVAL;
        }
    } else {
        return KIN_EINVAL;
    }
    ode->h = opt->method != KIN_RK4 ? opt->h : 0.0;
    if (opt->max_steps > 0) {
        ode->budget = opt->max_steps;
    } else if (opt->method == KIN_RK4) {
        ode->budget = DEFAULT_MAX_STEPS; /* its step count is known before it starts */
    } else {
        const double steps = DEFAULT_STEPS_BASE + DEFAULT_STEPS_PER_S * span;
        ode->budget = steps < (double)DEFAULT_MAX_STEPS ? (int32_t)steps : DEFAULT_MAX_STEPS;
    }
    return KIN_OK;
}

void kin_ode_reset(kin_ode *ode)
{
    ode->have_k1 = 0;
}

/* ---- RK4 ---- */

static int rk4_advance(kin_ode *ode, double *y, double t, double t_end)
{
    const int32_t n = ode->n;
    double k1[KIN_MAX_STATE], k2[KIN_MAX_STATE], k3[KIN_MAX_STATE], k4[KIN_MAX_STATE];
    double tmp[KIN_MAX_STATE];
    double steps = ceil((t_end - t) / ode->opt.h - 1e-9);
    if (steps < 1.0) {
        steps = 1.0;
    }
    if (steps > (double)ode->budget) {
        ode->stats->t_fail = t;
        return KIN_EMAXSTEPS;
    }
    const int32_t count = (int32_t)steps;
    const double h = (t_end - t) / steps;
    for (int32_t s = 0; s < count; s++) {
        const double ts = t + s * h;
        if (ode->times != NULL) {
            const double stage_t[3] = {ts, ts + 0.5 * h, ts + h};
            ode->times(ode->ctx, stage_t, 3);
        }
        int rc = eval(ode, ts, y, k1);
        for (int32_t i = 0; rc == KIN_OK && i < n; i++) {
            tmp[i] = y[i] + 0.5 * h * k1[i];
        }
        if (rc == KIN_OK) {
            rc = eval(ode, ts + 0.5 * h, tmp, k2);
        }
        for (int32_t i = 0; rc == KIN_OK && i < n; i++) {
            tmp[i] = y[i] + 0.5 * h * k2[i];
        }
        if (rc == KIN_OK) {
            rc = eval(ode, ts + 0.5 * h, tmp, k3);
        }
        for (int32_t i = 0; rc == KIN_OK && i < n; i++) {
            tmp[i] = y[i] + h * k3[i];
        }
        if (rc == KIN_OK) {
            rc = eval(ode, ts + h, tmp, k4);
        }
        if (rc != KIN_OK) {
            return rc;
        }
        for (int32_t i = 0; i < n; i++) {
            y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        if (!all_finite(y, n)) {
            ode->stats->t_fail = ts;
            return KIN_ENONFINITE;
        }
        ode->budget--;
        ode->stats->steps++;
    }
    return KIN_OK;
}

/* ---- Dormand-Prince 5(4) ---- */

static const double C2 = 1.0 / 5.0, C3 = 3.0 / 10.0, C4 = 4.0 / 5.0, C5 = 8.0 / 9.0;
static const double A21 = 1.0 / 5.0;
static const double A31 = 3.0 / 40.0, A32 = 9.0 / 40.0;
static const double A41 = 44.0 / 45.0, A42 = -56.0 / 15.0, A43 = 32.0 / 9.0;
static const double A51 = 19372.0 / 6561.0, A52 = -25360.0 / 2187.0, A53 = 64448.0 / 6561.0,
                    A54 = -212.0 / 729.0;
static const double A61 = 9017.0 / 3168.0, A62 = -355.0 / 33.0, A63 = 46732.0 / 5247.0,
                    A64 = 49.0 / 176.0, A65 = -5103.0 / 18656.0;
static const double A71 = 35.0 / 384.0, A73 = 500.0 / 1113.0, A74 = 125.0 / 192.0,
                    A75 = -2187.0 / 6784.0, A76 = 11.0 / 84.0;
/* Error weights: 5th-order minus embedded 4th-order solution. */
static const double E1 = 71.0 / 57600.0, E3 = -71.0 / 16695.0, E4 = 71.0 / 1920.0,
                    E5 = -17253.0 / 339200.0, E6 = 22.0 / 525.0, E7 = -1.0 / 40.0;

static double scaled_norm(const kin_ode *ode, const double *v, const double *y0, const double *y1)
{
    double sum = 0.0;
    for (int32_t i = 0; i < ode->n; i++) {
        double mag = fabs(y0[i]);
        if (y1 != NULL && fabs(y1[i]) > mag) {
            mag = fabs(y1[i]);
        }
        const double sc = ode->opt.atol + ode->opt.rtol * mag;
        const double e = v[i] / sc;
        sum += e * e;
    }
    return sqrt(sum / ode->n);
}

/* Hairer's starting step: from the sizes of y, f(y) and an estimate of f's change. */
static int initial_step(kin_ode *ode, const double *y, double t, double span, double order,
                        double *h_out)
{
    double y1[KIN_MAX_STATE], f1[KIN_MAX_STATE], diff[KIN_MAX_STATE];
    const double d0 = scaled_norm(ode, y, y, NULL);
    const double d1 = scaled_norm(ode, ode->k1, y, NULL);
    double h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 * (span > 1.0 ? span : 1.0) : 0.01 * d0 / d1;
    if (h0 > span) {
        h0 = span;
    }
    for (int32_t i = 0; i < ode->n; i++) {
        y1[i] = y[i] + h0 * ode->k1[i];
    }
    int rc = eval(ode, t + h0, y1, f1);
    if (rc != KIN_OK) {
        return rc;
    }
    for (int32_t i = 0; i < ode->n; i++) {
        diff[i] = f1[i] - ode->k1[i];
    }
    const double d2 = scaled_norm(ode, diff, y, NULL) / h0;
    const double dmax = d1 > d2 ? d1 : d2;
    const double h1 = dmax <= 1e-15 ? fmax(1e-6, h0 * 1e-3) : pow(0.01 / dmax, 1.0 / order);
    *h_out = fmin(100.0 * h0, h1);
    return KIN_OK;
}

/* One attempted step of an embedded pair from (t, y), k1 = f(t, y): writes the new
 * state to y1, its scaled error norm to *e (accept when <= 1), and, when the step is
 * accepted, f(t + h, y1) to k_end (first-same-as-last for the next step). */
typedef int (*try_step_fn)(kin_ode *ode, const double *y, double t, double h, double *y1,
                           double *k_end, double *e);

static int dopri5_try(kin_ode *ode, const double *y, double t, double h, double *y1,
                      double *k_end, double *e)
{
    const int32_t n = ode->n;
    double k2[KIN_MAX_STATE], k3[KIN_MAX_STATE], k4[KIN_MAX_STATE], k5[KIN_MAX_STATE];
    double k6[KIN_MAX_STATE], tmp[KIN_MAX_STATE], err[KIN_MAX_STATE];
    const double *k1 = ode->k1;
    double *k7 = k_end; /* the fifth-order error estimate needs it, accepted or not */
    int rc;
    if (ode->times != NULL) { /* the same expressions as the stages' times below */
        const double stage_t[5] = {t + C2 * h, t + C3 * h, t + C4 * h, t + C5 * h, t + h};
        ode->times(ode->ctx, stage_t, 5);
    }
    for (int32_t i = 0; i < n; i++) {
        tmp[i] = y[i] + h * A21 * k1[i];
    }
    if ((rc = eval(ode, t + C2 * h, tmp, k2)) != KIN_OK) {
        return rc;
    }
    for (int32_t i = 0; i < n; i++) {
        tmp[i] = y[i] + h * (A31 * k1[i] + A32 * k2[i]);
    }
    if ((rc = eval(ode, t + C3 * h, tmp, k3)) != KIN_OK) {
        return rc;
    }
    for (int32_t i = 0; i < n; i++) {
        tmp[i] = y[i] + h * (A41 * k1[i] + A42 * k2[i] + A43 * k3[i]);
    }
    if ((rc = eval(ode, t + C4 * h, tmp, k4)) != KIN_OK) {
        return rc;
    }
    for (int32_t i = 0; i < n; i++) {
        tmp[i] = y[i] + h * (A51 * k1[i] + A52 * k2[i] + A53 * k3[i] + A54 * k4[i]);
    }
    if ((rc = eval(ode, t + C5 * h, tmp, k5)) != KIN_OK) {
        return rc;
    }
    for (int32_t i = 0; i < n; i++) {
        tmp[i] = y[i] + h * (A61 * k1[i] + A62 * k2[i] + A63 * k3[i] + A64 * k4[i]
                             + A65 * k5[i]);
    }
    if ((rc = eval(ode, t + h, tmp, k6)) != KIN_OK) {
        return rc;
    }
    for (int32_t i = 0; i < n; i++) {
        y1[i] = y[i] + h * (A71 * k1[i] + A73 * k3[i] + A74 * k4[i] + A75 * k5[i]
                            + A76 * k6[i]);
    }
    if ((rc = eval(ode, t + h, y1, k7)) != KIN_OK) {
        return rc;
    }
    for (int32_t i = 0; i < n; i++) {
        err[i] = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i]
                      + E7 * k7[i]);
    }
    *e = scaled_norm(ode, err, y, y1);
    return KIN_OK;
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

/* The step for n states; inlined with n a constant for the common sizes (dop853_try),
 * so that the loops over the state unroll and the zero weights drop out at compile time. */
static inline __attribute__((always_inline)) int dop853_step(kin_ode *ode, const int32_t n,
                                                             const double *y, double t,
                                                             double h, double *y1,
                                                             double *k_end, double *e)
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
        if ((rc = eval(ode, t + D8_C[s] * h, tmp, k[s])) != KIN_OK) {
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
        return eval(ode, t + h, y1, k_end);
    }
    return KIN_OK;
}

static int dop853_try(kin_ode *ode, const double *y, double t, double h, double *y1,
                      double *k_end, double *e)
{
    switch (ode->n) {
    case 3: /* a body pose under a joint schedule */
        return dop853_step(ode, 3, y, t, h, y1, k_end, e);
    case 6: /* the trident's fields */
        return dop853_step(ode, 6, y, t, h, y1, k_end, e);
    default:
        return dop853_step(ode, ode->n, y, t, h, y1, k_end, e);
    }
}

/* Per method: its step, the order that sets the step-size exponent (that of the error
 * estimate plus one) and its PI weight. DOP853 takes 0.04 (with none it rejected 30
 * steps of the trident benchmark's 160, with 0.04 six); DOPRI5 keeps the plain
 * controller, so that its step sequence, which the planners' and predictors' results
 * rest on, is the one they were tuned with. */
typedef struct {
    try_step_fn try_step;
    double order;
    double beta;
} adaptive_method;

static const adaptive_method DOPRI5_METHOD = {dopri5_try, 5.0, 0.0};
static const adaptive_method DOP853_METHOD = {dop853_try, 8.0, 0.04};

static int adaptive_advance(kin_ode *ode, const adaptive_method *m, double *y, double t,
                            double t_end)
{
    const int32_t n = ode->n;
    double y1[KIN_MAX_STATE], k_end[KIN_MAX_STATE];
    const double span = t_end - t;
    const double h_min = ode->opt.h_min > 0.0 ? ode->opt.h_min
                                              : 1e-12 * fmax(1.0, fmax(fabs(t), fabs(t_end)));
    const double expo = 1.0 / m->order - 0.75 * m->beta;
    int rc;
    if (!ode->have_k1) {
        rc = eval(ode, t, y, ode->k1);
        if (rc != KIN_OK) {
            return rc;
        }
        ode->have_k1 = 1;
    }
    if (!(ode->h > 0.0)) {
        rc = initial_step(ode, y, t, span, m->order, &ode->h);
        if (rc != KIN_OK) {
            return rc;
        }
    }
    int last_rejected = 0;
    while (t < t_end) {
        if (ode->budget <= 0) {
            ode->stats->t_fail = t;
            return KIN_EMAXSTEPS;
        }
        double h = ode->h;
        int hits_end = 0;
        double t_next = t + h, t_resume = t_next;
        if (t + 1.01 * h >= t_end) {
            h = t_end - t; /* land exactly on the end (and avoid a sliver step after it) */
            hits_end = 1;
            t_next = t_resume = t_end;
        }
        if (ode->smooth != NULL) {
            double t_piece = t_next;
            if ((rc = ode->smooth(ode->ctx, t, y, t_next, &t_piece, &t_resume)) != KIN_OK) {
                return rc;
            }
            if (t_piece > t && t_piece < t_next && t_resume >= t_piece && t_resume <= t_next) {
                h = t_piece - t; /* land just before the switch, as on an end */
                hits_end = 1;
                t_next = t_piece;
            } else {
                t_resume = t_next;
            }
        }
        if (h < h_min && !hits_end) {
            ode->stats->t_fail = t;
            return KIN_ESTEPSIZE;
        }
        double e;
        if ((rc = m->try_step(ode, y, t, h, y1, k_end, &e)) != KIN_OK) {
            return rc;
        }
        ode->budget--;
        if (!isfinite(e)) {
            ode->stats->t_fail = t;
            return KIN_ENONFINITE;
        }
        /* SAFETY e^-expo e_prev^beta, one log and one exp */
        const double log_e = e > 0.0 ? log(e) : -INFINITY;
        if (e <= 1.0) {
            double fac = SAFETY * exp(m->beta * ode->log_err_prev - expo * log_e);
            t = t_next;
            for (int32_t i = 0; i < n; i++) {
                y[i] = y1[i];
                ode->k1[i] = k_end[i];
            }
            ode->stats->steps++;
            if (t_resume > t) { /* across the switch, with the velocity just after it */
                if ((rc = eval(ode, t_resume, y, k_end)) != KIN_OK) {
                    return rc;
                }
                for (int32_t i = 0; i < n; i++) {
                    y[i] += (t_resume - t) * k_end[i];
                }
                t = t_resume;
                if ((rc = eval(ode, t, y, ode->k1)) != KIN_OK) {
                    return rc;
                }
            }
            if (last_rejected && fac > 1.0) {
                fac = 1.0;
            }
            last_rejected = 0;
            double h_next = h * fmin(FAC_MAX, fmax(FAC_MIN, fac));
            if (hits_end && h < ode->h) {
                /* A step shortened to land on the end (or a switch) says little about
                 * the step the controller proposed: never grow past it, and keep it
                 * outright when the step was cut to under half (a sliver before an
                 * output time, knot or switch). */
                h_next = h < 0.5 * ode->h ? ode->h : fmin(h_next, ode->h);
            }
            ode->h = h_next;
            ode->log_err_prev = log_e > LOG_ERR_PREV_MIN ? log_e : LOG_ERR_PREV_MIN;
        } else {
            ode->stats->rejected++;
            last_rejected = 1;
            ode->h = h * fmax(FAC_MIN, SAFETY * exp(-expo * log_e));
            if (ode->h < h_min) {
                ode->stats->t_fail = t;
                return KIN_ESTEPSIZE;
            }
        }
    }
    return KIN_OK;
}

int kin_ode_advance(kin_ode *ode, double *y, double t, double t_end)
{
    if (!(t_end > t)) {
        return t_end == t ? KIN_OK : KIN_EINVAL;
    }
    if (ode->opt.method == KIN_RK4) {
        return rk4_advance(ode, y, t, t_end);
    }
    return adaptive_advance(ode, ode->opt.method == KIN_DOP853 ? &DOP853_METHOD : &DOPRI5_METHOD,
                            y, t, t_end);
}
