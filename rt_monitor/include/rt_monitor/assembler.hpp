// The monitor's configuration file and sample assembly: CAN frames in, one (q, y) sample per strain pair out.
//
// - The strain board's force half (type 0xA) and torque half (0xB) are paired only when the torque half
//   follows the force half within `pair_us` with no other strain frame between: a half is never paired with
//   a half of another sample (docs/design.md §5). The pair's time is the sample's time.
// - Encoder positions and PWMs are held at their latest values; a sample with any of them not renewed for
//   more than `stale_us` (or never received) is stale, and so is one with a saturated strain channel. A sample with an
//   encoder value that did not come after the previous sample is `held`: the monitor bridges it like a lost
//   sample (a held position is a kink the derivative filter would read as an acceleration spike). Whether a
//   value is new is told by order, not by its age: a sender preempted between its frames stamps the position
//   long before the strain pair, and that value is still this sample's (neither held nor stale).
// - Every bad frame has a counter (MonitorCounters); nothing throws, nothing allocates after set-up.
#pragma once

#include <linux/can.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "rt_monitor/coefficients.hpp"
#include "rt_monitor/frame_source.hpp"

namespace dynid::rt {

struct AxisMap {
    int bus = 0, address = 0, slot = 0;
    std::string joint;
    double ticks_per_degree = 1, zero_deg = 0;
};
struct PwmMap {
    int bus = 0, address = 0, slot = 0;
    std::string motor;
    double full_scale = 1;
};

struct MonitorConfig {
    std::string robot;
    std::vector<std::string> buses;
    std::string lcm_url;                 // empty: LCM's default (UDP multicast, ttl=0)
    int64_t stale_us = 5000, pair_us = 500;
    double status_hz = 10;
    int residual_every = 10;             // publish one residual message every N evaluated samples
    int strain_bus = 0, strain_address = 0;
    std::array<double, 6> full_scale{};  // N, N, N, Nm, Nm, Nm
    std::vector<AxisMap> axes;
    std::vector<PwmMap> pwms;
    struct Skin { int bus = 0, address = 0; std::string patch, side; };
    std::vector<Skin> skins;
};

// The configuration's limits (rt_monitor/README.md, "Configuration"): a value outside them is refused, not clamped.
constexpr double kStaleMsMin = 0.1, kStaleMsMax = 1000;  // beyond a second the staleness guard is as good as off
constexpr long long kPairUsMin = 1, kPairUsMax = 10000;  // two halves further apart are not one conversion
constexpr double kStatusHzMin = 0.1, kStatusHzMax = 1000;  // at most one status per 1 kHz sample
constexpr long long kResidualEveryMax = 100000;
constexpr double kFullScaleMax = 1e6;           // strain full scales, N and Nm
constexpr double kTicksPerDegreeMin = 1e-3, kTicksPerDegreeMax = 1e7;
constexpr double kZeroDegMax = 3600;            // |ZERO_DEG|: ten turns
constexpr double kPwmFullScaleMax = 32767;      // PID_VAL carries int16 counts

// The status message's period in CAN time, µs (status_hz within its limits: 1 000 to 10 000 000).
inline int64_t status_period_us(const MonitorConfig& c) noexcept { return int64_t(1e6 / c.status_hz); }

// Parses the configuration (rt_monitor/README.md, "Configuration") from its text; `path` names it in messages.
// False and one line naming the file, the line and the problem on error (line 0: the file as a whole).
bool parse_monitor_config(const std::string& text, const std::string& path, MonitorConfig& out, std::string& error);
// The same, read from the file at `path`.
bool load_monitor_config(const std::string& path, MonitorConfig& out, std::string& error);

// Every frame pushed is counted once in `frames` and once in exactly one of: error_frames, unknown_id, bad_length,
// strain_frames, position_frames, pid_frames, status_frames, skin_frames. Strain halves: strain_frames =
// 2 samples + unpaired_strain + (a force half still waiting for its torque half: pending_strain()).
struct MonitorCounters {
    int64_t frames = 0, samples = 0, stale_samples = 0, unknown_id = 0, bad_length = 0, error_frames = 0,
            unpaired_strain = 0, saturated = 0, board_faults = 0, board_restarts = 0, skin_frames = 0;
    int64_t strain_frames = 0, position_frames = 0, pid_frames = 0, status_frames = 0;  // decoded, by kind
};

struct Sample {
    int64_t t_us = 0;
    std::array<double, kMaxJoints> q{};
    std::array<double, kMaxOutputs> y{};
    bool stale = false;      // an input too old or missing, or a saturated strain channel
    bool held = false;       // an encoder value did not come after the previous sample: it is held, not new
    uint16_t skin_mask = 0;  // patches in contact (bit = index in the configuration's skin list)
};

class Assembler {
public:
    // Maps the coefficient file's joints and channels onto the configuration; false and one line if one is
    // not served by any board.
    bool init(const MonitorConfig& cfg, const Coefficients& coef, std::string& error);
    // One frame in; true when it completed a sample (then `out` holds it).
    bool push(const RxFrame& f, Sample& out) noexcept;
    const MonitorCounters& counters() const noexcept { return n_; }
    // 1 while a force half waits for its torque half (the input ended or stopped between the two), else 0.
    int pending_strain() const noexcept { return t_force_ >= 0 ? 1 : 0; }

private:
    static constexpr int kMaxBus = kMaxBuses;
    enum : int8_t { kNone = 0, kStrain = 1, kMc = 2, kSkin = 3 };
    int board(int bus, unsigned cls, unsigned address) const noexcept;

    const MonitorConfig* cfg_ = nullptr;
    int n_joints_ = 0, n_outputs_ = 0;
    // (bus, class, address) -> index of the board in its list, +1; 0: not configured.
    std::array<int16_t, kMaxBus * 8 * 16> boards_{};
    std::array<int, kMaxJoints> joint_axis_{};  // coefficient joint -> index in cfg.axes
    std::array<int, kMaxOutputs> out_src_{};    // channel -> 0..5 F/T component, or 6 + index in cfg.pwms
    std::vector<double> q_, pwm_;               // latest values, by cfg index
    std::vector<int64_t> t_q_, t_pwm_;          // their times (-1: never)
    std::vector<int> status_seq_;               // last STATUS sequence per motor board address (-1: none)
    std::array<double, 3> force_{};
    int64_t t_force_ = -1;
    int64_t t_strain_ = -1, t_boundary_ = -1;   // the last strain frame; the last one before the current force half
    bool force_saturated_ = false;
    uint16_t skin_mask_ = 0;
    MonitorCounters n_;
};

}  // namespace dynid::rt
