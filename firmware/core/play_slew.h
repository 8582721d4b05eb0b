/* Live changes to a running serpenoid, slewed: the player keeps working copies of the
 * amplitude, offset phi0, steering offset, omega and speed scale and moves them toward
 * the controller's registers a little each control tick, instead of taking a new value
 * at once (a step in phi0 or A would be a step in every goal).
 *
 * The per-tick bound is what the servo covers at its top speed (AX12_SPEED_MAX through
 * the AX-12's speed unit, ax12_table.h) in the tick's dt. The wave's own motion takes
 * its share first (A |omega| scale dt, in ticks); what is left, less two ticks for the
 * rounding of two goals, goes to the amplitude, then phi0, then steering. So no goal
 * steps by more than the bound while the wave itself is slower than the servo by that
 * margin; a parameter still moves at least one unit a tick when nothing is left, so every
 * target is reached. Omega and the speed scale ramp so that the wave's peak speed
 * changes by at most the servo's top speed per PLAY_SLEW_RAMP_MS, and of the speed's
 * factors (amplitude, |omega|, scale) none grows while another still shrinks, so the
 * speed on the way stays below the larger of the old and the new one; the phase is
 * integrated (play_player.c), so a change of speed never jumps it. */
#ifndef SNAKEBOT_PLAY_SLEW_H
#define SNAKEBOT_PLAY_SLEW_H

#include <stdint.h>

/* cffi:begin */
/* Time for the wave's peak goal speed to change by the servo's top speed. */
#define PLAY_SLEW_RAMP_MS 500

/* The player's working copies of the live serpenoid parameters (units as play_params). */
typedef struct {
    uint16_t amp_mrad;
    int16_t phi0_mrad;
    int16_t steering;
    int16_t omega_mrad_s;
    uint16_t speed_scale;
    uint8_t primed; /* 0: the next step takes the targets at once (a fresh start) */
} play_slew;

/* The next step adopts its targets at once. */
void play_slew_reset(play_slew *s);
/* Ticks a goal may move in dt_ms: the servo's top speed times dt, rounded down. */
uint32_t play_slew_step_bound(uint32_t dt_ms);
/* Move s toward target over dt_ms (at most PLAY_MAX_STEP_MS; target->primed is ignored);
 * returns the goal speed the parameter changes add this tick, ticks per second * 256
 * (0 once settled). */
uint32_t play_slew_toward(play_slew *s, const play_slew *target, uint32_t dt_ms);
/* cffi:end */

#endif
