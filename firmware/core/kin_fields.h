/* Internal to the kinematic core: field evaluation without argument checks. */
#ifndef SNAKEBOT_KIN_FIELDS_H
#define SNAKEBOT_KIN_FIELDS_H

#include "kin_core.h"
#include "kin_gen.h"

/* The trident's corner angles as the generated code takes them: alpha1..3, then their
 * cosines, then their sines. */
void kin_fields_corners(const kin_robot *rb, double corners[9]);

/* The 3-link snake's qdot = u1 g1 + u2 g2 (kin_fields_velocity_unchecked's snake case). */
int kin_fields_snake3_velocity(const kin_robot *rb, const double *q, const double *u,
                               double *qdot);

/* qdot = sum_i u_i g_i(q) for a robot already validated (form KIN_FORM_BODY or
 * KIN_FORM_WORLD, corners from kin_fields_corners); still KIN_ESINGULAR on the 3-link
 * singular line. Inline, so that an integrator's right-hand side calls the generated
 * velocity directly (one call less per evaluation: 3-5% of a trident trajectory). */
static inline int kin_fields_velocity_unchecked(const kin_robot *rb, const double *corners,
                                                int32_t form, const double *q,
                                                const double *u, double *qdot)
{
    if (rb->kind == KIN_SNAKE) {
        return kin_fields_snake3_velocity(rb, q, u, qdot);
    }
    if (form == KIN_FORM_BODY) {
        kin_gen_trident_body_v(rb->r, rb->l, corners, q, u, qdot);
    } else {
        kin_gen_trident_world_v(rb->r, rb->l, corners, q, u, qdot);
    }
    return KIN_OK;
}

#endif
