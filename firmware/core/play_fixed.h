/* Fixed-point maths for the player: a quarter-wave sine table, the serpenoid joint
 * angle in ticks, and AX-12 moving speeds. No floating point: the Cortex-M3 has no FPU.
 *
 * Angles inside the player are binary angles ("BAM"): a uint32_t where 2^32 is one turn,
 * so phases wrap for free. Serpenoid parameters arrive in milliradians (the controller's
 * registers). Error: before its final rounding play_serp_ticks() is within 0.03 tick of
 * the exact ticks-per-radian * (A sin(theta) + phi0) (the sine is good to 1.5 / 32767), so
 * its result is within 0.53 tick of the exact value: the exact value rounded, except
 * where that lies within 0.03 of a half (tests/model/test_player_serpenoid.py). */
#ifndef SNAKEBOT_PLAY_FIXED_H
#define SNAKEBOT_PLAY_FIXED_H

#include <stdint.h>

#include "ax12_table.h"

/* cffi:begin */
/* sin = 1.0 in play_sin_q15(). */
#define PLAY_SIN_ONE 32767
/* A quarter turn as a binary angle (2^30). */
#define PLAY_BAM_QUARTER 1073741824
/* Moving-speed floor in AX-12 units: keeps a servo that is off its goal moving at
 * ~11 deg/s (0 would mean "no speed control" on an AX-12). */
#define PLAY_MIN_SPEED 16

/* sin(angle) in Q15 (angle: 2^32 = one turn), from a 257-entry quarter table with linear
 * interpolation; |error| <= 1.5 / 32767. */
int16_t play_sin_q15(uint32_t angle);
/* Binary angle of mrad milliradians (any sign, wrapped to one turn). */
uint32_t play_mrad_to_bam(int32_t mrad);
/* round((amp_mrad * sin(theta) + phi0_mrad) * ticks per milliradian): the serpenoid
 * joint angle in ticks, relative to the joint's zero tick (halves away from zero). */
int32_t play_serp_ticks(uint16_t amp_mrad, int16_t phi0_mrad, uint32_t theta);
/* AX-12 Moving Speed (PLAY_MIN_SPEED..PLAY_MAX_SPEED, rounded up) that covers
 * ticks_per_s_q8 / 256 ticks per second. */
uint16_t play_speed_units(uint32_t ticks_per_s_q8);
/* Ticks per second * 256 at which the serpenoid joint angle changes at theta:
 * A |omega| |cos(theta)| * scale / 256, in ticks. */
uint32_t play_serp_rate_q8(uint16_t amp_mrad, int16_t omega_mrad_s, uint16_t scale_q8,
                           uint32_t theta);
/* v / 2^shift rounded to nearest, halves away from zero (shift >= 1). */
int64_t play_round_shift(int64_t v, unsigned shift);
/* cffi:end */

/* The ceiling: the largest joint-mode Moving Speed (from ax12_table.h). */
#define PLAY_MAX_SPEED AX12_SPEED_MAX

#endif
