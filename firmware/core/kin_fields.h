/* Internal to the kinematic core: field evaluation without argument checks. */
#ifndef SNAKEBOT_KIN_FIELDS_H
#define SNAKEBOT_KIN_FIELDS_H

#include "kin_core.h"

/* The trident's corner angles as the generated code takes them: alpha1..3, then their
 * cosines, then their sines. */
void kin_fields_corners(const kin_robot *rb, double corners[9]);

/* qdot = sum_i u_i g_i(q) for a robot already validated (form KIN_FORM_BODY or
 * KIN_FORM_WORLD, corners from kin_fields_corners); still KIN_ESINGULAR on the 3-link
 * singular line. */
int kin_fields_velocity_unchecked(const kin_robot *rb, const double *corners, int32_t form,
                                  const double *q, const double *u, double *qdot);

#endif
