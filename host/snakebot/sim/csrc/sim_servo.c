/* The emulated AX-12's hot path (see sim_servo.h); every step mirrors
 * snakebot.sim.servo.reference.ReferenceServo, operation for operation, so the two agree to the
 * last bit (rounding half to even as Python's round does, Python's float modulo). */
#include "sim_servo.h"

#include <math.h>

#include "ax12_table.h"
#include "dxl_packet.h"

static double py_mod(double x, double y) {
    /* Python's float %: the result takes the sign of the divisor */
    double m = fmod(x, y);
    if (m != 0.0) {
        if ((y < 0.0) != (m < 0.0)) {
            m += y;
        }
    } else {
        m = copysign(0.0, y);
    }
    return m;
}

static void put16(uint8_t *image, int address, int value) {
    image[address] = (uint8_t)(value & 0xFF);
    image[address + 1] = (uint8_t)((value >> 8) & 0xFF);
}

static int clamp_byte(double value) {
    double r = nearbyint(value);
    return r < 0.0 ? 0 : (r > 255.0 ? 255 : (int)r);
}

int sim_servo_conditions(const sim_servo *s) {
    int flags = s->voltage_bad ? DXL_ERR_INPUT_VOLTAGE : 0;
    if (nearbyint(s->temp) > s->temp_limit) {
        flags |= DXL_ERR_OVERHEATING;
    }
    if (s->overload) {
        flags |= DXL_ERR_OVERLOAD;
    }
    return flags;
}

void sim_servo_alarm(sim_servo *s, int flags) {
    int shut = flags & s->shutdown;
    if (shut) {
        put16(s->image, AX12_TORQUE_LIMIT, 0);
        s->torque_limit = 0;
        s->latched |= shut;
        s->overload = 0;
    }
}

static double thermal(const sim_servo *s, double temp, double fraction, double dt) {
    double steady = s->units->ambient_c + s->stall_rise * fraction * fraction;
    return steady + (temp - steady) * exp(-dt / s->thermal_tau);
}

static void heat(sim_servo *s, double fraction, double dt) {
    double temp = s->temp;
    if (fraction != 0.0 || temp != s->units->ambient_c) {
        temp = s->temp = thermal(s, temp, fraction, dt);
    }
    if (s->overload || s->voltage_bad || temp >= s->temp_limit + 0.5) {
        int conditions = sim_servo_conditions(s);
        if (conditions & s->shutdown) {
            sim_servo_alarm(s, conditions);
        }
    }
}

static void step(sim_servo *s, double dt) {
    const sim_servo_units *u = s->units;
    if (s->world_driven) { /* the world set the motion; heat and alarms stay ours */
        if (s->powered) {
            heat(s, s->load_fraction, dt);
        } else {
            s->temp = thermal(s, s->temp, 0.0, dt);
        }
        return;
    }
    if (!s->powered) {
        s->vel = 0.0;
        s->moving = 0;
        s->overload = 0;
        s->load_fraction = 0.0;
        s->temp = thermal(s, s->temp, 0.0, dt);
        return;
    }
    int limit = s->torque_limit;
    _Bool torque_on = s->torque_enable == 1 && limit > 0;
    double external = s->external_torque;
    double load = 0.0, available = 0.0, scale = 0.0;
    _Bool overload = 0;
    if (external != 0.0) {
        available = s->stall * limit / u->torque_full;
        load = external < 0.0 ? -external : external;
        overload = torque_on && load > available;
        scale = 1.0 - load / s->stall;
    }
    double old = s->pos;
    double now = old;
    _Bool moving = 0;
    _Bool wheel = s->wheel_mode;
    if (torque_on && !overload) {
        if (wheel) {
            int value = s->moving_speed;
            int speed_max = u->direction_bit - 1;
            double v = (double)(value & speed_max) / speed_max * s->vmax_wheel;
            if (external != 0.0) {
                v *= scale;
            }
            if (value & u->direction_bit) {
                v = -v;
            }
            now = py_mod(old + v * dt, u->ticks_per_rev);
            moving = v != 0.0;
        } else if (s->ideal) {
            now = (double)s->goal;
        } else {
            int low = s->goal - s->cw_margin;
            int high = s->goal + s->ccw_margin;
            if (old < low || old > high) {
                double vmax = external != 0.0 ? s->vmax * scale : s->vmax;
                double speed = s->speed_setting;
                double stride = (speed > vmax ? vmax : speed) * dt;
                if (old < low) {
                    now = old + stride;
                    if (now >= low) {
                        now = (double)low;
                    }
                } else {
                    now = old - stride;
                    if (now <= high) {
                        now = (double)high;
                    }
                }
                moving = !(low <= now && now <= high);
            }
        }
    }
    s->pos = now;
    double delta = now - old;
    if (wheel && fabs(delta) > u->ticks_per_rev / 2) {
        delta -= delta > 0 ? u->ticks_per_rev : -u->ticks_per_rev;
    }
    s->vel = delta / dt;
    s->moving = moving;
    s->overload = overload;
    double fraction;
    if (!torque_on) {
        fraction = 0.0;
    } else if (overload) {
        fraction = available / s->stall;
    } else if (external != 0.0) {
        fraction = load / s->stall + (delta != 0.0 ? s->moving_load : 0.0);
    } else {
        fraction = delta != 0.0 ? s->moving_load : 0.0;
    }
    s->load_fraction = fraction < 1.0 ? fraction : 1.0;
    s->load_cw = external != 0.0 ? external > 0 : delta < 0;
    heat(s, fraction, dt);
}

void sim_servo_advance(sim_servo *s, double t) {
    double dt_total = t - s->t;
    if (dt_total <= 0.0) {
        return;
    }
    double max_step = s->units->max_step_s;
    while (dt_total > max_step) {
        step(s, max_step);
        dt_total -= max_step;
    }
    step(s, dt_total);
    s->t = t;
}

void sim_servo_set_motion(sim_servo *s, double t, double pos, double vel, double load_fraction,
                          _Bool load_cw, _Bool moving, _Bool overload) {
    s->world_driven = 1;
    sim_servo_advance(s, t);
    s->pos = pos;
    s->vel = vel;
    s->load_fraction = load_fraction < 1.0 ? load_fraction : 1.0;
    s->load_cw = load_cw;
    s->moving = moving;
    s->overload = overload && s->powered;
    if (s->overload) {
        int conditions = sim_servo_conditions(s);
        if (conditions & s->shutdown) {
            sim_servo_alarm(s, conditions);
        }
    }
}

void sim_servo_controller(const sim_servo *s, double *out) {
    _Bool on = s->powered && s->torque_enable == 1 && s->torque_limit > 0;
    out[0] = s->goal;
    out[1] = s->speed_setting;
    out[2] = on ? 1.0 : 0.0;
    out[3] = s->torque_limit;
    out[4] = s->cw_margin;
    out[5] = s->ccw_margin;
    out[6] = s->cw_slope;
    out[7] = s->ccw_slope;
    out[8] = s->punch;
    out[9] = s->supply_v;
    out[10] = s->wheel_mode ? 1.0 : 0.0;
    out[11] = s->moving_speed;
}

static int signed_magnitude(const sim_servo_units *u, double magnitude, _Bool negative) {
    /* min(SPEED_MAX, magnitude), the direction bit set for a negative non-zero value */
    int speed_max = u->direction_bit - 1;
    int m = magnitude > speed_max ? speed_max : (int)magnitude;
    return negative && m > 0 ? (u->direction_bit | m) : m;
}

void sim_servo_refresh_present(sim_servo *s, int first, int end) {
    const sim_servo_units *u = s->units;
    uint8_t *image = s->image;
    if (first < AX12_PRESENT_POSITION + 2 && AX12_PRESENT_POSITION < end) {
        double p = nearbyint(s->pos);
        int value = p < 0.0 ? 0 : (p > u->max_position ? u->max_position : (int)p);
        put16(image, AX12_PRESENT_POSITION, value);
    }
    if (first < AX12_PRESENT_SPEED + 2 && AX12_PRESENT_SPEED < end) {
        double magnitude = nearbyint(fabs(s->vel) / u->speed_unit);
        put16(image, AX12_PRESENT_SPEED, signed_magnitude(u, magnitude, s->vel < 0));
    }
    if (first < AX12_PRESENT_LOAD + 2 && AX12_PRESENT_LOAD < end) {
        double raw = nearbyint(100.0 * s->load_fraction / u->load_step);
        if (raw < 0.0) { /* the encoding of a negative value, as the register holds it */
            raw = (double)(u->direction_bit | (int)-raw);
        }
        put16(image, AX12_PRESENT_LOAD, signed_magnitude(u, raw, s->load_cw));
    }
    if (first <= AX12_PRESENT_VOLTAGE && AX12_PRESENT_VOLTAGE < end) {
        image[AX12_PRESENT_VOLTAGE] = (uint8_t)clamp_byte(s->supply_v * 10);
    }
    if (first <= AX12_PRESENT_TEMPERATURE && AX12_PRESENT_TEMPERATURE < end) {
        image[AX12_PRESENT_TEMPERATURE] = (uint8_t)clamp_byte(s->temp);
    }
    if (first <= AX12_MOVING && AX12_MOVING < end) {
        image[AX12_MOVING] = s->moving ? 1 : 0;
    }
}

int sim_servo_read(sim_servo *s, double t, int address, int length, uint8_t *out, int cap) {
    sim_servo_advance(s, t);
    sim_servo_refresh_present(s, address, address + length);
    if (length < 1 || address + length > s->size || length > DXL_MAX_PARAMS) {
        return 0;
    }
    int error = sim_servo_conditions(s) | s->latched;
    return (int)dxl_status(out, (size_t)cap, (uint8_t)s->id, (uint8_t)error,
                           s->image + address, (size_t)length);
}

int sim_servo_write_goal(sim_servo *s, int address, const uint8_t *data, int n) {
    if (address != AX12_GOAL_POSITION || (n != 2 && n != 4)) {
        return -1;
    }
    int goal = data[0] | data[1] << 8;
    int speed = n == 4 ? (data[2] | data[3] << 8) : 0;
    int speed_max = s->units->direction_bit - 1;
    if (goal > s->goal_max || speed > s->speed_max) {
        return DXL_ERR_RANGE;
    }
    if (s->cw_limit || s->ccw_limit) { /* joint mode */
        if (!(s->cw_limit <= goal && goal <= s->ccw_limit)) {
            return DXL_ERR_ANGLE_LIMIT;
        }
        if (speed > speed_max) {
            return DXL_ERR_RANGE;
        }
    }
    for (int i = 0; i < n; i++) {
        s->image[address + i] = data[i];
    }
    s->goal = goal;
    if (n == 4) {
        int value = speed & speed_max;
        s->moving_speed = speed;
        s->speed_setting = value == 0 ? INFINITY
                                      : value * s->units->speed_unit_rpm *
                                            s->units->ticks_per_s_per_rpm;
    }
    if (s->torque_enable != 1) { /* a goal switches the torque on */
        s->image[AX12_TORQUE_ENABLE] = 1;
        s->torque_enable = 1;
    }
    return 0;
}

int sim_servo_sync_block(sim_servo *s, double t, int address, const uint8_t *data, int n) {
    if (!s->powered) {
        return 0;
    }
    sim_servo_advance(s, t);
    int flags = sim_servo_write_goal(s, address, data, n);
    if (flags > 0) {
        sim_servo_alarm(s, flags);
    }
    return flags < 0 ? -1 : 0;
}

int sim_servo_sync_write(sim_servo *const *by_id, const uint8_t *params, int n, double t) {
    int address = params[0], length = params[1], block = length + 1;
    if (address != AX12_GOAL_POSITION || (length != 2 && length != 4)) {
        return -1;
    }
    uint8_t done[256] = {0};
    for (int i = 2; i + block <= n; i += block) {
        int id = params[i];
        sim_servo *s = by_id[id];
        if (s == NULL || done[id]) { /* nobody, or not the first block naming it */
            continue;
        }
        done[id] = 1;
        sim_servo_sync_block(s, t, address, params + i + 1, length);
    }
    return 0;
}

int sim_servo_deliver_read(sim_servo *const *by_id, const uint8_t *frame, int n, double t,
                           uint8_t *out, int cap) {
    /* FF FF ID LEN=4 READ address length CHK; the checksum does not cover the header,
     * so a header damaged on the wire (a collision) must be caught here */
    if (n != 8 || frame[0] != DXL_HEADER_BYTE || frame[1] != DXL_HEADER_BYTE || frame[3] != 4 ||
        frame[4] != DXL_INST_READ) {
        return 0;
    }
    sim_servo *s = by_id[frame[2]];
    if (s == NULL || !s->powered || !s->srl || dxl_checksum(frame + 2, 5) != frame[7]) {
        return 0;
    }
    return sim_servo_read(s, t, frame[5], frame[6], out, cap);
}

int sim_servo_deliver_sync_write(sim_servo *const *by_id, const uint8_t *frame, int n,
                                 double t) {
    /* FF FF FE LEN SYNC_WRITE address length (ID data...)... CHK, as the general path
     * takes it unparsed: whole, within the packet cap, the checksum good, and the
     * parameters split into whole blocks (else no servo finds its slice) */
    if (n < 8 || n > DXL_MAX_PACKET || frame[0] != DXL_HEADER_BYTE ||
        frame[1] != DXL_HEADER_BYTE || frame[2] != DXL_BROADCAST_ID || frame[3] + 4 != n ||
        frame[4] != DXL_INST_SYNC_WRITE ||
        dxl_checksum(frame + 2, (size_t)n - 3) != frame[n - 1]) {
        return -1;
    }
    const uint8_t *params = frame + 5;
    int length = params[1], count = n - 6;
    if (length == 0 || (count - 2) % (length + 1)) {
        return -1;
    }
    return sim_servo_sync_write(by_id, params, count, t);
}
