/* board_frame.c - CAN frame bit lengths for the bus-load budget. */
#include "board_frame.h"

uint32_t board_frame_bits_worst(uint8_t dlc)
{
    const uint32_t g = 34u; /* SOF, 11-bit ID, RTR, IDE, r0, DLC, 15-bit CRC: the stuffed part with data */
    const uint32_t n = (dlc > 8u) ? 8u : (uint32_t)dlc;
    return g + 8u * n + 13u + (g + 8u * n - 1u) / 4u;
}
