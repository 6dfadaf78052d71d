// The robot's bus as a compiled table (docs/formats.md, "rt_monitor configuration"): which frame, by (bus, ID),
// carries which signal at which bits, and how a sample is clocked. `dynid export` compiles it from the robot's
// bus description; the monitor decodes every frame generically from it (no DBC parser, no robot-specific code).
//
// FrameDecoder: the frame of a (bus, ID) in O(1) from a fixed index built at start-up, and a signal's physical
// value (raw · scale + offset) from the payload's bits in either byte order, with no allocation and no exception.
#pragma once

#include <linux/can.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "rt_monitor/capacity.hpp"

namespace dynid::rt {

// What a signal is (its target). Values: q, dq, the outputs (pwm, current, tau, ft) and the skin patches; health:
// saturation and fault flags, the node's restart flag and sequence counter, bits that must be 0; kNone: carried only.
enum class Target : uint8_t {
    kNone, kQ, kDq, kPwm, kCurrent, kTau, kFt, kSkin, kSaturated, kFault, kRestart, kSeq, kReserved
};
enum class SignalType : uint8_t { kUnsigned, kSigned, kFloat };

struct SignalDef {
    int frame = 0;                 // index into BusTable::frames
    int start = 0, length = 1;     // DBC convention: LSB (little-endian) or MSB in sawtooth numbering (big-endian)
    bool big_endian = false;
    SignalType type = SignalType::kUnsigned;
    double scale = 1, offset = 0;
    Target target = Target::kNone;
    std::string name;              // the target's text ("q.r_elbow", "ft.r_arm_ft.fx", "skin.hand", "fault", ...)
    int slot = -1;                 // values: index into BusTable::values; skin: the patch's index
    int shift = 0;                 // where its bits sit in the little- or big-endian word of the payload (FrameDecoder)
    uint64_t mask = 1;
};

// Frames are counted by what they carry (MonitorCounters): the clock pair's halves (or the clock frame), health
// frames (sequence, restart, faults), skin, positions and velocities, other F/T sensors' frames, inputs (the rest).
enum class FrameKind : uint8_t { kClock, kStatus, kSkin, kPosition, kSensor, kInput };

struct FrameDef {
    std::string name, node;
    int bus = 0;
    uint32_t id = 0;
    int dlc = 0, long_dlc = 0;     // long_dlc: the long form's length (its optional signals), 0 none
    int64_t period_us = 0, offset_us = 0;  // the player's: 0 = every sample; send time relative to the sample
    int first_signal = 0, n_signals = 0;   // its signals: signals[first_signal, first_signal + n_signals)
    int node_index = 0;
    FrameKind kind = FrameKind::kInput;
    int pair = -1;                 // index into pairs, or -1
    bool first_half = false;       // the pair's first frame
};

struct PatchDef {
    std::string name;
    std::vector<std::pair<std::string, std::string>> sides;  // (sensor, distal|proximal)
};

struct BusTable {
    std::vector<FrameDef> frames;
    std::vector<SignalDef> signals;  // grouped by frame, each frame's in file order
    std::vector<std::string> values; // value targets (q.*, dq.*, pwm.*, current.*, tau.*, ft.*): a signal's slot
    std::vector<std::string> nodes;
    std::vector<std::pair<int, int>> pairs;  // (first, second) frame indices
    std::vector<PatchDef> patches;
    int clock = -1;                  // the frame that completes a sample
    int clock_pair = -1;             // the pair it closes, or -1
};

// Decodes frames with the table: lookup and bit extraction. init() once (it allocates nothing after).
class FrameDecoder {
public:
    void init(const BusTable& table) noexcept;
    // The frame index of a standard-ID data frame on `bus`, or -1 (extended, remote, error, unknown, no such bus).
    int lookup(int bus, canid_t id) const noexcept {
        if (id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG) || bus < 0 || bus >= kMaxBuses) return -1;
        return index_[size_t(bus) * kIds + (id & CAN_SFF_MASK)] - 1;
    }
    // A payload of `len` bytes (bytes beyond it read as 0) as one word read little-endian and one read big-endian:
    // every signal of the frame is then a shift and a mask of one of them.
    struct Words {
        uint64_t le = 0, be = 0;
    };
    static Words words(const uint8_t* data, int len) noexcept;
    // Fills a signal's shift and mask from its start, length and byte order (the parser does, for every signal).
    static void place(SignalDef& s) noexcept;
    // The raw bits of a signal.
    static uint64_t raw_bits(const SignalDef& s, const Words& w) noexcept;
    static uint64_t raw_bits(const SignalDef& s, const uint8_t* data, int len) noexcept {
        return raw_bits(s, words(data, len));
    }
    // Its physical value: raw (sign-extended, or an IEEE float) · scale + offset.
    static double value(const SignalDef& s, const Words& w) noexcept;
    static double value(const SignalDef& s, const uint8_t* data, int len) noexcept { return value(s, words(data, len)); }

private:
    static constexpr size_t kIds = 2048;  // 11-bit IDs
    std::array<int16_t, size_t(kMaxBuses) * kIds> index_{};  // frame index + 1; 0: none
};

}  // namespace dynid::rt
