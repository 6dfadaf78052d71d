/*
 * board_skin.h - skin board emulator, class 4, one board per patch, 1 kHz.
 * Simplified layout (documented in the DBC): TAXELS, a uint16 bitmask of taxel groups in contact.
 * The emulator drives group 0 from the simulation's contact flag for its patch.
 */
#ifndef BOARD_SKIN_H
#define BOARD_SKIN_H

#include <stdint.h>

#include "board_frame.h"

typedef struct {
    uint8_t address;
    uint16_t taxels;
} board_skin_t;

int board_skin_init(board_skin_t *b, uint8_t address);
void board_skin_sample(board_skin_t *b, uint16_t taxels);
int board_skin_frame(const board_skin_t *b, board_frame_t *out);

#endif /* BOARD_SKIN_H */
