/*
 * board_frame.h - one classic CAN frame as the emulated boards hand it to their CAN driver.
 * Kept free of any host header (no <linux/can.h>): the host tool converts it for its sinks.
 */
#ifndef BOARD_FRAME_H
#define BOARD_FRAME_H

#include <stdint.h>

typedef struct {
    uint16_t id;      /* 11-bit standard ID: class<<8 | source<<4 | type */
    uint8_t dlc;      /* 0..8 */
    uint8_t data[8];
} board_frame_t;

/* Bits on the wire of a standard-ID data frame, worst-case bit stuffing, interframe space included
 * (Davis, Burns, Bril, Lukkien 2007: 34 + 8*dlc + 13 + floor((34 + 8*dlc - 1) / 4); 135 for 8 bytes). */
uint32_t board_frame_bits_worst(uint8_t dlc);

#endif /* BOARD_FRAME_H */
