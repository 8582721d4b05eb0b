#include "play_safety.h"

uint16_t play_safety_check(const uint8_t *servo_errors, const uint8_t *missed, uint8_t count,
                           uint8_t servo_error_mask, uint8_t bus_loss_limit, bool moving,
                           uint32_t ms_since_link, uint8_t link_timeout_100ms)
{
    uint16_t faults = 0;
    for (uint8_t k = 0; k < count; k++) {
        if ((servo_errors[k] & servo_error_mask) != 0) faults |= CTL_ERROR_FLAGS_SERVO_ERROR;
        if (bus_loss_limit != 0 && missed[k] >= bus_loss_limit) faults |= CTL_ERROR_FLAGS_BUS_LOSS;
    }
    if (moving && link_timeout_100ms != 0 &&
        ms_since_link >= 100u * (uint32_t)link_timeout_100ms) {
        faults |= CTL_ERROR_FLAGS_LINK_LOSS;
    }
    return faults;
}
