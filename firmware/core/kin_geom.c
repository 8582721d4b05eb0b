/* Geometry of the wheeled chains and the minimum-slip body velocity (docs/models.md).
 *
 * Every wheel i has a position W_i, a rolling direction t_i and a normal n_i = J t_i
 * (J: rotation by +90 degrees). Its velocity is linear in the body velocity
 * xi = (dx, dy, dtheta) of the reference point p and in the joint velocities:
 *   v_i = (dx, dy) + dtheta J (W_i - p) + sum_j dphi_j J (W_i - P_j)
 * over the joints j that carry wheel i (P_j: the joint's position). Since
 * n.(J d) = t.d and t.(J d) = -n.d, the normal and tangential speeds are
 *   n_i.v_i = n_i.(dx, dy) + dtheta t_i.(W_i - p) + sum_j dphi_j t_i.(W_i - P_j)
 *   t_i.v_i = t_i.(dx, dy) - dtheta n_i.(W_i - p) - sum_j dphi_j n_i.(W_i - P_j). */
#include "kin_core.h"
#include "kin_geom.h"

#include <math.h>

#define RCOND_SINGULAR 1e-10
/* At or above this conditioning the normal equations are accurate enough (lsq3_normal). */
#define NORMAL_RCOND 1e-2

int kin_check_robot(const kin_robot *rb, int32_t *joints)
{
    if (rb == NULL) {
        return KIN_EINVAL;
    }
    if (!isfinite(rb->l) || !(rb->l > 0.0) || !isfinite(rb->c_n) || !(rb->c_n > 0.0)
        || !isfinite(rb->c_t) || !(rb->c_t >= 0.0)) {
        return KIN_EGEOMETRY;
    }
    int32_t count;
    if (rb->kind == KIN_SNAKE) {
        if (rb->links < 2 || rb->links > KIN_MAX_LINKS) {
            return KIN_EGEOMETRY;
        }
        count = rb->links - 1;
    } else if (rb->kind == KIN_TRIDENT) {
        if (!isfinite(rb->r) || !(rb->r >= 0.0) || !isfinite(rb->alpha[0])
            || !isfinite(rb->alpha[1]) || !isfinite(rb->alpha[2])) {
            return KIN_EGEOMETRY;
        }
        count = 3;
    } else {
        return KIN_EGEOMETRY;
    }
    if (joints != NULL) {
        *joints = count;
    }
    return KIN_OK;
}

int kin_wheel_count(const kin_robot *rb)
{
    if (kin_check_robot(rb, NULL) != KIN_OK) {
        return 0;
    }
    return rb->kind == KIN_SNAKE ? rb->links : 3;
}

static int finite_vec(const double *v, int32_t n)
{
    for (int32_t i = 0; i < n; i++) {
        if (!isfinite(v[i])) {
            return 0;
        }
    }
    return 1;
}

/* Wheel i at (wx, wy) rolling along (tx, ty): its position, direction and the
 * coefficients of dtheta in its normal and tangential speeds (q: the reference point). */
static void set_wheel(kin_wheel_rows *w, int32_t i, const double *q, double tx, double ty,
                      double wx, double wy)
{
    const double rx = wx - q[0], ry = wy - q[1];
    w->px[i] = wx;
    w->py[i] = wy;
    w->tx[i] = tx;
    w->ty[i] = ty;
    w->n_theta[i] = tx * rx + ty * ry;
    w->t_theta[i] = ty * rx - tx * ry;
}

/* Snake rows. Joint k (0-based) sits at the far end of link k: (jx[k], jy[k]). Sines
 * from libm and joint terms summed joint by joint in world coordinates, as the
 * planners' pinned results were computed: kin_sincos and a rearrangement into running
 * sums were both measured to move closed-loop routes near the singular line at the
 * level of rounding, and neither was faster here for five links. */
static void snake_rows(const kin_robot *rb, const double *q, const double *dphi,
                       kin_wheel_rows *w)
{
    const double px = q[0], py = q[1];
    const int32_t links = rb->links;
    double jx[KIN_MAX_JOINTS], jy[KIN_MAX_JOINTS];
    double psi = q[2], ax = px, ay = py;
    w->count = links;
    for (int32_t k = 0; k < links; k++) {
        if (k > 0) {
            psi += q[2 + k];
        }
        const double tx = cos(psi), ty = sin(psi);
        const double wx = ax + rb->l * tx, wy = ay + rb->l * ty;
        double nd = 0.0, td = 0.0;
        for (int32_t j = 0; j < k && dphi != NULL; j++) {
            const double dx = wx - jx[j], dy = wy - jy[j];
            nd += dphi[j] * (tx * dx + ty * dy);
            td -= dphi[j] * (-ty * dx + tx * dy);
        }
        set_wheel(w, k, q, tx, ty, wx, wy);
        w->n_joint[k] = nd;
        w->t_joint[k] = td;
        ax += 2.0 * rb->l * tx;
        ay += 2.0 * rb->l * ty;
        if (k < KIN_MAX_JOINTS) {
            jx[k] = ax;
            jy[k] = ay;
        }
    }
}

static void trident_rows(const kin_robot *rb, const double *q, const double *dphi,
                         kin_wheel_rows *w)
{
    w->count = 3;
    for (int32_t i = 0; i < 3; i++) {
        const double mu = q[2] + rb->alpha[i], nu = mu + q[3 + i]; /* corner, arm */
        const double tx = cos(nu), ty = sin(nu);
        const double ax = q[0] + rb->r * cos(mu), ay = q[1] + rb->r * sin(mu);
        set_wheel(w, i, q, tx, ty, ax + rb->l * tx, ay + rb->l * ty);
        /* W - A = l t: normal part l dphi, tangential part 0. */
        w->n_joint[i] = dphi != NULL ? rb->l * dphi[i] : 0.0;
        w->t_joint[i] = 0.0;
    }
}

void kin_geom_rows_unchecked(const kin_robot *rb, const double *q, const double *dphi,
                             kin_wheel_rows *w)
{
    if (rb->kind == KIN_SNAKE) {
        snake_rows(rb, q, dphi, w);
    } else {
        trident_rows(rb, q, dphi, w);
    }
}

int kin_geom_rows(const kin_robot *rb, const double *q, const double *dphi, kin_wheel_rows *w)
{
    int32_t joints;
    int rc = kin_check_robot(rb, &joints);
    if (rc != KIN_OK) {
        return rc;
    }
    if (q == NULL || w == NULL) {
        return KIN_EINVAL;
    }
    if (!finite_vec(q, 3 + joints) || (dphi != NULL && !finite_vec(dphi, joints))) {
        return KIN_ENONFINITE;
    }
    kin_geom_rows_unchecked(rb, q, dphi, w);
    return KIN_OK;
}

int kin_wheels(const kin_robot *rb, const double *q, double *pos, double *dir)
{
    kin_wheel_rows w;
    int rc = kin_geom_rows(rb, q, NULL, &w);
    if (rc != KIN_OK) {
        return rc;
    }
    for (int32_t i = 0; i < w.count; i++) {
        if (pos != NULL) {
            pos[2 * i] = w.px[i];
            pos[2 * i + 1] = w.py[i];
        }
        if (dir != NULL) {
            dir[2 * i] = w.tx[i];
            dir[2 * i + 1] = w.ty[i];
        }
    }
    return KIN_OK;
}

int kin_wheel_speeds(const kin_robot *rb, const double *q, const double *qdot, double *normal,
                     double *tangent)
{
    kin_wheel_rows w;
    if (qdot == NULL) {
        return KIN_EINVAL;
    }
    int rc = kin_geom_rows(rb, q, qdot + 3, &w);
    if (rc != KIN_OK) {
        return rc;
    }
    if (!finite_vec(qdot, 3)) {
        return KIN_ENONFINITE;
    }
    for (int32_t i = 0; i < w.count; i++) {
        const double vn = -w.ty[i] * qdot[0] + w.tx[i] * qdot[1] + w.n_theta[i] * qdot[2]
                          + w.n_joint[i];
        const double vt = w.tx[i] * qdot[0] + w.ty[i] * qdot[1] + w.t_theta[i] * qdot[2]
                          + w.t_joint[i];
        if (normal != NULL) {
            normal[i] = vn;
        }
        if (tangent != NULL) {
            tangent[i] = vt;
        }
    }
    return KIN_OK;
}

/* fmax() as the hot paths need it, without a libm call: the larger, or the one that is
 * not NaN. */
static double max2(double a, double b)
{
    return (b > a || isnan(a)) ? b : a;
}

/* Reciprocal 1-norm condition number of the upper triangular R = (r00 r01 r02; r11 r12;
 * r22), given as r[] = {r00, r01, r02, r11, r12, r22}, and its inverse, in the same
 * order, in inv[]: the caller has put the diagonal's reciprocals in inv[0], inv[3] and
 * inv[5]. Not finite when R is singular. */
static double r_rcond(const double r[6], double inv[6])
{
    inv[1] = -r[1] * inv[0] * inv[3];
    inv[4] = -r[4] * inv[3] * inv[5];
    inv[2] = -(r[1] * inv[4] + r[2] * inv[5]) * inv[0];
    const double n_r = max2(fabs(r[0]), max2(fabs(r[1]) + fabs(r[3]),
                                             fabs(r[2]) + fabs(r[4]) + fabs(r[5])));
    const double n_i = max2(fabs(inv[0]), max2(fabs(inv[1]) + fabs(inv[3]),
                                               fabs(inv[2]) + fabs(inv[4]) + fabs(inv[5])));
    return 1.0 / (n_r * n_i);
}

/* min ||M x - b|| for an m x 3 matrix (m <= 2 KIN_MAX_WHEELS) by Householder QR.
 * Writes x and the reciprocal 1-norm condition number of R. The columns must already
 * be in comparable units (the caller scales the rotation column by a body length):
 * they are deliberately NOT equilibrated by their own norms, since that would hide a
 * column that is small only through cancellation (a straight snake's longitudinal
 * direction), where the solution has lost its accuracy. */
static void lsq3(double m[][3], double *b, int32_t rows, double x[3], double *rcond)
{
    x[0] = x[1] = x[2] = 0.0;
    *rcond = 0.0;
    for (int32_t k = 0; k < 3; k++) {
        double norm = 0.0;
        for (int32_t i = k; i < rows; i++) {
            norm += m[i][k] * m[i][k];
        }
        norm = sqrt(norm);
        if (!(norm > 0.0)) {
            return;
        }
        const double alpha = m[k][k] > 0.0 ? -norm : norm;
        /* v = column k below the diagonal, minus alpha e_k; |v|^2 = 2 norm (norm + |m_kk|) */
        m[k][k] -= alpha;
        /* 2 / |v|^2, once: a multiplication per column instead of a division */
        const double two_over = 1.0 / (norm * (norm + fabs(m[k][k] + alpha)));
        for (int32_t j = k + 1; j < 3; j++) {
            double dot = 0.0;
            for (int32_t i = k; i < rows; i++) {
                dot += m[i][k] * m[i][j];
            }
            const double f = dot * two_over;
            for (int32_t i = k; i < rows; i++) {
                m[i][j] -= f * m[i][k];
            }
        }
        double dot = 0.0;
        for (int32_t i = k; i < rows; i++) {
            dot += m[i][k] * b[i];
        }
        const double f = dot * two_over;
        for (int32_t i = k; i < rows; i++) {
            b[i] -= f * m[i][k];
        }
        m[k][k] = alpha;
    }
    /* R = upper triangle of m[0..2] */
    const double r[6] = {m[0][0], m[0][1], m[0][2], m[1][1], m[1][2], m[2][2]};
    double inv[6] = {1.0 / r[0], 0.0, 0.0, 1.0 / r[3], 0.0, 1.0 / r[5]};
    const double rc = r_rcond(r, inv);
    if (!isfinite(rc)) {
        return;
    }
    *rcond = rc;
    const double z2 = b[2] * inv[5];
    const double z1 = (b[1] - r[4] * z2) * inv[3];
    const double z0 = (b[0] - r[1] * z1 - r[2] * z2) * inv[0];
    x[0] = z0;
    x[1] = z1;
    x[2] = z2;
}

/* The same problem through the normal equations M^T M x = M^T b, when that is as
 * accurate: their Cholesky factor is QR's R up to the signs of its rows (so the same
 * rcond), and they lose accuracy only as rcond^-2, at most NORMAL_RCOND^-2 = 1e4 ulps
 * here. a = M^T M as {a00, a01, a02, a11, a12, a22}, c = M^T b: sums the caller forms
 * straight from the wheel rows, about a third of Householder's time. Returns 0 (x
 * untouched) when rcond is below NORMAL_RCOND or the factorisation breaks down: then
 * QR decides. */
static int normal_solve(const double a[6], const double c[3], double x[3], double *rcond)
{
    if (!(a[0] > 0.0)) {
        return 0;
    }
    double r[6], inv[6];
    r[0] = sqrt(a[0]);
    inv[0] = 1.0 / r[0];
    r[1] = a[1] * inv[0];
    r[2] = a[2] * inv[0];
    const double d11 = a[3] - r[1] * r[1];
    if (!(d11 > 0.0)) {
        return 0;
    }
    r[3] = sqrt(d11);
    inv[3] = 1.0 / r[3];
    r[4] = (a[4] - r[1] * r[2]) * inv[3];
    const double d22 = a[5] - r[2] * r[2] - r[4] * r[4];
    if (!(d22 > 0.0)) {
        return 0;
    }
    r[5] = sqrt(d22);
    inv[5] = 1.0 / r[5];
    const double rc = r_rcond(r, inv);
    if (!(rc >= NORMAL_RCOND)) {
        return 0;
    }
    /* R^T z = M^T b, then R x = z */
    const double z0 = c[0] * inv[0];
    const double z1 = (c[1] - r[1] * z0) * inv[3];
    const double z2 = (c[2] - r[2] * z0 - r[4] * z1) * inv[5];
    x[2] = z2 * inv[5];
    x[1] = (z1 - r[4] * x[2]) * inv[3];
    x[0] = (z0 - r[1] * x[1] - r[2] * x[2]) * inv[0];
    *rcond = rc;
    return 1;
}

/* The weighted rows of the least-squares problem in the unknowns (dx, dy, len dtheta):
 * M (rows x 3) and b, for Householder QR. */
static int32_t weighted_rows(const kin_robot *rb, const kin_wheel_rows *w, double len,
                             double m[][3], double *b)
{
    const double wn = sqrt(rb->c_n), wt = sqrt(rb->c_t);
    const double wn_len = wn / len, wt_len = wt / len;
    int32_t rows = 0;
    for (int32_t i = 0; i < w->count; i++) {
        m[rows][0] = -w->ty[i] * wn;
        m[rows][1] = w->tx[i] * wn;
        m[rows][2] = w->n_theta[i] * wn_len;
        b[rows++] = -w->n_joint[i] * wn;
        if (wt > 0.0) {
            m[rows][0] = w->tx[i] * wt;
            m[rows][1] = w->ty[i] * wt;
            m[rows][2] = w->t_theta[i] * wt_len;
            b[rows++] = -w->t_joint[i] * wt;
        }
    }
    return rows;
}

int kin_geom_solve(const kin_robot *rb, const kin_wheel_rows *w, double *xi, double *slip,
                   double *rcond)
{
    /* Unknowns (dx, dy, L dtheta): L, the farthest wheel's distance from the reference
     * point, makes the rotation column a speed like the others. The normal equations'
     * sums are formed in (dx, dy, dtheta) and scaled after: each wheel's normal row is
     * sqrt(c_n) (-ty, tx, n_theta | -n_joint), its tangential row sqrt(c_t) (tx, ty,
     * t_theta | -t_joint). */
    const double cn = rb->c_n, ct = rb->c_t;
    double len2 = rb->l * rb->l; /* squared: one square root, not one per wheel */
    double a[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, c[3] = {0.0, 0.0, 0.0};
    int at_rest = 1;
    for (int32_t i = 0; i < w->count; i++) {
        const double tx = w->tx[i], ty = w->ty[i], nth = w->n_theta[i], tth = w->t_theta[i];
        const double nj = w->n_joint[i], tj = ct > 0.0 ? w->t_joint[i] : 0.0;
        len2 = max2(len2, nth * nth + tth * tth);
        a[0] += cn * ty * ty + ct * tx * tx;
        a[1] += (ct - cn) * tx * ty;
        a[2] += ct * tx * tth - cn * ty * nth;
        a[3] += cn * tx * tx + ct * ty * ty;
        a[4] += cn * tx * nth + ct * ty * tth;
        a[5] += cn * nth * nth + ct * tth * tth;
        c[0] += cn * ty * nj - ct * tx * tj;
        c[1] -= cn * tx * nj + ct * ty * tj;
        c[2] -= cn * nth * nj + ct * tth * tj;
        at_rest = at_rest && nj == 0.0 && tj == 0.0;
    }
    const double len = sqrt(len2), inv_len = 1.0 / len;
    a[2] *= inv_len;
    a[4] *= inv_len;
    a[5] *= inv_len * inv_len;
    c[2] *= inv_len;
    double x[3], rc;
    if (!normal_solve(a, c, x, &rc)) {
        double m[2 * KIN_MAX_WHEELS][3];
        double b[2 * KIN_MAX_WHEELS];
        lsq3(m, b, weighted_rows(rb, w, len, m, b), x, &rc);
    }
    if (rcond != NULL) {
        *rcond = rc;
    }
    if (rc < RCOND_SINGULAR) {
        /* Joints at rest: nothing pushes the body, which stays still even where the
         * axles leave it free (a straight snake). Otherwise the motion is undetermined. */
        xi[0] = xi[1] = xi[2] = 0.0;
        if (slip != NULL) {
            for (int32_t i = 0; i < w->count; i++) {
                slip[i] = 0.0;
            }
        }
        return at_rest ? KIN_OK : KIN_ESINGULAR;
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
    return KIN_OK;
}

int kin_body_velocity(const kin_robot *rb, const double *q, const double *dphi, double *xi,
                      double *slip, double *rcond)
{
    kin_wheel_rows w;
    if (dphi == NULL || xi == NULL) {
        return KIN_EINVAL;
    }
    int rc = kin_geom_rows(rb, q, dphi, &w);
    if (rc != KIN_OK) {
        return rc;
    }
    return kin_geom_solve(rb, &w, xi, slip, rcond);
}

const char *kin_strerror(int code)
{
    switch (code) {
    case KIN_OK:
        return "success";
    case KIN_EINVAL:
        return "invalid argument (null pointer, size out of range or bad option)";
    case KIN_EGEOMETRY:
        return "invalid robot geometry (lengths must be positive, 2 to 16 snake links)";
    case KIN_ESINGULAR:
        return "singular configuration: the wheel axles meet in one point or are all "
               "parallel, so the body velocity is not determined";
    case KIN_EINADMISSIBLE:
        return "the joint motion crosses a singular configuration in a direction the "
               "wheels cannot follow without slipping";
    case KIN_ESTEPSIZE:
        return "the adaptive step size fell below its minimum (the motion is too abrupt "
               "or singular there)";
    case KIN_EMAXSTEPS:
        return "the step budget ran out before the end time";
    case KIN_ENONFINITE:
        return "a non-finite number (NaN or infinity) appeared";
    case KIN_EUNSUPPORTED:
        return "the C core has no vector-field model for this robot (it has the 3-link "
               "snake's and the trident's)";
    default:
        return "unknown kinematic-core status";
    }
}
