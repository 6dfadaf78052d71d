/*
 * board_mc.h - motor-control board emulator, class 1: two axes per board address.
 *
 * Every period: POSITION (two int32 encoder ticks) and PID_VAL (two int16 PWM counts). Every
 * BOARD_MC_STATUS_DIVIDER periods: STATUS with the per-axis fault bits, the board flags and a sequence
 * counter (+1 per STATUS, wraps; 0 and the RESTARTED flag after board_mc_restart()).
 * Faults raised by the emulator itself: PWM_LIMIT when the commanded duty exceeds the PWM full scale
 * (the count is clamped), ENCODER when the angle cannot be represented in int32 ticks or is NaN.
 */
#ifndef BOARD_MC_H
#define BOARD_MC_H

#include <stdint.h>

#include "board_frame.h"

#define BOARD_MC_AXES 2u
#define BOARD_MC_STATUS_DIVIDER 10u /* STATUS at 100 Hz beside the 1 kHz periodic frames */

typedef struct {
    uint8_t used;             /* 0: the slot has no joint (sends 0 ticks, 0 PWM) */
    uint8_t has_pwm;          /* 0: no motor on this axis (PWM count 0) */
    double ticks_per_degree;  /* > 0 */
    double zero_deg;          /* encoder reading in degrees at joint angle 0 */
    double pwm_full_scale;    /* PWM count of duty 1.0, > 0 when has_pwm */
} board_mc_axis_t;

typedef struct {
    uint8_t address;
    board_mc_axis_t axis[BOARD_MC_AXES];
    int32_t ticks[BOARD_MC_AXES];
    int16_t pwm[BOARD_MC_AXES];
    uint8_t faults[BOARD_MC_AXES];   /* ICUB_CAN_MC_FAULT_* of the latest period */
    uint8_t board_flags;             /* ICUB_CAN_MC_BOARD_* pending for the next STATUS */
    uint8_t seq;
    uint32_t periods;                /* periods since init or restart */
} board_mc_t;

int board_mc_init(board_mc_t *b, uint8_t address, const board_mc_axis_t axis[2]);
/* A reset mid-run: counters restart, the next STATUS carries RESTARTED and sequence 0. */
void board_mc_restart(board_mc_t *b);
/* Latch one period: joint angles (rad) and duties ([-1, 1]) of the two slots. */
void board_mc_sample(board_mc_t *b, const double q_rad[2], const double duty[2]);
int board_mc_position_frame(const board_mc_t *b, board_frame_t *out);
int board_mc_pid_frame(const board_mc_t *b, board_frame_t *out);
/* 1 if this period (the one latched last) sends a STATUS. */
uint8_t board_mc_status_due(const board_mc_t *b);
/* The STATUS frame; advances the sequence and clears the one-shot board flags. */
int board_mc_status_frame(board_mc_t *b, board_frame_t *out);

#endif /* BOARD_MC_H */
