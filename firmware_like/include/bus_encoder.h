/*
 * bus_encoder.h - the generic CAN signal encoder: a physical value into a frame's bits, for any layout a robot's bus
 * description gives (docs/formats.md, "Bus description"): start bit and length as a DBC has them (little-endian:
 * the least significant bit; big-endian, Motorola: the most significant bit in the DBC's sawtooth numbering),
 * unsigned, signed or IEEE float, physical = raw * scale + offset.
 *
 * Rounding is cantools' (dynid's Python writer): raw = rint((value - offset) / scale), half to even, clamped to the
 * signal's range with a report. Firmware style: C99, no heap, the caller's 8-byte payload.
 */
#ifndef BUS_ENCODER_H
#define BUS_ENCODER_H

#include <stdint.h>

#define BUS_UNSIGNED 0u
#define BUS_SIGNED   1u
#define BUS_FLOAT    2u

#define BUS_OK       0
#define BUS_EINVAL (-1) /* a layout outside 8 bytes, a length of 0 or above 64, a float not 32 or 64 bits */

typedef struct {
    uint8_t start;      /* DBC start bit */
    uint8_t length;     /* 1..64 */
    uint8_t big_endian; /* 1: Motorola */
    uint8_t type;       /* BUS_UNSIGNED, BUS_SIGNED, BUS_FLOAT */
    double scale;       /* != 0 */
    double offset;
} bus_signal_t;

/* 0 if the layout fits an 8-byte payload, else BUS_EINVAL; *end_byte: 1 + the last byte it touches. */
int bus_signal_check(const bus_signal_t *s, uint8_t *end_byte);
/* The raw bits of a physical value: rint((value - offset) / scale) clamped to the signal's range (*clamped = 1 if it
 * was; NaN is clamped to 0), two's complement for signed signals; floats as their IEEE bits. */
uint64_t bus_signal_raw(const bus_signal_t *s, double value, uint8_t *clamped);
/* Write raw bits into the payload (the signal's bits only; the others are kept). */
void bus_signal_pack(uint8_t data[8], const bus_signal_t *s, uint64_t raw);
/* Read them back (the decoder's rule; bytes are all 8 of data). */
uint64_t bus_signal_unpack(const uint8_t data[8], const bus_signal_t *s);

#endif /* BUS_ENCODER_H */
