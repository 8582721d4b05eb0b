/* The physics world's per-tick coupling (see sim_world.h); every expression keeps the
 * order of operations of the Python it mirrors, so the results agree to the last bit. */
#include "sim_world.h"

#include <math.h>

int sim_actuator_drive(const sim_actuator *a, const double *controller, double pos_ticks,
                       double *out) {
    const double *c = controller;
    double goal = c[0], speed = c[1], limit = c[3], cw_m = c[4], ccw_m = c[5];
    double cw_s = c[6], ccw_s = c[7], punch = c[8], volts = c[9], raw = c[11];
    out[0] = out[1] = out[2] = out[3] = 0.0;
    if (c[2] == 0.0) { /* torque off */
        return 0;
    }
    double limit_cap = limit / a->duty_full;
    if (c[10] != 0.0) { /* wheel mode: the duty is Moving Speed's */
        int value = (int)raw;
        double u = (double)(value & (a->direction_bit - 1)) / a->duty_full;
        if (value & a->direction_bit) {
            u = -u;
        }
        out[2] = u;
        out[3] = limit_cap;
        return fabs(u) > limit_cap;
    }
    double error = goal - pos_ticks;
    double side, margin, slope;
    if (error > ccw_m) {
        side = 1.0, margin = ccw_m, slope = ccw_s;
    } else if (error < -cw_m) {
        side = -1.0, margin = cw_m, slope = cw_s;
    } else { /* inside the compliance margin: let go */
        return 0;
    }
    double base = punch / a->duty_full;
    /* duty = side * (base + (1 - base) * (|error| - margin) / slope), saturating at 1 */
    double gain = (1.0 - base) / slope;
    double bias = side * (base - gain * margin);
    double asked = fabs(gain * error + bias);
    double wanted = asked < 1.0 ? asked : 1.0;
    /* the speed setting: the duty that turns the unloaded motor at that speed */
    double no_load_ticks = a->no_load_rad_s * a->ticks_per_rad * volts / a->nominal_v;
    double speed_cap = no_load_ticks > 0 ? speed / no_load_ticks : 0.0;
    double cap = 1.0; /* the least of 1, limit_cap, speed_cap, as Python's min picks it */
    if (limit_cap < cap) {
        cap = limit_cap;
    }
    if (speed_cap < cap) {
        cap = speed_cap;
    }
    out[0] = gain;
    out[1] = goal;
    out[2] = bias;
    out[3] = cap;
    /* a cap cuts when the controller asks for more than the drive allowed: Torque Limit's
     * or (speed_limit "drive") Moving Speed's, whichever binds; no supply, no cut */
    return wanted > cap && no_load_ticks > 0;
}

double sim_actuator_power(const sim_actuator *a, double torque_nm, double speed_rad_s) {
    double tau = torque_nm;
    double power = tau * tau * a->no_load_rad_s / a->stall_nm + tau * speed_rad_s;
    return power > 0.0 ? power : 0.0;
}

void sim_world_measure(sim_world *w) {
    for (int k = 0; k < w->n; k++) {
        double speed = w->qvel[w->dadr[k]];
        w->speed[k] = speed;
        w->torque[k] = speed * w->brake + w->force[k];
    }
}

void sim_world_account(sim_world *w) {
    sim_world_measure(w);
    double dt = w->dt;
    for (int k = 0; k < w->n; k++) {
        double tau = w->torque[k], speed = w->speed[k];
        w->energy[k] += tau * speed * dt;
        w->electrical[k] += sim_actuator_power(w->actuator, tau, speed) * dt;
    }
}

int sim_world_sample(const sim_world *w, double t, double *row) {
    /* plain sums in order, as the Python check summed its lists */
    double q = 0.0, v = 0.0;
    for (int i = 0; i < w->nq; i++) {
        q += w->qpos[i];
    }
    for (int i = 0; i < w->nv; i++) {
        v += w->qvel[i];
    }
    if (!isfinite(q + v)) {
        return SIM_WORLD_BLEW_UP;
    }
    double z = 0.0; /* each link stays level: its wheel sinks with it */
    for (int i = 0; i < w->nz; i++) {
        z += w->qpos[w->zadr[i]];
        if (z < w->min_z) {
            return SIM_WORLD_SANK;
        }
    }
    *row++ = t - w->start;
    for (int g = 0; g < w->ngathers; g++) {
        const sim_gather *piece = &w->gathers[g];
        for (int i = 0; i < piece->n; i++) {
            *row++ = piece->source[piece->index[i]];
        }
    }
    return 0;
}

void sim_world_couple(sim_world *w, double t) {
    const sim_actuator *a = w->actuator;
    double tpr = a->ticks_per_rad, stall_nm = a->stall_nm;
    double stall_per_volt = a->stall_nm / a->nominal_v; /* Actuator.stall_at */
    double controls[SIM_SERVO_CONTROLLER], drive[4];
    for (int k = 0; k < w->n; k++) {
        sim_servo *servo = w->servos[k];
        double sign = w->sign[k], zero = w->zero[k];
        double pos = zero + sign * w->qpos[w->qadr[k]] * tpr;
        double speed = w->speed[k], tau = w->torque[k];
        _Bool on = w->on[k];
        /* a servo with its torque off drives nothing and reports no load (the gear train
         * still brakes the joint: that stays in the physics) */
        sim_servo_set_motion(servo, t, pos, sign * speed * tpr, on ? fabs(tau) / stall_nm : 0.0,
                             on && tau * sign < 0, w->moving[k], w->stalled[k] >= w->hold);
        sim_servo_controller(servo, controls);
        _Bool was_on = on;
        w->on[k] = controls[2] != 0.0;
        if (w->profile) {
            /* the speed setting moves the target (INFINITY, Moving Speed 0: at once) */
            double goal = controls[0], step = controls[1] * w->period;
            double ref = was_on ? w->reference[k] : pos;
            if (goal > ref + step) {
                ref += step;
            } else if (goal < ref - step) {
                ref -= step;
            } else {
                ref = goal;
            }
            w->reference[k] = ref;
            controls[0] = ref;
            controls[1] = INFINITY;
        }
        int cut = sim_actuator_drive(a, controls, pos, drive);
        double gain = drive[0], target = drive[1], offset = drive[2], cap = drive[3];
        double volts = controls[9];
        double stall = volts > 0.0 ? stall_per_volt * volts : 0.0;
        /* duty = gain * (target - ticks) + offset, ticks = zero + sign * ticks_per_rad * q,
         * as a joint torque (sign * stall * duty) affine in the joint angle q */
        double *bias = w->biasprm + k * w->nbias;
        bias[0] = sign * stall * (gain * (target - zero) + offset);
        bias[1] = -stall * gain * tpr;
        double high = stall * cap;
        w->forcerange[2 * k] = -high;
        w->forcerange[2 * k + 1] = high;
        /* stalled: held by the load well below the speed the allowed drive gives unloaded */
        double free_speed = a->no_load_rad_s * volts / a->nominal_v * cap;
        _Bool stalled = fabs(speed) < w->stalled_fraction * free_speed;
        w->stalled[k] = cut && stalled ? w->stalled[k] + w->period : 0.0;
        w->moving[k] = gain != 0.0 || offset != 0.0;
    }
}

int sim_joints_period(sim_joints *j) {
    sim_world *w = j->world;
    int n = w->n, nbias = w->nbias;
    double dt = w->dt, inertia = j->armature / dt, xi[3], xi1[3];
    double per_speed = inertia - w->brake; /* N m per rad/s of the step's end speed */
    double *phi = j->q + 3;
    double free[KIN_MAX_JOINTS], tried[KIN_MAX_JOINTS], load1[KIN_MAX_JOINTS];
    _Bool held[KIN_MAX_JOINTS];
    for (int s = 0; s < j->steps; s++) {
        int code = kin_quasi_static(j->rb, j->q, j->speed, xi, NULL, j->load);
        if (code == KIN_OK && s == j->slip_step) {
            double qdot[3 + KIN_MAX_JOINTS];
            for (int i = 0; i < 3; i++) {
                qdot[i] = xi[i];
            }
            for (int k = 0; k < n; k++) {
                qdot[3 + k] = j->speed[k];
            }
            code = kin_wheel_speeds(j->rb, j->q, qdot, j->slip, NULL);
        }
        if (code != KIN_OK) {
            return code;
        }
        for (int i = 0; i < 3; i++) {
            j->q[i] += dt * xi[i];
        }
        for (int k = 0; k < n; k++) {
            const double *bias = w->biasprm + k * nbias;
            double drive = bias[0] + bias[1] * phi[k];
            double high = w->forcerange[2 * k + 1], low = w->forcerange[2 * k];
            drive = drive > high ? high : (drive < low ? low : drive);
            j->force[k] = drive;
            j->load[k] *= j->unit_m;
            free[k] = (inertia * j->speed[k] + drive + j->external[k]) / per_speed;
            tried[k] = free[k] - j->load[k] / per_speed;
            /* held at its stop: the stop, not the body, takes what pushes it there */
            held[k] = (phi[k] <= j->lo[k] && tried[k] < 0.0) ||
                      (phi[k] >= j->hi[k] && tried[k] > 0.0);
            if (held[k]) {
                tried[k] = 0.0;
            }
        }
        code = kin_quasi_static(j->rb, j->q, tried, xi1, NULL, load1);
        if (code != KIN_OK) {
            return code;
        }
        double dd = 0.0, db = 0.0;
        for (int k = 0; k < n; k++) {
            load1[k] *= j->unit_m;
            if (held[k]) { /* its speed is the stop's: no part in the step's prox */
                continue;
            }
            double d = j->load[k] - load1[k];
            dd += d * d;
            db += d * (free[k] - load1[k] / per_speed);
        }
        if (dd > 0.0) { /* the speeds tried meet another piece's load: the prox of both */
            double alpha = db > 0.0 ? per_speed * db / dd : 0.0;
            alpha = alpha < 1.0 ? alpha : 1.0;
            for (int k = 0; k < n; k++) {
                j->load[k] = alpha * j->load[k] + (1.0 - alpha) * load1[k];
            }
        }
        /* The body only takes power from the joints (the wheels' friction): with nothing
         * driving them (torque off, inside their margins, no push), a load that drives them
         * (two pieces' blend, near rest) would keep them chattering and creeping. There the
         * body holds them instead. */
        double power = 0.0;
        _Bool passive = 1;
        for (int k = 0; k < n; k++) {
            if (!held[k]) {
                power += j->load[k] * (free[k] - j->load[k] / per_speed);
                passive = passive && j->force[k] == 0.0 && j->external[k] == 0.0;
            }
        }
        _Bool rest = passive && power < 0.0;
        for (int k = 0; k < n; k++) {
            if (rest && !held[k]) { /* the body holds each joint with what it asked */
                j->load[k] = per_speed * free[k];
            }
            j->speed[k] = held[k] || rest ? 0.0 : free[k] - j->load[k] / per_speed;
            phi[k] += dt * j->speed[k];
            if (phi[k] < j->lo[k] || phi[k] > j->hi[k]) { /* at its stop */
                phi[k] = phi[k] < j->lo[k] ? j->lo[k] : j->hi[k];
                j->speed[k] = 0.0;
            }
        }
        sim_world_account(w);
    }
    return KIN_OK;
}
