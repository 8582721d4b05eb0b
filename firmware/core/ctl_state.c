/* The controller's state machine and safety (protocol/controller.md): State and Error
 * Flags, the commands (PLAY, SERPENOID, PROGRAM_RUN, LIBRARY_PLAY, STOP, CLEAR) and why
 * one is refused, the robot's buttons, and the control tick's safety checks and player. */
#include "ctl_device_internal.h"

#include "play_safety.h"
#include "prog_limits.h"

/* ---- state changes --------------------------------------------------------------------- */

static void set_state(ctl_device *d, uint8_t s)
{
    d->regs[CTL_STATE] = s;
}

void ctl_raise_flags(ctl_device *d, uint16_t flags)
{
    set_reg(d, CTL_ERROR_FLAGS, 2, reg(d, CTL_ERROR_FLAGS, 2) | flags);
}

static bool moving(const ctl_device *d)
{
    return state(d) == CTL_STATE_PLAYING || state(d) == CTL_STATE_SERPENOID;
}

static void enter_safe(ctl_device *d, uint16_t faults)
{
    ctl_raise_flags(d, faults);
    if (state(d) == CTL_STATE_SAFE) return;
    play_stop(&d->player);
    set_state(d, CTL_STATE_SAFE);
    if (reg(d, CTL_SAFE_ACTION, 1) == CTL_SAFE_ACTION_TORQUE_OFF) {
        bus_request_torque(&d->bus, BUS_TORQUE_OFF);
    }
}

void ctl_stop_motion(ctl_device *d)
{
    if (moving(d)) set_state(d, CTL_STATE_IDLE);
    play_stop(&d->player);
}

/* The servos hold the robot's limits, or none are set. */
static bool limits_ready(const ctl_device *d)
{
    uint8_t s = bus_limits_state(&d->bus);
    return s == CTL_LIMITS_STATE_NONE || s == CTL_LIMITS_STATE_VERIFIED;
}

static bool roster_ok(const ctl_device *d)
{
    uint8_t n = joint_count(d);
    if (n == 0) return false;
    for (uint8_t k = 0; k < n; k++) {
        const play_joint *j = &d->roster[k];
        if (j->min > j->max || !ctl_within_robot(d, j->id, j->min, j->max)) return false;
    }
    return true;
}

/* Why PLAY cannot run now (CTL_REFUSAL_REASON_*; NONE: it can). */
static uint8_t play_refusal(const ctl_device *d)
{
    gt_info info;
    if (state(d) == CTL_STATE_SAFE) return CTL_REFUSAL_REASON_SAFE_STATE;
    if (d->active_len == 0 || ctl_active_is_program(d)) return CTL_REFUSAL_REASON_NO_TABLE;
    if (!limits_ready(d)) return CTL_REFUSAL_REASON_LIMITS_NOT_VERIFIED;
    /* robot limits set after the table may be narrower than its own */
    if (ctl_check_table(d, d->active, d->active_len, &info) != GT_OK) {
        return CTL_REFUSAL_REASON_TABLE_OUTSIDE_LIMITS;
    }
    return CTL_REFUSAL_REASON_NONE;
}

/* Why PROGRAM_RUN cannot run now (CTL_REFUSAL_REASON_*; NONE: it can). */
static uint8_t program_refusal(const ctl_device *d)
{
    if (state(d) == CTL_STATE_SAFE) return CTL_REFUSAL_REASON_SAFE_STATE;
    if (!ctl_active_is_program(d)) return CTL_REFUSAL_REASON_NO_TABLE;
    if (!limits_ready(d)) return CTL_REFUSAL_REASON_LIMITS_NOT_VERIFIED;
    /* robot limits set after the program may be narrower than its joints' (the program
     * itself was validated when it became active and has not changed since) */
    if (!ctl_program_fits(d, d->active)) return CTL_REFUSAL_REASON_TABLE_OUTSIDE_LIMITS;
    return CTL_REFUSAL_REASON_NONE;
}

/* Whether the serpenoid, as its registers and the roster stand, stays within the roster's
 * limits and the servo's speed: a refusal reason (NONE: it does). */
static uint8_t serpenoid_fits(const ctl_device *d)
{
    return prog_check_serpenoid(d->roster, joint_count(d), (uint16_t)reg(d, CTL_SERP_AMPLITUDE, 2),
                                (int16_t)reg(d, CTL_SERP_OMEGA, 2), (int16_t)reg(d, CTL_SERP_PHI0, 2),
                                (int16_t)reg(d, CTL_STEERING_OFFSET, 2),
                                (uint16_t)reg(d, CTL_SPEED_SCALE, 2));
}

/* Why SERPENOID cannot run now (CTL_REFUSAL_REASON_*; NONE: it can). */
static uint8_t serpenoid_refusal(const ctl_device *d)
{
    if (state(d) == CTL_STATE_SAFE) return CTL_REFUSAL_REASON_SAFE_STATE;
    if (joint_count(d) == 0) return CTL_REFUSAL_REASON_EMPTY_ROSTER;
    if (!roster_ok(d)) return CTL_REFUSAL_REASON_BAD_JOINT_LIMITS;
    if (!limits_ready(d)) return CTL_REFUSAL_REASON_LIMITS_NOT_VERIFIED;
    return serpenoid_fits(d);
}

/* Make library slot `slot`'s table active, without it counting as a new table to persist
 * (it is kept in the library already), and PLAY it. */
static void library_play(ctl_device *d, uint8_t slot, uint32_t now_ms)
{
    const uint8_t *blob = NULL;
    uint16_t len = 0;
    uint32_t crc = 0;
    uint8_t result = lib_playable(&d->lib, slot, d->table_changed != 0, &blob, &len, &crc);
    if (result == CTL_UPLOAD_RESULT_OK && len > d->capacity) result = CTL_UPLOAD_RESULT_BAD_LENGTH;
    bool program = result == CTL_UPLOAD_RESULT_OK && ctl_is_program(blob, len);
    if (result == CTL_UPLOAD_RESULT_OK && blob != d->active) {
        uint8_t pending = d->table_changed;
        result = ctl_load_active(d, blob, len, crc,
                                 program ? CTL_UPLOAD_COMMIT_PROGRAM : CTL_UPLOAD_COMMIT_TABLE);
        d->table_changed = pending; /* kept in the library already, not a new table */
    }
    if (lib_note(&d->lib, result)) {
        ctl_raise_flags(d, CTL_ERROR_FLAGS_LIBRARY | CTL_ERROR_FLAGS_REFUSED);
        return;
    }
    ctl_command(d, program ? CTL_COMMAND_PROGRAM_RUN : CTL_COMMAND_PLAY, now_ms);
}

void ctl_command(ctl_device *d, uint8_t cmd, uint32_t now_ms)
{
    bool started = false;
    uint8_t why = CTL_REFUSAL_REASON_NONE;
    switch (cmd) {
    case CTL_COMMAND_PLAY:
        why = play_refusal(d);
        if (why != CTL_REFUSAL_REASON_NONE) break;
        started = play_start_table(&d->player, d->active, d->active_len, now_ms);
        if (started) set_state(d, CTL_STATE_PLAYING);
        else why = CTL_REFUSAL_REASON_NO_TABLE;
        break;
    case CTL_COMMAND_SERPENOID:
        why = serpenoid_refusal(d);
        if (why != CTL_REFUSAL_REASON_NONE) break;
        started = play_start_serpenoid(&d->player, joint_count(d), now_ms);
        if (started) set_state(d, CTL_STATE_SERPENOID);
        else why = CTL_REFUSAL_REASON_EMPTY_ROSTER;
        break;
    case CTL_COMMAND_LIBRARY_PLAY: library_play(d, d->lib.slot, now_ms); return;
    case CTL_COMMAND_PROGRAM_RUN:
        why = program_refusal(d);
        if (why != CTL_REFUSAL_REASON_NONE) break;
        play_start_program(&d->player, d->active, now_ms);
        set_state(d, CTL_STATE_PLAYING);
        started = true;
        break;
    case CTL_COMMAND_STOP: ctl_stop_motion(d); return;
    case CTL_COMMAND_CLEAR:
        set_reg(d, CTL_ERROR_FLAGS, 2, 0);
        bus_clear_faults(&d->bus);
        if (bus_limits_state(&d->bus) == CTL_LIMITS_STATE_FAILED) bus_recheck_limits(&d->bus);
        if (state(d) == CTL_STATE_SAFE) set_state(d, CTL_STATE_IDLE);
        return;
    default: return;
    }
    d->refusal = why;
    if (!started) {
        ctl_raise_flags(d, CTL_ERROR_FLAGS_REFUSED);
        return;
    }
    d->last_link_ms = now_ms;
    bus_request_torque(&d->bus, BUS_TORQUE_ON);
}

void ctl_set_library(ctl_device *d, const lib_store *store)
{
    lib_init(&d->lib, store);
}

void ctl_library_stored(ctl_device *d, uint8_t result)
{
    if (lib_note(&d->lib, result)) ctl_raise_flags(d, CTL_ERROR_FLAGS_LIBRARY);
    if (d->regs[CTL_UPLOAD_RESULT] == CTL_UPLOAD_RESULT_LIBRARY_STORING) {
        d->regs[CTL_UPLOAD_RESULT] = result;
    }
}

uint8_t ctl_buttons(ctl_device *d, uint8_t held, uint32_t now_ms)
{
    uint8_t slots = d->lib.store != NULL ? d->lib.store->slots : 0u;
    uint8_t action = lib_panel_tick(&d->lib.panel, held | d->lib.buttons, slots, moving(d));
    if (action == LIB_PANEL_STOP) ctl_command(d, CTL_COMMAND_STOP, now_ms);
    if (action == LIB_PANEL_PLAY) library_play(d, d->lib.panel.slot, now_ms);
    d->lib.leds = lib_panel_leds(&d->lib.panel, moving(d));
    return d->lib.leds;
}

/* serpenoid_fits() with the registers and the roster as the write of data[0..n) at start
 * (already range-checked) would leave them. */
uint8_t ctl_serpenoid_fits_after(const ctl_device *d, uint8_t start, const uint8_t *data,
                                 size_t n)
{
    uint8_t count = (uint8_t)ctl_value_after(d, CTL_JOINT_COUNT, 1, start, data, n);
    uint8_t page = byte_after(d, CTL_WINDOW_PAGE, start, data, n);
    uint16_t amp = (uint16_t)ctl_value_after(d, CTL_SERP_AMPLITUDE, 2, start, data, n);
    int16_t phi0 = (int16_t)ctl_value_after(d, CTL_SERP_PHI0, 2, start, data, n);
    int16_t steering = (int16_t)ctl_value_after(d, CTL_STEERING_OFFSET, 2, start, data, n);
    /* one joint at a time, its record as the write would leave it (no roster copy: the
     * PC link's deepest path is this one) */
    for (uint8_t k = 0; k < count && k < CTL_MAX_JOINTS; k++) {
        play_joint j = d->roster[k];
        if (page < CTL_SERVO_PAGES && k / CTL_SERVO_RECORDS == page) {
            uint8_t rec[CTL_SERVO_RECORD_SIZE];
            (void)ctl_check_record(d, k % CTL_SERVO_RECORDS, page, start, data, n, rec);
            ctl_record_write(&j, 0, rec);
        }
        if (!prog_joint_fits(&j, amp, phi0, steering)) return CTL_REFUSAL_REASON_AMPLITUDE;
    }
    if (!prog_speed_fits(amp, (int16_t)ctl_value_after(d, CTL_SERP_OMEGA, 2, start, data, n),
                         (uint16_t)ctl_value_after(d, CTL_SPEED_SCALE, 2, start, data, n))) {
        return CTL_REFUSAL_REASON_SPEED;
    }
    return CTL_REFUSAL_REASON_NONE;
}

/* ---- public ---------------------------------------------------------------------------- */

void ctl_tick(ctl_device *d, uint32_t now_ms)
{
    uint8_t errors[CTL_MAX_JOINTS];
    uint8_t missed[CTL_MAX_JOINTS];
    uint8_t n = bus_roster_count(&d->bus);
    for (uint8_t k = 0; k < n; k++) {
        const bus_servo *s = bus_servo_at(&d->bus, k);
        errors[k] = s->error;
        missed[k] = s->missed;
    }
    uint16_t faults = play_safety_check(errors, missed, n, d->regs[CTL_SERVO_ERROR_MASK],
                                        d->regs[CTL_BUS_LOSS_LIMIT], moving(d),
                                        now_ms - d->last_link_ms, d->regs[CTL_LINK_TIMEOUT]);
    if (faults != 0) enter_safe(d, faults);
    if (bus_limits_state(&d->bus) == CTL_LIMITS_STATE_FAILED) {
        ctl_raise_flags(d, CTL_ERROR_FLAGS_LIMITS);
    }

    play_params params;
    params.speed_scale = (uint16_t)reg(d, CTL_SPEED_SCALE, 2);
    params.steering = (int16_t)reg(d, CTL_STEERING_OFFSET, 2);
    params.loop = d->regs[CTL_LOOP];
    params.amp_mrad = (uint16_t)reg(d, CTL_SERP_AMPLITUDE, 2);
    params.omega_mrad_s = (int16_t)reg(d, CTL_SERP_OMEGA, 2);
    params.delta_mrad = (int16_t)reg(d, CTL_SERP_DELTA, 2);
    params.phi0_mrad = (int16_t)reg(d, CTL_SERP_PHI0, 2);
    d->out_count = play_tick(&d->player, &params, d->roster, joint_count(d), now_ms);
    if (moving(d) && play_mode(&d->player) == PLAY_MODE_IDLE) set_state(d, CTL_STATE_IDLE);
    ctl_refresh(d);
    bus_begin_tick(&d->bus);
}

uint8_t ctl_state(const ctl_device *d)
{
    return state(d);
}

uint16_t ctl_error_flags(const ctl_device *d)
{
    return (uint16_t)reg(d, CTL_ERROR_FLAGS, 2);
}
