#include "gt_table.h"

#include "crc32.h"

static uint16_t rd16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}

static uint32_t rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static const uint8_t *joint_record(const uint8_t *table, uint8_t joint)
{
    return table + GT_HEADER_SIZE + (size_t)GT_JOINT_SIZE * joint;
}

uint32_t gt_crc(const uint8_t *table, size_t len)
{
    uint32_t state = crc32_update(CRC32_INIT, table, GT_CRC_OFFSET);
    if (len > GT_HEADER_SIZE) {
        state = crc32_update(state, table + GT_HEADER_SIZE, len - GT_HEADER_SIZE);
    }
    return crc32_final(state);
}

static int check_header(const uint8_t *t, size_t len, gt_info *info)
{
    if (len < GT_HEADER_SIZE) return GT_ERR_TRUNCATED;
    if (rd32(t) != (uint32_t)GT_MAGIC) return GT_ERR_MAGIC;
    if (t[4] != GT_VERSION) return GT_ERR_VERSION;
    uint8_t joints = t[5];
    if (joints == 0 || joints > GT_MAX_JOINTS) return GT_ERR_JOINT_COUNT;
    if ((t[6] & (uint8_t)~GT_FLAG_LOOP) != 0 || t[7] != 0) return GT_ERR_FLAGS;
    uint16_t period = rd16(t + 8);
    uint16_t frames = rd16(t + 10);
    if (period == 0) return GT_ERR_PERIOD;
    if (frames == 0) return GT_ERR_FRAME_COUNT;
    uint32_t size = GT_HEADER_SIZE + (uint32_t)GT_JOINT_SIZE * joints +
                    2u * joints * (uint32_t)frames;
    if (size > GT_MAX_TABLE_BYTES) return GT_ERR_TOO_BIG;
    if (len < size) return GT_ERR_TRUNCATED;
    if (len > size) return GT_ERR_TRAILING;
    info->size = (uint16_t)size;
    info->frame_period_ms = period;
    info->frame_count = frames;
    info->joint_count = joints;
    info->flags = t[6];
    info->crc = rd32(t + GT_CRC_OFFSET);
    return GT_OK;
}

static int check_body(const uint8_t *t, const gt_info *info)
{
    uint8_t seen[32] = {0}; /* one bit per servo ID */
    for (uint8_t j = 0; j < info->joint_count; j++) {
        const uint8_t *rec = joint_record(t, j);
        uint8_t id = rec[0];
        if (rec[1] != 0) return GT_ERR_FLAGS;
        if (id > GT_MAX_ID || (seen[id >> 3] & (1u << (id & 7))) != 0) return GT_ERR_JOINT_ID;
        seen[id >> 3] |= (uint8_t)(1u << (id & 7));
        if (rd16(rec + 2) > rd16(rec + 4) || rd16(rec + 4) > GT_MAX_TICK) return GT_ERR_LIMITS;
    }
    for (uint16_t f = 0; f < info->frame_count; f++) {
        for (uint8_t j = 0; j < info->joint_count; j++) {
            uint16_t v = gt_frame(t, info, f, j);
            if (v < gt_joint_min(t, info, j) || v > gt_joint_max(t, info, j)) {
                return GT_ERR_FRAME_RANGE;
            }
        }
    }
    return GT_OK;
}

int gt_describe(const uint8_t *table, size_t len, gt_info *info)
{
    gt_info found = {0};
    *info = found;
    if (table == NULL) return GT_ERR_TRUNCATED;
    int status = check_header(table, len, &found);
    if (status == GT_OK) *info = found;
    return status;
}

int gt_validate(const uint8_t *table, size_t len, gt_info *info)
{
    gt_info found = {0};
    *info = found;
    if (table == NULL) return GT_ERR_TRUNCATED;
    int status = check_header(table, len, &found);
    if (status != GT_OK) return status;
    if (gt_crc(table, found.size) != found.crc) return GT_ERR_CRC;
    status = check_body(table, &found);
    if (status == GT_OK) *info = found;
    return status;
}

const char *gt_strerror(int status)
{
    switch (status) {
    case GT_OK: return "ok";
    case GT_ERR_TRUNCATED: return "truncated: fewer bytes than the header says";
    case GT_ERR_MAGIC: return "bad magic: not a gait table";
    case GT_ERR_VERSION: return "unknown gait-table version";
    case GT_ERR_JOINT_COUNT: return "joint count 0 or above the controller's maximum";
    case GT_ERR_FLAGS: return "unknown flags or a reserved byte not 0";
    case GT_ERR_PERIOD: return "frame period 0";
    case GT_ERR_FRAME_COUNT: return "no frames";
    case GT_ERR_TOO_BIG: return "table too large for the controller";
    case GT_ERR_TRAILING: return "bytes after the end of the table";
    case GT_ERR_CRC: return "CRC mismatch";
    case GT_ERR_JOINT_ID: return "servo ID above 253 or used twice";
    case GT_ERR_LIMITS: return "joint limits not min <= max <= 1023";
    case GT_ERR_FRAME_RANGE: return "a frame lies outside its joint's limits";
    default: return "unknown gait-table status";
    }
}

uint8_t gt_joint_id(const uint8_t *table, const gt_info *info, uint8_t joint)
{
    return joint < info->joint_count ? joint_record(table, joint)[0] : 0;
}

uint16_t gt_joint_min(const uint8_t *table, const gt_info *info, uint8_t joint)
{
    return joint < info->joint_count ? rd16(joint_record(table, joint) + 2) : 0;
}

uint16_t gt_joint_max(const uint8_t *table, const gt_info *info, uint8_t joint)
{
    return joint < info->joint_count ? rd16(joint_record(table, joint) + 4) : 0;
}

uint16_t gt_frame(const uint8_t *table, const gt_info *info, uint16_t frame, uint8_t joint)
{
    if (joint >= info->joint_count || frame >= info->frame_count) return 0;
    size_t index = (size_t)frame * info->joint_count + joint;
    return rd16(joint_record(table, info->joint_count) + 2 * index);
}
