/* The physics world's coupling of MuJoCo and the emulated servos (snakebot.sim.physics.world),
 * once per control tick for every joint at once: each servo's registers to its motor's
 * drive (snakebot.sim.physics.actuator.Actuator.drive), the physics back to each servo,
 * the motors' energy, a sample's row. Python steps MuJoCo between the calls; these
 * work on MuJoCo's own arrays (pointers to its mjData and mjModel buffers, which do not
 * move). Every step mirrors the Python it replaced, operation for operation, so the
 * world's trajectories stay the same to the last bit; tests/sim/test_physics_coupling.py
 * holds the drive and the power to the Python models. The kinematic world's loaded servos
 * (sim_joints below) use the same coupling on arrays of their own. Host-side only. */
#ifndef SNAKEBOT_SIM_WORLD_H
#define SNAKEBOT_SIM_WORLD_H

#include "kin_core.h"
#include "sim_servo.h"

/* cffi:begin */
typedef struct {
    double stall_nm;      /* stall torque at the nominal voltage, N m at the joint */
    double nominal_v;     /* the supply voltage of the motor's figures */
    double no_load_rad_s; /* no-load speed at the nominal voltage */
    double ticks_per_rad; /* position ticks per radian */
    double duty_full;     /* Torque Limit, Punch and wheel-mode Moving Speed at full duty */
    int direction_bit;    /* wheel-mode Moving Speed's direction bit, as a value */
} sim_actuator;

/* Actuator.drive: the drive of a motor whose servo's controller (sim_servo_controller)
 * is `controller`, at position pos_ticks, into out[4]: gain (1/tick), target (ticks),
 * bias, cap (duty = gain (target - position) + bias, limited to +-cap); returns whether
 * the cap (Torque Limit's or Moving Speed's, whichever binds) cuts the duty the controller
 * asks for (1) or not (0). */
int sim_actuator_drive(const sim_actuator *a, const double *controller, double pos_ticks,
                       double *out);
/* MotorSpec.electrical_power_w: the power (W) the motor draws to give torque_nm at
 * speed_rad_s, never negative. */
double sim_actuator_power(const sim_actuator *a, double torque_nm, double speed_rad_s);

/* A sample's piece: out[i] = source[index[i]] for i < n. */
typedef struct {
    const double *source;
    const int *index;
    int n;
} sim_gather;

typedef struct {
    int n;                              /* joints; actuator k drives joint k */
    sim_servo **servos;                 /* joint k's servo */
    const double *sign, *zero;          /* joint k's direction (+-1) and tick at angle 0 */
    const int *qadr, *dadr;             /* joint k's entry in qpos, in qvel */
    const double *qpos, *qvel, *force;  /* mjData's qpos, qvel, actuator_force */
    int nq, nv;
    double *biasprm, *forcerange;       /* mjModel's actuator_biasprm, actuator_forcerange */
    int nbias;                          /* biasprm's row length */
    const sim_actuator *actuator;
    double brake;                       /* minus the back-EMF damping, N m s/rad */
    double stalled_fraction; /* a joint slower than this fraction of the speed its capped
                              * drive turns the unloaded motor at is stalled */
    double hold;                        /* stalled and cut this long (s): overload */
    double period;                      /* the control period, s */
    double dt;                          /* the MuJoCo step, s */
    double start;                       /* bus time of the world's start */
    double min_z;                       /* a link's lowest height before it counts sunk */
    const int *zadr;                    /* the z slides in qpos from the root down the chain:
                                         * a link's height is the sum up to its own */
    int nz;
    const sim_gather *gathers;          /* a sample's row after its time, piece by piece */
    int ngathers;
    /* per joint, carried from tick to tick */
    double *speed, *torque;             /* rad/s and the motor's N m, as last measured */
    double *energy, *electrical;        /* J, mechanical (signed) and drawn */
    double *stalled;                    /* how long it has been stalled and cut, s */
    int profile;                        /* Moving Speed limits the target's motion, not
                                         * the drive (the robot's speed_limit) */
    double *reference;                  /* profile: the target it moves, ticks */
    _Bool *on, *moving;                 /* its torque on; its motor driven */
} sim_world;

/* Each joint's speed and motor torque now (the drive less the back-EMF braking). */
void sim_world_measure(sim_world *w);
/* After a MuJoCo step of dt: measure, and add each motor's work and electrical energy
 * over the step (the drive in force during the step, the speed at its end). */
void sim_world_account(sim_world *w);
/* A sample at bus time t into row (its time since the start, then the gathers): 0, or
 * SIM_WORLD_BLEW_UP / SIM_WORLD_SANK (nothing written) if the physics has failed. */
#define SIM_WORLD_BLEW_UP 1
#define SIM_WORLD_SANK 2
int sim_world_sample(const sim_world *w, double t, double *row);
/* At bus time t: report each joint to its servo (sim_servo_set_motion) and set its
 * motor's drive from the servo's registers as they are then, as MuJoCo's actuator bias
 * (affine in the joint angle) and force range. With profile, the drive aims at the
 * joint's reference, which moves to Goal Position by at most Moving Speed times the
 * control period a tick (from where the joint is when its torque comes on), and Moving
 * Speed no longer caps the drive. */
void sim_world_couple(sim_world *w, double t);

/* The kinematic world with its servos under the body's load (snakebot.sim.physics.joints):
 * the same drives, moving joints whose load is the quasi-static body's. world's qpos, qvel
 * and force point at q + 3, speed and force here. */
typedef struct {
    sim_world *world;     /* the coupling: servos, drives, energy */
    const kin_robot *rb;  /* the quasi-static model, with the world's friction */
    double unit_m;        /* metres per robot length unit */
    double armature;      /* the motor's inertia at the joint, kg m^2 */
    int steps;            /* steps of world->dt per control period */
    double *q;            /* the state: pose (x, y, theta; robot units) and joints (rad) */
    double *speed;        /* per joint, rad/s */
    double *force;        /* per joint: the drive's torque in the last step, N m */
    double *load;         /* per joint: the body's load in the last step, N m */
    const double *external; /* per joint: a torque from outside (a hand pushing the horn;
                             * the servos' set_external_torque), N m, on the joint's axis */
    const double *lo, *hi; /* per joint: its stops (rad), as the physics world's joint
                            * ranges: a joint pushed there stops (and stalls its motor) */
    int slip_step;        /* the step whose start is the middle of a sample's interval (-1:
                           * none in this period) */
    double *slip;         /* per wheel: its normal speed there */
} sim_joints;
/* One control period under the drives sim_world_couple set (MuJoCo's affine actuator: the
 * torque bias[0] + bias[1] phi within the force range), the motors' back-EMF braking and
 * armature, and the body's load: the joint torques the quasi-static model needs for the
 * joints' motion (kin_quasi_static), whose body velocity moves the pose. Per step of dt,
 * the drive and the body velocity as at the step's start, the braking implicit (as MuJoCo
 * integrates damping):
 *     (armature / dt - brake) speed' = armature / dt speed + drive(phi) + external - load
 *     phi' = phi + dt speed',  pose' = pose + dt xi(q, speed)
 * (a joint that would pass its stop ends there, at rest),
 * The load is Coulomb friction's: piecewise constant in the joints' speeds (a subgradient
 * of the power the wheels dissipate, which is convex and piecewise linear in them), so it
 * is taken implicitly: the load at the start's speeds first; if the speeds that gives meet
 * another piece's load, the step takes the speeds that minimise the motors' quadratic plus
 * the larger of the two pieces (a proximal step): the new piece's load, or on the boundary
 * between the pieces a mix of both. Each step is accounted (sim_world_account). KIN_OK,
 * or the model's error. */
int sim_joints_period(sim_joints *j);
/* cffi:end */

#endif
