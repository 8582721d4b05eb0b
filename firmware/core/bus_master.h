/* The Dynamixel bus master's schedule, as pure logic over byte buffers: the app does the
 * UART I/O (direction pins, timeouts), this decides what goes on the wire and what the
 * replies mean. Each control tick:
 *
 *     bus_begin_tick(&bus);
 *     while ((n = bus_next(&bus, ids, goals, speeds, count, tx, sizeof tx, &txn)) > 0) {
 *         send tx[0..n);
 *         if (txn.reply_len) {                    // a READ: wait for its status packet
 *             while (no timeout && bus_rx(&bus, rx, got) == false) receive more;
 *             bus_rx_done(&bus);                  // reply taken, or counted as a timeout
 *         }
 *     }
 *
 * A tick sends, in order: a pending torque on/off, the SYNC_WRITE of goal positions and
 * moving speeds (addresses 30-33), then one READ of the telemetry block (addresses 36-43)
 * of the next roster servo, round robin. Replies are found in whatever bytes come back,
 * so an echo of our own instruction (one-wire adapters) or leading noise is skipped.
 *
 * The robot's limits (bus_set_limits): while some servo's CW/CCW Angle Limit is not yet
 * known to equal them, every other tick's READ is one step of the limits check instead
 * of telemetry (so a tick never waits for more than one reply): READ the servo's angle
 * limits; only if they differ WRITE them (they live in EEPROM, which wears) and READ
 * them back. A servo that will not take them (BUS_LIMIT_TRIES writes), or does not
 * answer (BUS_LIMIT_SILENT reads), leaves the check FAILED. The check runs again after
 * every roster change; and once VERIFIED, every BUS_LIMIT_AUDIT_TICKS ticks one servo's
 * angle limits are read again (round robin), since a damaged packet could have changed
 * them: one found changed is checked (and written) again.
 *
 * A robot-wide Torque Limit (bus_set_torque_limit) is checked the same way, for each
 * servo once its angle limits are verified: READ, WRITE only if it differs, READ back;
 * and the audit reads it too (after the servo's angle limits). Torque Limit is RAM on an
 * AX-12: a power cycle sets it back to Max Torque, an alarm shutdown to 0; the audit
 * finds that and writes it again. */
#ifndef SNAKEBOT_BUS_MASTER_H
#define SNAKEBOT_BUS_MASTER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ax12_table.h"
#include "ctl_table.h"

/* The telemetry block: Present Position through Present Temperature. */
#define BUS_TELEMETRY_ADDRESS AX12_PRESENT_POSITION
#define BUS_TELEMETRY_LENGTH \
    (AX12_PRESENT_TEMPERATURE + AX12_PRESENT_TEMPERATURE_SIZE - AX12_PRESENT_POSITION)

/* cffi:begin */
/* Bytes of the status packet answering the telemetry READ. */
#define BUS_REPLY_BYTES 14
/* A reply window the app may use: 14 + 8 bytes at 1 Mbps, plus the AX-12's default
 * 500 us return delay, with margin. Shorten it once Return Delay Time is 0. */
#define BUS_SUGGESTED_TIMEOUT_US 1500
/* Bytes of reply kept while searching for the status packet. */
#define BUS_RX_BUFFER 48
#define BUS_TXN_WRITE 1
#define BUS_TXN_READ 2
#define BUS_TORQUE_NONE 0
#define BUS_TORQUE_ON 1
#define BUS_TORQUE_OFF 2
/* A servo fails the check after this many WRITEs it did not take (read back different),
 * or this many limits READs in a row without an answer: enough that a bus damaging most
 * packets (5 % of bytes) still gets through, few enough to give up within a second. */
#define BUS_LIMIT_TRIES 16
#define BUS_LIMIT_SILENT 48
#define BUS_LIMIT_AUDIT_TICKS 25
/* No robot-wide Torque Limit: the servos' own is left alone (what the Limits page's
 * Robot Torque Limit shows then). */
#define BUS_TORQUE_LIMIT_NONE 0xFFFF

/* What bus_next() produced. */
typedef struct {
    uint8_t kind;       /* BUS_TXN_WRITE (no reply) or BUS_TXN_READ */
    uint8_t id;         /* addressed servo (BUS_TXN_READ) or 254 (broadcast) */
    uint8_t reply_len;  /* bytes of the expected status packet; 0 = none */
} bus_txn;

/* The mirror of one roster servo. */
typedef struct {
    uint16_t position;     /* address 36 */
    uint16_t speed;        /* address 38 */
    uint16_t load;         /* address 40 */
    uint8_t voltage;       /* address 42 */
    uint8_t temperature;   /* address 43 */
    uint8_t error;         /* error byte of its last status packet */
    uint8_t error_count;   /* status packets with error != 0 (stops at 255) */
    uint8_t timeout_count; /* reads without a usable reply (stops at 255) */
    uint8_t missed;        /* reads without a usable reply in a row */
    uint8_t fresh;         /* 1 once a reply has been taken */
} bus_servo;

typedef struct bus_master bus_master;

/* Bytes to allocate for a bus_master. */
size_t bus_master_size(void);
/* Empty roster, counters zero. */
void bus_init(bus_master *b);
/* The servos to poll; a slot whose ID is unchanged keeps its telemetry, others restart. */
void bus_set_roster(bus_master *b, const uint8_t *ids, uint8_t count);
/* Queue torque on (SYNC_WRITE to the goal IDs) or off (broadcast) for the next tick. */
void bus_request_torque(bus_master *b, uint8_t request);
/* Start a tick's sequence. */
void bus_begin_tick(bus_master *b);
/* Next packet of this tick into out (returns its length, 0 = the tick is done); goals
 * and speeds for ids[0..count) (count 0 = no SYNC_WRITE). */
size_t bus_next(bus_master *b, const uint8_t *ids, const uint16_t *goals,
                const uint16_t *speeds, uint8_t count, uint8_t *out, size_t cap, bus_txn *txn);
/* Bytes received for the pending READ; true once its status packet is in. */
bool bus_rx(bus_master *b, const uint8_t *data, size_t len);
/* Close the pending READ: its reply is applied, or it counts as a timeout. */
void bus_rx_done(bus_master *b);
/* Forget servo errors and missed-read runs (after the safe state is cleared). */
void bus_clear_faults(bus_master *b);
/* Roster size and the mirror of roster servo k (NULL if k is out of range). */
uint8_t bus_roster_count(const bus_master *b);
const bus_servo *bus_servo_at(const bus_master *b, uint8_t k);
/* The robot's limits: servo ids[i] may move in [mins[i], maxs[i]] (count 0 = none);
 * starts the check of the servos' angle limits. */
void bus_set_limits(bus_master *b, const uint8_t *ids, const uint16_t *mins,
                    const uint16_t *maxs, uint8_t count);
/* The robot's Torque Limit for every covered servo (BUS_TORQUE_LIMIT_NONE = none; set
 * after bus_set_limits, which forgets it); starts the check again. */
void bus_set_torque_limit(bus_master *b, uint16_t torque);
uint16_t bus_torque_limit(const bus_master *b);
/* Run the check again from the first servo (e.g. after CLEAR). */
void bus_recheck_limits(bus_master *b);
/* CTL_LIMITS_STATE_* (the Limits State register), the servos the limits cover, and those of servo id (false: none). */
uint8_t bus_limits_state(const bus_master *b);
uint8_t bus_limits_count(const bus_master *b);
bool bus_limits_of(const bus_master *b, uint8_t id, uint16_t *min, uint16_t *max);
/* EEPROM WRITEs of angle limits sent (wraps). */
uint16_t bus_limit_writes(const bus_master *b);
/* Counters (wrap): replies taken, reads without a usable reply, corrupt replies. */
uint16_t bus_reads(const bus_master *b);
uint16_t bus_timeouts(const bus_master *b);
uint16_t bus_errors(const bus_master *b);
/* cffi:end */

struct bus_master {
    uint8_t count;
    uint8_t ids[CTL_MAX_JOINTS];
    bus_servo servo[CTL_MAX_JOINTS];
    uint8_t next;          /* round-robin position */
    uint8_t step;          /* where the tick's sequence is */
    uint8_t torque;        /* BUS_TORQUE_* pending */
    uint8_t awaiting;      /* roster slot of the pending READ, or 0xFF */
    uint8_t awaiting_id;
    uint8_t awaiting_kind; /* what the pending reply answers (AWAIT_* in bus_master.c) */
    uint8_t taken;         /* the pending READ's reply has been applied */
    uint8_t corrupt;       /* a reply with a bad checksum was seen */
    uint8_t rx_len;
    uint8_t rx[BUS_RX_BUFFER];
    uint16_t reads;
    uint16_t timeouts;
    uint16_t errors;
    /* the robot's limits and their check */
    uint8_t lim_count;
    uint8_t lim_id[CTL_MAX_JOINTS];
    uint16_t lim_min[CTL_MAX_JOINTS];
    uint16_t lim_max[CTL_MAX_JOINTS];
    uint8_t lim_next;      /* servo being checked; lim_count = check done */
    uint8_t lim_phase;     /* LIM_* in bus_master.c */
    uint8_t lim_tries;     /* WRITEs not taken */
    uint8_t lim_silent;    /* READs without an answer, in a row */
    uint8_t lim_failed;
    uint8_t lim_turn;      /* alternates the tick's READ between telemetry and the check */
    uint8_t lim_audit_k;   /* the servo the next audit READ asks */
    uint8_t lim_audit_wait; /* ticks since the last audit READ */
    uint16_t lim_writes;
    uint16_t lim_torque;      /* the robot's Torque Limit, or BUS_TORQUE_LIMIT_NONE */
    uint8_t lim_audit_torque; /* the next audit READ asks Torque Limit */
};

#endif
