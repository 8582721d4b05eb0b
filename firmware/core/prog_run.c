#include "prog_run.h"

#include "ax12_table.h"
#include "ctl_table.h"
#include "play_fixed.h"
#include "prog_limits.h"

/* 2^56 binary angle per (mrad/s * ms): 2^56 / (2 pi 10^6), so one step's phase increment
 * omega * period * this stays below 2^63 for |omega| < 2^15 and period <= 1000 ms. */
#define BAM56_PER_MRAD_S_MS 11468322278LL
#define BAM56_MASK ((1ULL << 56) - 1u)
/* A program whose offset ramp goes further than this (mrad) cannot fit any joint; the
 * bound also keeps the fixed-point products below 2^63. */
#define MAX_RAMP_MRAD 100000LL
/* The largest carry, 1/16 tick, that still fits the cursor's int16. */
#define MAX_CARRY 30000
#define ONE_Q15 32768LL
#define MS_PER_S 1000LL

static uint16_t rd16(const uint8_t *b)
{
    return (uint16_t)(b[0] | (b[1] << 8));
}

static int16_t rd16s(const uint8_t *b)
{
    return (int16_t)rd16(b);
}

static uint32_t rd32(const uint8_t *b)
{
    return (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) |
           ((uint32_t)b[3] << 24);
}

/* Byte offsets of the program's parts (protocol/program.md). */
typedef struct {
    size_t joints;
    size_t segments;
    size_t blocks;
    size_t frames;
    size_t size;
    uint8_t joint_count;
} layout;

static layout layout_of(const uint8_t *blob)
{
    layout l;
    size_t j = blob[5];
    l.joint_count = blob[5];
    l.joints = PROG_HEADER_SIZE;
    l.segments = l.joints + PROG_JOINT_SIZE * j;
    l.blocks = l.segments + PROG_SEGMENT_SIZE * (size_t)blob[6];
    l.frames = l.blocks + PROG_PERIODIC_JOINT_SIZE * j * blob[7];
    l.size = l.frames + 2u * j * rd16(blob + 10);
    return l;
}

size_t prog_size(const uint8_t *blob, size_t len)
{
    return len < PROG_HEADER_SIZE ? 0 : layout_of(blob).size;
}

uint8_t prog_joint_count(const uint8_t *blob)
{
    return blob[5];
}

uint8_t prog_segment_count(const uint8_t *blob)
{
    return blob[6];
}

uint16_t prog_period_ms(const uint8_t *blob)
{
    return rd16(blob + 8);
}

static const uint8_t *joint_rec(const uint8_t *blob, uint8_t j)
{
    return blob + PROG_HEADER_SIZE + PROG_JOINT_SIZE * (size_t)j;
}

uint8_t prog_joint_id(const uint8_t *blob, uint8_t j)
{
    return joint_rec(blob, j)[0];
}

prog_joint prog_joint_at(const uint8_t *blob, uint8_t j)
{
    const uint8_t *r = joint_rec(blob, j);
    prog_joint out = {r[0], (uint8_t)(r[1] & PROG_JOINT_REVERSE), rd16(r + 2), rd16(r + 4),
                      rd16(r + 6)};
    return out;
}

static const uint8_t *segment_rec(const uint8_t *blob, uint8_t s)
{
    return blob + layout_of(blob).segments + PROG_SEGMENT_SIZE * (size_t)s;
}

/* Steps a segment lasts (0 for an unknown kind). */
static uint32_t duration(const uint8_t *seg)
{
    switch (seg[0]) {
    case PROG_KIND_TABLE: return (uint32_t)rd16(seg + 4) * rd16(seg + 6);
    case PROG_KIND_SERPENOID: return rd16(seg + 10);
    case PROG_KIND_PERIODIC: return rd16(seg + 6);
    default: return 0;
    }
}

/* omega t at step s, as a binary angle (2^32 = one turn). */
static uint32_t phase(int16_t omega_mrad_s, uint16_t period_ms, uint32_t s)
{
    int64_t inc = (int64_t)omega_mrad_s * period_ms * BAM56_PER_MRAD_S_MS;
    /* modular products: the low 56 bits of inc * s are exact whatever the wrap */
    uint64_t p = ((uint64_t)inc * (uint64_t)s) & BAM56_MASK;
    return (uint32_t)(p >> 24);
}

/* An angle in mrad * 2^15 relative to the joint's zero, as a goal in 1/16 tick. */
static int32_t goal_q4(const uint8_t *joint, int64_t angle_q15)
{
    int64_t rel = play_round_shift(angle_q15 * AX12_TICKS_PER_MRAD_Q24, 15 + 24 - PROG_CARRY_SHIFT);
    int64_t zero = (int64_t)rd16(joint + 2) << PROG_CARRY_SHIFT;
    return (int32_t)((joint[1] & PROG_JOINT_REVERSE) ? zero - rel : zero + rel);
}

/* round(v / 1000) for any sign. */
static int64_t div_ms(int64_t v)
{
    return v >= 0 ? (v + MS_PER_S / 2) / MS_PER_S : -((-v + MS_PER_S / 2) / MS_PER_S);
}

/* Joint k's goal from segment seg's generator at step s, 1/16 tick, without the carry. */
static int32_t generate(const uint8_t *blob, const uint8_t *seg, uint32_t s, uint8_t k)
{
    layout l = layout_of(blob);
    const uint8_t *joint = joint_rec(blob, k);
    uint16_t period = rd16(blob + 8);
    if (seg[0] == PROG_KIND_TABLE) {
        uint32_t frame = rd16(seg + 2) + s % rd16(seg + 4);
        const uint8_t *v = blob + l.frames + 2u * ((size_t)frame * l.joint_count + k);
        return (int32_t)rd16(v) << PROG_CARRY_SHIFT;
    }
    if (seg[0] == PROG_KIND_SERPENOID) {
        uint32_t theta = phase(rd16s(seg + 4), period, s) + play_mrad_to_bam(rd16s(seg + 6)) * k;
        int64_t angle = (int64_t)rd16(seg + 2) * play_sin_q15(theta) + rd16s(seg + 8) * ONE_Q15;
        return goal_q4(joint, angle);
    }
    const uint8_t *block = blob + l.blocks +
                           PROG_PERIODIC_JOINT_SIZE * ((size_t)rd16(seg + 2) * l.joint_count + k);
    uint32_t theta = phase(rd16s(seg + 4), period, s);
    int64_t ramp = div_ms((int64_t)rd16s(block) * s * period * ONE_Q15);
    int64_t angle = ramp + (int64_t)rd16s(block + 2) * play_sin_q15(theta) +
                    (int64_t)rd16s(block + 4) * play_sin_q15(theta + (uint32_t)PLAY_BAM_QUARTER);
    return goal_q4(joint, angle);
}

/* Replace prev's carries with those for entering segment next after it; false if one
 * does not fit an int16 (only an invalid program's can't). */
static bool carry_into(const uint8_t *blob, const uint8_t *prev, const uint8_t *next,
                       int16_t *carry)
{
    uint32_t end = duration(prev);
    bool ok = true;
    for (uint8_t k = 0; k < blob[5]; k++) {
        int32_t c = generate(blob, prev, end, k) + carry[k] - generate(blob, next, 0, k);
        if (c > MAX_CARRY || c < -MAX_CARRY) ok = false;
        carry[k] = (int16_t)(c > MAX_CARRY ? MAX_CARRY : (c < -MAX_CARRY ? -MAX_CARRY : c));
    }
    return ok;
}

static uint8_t check_header(const uint8_t *blob, size_t len, size_t capacity)
{
    if (len < PROG_HEADER_SIZE) return PROG_ERR_TRUNCATED;
    if (rd32(blob) != PROG_MAGIC) return PROG_ERR_MAGIC;
    if (blob[4] != PROG_VERSION) return PROG_ERR_VERSION;
    if (blob[5] == 0 || blob[5] > GT_MAX_JOINTS) return PROG_ERR_JOINT_COUNT;
    if (blob[6] == 0 || blob[6] > CTL_MAX_PROGRAM_SEGMENTS) return PROG_ERR_SEGMENT_COUNT;
    uint16_t period = rd16(blob + 8);
    if (period == 0 || period > PROG_MAX_PERIOD_MS) return PROG_ERR_PERIOD;
    size_t size = layout_of(blob).size;
    if (size > capacity) return PROG_ERR_TOO_BIG;
    if (len < size) return PROG_ERR_TRUNCATED;
    if (len > size) return PROG_ERR_TRAILING;
    if (gt_crc(blob, len) != rd32(blob + PROG_CRC_OFFSET)) return PROG_ERR_CRC;
    return PROG_OK;
}

static uint8_t check_joints(const uint8_t *blob)
{
    layout l = layout_of(blob);
    for (uint8_t k = 0; k < l.joint_count; k++) {
        const uint8_t *j = joint_rec(blob, k);
        uint16_t zero = rd16(j + 2), lo = rd16(j + 4), hi = rd16(j + 6);
        if (j[0] > GT_MAX_ID || (j[1] & ~PROG_JOINT_REVERSE) != 0) return PROG_ERR_JOINT;
        for (uint8_t e = 0; e < k; e++) {
            if (joint_rec(blob, e)[0] == j[0]) return PROG_ERR_JOINT;
        }
        if (lo > hi || hi > GT_MAX_TICK || zero < lo || zero > hi) return PROG_ERR_JOINT;
    }
    uint16_t frames = rd16(blob + 10);
    for (uint32_t f = 0; f < frames; f++) {
        for (uint8_t k = 0; k < l.joint_count; k++) {
            const uint8_t *j = joint_rec(blob, k);
            uint16_t v = rd16(blob + l.frames + 2u * ((size_t)f * l.joint_count + k));
            if (v < rd16(j + 4) || v > rd16(j + 6)) return PROG_ERR_FRAME_RANGE;
        }
    }
    return PROG_OK;
}

/* Whether a segment's fields are well formed (kind, reserved bytes, ranges it indexes). */
static bool segment_well_formed(const uint8_t *blob, const uint8_t *seg)
{
    uint32_t steps = duration(seg);
    if (seg[1] != 0 || steps == 0 || steps > UINT16_MAX) return false;
    if (seg[0] == PROG_KIND_TABLE) {
        uint32_t end = (uint32_t)rd16(seg + 2) + rd16(seg + 4);
        return rd16(seg + 8) == 0 && rd16(seg + 10) == 0 && end <= rd16(blob + 10);
    }
    if (seg[0] == PROG_KIND_PERIODIC) {
        return rd16(seg + 2) < blob[7] && rd16(seg + 8) == 0 && rd16(seg + 10) == 0;
    }
    return seg[0] == PROG_KIND_SERPENOID;
}

static int64_t abs64(int64_t v)
{
    return v < 0 ? -v : v;
}

/* Whether the goals from lo_q4..hi_q4 (either order) plus carry, rounded, fit joint k. */
static bool fits(const uint8_t *blob, uint8_t k, int32_t a_q4, int32_t b_q4, int32_t carry)
{
    const uint8_t *j = joint_rec(blob, k);
    int32_t lo = (a_q4 < b_q4 ? a_q4 : b_q4) + carry;
    int32_t hi = (a_q4 < b_q4 ? b_q4 : a_q4) + carry;
    return play_round_shift(lo, PROG_CARRY_SHIFT) >= rd16(j + 4) &&
           play_round_shift(hi, PROG_CARRY_SHIFT) <= rd16(j + 6);
}

/* PROG_OK if joint k's goals over the whole segment stay within its limits, then the
 * segment's fastest motion within the servo's speed. */
static uint8_t check_motion(const uint8_t *blob, const uint8_t *seg, uint8_t k, int32_t carry)
{
    const uint8_t *joint = joint_rec(blob, k);
    if (seg[0] == PROG_KIND_TABLE) {
        /* a plain scan down the joint's column: this is the check's bulk (up to 64
         * segments over ~1000 frame values), and it runs in the PC link's time */
        layout l = layout_of(blob);
        size_t stride = 2u * l.joint_count;
        const uint8_t *v = blob + l.frames + 2u * ((size_t)rd16(seg + 2) * l.joint_count + k);
        uint16_t lo = UINT16_MAX, hi = 0;
        for (uint16_t f = rd16(seg + 4); f > 0; f--, v += stride) {
            uint16_t g = rd16(v);
            lo = g < lo ? g : lo;
            hi = g > hi ? g : hi;
        }
        return fits(blob, k, (int32_t)lo << PROG_CARRY_SHIFT, (int32_t)hi << PROG_CARRY_SHIFT,
                    carry)
                   ? PROG_OK
                   : PROG_ERR_OUT_OF_RANGE;
    }
    if (seg[0] == PROG_KIND_SERPENOID) {
        int64_t amp = (int64_t)rd16(seg + 2) * PLAY_SIN_ONE;
        int64_t phi0 = rd16s(seg + 8) * ONE_Q15;
        if (!fits(blob, k, goal_q4(joint, phi0 - amp), goal_q4(joint, phi0 + amp), carry)) {
            return PROG_ERR_OUT_OF_RANGE;
        }
        bool fast = !prog_speed_fits(rd16(seg + 2), rd16s(seg + 4), CTL_SPEED_SCALE_ONE);
        return fast ? PROG_ERR_TOO_FAST : PROG_OK;
    }
    const uint8_t *block = blob + layout_of(blob).blocks +
                           PROG_PERIODIC_JOINT_SIZE * ((size_t)rd16(seg + 2) * blob[5] + k);
    int64_t rate = rd16s(block);
    int64_t wave = abs64(rd16s(block + 2)) + abs64(rd16s(block + 4));
    int64_t ramp = div_ms(rate * (int64_t)duration(seg) * rd16(blob + 8));
    if (abs64(ramp) > MAX_RAMP_MRAD) return PROG_ERR_OUT_OF_RANGE;
    int64_t lo = ((ramp < 0 ? ramp : 0) - wave) * ONE_Q15;
    int64_t hi = ((ramp > 0 ? ramp : 0) + wave) * ONE_Q15;
    if (!fits(blob, k, goal_q4(joint, lo), goal_q4(joint, hi), carry)) {
        return PROG_ERR_OUT_OF_RANGE;
    }
    int64_t peak = abs64(rate) * MS_PER_S + abs64(rd16s(seg + 4)) * wave; /* mrad/s * 1000 */
    return peak > (int64_t)AX12_MAX_SPEED_MRAD_S * MS_PER_S ? PROG_ERR_TOO_FAST : PROG_OK;
}

static uint8_t check_segments(const uint8_t *blob, uint8_t *bad_segment)
{
    int16_t carry[GT_MAX_JOINTS] = {0};
    for (uint8_t s = 0; s < blob[6]; s++) {
        const uint8_t *seg = segment_rec(blob, s);
        if (bad_segment != NULL) *bad_segment = s;
        if (!segment_well_formed(blob, seg)) return PROG_ERR_SEGMENT;
        if (s > 0 && !carry_into(blob, segment_rec(blob, (uint8_t)(s - 1u)), seg, carry)) {
            return PROG_ERR_OUT_OF_RANGE;
        }
        for (uint8_t k = 0; k < blob[5]; k++) {
            uint8_t status = check_motion(blob, seg, k, carry[k]);
            if (status != PROG_OK) return status;
        }
    }
    if (bad_segment != NULL) *bad_segment = 0;
    return PROG_OK;
}

uint8_t prog_validate(const uint8_t *blob, size_t len, size_t capacity, uint8_t *bad_segment)
{
    if (bad_segment != NULL) *bad_segment = 0;
    uint8_t status = check_header(blob, len, capacity);
    if (status == PROG_OK) status = check_joints(blob);
    if (status == PROG_OK) status = check_segments(blob, bad_segment);
    return status;
}

void prog_start(prog_cursor *c)
{
    prog_cursor zero = {0};
    *c = zero;
}

void prog_goals(const uint8_t *blob, const prog_cursor *c, int16_t steering, uint16_t *goals)
{
    const uint8_t *seg = segment_rec(blob, c->segment);
    for (uint8_t k = 0; k < blob[5]; k++) {
        const uint8_t *j = joint_rec(blob, k);
        int64_t g = play_round_shift(generate(blob, seg, c->step, k) + c->carry[k],
                                     PROG_CARRY_SHIFT);
        g += (j[1] & PROG_JOINT_REVERSE) ? -(int32_t)steering : steering;
        /* a validated program needs the clamp only for the steering; it guards the servos */
        if (g < rd16(j + 4)) g = rd16(j + 4);
        if (g > rd16(j + 6)) g = rd16(j + 6);
        goals[k] = (uint16_t)g;
    }
}

bool prog_advance(const uint8_t *blob, prog_cursor *c, uint32_t steps)
{
    while (!c->done) {
        const uint8_t *seg = segment_rec(blob, c->segment);
        uint32_t left = duration(seg) - c->step;
        if (steps < left) {
            c->step = (uint16_t)(c->step + steps);
            return true;
        }
        steps -= left;
        if ((uint8_t)(c->segment + 1u) >= blob[6]) {
            c->step = (uint16_t)(duration(seg) - 1u);
            c->done = 1;
            break;
        }
        (void)carry_into(blob, seg, segment_rec(blob, (uint8_t)(c->segment + 1u)), c->carry);
        c->segment++;
        c->step = 0;
    }
    return false;
}

bool prog_serpenoid_at(const uint8_t *blob, const prog_cursor *c, uint16_t *amp_mrad,
                       int16_t *omega_mrad_s)
{
    const uint8_t *seg = segment_rec(blob, c->segment);
    if (seg[0] != PROG_KIND_SERPENOID) return false;
    *amp_mrad = rd16(seg + 2);
    *omega_mrad_s = rd16s(seg + 4);
    return true;
}

bool prog_tick(const uint8_t *blob, prog_cursor *c, uint32_t dt_ms, uint16_t speed_scale)
{
    uint32_t span = (uint32_t)rd16(blob + 8) << 8; /* one step, ms * 256 */
    /* the caller bounds dt (PLAY_MAX_STEP_MS) and the scale (1..1024); these bounds only
     * keep the sum below 2^32 whatever they pass */
    uint32_t dt = dt_ms > UINT16_MAX ? UINT16_MAX : dt_ms;
    uint32_t acc = c->acc_q8 + dt * (speed_scale > 0xFFFu ? 0xFFFu : speed_scale);
    c->acc_q8 = acc % span;
    return prog_advance(blob, c, acc / span);
}
