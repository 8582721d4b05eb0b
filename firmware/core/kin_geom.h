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
/* The vertex of the active set s (the point where its three rows vanish) tested: out[0]
 * the power there (the friction problem's objective), out[1] how far its certificate
 * fails (the largest of its rows' friction multipliers, less 1 and the rounding allowed:
 * <= 0 where s is optimal, as a solve warm-started from s finds), out[2] the residual of
 * row `row` there (NAN for row -1). Along a schedule, where the optimum passes from s to
 * another set, either a stuck wheel's force reaches its limit (out[1] crosses 0 smoothly;
 * the velocity jumps) or another row passes through the vertex (out[2] crosses 0; the
 * velocity has a kink, and the two sets' powers become equal). Returns 0 when s's vertex
 * is ill-conditioned. */
int kin_geom_vertex_test(const kin_robot *rb, const kin_wheel_rows *w, const int32_t s[3],
                         int32_t row, double out[3]);
/* kin_geom_vertex_test (row -1) of each of count sets into out[i], ok[i] its return, the
 * problem built once; returns ok[0] (0 for no sets). */
int kin_geom_vertex_tests(const kin_robot *rb, const kin_wheel_rows *w, int32_t count,
                          int32_t (*sets)[3], double (*out)[3], int *ok);
/* kin_geom_active_set and, where it returns 1, kin_geom_vertex_tests on the same
 * problem (a switch's probe: which set holds there and how far from switching). */
int kin_geom_active_set_tests(const kin_robot *rb, const kin_wheel_rows *w, int32_t active[3],
                              double *rcond, int32_t count, int32_t (*sets)[3],
                              double (*out)[3], int *ok);

#endif
