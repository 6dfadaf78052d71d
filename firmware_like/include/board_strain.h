/*
 * board_strain.h - strain (6-axis F/T) board emulator, class 3, 1 kHz.
 *
 * Each period the board converts its six channels once (board_strain_sample) and then sends the two
 * halves of that conversion: type 0xA (Fx Fy Fz) and type 0xB (Tx Ty Tz), offset-binary uint16 over the
 * configured full scales. The saturation variant sends 7-byte frames whose byte 6 flags the clamped
 * channels; the plain variant sends 6 bytes (a clamped channel then only shows as a full-scale count).
 */
#ifndef BOARD_STRAIN_H
#define BOARD_STRAIN_H

#include <stdint.h>

#include "board_frame.h"

#define BOARD_STRAIN_CHANNELS 6u
#define BOARD_STRAIN_HALF_FORCE  0u
#define BOARD_STRAIN_HALF_TORQUE 1u

typedef struct {
    uint8_t address;                         /* CAN source address 0..15 */
    uint8_t sat_variant;                     /* 1: 7-byte frames with saturation flags */
    double full_scale[BOARD_STRAIN_CHANNELS];/* N, N, N, Nm, Nm, Nm: value of count 32768 */
    int16_t counts[BOARD_STRAIN_CHANNELS];   /* the latched conversion */
    uint8_t saturated;                       /* bit ch: channel ch clamped in the latched conversion */
    uint32_t conversions;
    uint32_t saturations;                    /* channel-conversions clamped since init */
} board_strain_t;

/* ICUB_CAN_ERANGE on a bad address or a full scale that is not finite and > 0. */
int board_strain_init(board_strain_t *b, uint8_t address, const double full_scale[6], uint8_t sat_variant);
/* Convert one wrench (N, Nm) and latch it. ICUB_CAN_EINVAL on a NaN channel (nothing latched). */
int board_strain_sample(board_strain_t *b, const double wrench[6]);
/* The frame of one half of the latched conversion; returns its DLC or a negative ICUB_CAN_E*. */
int board_strain_frame(const board_strain_t *b, uint8_t half, board_frame_t *out);

#endif /* BOARD_STRAIN_H */
