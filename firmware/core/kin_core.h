/* Kinematic core: wheeled snake and trident models, their control vector fields and
 * Lie brackets, and whole-trajectory integrators (fixed-step RK4, adaptive
 * Dormand-Prince 5(4) and 8(5,3)). Conventions: docs/models.md.
 *
 * Portable C99, double precision, no heap, no hardware: every buffer is the caller's
 * and every size is bounded by the KIN_MAX_* constants. Functions return a KIN_*
 * status code; kin_strerror() gives its text. */
#ifndef SNAKEBOT_KIN_CORE_H
#define SNAKEBOT_KIN_CORE_H

#include <stddef.h>
#include <stdint.h>

/* cffi:begin */
#define KIN_MAX_LINKS 16
#define KIN_MAX_JOINTS 15
#define KIN_MAX_WHEELS 16
#define KIN_MAX_STATE 18
#define KIN_MAX_FIELDS 6
#define KIN_MAX_INPUTS 3

/* Status codes. */
#define KIN_OK 0
#define KIN_EINVAL 1       /* bad argument: null pointer, size out of range, bad option */
#define KIN_EGEOMETRY 2    /* robot geometry invalid (non-positive length, link count) */
#define KIN_ESINGULAR 3    /* singular configuration: the body velocity is not determined */
#define KIN_EINADMISSIBLE 4 /* joint motion crosses a singular configuration inadmissibly */
#define KIN_ESTEPSIZE 5    /* adaptive step size fell below the minimum */
#define KIN_EMAXSTEPS 6    /* step budget exhausted before the end time */
#define KIN_ENONFINITE 7   /* a non-finite number appeared (input or result) */
#define KIN_EUNSUPPORTED 8 /* no such model for this robot (fields exist for the 3-link snake and trident) */

/* Robot kinds. */
#define KIN_SNAKE 0
#define KIN_TRIDENT 1

/* Input forms of the trident's fields (the 3-link snake has joint-velocity inputs). */
#define KIN_FORM_BODY 0
#define KIN_FORM_WORLD 1

/* Integration methods. */
#define KIN_RK4 0
#define KIN_DOPRI5 1
#define KIN_DOP853 2 /* Dormand-Prince 8(5,3): fewer evaluations; steps end at switches */

/* Joint schedules (joint angles prescribed as functions of time). */
#define KIN_SCHED_SINES 0  /* phi_j = offset_j + rate_j t + amp_j sin(omega t + phase_j) */
#define KIN_SCHED_TABLE 1  /* samples every dt, linear in between; loop wraps last -> first */

/* Geometry. Snake: `links` links of length 2l, wheels at the middles; reference point
 * (x, y) = free end of link 1, theta = heading of link 1. Trident: base centre (x, y),
 * heading theta, arm i (length l) jointed at radius r, angle alpha[i]; wheel at the arm's
 * end. Friction, per wheel i, in newtons: lateral[i] = mu N_i, the Coulomb force across the
 * wheel when it slides (> 0); rolling[i] = C_rr N_i + axle torque / wheel radius, the
 * force resisting its rolling (>= 0; 0: free rolling, singular where the axles meet). */
typedef struct {
    int32_t kind;
    int32_t links;
    double l;
    double r;
    double alpha[3];
    double lateral[KIN_MAX_WHEELS];
    double rolling[KIN_MAX_WHEELS];
} kin_robot;

typedef struct {
    int32_t type;
    int32_t joints;
    double omega;
    double offset[KIN_MAX_JOINTS];
    double rate[KIN_MAX_JOINTS];
    double amp[KIN_MAX_JOINTS];
    double phase[KIN_MAX_JOINTS];
    const double *samples; /* table: rows x joints, row-major */
    int32_t rows;
    double dt;
    int32_t loop;
} kin_schedule;

/* Inputs of the field-driven system, a constant plus two harmonics:
 * u_i(t) = c_i + a_i sin(w t) + b_i cos(w t) + a2_i sin(2 w t) + b2_i cos(2 w t).
 * One harmonic traces loops for second-order brackets [g_i, g_j]; the second is
 * needed for third-order ones [g_i, [g_i, g_j]]. */
typedef struct {
    int32_t form;
    double omega;
    double c[KIN_MAX_INPUTS];
    double a[KIN_MAX_INPUTS];
    double b[KIN_MAX_INPUTS];
    double a2[KIN_MAX_INPUTS];
    double b2[KIN_MAX_INPUTS];
} kin_inputs;

typedef struct {
    int32_t method;    /* KIN_RK4, KIN_DOPRI5 or KIN_DOP853 */
    double h;          /* RK4: step; adaptive: first step (0 = automatic) */
    double rtol;       /* adaptive: relative tolerance */
    double atol;       /* adaptive: absolute tolerance */
    double h_min;      /* adaptive: smallest step before KIN_ESTEPSIZE (0 = automatic) */
    int32_t max_steps; /* step budget for the whole call (0 = by the span, kin_ode.c) */
} kin_options;

typedef struct {
    int32_t steps;     /* accepted steps */
    int32_t rejected;  /* rejected steps (adaptive methods) */
    int32_t evals;     /* right-hand-side evaluations (DOP853: and probes for switches) */
    int32_t fallbacks; /* evaluations near a singular configuration done by extrapolation in time */
    double min_rcond;  /* smallest conditioning of the friction problem seen */
    double t_fail;     /* time reached when an error stopped the integration */
} kin_stats;

/* KIN_OK if the geometry is usable; the number of joints in *joints (may be NULL). */
int kin_check_robot(const kin_robot *rb, int32_t *joints);
/* Number of wheels of a valid robot (snake: links; trident: 3). */
int kin_wheel_count(const kin_robot *rb);
/* Wheel positions pos[2i..2i+1] and unit rolling directions dir[2i..2i+1] at q. */
int kin_wheels(const kin_robot *rb, const double *q, double *pos, double *dir);
/* Each wheel's velocity for the state velocity qdot, split into normal (slip across the
 * wheel) and tangential (rolling) components; either output may be NULL. */
int kin_wheel_speeds(const kin_robot *rb, const double *q, const double *qdot,
                     double *normal, double *tangent);
/* Quasi-static body velocity xi = (dx, dy, dtheta) (world frame) for joint velocities
 * dphi at q: the one minimising the wheels' frictional power
 * sum_i lateral_i |n_i.v_i| + rolling_i |t_i.v_i| (exactly, at a vertex of that L1 fit).
 * slip (may be NULL): each wheel's normal speed n.v. rcond (may be NULL): reciprocal
 * 1-norm condition number of the three sticking rows' system (rotation column scaled by
 * the body length). KIN_ESINGULAR (xi = 0) when the rows do not determine the motion
 * (only with rolling = 0: axles concurrent or all parallel, e.g. the 3-link snake with
 * phi1 = phi2) and the joints move. Joints at rest give xi = 0. */
int kin_body_velocity(const kin_robot *rb, const double *q, const double *dphi,
                      double *xi, double *slip, double *rcond);
/* The same body velocity with the forces behind it: force (2 x wheels, may be NULL) the
 * friction force on wheel i across (force[2i], along n_i) and along (force[2i+1], along
 * t_i) it, in newtons; torque (joints, may be NULL) each joint's torque that drives the
 * motion against that friction (newtons times the robot's length unit). The power the
 * joints put in, sum torque_j dphi_j, is the power the wheels dissipate. */
int kin_quasi_static(const kin_robot *rb, const double *q, const double *dphi, double *xi,
                     double *force, double *torque);
/* kin_quasi_static's torques and kin_wheels' positions and directions at each of count
 * states, in one call (what a whole sampled motion's effort needs): q[k * n] (n = 3 +
 * joints), dphi[k * joints]; torque[k * joints], pos[k * 2 * wheels], dir[k * 2 * wheels];
 * any output may be NULL. Every state is solved as a call of its own would solve it. On
 * an error the failing state's index is in *failed (may be NULL). */
int kin_quasi_static_path(const kin_robot *rb, int32_t count, const double *q,
                          const double *dphi, double *torque, double *pos, double *dir,
                          int32_t *failed);

/* Number of fields (inputs g... then brackets h...) and of inputs; KIN_EUNSUPPORTED
 * for robots without a field model (snakes other than 3 links). */
int kin_field_count(const kin_robot *rb, int32_t *fields, int32_t *inputs);
/* All fields at q (thesis order: g1.., h1..), out[f * n + k], n = 3 + joints.
 * The 3-link snake's fields are undefined where det B = 0 (phi1 = phi2, or a joint at +-pi)
 * (KIN_ESINGULAR); *det receives det B there (3-link) or 1 (trident); may be NULL. */
int kin_fields(const kin_robot *rb, int32_t form, const double *q, double *out, double *det);
/* Velocity of the field-driven system: qdot = sum_i u_i g_i(q). */
int kin_field_velocity(const kin_robot *rb, int32_t form, const double *q, const double *u,
                       double *qdot);

/* Joint angles and velocities of a schedule at time t (phi, dphi: `joints` entries). */
int kin_schedule_eval(const kin_schedule *s, double t, double *phi, double *dphi);

/* Body pose driven by a joint schedule through the quasi-static friction model, from pose0 =
 * (x, y, theta) at t0 to t1. Writes n_out >= 2 rows of q = (x, y, theta, phi..) at
 * t0 + k (t1 - t0) / (n_out - 1) to out, and each wheel's normal slip speed at those
 * times to slip (n_out x wheels; may be NULL). stats may be NULL. */
int kin_integrate_joints(const kin_robot *rb, const kin_schedule *s, const double *pose0,
                         double t0, double t1, int32_t n_out, const kin_options *opt,
                         double *out, double *slip, kin_stats *stats);
/* kin_integrate_joints for each of `count` schedules s[0..count-1] (a gait search's
 * parameter grid) in one call: trajectory k writes its n_out rows to
 * out + k * n_out * (3 + joints), its status to status[k] (KIN_OK, or the error that
 * stopped it: the others still run) and, unless stats is NULL, its counters to stats[k].
 * Returns KIN_OK when every trajectory ran to the end, else the first failure's status
 * (KIN_EINVAL at once for a bad shared argument). */
int kin_integrate_joints_batch(const kin_robot *rb, const kin_schedule *s, int32_t count,
                               const double *pose0, double t0, double t1, int32_t n_out,
                               const kin_options *opt, double *out, int32_t *status,
                               kin_stats *stats);
/* The field-driven system qdot = sum_i u_i(t) g_i(q) from q0 at t0 to t1; writes n_out
 * rows of q at evenly spaced times to out. */
int kin_integrate_fields(const kin_robot *rb, const kin_inputs *u, const double *q0,
                         double t0, double t1, int32_t n_out, const kin_options *opt,
                         double *out, kin_stats *stats);

/* Text of a status code. */
const char *kin_strerror(int code);
/* cffi:end */

#endif
