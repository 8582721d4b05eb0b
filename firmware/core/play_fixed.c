#include "play_fixed.h"

/* round(32767 * sin(i * (pi / 2) / 256)), i = 0..256 */
static const int16_t quarter_sine[257] = {
    0, 201, 402, 603, 804, 1005, 1206, 1407, 1608, 1809,
    2009, 2210, 2410, 2611, 2811, 3012, 3212, 3412, 3612, 3811,
    4011, 4210, 4410, 4609, 4808, 5007, 5205, 5404, 5602, 5800,
    5998, 6195, 6393, 6590, 6786, 6983, 7179, 7375, 7571, 7767,
    7962, 8157, 8351, 8545, 8739, 8933, 9126, 9319, 9512, 9704,
    9896, 10087, 10278, 10469, 10659, 10849, 11039, 11228, 11417, 11605,
    11793, 11980, 12167, 12353, 12539, 12725, 12910, 13094, 13279, 13462,
    13645, 13828, 14010, 14191, 14372, 14553, 14732, 14912, 15090, 15269,
    15446, 15623, 15800, 15976, 16151, 16325, 16499, 16673, 16846, 17018,
    17189, 17360, 17530, 17700, 17869, 18037, 18204, 18371, 18537, 18703,
    18868, 19032, 19195, 19357, 19519, 19680, 19841, 20000, 20159, 20317,
    20475, 20631, 20787, 20942, 21096, 21250, 21403, 21554, 21705, 21856,
    22005, 22154, 22301, 22448, 22594, 22739, 22884, 23027, 23170, 23311,
    23452, 23592, 23731, 23870, 24007, 24143, 24279, 24413, 24547, 24680,
    24811, 24942, 25072, 25201, 25329, 25456, 25582, 25708, 25832, 25955,
    26077, 26198, 26319, 26438, 26556, 26674, 26790, 26905, 27019, 27133,
    27245, 27356, 27466, 27575, 27683, 27790, 27896, 28001, 28105, 28208,
    28310, 28411, 28510, 28609, 28706, 28803, 28898, 28992, 29085, 29177,
    29268, 29358, 29447, 29534, 29621, 29706, 29791, 29874, 29956, 30037,
    30117, 30195, 30273, 30349, 30424, 30498, 30571, 30643, 30714, 30783,
    30852, 30919, 30985, 31050, 31113, 31176, 31237, 31297, 31356, 31414,
    31470, 31526, 31580, 31633, 31685, 31736, 31785, 31833, 31880, 31926,
    31971, 32014, 32057, 32098, 32137, 32176, 32213, 32250, 32285, 32318,
    32351, 32382, 32412, 32441, 32469, 32495, 32521, 32545, 32567, 32589,
    32609, 32628, 32646, 32663, 32678, 32692, 32705, 32717, 32728, 32737,
    32745, 32752, 32757, 32761, 32765, 32766, 32767,
};

/* Binary angle per milliradian, Q16: 2^32 / (2000 pi) * 2^16. */
#define BAM_PER_MRAD_Q16 44798133900LL
/* The servo's units (ticks per milliradian, Moving Speed units per tick/s) come from
 * ax12_table.h, generated from the AX-12A's description with the fixed-point shifts below. */
#define TICKS_PER_MRAD_Q24 AX12_TICKS_PER_MRAD_Q24
#define UNITS_PER_TICK_S_Q18 ((uint64_t)AX12_SPEED_UNITS_PER_TICK_S_Q18)

/* floor((v + 2^(shift-1)) / 2^shift) for any sign, without relying on >> of negatives. */
static int64_t round_shift(int64_t v, unsigned shift)
{
    int64_t half = (int64_t)1 << (shift - 1);
    if (v >= 0) return (v + half) >> shift;
    return -(int64_t)(((uint64_t)(-v) + (uint64_t)half - 1u) >> shift);
}

int64_t play_round_shift(int64_t v, unsigned shift)
{
    return round_shift(v, shift);
}

int16_t play_sin_q15(uint32_t angle)
{
    uint32_t quadrant = angle >> 30;
    uint32_t index = (angle >> 22) & 0xFFu;      /* 256 steps per quarter */
    int32_t frac = (int32_t)((angle >> 6) & 0xFFFFu); /* position between steps, Q16 */
    int32_t a;
    int32_t b;
    if ((quadrant & 1u) == 0) {
        a = quarter_sine[index];
        b = quarter_sine[index + 1];
    } else {
        a = quarter_sine[256 - index];
        b = quarter_sine[255 - index];
    }
    int32_t value = a + (int32_t)round_shift((int64_t)(b - a) * frac, 16);
    return (int16_t)(quadrant >= 2 ? -value : value);
}

uint32_t play_mrad_to_bam(int32_t mrad)
{
    uint64_t magnitude = (uint64_t)(mrad < 0 ? -(int64_t)mrad : (int64_t)mrad);
    uint32_t bam = (uint32_t)((magnitude * (uint64_t)BAM_PER_MRAD_Q16 + 0x8000u) >> 16);
    return mrad < 0 ? (uint32_t)(0u - bam) : bam;
}

int32_t play_serp_ticks(uint16_t amp_mrad, int16_t phi0_mrad, uint32_t theta)
{
    /* angle in mrad, Q15 */
    int64_t angle = (int64_t)amp_mrad * play_sin_q15(theta) + (int64_t)phi0_mrad * 32768;
    return (int32_t)round_shift(angle * TICKS_PER_MRAD_Q24, 15 + 24);
}

uint16_t play_speed_units(uint32_t ticks_per_s_q8)
{
    uint64_t units = ((uint64_t)ticks_per_s_q8 * UNITS_PER_TICK_S_Q18 + ((1ULL << 26) - 1u)) >> 26;
    if (units < PLAY_MIN_SPEED) return PLAY_MIN_SPEED;
    if (units > PLAY_MAX_SPEED) return PLAY_MAX_SPEED;
    return (uint16_t)units;
}

uint32_t play_serp_rate_q8(uint16_t amp_mrad, int16_t omega_mrad_s, uint16_t scale_q8,
                           uint32_t theta)
{
    int32_t c = play_sin_q15(theta + (uint32_t)PLAY_BAM_QUARTER);
    uint64_t omega = (uint64_t)(omega_mrad_s < 0 ? -(int32_t)omega_mrad_s : omega_mrad_s);
    uint64_t cos_mag = (uint64_t)(c < 0 ? -c : c);
    /* mrad/s * 256: A * |omega| / 1000 * scale * |cos| / 32768 */
    uint64_t rate = (uint64_t)amp_mrad * omega * scale_q8 * cos_mag / (1000ULL * 32768ULL);
    uint64_t ticks = (rate * (uint64_t)TICKS_PER_MRAD_Q24) >> 24;
    return ticks > 0xFFFFFFFFULL ? 0xFFFFFFFFu : (uint32_t)ticks;
}
