/* Quasi-static Coulomb friction of the wheels: the body velocity the wheels allow
 * (docs/models.md, "The general model").
 *
 * Given the joint velocities, every wheel's speed across (n.v) and along (t.v) its
 * rolling direction is affine in the body velocity. Friction across a wheel is Coulomb,
 * lateral_i = mu N_i at full slip; along it the wheel resists rolling with
 * rolling_i = C_rr N_i (+ the axle's friction referred to the rim). Without inertia the
 * body moves so that the friction forces balance, which for Coulomb friction is the
 * body velocity minimising the dissipated power (the maximum-dissipation principle):
 *
 *     minimise  f(x) = sum_k w_k |a_k . x - b_k|     over x = (dx, dy, L dtheta),
 *
 * two rows per wheel (normal: weight lateral_i; tangential: weight rolling_i). This is a
 * weighted L1 fit in three unknowns. Its minimum is at a vertex, where three rows
 * (the active set S) vanish: those are the wheels' directions that stick. The solver
 * is the simplex method for L1 fits (Barrodale and Roberts' idea, in three unknowns):
 * at a vertex it computes the friction multipliers of the active rows, which certify
 * optimality when they lie in [-1, 1] (the sticking directions need no more force than
 * friction gives); otherwise it releases the row whose multiplier is out of range and
 * moves along the edge that opens to the minimum of the convex, piecewise linear
 * objective on it, where another row enters. Each pivot lowers f, so it ends exactly,
 * at a vertex; a warm start from the previous call's active set (the integrator's) makes
 * most calls a single certificate. Degenerate vertices, which could cycle (a joint at
 * rest for a frame leaves the wheels behind it all sticking at xi = 0), end in a check
 * of every vertex (exact, slower) as soon as an active set comes round again, or after
 * a pivot budget. */
#include "kin_core.h"
#include "kin_geom.h"

#include <math.h>

#define QS_MAX_ROWS (2 * KIN_MAX_WHEELS)
#define QS_MAX_PIVOTS 48
/* A vertex whose 3x3 system is conditioned worse than this is not used. */
#define QS_RCOND_MIN 1e-12
/* Multipliers this far past 1 still certify (rounding). */
#define QS_CERT_TOL 1e-9
/* Where the minimum is an edge rather than a point (concurrent axles whose rolling
 * resistances balance) the answer is the centre of the minima (centre_of_minima).
 * The centre of a set of minima: vertices conditioned at least this well, whose power is
 * within this tolerance of the least (relative to the problem's power), as far apart
 * (relative to its speeds) to count as distinct, at most this many. */
#define QS_CENTRE_RCOND 1e-6
#define QS_CENTRE_TOL 1e-12
#define QS_CENTRE_APART 1e-9
#define QS_MAX_CENTRE 16
/* sole_minimum: how many times the farthest a vertex within the slack may lie from x
 * must fit into apart (2 would do: such vertices then lie within apart of one another;
 * twice that, for rounding), and the rounding of the balance of forces allowed for
 * (relative to its terms; at a conditioning of QS_CENTRE_RCOND it is some 1e-10). */
#define QS_SOLE_MARGIN 4.0
#define QS_SOLE_ROUNDING 1e-8
/* Relative size below which a residual counts as zero (the row passes through x). */
#define QS_ZERO_TOL 1e-12

typedef struct {
    int32_t rows;
    int32_t id[QS_MAX_ROWS]; /* 2 wheel (normal) or 2 wheel + 1 (tangential) */
    double a[QS_MAX_ROWS][3];
    double b[QS_MAX_ROWS];
    double w[QS_MAX_ROWS];
    double amax[QS_MAX_ROWS]; /* absmax3(a[k]), needed at every vertex */
} qs_problem;

/* fmax(a, b) (a NaN yields the other), inline: without -ffinite-math-only the compiler
 * calls libm's fmax, and the solver's vertex test takes some 10 % of an integration's
 * time in those calls. */
static inline double qs_max(double a, double b)
{
    return (b > a || a != a) ? b : a;
}

static double absmax3(const double *v)
{
    return qs_max(fabs(v[0]), qs_max(fabs(v[1]), fabs(v[2])));
}

/* The rows, the rotation column scaled by len (so all three unknowns are speeds). */
static void qs_rows(const kin_robot *rb, const kin_wheel_rows *w, double len, qs_problem *p)
{
    const double inv_len = 1.0 / len;
    p->rows = 0;
    for (int32_t i = 0; i < w->count; i++) {
        if (rb->lateral[i] > 0.0) {
            const int32_t k = p->rows++;
            p->id[k] = 2 * i;
            p->a[k][0] = -w->ty[i];
            p->a[k][1] = w->tx[i];
            p->a[k][2] = w->n_theta[i] * inv_len;
            p->b[k] = -w->n_joint[i];
            p->w[k] = rb->lateral[i];
            p->amax[k] = absmax3(p->a[k]);
        }
        if (rb->rolling[i] > 0.0) {
            const int32_t k = p->rows++;
            p->id[k] = 2 * i + 1;
            p->a[k][0] = w->tx[i];
            p->a[k][1] = w->ty[i];
            p->a[k][2] = w->t_theta[i] * inv_len;
            p->b[k] = -w->t_joint[i];
            p->w[k] = rb->rolling[i];
            p->amax[k] = absmax3(p->a[k]);
        }
    }
}

/* Inverse of the 3x3 matrix whose rows are a[s[0]], a[s[1]], a[s[2]], into m (column j
 * of m is the direction moving row s[j]'s residual by 1 and the others' not at all);
 * returns 0 when singular. */
static int inverse3_only(const qs_problem *p, const int32_t s[3], double m[3][3])
{
    const double *r0 = p->a[s[0]], *r1 = p->a[s[1]], *r2 = p->a[s[2]];
    const double c00 = r1[1] * r2[2] - r1[2] * r2[1];
    const double c01 = r1[2] * r2[0] - r1[0] * r2[2];
    const double c02 = r1[0] * r2[1] - r1[1] * r2[0];
    const double det = r0[0] * c00 + r0[1] * c01 + r0[2] * c02;
    if (!(fabs(det) > 0.0) || !isfinite(det)) {
        return 0;
    }
    const double id = 1.0 / det;
    m[0][0] = c00 * id;
    m[1][0] = c01 * id;
    m[2][0] = c02 * id;
    m[0][1] = (r0[2] * r2[1] - r0[1] * r2[2]) * id;
    m[1][1] = (r0[0] * r2[2] - r0[2] * r2[0]) * id;
    m[2][1] = (r0[1] * r2[0] - r0[0] * r2[1]) * id;
    m[0][2] = (r0[1] * r1[2] - r0[2] * r1[1]) * id;
    m[1][2] = (r0[2] * r1[0] - r0[0] * r1[2]) * id;
    m[2][2] = (r0[0] * r1[1] - r0[1] * r1[0]) * id;
    return 1;
}

/* The reciprocal 1-norm condition number of the rows s, m their inverse. */
static double rcond3(const qs_problem *p, const int32_t s[3], double m[3][3])
{
    const double *r0 = p->a[s[0]], *r1 = p->a[s[1]], *r2 = p->a[s[2]];
    double norm_a = 0.0, norm_m = 0.0;
    for (int32_t j = 0; j < 3; j++) {
        norm_a = qs_max(norm_a, fabs(r0[j]) + fabs(r1[j]) + fabs(r2[j]));
        norm_m = qs_max(norm_m, fabs(m[0][j]) + fabs(m[1][j]) + fabs(m[2][j]));
    }
    return 1.0 / (norm_a * norm_m);
}

/* inverse3_only, returning the reciprocal condition number (0 when singular). */
static double inverse3(const qs_problem *p, const int32_t s[3], double m[3][3])
{
    return inverse3_only(p, s, m) ? rcond3(p, s, m) : 0.0;
}

/* The power at x, summed row by row; once the sum passes limit the rest is left out
 * (its terms are not negative, so the whole is above limit too). */
static double objective_upto(const qs_problem *p, const double x[3], double limit)
{
    double f = 0.0;
    for (int32_t k = 0; k < p->rows && !(f > limit); k++) {
        f += p->w[k] * fabs(p->a[k][0] * x[0] + p->a[k][1] * x[1] + p->a[k][2] * x[2] - p->b[k]);
    }
    return f;
}

static double objective(const qs_problem *p, const double x[3])
{
    return objective_upto(p, x, INFINITY);
}

/* The vertex of active set s: x, every row's residual r (exactly 0 on s), the zero
 * tolerance, and each row's friction multiplier y in w y (sign of the residual off s;
 * from the balance of forces on s). Returns the largest |y| on s, and its position in
 * *worst; *through counts the rows off s that pass through the vertex too (a degenerate
 * vertex). */
static double vertex(const qs_problem *p, const int32_t s[3], double m[3][3], double x[3],
                     double *r, double *y, double *tol, int32_t *worst, int32_t *through)
{
    /* In locals, and the rows of s as bits: r and y may alias nothing the loop reads,
     * but the compiler cannot know it and would reload x and tol at every row. */
    double v[3];
    for (int32_t i = 0; i < 3; i++) {
        v[i] = m[i][0] * p->b[s[0]] + m[i][1] * p->b[s[1]] + m[i][2] * p->b[s[2]];
        x[i] = v[i];
    }
    const double size = absmax3(v);
    double scale = 0.0;
    for (int32_t k = 0; k < p->rows; k++) {
        scale = qs_max(scale, fabs(p->b[k]) + p->amax[k] * size);
    }
    const double zero_tol = QS_ZERO_TOL * scale;
    *tol = zero_tol;
    const uint32_t on_s = (1u << s[0]) | (1u << s[1]) | (1u << s[2]);
    double g[3] = {0.0, 0.0, 0.0};
    int32_t zero = -3; /* the rows of s */
    for (int32_t k = 0; k < p->rows; k++) {
        const double *a = p->a[k];
        double rk = a[0] * v[0] + a[1] * v[1] + a[2] * v[2] - p->b[k];
        double yk = rk > zero_tol ? 1.0 : (rk < -zero_tol ? -1.0 : 0.0);
        if (on_s & (1u << k)) {
            rk = 0.0;
            yk = 0.0;
        }
        r[k] = rk;
        y[k] = yk;
        const double f = p->w[k] * yk;
        g[0] += f * a[0];
        g[1] += f * a[1];
        g[2] += f * a[2];
        zero += yk == 0.0;
    }
    *through = zero;
    /* sum_{j in s} w_j y_j a_j = -g: (w y)_s = -M^T g */
    double most = -1.0;
    for (int32_t j = 0; j < 3; j++) {
        const double z = -(m[0][j] * g[0] + m[1][j] * g[1] + m[2][j] * g[2]);
        y[s[j]] = z / p->w[s[j]];
        if (fabs(y[s[j]]) > most) {
            most = fabs(y[s[j]]);
            *worst = j;
        }
    }
    return most;
}

/* A first active set: rows in order of falling weight, each taken when independent of
 * those taken (its part orthogonal to them is not small). Returns 0 if the rows span
 * fewer than three dimensions. */
static int first_set(const qs_problem *p, int32_t s[3])
{
    double basis[3][3];
    int32_t taken = 0;
    uint32_t used = 0;
    while (taken < 3) {
        int32_t best = -1;
        for (int32_t k = 0; k < p->rows; k++) {
            if (!(used & (1u << k)) && (best < 0 || p->w[k] > p->w[best])) {
                best = k;
            }
        }
        if (best < 0) {
            return 0;
        }
        used |= 1u << best;
        double v[3] = {p->a[best][0], p->a[best][1], p->a[best][2]};
        const double n0 = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        for (int32_t i = 0; i < taken; i++) {
            const double d = v[0] * basis[i][0] + v[1] * basis[i][1] + v[2] * basis[i][2];
            v[0] -= d * basis[i][0];
            v[1] -= d * basis[i][1];
            v[2] -= d * basis[i][2];
        }
        const double n1 = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        if (n1 > 1e-6 * n0) {
            basis[taken][0] = v[0] / n1;
            basis[taken][1] = v[1] / n1;
            basis[taken][2] = v[2] / n1;
            s[taken++] = best;
        }
    }
    return 1;
}

/* Every vertex whose three rows are conditioned at least rcond_min and whose power is
 * at most limit(ctx), in order, handed to visit with its rows, its point and its power.
 * A vertex of more power is passed over before its conditioning is computed and before
 * the rest of its power is summed (a visitor does nothing with one). */
typedef void (*qs_visit)(void *ctx, const qs_problem *p, const int32_t t[3], const double x[3],
                         double f);
typedef double (*qs_limit)(const void *ctx);

static void each_vertex(const qs_problem *p, double rcond_min, qs_limit limit, qs_visit visit,
                        void *ctx)
{
    double m[3][3], x[3];
    for (int32_t i = 0; i < p->rows; i++) {
        for (int32_t j = i + 1; j < p->rows; j++) {
            for (int32_t k = j + 1; k < p->rows; k++) {
                const int32_t t[3] = {i, j, k};
                if (!inverse3_only(p, t, m)) {
                    continue;
                }
                for (int32_t c = 0; c < 3; c++) {
                    x[c] = m[c][0] * p->b[i] + m[c][1] * p->b[j] + m[c][2] * p->b[k];
                }
                const double most = limit(ctx);
                const double f = objective_upto(p, x, most);
                if (f > most || rcond3(p, t, m) < rcond_min) {
                    continue;
                }
                visit(ctx, p, t, x, f);
            }
        }
    }
}

typedef struct {
    double best;
    int32_t s[3];
    int found;
} qs_best;

static double best_limit(const void *ctx)
{
    return ((const qs_best *)ctx)->best;
}

static void keep_best(void *ctx, const qs_problem *p, const int32_t t[3], const double x[3],
                      double f)
{
    qs_best *b = (qs_best *)ctx;
    (void)p;
    (void)x;
    if (f < b->best) {
        b->best = f;
        b->s[0] = t[0];
        b->s[1] = t[1];
        b->s[2] = t[2];
        b->found = 1;
    }
}

/* Every vertex, the best kept: the exact answer when pivoting could cycle. */
static int enumerate(const qs_problem *p, int32_t s[3])
{
    qs_best b = {INFINITY, {0, 0, 0}, 0};
    each_vertex(p, QS_RCOND_MIN, best_limit, keep_best, &b);
    if (b.found) {
        s[0] = b.s[0];
        s[1] = b.s[1];
        s[2] = b.s[2];
    }
    return b.found;
}

/* The distinct vertices whose power is within slack of the least seen. */
typedef struct {
    double f_min, slack, apart;
    int32_t count;
    double found[QS_MAX_CENTRE][3];
} qs_minima;

static double minima_limit(const void *ctx)
{
    const qs_minima *c = (const qs_minima *)ctx;
    return c->f_min + c->slack;
}

static void collect_minima(void *ctx, const qs_problem *p, const int32_t t[3],
                           const double x[3], double f)
{
    qs_minima *c = (qs_minima *)ctx;
    (void)p;
    (void)t;
    if (f < c->f_min) {
        c->f_min = f;
    }
    if (f > c->f_min + c->slack || c->count == QS_MAX_CENTRE) {
        return;
    }
    for (int32_t n = 0; n < c->count; n++) {
        const double d[3] = {x[0] - c->found[n][0], x[1] - c->found[n][1],
                             x[2] - c->found[n][2]};
        if (absmax3(d) <= c->apart) {
            return;
        }
    }
    c->found[c->count][0] = x[0];
    c->found[c->count][1] = x[1];
    c->found[c->count][2] = x[2];
    c->count++;
}

/* The power within which a vertex counts as a minimum of the problem at x, and how far
 * apart two count as distinct (centre_of_minima): sizes of the speeds and of the power
 * (its terms' at x = 0), so that a minimum near zero power (nearly compatible wheels) is
 * judged on the problem's scale. */
static void centre_sizes(const qs_problem *p, const double x[3], double *slack, double *apart)
{
    double scale = absmax3(x), power = 0.0;
    for (int32_t k = 0; k < p->rows; k++) {
        scale = qs_max(scale, fabs(p->b[k]));
        power += p->w[k] * fabs(p->b[k]);
    }
    *slack = QS_CENTRE_TOL * power;
    *apart = QS_CENTRE_APART * scale;
}

/* Where the minimum is not a point. On concurrent axles whose rolling resistances
 * balance (four wheels of equal rolling resistance on an arc, as a gait table whose joints
 * are equal in ticks makes them: a weighted median of an even count) every point of an
 * edge of the polytope is a minimum, and its ends are degenerate vertices (more than three
 * rows through them). Which end a solve reaches then depends on rounding, and an
 * integrator cannot follow a body velocity jumping between the two. The model takes the
 * centre of the minima: the mean of the distinct minimising vertices, as the median of an
 * even count is the mean of the middle two. Only called at a degenerate vertex; where the
 * minimum is one point all its vertices coincide and x is left as it is. */
static void centre_of_minima(const qs_problem *p, double x[3])
{
    qs_minima c;
    c.f_min = objective(p, x);
    centre_sizes(p, x, &c.slack, &c.apart);
    c.count = 0;
    each_vertex(p, QS_CENTRE_RCOND, minima_limit, collect_minima, &c);
    /* A vertex kept before a lower minimum turned up is not a minimum: drop it. */
    double sum[3] = {0.0, 0.0, 0.0};
    int32_t kept = 0;
    for (int32_t n = 0; n < c.count; n++) {
        if (objective(p, c.found[n]) <= c.f_min + c.slack) {
            sum[0] += c.found[n][0];
            sum[1] += c.found[n][1];
            sum[2] += c.found[n][2];
            kept++;
        }
    }
    if (kept > 1) {
        x[0] = sum[0] / kept;
        x[1] = sum[1] / kept;
        x[2] = sum[2] / kept;
    }
}

/* Whether x, the certified vertex of s (inverse m, conditioning rcond, multipliers y,
 * zero tolerance tol), is provably the one minimum centre_of_minima would find, which then
 * leaves x as it is: at most one distinct vertex within its slack. By weak duality with
 * y, any point x' has at least sum_{j in s} w_j (1 - |y_j|) |r_j(x')| more power than x,
 * less the tol sum(w) that rows through x within tol may hide, and |x' - x| is at most
 * |M| max_j |r_j(x')|. So every vertex within slack of the least power lies within
 * (slack + tol sum(w)) / slope of x, slope = min_j w_j (1 - |y_j|) / |M|; when that is
 * under half of apart they all count as one (QS_SOLE_MARGIN asks for a quarter). The
 * slope is taken less a hundred times the rounding the balance of forces can carry at
 * this conditioning. */
static int sole_minimum(const qs_problem *p, const int32_t s[3], double m[3][3], double rcond,
                        const double *y, double tol, const double x[3])
{
    if (!(rcond >= QS_CENTRE_RCOND)) {
        return 0;
    }
    double firm = INFINITY, norm_m = 0.0, weight = 0.0, amax = 0.0;
    for (int32_t j = 0; j < 3; j++) {
        const double margin = p->w[s[j]] * (1.0 - fabs(y[s[j]]));
        if (!(margin > 0.0)) {
            return 0;
        }
        firm = margin < firm ? margin : firm;
        norm_m = qs_max(norm_m, fabs(m[j][0]) + fabs(m[j][1]) + fabs(m[j][2]));
    }
    for (int32_t k = 0; k < p->rows; k++) {
        weight += p->w[k];
        amax = qs_max(amax, p->amax[k]);
    }
    double slack, apart;
    centre_sizes(p, x, &slack, &apart);
    const double slope = firm / norm_m - QS_SOLE_ROUNDING * weight * amax;
    return slope > 0.0 && QS_SOLE_MARGIN * (slack + tol * weight) < slope * apart;
}

/* Whether the active set s is one of the first count of visited. */
static int seen(const int32_t visited[][3], int32_t count, const int32_t s[3])
{
    for (int32_t i = 0; i < count; i++) {
        if (visited[i][0] == s[0] && visited[i][1] == s[1] && visited[i][2] == s[2]) {
            return 1;
        }
    }
    return 0;
}

/* Minimise; s holds the active set (a warm start if valid), x the answer, y each row's
 * multiplier, *rcond the vertex's conditioning, *degenerate whether more than the three
 * rows of s pass through the answer (its active set is then not the only one). Returns 0
 * when the rows do not span three dimensions (the motion is not determined). */
static int qs_minimise(const qs_problem *p, int32_t s[3], double x[3], double *y, double *rcond,
                       int *degenerate)
{
    *degenerate = 0;
    double m[3][3], r[QS_MAX_ROWS], tol;
    int valid = s[0] >= 0 && s[1] >= 0 && s[2] >= 0 && s[0] < p->rows && s[1] < p->rows
                && s[2] < p->rows && s[0] != s[1] && s[1] != s[2] && s[0] != s[2];
    *rcond = valid ? inverse3(p, s, m) : 0.0;
    if (*rcond < QS_RCOND_MIN) {
        if (!first_set(p, s)) {
            return 0;
        }
        *rcond = inverse3(p, s, m);
    }
    /* The active sets visited: each pivot is a function of the (ordered) active set
     * alone, so meeting one again means a cycle that would run out the pivot budget and
     * end in enumerate; it goes there at once, to the same answer. */
    int32_t visited[QS_MAX_PIVOTS + 1][3];
    for (int32_t pivot = 0; pivot <= QS_MAX_PIVOTS; pivot++) {
        if (pivot > 0) {
            *rcond = inverse3(p, s, m); /* the first: the warm start's, just checked */
        }
        visited[pivot][0] = s[0];
        visited[pivot][1] = s[1];
        visited[pivot][2] = s[2];
        if (*rcond < QS_RCOND_MIN) {
            break;
        }
        int32_t j = 0, through = 0;
        const double most = vertex(p, s, m, x, r, y, &tol, &j, &through);
        if (most <= 1.0 + QS_CERT_TOL) {
            if (through > 0) {
                *degenerate = 1;
                if (!sole_minimum(p, s, m, *rcond, y, tol, x)) {
                    centre_of_minima(p, x);
                }
            }
            return 1;
        }
        if (pivot == QS_MAX_PIVOTS) {
            break;
        }
        /* Release row s[j] along D (moving its residual by sign(y)), where f falls at
         * the rate w (|y| - 1); find where the slope turns: that row enters. */
        const double sign = y[s[j]] > 0.0 ? 1.0 : -1.0;
        const double dir[3] = {sign * m[0][j], sign * m[1][j], sign * m[2][j]};
        const double dn = absmax3(dir);
        double slope = p->w[s[j]] * (1.0 - fabs(y[s[j]]));
        double bt[QS_MAX_ROWS], binc[QS_MAX_ROWS];
        int32_t brow[QS_MAX_ROWS], nb = 0;
        for (int32_t k = 0; k < p->rows; k++) {
            if (k == s[0] || k == s[1] || k == s[2]) {
                continue;
            }
            const double ad = p->a[k][0] * dir[0] + p->a[k][1] * dir[1] + p->a[k][2] * dir[2];
            if (!(fabs(ad) > 1e-12 * p->amax[k] * dn)) {
                continue;
            }
            if (fabs(r[k]) <= tol) {
                bt[nb] = 0.0;
                binc[nb] = p->w[k] * fabs(ad);
            } else {
                const double t = -r[k] / ad;
                if (!(t > 0.0)) {
                    continue;
                }
                bt[nb] = t;
                binc[nb] = 2.0 * p->w[k] * fabs(ad);
            }
            brow[nb++] = k;
        }
        int32_t enter = -1;
        while (nb > 0) {
            int32_t first = 0;
            for (int32_t i = 1; i < nb; i++) {
                if (bt[i] < bt[first]) {
                    first = i;
                }
            }
            slope += binc[first];
            if (slope >= 0.0) {
                enter = brow[first];
                break;
            }
            nb--;
            bt[first] = bt[nb];
            binc[first] = binc[nb];
            brow[first] = brow[nb];
        }
        if (enter < 0) {
            break; /* unbounded along the edge: cannot happen when the rows span R^3 */
        }
        s[j] = enter;
        if (seen(visited, pivot + 1, s)) {
            break;
        }
    }
    if (!enumerate(p, s)) {
        return 0;
    }
    *rcond = inverse3(p, s, m);
    int32_t j = 0, through = 0;
    (void)vertex(p, s, m, x, r, y, &tol, &j, &through);
    *degenerate = 1; /* pivoting cycled: the vertex is degenerate */
    if (!sole_minimum(p, s, m, *rcond, y, tol, x)) {
        centre_of_minima(p, x);
    }
    return 1;
}

/* The problem for the rows w: the rotation column scaled by L, the farthest wheel's
 * distance from the reference point (a speed like the others); returns L. */
static double qs_setup(const kin_robot *rb, const kin_wheel_rows *w, qs_problem *p,
                       int *at_rest)
{
    double len2 = rb->l * rb->l;
    *at_rest = 1;
    for (int32_t i = 0; i < w->count; i++) {
        len2 = qs_max(len2, w->n_theta[i] * w->n_theta[i] + w->t_theta[i] * w->t_theta[i]);
        *at_rest = *at_rest && w->n_joint[i] == 0.0 && w->t_joint[i] == 0.0;
    }
    const double len = sqrt(len2);
    qs_rows(rb, w, len, p);
    return len;
}

/* kin_geom_vertex_test on the problem p. */
static int vertex_test(const qs_problem *p, const int32_t s[3], int32_t row, double out[3])
{
    double m[3][3];
    if (s[0] < 0 || s[1] < 0 || s[2] < 0 || s[0] >= p->rows || s[1] >= p->rows
        || s[2] >= p->rows || inverse3(p, s, m) < QS_RCOND_MIN) {
        return 0;
    }
    double x[3], r[QS_MAX_ROWS], y[QS_MAX_ROWS], tol;
    int32_t worst, through;
    const double most = vertex(p, s, m, x, r, y, &tol, &worst, &through);
    out[0] = objective(p, x);
    out[1] = most - (1.0 + QS_CERT_TOL);
    out[2] = row >= 0 && row < p->rows ? r[row] : NAN;
    return isfinite(out[0] + out[1]);
}

static void vertex_tests(const qs_problem *p, int32_t count, int32_t (*sets)[3],
                         double (*out)[3], int *ok)
{
    for (int32_t i = 0; i < count; i++) {
        ok[i] = vertex_test(p, sets[i], -1, out[i]);
    }
}

int kin_geom_active_set_tests(const kin_robot *rb, const kin_wheel_rows *w, int32_t active[3],
                              double *rcond, int32_t count, int32_t (*sets)[3],
                              double (*out)[3], int *ok)
{
    qs_problem p;
    int at_rest, degenerate;
    (void)qs_setup(rb, w, &p, &at_rest);
    double x[3], y[QS_MAX_ROWS];
    *rcond = 0.0;
    if (!qs_minimise(&p, active, x, y, rcond, &degenerate) || !isfinite(x[0] + x[1] + x[2])
        || degenerate) {
        return 0;
    }
    vertex_tests(&p, count, sets, out, ok);
    return 1;
}

int kin_geom_active_set(const kin_robot *rb, const kin_wheel_rows *w, int32_t active[3],
                        double *rcond)
{
    return kin_geom_active_set_tests(rb, w, active, rcond, 0, NULL, NULL, NULL);
}

int kin_geom_vertex_tests(const kin_robot *rb, const kin_wheel_rows *w, int32_t count,
                          int32_t (*sets)[3], double (*out)[3], int *ok)
{
    qs_problem p;
    int at_rest;
    (void)qs_setup(rb, w, &p, &at_rest);
    vertex_tests(&p, count, sets, out, ok);
    return count > 0 && ok[0];
}

int kin_geom_vertex_test(const kin_robot *rb, const kin_wheel_rows *w, const int32_t s[3],
                         int32_t row, double out[3])
{
    qs_problem p;
    int at_rest;
    (void)qs_setup(rb, w, &p, &at_rest);
    return vertex_test(&p, s, row, out);
}

int kin_geom_solve(const kin_robot *rb, const kin_wheel_rows *w, int32_t *active, double *xi,
                   double *slip, double *force, double *rcond)
{
    qs_problem p;
    int at_rest, degenerate;
    const double len = qs_setup(rb, w, &p, &at_rest);
    int32_t s[3] = {-1, -1, -1};
    if (active != NULL) {
        s[0] = active[0];
        s[1] = active[1];
        s[2] = active[2];
    }
    double x[3], y[QS_MAX_ROWS], rc = 0.0;
    const int ok = qs_minimise(&p, s, x, y, &rc, &degenerate);
    if (rcond != NULL) {
        *rcond = ok ? rc : 0.0;
    }
    if (!ok || !isfinite(x[0] + x[1] + x[2])) {
        xi[0] = xi[1] = xi[2] = 0.0;
        for (int32_t i = 0; i < w->count; i++) {
            if (slip != NULL) {
                slip[i] = 0.0;
            }
            if (force != NULL) {
                force[2 * i] = force[2 * i + 1] = 0.0;
            }
        }
        /* Joints at rest: nothing pushes the body, which stays still even where the
         * wheels leave it free. Otherwise the motion is undetermined. */
        return at_rest ? KIN_OK : KIN_ESINGULAR;
    }
    if (active != NULL) {
        active[0] = s[0];
        active[1] = s[1];
        active[2] = s[2];
    }
    xi[0] = x[0];
    xi[1] = x[1];
    xi[2] = x[2] / len;
    if (slip != NULL) {
        for (int32_t i = 0; i < w->count; i++) {
            slip[i] = -w->ty[i] * xi[0] + w->tx[i] * xi[1] + w->n_theta[i] * xi[2]
                      + w->n_joint[i];
        }
    }
    if (force != NULL) {
        for (int32_t i = 0; i < 2 * w->count; i++) {
            force[i] = 0.0;
        }
        for (int32_t k = 0; k < p.rows; k++) {
            force[p.id[k]] = -p.w[k] * y[k];
        }
    }
    return KIN_OK;
}
