/* Dynamixel Protocol 1.0 packets: checksum, framing and the instruction builders the
 * firmware needs. Packet: FF FF ID LEN CODE P1..PN CHK, LEN = N + 2,
 * CHK = ~(ID + LEN + CODE + P1 + ... + PN) & 0xFF; CODE is the instruction, or the error
 * byte in a status packet. Layouts and vectors: protocol/README.md, protocol/vectors/.
 * Every builder writes into a caller buffer of `cap` bytes and returns the packet length,
 * or 0 (nothing usable written) if the packet would not fit or the arguments are invalid. */
#ifndef SNAKEBOT_DXL_PACKET_H
#define SNAKEBOT_DXL_PACKET_H

#include <stddef.h>
#include <stdint.h>

/* cffi:begin */
#define DXL_HEADER_BYTE 255
#define DXL_BROADCAST_ID 254
#define DXL_MAX_ID 253
/* Whole packet, header to checksum (ROBOTIS SDK cap): LEN byte 2..246. */
#define DXL_MAX_PACKET 250
#define DXL_MAX_PARAMS 244
#define DXL_MIN_LEN_FIELD 2
#define DXL_MAX_LEN_FIELD 246

#define DXL_INST_PING 1
#define DXL_INST_READ 2
#define DXL_INST_WRITE 3
#define DXL_INST_REG_WRITE 4
#define DXL_INST_ACTION 5
#define DXL_INST_RESET 6
#define DXL_INST_SYNC_WRITE 131
#define DXL_INST_BULK_READ 146

/* Error byte of a status packet. */
#define DXL_ERR_INPUT_VOLTAGE 1
#define DXL_ERR_ANGLE_LIMIT 2
#define DXL_ERR_OVERHEATING 4
#define DXL_ERR_RANGE 8
#define DXL_ERR_CHECKSUM 16
#define DXL_ERR_OVERLOAD 32
#define DXL_ERR_INSTRUCTION 64

/* Checksum of body = ID, LEN, CODE, params: the low byte of the inverted sum. */
uint8_t dxl_checksum(const uint8_t *body, size_t len);
/* Frame one packet (ID 0..254, up to DXL_MAX_PARAMS params; params may be NULL if none). */
size_t dxl_encode(uint8_t *out, size_t cap, uint8_t id, uint8_t code,
                  const uint8_t *params, size_t nparams);
/* Status packet from device `id` (0..253) with error byte and returned data. */
size_t dxl_status(uint8_t *out, size_t cap, uint8_t id, uint8_t error,
                  const uint8_t *params, size_t nparams);
/* PING `id`. */
size_t dxl_ping(uint8_t *out, size_t cap, uint8_t id);
/* READ `length` (1..DXL_MAX_PARAMS) bytes at `address` from `id`. */
size_t dxl_read(uint8_t *out, size_t cap, uint8_t id, uint8_t address, uint8_t length);
/* WRITE `len` (>= 1) bytes of data at `address` of `id`. */
size_t dxl_write(uint8_t *out, size_t cap, uint8_t id, uint8_t address,
                 const uint8_t *data, size_t len);
/* REG_WRITE: like dxl_write, applied when ACTION arrives. */
size_t dxl_reg_write(uint8_t *out, size_t cap, uint8_t id, uint8_t address,
                     const uint8_t *data, size_t len);
/* ACTION to `id` (usually DXL_BROADCAST_ID). */
size_t dxl_action(uint8_t *out, size_t cap, uint8_t id);
/* SYNC_WRITE (broadcast): `length` bytes at `address` to `count` devices; ids[k] (0..253)
 * gets data[k * length .. k * length + length - 1]. */
size_t dxl_sync_write(uint8_t *out, size_t cap, uint8_t address, uint8_t length,
                      const uint8_t *ids, const uint8_t *data, size_t count);
/* cffi:end */

#endif
