#include "prog_limits.h"

#include "ax12_table.h"
#include "ctl_table.h"
#include "play_fixed.h"

#define MRAD_PER_RAD 1000u

bool prog_joint_fits(const play_joint *j, uint16_t amp_mrad, int16_t phi0_mrad,
                     int16_t steering)
{
    /* the wave's extremes, in ticks from the zero tick, exactly as the player rounds them */
    int32_t top = play_serp_ticks(amp_mrad, phi0_mrad, (uint32_t)PLAY_BAM_QUARTER);
    int32_t bottom = play_serp_ticks(amp_mrad, phi0_mrad, 3u * (uint32_t)PLAY_BAM_QUARTER);
    int32_t sign = j->reverse ? -1 : 1;
    int32_t a = (int32_t)j->zero + sign * (top + steering);
    int32_t b = (int32_t)j->zero + sign * (bottom + steering);
    int32_t lo = a < b ? a : b;
    int32_t hi = a < b ? b : a;
    return lo >= (int32_t)j->min && hi <= (int32_t)j->max;
}

bool prog_speed_fits(uint16_t amp_mrad, int16_t omega_mrad_s, uint16_t speed_scale)
{
    /* peak joint speed A |omega| * scale / 256 (mrad/s), kept in integers */
    uint64_t omega = (uint64_t)(omega_mrad_s < 0 ? -(int32_t)omega_mrad_s : omega_mrad_s);
    uint64_t peak = (uint64_t)amp_mrad * omega * speed_scale;
    return peak <= (uint64_t)AX12_MAX_SPEED_MRAD_S * MRAD_PER_RAD * CTL_SPEED_SCALE_ONE;
}

uint8_t prog_check_serpenoid(const play_joint *roster, uint8_t count, uint16_t amp_mrad,
                             int16_t omega_mrad_s, int16_t phi0_mrad, int16_t steering,
                             uint16_t speed_scale)
{
    for (uint8_t k = 0; k < count; k++) {
        if (!prog_joint_fits(&roster[k], amp_mrad, phi0_mrad, steering)) {
            return CTL_REFUSAL_REASON_AMPLITUDE;
        }
    }
    if (!prog_speed_fits(amp_mrad, omega_mrad_s, speed_scale)) return CTL_REFUSAL_REASON_SPEED;
    return CTL_REFUSAL_REASON_NONE;
}
