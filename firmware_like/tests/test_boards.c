/*
 * test_boards.c - plain C99 checks of the board emulators against hand-computed frames
 * (bytes written out from the protocol of docs/design.md §5, not from the codec under test).
 */
#include "board_mc.h"
#include "board_skin.h"
#include "board_strain.h"
#include "icub_can.h"

#include "check.h"

#include <stdio.h>
#include <string.h>

static void test_bits(void)
{
    /* 34 + 8n + 13 + floor((34 + 8n - 1) / 4): the textbook 135 bits of a full standard frame */
    CHECK_EQ(board_frame_bits_worst(8u), 135);
    CHECK_EQ(board_frame_bits_worst(0u), 55);
    CHECK_EQ(board_frame_bits_worst(6u), 115);
    CHECK_EQ(board_frame_bits_worst(2u), 75);
}

static void test_strain(void)
{
    board_strain_t b;
    board_frame_t f;
    const double fs[6] = {200.0, 200.0, 200.0, 10.0, 10.0, 10.0};
    /* 1 N -> 163.84 -> 164 = 0x80A4; -200 N -> -32768 -> 0x0000; 0 -> 0x8000;
     * 0.5 Nm -> 1638.4 -> 1638 = 0x8666; 20 Nm clamps to 32767 = 0xFFFF; -0.00015 Nm -> -0.49 -> 0 */
    const double w[6] = {1.0, -200.0, 0.0, 0.5, 20.0, -0.00015};
    CHECK_EQ(board_strain_init(&b, 13u, fs, 0u), ICUB_CAN_OK);
    CHECK_EQ(board_strain_sample(&b, w), ICUB_CAN_OK);
    CHECK_EQ(board_strain_frame(&b, BOARD_STRAIN_HALF_FORCE, &f), 6);
    CHECK_EQ(f.id, 0x3DA);
    CHECK_BYTES(f.data, 0xA4, 0x80, 0x00, 0x00, 0x00, 0x80);
    CHECK_EQ(board_strain_frame(&b, BOARD_STRAIN_HALF_TORQUE, &f), 6);
    CHECK_EQ(f.id, 0x3DB);
    CHECK_BYTES(f.data, 0x66, 0x86, 0xFF, 0xFF, 0x00, 0x80);
    CHECK_EQ(b.saturations, 1);
    /* the saturation variant: byte 6 flags Ty (channel 1 of the torque half) */
    CHECK_EQ(board_strain_init(&b, 13u, fs, 1u), ICUB_CAN_OK);
    CHECK_EQ(board_strain_sample(&b, w), ICUB_CAN_OK);
    CHECK_EQ(board_strain_frame(&b, BOARD_STRAIN_HALF_FORCE, &f), 7);
    CHECK_EQ(f.data[6], 0x00);
    CHECK_EQ(board_strain_frame(&b, BOARD_STRAIN_HALF_TORQUE, &f), 7);
    CHECK_EQ(f.data[6], 0x02);
    {
        const double bad_fs[6] = {200.0, 0.0, 200.0, 10.0, 10.0, 10.0};
        double nan_w[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
        CHECK_EQ(board_strain_init(&b, 13u, bad_fs, 0u), ICUB_CAN_ERANGE);
        CHECK_EQ(board_strain_init(&b, 16u, fs, 0u), ICUB_CAN_ERANGE);
        CHECK_EQ(board_strain_init(&b, 13u, fs, 0u), ICUB_CAN_OK);
        CHECK_EQ(board_strain_sample(&b, w), ICUB_CAN_OK);
        volatile double zero = 0.0;
        nan_w[2] = zero / zero;
        CHECK_EQ(board_strain_sample(&b, nan_w), ICUB_CAN_EINVAL);
        CHECK_EQ(b.counts[0], 164); /* the previous conversion is kept */
    }
}

static void test_mc(void)
{
    board_mc_t b;
    board_frame_t f;
    board_mc_axis_t ax[2];
    /* 1 rad = 57.29577951 deg; at 100 ticks/deg with a 10 deg zero: 6729.577951 -> 6730 = 0x1A4A.
     * -0.5 rad: -28.64788976 deg + 10 = -18.64788976 -> -1864.788976 -> -1865 = 0xFFFFF8B7. */
    const double q[2] = {1.0, -0.5};
    const double duty[2] = {0.5, -30.0};
    unsigned i;
    memset(ax, 0, sizeof ax);
    for (i = 0u; i < 2u; ++i) {
        ax[i].used = 1u;
        ax[i].has_pwm = 1u;
        ax[i].ticks_per_degree = 100.0;
        ax[i].zero_deg = 10.0;
        ax[i].pwm_full_scale = 1333.0;
    }
    CHECK_EQ(board_mc_init(&b, 2u, ax), ICUB_CAN_OK);
    board_mc_sample(&b, q, duty);
    CHECK_EQ(board_mc_position_frame(&b, &f), 8);
    CHECK_EQ(f.id, 0x121);
    CHECK_BYTES(f.data, 0x4A, 0x1A, 0x00, 0x00, 0xB7, 0xF8, 0xFF, 0xFF);
    /* 0.5 * 1333 = 666.5 -> 666 (half to even, as numpy rounds) = 0x029A; -30 * 1333 clamps to -32768 */
    CHECK_EQ(board_mc_pid_frame(&b, &f), 4);
    CHECK_EQ(f.id, 0x122);
    CHECK_BYTES(f.data, 0x9A, 0x02, 0x00, 0x80);
    CHECK_EQ(board_mc_status_due(&b), 1);
    CHECK_EQ(board_mc_status_frame(&b, &f), 4);
    CHECK_EQ(f.id, 0x123);
    CHECK_BYTES(f.data, 0x00, ICUB_CAN_MC_FAULT_PWM_LIMIT, 0x00, 0x00);
    for (i = 1u; i < 10u; ++i) {
        board_mc_sample(&b, q, duty);
        CHECK_EQ(board_mc_status_due(&b), 0);
    }
    board_mc_sample(&b, q, duty);
    CHECK_EQ(board_mc_status_due(&b), 1);
    board_mc_status_frame(&b, &f);
    CHECK_EQ(f.data[3], 1); /* sequence */
    board_mc_restart(&b);
    board_mc_sample(&b, q, duty);
    CHECK_EQ(board_mc_status_due(&b), 1);
    board_mc_status_frame(&b, &f);
    CHECK_BYTES(f.data, 0x00, ICUB_CAN_MC_FAULT_PWM_LIMIT, ICUB_CAN_MC_BOARD_RESTARTED, 0x00);
    board_mc_sample(&b, q, duty);
    for (i = 1u; i < 10u; ++i) {
        board_mc_sample(&b, q, duty);
    }
    board_mc_status_frame(&b, &f);
    CHECK_EQ(f.data[2], 0x00); /* RESTARTED only once */
    CHECK_EQ(f.data[3], 1);
    {
        const double far[2] = {1e9, 0.0};
        board_mc_sample(&b, far, duty);
        CHECK_EQ(b.faults[0], ICUB_CAN_MC_FAULT_ENCODER);
        CHECK_EQ(b.ticks[0], 6730); /* held */
    }
    ax[1].ticks_per_degree = 0.0;
    CHECK_EQ(board_mc_init(&b, 2u, ax), ICUB_CAN_ERANGE);
}

static void test_skin(void)
{
    board_skin_t b;
    board_frame_t f;
    CHECK_EQ(board_skin_init(&b, 8u), ICUB_CAN_OK);
    board_skin_sample(&b, 0x0201u);
    CHECK_EQ(board_skin_frame(&b, &f), 2);
    CHECK_EQ(f.id, 0x480);
    CHECK_BYTES(f.data, 0x01, 0x02);
}

int main(void)
{
    test_bits();
    test_strain();
    test_mc();
    test_skin();
    printf("%u checks, %u failed\n", g_checks, g_failed);
    return g_failed ? 1 : 0;
}
