/* Fixed-step RK4 and adaptive Dormand-Prince 5(4) (Hairer, Norsett & Wanner, Solving
 * ODEs I, II.4-II.5: coefficients, error norm, step-size control, initial step). */
#include "kin_ode.h"

#include <math.h>

#define DEFAULT_MAX_STEPS 1000000
#define SAFETY 0.9
#define FAC_MIN 0.2
#define FAC_MAX 5.0
/* Proportional-integral step control (Gustafsson; the stabilisation of Hairer's DOPRI5):
 * the new step also leans on the previous step's error, which damps the oscillation of
 * step sizes around the tolerance that otherwise ends in rejected steps. */
#define PI_BETA 0.04
#define PI_EXPO (0.2 - 0.75 * PI_BETA)
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
                 kin_stats *stats)
{
    if (ode == NULL || f == NULL || opt == NULL || stats == NULL || n < 1 || n > KIN_MAX_STATE) {
        return KIN_EINVAL;
    }
    ode->n = n;
    ode->f = f;
    ode->times = NULL;
    ode->ctx = ctx;
    ode->opt = *opt;
    ode->stats = stats;
    ode->have_k1 = 0;
    ode->log_err_prev = LOG_ERR_PREV_MIN;
    if (opt->method == KIN_RK4) {
        if (!(opt->h > 0.0) || !isfinite(opt->h)) {
            return KIN_EINVAL;
        }
    } else if (opt->method == KIN_DOPRI5) {
        if (!(opt->rtol >= 0.0) || !(opt->atol >= 0.0) || opt->rtol + opt->atol <= 0.0
            || !isfinite(opt->rtol + opt->atol) || opt->h < 0.0 || opt->h_min < 0.0) {
            return KIN_EINVAL;
        }
    } else {
        return KIN_EINVAL;
    }
    ode->h = opt->method == KIN_DOPRI5 ? opt->h : 0.0;
    ode->budget = opt->max_steps > 0 ? opt->max_steps : DEFAULT_MAX_STEPS;
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
static int initial_step(kin_ode *ode, const double *y, double t, double span, double *h_out)
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
    const double h1 = dmax <= 1e-15 ? fmax(1e-6, h0 * 1e-3) : pow(0.01 / dmax, 1.0 / 5.0);
    *h_out = fmin(100.0 * h0, h1);
    return KIN_OK;
}

static int dopri_advance(kin_ode *ode, double *y, double t, double t_end)
{
    const int32_t n = ode->n;
    double k2[KIN_MAX_STATE], k3[KIN_MAX_STATE], k4[KIN_MAX_STATE], k5[KIN_MAX_STATE];
    double k6[KIN_MAX_STATE], k7[KIN_MAX_STATE], tmp[KIN_MAX_STATE], y1[KIN_MAX_STATE];
    double err[KIN_MAX_STATE];
    const double span = t_end - t;
    const double h_min = ode->opt.h_min > 0.0 ? ode->opt.h_min
                                              : 1e-12 * fmax(1.0, fmax(fabs(t), fabs(t_end)));
    int rc;
    if (!ode->have_k1) {
        rc = eval(ode, t, y, ode->k1);
        if (rc != KIN_OK) {
            return rc;
        }
        ode->have_k1 = 1;
    }
    if (!(ode->h > 0.0)) {
        rc = initial_step(ode, y, t, span, &ode->h);
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
        if (t + 1.01 * h >= t_end) {
            h = t_end - t; /* land exactly on the end (and avoid a sliver step after it) */
            hits_end = 1;
        }
        if (h < h_min && !hits_end) {
            ode->stats->t_fail = t;
            return KIN_ESTEPSIZE;
        }
        const double *k1 = ode->k1;
        if (ode->times != NULL) { /* the same expressions as the stages' times below */
            const double stage_t[KIN_ODE_MAX_TIMES] = {t + C2 * h, t + C3 * h, t + C4 * h,
                                                       t + C5 * h, t + h};
            ode->times(ode->ctx, stage_t, KIN_ODE_MAX_TIMES);
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
        ode->budget--;
        const double e = scaled_norm(ode, err, y, y1);
        if (!isfinite(e)) {
            ode->stats->t_fail = t;
            return KIN_ENONFINITE;
        }
        /* SAFETY e^-PI_EXPO e_prev^PI_BETA, one log and one exp */
        const double log_e = e > 0.0 ? log(e) : -INFINITY;
        if (e <= 1.0) {
            double fac = SAFETY * exp(PI_BETA * ode->log_err_prev - PI_EXPO * log_e);
            t = hits_end ? t_end : t + h;
            for (int32_t i = 0; i < n; i++) {
                y[i] = y1[i];
                ode->k1[i] = k7[i];
            }
            ode->stats->steps++;
            if (last_rejected && fac > 1.0) {
                fac = 1.0;
            }
            last_rejected = 0;
            double h_next = h * fmin(FAC_MAX, fmax(FAC_MIN, fac));
            if (hits_end && h < ode->h) {
                /* A step shortened to land on the end says little about the step the
                 * controller proposed: never grow past it, and keep it outright when the
                 * step was cut to under half (a sliver before an output time or knot). */
                h_next = h < 0.5 * ode->h ? ode->h : fmin(h_next, ode->h);
            }
            ode->h = h_next;
            ode->log_err_prev = log_e > LOG_ERR_PREV_MIN ? log_e : LOG_ERR_PREV_MIN;
        } else {
            ode->stats->rejected++;
            last_rejected = 1;
            ode->h = h * fmax(FAC_MIN, SAFETY * exp(-PI_EXPO * log_e));
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
    return dopri_advance(ode, y, t, t_end);
}
