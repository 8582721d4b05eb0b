/* Internal to the kinematic core: per-wheel rows of the slip equations. */
#ifndef SNAKEBOT_KIN_GEOM_H
#define SNAKEBOT_KIN_GEOM_H

#include "kin_core.h"

/* Wheel i: position (px, py), rolling direction (tx, ty), and the coefficients of its
 * normal / tangential speed: n.v = n.(dx, dy) + n_theta dtheta + n_joint, where n_joint
 * (t_joint) is the joint velocities' contribution. */
typedef struct {
    int32_t count;
    double px[KIN_MAX_WHEELS], py[KIN_MAX_WHEELS];
    double tx[KIN_MAX_WHEELS], ty[KIN_MAX_WHEELS];
    double n_theta[KIN_MAX_WHEELS], t_theta[KIN_MAX_WHEELS];
    double n_joint[KIN_MAX_WHEELS], t_joint[KIN_MAX_WHEELS];
} kin_wheel_rows;

/* Fill the rows at q for joint velocities dphi (NULL: zero). */
int kin_geom_rows(const kin_robot *rb, const double *q, const double *dphi, kin_wheel_rows *w);
/* The same for a robot already validated, q and dphi not checked (the right-hand side's
 * path: a non-finite value comes out in the rows, and the integrator reports it). */
void kin_geom_rows_unchecked(const kin_robot *rb, const double *q, const double *dphi,
                             kin_wheel_rows *w);
/* The quasi-static body velocity for those rows (kin_qs.c; see kin_body_velocity).
 * active (may be NULL): three row indices, the previous answer's active set, used as a
 * warm start and updated; {-1, -1, -1} for none. force (may be NULL): each wheel's
 * friction force across (force[2i], along n_i) and along (force[2i+1], along t_i) it. */
int kin_geom_solve(const kin_robot *rb, const kin_wheel_rows *w, int32_t *active, double *xi,
                   double *slip, double *force, double *rcond);
/* The active set of that solve alone (active: the warm start, updated; *rcond its
 * conditioning). Returns 1 when the minimum is a vertex with exactly those three rows
 * through it, 0 when it is degenerate (its active set is one of several) or undetermined. */
int kin_geom_active_set(const kin_robot *rb, const kin_wheel_rows *w, int32_t active[3],
                        double *rcond);
/* The power (the friction problem's objective) at the vertex of the active set s, the
 * point where s's three rows vanish: two sets' powers are equal where the optimum passes
 * from one to the other (a switch between sticking and slipping). Returns 0 when s's
 * vertex is ill-conditioned. */
int kin_geom_vertex_power(const kin_robot *rb, const kin_wheel_rows *w, const int32_t s[3],
                          double *power);

#endif
