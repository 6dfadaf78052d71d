/* board_mc.c - motor-control board emulator: two axes, POSITION + PID_VAL each period, STATUS at 100 Hz. */
#include "board_mc.h"

#include <math.h>

#include "icub_can.h"

int board_mc_init(board_mc_t *b, uint8_t address, const board_mc_axis_t axis[2])
{
    uint8_t i;
    if (b == 0 || axis == 0) {
        return ICUB_CAN_EINVAL;
    }
    if (address > ICUB_CAN_SRC_MAX) {
        return ICUB_CAN_ERANGE;
    }
    for (i = 0u; i < BOARD_MC_AXES; ++i) {
        if (axis[i].used && !(axis[i].ticks_per_degree > 0.0 && isfinite(axis[i].ticks_per_degree) &&
                              isfinite(axis[i].zero_deg))) {
            return ICUB_CAN_ERANGE;
        }
        if (axis[i].used && axis[i].has_pwm && !(axis[i].pwm_full_scale > 0.0 && axis[i].pwm_full_scale <= 32767.0)) {
            return ICUB_CAN_ERANGE;
        }
    }
    for (i = 0u; i < BOARD_MC_AXES; ++i) {
        b->axis[i] = axis[i];
        b->ticks[i] = 0;
        b->pwm[i] = 0;
        b->faults[i] = 0u;
    }
    b->address = address;
    b->board_flags = 0u; /* already running when the emulation starts: no RESTARTED flag */
    b->seq = 0u;
    b->periods = 0u;
    return ICUB_CAN_OK;
}

void board_mc_restart(board_mc_t *b)
{
    b->board_flags = ICUB_CAN_MC_BOARD_RESTARTED;
    b->seq = 0u;
    b->periods = 0u;
}

/* rint: half to even in the default rounding mode, as the host tools (numpy) round ticks and counts. */
void board_mc_sample(board_mc_t *b, const double q_rad[2], const double duty[2])
{
    uint8_t i;
    for (i = 0u; i < BOARD_MC_AXES; ++i) {
        const board_mc_axis_t *a = &b->axis[i];
        uint8_t f = 0u;
        int32_t ticks = 0;
        int16_t pwm = 0;
        if (a->used) {
            const double deg = q_rad[i] * (180.0 / 3.14159265358979323846) + a->zero_deg;
            const double t = rint(deg * a->ticks_per_degree);
            if (t >= -2147483648.0 && t <= 2147483647.0) {
                ticks = (int32_t)t;
            } else {
                f |= ICUB_CAN_MC_FAULT_ENCODER; /* also NaN: the comparisons fail */
                ticks = b->ticks[i];            /* hold the last reading */
            }
            if (a->has_pwm) {
                double c = rint(duty[i] * a->pwm_full_scale);
                if (c != c) {
                    c = 0.0;
                }
                if (c > 32767.0 || c < -32768.0) {
                    f |= ICUB_CAN_MC_FAULT_PWM_LIMIT;
                    c = (c > 0.0) ? 32767.0 : -32768.0;
                }
                pwm = (int16_t)c;
            }
        }
        b->ticks[i] = ticks;
        b->pwm[i] = pwm;
        b->faults[i] = f;
    }
    ++b->periods;
}

int board_mc_position_frame(const board_mc_t *b, board_frame_t *out)
{
    const int dlc = icub_can_mc_position_pack(out->data, b->ticks[0], b->ticks[1]);
    out->id = icub_can_id((uint8_t)ICUB_CAN_CLASS_MC, b->address, (uint8_t)ICUB_CAN_MC_POSITION);
    out->dlc = (uint8_t)dlc;
    return dlc;
}

int board_mc_pid_frame(const board_mc_t *b, board_frame_t *out)
{
    const int dlc = icub_can_mc_pid_val_pack(out->data, b->pwm[0], b->pwm[1]);
    out->id = icub_can_id((uint8_t)ICUB_CAN_CLASS_MC, b->address, (uint8_t)ICUB_CAN_MC_PID_VAL);
    out->dlc = (uint8_t)dlc;
    return dlc;
}

uint8_t board_mc_status_due(const board_mc_t *b)
{
    return (uint8_t)(b->periods > 0u && (b->periods - 1u) % BOARD_MC_STATUS_DIVIDER == 0u);
}

int board_mc_status_frame(board_mc_t *b, board_frame_t *out)
{
    const int dlc = icub_can_mc_status_pack(out->data, b->faults[0], b->faults[1], b->board_flags, b->seq);
    if (dlc < 0) {
        return dlc;
    }
    out->id = icub_can_id((uint8_t)ICUB_CAN_CLASS_MC, b->address, (uint8_t)ICUB_CAN_MC_STATUS);
    out->dlc = (uint8_t)dlc;
    b->seq = (uint8_t)(b->seq + 1u); /* wraps 255 -> 0 */
    b->board_flags = 0u;
    return dlc;
}
