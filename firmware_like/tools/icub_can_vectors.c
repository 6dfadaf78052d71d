/*
 * icub_can_vectors - test vectors from the C side of the protocol, for the DBC cross-check
 * (tools/tests/test_can_dbc.py decodes and re-encodes every frame with cantools).
 *
 * Output, one record a line:
 *   const NAME VALUE                 a macro of icub_can.h, as the compiler sees it
 *   frame ID DLC HEXPAYLOAD k=v ...  a frame made by the pack functions, and the values packed
 * Values are edge cases plus a fixed-seed LCG, so every run prints the same vectors.
 */
#include <stdio.h>

#include "icub_can.h"

static uint32_t g_state = 12345u;

static uint32_t lcg(void)
{
    g_state = g_state * 1664525u + 1013904223u;
    return g_state;
}

static void frame(uint16_t id, int dlc, const uint8_t *p)
{
    int i;
    printf("frame %03X %d ", (unsigned)id, dlc);
    for (i = 0; i < dlc; ++i)
        printf("%02X", (unsigned)p[i]);
}

#define CONST(name) printf("const %s %ld\n", #name, (long)(name))

int main(void)
{
    static const int16_t edge16[] = {0, 1, -1, INT16_MAX, INT16_MIN, 12345, -23456};
    static const int32_t edge32[] = {0, 1, -1, INT32_MAX, INT32_MIN, 16384 * 90, -7};
    uint8_t p[8];
    int i, n;

    CONST(ICUB_CAN_CLASS_MC);
    CONST(ICUB_CAN_CLASS_STRAIN);
    CONST(ICUB_CAN_CLASS_SKIN);
    CONST(ICUB_CAN_MC_POSITION);
    CONST(ICUB_CAN_MC_PID_VAL);
    CONST(ICUB_CAN_MC_STATUS);
    CONST(ICUB_CAN_MC_POSITION_DLC);
    CONST(ICUB_CAN_MC_PID_VAL_DLC);
    CONST(ICUB_CAN_MC_STATUS_DLC);
    CONST(ICUB_CAN_STRAIN_FORCE);
    CONST(ICUB_CAN_STRAIN_TORQUE);
    CONST(ICUB_CAN_STRAIN_DLC);
    CONST(ICUB_CAN_STRAIN_DLC_SAT);
    CONST(ICUB_CAN_STRAIN_SAT_MASK);
    CONST(ICUB_CAN_SKIN_TAXELS);
    CONST(ICUB_CAN_SKIN_TAXELS_DLC);
    CONST(ICUB_CAN_MC_FAULT_OVERCURRENT);
    CONST(ICUB_CAN_MC_FAULT_OVERTEMP);
    CONST(ICUB_CAN_MC_FAULT_ENCODER);
    CONST(ICUB_CAN_MC_FAULT_EXTERNAL);
    CONST(ICUB_CAN_MC_FAULT_PWM_LIMIT);
    CONST(ICUB_CAN_MC_FAULT_MASK);
    CONST(ICUB_CAN_MC_BOARD_RESTARTED);
    CONST(ICUB_CAN_MC_BOARD_TX_OVERRUN);
    CONST(ICUB_CAN_MC_BOARD_MASK);

    for (i = 0; i < 64; ++i) {
        int16_t s[3];
        int32_t a0, a1;
        int16_t w0, w1;
        uint8_t f0, f1, b, seq, flags;
        uint16_t taxels, id;
        uint8_t src = (uint8_t)(lcg() >> 28); /* any board address: the layout must not depend on it */
        for (n = 0; n < 3; ++n)
            s[n] = i < 7 ? edge16[(i + n) % 7] : (int16_t)(lcg() >> 16);
        flags = (uint8_t)((lcg() >> 24) & ICUB_CAN_STRAIN_SAT_MASK);
        id = icub_can_id(ICUB_CAN_CLASS_STRAIN, src, (i & 1) ? ICUB_CAN_STRAIN_TORQUE : ICUB_CAN_STRAIN_FORCE);
        n = (i & 2) ? icub_can_strain_pack_sat(p, s, flags) : icub_can_strain_pack(p, s);
        frame(id, n, p);
        printf(" s0=%d s1=%d s2=%d flags=%u\n", s[0], s[1], s[2], (unsigned)((i & 2) ? flags : 0));

        a0 = i < 7 ? edge32[i] : (int32_t)lcg();
        a1 = i < 7 ? edge32[6 - i] : (int32_t)lcg();
        n = icub_can_mc_position_pack(p, a0, a1);
        frame(icub_can_id(ICUB_CAN_CLASS_MC, src, ICUB_CAN_MC_POSITION), n, p);
        printf(" axis0=%ld axis1=%ld\n", (long)a0, (long)a1);

        w0 = i < 7 ? edge16[i] : (int16_t)(lcg() >> 16);
        w1 = i < 7 ? edge16[6 - i] : (int16_t)(lcg() >> 16);
        n = icub_can_mc_pid_val_pack(p, w0, w1);
        frame(icub_can_id(ICUB_CAN_CLASS_MC, src, ICUB_CAN_MC_PID_VAL), n, p);
        printf(" axis0=%d axis1=%d\n", w0, w1);

        f0 = (uint8_t)(lcg() >> 24) & ICUB_CAN_MC_FAULT_MASK;
        f1 = (uint8_t)(lcg() >> 24) & ICUB_CAN_MC_FAULT_MASK;
        b = (uint8_t)(lcg() >> 24) & ICUB_CAN_MC_BOARD_MASK;
        seq = (uint8_t)(lcg() >> 24);
        n = icub_can_mc_status_pack(p, f0, f1, b, seq);
        frame(icub_can_id(ICUB_CAN_CLASS_MC, src, ICUB_CAN_MC_STATUS), n, p);
        printf(" faults0=%u faults1=%u board=%u seq=%u\n", (unsigned)f0, (unsigned)f1, (unsigned)b, (unsigned)seq);

        taxels = (uint16_t)(lcg() >> 16);
        n = icub_can_skin_pack(p, taxels);
        frame(icub_can_id(ICUB_CAN_CLASS_SKIN, src, ICUB_CAN_SKIN_TAXELS), n, p);
        printf(" taxels=%u\n", (unsigned)taxels);
    }
    return 0;
}
