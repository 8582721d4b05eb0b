/* Fixed-step RK4, adaptive Dormand-Prince 5(4) and 8(5,3) (Hairer, Norsett & Wanner,
 * Solving ODEs I, II.4-II.5 and II.10: coefficients, error norms, step-size control,
 * initial step). */
#include "kin_ode.h"
#include "kin_ode_dop853.h"

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

/* f at (t, y), counted (kin_ode_dop853.h). */
static int eval(kin_ode *ode, double t, const double *y, double *dy)
{
    return kin_ode_eval(ode, ode->f, t, y, dy);
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
    ode->step = NULL;
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

static int dop853_try(kin_ode *ode, const double *y, double t, double h, double *y1,
                      double *k_end, double *e)
{
    if (ode->step != NULL) { /* the caller's, with its right-hand side inlined */
        return ode->step(ode, y, t, h, y1, k_end, e);
    }
    switch (ode->n) {
    case 3: /* a body pose under a joint schedule */
        return kin_dop853_step(ode, 3, ode->f, y, t, h, y1, k_end, e);
    case 6: /* the trident's fields, on CPUs without a step of their own (kin_integrate.c) */
        return kin_dop853_step(ode, 6, ode->f, y, t, h, y1, k_end, e);
    default:
        return kin_dop853_step(ode, ode->n, ode->f, y, t, h, y1, k_end, e);
    }
}

/* Per method: its step, the order that sets the step-size exponent (that of the error
 * estimate plus one) and its PI weight. DOP853 takes 0.04 (with none it rejected 30
 * steps of the trident benchmark's 160, with 0.04 six); DOPRI5 keeps the plain
 * controller, so that its step sequence, which the planners' and predictors' results
 * rest on, is the one they were tuned with. */
typedef struct {
    kin_step_fn try_step;
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
