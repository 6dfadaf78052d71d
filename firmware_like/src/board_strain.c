/* board_strain.c - strain (F/T) board emulator: convert, latch, send two halves. */
#include "board_strain.h"

#include "icub_can.h"

int board_strain_init(board_strain_t *b, uint8_t address, const double full_scale[6], uint8_t sat_variant)
{
    uint8_t ch;
    if (b == 0 || full_scale == 0) {
        return ICUB_CAN_EINVAL;
    }
    if (address > ICUB_CAN_SRC_MAX) {
        return ICUB_CAN_ERANGE;
    }
    for (ch = 0u; ch < BOARD_STRAIN_CHANNELS; ++ch) {
        /* the negated test also rejects NaN; 1e300 stands in for "finite" without <math.h> */
        if (!(full_scale[ch] > 0.0 && full_scale[ch] < 1e300)) {
            return ICUB_CAN_ERANGE;
        }
    }
    for (ch = 0u; ch < BOARD_STRAIN_CHANNELS; ++ch) {
        b->full_scale[ch] = full_scale[ch];
        b->counts[ch] = 0;
    }
    b->address = address;
    b->sat_variant = sat_variant ? 1u : 0u;
    b->saturated = 0u;
    b->conversions = 0u;
    b->saturations = 0u;
    return ICUB_CAN_OK;
}

int board_strain_sample(board_strain_t *b, const double wrench[6])
{
    int16_t s[BOARD_STRAIN_CHANNELS];
    uint8_t sat = 0u;
    uint8_t ch;
    if (b == 0 || wrench == 0) {
        return ICUB_CAN_EINVAL;
    }
    for (ch = 0u; ch < BOARD_STRAIN_CHANNELS; ++ch) {
        uint8_t clamped = 0u;
        const int rc = icub_can_strain_count(wrench[ch], b->full_scale[ch], &s[ch], &clamped);
        if (rc != ICUB_CAN_OK) {
            return rc; /* nothing latched: the previous conversion stays */
        }
        sat = (uint8_t)(sat | (clamped ? (uint8_t)(1u << ch) : 0u));
    }
    for (ch = 0u; ch < BOARD_STRAIN_CHANNELS; ++ch) {
        b->counts[ch] = s[ch];
        if (sat & (1u << ch)) {
            ++b->saturations;
        }
    }
    b->saturated = sat;
    ++b->conversions;
    return ICUB_CAN_OK;
}

int board_strain_frame(const board_strain_t *b, uint8_t half, board_frame_t *out)
{
    int dlc;
    uint8_t flags;
    const uint8_t first = (uint8_t)(3u * half);
    if (b == 0 || out == 0 || half > BOARD_STRAIN_HALF_TORQUE) {
        return ICUB_CAN_EINVAL;
    }
    /* byte 6, bit i: channel first+i of this half was clamped */
    flags = (uint8_t)((b->saturated >> first) & ICUB_CAN_STRAIN_SAT_MASK);
    if (b->sat_variant) {
        dlc = icub_can_strain_pack_sat(out->data, &b->counts[first], flags);
    } else {
        dlc = icub_can_strain_pack(out->data, &b->counts[first]);
    }
    if (dlc < 0) {
        return dlc;
    }
    out->id = icub_can_id((uint8_t)ICUB_CAN_CLASS_STRAIN, b->address,
                          (uint8_t)(half == BOARD_STRAIN_HALF_FORCE ? ICUB_CAN_STRAIN_FORCE : ICUB_CAN_STRAIN_TORQUE));
    out->dlc = (uint8_t)dlc;
    return dlc;
}
