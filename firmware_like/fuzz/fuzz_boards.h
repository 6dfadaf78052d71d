/*
 * fuzz_boards.h - shared by the boards program's harnesses: the board emulators set up from a configuration and
 * played one sample, every frame they send checked to decode (a frame the boards send is one the monitor reads).
 * Static buffers only (C99, no heap).
 */
#ifndef FUZZ_BOARDS_H
#define FUZZ_BOARDS_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "board_mc.h"
#include "board_skin.h"
#include "board_strain.h"
#include "boards_tool.h"
#include "icub_can.h"

#define FUZZ_CHECK(cond) do { if (!(cond)) abort(); } while (0)

typedef struct {
    board_strain_t strain;
    board_mc_t mc[BOARDS_MAX_MC];
    board_skin_t skin[BOARDS_MAX_SKIN];
    int ready; /* the boards program would run with this configuration */
} fuzz_boards_t;

/* A frame a board sent: its class's decoder takes it. */
static void fuzz_boards_frame_decodes(const board_frame_t *f)
{
    uint8_t cls = 0, src = 0, type = 0, b0, b1, b2, b3;
    int32_t p0, p1;
    int16_t s[3];
    uint16_t taxels;
    FUZZ_CHECK(icub_can_id_split(f->id, &cls, &src, &type) == ICUB_CAN_OK);
    if (cls == ICUB_CAN_CLASS_STRAIN) {
        FUZZ_CHECK(icub_can_strain_unpack(f->data, f->dlc, s, &b0) == ICUB_CAN_OK);
    } else if (cls == ICUB_CAN_CLASS_SKIN) {
        FUZZ_CHECK(icub_can_skin_unpack(f->data, f->dlc, &taxels) == ICUB_CAN_OK);
    } else if (type == ICUB_CAN_MC_POSITION) {
        FUZZ_CHECK(icub_can_mc_position_unpack(f->data, f->dlc, &p0, &p1) == ICUB_CAN_OK);
    } else if (type == ICUB_CAN_MC_PID_VAL) {
        FUZZ_CHECK(icub_can_mc_pid_val_unpack(f->data, f->dlc, (int16_t *)&s[0], (int16_t *)&s[1]) == ICUB_CAN_OK);
    } else {
        FUZZ_CHECK(cls == ICUB_CAN_CLASS_MC && type == ICUB_CAN_MC_STATUS);
        FUZZ_CHECK(icub_can_mc_status_unpack(f->data, f->dlc, &b0, &b1, &b2, &b3) == ICUB_CAN_OK);
    }
}

/* As boards.c sets them up (the board inits refuse what the program refuses: exit 4). */
static void fuzz_boards_init(fuzz_boards_t *b, const boards_conf_t *c, uint8_t sat_variant)
{
    int i;
    b->ready = board_strain_init(&b->strain, c->strain_address, c->strain_fs, sat_variant) == 0;
    for (i = 0; i < c->n_mc; ++i) {
        b->ready = b->ready && board_mc_init(&b->mc[i], c->mc[i].address, c->mc[i].axis) == 0;
    }
    for (i = 0; i < c->n_skin; ++i) {
        b->ready = b->ready && board_skin_init(&b->skin[i], c->skin_address[i]) == 0;
    }
}

/* One sample, as boards.c plays it: q and duty per motor-control board and slot, the wrench, the skin bits. */
static void fuzz_boards_play(fuzz_boards_t *b, const boards_conf_t *c, const double q[][2], const double duty[][2],
                             const double wrench[6], uint16_t skin, int restart)
{
    board_frame_t f;
    int i;
    for (i = 0; i < c->n_mc; ++i) {
        if (restart == i) {
            board_mc_restart(&b->mc[i]);
        }
        board_mc_sample(&b->mc[i], q[i], duty[i]);
        FUZZ_CHECK(board_mc_position_frame(&b->mc[i], &f) > 0);
        fuzz_boards_frame_decodes(&f);
        FUZZ_CHECK(board_mc_pid_frame(&b->mc[i], &f) > 0);
        fuzz_boards_frame_decodes(&f);
        if (board_mc_status_due(&b->mc[i])) {
            FUZZ_CHECK(board_mc_status_frame(&b->mc[i], &f) > 0);
            fuzz_boards_frame_decodes(&f);
        }
    }
    for (i = 0; i < c->n_skin; ++i) {
        board_skin_sample(&b->skin[i], (uint16_t)((skin >> i) & 1u));
        FUZZ_CHECK(board_skin_frame(&b->skin[i], &f) > 0);
        fuzz_boards_frame_decodes(&f);
    }
    if (board_strain_sample(&b->strain, wrench) == ICUB_CAN_OK) {
        FUZZ_CHECK(board_strain_frame(&b->strain, BOARD_STRAIN_HALF_FORCE, &f) > 0);
        fuzz_boards_frame_decodes(&f);
        FUZZ_CHECK(board_strain_frame(&b->strain, BOARD_STRAIN_HALF_TORQUE, &f) > 0);
        fuzz_boards_frame_decodes(&f);
    }
}

/* fmemopen over a copy of the input (fmemopen wants a writable buffer; a zero size is not portable). */
static FILE *fuzz_boards_open(const uint8_t *data, size_t size)
{
    static char buf[1L << 20];
    if (size > sizeof buf) {
        return 0;
    }
    memcpy(buf, data, size);
    return fmemopen(buf, size ? size : 1, "r");
}

#endif /* FUZZ_BOARDS_H */
