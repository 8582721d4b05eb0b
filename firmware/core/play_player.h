/* The gait player: turns the active table, or the serpenoid parameters, into one goal
 * position and one moving speed per joint at each control tick.
 *
 * Table mode plays frame k at k * period (scaled by the speed factor), interpolating
 * linearly in ticks between frames, looping or once; serpenoid mode computes
 * phi_k = A sin(omega t + k delta) + phi0 per roster joint in fixed point. Goals get the
 * steering offset (negated for reversed joints) and are clamped to the joint's limits
 * (the table header's in table mode, the roster's in serpenoid mode). Program mode sends
 * the program's goals (prog_run.h) for the step the elapsed time has reached. Moving speeds come
 * from the motion until the next frame (table) or the wave's derivative (serpenoid), so
 * the servos move smoothly instead of jumping at full speed.
 *
 * The caller owns the play_state (size: play_state_size()), the roster and the table
 * bytes; the player keeps a pointer to the table, which must stay put while it plays. */
#ifndef SNAKEBOT_PLAY_PLAYER_H
#define SNAKEBOT_PLAY_PLAYER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "gt_table.h"
#include "play_slew.h"
#include "prog_run.h"

/* cffi:begin */
#define PLAY_MODE_IDLE 0
#define PLAY_MODE_TABLE 1
#define PLAY_MODE_SERPENOID 2
#define PLAY_MODE_PROGRAM 3
/* A gap between two ticks longer than this counts as this (after a stall, the gait
 * resumes instead of jumping far ahead). */
#define PLAY_MAX_STEP_MS 1000

/* One roster joint (the controller's servo window). */
typedef struct {
    uint8_t id;       /* servo ID */
    uint8_t reverse;  /* 1: the joint angle grows as the tick falls */
    uint16_t zero;    /* tick at joint angle 0 */
    uint16_t min;     /* clamp range, ticks */
    uint16_t max;
} play_joint;

/* What the controller's registers ask for; read at every tick. Table mode applies changes
 * at once; serpenoid mode slews amplitude, phi0, steering, omega and scale toward them
 * (play_slew.h). */
typedef struct {
    uint16_t speed_scale;   /* 1/256: 256 = as fast as written; 1..1024 */
    int16_t steering;       /* ticks added to every goal (negated for reversed joints) */
    uint8_t loop;           /* table mode: 1 = loop, 0 = play once */
    uint16_t amp_mrad;      /* serpenoid A */
    int16_t omega_mrad_s;   /* serpenoid omega */
    int16_t delta_mrad;     /* serpenoid phase step between joints */
    int16_t phi0_mrad;      /* serpenoid offset */
} play_params;

typedef struct play_state play_state;

/* Bytes to allocate for a play_state. */
size_t play_state_size(void);
/* Idle, no outputs. */
void play_init(play_state *p);
/* Play the table in table[0..len) from its first frame; false (and idle) if the table
 * does not validate. */
bool play_start_table(play_state *p, const uint8_t *table, size_t len, uint32_t now_ms);
/* Run the serpenoid on the first count roster joints from phase 0; false (and idle) if
 * count is 0 or above the maximum. */
bool play_start_serpenoid(play_state *p, uint8_t count, uint32_t now_ms);
/* Run the program in blob (validated with prog_validate; it must stay put while it runs)
 * from its first step; the speed scale runs its time and the steering offset applies to
 * its serpenoid segments, slewed as in serpenoid mode (protocol/program.md). */
void play_start_program(play_state *p, const uint8_t *blob, uint32_t now_ms);
/* Stop; the last outputs stay readable. */
void play_stop(play_state *p);
/* Advance to now_ms and compute the outputs; returns how many joints have a goal to send
 * (0 when idle). A table played once ends idle with its last frame as the outputs. */
uint8_t play_tick(play_state *p, const play_params *params, const play_joint *roster,
                  uint8_t roster_count, uint32_t now_ms);
/* PLAY_MODE_*. */
uint8_t play_mode(const play_state *p);
/* True once a table played once has reached its last frame, or a program its last step. */
bool play_finished(const play_state *p);
/* The segment the program is running (or ran last). */
uint8_t play_program_segment(const play_state *p);
/* Table mode: the frame being played. */
uint16_t play_frame_index(const play_state *p);
/* Outputs of the last tick: joint count, and per joint j the servo ID, goal and speed. */
uint8_t play_out_count(const play_state *p);
uint8_t play_out_id(const play_state *p, uint8_t j);
uint16_t play_out_goal(const play_state *p, uint8_t j);
uint16_t play_out_speed(const play_state *p, uint8_t j);
/* cffi:end */

struct play_state {
    uint8_t mode;
    uint8_t finished;
    uint8_t out_count;
    uint16_t frame;           /* table: current frame */
    uint32_t offset_q8;       /* table: ms * 256 into the current frame */
    uint32_t last_ms;
    uint64_t phase;           /* serpenoid: omega t as a 48-bit binary angle */
    play_slew slew;           /* serpenoid, program: working copies of the live parameters */
    prog_cursor program;      /* program: where it is (the blob is in table) */
    const uint8_t *table;
    gt_info info;
    uint8_t out_id[GT_MAX_JOINTS];
    uint16_t out_goal[GT_MAX_JOINTS];
    uint16_t out_speed[GT_MAX_JOINTS];
};

#endif
