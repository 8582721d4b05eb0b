/* Internal to the kinematic core: a generic ODE stepper (fixed-step RK4 and adaptive
 * Dormand-Prince 5(4) and 8(5,3), with FSAL and error control) over a right-hand-side
 * callback.
 * Not published to Python; the kin_integrate_* functions drive it. */
#ifndef SNAKEBOT_KIN_ODE_H
#define SNAKEBOT_KIN_ODE_H

#include "kin_core.h"

typedef int (*kin_rhs_fn)(void *ctx, double t, const double *y, double *dy);
/* Optional, called before each step with the times at which its stages will call f:
 * a right-hand side can then evaluate its parts that depend on time alone for all of
 * them in one go (the inputs' sines), and look them up by t. */
typedef void (*kin_times_fn)(void *ctx, const double *t, int32_t count);
/* Optional, adaptive methods: called before each step from (t, y) to t_end with where
 * the right-hand side stops being smooth. If it finds a switch in between (wheels passing
 * between sticking and slipping: a kink or a jump of the velocity), *t_piece is a point
 * just before it and *t_resume one just after (t < *t_piece <= *t_resume <= t_end, the
 * two a hair apart); otherwise both are t_end. The step then ends at *t_piece, its stages
 * all on the one smooth piece, so that the method's order holds and its step-size
 * controller does not reject step after step to get across; the hair to *t_resume is
 * crossed with the velocity just after the switch, and the next step starts there. */
typedef int (*kin_smooth_fn)(void *ctx, double t, const double *y, double t_end,
                             double *t_piece, double *t_resume);

/* Most distinct stage times of one step (Dormand-Prince 5(4): 5, 8(5,3): 11). */
#define KIN_ODE_MAX_TIMES 11

typedef struct kin_ode kin_ode;
/* One attempted step of an embedded pair from (t, y), k1 = f(t, y) in ode->k1: writes
 * the new state to y1, its scaled error norm to *e (accept when <= 1), and, when the step
 * is accepted, f(t + h, y1) to k_end (first-same-as-last for the next step). */
typedef int (*kin_step_fn)(kin_ode *ode, const double *y, double t, double h, double *y1,
                           double *k_end, double *e);

struct kin_ode {
    int32_t n;            /* state dimension, <= KIN_MAX_STATE */
    kin_rhs_fn f;
    kin_times_fn times;   /* may be NULL; kin_ode_init sets NULL, set it after */
    kin_smooth_fn smooth; /* may be NULL, as times */
    /* DOP853 only, may be NULL (kin_ode_init sets NULL): the caller's own step, the same
     * method with its right-hand side inlined (kin_dop853_step, kin_ode_dop853.h) */
    kin_step_fn step;
    void *ctx;
    kin_options opt;      /* validated copy, defaults filled in */
    kin_stats *stats;     /* never NULL once initialised */
    double h;             /* adaptive: the step to try next (0 = choose one) */
    int32_t budget;       /* steps left (accepted + rejected) */
    int32_t have_k1;      /* adaptive FSAL: k1 holds f(t, y) for the current (t, y) */
    double log_err_prev;  /* adaptive: log of the last accepted step's scaled error */
    double k1[KIN_MAX_STATE];
};

/* Validate options and prepare; stats must not be NULL. span (t_end - t0 of the whole
 * call) sizes the default step budget of the adaptive methods. */
int kin_ode_init(kin_ode *ode, int32_t n, kin_rhs_fn f, void *ctx, const kin_options *opt,
                 kin_stats *stats, double span);
/* Forget the cached derivative (call when the right-hand side changes discontinuously). */
void kin_ode_reset(kin_ode *ode);
/* Advance y in place from t to t_end (t_end > t). */
int kin_ode_advance(kin_ode *ode, double *y, double t, double t_end);

#endif
