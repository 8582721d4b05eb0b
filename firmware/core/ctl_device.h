/* The controller as a Protocol 1.0 device on the PC link, and the glue of the control
 * loop: control table (protocol/controller.md), upload and commit, commands, safety,
 * player and bus master. The app owns one ctl_device followed by its table arena, which
 * holds the active table and the staging area (ctl_device_bytes(arena): about 1.6 KB plus
 * the arena; the board sizes the arena, see ctl_set_tables()), and only moves bytes:
 *
 *     ctl_init(&ctl);                       // once, then
 *     ctl_set_tables(&ctl, arena, capacity);
 *                                           // then maybe ctl_load_limits() and
 *                                           // ctl_load_table() from flash, in that order
 *     // PC link, for each received byte (main loop draining the USART3 RX ring):
 *     ctl_pc_feed(&ctl, byte);
 *     while (ctl_pc_poll(&ctl, now_ms, tx, sizeof tx, &n)) if (n) pc_send(tx, n);
 *     // every control tick:
 *     ctl_tick(&ctl, now_ms);
 *     while ((n = ctl_bus_next(&ctl, tx, sizeof tx, &reply_len)) > 0) {
 *         bus_send(tx, n);
 *         if (reply_len) { receive with timeout, handing bytes to ctl_bus_rx() until it
 *                          returns true; then ctl_bus_rx_done(); }
 *     }
 *     if (ctl_table_changed(&ctl)) persist ctl_active_table(&ctl, &len) to flash;
 *     if (ctl_limits_changed(&ctl)) persist ctl_robot_limits(&ctl, buf, sizeof buf);
 */
#ifndef SNAKEBOT_CTL_DEVICE_H
#define SNAKEBOT_CTL_DEVICE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "bus_master.h"
#include "ctl_table.h"
#include "dxl_parser.h"
#include "gt_table.h"
#include "lib_regs.h"
#include "play_player.h"

/* cffi:begin */
/* Buffer sizes the app needs: a PC-link reply (a status packet of up to 244 bytes of
 * data) and a bus packet (SYNC_WRITE of 4 bytes to 18 servos: 8 + 5 * 18). */
#define CTL_PC_REPLY_MAX 250
#define CTL_BUS_TX_MAX 98

typedef struct ctl_device ctl_device;

/* Bytes of a ctl_device without its table arena. */
size_t ctl_device_size(void);
/* Bytes to allocate for a ctl_device followed by a table arena of `arena` bytes. */
size_t ctl_device_bytes(size_t arena);
/* Factory state: registers at their defaults, no table, idle; no table arena yet (every
 * upload is refused until ctl_set_tables()). */
void ctl_init(ctl_device *d);
/* The device's table arena: the `arena` bytes that follow it in memory (see
 * ctl_device_bytes()), at most 65535; and its table capacity (at most the arena and
 * CTL_MAX_TABLE_BYTES). The active table lies at the arena's start, the staging area is
 * its last `capacity` bytes (protocol/controller.md, "Where a table is staged"): an
 * arena of twice the capacity never refuses an upload. Drops any table. */
void ctl_set_tables(ctl_device *d, size_t arena, uint16_t capacity);
/* The board's table capacity in bytes (at most the arena holds; Table Capacity on the
 * Program page shows it): commits and uploads beyond it are refused. */
void ctl_set_capacity(ctl_device *d, uint16_t bytes);
/* The board the firmware runs on (CTL_BOARD_*, from the board's BOARD_ID; Board on the
 * Program page shows it): the core knows no board itself, so the app names it. */
void ctl_set_board(ctl_device *d, uint8_t board);
/* Make table[0..len) (a table, or a program: protocol/program.md) active without an
 * upload (e.g. one kept in flash); false, and nothing changed, if it does not validate. */
bool ctl_load_table(ctl_device *d, const uint8_t *table, size_t len);
/* The robot's limits as Upload Commit LIMITS takes them (protocol/controller.md), e.g.
 * kept in flash; false, and nothing changed, if they are malformed. */
bool ctl_load_limits(ctl_device *d, const uint8_t *blob, size_t len);
/* Bytes of the robot's limits in that form (at most CTL_LIMITS_BLOB_MAX); 0 if none are
 * set or cap is too small. */
size_t ctl_robot_limits(const ctl_device *d, uint8_t *out, size_t cap);
/* True once after each commit that set the robot's limits. */
bool ctl_limits_changed(ctl_device *d);

/* PC link: one received byte (false: the parser is full, poll first). */
bool ctl_pc_feed(ctl_device *d, uint8_t byte);
/* Handle the next parsed packet, if any (false: none left). *out_len = bytes of the
 * status packet to send back (0: no reply). */
bool ctl_pc_poll(ctl_device *d, uint32_t now_ms, uint8_t *out, size_t cap, size_t *out_len);
/* Handle one instruction packet (any ID: others are ignored); returns the reply's length
 * in out (0: no reply). */
size_t ctl_handle_packet(ctl_device *d, uint8_t id, uint8_t instruction, const uint8_t *params,
                         size_t nparams, uint32_t now_ms, uint8_t *out, size_t cap);

/* Control tick: safety checks, the player, then the bus schedule for this tick. */
void ctl_tick(ctl_device *d, uint32_t now_ms);
/* Next bus packet of this tick (0: done); *reply_len = bytes of the awaited status
 * packet, 0 if none. */
size_t ctl_bus_next(ctl_device *d, uint8_t *out, size_t cap, uint8_t *reply_len);
/* Bytes received from the bus for the awaited reply; true once it is complete. */
bool ctl_bus_rx(ctl_device *d, const uint8_t *data, size_t len);
/* End of the reply window (after the reply, or at the timeout). */
void ctl_bus_rx_done(ctl_device *d);

/* State (CTL_STATE_*) and Error Flags (CTL_ERROR_FLAGS_*). */
uint8_t ctl_state(const ctl_device *d);
uint16_t ctl_error_flags(const ctl_device *d);
/* The controller's current ID on the PC link. */
uint8_t ctl_id(const ctl_device *d);
/* True once after each commit or load that changed the active table. */
bool ctl_table_changed(ctl_device *d);
/* The active table's bytes (NULL and *len = 0 if none). */
const uint8_t *ctl_active_table(const ctl_device *d, size_t *len);
/* The gait library's ctl_set_library() and ctl_buttons(): in lib_regs.h. */
/* cffi:end */

/* Upload Commit FIRMWARE_CHECK: the Upload Result for the firmware image's own CRC-32
 * compared with `len` bytes and `crc` (protocol/controller.md). The app defines it
 * (firmware/app/image_info.c); the core's weak default, used where there is no image
 * (the host build), answers FIRMWARE_UNAVAILABLE. */
uint8_t ctl_firmware_check(uint32_t len, uint32_t crc);

/* The robot's limits as staged: a count, then per servo its ID, min tick, max tick;
 * then, optionally, the robot-wide Torque Limit (u16). */
#define CTL_LIMITS_RECORD 5u
#define CTL_LIMITS_TORQUE AX12_TORQUE_LIMIT_SIZE
#define CTL_LIMITS_BLOB_MAX (1u + CTL_LIMITS_RECORD * CTL_MAX_JOINTS + CTL_LIMITS_TORQUE)

struct ctl_device {
    uint8_t regs[CTL_CONTROL_TABLE_BYTES]; /* the stored registers (windows excluded) */
    play_joint roster[CTL_MAX_JOINTS];
    play_state player;
    bus_master bus;
    dxl_parser pc;
    uint32_t last_link_ms;
    uint16_t arena_size;    /* bytes of the table arena (active[]) */
    uint16_t staged_end;    /* staging bytes written since the upload began at offset 0 */
    uint16_t active_len;    /* 0: no active table */
    uint16_t capacity;      /* the board's table capacity (<= arena_size) */
    uint8_t refusal;        /* CTL_REFUSAL_REASON_* of the last command */
    uint8_t out_count;      /* goals to send this tick */
    uint8_t table_changed;
    uint8_t limits_changed;
    uint8_t board;          /* CTL_BOARD_* the app named (NONE until it does) */
    lib_device lib;
    /* The table arena, as long as the app made it: the active table at its start, the
     * staging area its last `capacity` bytes. Not a pointer: that would cost the QEMU
     * board RAM it does not have. */
    uint8_t active[];
};

#endif
