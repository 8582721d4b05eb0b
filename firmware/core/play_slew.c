#include "play_slew.h"

#include <stdbool.h>

#include "ax12_table.h"
#include "play_fixed.h"

/* The servo's top speed in ticks per second * 256 and per millisecond (Q30), and ticks
 * per milliradian (Q24) and its inverse (Q16), all from the AX-12's description
 * (ax12_table.h). Divisions by them are multiplications by 32-bit constants: a 64-bit
 * literal would 8-align the code and leave a gap in the image after its header. */
#define TOP_TICKS_S_Q8 \
    ((uint32_t)(((uint64_t)AX12_SPEED_MAX << (18 + 8)) / AX12_SPEED_UNITS_PER_TICK_S_Q18))
#define TOP_TICKS_MS_Q30                                          \
    ((uint32_t)(((uint64_t)AX12_SPEED_MAX << (18 + 30)) /          \
                ((uint64_t)AX12_SPEED_UNITS_PER_TICK_S_Q18 * 1000u)))
#define TICKS_PER_MRAD_Q24 ((uint32_t)AX12_TICKS_PER_MRAD_Q24)
#define MRAD_PER_TICK_Q16 ((uint32_t)((1ULL << (24 + 16)) / AX12_TICKS_PER_MRAD_Q24))
/* ms per s, and ms per s * 256 (a rate in ticks/s * 256 times ms, to ticks). */
#define MS_PER_S 1000u
#define MS_PER_S_Q8 256000u

void play_slew_reset(play_slew *s)
{
    s->primed = 0;
}

uint32_t play_slew_step_bound(uint32_t dt_ms)
{
    return (uint32_t)(((uint64_t)TOP_TICKS_MS_Q30 * dt_ms) >> 30);
}

/* now moved toward target by at most max_step, and always by at least one unit. */
static int32_t approach(int32_t now, int32_t target, uint64_t max_step)
{
    int32_t step = max_step == 0 ? 1 : max_step > 0xFFFFu ? 0xFFFF : (int32_t)max_step;
    if (target - now > step) return now + step;
    if (now - target > step) return now - step;
    return target;
}

static uint32_t magnitude(int32_t v)
{
    return (uint32_t)(v < 0 ? -v : v);
}

/* Whether moving a signed factor from now toward target first brings it nearer zero. */
static bool shrinks(int32_t now, int32_t target)
{
    return now > 0 ? target < now : now < 0 && target > now;
}

/* Milliradians a joint angle may change in `ticks` ticks, and the ticks `mrad` takes. */
static uint64_t mrad_in_ticks(uint32_t ticks)
{
    return ((uint64_t)ticks * MRAD_PER_TICK_Q16) >> 16; /* rounded down: never over */
}

static uint32_t ticks_of_mrad(uint32_t mrad)
{
    return (uint32_t)(((uint64_t)mrad * TICKS_PER_MRAD_Q24 + (1u << 24) - 1u) >> 24);
}

/* Largest change of a rate factor (omega or scale) that moves the wave's peak speed,
 * proportional to amp * other * factor, by at most dv_q8 ticks/s * 256; no limit when the
 * wave does not depend on it. */
static uint64_t ramp_step(uint64_t dv_q8, uint32_t amp, uint32_t other)
{
    /* the peak speed per unit of the factor, ticks/s * 256, times 1000 * 2^24 */
    uint64_t per_unit = (uint64_t)TICKS_PER_MRAD_Q24 * amp * other;
    if (per_unit == 0) return UINT64_MAX;
    return ((dv_q8 * MS_PER_S) << 24) / per_unit;
}

/* An angle (mrad) moved toward its target within *left ticks of goal motion; the ticks
 * it takes move from *left to *used. */
static int32_t slew_angle(int32_t now, int32_t target, uint32_t *left, uint32_t *used)
{
    int32_t next = approach(now, target, mrad_in_ticks(*left));
    uint32_t ticks = ticks_of_mrad(magnitude(next - now));
    *used += ticks;
    *left = *left > ticks ? *left - ticks : 0u;
    return next;
}

uint32_t play_slew_toward(play_slew *s, const play_slew *target, uint32_t dt_ms)
{
    if (!s->primed) {
        *s = *target;
        s->primed = 1;
        return 0;
    }
    if (dt_ms == 0) return 0;

    /* The wave's speed is A |omega| scale: a factor grows only once none shrinks, so on
     * the way the speed never passes above both its old and its new value. */
    bool omega_shrinks = shrinks(s->omega_mrad_s, target->omega_mrad_s);
    bool hold = omega_shrinks || target->amp_mrad < s->amp_mrad ||
                target->speed_scale < s->speed_scale;
    uint64_t dv_q8 = (uint64_t)TOP_TICKS_S_Q8 * dt_ms / PLAY_SLEW_RAMP_MS;
    if (omega_shrinks || !hold) {
        /* a reversal stops at zero first: past it, omega grows */
        bool reverses = (s->omega_mrad_s < 0) != (target->omega_mrad_s < 0);
        int32_t goal = omega_shrinks && reverses ? 0 : target->omega_mrad_s;
        s->omega_mrad_s = (int16_t)approach(s->omega_mrad_s, goal,
                                            ramp_step(dv_q8, s->amp_mrad, s->speed_scale));
    }
    if (target->speed_scale < s->speed_scale || !hold) {
        s->speed_scale = (uint16_t)approach(
            s->speed_scale, target->speed_scale,
            ramp_step(dv_q8, s->amp_mrad, magnitude(s->omega_mrad_s)));
    }

    /* What the wave moves a goal this tick, rounded up; the rest is the parameters'. */
    uint64_t wave_q8 = (uint64_t)play_serp_rate_q8(s->amp_mrad, s->omega_mrad_s, s->speed_scale,
                                                   0) * dt_ms;
    uint64_t wave = (wave_q8 + MS_PER_S_Q8 - 1u) / MS_PER_S_Q8;
    uint64_t bound = play_slew_step_bound(dt_ms);
    uint32_t left = bound > wave + 2u ? (uint32_t)(bound - wave - 2u) : 0u;
    uint32_t used = 0;

    if (target->amp_mrad < s->amp_mrad || !hold) {
        s->amp_mrad = (uint16_t)slew_angle(s->amp_mrad, target->amp_mrad, &left, &used);
    }
    s->phi0_mrad = (int16_t)slew_angle(s->phi0_mrad, target->phi0_mrad, &left, &used);
    int32_t steering = approach(s->steering, target->steering, left);
    used += magnitude(steering - s->steering);
    s->steering = (int16_t)steering;
    return (uint32_t)((uint64_t)used * MS_PER_S_Q8 / dt_ms);
}
