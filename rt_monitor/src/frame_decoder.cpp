// The compiled bus table's decoder (bus_table.hpp): O(1) frame lookup, bit extraction in both byte orders.
#include <cstring>

#include "rt_monitor/bus_table.hpp"

namespace dynid::rt {

void FrameDecoder::init(const BusTable& table) noexcept {
    index_.fill(0);
    for (size_t i = 0; i < table.frames.size(); ++i) {
        const FrameDef& f = table.frames[i];
        index_[size_t(f.bus) * kIds + (f.id & CAN_SFF_MASK)] = int16_t(i + 1);
    }
}

FrameDecoder::Words FrameDecoder::words(const uint8_t* data, int len) noexcept {
    uint8_t b[8] = {};
    std::memcpy(b, data, size_t(len < 0 ? 0 : len > 8 ? 8 : len));
    Words w;
    for (int i = 0; i < 8; ++i) {
        w.le |= uint64_t(b[i]) << (8 * i);
        w.be = w.be << 8 | b[i];
    }
    return w;
}

void FrameDecoder::place(SignalDef& s) noexcept {
    s.mask = s.length >= 64 ? ~uint64_t(0) : (uint64_t(1) << s.length) - 1;
    // Motorola: `start` is the most significant bit in the DBC's sawtooth numbering (bit 7 of byte 0 is 7). In the
    // payload read as one big-endian word, MSB first from bit 0, it is bit 8·(start / 8) + 7 − start % 8.
    const int msb = 8 * (s.start / 8) + 7 - s.start % 8;
    s.shift = s.big_endian ? 64 - msb - s.length : s.start;  // the parser keeps the signal inside: 0 <= shift
}

uint64_t FrameDecoder::raw_bits(const SignalDef& s, const Words& w) noexcept {
    return ((s.big_endian ? w.be : w.le) >> s.shift) & s.mask;
}

double FrameDecoder::value(const SignalDef& s, const Words& w) noexcept {
    const uint64_t raw = raw_bits(s, w);
    double v = 0;
    if (s.type == SignalType::kFloat) {
        if (s.length == 32) {
            const uint32_t r32 = uint32_t(raw);
            float x;
            std::memcpy(&x, &r32, sizeof x);
            v = double(x);
        } else {
            std::memcpy(&v, &raw, sizeof v);
        }
    } else if (s.type == SignalType::kSigned && s.length < 64 && (raw >> (s.length - 1)) & 1) {
        v = double(int64_t(raw | ~((uint64_t(1) << s.length) - 1)));  // sign-extended
    } else if (s.type == SignalType::kSigned) {
        v = double(int64_t(raw));
    } else {
        v = double(raw);
    }
    return v * s.scale + s.offset;
}

}  // namespace dynid::rt
