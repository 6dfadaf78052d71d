/*
 * test_bus_encoder.c - plain C99 checks of the generic signal encoder against frames written out by hand: both byte
 * orders (Motorola in the DBC's sawtooth numbering), signs, IEEE floats, scale and offset, cantools' rounding (half
 * to even) and clamping.
 */
#include "bus_encoder.h"

#include "check.h"

#include <string.h>

static bus_signal_t sig(int start, int length, int big_endian, int type, double scale, double offset)
{
    bus_signal_t s;
    s.start = (uint8_t)start;
    s.length = (uint8_t)length;
    s.big_endian = (uint8_t)big_endian;
    s.type = (uint8_t)type;
    s.scale = scale;
    s.offset = offset;
    return s;
}

static void test_little_endian(void)
{
    uint8_t d[8];
    uint8_t c = 9u;
    const bus_signal_t pos = sig(0, 32, 0, BUS_SIGNED, 1e-6, 0.0);  /* µrad */
    const bus_signal_t cur = sig(32, 16, 0, BUS_SIGNED, 1e-3, 0.0); /* mA */
    const bus_signal_t off = sig(0, 16, 0, BUS_UNSIGNED, 200.0 / 32768.0, -200.0); /* the iCub strain's offset binary */
    memset(d, 0, sizeof d);
    bus_signal_pack(d, &pos, bus_signal_raw(&pos, -2e-6, &c));
    CHECK_EQ(c, 0);
    bus_signal_pack(d, &cur, bus_signal_raw(&cur, 1.2345, &c)); /* 1234.5 mA: half to even, 1234 */
    CHECK_BYTES(d, 0xFE, 0xFF, 0xFF, 0xFF, 0xD2, 0x04, 0x00, 0x00);
    CHECK_EQ(bus_signal_unpack(d, &cur), 1234);
    CHECK_EQ(bus_signal_raw(&cur, 1.2355, &c), 1236); /* 1235.5: to even, up */
    CHECK_EQ(bus_signal_raw(&cur, 40.0, &c), 32767);
    CHECK_EQ(c, 1);
    CHECK_EQ(bus_signal_raw(&cur, -40.0, &c), 0x8000); /* -32768, two's complement in 16 bits */
    CHECK_EQ(c, 1);
    CHECK_EQ(bus_signal_raw(&off, 0.0, &c), 0x8000);
    CHECK_EQ(bus_signal_raw(&off, 1.0, &c), 0x80A4); /* 163.84 -> 164 */
    CHECK_EQ(bus_signal_raw(&off, 250.0, &c), 0xFFFF);
    CHECK_EQ(c, 1);
    CHECK_EQ(bus_signal_raw(&off, 0.0 / 0.0, &c), 0); /* NaN: 0, reported */
    CHECK_EQ(c, 1);
    memset(d, 0xFF, sizeof d); /* packing keeps the other bits */
    bus_signal_pack(d, &cur, 0u);
    CHECK_BYTES(d, 0xFF, 0xFF, 0xFF, 0xFF, 0x00, 0x00, 0xFF, 0xFF);
}

static void test_big_endian(void)
{
    uint8_t d[8];
    uint8_t end = 0u;
    const bus_signal_t w = sig(7, 16, 1, BUS_UNSIGNED, 1.0, 0.0);  /* bytes 0-1, MSB first */
    const bus_signal_t n = sig(3, 8, 1, BUS_UNSIGNED, 1.0, 0.0);   /* low nibble of byte 0, high nibble of byte 1 */
    const bus_signal_t x = sig(55, 16, 1, BUS_SIGNED, 0.5, 1.0);   /* bytes 6-7 */
    memset(d, 0, sizeof d);
    bus_signal_pack(d, &w, 0x1234u);
    CHECK_BYTES(d, 0x12, 0x34, 0, 0, 0, 0, 0, 0);
    memset(d, 0, sizeof d);
    bus_signal_pack(d, &n, 0x23u);
    CHECK_BYTES(d, 0x02, 0x30, 0, 0, 0, 0, 0, 0);
    CHECK_EQ(bus_signal_unpack(d, &n), 0x23);
    memset(d, 0, sizeof d);
    bus_signal_pack(d, &x, bus_signal_raw(&x, -3.0, 0)); /* (-3 - 1) / 0.5 = -8 = 0xFFF8 */
    CHECK_BYTES(d, 0, 0, 0, 0, 0, 0, 0xFF, 0xF8);
    CHECK_EQ(bus_signal_check(&x, &end), BUS_OK);
    CHECK_EQ(end, 8);
    CHECK_EQ(bus_signal_check(&n, &end), BUS_OK);
    CHECK_EQ(end, 2);
    {
        const bus_signal_t out = sig(56, 16, 1, BUS_UNSIGNED, 1.0, 0.0); /* would run past byte 7 */
        const bus_signal_t f16 = sig(0, 16, 0, BUS_FLOAT, 1.0, 0.0);
        CHECK_EQ(bus_signal_check(&out, &end), BUS_EINVAL);
        CHECK_EQ(bus_signal_check(&f16, &end), BUS_EINVAL);
    }
}

static void test_floats_and_64_bits(void)
{
    uint8_t d[8];
    const bus_signal_t f = sig(0, 32, 0, BUS_FLOAT, 2.0, 0.5);
    const bus_signal_t g = sig(7, 32, 1, BUS_FLOAT, 1.0, 0.0);
    const bus_signal_t u64 = sig(0, 64, 0, BUS_UNSIGNED, 1.0, 0.0);
    const bus_signal_t s64 = sig(0, 64, 0, BUS_SIGNED, 1.0, 0.0);
    uint8_t c = 0u;
    memset(d, 0, sizeof d);
    bus_signal_pack(d, &f, bus_signal_raw(&f, -2.0, 0)); /* (-2 - 0.5) / 2 = -1.25f = 0xBFA00000 */
    CHECK_BYTES(d, 0x00, 0x00, 0xA0, 0xBF, 0, 0, 0, 0);
    memset(d, 0, sizeof d);
    bus_signal_pack(d, &g, bus_signal_raw(&g, 1.5, 0)); /* 0x3FC00000, big-endian */
    CHECK_BYTES(d, 0x3F, 0xC0, 0x00, 0x00, 0, 0, 0, 0);
    CHECK(bus_signal_raw(&u64, 1e30, &c) > 0xFFFFFFFFFFFFF000ull);
    CHECK_EQ(c, 1);
    CHECK_EQ((int64_t)bus_signal_raw(&s64, -5.0, &c), -5);
    CHECK_EQ(c, 0);
}

int main(void)
{
    test_little_endian();
    test_big_endian();
    test_floats_and_64_bits();
    printf("%u checks, %u failed\n", g_checks, g_failed);
    return g_failed ? 1 : 0;
}
