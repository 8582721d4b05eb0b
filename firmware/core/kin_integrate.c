/* Whole trajectories in one call: joint schedules (the body follows through the
 * quasi-static friction model) and field-driven systems (qdot = sum_i u_i(t) g_i(q)).
 *
 * Singular configurations under a joint schedule. With wheels that roll freely
 * (rolling = 0), where the wheel axles are concurrent (the 3-link snake's line
 * phi1 = phi2) the body velocity is 0/0: a serpenoid
 * crosses that line with the one admissible joint velocity, so along the trajectory the
 * body velocity is a smooth function of time with a removable singularity, but
 * evaluating it within ~1e-8 of the crossing loses all accuracy. There, and only there,
 * the right-hand side is extrapolated in time at fixed pose from four well-conditioned
 * neighbours t +- e, t +- 2e (Richardson: error e^4 f''''/6, e = 1e-4 of the schedule's
 * time scale). A genuine pole (an inadmissible crossing) is told apart by its
 * differences growing, not shrinking, towards t, and reported as KIN_EINADMISSIBLE. */
#include "kin_core.h"
#include "kin_fields.h"
#include "kin_geom.h"
#include "kin_ode.h"
#include "kin_ode_dop853.h"
#include "kin_trig.h"
#include "kin_trig_block.h"

#include <math.h>
#include <string.h>

#define TWO_PI 6.283185307179586
/* Below this conditioning the direct solve is not trusted to ~1e-8: extrapolate. */
#define RCOND_FALLBACK 1e-8
#define FALLBACK_EPS 1e-4
#define FALLBACK_TRIES 5

/* ---- sines of the phase omega t at a step's stage times ---- */

typedef struct {
    double omega;
    int32_t count;
    double t[KIN_TRIG_PADDED(KIN_ODE_MAX_TIMES)];
    double sn[KIN_TRIG_PADDED(KIN_ODE_MAX_TIMES)], cs[KIN_TRIG_PADDED(KIN_ODE_MAX_TIMES)];
} phase_table;

#define PHASE_ZERO {0.0, 0, {0.0}, {0.0}, {0.0}}

/* The integrator's times hook: sin and cos of omega t for all stages in one call. */
static void phase_fill(phase_table *p, const double *t, int32_t count)
{
    double angle[KIN_TRIG_PADDED(KIN_ODE_MAX_TIMES)];
    for (int32_t k = 0; k < KIN_TRIG_PADDED(count); k++) {
        p->t[k] = k < count ? t[k] : t[0];
        angle[k] = p->omega * p->t[k];
    }
    p->count = count;
    kin_sincos(count, angle, p->sn, p->cs);
}

/* sin and cos of omega t: from the table when t is one of the step's stage times (the
 * integrator computes them with the same expression), otherwise directly. */
static void phase_at(const phase_table *p, double t, double *sn, double *cs)
{
    for (int32_t k = 0; k < p->count; k++) {
        if (p->t[k] == t) {
            *sn = p->sn[k];
            *cs = p->cs[k];
            return;
        }
    }
    *sn = sin(p->omega * t);
    *cs = cos(p->omega * t);
}

/* ---- schedules ---- */

static int schedule_check(const kin_schedule *s, int32_t joints)
{
    if (s == NULL || s->joints != joints || joints < 1 || joints > KIN_MAX_JOINTS) {
        return KIN_EINVAL;
    }
    if (s->type == KIN_SCHED_SINES) {
        if (!isfinite(s->omega)) {
            return KIN_ENONFINITE;
        }
        for (int32_t j = 0; j < joints; j++) {
            if (!isfinite(s->offset[j]) || !isfinite(s->rate[j]) || !isfinite(s->amp[j])
                || !isfinite(s->phase[j])) {
                return KIN_ENONFINITE;
            }
        }
        return KIN_OK;
    }
    if (s->type == KIN_SCHED_TABLE) {
        if (s->samples == NULL || s->rows < 1 || !(s->dt > 0.0) || !isfinite(s->dt)) {
            return KIN_EINVAL;
        }
        for (int32_t i = 0; i < s->rows * joints; i++) {
            if (!isfinite(s->samples[i])) {
                return KIN_ENONFINITE;
            }
        }
        return KIN_OK;
    }
    return KIN_EINVAL;
}

static double segment_of(const kin_schedule *s, double t)
{
    return s->type == KIN_SCHED_TABLE ? floor(t / s->dt) : 0.0;
}

/* Joint j of a sines schedule at t, given sin and cos of its argument omega t + phase_j. */
static void sine_joint(const kin_schedule *s, int32_t j, double t, double sn, double cs,
                       double *phi, double *dphi)
{
    phi[j] = s->offset[j] + s->rate[j] * t + s->amp[j] * sn;
    dphi[j] = s->rate[j] + s->amp[j] * s->omega * cs;
}

/* Evaluate the schedule; a table uses segment `seg` (its linear extension around it). */
static void schedule_at(const kin_schedule *s, double seg, double t, double *phi, double *dphi)
{
    const int32_t n = s->joints;
    if (s->type == KIN_SCHED_SINES) {
        for (int32_t j = 0; j < n; j++) {
            const double arg = s->omega * t + s->phase[j];
            sine_joint(s, j, t, sin(arg), cos(arg), phi, dphi);
        }
        return;
    }
    const double rows = (double)s->rows;
    int32_t r0, r1;
    int hold = 0;
    if (s->loop) {
        double m = fmod(seg, rows);
        if (m < 0.0) {
            m += rows;
        }
        r0 = (int32_t)m;
        if (r0 >= s->rows) {
            r0 = s->rows - 1;
        }
        r1 = r0 + 1 < s->rows ? r0 + 1 : 0;
    } else if (seg < 0.0) {
        r0 = r1 = 0;
        hold = 1;
    } else if (seg >= rows - 1.0) {
        r0 = r1 = s->rows - 1;
        hold = 1;
    } else {
        r0 = (int32_t)seg;
        r1 = r0 + 1;
    }
    const double *a = s->samples + (size_t)r0 * (size_t)n;
    const double *b = s->samples + (size_t)r1 * (size_t)n;
    const double frac = (t - seg * s->dt) / s->dt;
    for (int32_t j = 0; j < n; j++) {
        const double slope = hold ? 0.0 : (b[j] - a[j]) / s->dt;
        phi[j] = a[j] + (hold ? 0.0 : frac * (b[j] - a[j]));
        dphi[j] = slope;
    }
}

int kin_schedule_eval(const kin_schedule *s, double t, double *phi, double *dphi)
{
    if (s == NULL || phi == NULL || dphi == NULL || !isfinite(t)) {
        return KIN_EINVAL;
    }
    int rc = schedule_check(s, s->joints);
    if (rc != KIN_OK) {
        return rc;
    }
    schedule_at(s, segment_of(s, t), t, phi, dphi);
    return KIN_OK;
}

/* ---- joint-driven body motion ---- */

typedef struct {
    const kin_robot *rb;
    const kin_schedule *s;
    int32_t joints;
    double seg;
    double tscale;
    kin_stats *stats;
    int32_t active[3]; /* the last vertex of the friction problem: the next one's start */
    /* Sines: cos and sin of each joint's phase, so that one sin and cos of omega t serve
     * every joint (the addition theorem) instead of a pair per joint and evaluation. */
    double cos_phase[KIN_MAX_JOINTS], sin_phase[KIN_MAX_JOINTS];
    phase_table phase;
    /* Switches (joint_smooth): the active set last found at time probe_t of segment
     * probe_seg (probe_ok 0: none); the set at the start step_t of the step being tried
     * and the earliest time other_t one of its stages found another (other_set); the
     * warm start for a solve at warm_t, just past a switch. */
    int32_t probe_ok, step_ok;
    double probe_t, probe_seg, step_t, other_t, warm_t;
    int32_t probe_set[3], step_set[3], other_set[3], warm_set[3];
} joint_ctx;

/* Whether two active sets hold the same rows (in any order). */
static int same_set(const int32_t a[3], const int32_t b[3])
{
    int32_t found = 0;
    for (int32_t i = 0; i < 3; i++) {
        found += a[i] == b[0] || a[i] == b[1] || a[i] == b[2];
    }
    return found == 3;
}

static void copy_set(int32_t to[3], const int32_t from[3])
{
    to[0] = from[0];
    to[1] = from[1];
    to[2] = from[2];
}

static void joint_ctx_phases(joint_ctx *c)
{
    for (int32_t j = 0; c->s->type == KIN_SCHED_SINES && j < c->joints; j++) {
        c->cos_phase[j] = cos(c->s->phase[j]);
        c->sin_phase[j] = sin(c->s->phase[j]);
    }
}

/* The schedule at t in the right-hand side: schedule_at, with sines by the addition
 * theorem (equal to it within a few ulps of the angles). */
static void joint_schedule(const joint_ctx *c, double t, double *phi, double *dphi)
{
    const kin_schedule *s = c->s;
    if (s->type != KIN_SCHED_SINES) {
        schedule_at(s, c->seg, t, phi, dphi);
        return;
    }
    double sw, cw;
    phase_at(&c->phase, t, &sw, &cw);
    for (int32_t j = 0; j < c->joints; j++) {
        sine_joint(s, j, t, sw * c->cos_phase[j] + cw * c->sin_phase[j],
                   cw * c->cos_phase[j] - sw * c->sin_phase[j], phi, dphi);
    }
}

static int joint_rates(joint_ctx *c, double t, const double *pose, double *xi, double *slip,
                       double *rcond)
{
    double q[KIN_MAX_STATE], dphi[KIN_MAX_JOINTS];
    kin_wheel_rows w;
    q[0] = pose[0];
    q[1] = pose[1];
    q[2] = pose[2];
    joint_schedule(c, t, q + 3, dphi);
    kin_geom_rows_unchecked(c->rb, q, dphi, &w);
    if (t == c->warm_t) {
        copy_set(c->active, c->warm_set);
    }
    const int rc = kin_geom_solve(c->rb, &w, c->active, xi, slip, NULL, rcond);
    if (c->step_ok && t > c->step_t && t < c->other_t && !same_set(c->active, c->step_set)) {
        c->other_t = t; /* a stage of the step being tried met another set */
        copy_set(c->other_set, c->active);
    }
    if (*rcond < c->stats->min_rcond) {
        c->stats->min_rcond = *rcond;
    }
    return rc;
}

static double norm3(const double *v)
{
    return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/* Body velocity (and slip) at t, extrapolating in time near a singular configuration. */
static int joint_rates_robust(joint_ctx *c, double t, const double *pose, double *xi,
                              double *slip)
{
    double rcond;
    int rc = joint_rates(c, t, pose, xi, slip, &rcond);
    if (rc == KIN_OK && rcond >= RCOND_FALLBACK) {
        return KIN_OK;
    }
    if (rc != KIN_OK && rc != KIN_ESINGULAR) {
        return rc;
    }
    c->stats->fallbacks++;
    const int32_t wheels = kin_wheel_count(c->rb);
    static const double offsets[4] = {-2.0, -1.0, 1.0, 2.0};
    double e = FALLBACK_EPS * c->tscale;
    for (int32_t attempt = 0; attempt < FALLBACK_TRIES; attempt++, e *= 4.0) {
        double x[4][3], s[4][KIN_MAX_WHEELS];
        int ok = 1;
        for (int32_t k = 0; k < 4 && ok; k++) {
            rc = joint_rates(c, t + offsets[k] * e, pose, x[k], s[k], &rcond);
            ok = rc == KIN_OK && rcond >= RCOND_FALLBACK;
        }
        if (!ok) {
            continue;
        }
        double d1[3], d2[3], scale = 0.0;
        for (int32_t i = 0; i < 3; i++) {
            d1[i] = x[2][i] - x[1][i];
            d2[i] = x[3][i] - x[0][i];
            xi[i] = (4.0 * (x[1][i] + x[2][i]) - (x[0][i] + x[3][i])) / 6.0;
        }
        for (int32_t k = 0; k < 4; k++) {
            scale = fmax(scale, norm3(x[k]));
        }
        /* Smooth: |d1| ~ |d2| / 2 or less. Pole c / (t' - t): |d1| ~ 2 |d2|. */
        if (norm3(d1) > norm3(d2) && norm3(d1) > 1e-6 * scale) {
            c->stats->t_fail = t;
            return KIN_EINADMISSIBLE;
        }
        if (slip != NULL) {
            for (int32_t i = 0; i < wheels; i++) {
                slip[i] = (4.0 * (s[1][i] + s[2][i]) - (s[0][i] + s[3][i])) / 6.0;
            }
        }
        return KIN_OK;
    }
    c->stats->t_fail = t;
    return KIN_ESINGULAR;
}

/* ---- switches: where wheels pass between sticking and slipping ----
 *
 * The body velocity is that of the friction problem's optimal vertex, the point where
 * its three active rows (the wheel directions that stick) vanish: a smooth function of
 * the joints' angles and speeds while the active set stays. Where it changes the velocity
 * has a kink (another row passes through the vertex) or a jump (a stuck wheel's force
 * reaches its limit: an edge of equal power, whose ends the velocity leaps between).
 * Which set is optimal depends on the shape alone, not on the pose (the problem turns and
 * shifts with the body), so along a schedule the switches lie at fixed times, found
 * without the trajectory: a step whose end (or, once it failed, one of whose stages) has
 * another active set than its start ends just before the first switch, located by
 * regula falsi (Illinois) on a function that crosses zero there (switch_value),
 * bracketed by the active sets themselves. */

/* Where a switch is known to this (times the schedule's time scale): the hair the step
 * after it starts past it, crossed with one velocity, costs far less than the tolerance. */
#define SWITCH_TIME_TOL 1e-10
#define SWITCH_MAX_PROBES 64

/* The rows of the friction problem at time t (any pose will do: pose). */
static void joint_rows(const joint_ctx *c, double t, const double *pose, kin_wheel_rows *w)
{
    double q[KIN_MAX_STATE], dphi[KIN_MAX_JOINTS];
    q[0] = pose[0];
    q[1] = pose[1];
    q[2] = pose[2];
    joint_schedule(c, t, q + 3, dphi);
    kin_geom_rows_unchecked(c->rb, q, dphi, w);
}

/* The active set at t into set (warm-started from it), the rows in w; 0 where it is not
 * one well-conditioned vertex (then no switch is looked for). Counted as an evaluation:
 * it costs one. Where it is one, the count vertex tests of sets (kin_geom_vertex_tests)
 * into out and ok, from the same problem. */
static int joint_set_tests(joint_ctx *c, double t, const double *pose, kin_wheel_rows *w,
                           int32_t set[3], int32_t count, int32_t (*sets)[3],
                           double (*out)[3], int *ok)
{
    double rcond;
    c->stats->evals++;
    joint_rows(c, t, pose, w);
    return kin_geom_active_set_tests(c->rb, w, set, &rcond, count, sets, out, ok)
           && rcond >= RCOND_FALLBACK;
}

static int joint_set(joint_ctx *c, double t, const double *pose, kin_wheel_rows *w,
                     int32_t set[3])
{
    return joint_set_tests(c, t, pose, w, set, 0, NULL, NULL, NULL);
}

/* The row of b not in a when the two differ by one row; -1 otherwise. */
static int32_t entering_row(const int32_t a[3], const int32_t b[3])
{
    int32_t row = -1, count = 0;
    for (int32_t i = 0; i < 3; i++) {
        if (b[i] != a[0] && b[i] != a[1] && b[i] != a[2]) {
            row = b[i];
            count++;
        }
    }
    return count == 1 ? row : -1;
}

/* Whether the switch from sa (at a) to sb (at b) is a kink: the row that enters passes
 * through sa's vertex on the way (or two rows change at once, as where every wheel can
 * stick); otherwise a jump, where one of sa's multipliers reaches its limit. */
static int switch_is_kink(const joint_ctx *c, const double *pose, double a, double b,
                          const int32_t sa[3], const int32_t sb[3], kin_wheel_rows *w)
{
    const int32_t row = entering_row(sa, sb);
    double va[3], vb[3];
    if (row < 0) {
        return 1;
    }
    joint_rows(c, a, pose, w);
    const int ok = kin_geom_vertex_test(c->rb, w, sa, row, va);
    joint_rows(c, b, pose, w);
    return !(ok && kin_geom_vertex_test(c->rb, w, sa, row, vb)) || !(va[2] * vb[2] > 0.0);
}

/* A function of the rows that is < 0 before the switch from sa to sb and > 0 after,
 * smooth through it where it can be: a jump's, how far sa's certificate fails (exactly
 * what a solve warm-started from sa tests); a kink's, sa's power less sb's. From the
 * vertex tests of sa and (for a kink) sb there, v[0] and v[1] (kin_geom_vertex_tests);
 * NAN when a vertex is ill-conditioned. */
static double switch_of(double v[2][3], const int ok[2], int kink)
{
    if (!ok[0]) {
        return NAN;
    }
    if (!kink) {
        return v[0][1];
    }
    return ok[1] ? v[0][0] - v[1][0] : NAN;
}

/* The sets whose vertex tests switch_of needs: sa and sb, in sets; how many (a jump's: sa
 * alone). */
static int32_t switch_sets(const int32_t sa[3], const int32_t sb[3], int kink,
                           int32_t sets[2][3])
{
    copy_set(sets[0], sa);
    copy_set(sets[1], sb);
    return kink ? 2 : 1;
}

/* switch_of at the rows w. */
static double switch_value(const joint_ctx *c, const kin_wheel_rows *w, const int32_t sa[3],
                           const int32_t sb[3], int kink)
{
    int32_t sets[2][3];
    double v[2][3];
    int ok[2] = {0, 0};
    const int32_t count = switch_sets(sa, sb, kink, sets);
    (void)kin_geom_vertex_tests(c->rb, w, count, sets, v, ok);
    return switch_of(v, ok, kink);
}

/* The switch after a, where set sa holds, before b, where sb does: [a, b] narrowed to
 * under tol (on return sb is the set just after the switch); w is scratch. */
static void locate_switch(joint_ctx *c, const double *pose, double tol, double *a_io,
                          double *b_io, const int32_t sa[3], int32_t sb[3],
                          kin_wheel_rows *w)
{
    double a = *a_io, b = *b_io;
    int kink = switch_is_kink(c, pose, a, b, sa, sb, w);
    joint_rows(c, a, pose, w);
    double fa = switch_value(c, w, sa, sb, kink);
    joint_rows(c, b, pose, w);
    double fb = switch_value(c, w, sa, sb, kink);
    int32_t side = 0;
    for (int32_t probe = 0; probe < SWITCH_MAX_PROBES && b - a > tol; probe++) {
        double m = 0.5 * (a + b);
        if (fa < 0.0 && fb > 0.0) { /* false position, nudged past the end that moved last */
            m = b - fb * (b - a) / (fb - fa) + 0.5 * tol * (double)(-side);
        }
        m = fmin(fmax(m, a + 0.25 * tol), b - 0.25 * tol);
        int32_t sm[3], sets[2][3];
        double v[2][3];
        int ok[2] = {0, 0};
        const int32_t count = switch_sets(sa, sb, kink, sets);
        copy_set(sm, sa);
        if (!joint_set_tests(c, m, pose, w, sm, count, sets, v, ok)) {
            /* A degenerate vertex: more rows than three through it, as at the switch
             * itself (where all wheels can stick at once, the sets on either side
             * differ by two rows): m is on it, to the vertex's tolerance. */
            a = fmax(a, m - 0.5 * tol);
            b = fmin(b, m + 0.5 * tol);
            break;
        }
        if (same_set(sm, sa)) {
            a = m;
            fa = switch_of(v, ok, kink);
            fb = side < 0 ? 0.5 * fb : fb; /* Illinois: the end that stays weighs less */
            side = -1;
        } else if (same_set(sm, sb)) {
            b = m;
            fb = switch_of(v, ok, kink);
            fa = side > 0 ? 0.5 * fa : fa;
            side = 1;
        } else { /* another switch comes first: aim at that one */
            b = m;
            copy_set(sb, sm);
            kink = switch_is_kink(c, pose, a, b, sa, sb, w);
            joint_rows(c, a, pose, w);
            fa = switch_value(c, w, sa, sb, kink);
            joint_rows(c, b, pose, w);
            fb = switch_value(c, w, sa, sb, kink);
            side = 0;
        }
    }
    *a_io = a;
    *b_io = b;
}

static int joint_smooth(void *ctx, double t, const double *y, double t_end, double *t_piece,
                        double *t_resume)
{
    joint_ctx *c = (joint_ctx *)ctx;
    kin_wheel_rows w;
    int32_t sa[3], sb[3];
    *t_piece = *t_resume = t_end;
    copy_set(sa, c->active);
    const int known = c->probe_ok && c->probe_t == t && c->probe_seg == c->seg;
    if (known) {
        copy_set(sa, c->probe_set);
    } else if (!joint_set(c, t, y, &w, sa)) {
        c->step_ok = 0;
        return KIN_OK;
    }
    /* Where the last try from t met another set (a stage): it failed across a switch
     * that the sets at its ends did not show (one there and back). */
    double b = t_end;
    const int seen = c->step_ok && c->step_t == t && c->other_t > t && c->other_t < t_end;
    if (seen) {
        b = c->other_t;
        copy_set(sb, c->other_set);
    } else {
        copy_set(sb, sa);
        c->probe_ok = joint_set(c, t_end, y, &w, sb);
        c->probe_t = t_end;
        c->probe_seg = c->seg;
        copy_set(c->probe_set, sb);
    }
    c->step_ok = 1;
    c->step_t = t;
    c->other_t = INFINITY;
    copy_set(c->step_set, sa);
    if ((!seen && !c->probe_ok) || same_set(sa, sb)) {
        return KIN_OK;
    }
    double a = t;
    locate_switch(c, y, SWITCH_TIME_TOL * c->tscale, &a, &b, sa, sb, &w);
    if (!(a > t)) {
        return KIN_OK;
    }
    *t_piece = a;
    *t_resume = b;
    copy_set(c->active, sa); /* the step's stages, up to a: warm start on sa's side */
    c->warm_t = b;           /* and the first solve after the switch on sb's */
    copy_set(c->warm_set, sb);
    c->probe_ok = 1;
    c->probe_t = b;
    c->probe_seg = c->seg;
    copy_set(c->probe_set, sb);
    return KIN_OK;
}

static int joint_rhs(void *ctx, double t, const double *y, double *dy)
{
    return joint_rates_robust((joint_ctx *)ctx, t, y, dy, NULL);
}

static void joint_times(void *ctx, const double *t, int32_t count)
{
    phase_fill(&((joint_ctx *)ctx)->phase, t, count);
}

/* Whether the friction problem has more rows than the three of a vertex (else its active
 * set never changes, and there are no kinks to look for). */
static int switches(const kin_robot *rb)
{
    int32_t rows = 0;
    for (int32_t i = 0; i < kin_wheel_count(rb); i++) {
        rows += (rb->lateral[i] > 0.0) + (rb->rolling[i] > 0.0);
    }
    return rows > 3;
}

static int check_span(double t0, double t1, int32_t n_out, const double *out)
{
    if (out == NULL || n_out < 2 || !isfinite(t0) || !isfinite(t1) || !(t1 >= t0)) {
        return KIN_EINVAL;
    }
    return KIN_OK;
}

static void stats_start(kin_stats *st, double t0)
{
    st->steps = st->rejected = st->evals = st->fallbacks = 0;
    st->min_rcond = 1.0;
    st->t_fail = t0;
}

/* The whole state of a table schedule's integration at a knot, where the integrator
 * has just landed and is about to start the next segment afresh (kin_ode_reset): the
 * pose, the ODE's step controller, the friction problem's warm start and the counters.
 * A schedule whose rows agree with another's up to a knot's row continues from that
 * knot exactly as it would have run from the start. */
typedef struct {
    int32_t valid;
    double y[3];
    double t;
    double seg;
    double h;
    double log_err_prev;
    int32_t budget;
    int32_t active[3];
    kin_stats stats;
} knot_state;

/* Knots recorded for a batch's first schedule: a plan's loops have 25 rows (on the stack:
 * a few kilobytes). */
#define BATCH_KNOTS 64

static int integrate_joints(const kin_robot *rb, const kin_schedule *s, const double *pose0,
                            double t0, double t1, int32_t n_out, const kin_options *opt,
                            double *out, double *slip, kin_stats *stats, knot_state *record,
                            int32_t record_n, const knot_state *resume)
{
    kin_stats local;
    kin_stats *st = stats != NULL ? stats : &local;
    int32_t joints;
    int rc = kin_check_robot(rb, &joints);
    if (rc != KIN_OK) {
        return rc;
    }
    if (pose0 == NULL || (rc = check_span(t0, t1, n_out, out)) != KIN_OK
        || (rc = schedule_check(s, joints)) != KIN_OK) {
        return rc;
    }
    if (!isfinite(pose0[0]) || !isfinite(pose0[1]) || !isfinite(pose0[2])) {
        return KIN_ENONFINITE;
    }
    stats_start(st, t0);
    joint_ctx c = {rb, s, joints, segment_of(s, t0), 1.0, st, {-1, -1, -1},
                   {0.0}, {0.0}, PHASE_ZERO, 0, 0, 0.0, 0.0, 0.0, INFINITY, NAN,
                   {-1, -1, -1}, {-1, -1, -1}, {-1, -1, -1}, {-1, -1, -1}};
    joint_ctx_phases(&c);
    c.phase.omega = s->omega;
    if (s->type == KIN_SCHED_TABLE) {
        c.tscale = s->dt;
    } else if (s->omega != 0.0) {
        c.tscale = TWO_PI / fabs(s->omega);
    }
    kin_ode ode;
    if ((rc = kin_ode_init(&ode, 3, joint_rhs, &c, opt, st, t1 - t0)) != KIN_OK) {
        return rc;
    }
    if (s->type == KIN_SCHED_SINES) {
        ode.times = joint_times;
    }
    if (switches(rb) && opt->method == KIN_DOP853) {
        /* DOPRI5 keeps stepping across the switches: the planners' and predictors'
         * results, and what their tests hold them to, rest on its step sequence. */
        ode.smooth = joint_smooth;
    }
    const int32_t width = 3 + joints;
    const int32_t wheels = kin_wheel_count(rb);
    double y[3] = {pose0[0], pose0[1], pose0[2]};
    double t = t0;
    for (int32_t k = 0; k < n_out; k++) {
        const double tk = k == n_out - 1 ? t1 : t0 + (t1 - t0) * (double)k / (double)(n_out - 1);
        if (k == 1 && resume != NULL) {
            /* continue from the knot, as the run that recorded it did */
            for (int32_t i = 0; i < 3; i++) {
                y[i] = resume->y[i];
                c.active[i] = resume->active[i];
            }
            t = resume->t;
            c.seg = resume->seg;
            ode.h = resume->h;
            ode.log_err_prev = resume->log_err_prev;
            ode.budget = resume->budget;
            ode.have_k1 = 0;
            *st = resume->stats;
        }
        while (t < tk) {
            double seg = segment_of(s, t), end = tk;
            int on_knot = 0;
            if (s->type == KIN_SCHED_TABLE) {
                double knot = (seg + 1.0) * s->dt;
                if (knot - t <= 1e-12 * s->dt) { /* t sits on a knot: rounding put it left */
                    seg += 1.0;
                    knot = (seg + 1.0) * s->dt;
                }
                if (knot < end) {
                    end = knot;
                    on_knot = 1;
                }
            }
            if (seg != c.seg) {
                c.seg = seg;
                kin_ode_reset(&ode);
            }
            if ((rc = kin_ode_advance(&ode, y, t, end)) != KIN_OK) {
                return rc;
            }
            t = end;
            const double index = seg + 1.0;
            if (on_knot && record != NULL && index >= 0.0 && index < (double)record_n) {
                knot_state *r = record + (int32_t)index;
                for (int32_t i = 0; i < 3; i++) {
                    r->y[i] = y[i];
                    r->active[i] = c.active[i];
                }
                r->t = t;
                r->seg = c.seg;
                r->h = ode.h;
                r->log_err_prev = ode.log_err_prev;
                r->budget = ode.budget;
                r->stats = *st;
                r->valid = 1;
            }
        }
        double *row = out + (size_t)k * (size_t)width;
        double dphi[KIN_MAX_JOINTS], xi[3];
        row[0] = y[0];
        row[1] = y[1];
        row[2] = y[2];
        schedule_at(s, c.seg, tk, row + 3, dphi);
        if (slip != NULL) {
            rc = joint_rates_robust(&c, tk, y, xi, slip + (size_t)k * (size_t)wheels);
            if (rc != KIN_OK) {
                return rc;
            }
        }
    }
    return KIN_OK;
}

int kin_integrate_joints(const kin_robot *rb, const kin_schedule *s, const double *pose0,
                         double t0, double t1, int32_t n_out, const kin_options *opt,
                         double *out, double *slip, kin_stats *stats)
{
    return integrate_joints(rb, s, pose0, t0, t1, n_out, opt, out, slip, stats, NULL, 0, NULL);
}

/* Whether the batch's schedule k can continue from the first one's knots: both tables
 * of the same shape, timing and ends, integrated start to end in one span. */
static int shares_knots(const kin_schedule *first, const kin_schedule *k, int32_t n_out)
{
    return n_out == 2 && first->type == KIN_SCHED_TABLE && k->type == KIN_SCHED_TABLE
           && !first->loop && !k->loop && first->rows == k->rows && first->joints == k->joints
           && first->dt == k->dt && first->samples != NULL && k->samples != NULL;
}

/* The knot schedule k continues from: the last one before the first row it changes
 * (the segment that ends on that row is the first to differ); NULL if none is recorded. */
static const knot_state *resume_knot(const kin_schedule *first, const kin_schedule *k,
                                     const knot_state *knots)
{
    const int32_t n = k->joints;
    int32_t row = 0;
    while (row < k->rows) {
        const double *a = first->samples + (size_t)row * (size_t)n;
        const double *b = k->samples + (size_t)row * (size_t)n;
        int same = 1;
        for (int32_t j = 0; j < n && same; j++) {
            /* bit for bit: -0.0 and 0.0 differ in what they may produce downstream */
            same = memcmp(&a[j], &b[j], sizeof(double)) == 0;
        }
        if (!same) {
            break;
        }
        row++;
    }
    int32_t knot = row - 1; /* the knot at the start of the first segment that differs */
    if (knot > k->rows - 2) {
        knot = k->rows - 2; /* the same rows: the last knot before the end */
    }
    if (knot < 1 || knot >= BATCH_KNOTS || !knots[knot].valid) {
        return NULL;
    }
    return knots + knot;
}

int kin_integrate_joints_batch(const kin_robot *rb, const kin_schedule *s, int32_t count,
                               const double *pose0, double t0, double t1, int32_t n_out,
                               const kin_options *opt, double *out, int32_t *status,
                               kin_stats *stats)
{
    int32_t joints;
    int rc = kin_check_robot(rb, &joints);
    if (rc != KIN_OK) {
        return rc;
    }
    if (count < 0 || (count > 0 && (s == NULL || status == NULL))) {
        return KIN_EINVAL;
    }
    if ((rc = check_span(t0, t1, n_out, out)) != KIN_OK) {
        return rc;
    }
    const size_t rows = (size_t)n_out * (size_t)(3 + joints);
    /* Schedules that differ from the first only from some row on (a search's trials of
     * one frame each) continue from the first one's state at the knot before that row:
     * the same arithmetic as from the start, without integrating the same rows again. */
    knot_state knots[BATCH_KNOTS];
    for (int32_t i = 0; i < BATCH_KNOTS; i++) {
        knots[i].valid = 0;
    }
    int first = KIN_OK;
    for (int32_t k = 0; k < count; k++) {
        const int shared = k > 0 && shares_knots(s, s + k, n_out);
        const knot_state *resume = shared ? resume_knot(s, s + k, knots) : NULL;
        status[k] = integrate_joints(rb, s + k, pose0, t0, t1, n_out, opt,
                                     out + (size_t)k * rows, NULL,
                                     stats != NULL ? stats + k : NULL,
                                     k == 0 ? knots : NULL, k == 0 ? BATCH_KNOTS : 0, resume);
        if (first == KIN_OK) {
            first = status[k];
        }
    }
    return first;
}

/* ---- field-driven systems ---- */

typedef struct {
    const kin_robot *rb;
    const kin_inputs *u;
    int32_t inputs;
    double corners[9];
    phase_table phase;
} field_ctx;

/* The inputs u(t). */
static inline __attribute__((always_inline)) void field_inputs(const field_ctx *c, double t,
                                                               double *u)
{
    double sn, cs;
    phase_at(&c->phase, t, &sn, &cs);
    const double sn2 = 2.0 * sn * cs, cs2 = cs * cs - sn * sn;
    for (int32_t i = 0; i < c->inputs; i++) {
        u[i] = c->u->c[i] + c->u->a[i] * sn + c->u->b[i] * cs + c->u->a2[i] * sn2
               + c->u->b2[i] * cs2;
    }
}

static int field_rhs(void *ctx, double t, const double *y, double *dy)
{
    const field_ctx *c = (const field_ctx *)ctx;
    double u[KIN_MAX_INPUTS];
    field_inputs(c, t, u);
    return kin_fields_velocity_unchecked(c->rb, c->corners, c->u->form, y, u, dy);
}

#if KIN_TRIG_BLOCK_CODE
/* The trident's DOP853 step with its velocity and the velocity's sines inlined, compiled
 * for x86-64-v3 with fused multiply-adds (where kin_trig_block_ok()): an evaluation is a
 * chain of dependent operations (the stage's state, its angles, their sines, the
 * velocity, the next stage), and inlined, wider and fused it is about a fifth shorter
 * (the trident benchmark's 10 s trajectory, timed in C alone: 66 us to 52). The same
 * method and steps as kin_ode.c's; the last bits differ (fused roundings). */
#define FAST_STEP __attribute__((target("arch=x86-64-v3"), optimize("fp-contract=fast")))

/* A trident velocity from kin_gen.h, with the sines it is to use. */
typedef void (*trident_velocity_fn)(kin_sincos_fn sincos, double r, double l,
                                    const double *alpha, const double *q, const double *u,
                                    double *out);

static inline __attribute__((always_inline)) int trident_rhs(const field_ctx *c, double t,
                                                             const double *y, double *dy,
                                                             trident_velocity_fn velocity)
{
    double u[KIN_MAX_INPUTS];
    field_inputs(c, t, u);
    velocity(kin_sincos_block, c->rb->r, c->rb->l, c->corners, y, u, dy);
    return KIN_OK;
}

static inline __attribute__((always_inline)) int trident_body_rhs(void *ctx, double t,
                                                                  const double *y, double *dy)
{
    return trident_rhs((const field_ctx *)ctx, t, y, dy, kin_gen_trident_body_v_by);
}

static inline __attribute__((always_inline)) int trident_world_rhs(void *ctx, double t,
                                                                   const double *y, double *dy)
{
    return trident_rhs((const field_ctx *)ctx, t, y, dy, kin_gen_trident_world_v_by);
}

FAST_STEP static int trident_body_step(kin_ode *ode, const double *y, double t, double h,
                                       double *y1, double *k_end, double *e)
{
    return kin_dop853_step(ode, 6, trident_body_rhs, y, t, h, y1, k_end, e);
}

FAST_STEP static int trident_world_step(kin_ode *ode, const double *y, double t, double h,
                                        double *y1, double *k_end, double *e)
{
    return kin_dop853_step(ode, 6, trident_world_rhs, y, t, h, y1, k_end, e);
}
#endif

/* The step with the model inlined, where there is one for this robot, form and CPU. */
static kin_step_fn field_step(const kin_robot *rb, int32_t form, int32_t n)
{
#if KIN_TRIG_BLOCK_CODE
    if (rb->kind == KIN_TRIDENT && n == 6 && kin_trig_block_ok()) {
        return form == KIN_FORM_BODY ? trident_body_step : trident_world_step;
    }
#else
    (void)rb;
    (void)form;
    (void)n;
#endif
    return NULL;
}

static void field_times(void *ctx, const double *t, int32_t count)
{
    phase_fill(&((field_ctx *)ctx)->phase, t, count);
}

int kin_integrate_fields(const kin_robot *rb, const kin_inputs *u, const double *q0,
                         double t0, double t1, int32_t n_out, const kin_options *opt,
                         double *out, kin_stats *stats)
{
    kin_stats local;
    kin_stats *st = stats != NULL ? stats : &local;
    int32_t fields, inputs, joints;
    int rc = kin_field_count(rb, &fields, &inputs);
    if (rc != KIN_OK || (rc = kin_check_robot(rb, &joints)) != KIN_OK) {
        return rc;
    }
    if (u == NULL || q0 == NULL || (rc = check_span(t0, t1, n_out, out)) != KIN_OK) {
        return rc == KIN_OK ? KIN_EINVAL : rc;
    }
    if (u->form != KIN_FORM_BODY && u->form != KIN_FORM_WORLD) {
        return KIN_EINVAL;
    }
    if (!isfinite(u->omega)) {
        return KIN_ENONFINITE;
    }
    for (int32_t i = 0; i < inputs; i++) {
        if (!isfinite(u->c[i]) || !isfinite(u->a[i]) || !isfinite(u->b[i])
            || !isfinite(u->a2[i]) || !isfinite(u->b2[i])) {
            return KIN_ENONFINITE;
        }
    }
    const int32_t n = 3 + joints;
    for (int32_t i = 0; i < n; i++) {
        if (!isfinite(q0[i])) {
            return KIN_ENONFINITE;
        }
    }
    stats_start(st, t0);
    field_ctx c = {rb, u, inputs, {0.0}, PHASE_ZERO};
    c.phase.omega = u->omega;
    kin_fields_corners(rb, c.corners);
    kin_ode ode;
    if ((rc = kin_ode_init(&ode, n, field_rhs, &c, opt, st, t1 - t0)) != KIN_OK) {
        return rc;
    }
    ode.times = field_times;
    ode.step = field_step(rb, u->form, n);
    double y[KIN_MAX_STATE];
    for (int32_t i = 0; i < n; i++) {
        y[i] = q0[i];
    }
    double t = t0;
    for (int32_t k = 0; k < n_out; k++) {
        const double tk = k == n_out - 1 ? t1 : t0 + (t1 - t0) * (double)k / (double)(n_out - 1);
        if (tk > t) {
            if ((rc = kin_ode_advance(&ode, y, t, tk)) != KIN_OK) {
                return rc;
            }
            t = tk;
        }
        for (int32_t i = 0; i < n; i++) {
            out[(size_t)k * (size_t)n + (size_t)i] = y[i];
        }
    }
    return KIN_OK;
}
