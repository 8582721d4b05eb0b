/* Geometry of the wheeled chains (docs/models.md); the body velocity they allow is in
 * kin_qs.c.
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

int kin_check_robot(const kin_robot *rb, int32_t *joints)
{
    if (rb == NULL) {
        return KIN_EINVAL;
    }
    if (!isfinite(rb->l) || !(rb->l > 0.0)) {
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
    /* Friction: every wheel resists sliding across it (lateral > 0); rolling >= 0. */
    const int32_t wheels = rb->kind == KIN_SNAKE ? rb->links : 3;
    for (int32_t i = 0; i < wheels; i++) {
        if (!isfinite(rb->lateral[i]) || !(rb->lateral[i] > 0.0) || !isfinite(rb->rolling[i])
            || !(rb->rolling[i] >= 0.0)) {
            return KIN_EGEOMETRY;
        }
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

/* The wheels' positions and rolling directions of rows w into pos and dir (either may
 * be NULL). */
static void wheels_of(const kin_wheel_rows *w, double *pos, double *dir)
{
    for (int32_t i = 0; i < w->count; i++) {
        if (pos != NULL) {
            pos[2 * i] = w->px[i];
            pos[2 * i + 1] = w->py[i];
        }
        if (dir != NULL) {
            dir[2 * i] = w->tx[i];
            dir[2 * i + 1] = w->ty[i];
        }
    }
}

int kin_wheels(const kin_robot *rb, const double *q, double *pos, double *dir)
{
    kin_wheel_rows w;
    int rc = kin_geom_rows(rb, q, NULL, &w);
    if (rc != KIN_OK) {
        return rc;
    }
    wheels_of(&w, pos, dir);
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
    return kin_geom_solve(rb, &w, NULL, xi, slip, NULL, rcond);
}

/* Joint j's torque balances the friction forces' generalised force on phi_j: minus the
 * sum over the wheels of each force times its speed's coefficient of dphi_j (the rows
 * with dphi = e_j), worked out from the rows' geometry as snake_rows and trident_rows
 * would with that dphi, term for term, without their trigonometry. */
static void joint_torques(const kin_robot *rb, const double *q, const kin_wheel_rows *w,
                          const double *f, int32_t joints, double *torque)
{
    if (rb->kind != KIN_SNAKE) {
        for (int32_t j = 0; j < joints; j++) {
            torque[j] = 0.0 - f[2 * j] * (rb->l * 1.0); /* n_joint = l dphi_j, t_joint = 0 */
        }
        return;
    }
    double jx[KIN_MAX_JOINTS], jy[KIN_MAX_JOINTS];
    double ax = q[0], ay = q[1];
    for (int32_t k = 0; k < joints; k++) {
        ax += 2.0 * rb->l * w->tx[k];
        ay += 2.0 * rb->l * w->ty[k];
        jx[k] = ax;
        jy[k] = ay;
    }
    for (int32_t j = 0; j < joints; j++) {
        double tq = 0.0;
        for (int32_t k = j + 1; k < w->count; k++) {
            const double tx = w->tx[k], ty = w->ty[k];
            const double dx = w->px[k] - jx[j], dy = w->py[k] - jy[j];
            const double nd = tx * dx + ty * dy;
            const double td = 0.0 - (-ty * dx + tx * dy);
            tq -= f[2 * k] * nd + f[2 * k + 1] * td;
        }
        torque[j] = tq;
    }
}

/* kin_quasi_static on rows already made (w, with dphi): the solve and the torques. */
static int quasi_static_rows(const kin_robot *rb, const double *q, const kin_wheel_rows *w,
                             int32_t joints, double *xi, double *force, double *torque)
{
    double f[2 * KIN_MAX_WHEELS];
    const int rc = kin_geom_solve(rb, w, NULL, xi, NULL, f, NULL);
    if (rc != KIN_OK) {
        return rc;
    }
    if (force != NULL) {
        for (int32_t i = 0; i < 2 * w->count; i++) {
            force[i] = f[i];
        }
    }
    if (torque != NULL) {
        joint_torques(rb, q, w, f, joints, torque);
    }
    return KIN_OK;
}

int kin_quasi_static(const kin_robot *rb, const double *q, const double *dphi, double *xi,
                     double *force, double *torque)
{
    kin_wheel_rows w;
    int32_t joints;
    if (dphi == NULL || xi == NULL) {
        return KIN_EINVAL;
    }
    int rc = kin_geom_rows(rb, q, dphi, &w);
    if (rc != KIN_OK) {
        return rc;
    }
    (void)kin_check_robot(rb, &joints);
    return quasi_static_rows(rb, q, &w, joints, xi, force, torque);
}

int kin_quasi_static_path(const kin_robot *rb, int32_t count, const double *q,
                          const double *dphi, double *torque, double *pos, double *dir,
                          int32_t *failed)
{
    int32_t joints;
    int rc = kin_check_robot(rb, &joints);
    if (rc != KIN_OK || count < 0 || q == NULL || (torque != NULL && dphi == NULL)) {
        return rc != KIN_OK ? rc : KIN_EINVAL;
    }
    const int32_t n = 3 + joints;
    const int32_t wheels = kin_wheel_count(rb);
    for (int32_t k = 0; k < count; k++) {
        /* One set of rows per state serves the solve and the wheels (their positions and
         * directions do not depend on dphi). */
        kin_wheel_rows w;
        double xi[3];
        rc = KIN_OK;
        if (torque != NULL || pos != NULL || dir != NULL) {
            rc = kin_geom_rows(rb, q, torque != NULL ? dphi : NULL, &w);
        }
        if (rc == KIN_OK && torque != NULL) {
            rc = quasi_static_rows(rb, q, &w, joints, xi, NULL, torque);
            dphi += joints;
            torque += joints;
        }
        if (rc == KIN_OK && (pos != NULL || dir != NULL)) {
            wheels_of(&w, pos, dir);
            pos = pos == NULL ? NULL : pos + 2 * wheels;
            dir = dir == NULL ? NULL : dir + 2 * wheels;
        }
        if (rc != KIN_OK) {
            if (failed != NULL) {
                *failed = k;
            }
            return rc;
        }
        q += n;
    }
    return KIN_OK;
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
