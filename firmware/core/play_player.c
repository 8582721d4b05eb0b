#include "play_player.h"

#include "play_fixed.h"
#include "play_slew.h"

/* 2^48 binary angle per (mrad/s * ms): 2^48 / (2 pi 10^6). */
#define BAM48_PER_MRAD_S_MS 44798134LL
#define BAM48_MASK ((1ULL << 48) - 1u)

size_t play_state_size(void)
{
    return sizeof(play_state);
}

void play_init(play_state *p)
{
    play_state zero = {0};
    *p = zero;
}

/* Start mode on table (NULL for none) at now_ms. */
static void begin(play_state *p, uint8_t mode, const uint8_t *table, uint32_t now_ms)
{
    p->table = table;
    p->mode = mode;
    p->finished = 0;
    p->last_ms = now_ms;
}

bool play_start_table(play_state *p, const uint8_t *table, size_t len, uint32_t now_ms)
{
    gt_info info;
    if (gt_validate(table, len, &info) != GT_OK) {
        p->mode = PLAY_MODE_IDLE;
        return false;
    }
    begin(p, PLAY_MODE_TABLE, table, now_ms);
    p->info = info;
    p->frame = 0;
    p->offset_q8 = 0;
    return true;
}

bool play_start_serpenoid(play_state *p, uint8_t count, uint32_t now_ms)
{
    if (count == 0 || count > GT_MAX_JOINTS) {
        p->mode = PLAY_MODE_IDLE;
        return false;
    }
    begin(p, PLAY_MODE_SERPENOID, NULL, now_ms);
    p->phase = 0;
    play_slew_reset(&p->slew);
    return true;
}

void play_start_program(play_state *p, const uint8_t *blob, uint32_t now_ms)
{
    begin(p, PLAY_MODE_PROGRAM, blob, now_ms);
    p->out_count = 0;
    prog_start(&p->program);
    play_slew_reset(&p->slew);
}

void play_stop(play_state *p)
{
    p->mode = PLAY_MODE_IDLE;
}

static uint16_t clamp_tick(int32_t v, uint16_t lo, uint16_t hi)
{
    if (v > (int32_t)hi) v = hi;
    if (v < (int32_t)lo) v = lo;
    return (uint16_t)v;
}

static int32_t steer(const play_params *params, const play_joint *roster, uint8_t roster_count,
                     uint8_t j)
{
    bool reverse = j < roster_count && roster[j].reverse;
    return reverse ? -(int32_t)params->steering : params->steering;
}

static uint32_t elapsed(play_state *p, uint32_t now_ms)
{
    uint32_t dt = now_ms - p->last_ms; /* wraps correctly */
    p->last_ms = now_ms;
    return dt > PLAY_MAX_STEP_MS ? PLAY_MAX_STEP_MS : dt;
}

static uint8_t tick_table(play_state *p, const play_params *params, const play_joint *roster,
                          uint8_t roster_count, uint32_t dt)
{
    const gt_info *info = &p->info;
    uint32_t span = (uint32_t)info->frame_period_ms * 256u; /* one frame, ms * 256 */
    uint16_t frames = info->frame_count;
    uint16_t last = (uint16_t)(frames - 1u);

    p->offset_q8 += dt * params->speed_scale;
    uint32_t steps = p->offset_q8 / span;
    p->offset_q8 %= span;
    if (params->loop) {
        p->frame = (uint16_t)(((uint32_t)p->frame + steps) % frames);
    } else if ((uint32_t)p->frame + steps >= last) {
        p->frame = last;
        p->offset_q8 = 0;
        p->finished = 1;
        p->mode = PLAY_MODE_IDLE;
    } else {
        p->frame = (uint16_t)(p->frame + steps);
    }
    uint16_t next = p->frame == last ? (params->loop ? 0 : last) : (uint16_t)(p->frame + 1u);

    for (uint8_t j = 0; j < info->joint_count; j++) {
        int64_t a = gt_frame(p->table, info, p->frame, j);
        int64_t b = gt_frame(p->table, info, next, j);
        /* round((a * span + (b - a) * offset) / span), halves up; the numerator is >= 0 */
        int64_t num = a * span + (b - a) * (int64_t)p->offset_q8 + span / 2u;
        int32_t goal = (int32_t)(num / span) + steer(params, roster, roster_count, j);
        uint32_t step = (uint32_t)(b > a ? b - a : a - b);
        /* ticks/s * 256 = step / (period / scale) * 1000 * 256 / 256 */
        uint32_t rate = (uint32_t)(((uint64_t)step * 1000u * params->speed_scale) /
                                   info->frame_period_ms);
        p->out_id[j] = gt_joint_id(p->table, info, j);
        p->out_goal[j] = clamp_tick(goal, gt_joint_min(p->table, info, j),
                                    gt_joint_max(p->table, info, j));
        p->out_speed[j] = play_speed_units(rate);
    }
    p->out_count = info->joint_count;
    return p->out_count;
}

/* The register values in params replaced by the slewed working copies (play_slew.h);
 * returns the goal speed the slewing adds, ticks/s * 256. */
static uint32_t slew_live(play_state *p, play_params *live, uint32_t dt)
{
    play_slew target = {live->amp_mrad, live->phi0_mrad, live->steering, live->omega_mrad_s,
                        live->speed_scale, 1};
    uint32_t extra = play_slew_toward(&p->slew, &target, dt);
    live->amp_mrad = p->slew.amp_mrad;
    live->phi0_mrad = p->slew.phi0_mrad;
    live->steering = p->slew.steering;
    live->omega_mrad_s = p->slew.omega_mrad_s;
    live->speed_scale = p->slew.speed_scale;
    return extra;
}

static uint8_t tick_serpenoid(play_state *p, const play_params *params, const play_joint *roster,
                              uint8_t roster_count, uint32_t dt, uint32_t extra_rate_q8)
{
    int64_t inc = (int64_t)params->omega_mrad_s * (int64_t)dt * params->speed_scale *
                  BAM48_PER_MRAD_S_MS;
    /* inc / 256, rounded, as a 48-bit wrap-around step */
    uint64_t mag = ((uint64_t)(inc < 0 ? -inc : inc) + 128u) >> 8;
    p->phase = (inc < 0 ? p->phase - mag : p->phase + mag) & BAM48_MASK;

    uint8_t count = roster_count > GT_MAX_JOINTS ? GT_MAX_JOINTS : roster_count;
    uint32_t base = (uint32_t)(p->phase >> 16);
    uint32_t delta = play_mrad_to_bam(params->delta_mrad);
    for (uint8_t k = 0; k < count; k++) {
        const play_joint *jt = &roster[k];
        uint32_t theta = base + delta * k;
        int32_t angle = play_serp_ticks(params->amp_mrad, params->phi0_mrad, theta);
        int32_t goal = (int32_t)jt->zero + (jt->reverse ? -angle : angle) +
                       steer(params, roster, roster_count, k);
        uint16_t lo = jt->min > AX12_POSITION_MAX ? AX12_POSITION_MAX : jt->min;
        uint16_t hi = jt->max > AX12_POSITION_MAX ? AX12_POSITION_MAX : jt->max;
        p->out_id[k] = jt->id;
        p->out_goal[k] = clamp_tick(goal, lo, hi < lo ? lo : hi);
        p->out_speed[k] = play_speed_units(
            play_serp_rate_q8(params->amp_mrad, params->omega_mrad_s, params->speed_scale, theta) +
            extra_rate_q8);
    }
    p->out_count = count;
    return count;
}

/* Live steering of a program (protocol/program.md): the speed scale runs its time, the
 * steering offset applies while a SERPENOID segment runs and slews back to 0 in the
 * others, both slewed as the plain serpenoid's (play_slew.h) with the running wave's
 * A and omega (none outside serpenoid segments: the scale then applies at once, as in
 * table mode). The slew's working copies are the player's (program mode leaves the
 * serpenoid's idle). */
static uint32_t slew_program(play_state *p, const play_params *params, uint32_t dt)
{
    play_slew target = {0, 0, 0, 0, params->speed_scale, 1};
    if (prog_serpenoid_at(p->table, &p->program, &target.amp_mrad, &target.omega_mrad_s)) {
        target.steering = params->steering;
    }
    /* the wave's own parameters are the segment's: the slew takes them as they are */
    p->slew.amp_mrad = target.amp_mrad;
    p->slew.omega_mrad_s = target.omega_mrad_s;
    return play_slew_toward(&p->slew, &target, dt);
}

static uint8_t tick_program(play_state *p, const play_params *params, uint32_t dt)
{
    const uint8_t *blob = p->table;
    uint8_t count = prog_joint_count(blob);
    uint16_t goals[GT_MAX_JOINTS];
    uint32_t period = prog_period_ms(blob);
    bool first = p->out_count == 0;
    uint32_t extra = slew_program(p, params, dt);
    if (!prog_tick(blob, &p->program, dt, p->slew.speed_scale)) {
        p->finished = 1;
        p->mode = PLAY_MODE_IDLE;
    }
    prog_goals(blob, &p->program, p->slew.steering, goals);
    for (uint8_t j = 0; j < count; j++) {
        /* speed: cover the goal's change within one program step at the speed scale
         * (ticks/s * 256), plus what the steering's slew adds; kept while the goal
         * holds, so a servo still on its way is not slowed down; the first goal is
         * approached at the floor speed */
        uint32_t change = (uint32_t)(goals[j] > p->out_goal[j] ? goals[j] - p->out_goal[j]
                                                               : p->out_goal[j] - goals[j]);
        uint32_t rate = change * 1000u * p->slew.speed_scale / period + extra;
        if (first) p->out_speed[j] = PLAY_MIN_SPEED;
        else if (change != 0) p->out_speed[j] = play_speed_units(rate);
        p->out_id[j] = prog_joint_id(blob, j);
        p->out_goal[j] = goals[j];
    }
    p->out_count = count;
    return count;
}

uint8_t play_tick(play_state *p, const play_params *params, const play_joint *roster,
                  uint8_t roster_count, uint32_t now_ms)
{
    uint32_t dt = elapsed(p, now_ms);
    if (p->mode == PLAY_MODE_TABLE) return tick_table(p, params, roster, roster_count, dt);
    if (p->mode == PLAY_MODE_PROGRAM) return tick_program(p, params, dt);
    if (p->mode == PLAY_MODE_SERPENOID) {
        play_params live = *params;
        uint32_t extra = slew_live(p, &live, dt);
        return tick_serpenoid(p, &live, roster, roster_count, dt, extra);
    }
    return 0;
}

uint8_t play_mode(const play_state *p)
{
    return p->mode;
}

bool play_finished(const play_state *p)
{
    return p->finished != 0;
}

uint8_t play_program_segment(const play_state *p)
{
    return p->program.segment;
}

uint16_t play_frame_index(const play_state *p)
{
    return p->frame;
}

uint8_t play_out_count(const play_state *p)
{
    return p->out_count;
}

uint8_t play_out_id(const play_state *p, uint8_t j)
{
    return j < p->out_count ? p->out_id[j] : 0;
}

uint16_t play_out_goal(const play_state *p, uint8_t j)
{
    return j < p->out_count ? p->out_goal[j] : 0;
}

uint16_t play_out_speed(const play_state *p, uint8_t j)
{
    return j < p->out_count ? p->out_speed[j] : 0;
}
