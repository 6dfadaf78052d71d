/* board_skin.c - skin board emulator: one TAXELS frame per period. */
#include "board_skin.h"

#include "icub_can.h"

int board_skin_init(board_skin_t *b, uint8_t address)
{
    if (b == 0) {
        return ICUB_CAN_EINVAL;
    }
    if (address > ICUB_CAN_SRC_MAX) {
        return ICUB_CAN_ERANGE;
    }
    b->address = address;
    b->taxels = 0u;
    return ICUB_CAN_OK;
}

void board_skin_sample(board_skin_t *b, uint16_t taxels)
{
    b->taxels = taxels;
}

int board_skin_frame(const board_skin_t *b, board_frame_t *out)
{
    const int dlc = icub_can_skin_pack(out->data, b->taxels);
    out->id = icub_can_id((uint8_t)ICUB_CAN_CLASS_SKIN, b->address, (uint8_t)ICUB_CAN_SKIN_TAXELS);
    out->dlc = (uint8_t)dlc;
    return dlc;
}
