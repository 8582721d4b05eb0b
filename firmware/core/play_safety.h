/* When to stop: the safety rules of the player, as one pure function the controller
 * calls every tick. The result is a set of CTL_ERROR_FLAGS_* bits (ctl_table.h); any bit
 * set means "enter the safe state". */
#ifndef SNAKEBOT_PLAY_SAFETY_H
#define SNAKEBOT_PLAY_SAFETY_H

#include <stdbool.h>
#include <stdint.h>

#include "ctl_table.h"

/* cffi:begin */
/* Faults among count roster servos:
 * - SERVO_ERROR: a servo's last error byte has a bit of servo_error_mask (0 = never);
 * - BUS_LOSS: a servo missed bus_loss_limit telemetry reads in a row (0 = never);
 * - LINK_LOSS: moving, link_timeout_100ms > 0, and no packet from the PC for that long. */
uint16_t play_safety_check(const uint8_t *servo_errors, const uint8_t *missed, uint8_t count,
                           uint8_t servo_error_mask, uint8_t bus_loss_limit, bool moving,
                           uint32_t ms_since_link, uint8_t link_timeout_100ms);
/* cffi:end */

#endif
