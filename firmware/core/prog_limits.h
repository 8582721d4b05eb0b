/* Checks every on-board generator passes before it starts, and again when its live
 * parameters change: the goals it can reach stay within each roster joint's limits
 * (Min Tick..Max Tick, as the player computes them: zero tick, direction, steering), and
 * its fastest joint motion stays within the servo's no-load speed (AX12_MAX_SPEED_MRAD_S,
 * from the device description). Refusing is the alternative to clipping goals silently
 * and to servos that saturate and lag (protocol/controller.md, "Validation"). */
#ifndef SNAKEBOT_PROG_LIMITS_H
#define SNAKEBOT_PROG_LIMITS_H

#include <stdbool.h>
#include <stdint.h>

#include "play_player.h"

/* cffi:begin */
/* Whether roster joint j's goals for the serpenoid A sin(theta) + phi0 (milliradians),
 * steered by steering ticks, stay within its Min Tick..Max Tick at the wave's extremes. */
bool prog_joint_fits(const play_joint *j, uint16_t amp_mrad, int16_t phi0_mrad,
                     int16_t steering);
/* Whether the fastest joint motion A |omega| speed_scale / 256 is within the servo's. */
bool prog_speed_fits(uint16_t amp_mrad, int16_t omega_mrad_s, uint16_t speed_scale);
/* CTL_REFUSAL_REASON_NONE if the serpenoid A sin(theta) + phi0 (milliradians), steered
 * by steering ticks, keeps every one of the first count roster joints within its limits
 * and A |omega| scale / 256 within the servo's speed; else CTL_REFUSAL_REASON_AMPLITUDE
 * or CTL_REFUSAL_REASON_SPEED (the range is checked first). */
uint8_t prog_check_serpenoid(const play_joint *roster, uint8_t count, uint16_t amp_mrad,
                             int16_t omega_mrad_s, int16_t phi0_mrad, int16_t steering,
                             uint16_t speed_scale);
/* cffi:end */

#endif
