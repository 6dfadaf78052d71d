/*
 * test_icub_can.c - plain C99 checks for icub_can. Exit status 1 on any failed
 * check, each failure printed with its line. `--must-fail` runs one false
 * check on purpose: ctest expects that run to fail, proving failures surface.
 */
#include "icub_can.h"

#include "check.h"

#include <stdio.h>
#include <string.h>

static int bytes_eq(const uint8_t *p, const uint8_t *want, unsigned n)
{
    return memcmp(p, want, n) == 0;
}

static void test_ids(void)
{
    uint8_t c, s, t;
    unsigned id;

    /* Known IDs. */
    CHECK_EQ(icub_can_id(ICUB_CAN_CLASS_STRAIN, 0xD, ICUB_CAN_STRAIN_FORCE), 0x3DA);
    CHECK_EQ(icub_can_id(ICUB_CAN_CLASS_STRAIN, 0xD, ICUB_CAN_STRAIN_TORQUE), 0x3DB);
    CHECK_EQ(icub_can_id(ICUB_CAN_CLASS_MC, 0x0, ICUB_CAN_MC_POSITION), 0x101);
    CHECK_EQ(icub_can_id(ICUB_CAN_CLASS_MC, 0x1, ICUB_CAN_MC_PID_VAL), 0x112);
    CHECK_EQ(icub_can_id(ICUB_CAN_CLASS_MC, 0xF, ICUB_CAN_MC_STATUS), 0x1F3);
    CHECK_EQ(icub_can_id(ICUB_CAN_CLASS_SKIN, 0xE, 0x0), 0x4E0);
    CHECK_EQ(icub_can_id(0, 0, 0), 0x000);
    CHECK_EQ(icub_can_id(7, 15, 15), 0x7FF);

    /* Fields wider than their bits. */
    CHECK_EQ(icub_can_id(8, 0, 0), ICUB_CAN_ID_INVALID);
    CHECK_EQ(icub_can_id(0, 16, 0), ICUB_CAN_ID_INVALID);
    CHECK_EQ(icub_can_id(0, 0, 16), ICUB_CAN_ID_INVALID);
    CHECK_EQ(icub_can_id(255, 255, 255), ICUB_CAN_ID_INVALID);

    /* Split is the exact inverse over the whole 11-bit space. */
    for (id = 0; id <= ICUB_CAN_ID_MAX; ++id) {
        if (icub_can_id_split((uint16_t)id, &c, &s, &t) != ICUB_CAN_OK ||
            icub_can_id(c, s, t) != id) {
            CHECK_EQ(id, 0xFFFFFu); /* report the first offender, then stop */
            break;
        }
    }
    CHECK_EQ(icub_can_id_split(0x3DA, &c, &s, &t), ICUB_CAN_OK);
    CHECK(c == 3 && s == 0xD && t == 0xA);
    CHECK_EQ(icub_can_id_split(0x800, &c, &s, &t), ICUB_CAN_ERANGE);
    CHECK_EQ(icub_can_id_split(0xFFFF, NULL, NULL, NULL), ICUB_CAN_ERANGE);
    CHECK_EQ(icub_can_id_split(0x7FF, NULL, NULL, NULL), ICUB_CAN_OK);
}

static void test_offset_binary(void)
{
    long v;
    CHECK_EQ(icub_can_ob_encode(0), 0x8000);
    CHECK_EQ(icub_can_ob_encode(1), 0x8001);
    CHECK_EQ(icub_can_ob_encode(-1), 0x7FFF);
    CHECK_EQ(icub_can_ob_encode(INT16_MIN), 0x0000);
    CHECK_EQ(icub_can_ob_encode(INT16_MAX), 0xFFFF);
    for (v = INT16_MIN; v <= INT16_MAX; ++v) {
        if (icub_can_ob_decode(icub_can_ob_encode((int16_t)v)) != v) {
            CHECK_EQ(v, 0x7FFFFFFFL);
            break;
        }
    }
}

static void test_strain_payload(void)
{
    uint8_t p[8], f;
    int16_t s[3], in[3];
    long v;
    unsigned dlc;

    /* Known bytes: s = 0 -> 00 80; ends of the range. */
    in[0] = 0; in[1] = INT16_MIN; in[2] = INT16_MAX;
    memset(p, 0xEE, sizeof p);
    CHECK_EQ(icub_can_strain_pack(p, in), 6);
    {
        static const uint8_t want[8] = {0x00, 0x80, 0x00, 0x00, 0xFF, 0xFF, 0xEE, 0xEE};
        CHECK(bytes_eq(p, want, 8)); /* and bytes 6, 7 untouched */
    }
    in[0] = 1; in[1] = -1; in[2] = 0x1234;
    CHECK_EQ(icub_can_strain_pack(p, in), 6);
    {
        static const uint8_t want[6] = {0x01, 0x80, 0xFF, 0x7F, 0x34, 0x92};
        CHECK(bytes_eq(p, want, 6));
    }

    /* Round trip of every int16 value on every channel position. */
    for (v = INT16_MIN; v <= INT16_MAX; ++v) {
        in[0] = (int16_t)v; in[1] = (int16_t)(-v - 1); in[2] = (int16_t)(v ^ 0x5555);
        f = 0xAA;
        if (icub_can_strain_pack(p, in) != 6 || icub_can_strain_unpack(p, 6, s, &f) != 0 ||
            s[0] != in[0] || s[1] != in[1] || s[2] != in[2] || f != 0) {
            CHECK_EQ(v, 0x7FFFFFFFL);
            break;
        }
    }

    /* Saturation flags in byte 6. */
    in[0] = INT16_MAX; in[1] = 0; in[2] = INT16_MIN;
    CHECK_EQ(icub_can_strain_pack_sat(p, in, ICUB_CAN_STRAIN_SAT(0) | ICUB_CAN_STRAIN_SAT(2)), 7);
    CHECK_EQ(p[6], 0x05);
    CHECK_EQ(icub_can_strain_unpack(p, 7, s, &f), ICUB_CAN_OK);
    CHECK_EQ(f, 0x05);
    CHECK(s[0] == INT16_MAX && s[1] == 0 && s[2] == INT16_MIN);
    /* A 6-byte frame reports no flags, whatever sits past its end. */
    CHECK_EQ(icub_can_strain_unpack(p, 6, s, &f), ICUB_CAN_OK);
    CHECK_EQ(f, 0);
    CHECK_EQ(icub_can_strain_unpack(p, 7, s, NULL), ICUB_CAN_OK);
    /* Reserved flag bits: refused both ways, no output written. */
    memset(p, 0xEE, sizeof p);
    CHECK_EQ(icub_can_strain_pack_sat(p, in, 0x08), ICUB_CAN_ERANGE);
    CHECK_EQ(p[0], 0xEE);
    p[6] = 0x80;
    s[0] = 42; f = 42;
    CHECK_EQ(icub_can_strain_unpack(p, 7, s, &f), ICUB_CAN_ERANGE);
    CHECK(s[0] == 42 && f == 42);

    /* Bad lengths. */
    for (dlc = 0; dlc <= 255; ++dlc) {
        int rc = icub_can_strain_unpack(p, (uint8_t)dlc, s, &f);
        if (dlc == 6 || dlc == 7)
            continue;
        if (rc != ICUB_CAN_EBADLEN) {
            CHECK_EQ(dlc, 0xFFFFu);
            break;
        }
    }
    CHECK_EQ(icub_can_strain_unpack(p, 8, s, &f), ICUB_CAN_EBADLEN);
    CHECK_EQ(icub_can_strain_unpack(p, 5, s, &f), ICUB_CAN_EBADLEN);

    CHECK_EQ(icub_can_strain_pack(NULL, in), ICUB_CAN_EINVAL);
    CHECK_EQ(icub_can_strain_pack(p, NULL), ICUB_CAN_EINVAL);
    CHECK_EQ(icub_can_strain_unpack(NULL, 6, s, &f), ICUB_CAN_EINVAL);
}

static void test_mc_position(void)
{
    static const int32_t edge[] = {0, 1, -1, INT32_MIN, INT32_MAX, INT32_MIN + 1,
                                   INT32_MAX - 1, 0x12345678, -0x12345678, 0x7F, 0x80, -0x80};
    const unsigned n = sizeof edge / sizeof edge[0];
    uint8_t p[8];
    int32_t a, b;
    unsigned i, j, dlc;

    for (i = 0; i < n; ++i)
        for (j = 0; j < n; ++j) {
            a = b = 42;
            CHECK_EQ(icub_can_mc_position_pack(p, edge[i], edge[j]), 8);
            CHECK_EQ(icub_can_mc_position_unpack(p, 8, &a, &b), ICUB_CAN_OK);
            CHECK_EQ(a, edge[i]);
            CHECK_EQ(b, edge[j]);
        }

    CHECK_EQ(icub_can_mc_position_pack(p, 0x12345678, -1), 8);
    {
        static const uint8_t want[8] = {0x78, 0x56, 0x34, 0x12, 0xFF, 0xFF, 0xFF, 0xFF};
        CHECK(bytes_eq(p, want, 8));
    }
    CHECK_EQ(icub_can_mc_position_pack(p, INT32_MIN, 1), 8);
    {
        static const uint8_t want[8] = {0x00, 0x00, 0x00, 0x80, 0x01, 0x00, 0x00, 0x00};
        CHECK(bytes_eq(p, want, 8));
    }

    for (dlc = 0; dlc <= 255; ++dlc) {
        if (dlc == 8)
            continue;
        a = 42;
        if (icub_can_mc_position_unpack(p, (uint8_t)dlc, &a, &b) != ICUB_CAN_EBADLEN || a != 42) {
            CHECK_EQ(dlc, 0xFFFFu);
            break;
        }
    }
    CHECK_EQ(icub_can_mc_position_unpack(p, 7, &a, &b), ICUB_CAN_EBADLEN);
    CHECK_EQ(icub_can_mc_position_unpack(p, 8, NULL, &b), ICUB_CAN_EINVAL);
    CHECK_EQ(icub_can_mc_position_pack(NULL, 0, 0), ICUB_CAN_EINVAL);
}

static void test_mc_pid_val(void)
{
    static const int16_t edge[] = {0, 1, -1, INT16_MIN, INT16_MAX, INT16_MIN + 1,
                                   INT16_MAX - 1, 0x1234, -0x1234, 0x7F, 0x80, -0x80};
    const unsigned n = sizeof edge / sizeof edge[0];
    uint8_t p[8];
    int16_t a, b;
    unsigned i, j, dlc;

    for (i = 0; i < n; ++i)
        for (j = 0; j < n; ++j) {
            a = b = 42;
            CHECK_EQ(icub_can_mc_pid_val_pack(p, edge[i], edge[j]), 4);
            CHECK_EQ(icub_can_mc_pid_val_unpack(p, 4, &a, &b), ICUB_CAN_OK);
            CHECK_EQ(a, edge[i]);
            CHECK_EQ(b, edge[j]);
        }

    memset(p, 0xEE, sizeof p);
    CHECK_EQ(icub_can_mc_pid_val_pack(p, -2, INT16_MIN), 4);
    {
        static const uint8_t want[8] = {0xFE, 0xFF, 0x00, 0x80, 0xEE, 0xEE, 0xEE, 0xEE};
        CHECK(bytes_eq(p, want, 8));
    }

    for (dlc = 0; dlc <= 255; ++dlc) {
        if (dlc == 4)
            continue;
        a = 42;
        if (icub_can_mc_pid_val_unpack(p, (uint8_t)dlc, &a, &b) != ICUB_CAN_EBADLEN || a != 42) {
            CHECK_EQ(dlc, 0xFFFFu);
            break;
        }
    }
    CHECK_EQ(icub_can_mc_pid_val_unpack(p, 8, &a, &b), ICUB_CAN_EBADLEN);
    CHECK_EQ(icub_can_mc_pid_val_unpack(p, 3, &a, &b), ICUB_CAN_EBADLEN);
    CHECK_EQ(icub_can_mc_pid_val_unpack(p, 4, &a, NULL), ICUB_CAN_EINVAL);
}

static void test_count_fixed(void)
{
    int16_t s = 0;
    uint8_t sat = 7;
    long v;

    CHECK_EQ(icub_can_strain_count_fx(0, 1000, &s, &sat), ICUB_CAN_OK);
    CHECK(s == 0 && sat == 0);
    /* +FS is one count past the top: clamps and reports it; -FS is exact. */
    CHECK_EQ(icub_can_strain_count_fx(1000, 1000, &s, &sat), ICUB_CAN_OK);
    CHECK(s == INT16_MAX && sat == 1);
    CHECK_EQ(icub_can_strain_count_fx(-1000, 1000, &s, &sat), ICUB_CAN_OK);
    CHECK(s == INT16_MIN && sat == 0);
    CHECK_EQ(icub_can_strain_count_fx(-1001, 1000, &s, &sat), ICUB_CAN_OK);
    CHECK(s == INT16_MIN && sat == 1);
    CHECK_EQ(icub_can_strain_count_fx(INT32_MAX, 1, &s, &sat), ICUB_CAN_OK);
    CHECK(s == INT16_MAX && sat == 1);
    CHECK_EQ(icub_can_strain_count_fx(INT32_MIN, 1, &s, &sat), ICUB_CAN_OK);
    CHECK(s == INT16_MIN && sat == 1);
    /* Ties go away from zero: fs = 65536 makes value/2 exact. */
    CHECK_EQ(icub_can_strain_count_fx(1, 65536, &s, NULL), ICUB_CAN_OK);
    CHECK_EQ(s, 1);
    CHECK_EQ(icub_can_strain_count_fx(-1, 65536, &s, NULL), ICUB_CAN_OK);
    CHECK_EQ(s, -1);
    CHECK_EQ(icub_can_strain_count_fx(3, 65536, &s, NULL), ICUB_CAN_OK);
    CHECK_EQ(s, 2);
    CHECK_EQ(icub_can_strain_count_fx(-3, 65536, &s, NULL), ICUB_CAN_OK);
    CHECK_EQ(s, -2);
    /* The last value below the top tie, and the tie itself. */
    CHECK_EQ(icub_can_strain_count_fx(65534, 65536, &s, &sat), ICUB_CAN_OK);
    CHECK(s == 32767 && sat == 0);
    CHECK_EQ(icub_can_strain_count_fx(65535, 65536, &s, &sat), ICUB_CAN_OK);
    CHECK(s == 32767 && sat == 1);
    CHECK_EQ(icub_can_strain_count_fx(-65536, 65536, &s, &sat), ICUB_CAN_OK);
    CHECK(s == -32768 && sat == 0);
    CHECK_EQ(icub_can_strain_count_fx(-65537, 65536, &s, &sat), ICUB_CAN_OK);
    CHECK(s == -32768 && sat == 1);
    /* Bad full scales and NULL: refused, output untouched. */
    s = 42;
    CHECK_EQ(icub_can_strain_count_fx(1, 0, &s, &sat), ICUB_CAN_ERANGE);
    CHECK_EQ(icub_can_strain_count_fx(1, -5, &s, &sat), ICUB_CAN_ERANGE);
    CHECK_EQ(s, 42);
    CHECK_EQ(icub_can_strain_count_fx(1, 5, NULL, &sat), ICUB_CAN_EINVAL);

    /* Inverse. */
    CHECK_EQ(icub_can_strain_value_fx(0, 1000), 0);
    CHECK_EQ(icub_can_strain_value_fx(INT16_MIN, 1000), -1000);
    CHECK_EQ(icub_can_strain_value_fx(16384, 1000), 500);
    CHECK_EQ(icub_can_strain_value_fx(INT16_MIN, INT32_MAX), -INT32_MAX);
    CHECK_EQ(icub_can_strain_value_fx(INT16_MAX, INT32_MAX), 2147418111L); /* 2^31 - 2^16 - 32767/32768 */
    /* count(value(s)) == s when FS has at least 16 bits of resolution. */
    for (v = INT16_MIN; v <= INT16_MAX; ++v) {
        if (icub_can_strain_count_fx(icub_can_strain_value_fx((int16_t)v, 200000), 200000, &s, &sat) != 0 ||
            s != v || sat) {
            CHECK_EQ(v, 0x7FFFFFFFL);
            break;
        }
    }
}

#ifndef ICUB_CAN_NO_FLOAT
static void test_count_double(void)
{
    int16_t s = 0, sfx = 0;
    uint8_t sat = 7, satfx = 7;
    long v;
    double inf = 1e308 * 10.0;
    double nan = inf - inf;

    CHECK_EQ(icub_can_strain_count(0.0, 100.0, &s, &sat), ICUB_CAN_OK);
    CHECK(s == 0 && sat == 0);
    CHECK_EQ(icub_can_strain_count(100.0, 100.0, &s, &sat), ICUB_CAN_OK);
    CHECK(s == INT16_MAX && sat == 1);
    CHECK_EQ(icub_can_strain_count(-100.0, 100.0, &s, &sat), ICUB_CAN_OK);
    CHECK(s == INT16_MIN && sat == 0);
    CHECK_EQ(icub_can_strain_count(99.99, 100.0, &s, &sat), ICUB_CAN_OK); /* 32764.72 */
    CHECK(s == 32765 && sat == 0);
    CHECK_EQ(icub_can_strain_count(1.0, 65536.0, &s, NULL), ICUB_CAN_OK); /* 0.5 */
    CHECK_EQ(s, 1);
    CHECK_EQ(icub_can_strain_count(-1.0, 65536.0, &s, NULL), ICUB_CAN_OK);
    CHECK_EQ(s, -1);
    CHECK_EQ(icub_can_strain_count(65535.0, 65536.0, &s, &sat), ICUB_CAN_OK); /* 32767.5 */
    CHECK(s == INT16_MAX && sat == 1);
    CHECK_EQ(icub_can_strain_count(-65537.0, 65536.0, &s, &sat), ICUB_CAN_OK); /* -32768.5 */
    CHECK(s == INT16_MIN && sat == 1);
    /* The classic floor(x + 0.5) trap: 0.49999999999999994 must give 0. */
    CHECK_EQ(icub_can_strain_count(0.49999999999999994, 32768.0, &s, NULL), ICUB_CAN_OK);
    CHECK_EQ(s, 0);
    CHECK_EQ(icub_can_strain_count(-0.49999999999999994, 32768.0, &s, NULL), ICUB_CAN_OK);
    CHECK_EQ(s, 0);
    CHECK_EQ(icub_can_strain_count(1e300, 1.0, &s, &sat), ICUB_CAN_OK);
    CHECK(s == INT16_MAX && sat == 1);
    CHECK_EQ(icub_can_strain_count(inf, 1.0, &s, &sat), ICUB_CAN_OK);
    CHECK(s == INT16_MAX && sat == 1);
    CHECK_EQ(icub_can_strain_count(-inf, 1.0, &s, &sat), ICUB_CAN_OK);
    CHECK(s == INT16_MIN && sat == 1);
    s = 42;
    CHECK_EQ(icub_can_strain_count(nan, 1.0, &s, &sat), ICUB_CAN_EINVAL);
    CHECK_EQ(icub_can_strain_count(1.0, 0.0, &s, &sat), ICUB_CAN_ERANGE);
    CHECK_EQ(icub_can_strain_count(1.0, -1.0, &s, &sat), ICUB_CAN_ERANGE);
    CHECK_EQ(icub_can_strain_count(1.0, nan, &s, &sat), ICUB_CAN_ERANGE);
    CHECK_EQ(icub_can_strain_count(1.0, inf, &s, &sat), ICUB_CAN_ERANGE);
    CHECK_EQ(s, 42);

    /* Double and fixed-point paths agree on integer inputs, ties included. */
    for (v = -140000; v <= 140000; v += 7) {
        long fs;
        for (fs = 50000; fs <= 65536; fs += 15536) {
            icub_can_strain_count((double)v, (double)fs, &s, &sat);
            icub_can_strain_count_fx((int32_t)v, (int32_t)fs, &sfx, &satfx);
            if (s != sfx || sat != satfx) {
                CHECK_EQ(v, 0x7FFFFFFFL);
                v = 140001;
                break;
            }
        }
    }

    /* count(value(s)) == s for a non-round full scale. */
    for (v = INT16_MIN; v <= INT16_MAX; ++v) {
        double fs = 123.456;
        if (icub_can_strain_count(icub_can_strain_value((int16_t)v, fs), fs, &s, &sat) != 0 ||
            s != v || sat) {
            CHECK_EQ(v, 0x7FFFFFFFL);
            break;
        }
    }
    CHECK(icub_can_strain_value(INT16_MIN, 100.0) == -100.0);
    CHECK(icub_can_strain_value(16384, 100.0) == 50.0);
}
#endif

/* A board's view: three physical values -> counts + flags -> 7-byte frame -> back. */
static void test_saturation_frame(void)
{
    static const int32_t value[3] = {1500, -200, -1600}; /* mN, FS 1000 mN */
    int16_t s[3], out[3];
    uint8_t p[8], flags = 0, sat, got;
    int i;

    for (i = 0; i < 3; ++i) {
        CHECK_EQ(icub_can_strain_count_fx(value[i], 1000, &s[i], &sat), ICUB_CAN_OK);
        flags = (uint8_t)(flags | (sat ? ICUB_CAN_STRAIN_SAT(i) : 0));
    }
    CHECK_EQ(flags, 0x05);
    CHECK_EQ(icub_can_strain_pack_sat(p, s, flags), 7);
    CHECK_EQ(icub_can_strain_unpack(p, 7, out, &got), ICUB_CAN_OK);
    CHECK_EQ(got, 0x05);
    CHECK(out[0] == INT16_MAX && out[1] == -6554 && out[2] == INT16_MIN);
}

static void test_mc_status_and_skin(void)
{
    uint8_t p[8] = {0}, f0 = 0, f1 = 0, b = 0, seq = 0;
    uint16_t tx = 0;
    CHECK_EQ(icub_can_mc_status_pack(p, ICUB_CAN_MC_FAULT_OVERCURRENT, ICUB_CAN_MC_FAULT_PWM_LIMIT,
                                     ICUB_CAN_MC_BOARD_RESTARTED, 255), 4);
    CHECK(p[0] == 0x01 && p[1] == 0x10 && p[2] == 0x01 && p[3] == 0xFF);
    CHECK_EQ(icub_can_mc_status_unpack(p, 4, &f0, &f1, &b, &seq), ICUB_CAN_OK);
    CHECK(f0 == 0x01 && f1 == 0x10 && b == 0x01 && seq == 255);
    CHECK_EQ(icub_can_mc_status_unpack(p, 3, &f0, NULL, NULL, NULL), ICUB_CAN_EBADLEN);
    CHECK_EQ(icub_can_mc_status_pack(p, 0x20, 0, 0, 0), ICUB_CAN_ERANGE);
    CHECK_EQ(icub_can_mc_status_pack(p, 0, 0, 0x04, 0), ICUB_CAN_ERANGE);
    CHECK(p[0] == 0x01); /* nothing written on error */
    p[2] = 0x80;
    CHECK_EQ(icub_can_mc_status_unpack(p, 4, NULL, NULL, NULL, NULL), ICUB_CAN_ERANGE);

    CHECK_EQ(icub_can_skin_pack(p, 0xA001), 2);
    CHECK(p[0] == 0x01 && p[1] == 0xA0);
    CHECK_EQ(icub_can_skin_unpack(p, 2, &tx), ICUB_CAN_OK);
    CHECK_EQ(tx, 0xA001);
    CHECK_EQ(icub_can_skin_unpack(p, 8, &tx), ICUB_CAN_EBADLEN);
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "--must-fail") == 0) {
        CHECK_EQ(icub_can_id(ICUB_CAN_CLASS_STRAIN, 0xD, ICUB_CAN_STRAIN_FORCE), 0x3DB);
    } else {
        test_ids();
        test_offset_binary();
        test_strain_payload();
        test_mc_position();
        test_mc_pid_val();
        test_count_fixed();
#ifndef ICUB_CAN_NO_FLOAT
        test_count_double();
#endif
        test_saturation_frame();
        test_mc_status_and_skin();
    }
    printf("icub_can: %u checks, %u failed\n", g_checks, g_failed);
    return g_failed ? 1 : 0;
}
