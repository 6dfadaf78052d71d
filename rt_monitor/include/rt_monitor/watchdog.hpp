// The monitor's watchdog: a safety monitor never runs blind in silence. It watches what comes in and what the core
// makes of it, and raises a fault, with the reason it can tell, when:
//   kBlind      frames arrive for `blind_us` (a few sample periods), more than that many samples' frames, and no
//               sample has been evaluated nor a fresh one assembled (one the sample clock holds for a late sender is not blindness): unpaired
//               halves (pair_us below their spacing), no clock frame, every sample stale (which value), all held;
//   kSilent     a frame of the robot's bus never came within a second of the first frame, or stopped for a second;
//   kNotFinite  T² is not a number (a model or a scale that overflows);
//   kPeriod     the stream's sample spacing is not the coefficient file's sample period (±5 %);
//   kJointRange a decoded joint position left its range by `range_margin` (a wrong encoder scale or zero);
//   kStopped    a live source delivered nothing for a second after frames flowed;
//   kDutyRange  a PWM channel's duty beyond ±1 by `duty_margin` (a wrong PWM scale or offset);
//   kStartFit   T² above T²_α on more than three quarters of the first `fit_s` seconds' evaluated samples: the model or the
//               configuration does not fit this robot (or it was touched all through the start);
//   kBridged    more than `bridged_share` of a second's samples bridged by interpolation (lost, or held by a frame
//               that did not come), or the filter restarted `restarts_per_s` times in it (gaps too long to bridge):
//               a frame at another rate than the bus's, or a bus dropping frames; the core then sees invented
//               samples, or is reset every few. Cleared by a second under both;
//   kTimeBack   a sample stamped at or before the one before it (a sender's clock reset, a log spliced, a duplicate):
//               the sample clock restarts the filter there, which only the filter_restarts counter said. Cleared by
//               a second of samples in order;
//   kLongContact a contact held for the configuration's contact_limit_s (10 s by default): more likely the model no
//               longer fitting than a touch (an encoder offset, a sensor's step, a load the model lacks; the start-fit
//               check sees only the start), and while it holds a new contact makes no event. Cleared when it ends.
// The period is checked on the first `period_samples` samples (a wrong file is said at once), then on every second of
// samples, not the start alone: a stream whose rate changes mid-run (a board reconfigured) is a fault from its next
// second, cleared by a second at the file's period (a second's median: a logger's jitter moves 64 samples' by 5 %).
// Faults are a bitmask on the status message (`faults`, and `faults_seen` since the start) and on each contact event;
// each rise is one line on stderr with its reason, from a buffer sized at start-up (no allocation in the loop), at most
// one a second of wall time per fault (a flapping fault's rises in between are counted on its next line: a blocked
// stderr must not stall the loop).
// Nothing here decides a contact: a fault is never an event.
#pragma once

#include <array>
#include <cstdint>

#include "rt_monitor/assembler.hpp"
#include "rt_monitor/coefficients.hpp"
#include "rt_monitor/core.hpp"
#include "rt_monitor/monitor_config.hpp"

namespace dynid::rt {

enum Fault : uint32_t {
    kBlind = 1u << 0,
    kSilent = 1u << 1,
    kNotFinite = 1u << 2,
    kPeriod = 1u << 3,
    kJointRange = 1u << 4,
    kStopped = 1u << 5,
    kDutyRange = 1u << 6,
    kStartFit = 1u << 7,
    kBridged = 1u << 8,
    kTimeBack = 1u << 9,
    kLongContact = 1u << 10,
};
constexpr int kFaultKinds = 11;

struct WatchdogSettings {
    double blind_periods = 5;      // sample periods without an evaluated sample while frames arrive
    int64_t silent_us = 1000000;   // a frame unseen this long (from the first frame) is silent
    // relative: the stream's median sample spacing against the file's period. A bus keeps its rate to a fraction of a
    // percent; 20 % let stamps 1.15 times apart through, 15 % of the samples invented (a walkthrough on TIAGo)
    double period_tolerance = 0.05;
    int period_samples = 64;       // samples the spacing is first measured on; then a second's (at most 1024)
    double range_margin = 0.2;     // rad (or m) beyond a joint's range before a position is implausible
    int range_samples = 10;        // consecutive samples out of range before the fault
    double duty_margin = 0.05;     // beyond ±1 duty
    double fit_s = 4.0;            // the start-up block (s of samples at the file's period) whose T² is checked
                                   // against T²_α: a time, so a slow bus is not blind for longer (400 at 100 Hz)
    double bridged_share = 0.05;   // of a second's samples bridged: above, kBridged (a 1 % loss bridges 1 %)
    int restarts_per_s = 3;        // filter restarts in a second: at this many, kBridged
};

class Watchdog {
public:
    // Sized and filled once, at start-up (it keeps references: all three must outlive it).
    void init(const MonitorConfig& cfg, const Coefficients& coef, const Assembler& assembler,
              const WatchdogSettings& settings = {}) noexcept;
    // A frame was read (CAN time µs).
    void frame(int64_t t_us) noexcept {
        first_frame_ = first_frame_ < 0 ? t_us : first_frame_;
        if (waiting_since_ < 0) waiting_since_ = t_us, frames_waiting_ = 0;
        ++frames_waiting_;
    }
    // A sample was assembled (evaluated or not).
    void sample(const Sample& s) noexcept;
    // The core evaluated a sample at CAN time t_us.
    void evaluated(const Output& o, int64_t t_us) noexcept;
    // The sample clock placed a sample on its grid, bridged (interpolated) or not, the filter restarted before it or not.
    void placed(bool interpolated, bool restart) noexcept;
    // The blind check at CAN time now_us (after every frame: cheap); the faults active. Newly raised ones are written
    // to stderr.
    uint32_t check(int64_t now_us) noexcept;
    // The bus's frames, silent or stopped (every frame of the table: at the status rate).
    uint32_t check_bus(int64_t now_us) noexcept;
    // A live source has been silent for `idle_us` of wall time after frames flowed.
    void idle(int64_t idle_us) noexcept;
    uint32_t active() const noexcept { return active_; }
    uint32_t seen() const noexcept { return seen_; }
    // The reason of a fault (its last raise), "" if it never rose.
    const char* reason(Fault f) const noexcept;
    // The name of fault bit `bit` (0 ≤ bit < kFaultKinds), as its stderr line and the README's table give it.
    static const char* name(int bit) noexcept;

private:
    void raise(Fault f) noexcept;
    void clear(Fault f) noexcept { active_ &= ~uint32_t(f); }
    char* text(Fault f) noexcept;
    void blind_reason(int64_t now_us) noexcept;

    const MonitorConfig* cfg_ = nullptr;
    const Coefficients* coef_ = nullptr;
    const Assembler* asm_ = nullptr;
    WatchdogSettings set_;
    int64_t blind_us_ = 0;
    uint32_t active_ = 0, seen_ = 0;
    int64_t first_frame_ = -1, last_evaluated_ = -1, last_good_ = -1;
    // The first frame since the last evaluated (or fresh) sample: blindness is frames arriving for blind_us with no
    // sample, not a pause of the sender (its next frames complete a sample at once)
    int64_t waiting_since_ = -1;
    int64_t frames_waiting_ = 0, blind_frames_ = 0;  // frames since then; blind_periods samples' worth of the bus's
    int64_t unpaired_at_eval_ = 0, samples_at_eval_ = 0;
    int last_stale_slot_ = -1;
    // the stream's sample spacing: the first stamps' differences
    std::array<int64_t, 1024> spacing_{};
    int n_spacing_ = 0, period_block_ = 64;  // the block the spacing's median is taken on: the first, then a second's
    int64_t last_sample_t_ = -1;
    // Each fault's last stderr line, in CLOCK_MONOTONIC µs (−1: none yet; wall time, not CAN time, which may stand
    // still or jump), and its rises since then, not written
    std::array<int64_t, kFaultKinds> written_at_{};
    std::array<int64_t, kFaultKinds> unwritten_{};
    int64_t contact_samples_ = 0, contact_limit_ = 10000;  // evaluated samples in the contact; the limit in samples
    int out_of_range_ = 0;
    std::array<bool, kMaxOutputs> is_pwm_{};
    int duty_out_ = 0;
    // At least this many samples however fast the file: three quarters of them above T²_α is not chance at any α
    static constexpr int kMinFitSamples = 100;
    int fit_samples_ = 4000, fit_evaluated_ = 0, fit_above_ = 0;
    int bridge_block_ = 1000, placed_ = 0, bridged_ = 0, restarts_ = 0;  // a second of samples at the file's period
    int in_order_ = 0;  // samples in stamp order since the last one stamped before its predecessor
    std::array<std::array<char, 256>, kFaultKinds> reasons_{};
};

}  // namespace dynid::rt
