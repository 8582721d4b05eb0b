/* The hot path of an emulated AX-12 (snakebot.sim.servo.reference.VirtualServo) in C: its motion,
 * heat and alarms between packets, the telemetry READ, the write of Goal Position
 * (+ Moving Speed) that every SYNC_WRITE carries, and a physics world's hooks. The Python object keeps its state in
 * this struct (one store), so its own methods and these functions see the same servo;
 * the pure-Python ReferenceServo is the model these follow, checked by
 * tests/sim/test_fast_servo.py. Host-side only: never compiled into the firmware.
 * Unit facts and value ranges come from the device description through Python
 * (sim_servo_units); register addresses from ax12_table.h, generated from it too. */
#ifndef SNAKEBOT_SIM_SERVO_H
#define SNAKEBOT_SIM_SERVO_H

#include <stdint.h>

/* cffi:begin */
typedef struct {
    double ticks_per_rev;     /* a full turn in position ticks */
    double speed_unit;        /* ticks/s of one Present Speed unit */
    double speed_unit_rpm;    /* rpm of one Moving Speed unit */
    double ticks_per_s_per_rpm;
    double load_step;         /* percent of stall torque per Present Load unit */
    double torque_full;       /* Torque Limit at the full stall torque */
    double ambient_c;
    double max_step_s;        /* longest physics step */
    int direction_bit;        /* speed/load sign bit, as a value */
    int max_position;
} sim_servo_units;

typedef struct {
    const sim_servo_units *units;
    uint8_t *image;           /* the control table (the Python RegisterFile's bytes) */
    int size;
    /* model constants */
    double stall, moving_load, stall_rise, thermal_tau;
    int goal_max, speed_max;  /* write ranges of Goal Position, Moving Speed */
    /* registers mirrored for the physics ("shadows") and what follows from them */
    int goal, moving_speed, torque_enable, torque_limit;
    int cw_margin, ccw_margin, cw_limit, ccw_limit, temp_limit, shutdown, srl, id;
    int cw_slope, ccw_slope, punch;
    double speed_setting, vmax, vmax_wheel;
    _Bool wheel_mode, voltage_bad, ideal, world_driven, powered;
    /* the physical state */
    double t, pos, vel, temp, load_fraction, supply_v, external_torque;
    _Bool load_cw, moving, overload;
    int latched;
} sim_servo;

/* Bring the physical state forward to bus time t (nothing if t is not later). */
void sim_servo_advance(sim_servo *s, double t);
/* Refresh the present-state registers overlapping addresses first..end-1. */
void sim_servo_refresh_present(sim_servo *s, int first, int end);
/* The error bits of the conditions that hold now (voltage, heat, overload). */
int sim_servo_conditions(const sim_servo *s);
/* Errors in the Shutdown mask cut the torque and stay reported. */
void sim_servo_alarm(sim_servo *s, int flags);
/* A READ of `length` bytes at `address` heard at time t, answered with a status packet
 * into out (cap bytes): its length, or 0 if the general path must answer (a READ past
 * the table's end, a reply that does not fit). */
int sim_servo_read(sim_servo *s, double t, int address, int length, uint8_t *out, int cap);
/* A write of n bytes at `address` that is the write of Goal Position (n = 2) or Goal
 * Position + Moving Speed (n = 4), checked and stored with what it sets off: the error
 * bits (0: stored), or -1 if it is another write (the general path handles it). */
int sim_servo_write_goal(sim_servo *s, int address, const uint8_t *data, int n);
/* This servo's block of a SYNC_WRITE heard at time t: sim_servo_write_goal after the
 * motion is brought up to t, errors taken as alarms; 0, or -1 as above (the motion
 * is brought up to t all the same). */
int sim_servo_sync_block(sim_servo *s, double t, int address, const uint8_t *data, int n);
/* A broadcast SYNC_WRITE (params: address, length, then ID + length bytes per servo, n
 * bytes in all, whole blocks) heard at time t: if it writes Goal Position (+ Moving
 * Speed), each servo named gets the first block that names it (sim_servo_sync_block)
 * and 0 is returned; otherwise nothing happens and -1 is returned (the general path
 * handles it). by_id[id] is the servo with that ID on the line, NULL if none. */
int sim_servo_sync_write(sim_servo *const *by_id, const uint8_t *params, int n, double t);
/* A whole frame of n bytes heard at time t by the servos of by_id (as above): if it is a
 * good READ for a servo there that answers READs, its status packet (sim_servo_read)
 * into out, and its length; 0 if the general path must handle the frame. */
int sim_servo_deliver_read(sim_servo *const *by_id, const uint8_t *frame, int n, double t,
                           uint8_t *out, int cap);
/* A whole frame of n bytes heard at time t by the servos of by_id (as above): if it is a
 * good broadcast SYNC_WRITE of Goal Position (+ Moving Speed) in whole blocks, it is
 * handled (sim_servo_sync_write) and 0 returned; -1 if the general path must handle the
 * frame (nothing has happened then). */
int sim_servo_deliver_sync_write(sim_servo *const *by_id, const uint8_t *frame, int n,
                                 double t);
/* A physics world's report at bus time t (ReferenceServo.set_motion): the joint's position
 * (ticks), speed (ticks/s), load (fraction of the stall torque; load_cw: pushing toward
 * smaller positions), whether it moves, whether the load exceeds what it may give. Heat
 * and alarms follow as for the servo's own motion. */
void sim_servo_set_motion(sim_servo *s, double t, double pos, double vel, double load_fraction,
                          _Bool load_cw, _Bool moving, _Bool overload);
/* What the position controller works from (ReferenceServo.controller), into
 * out[SIM_SERVO_CONTROLLER]: goal, speed setting (ticks/s, inf: no limit), torque on (0/1),
 * Torque Limit, CW and CCW margin, CW and CCW slope, Punch, supply volts, wheel mode (0/1),
 * raw Moving Speed. */
#define SIM_SERVO_CONTROLLER 12
void sim_servo_controller(const sim_servo *s, double *out);
/* cffi:end */

#endif
