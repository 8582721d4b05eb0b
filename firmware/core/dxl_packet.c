#include "dxl_packet.h"

uint8_t dxl_checksum(const uint8_t *body, size_t len)
{
    uint8_t sum = 0;
    for (size_t i = 0; i < len; i++) {
        sum = (uint8_t)(sum + body[i]);
    }
    return (uint8_t)~sum;
}

/* Writes the header, ID, LEN and code of a packet with `nparams` params and returns the
 * packet's total length, or 0 if it is invalid or does not fit in `cap`. The caller then
 * fills out[5 .. 5 + nparams - 1] and calls finish(). */
static size_t start(uint8_t *out, size_t cap, uint8_t id, uint8_t code, size_t nparams)
{
    if (out == NULL || id > DXL_BROADCAST_ID || nparams > DXL_MAX_PARAMS) {
        return 0;
    }
    size_t total = nparams + 6u;
    if (total > cap) {
        return 0;
    }
    out[0] = DXL_HEADER_BYTE;
    out[1] = DXL_HEADER_BYTE;
    out[2] = id;
    out[3] = (uint8_t)(nparams + 2u);
    out[4] = code;
    return total;
}

static size_t finish(uint8_t *out, size_t total)
{
    out[total - 1u] = dxl_checksum(&out[2], total - 3u);
    return total;
}

size_t dxl_encode(uint8_t *out, size_t cap, uint8_t id, uint8_t code,
                  const uint8_t *params, size_t nparams)
{
    if (params == NULL && nparams != 0) {
        return 0;
    }
    size_t total = start(out, cap, id, code, nparams);
    if (total == 0) {
        return 0;
    }
    for (size_t i = 0; i < nparams; i++) {
        out[5u + i] = params[i];
    }
    return finish(out, total);
}

size_t dxl_status(uint8_t *out, size_t cap, uint8_t id, uint8_t error,
                  const uint8_t *params, size_t nparams)
{
    if (id > DXL_MAX_ID) {
        return 0;
    }
    return dxl_encode(out, cap, id, error, params, nparams);
}

size_t dxl_ping(uint8_t *out, size_t cap, uint8_t id)
{
    return dxl_encode(out, cap, id, DXL_INST_PING, NULL, 0);
}

size_t dxl_read(uint8_t *out, size_t cap, uint8_t id, uint8_t address, uint8_t length)
{
    if (length == 0 || length > DXL_MAX_PARAMS) {
        return 0;
    }
    const uint8_t params[2] = {address, length};
    return dxl_encode(out, cap, id, DXL_INST_READ, params, 2);
}

static size_t address_and_data(uint8_t *out, size_t cap, uint8_t id, uint8_t code,
                               uint8_t address, const uint8_t *data, size_t len)
{
    if (data == NULL || len == 0 || len > DXL_MAX_PARAMS - 1u) {
        return 0;
    }
    size_t total = start(out, cap, id, code, len + 1u);
    if (total == 0) {
        return 0;
    }
    out[5] = address;
    for (size_t i = 0; i < len; i++) {
        out[6u + i] = data[i];
    }
    return finish(out, total);
}

size_t dxl_write(uint8_t *out, size_t cap, uint8_t id, uint8_t address,
                 const uint8_t *data, size_t len)
{
    return address_and_data(out, cap, id, DXL_INST_WRITE, address, data, len);
}

size_t dxl_reg_write(uint8_t *out, size_t cap, uint8_t id, uint8_t address,
                     const uint8_t *data, size_t len)
{
    return address_and_data(out, cap, id, DXL_INST_REG_WRITE, address, data, len);
}

size_t dxl_action(uint8_t *out, size_t cap, uint8_t id)
{
    return dxl_encode(out, cap, id, DXL_INST_ACTION, NULL, 0);
}

size_t dxl_sync_write(uint8_t *out, size_t cap, uint8_t address, uint8_t length,
                      const uint8_t *ids, const uint8_t *data, size_t count)
{
    if (ids == NULL || data == NULL || length == 0 || count == 0
        || count > DXL_MAX_PARAMS / 2u) {
        return 0;
    }
    size_t nparams = 2u + count * ((size_t)length + 1u);
    size_t total = start(out, cap, DXL_BROADCAST_ID, DXL_INST_SYNC_WRITE, nparams);
    if (total == 0) {
        return 0;
    }
    out[5] = address;
    out[6] = length;
    size_t at = 7;
    for (size_t k = 0; k < count; k++) {
        if (ids[k] > DXL_MAX_ID) {
            return 0;
        }
        out[at++] = ids[k];
        for (size_t i = 0; i < length; i++) {
            out[at++] = data[k * length + i];
        }
    }
    return finish(out, total);
}
