/* bus_encoder.c - physical values into CAN frame bits, for any layout of a bus description (bus_encoder.h). */
#include "bus_encoder.h"

#include <math.h>
#include <string.h>

/* The payload bits of a signal, from its most significant (i = length - 1) down: little-endian from start + length
 * - 1 down; Motorola from `start`, down within a byte, then bit 7 of the next byte. */
static int next_down(const bus_signal_t *s, int pos)
{
    if (!s->big_endian) {
        return pos - 1;
    }
    return (pos % 8) ? pos - 1 : pos + 15;
}

static int msb_pos(const bus_signal_t *s)
{
    return s->big_endian ? (int)s->start : (int)s->start + (int)s->length - 1;
}

int bus_signal_check(const bus_signal_t *s, uint8_t *end_byte)
{
    int i, b;
    int last = 0;
    if (s->length == 0u || s->length > 64u || s->start > 63u) {
        return BUS_EINVAL;
    }
    if (s->type == BUS_FLOAT && s->length != 32u && s->length != 64u) {
        return BUS_EINVAL;
    }
    for (i = (int)s->length - 1, b = msb_pos(s); i >= 0; --i, b = next_down(s, b)) {
        if (b < 0 || b > 63) {
            return BUS_EINVAL;
        }
        last = b > last ? b : last;
    }
    if (end_byte) {
        *end_byte = (uint8_t)(last / 8 + 1);
    }
    return BUS_OK;
}

uint64_t bus_signal_raw(const bus_signal_t *s, double value, uint8_t *clamped)
{
    const double x = (value - s->offset) / s->scale;
    double r, lo, hi;
    uint8_t c = 0u;
    uint64_t raw;
    if (s->type == BUS_FLOAT) {
        if (s->length == 32u) {
            const float f = (float)x;
            uint32_t b32;
            memcpy(&b32, &f, sizeof b32);
            raw = b32;
        } else {
            memcpy(&raw, &x, sizeof raw);
        }
        if (clamped) {
            *clamped = 0u;
        }
        return raw;
    }
    /* The range as doubles; at 64 bits, the largest doubles below 2^64 and 2^63 (the conversions stay defined). */
    if (s->type == BUS_SIGNED) {
        lo = -ldexp(1.0, s->length - 1);
        hi = s->length == 64u ? 9223372036854774784.0 : ldexp(1.0, s->length - 1) - 1.0;
    } else {
        lo = 0.0;
        hi = s->length == 64u ? 18446744073709549568.0 : ldexp(1.0, s->length) - 1.0;
    }
    r = rint(x); /* half to even in the default rounding mode, as Python's round() */
    if (r != r) {
        r = 0.0;
        c = 1u;
    } else if (r < lo) {
        r = lo;
        c = 1u;
    } else if (r > hi) {
        r = hi;
        c = 1u;
    }
    if (clamped) {
        *clamped = c;
    }
    if (s->type == BUS_SIGNED) {
        raw = (uint64_t)(int64_t)r;
        if (s->length < 64u) {
            raw &= ((uint64_t)1 << s->length) - 1u;
        }
        return raw;
    }
    return (uint64_t)r;
}

void bus_signal_pack(uint8_t data[8], const bus_signal_t *s, uint64_t raw)
{
    int i, b;
    for (i = (int)s->length - 1, b = msb_pos(s); i >= 0; --i, b = next_down(s, b)) {
        const uint8_t mask = (uint8_t)(1u << (b % 8));
        if ((raw >> i) & 1u) {
            data[b / 8] = (uint8_t)(data[b / 8] | mask);
        } else {
            data[b / 8] = (uint8_t)(data[b / 8] & (uint8_t)~mask);
        }
    }
}

uint64_t bus_signal_unpack(const uint8_t data[8], const bus_signal_t *s)
{
    uint64_t raw = 0u;
    int i, b;
    for (i = (int)s->length - 1, b = msb_pos(s); i >= 0; --i, b = next_down(s, b)) {
        raw |= (uint64_t)((data[b / 8] >> (b % 8)) & 1u) << i;
    }
    return raw;
}
