/* Control vector fields and their Lie brackets, evaluated from the C that sympy
 * generated (kin_gen.c): exact derivatives, no finite differences. */
#include "kin_core.h"
#include "kin_fields.h"
#include "kin_gen.h"

#include <math.h>

/* |det B| / l below this counts as the 3-link singular set (phi1 = phi2, or a joint at +-pi). */
#define SNAKE3_DET_MIN 1e-12

static int field_model(const kin_robot *rb, int32_t *fields, int32_t *inputs, int32_t *n)
{
    int32_t joints;
    int rc = kin_check_robot(rb, &joints);
    if (rc != KIN_OK) {
        return rc;
    }
    if (rb->kind == KIN_SNAKE && rb->links == 3) {
        *fields = 5;
        *inputs = 2;
    } else if (rb->kind == KIN_TRIDENT) {
        *fields = 6;
        *inputs = 3;
    } else {
        return KIN_EUNSUPPORTED;
    }
    *n = 3 + joints;
    return KIN_OK;
}

int kin_field_count(const kin_robot *rb, int32_t *fields, int32_t *inputs)
{
    int32_t f, u, n;
    int rc = field_model(rb, &f, &u, &n);
    if (rc == KIN_OK) {
        if (fields != NULL) {
            *fields = f;
        }
        if (inputs != NULL) {
            *inputs = u;
        }
    }
    return rc;
}

static int check_q(const double *q, int32_t n)
{
    if (q == NULL) {
        return KIN_EINVAL;
    }
    for (int32_t i = 0; i < n; i++) {
        if (!isfinite(q[i])) {
            return KIN_ENONFINITE;
        }
    }
    return KIN_OK;
}

/* The 3-link snake's det B = l (sin p1 - sin p2 + sin(p1 - p2)); KIN_ESINGULAR near 0. */
static int snake3_det(const kin_robot *rb, const double *q, double *det)
{
    const double d = rb->l * (sin(q[3]) - sin(q[4]) + sin(q[3] - q[4]));
    if (det != NULL) {
        *det = d;
    }
    return fabs(d) < SNAKE3_DET_MIN * rb->l ? KIN_ESINGULAR : KIN_OK;
}

static int finite_out(const double *out, int32_t count)
{
    for (int32_t i = 0; i < count; i++) {
        if (!isfinite(out[i])) {
            return KIN_ENONFINITE;
        }
    }
    return KIN_OK;
}

int kin_fields(const kin_robot *rb, int32_t form, const double *q, double *out, double *det)
{
    int32_t f, u, n;
    int rc = field_model(rb, &f, &u, &n);
    if (rc != KIN_OK) {
        return rc;
    }
    if (out == NULL || (form != KIN_FORM_BODY && form != KIN_FORM_WORLD)) {
        return KIN_EINVAL;
    }
    if ((rc = check_q(q, n)) != KIN_OK) {
        return rc;
    }
    if (rb->kind == KIN_SNAKE) {
        if ((rc = snake3_det(rb, q, det)) != KIN_OK) {
            return rc;
        }
        kin_gen_snake3_all(rb->l, q, out);
    } else {
        if (det != NULL) {
            *det = 1.0;
        }
        double corners[9];
        kin_fields_corners(rb, corners);
        if (form == KIN_FORM_BODY) {
            kin_gen_trident_body_all(rb->r, rb->l, corners, q, out);
        } else {
            kin_gen_trident_world_all(rb->r, rb->l, corners, q, out);
        }
    }
    return finite_out(out, f * n);
}

void kin_fields_corners(const kin_robot *rb, double corners[9])
{
    for (int32_t i = 0; i < 3; i++) {
        corners[i] = rb->alpha[i];
        corners[3 + i] = cos(rb->alpha[i]);
        corners[6 + i] = sin(rb->alpha[i]);
    }
}

/* From the generated velocity function: no field is stored only to be summed. */
int kin_fields_snake3_velocity(const kin_robot *rb, const double *q, const double *u,
                               double *qdot)
{
    int rc = snake3_det(rb, q, NULL);
    if (rc != KIN_OK) {
        return rc;
    }
    kin_gen_snake3_v(rb->l, q, u, qdot);
    return KIN_OK;
}

int kin_field_velocity(const kin_robot *rb, int32_t form, const double *q, const double *u,
                       double *qdot)
{
    int32_t f, m, n;
    int rc = field_model(rb, &f, &m, &n);
    if (rc != KIN_OK) {
        return rc;
    }
    if (u == NULL || qdot == NULL || (form != KIN_FORM_BODY && form != KIN_FORM_WORLD)) {
        return KIN_EINVAL;
    }
    if ((rc = check_q(q, n)) != KIN_OK || (rc = check_q(u, m)) != KIN_OK) {
        return rc;
    }
    double corners[9];
    kin_fields_corners(rb, corners);
    if ((rc = kin_fields_velocity_unchecked(rb, corners, form, q, u, qdot)) != KIN_OK) {
        return rc;
    }
    return finite_out(qdot, n);
}
