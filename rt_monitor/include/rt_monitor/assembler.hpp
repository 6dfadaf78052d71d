// Sample assembly: CAN frames in, decoded with the compiled bus table (bus_table.hpp), one (q, y) sample per clock
// frame out. Generic over robots: what a frame carries is the table's, nothing here knows a protocol.
//
// - A pair's halves (the iCub strain board's force 0xA and torque 0xB) are committed together, only when the second
//   follows the first within `pair_us` with no other first half between: a half is never paired with a half of
//   another sample (docs/design.md §5). The clock frame (the clock pair's second half) completes a sample; its time
//   is the sample's. Another pair's values are its latest complete pair (an iCub leg's second F/T sensor).
// - Every other value is held at its latest; a sample with any of them not renewed for more than `stale_us` (or
//   never received) is stale, and so is one with a saturated value. A sample with a position that did not come after
//   the previous sample is `held`: the monitor bridges it like a lost sample (a held position is a kink the
//   derivative filter would read as an acceleration spike). Whether a value is new is told by order, not by its age:
//   a sender preempted between its frames stamps the position long before the clock frame, and that value is still
//   this sample's (neither held nor stale).
// - A node's restart (its restart flag, or its sequence counter back to 0 when not due to wrap) drops that node's
//   values until fresh ones come.
// - Every bad frame has a counter (MonitorCounters); nothing throws, nothing allocates after init().
#pragma once

#include <linux/can.h>

#include <array>
#include <cstdint>
#include <string>

#include "rt_monitor/bus_table.hpp"
#include "rt_monitor/coefficients.hpp"
#include "rt_monitor/frame_source.hpp"
#include "rt_monitor/monitor_config.hpp"

namespace dynid::rt {

// Every frame pushed is counted once in `frames` and once in exactly one of: error_frames, unknown_id, bad_length
// (a wrong length, reserved bits set or a non-finite float), strain_frames (the clock pair's halves, or the clock
// frame), position_frames, pid_frames (inputs), status_frames (health), skin_frames, sensor_frames (other pairs and
// F/T frames). Clock halves: strain_frames = 2 samples + unpaired_strain + pending_strain() (a single clock frame:
// strain_frames = samples).
struct MonitorCounters {
    int64_t frames = 0, samples = 0, stale_samples = 0, unknown_id = 0, bad_length = 0, error_frames = 0,
            unpaired_strain = 0, saturated = 0, board_faults = 0, board_restarts = 0, skin_frames = 0;
    int64_t strain_frames = 0, position_frames = 0, pid_frames = 0, status_frames = 0;  // decoded, by kind
    int64_t sensor_frames = 0, unpaired_sensor = 0;  // the other pairs' frames, and their halves never paired
};

struct Sample {
    int64_t t_us = 0;
    std::array<double, kMaxJoints> q{};
    std::array<double, kMaxOutputs> y{};
    std::array<double, kMaxJoints> dq{};  // the measured q̇, where the bus carries every joint's (has_dq)
    bool has_dq = false;
    bool stale = false;      // an input too old or missing, or a saturated value
    int stale_slot = -1;     // the first stale value (index into the bus table's values), for the watchdog's reason
    bool held = false;       // a position did not come after the previous sample: it is held, not new
    uint16_t skin_mask = 0;  // patches in contact (bit = index in the configuration's patch list)
};

class Assembler {
public:
    // Maps the coefficient file's joints (q, and dq where every joint has one) and channels (ft.S.C, pwm.M,
    // current.M, tau.J, by name) onto the table's values; false and one line if one is carried by no signal.
    bool init(const MonitorConfig& cfg, const Coefficients& coef, std::string& error);
    // One frame in; true when it completed a sample (then `out` holds it).
    bool push(const RxFrame& f, Sample& out) noexcept;
    const MonitorCounters& counters() const noexcept { return n_; }
    // 1 while the clock pair's first half waits for its second (the input ended or stopped between the two), else 0.
    int pending_strain() const noexcept { return cfg_ && cfg_->bus.clock_pair >= 0 && t_first_[size_t(cfg_->bus.clock_pair)] >= 0; }
    // When frame `frame` of the table last came with its length (µs, the source's stamps; -1: never): the watchdog's.
    int64_t last_seen(int frame) const noexcept { return last_seen_[size_t(frame)]; }
    // The time between the last pair refused for coming apart and its first half (µs; -1: none refused yet).
    int64_t last_pair_gap() const noexcept { return last_pair_gap_; }

private:
    struct Slot {
        double value = 0;
        int64_t t = -1;  // -1: never, or dropped by a restart
        bool saturated = false;
    };
    void commit(int frame, const double* v, int64_t t, bool saturated) noexcept;
    void restart(int node) noexcept;
    bool close(int64_t t, Sample& out) noexcept;

    const MonitorConfig* cfg_ = nullptr;
    FrameDecoder decoder_;
    int n_joints_ = 0, n_outputs_ = 0;
    bool has_dq_ = false;
    std::array<int, kMaxJoints> q_slot_{}, dq_slot_{};
    std::array<int, kMaxOutputs> y_slot_{};
    std::array<Slot, kMaxSignals> slots_{};
    std::array<int, kMaxSignals> node_slots_{};      // the value slots of each node, grouped by node
    std::array<int, kMaxFrames + 1> node_first_{};   // node k's slots: node_slots_[node_first_[k], node_first_[k + 1])
    std::array<int64_t, kMaxFrames> last_seq_{};         // per frame: the last sequence counter (-1: none yet)
    // Pairs: the first half's decoded values (by its signals' order), its time (-1: none waiting), saturation.
    std::array<std::array<double, 64>, kMaxFrames / 2> first_values_{};
    std::array<int64_t, kMaxFrames / 2> t_first_{};
    std::array<bool, kMaxFrames / 2> first_saturated_{};
    std::array<double, kMaxSignals> scratch_{};
    std::array<int64_t, kMaxFrames> last_seen_{};
    int64_t last_pair_gap_ = -1;
    int64_t t_clock_ = -1, t_boundary_ = -1;  // the last clock frame; the last one before the current sample opened
    uint16_t skin_mask_ = 0;
    MonitorCounters n_;
};

}  // namespace dynid::rt
