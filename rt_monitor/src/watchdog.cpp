// The monitor's watchdog (watchdog.hpp): every check works on fixed storage filled at start-up; a raised fault's reason
// is formatted into its own buffer and written to stderr with one write(2).
#include "rt_monitor/watchdog.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>

namespace dynid::rt {
namespace {

constexpr const char* kNames[kFaultKinds] = {"blind", "silent frame", "T² not finite", "sample period",
                                            "joint out of range", "source stopped", "duty out of range",
                                            "model does not fit at start", "samples bridged", "stamps went back",
                                            "contact too long"};

int index_of(Fault f) noexcept {
    int i = 0;
    while (i < kFaultKinds && (1u << i) != uint32_t(f)) ++i;
    return i;
}

}  // namespace

const char* Watchdog::name(int bit) noexcept { return bit >= 0 && bit < kFaultKinds ? kNames[bit] : "?"; }

void Watchdog::init(const MonitorConfig& cfg, const Coefficients& coef, const Assembler& assembler,
                    const WatchdogSettings& settings) noexcept {
    cfg_ = &cfg;
    coef_ = &coef;
    asm_ = &assembler;
    set_ = settings;
    set_.period_samples = std::clamp(set_.period_samples, 3, int(spacing_.size()));
    period_block_ = set_.period_samples;
    blind_us_ = int64_t(set_.blind_periods * coef.sample_period * 1e6);
    fit_samples_ = std::max(kMinFitSamples, int(std::lround(set_.fit_s / coef.sample_period)));
    bridge_block_ = std::max(1, int(std::lround(1.0 / coef.sample_period)));
    contact_limit_ = std::max<int64_t>(1, std::llround(cfg.contact_limit_s / coef.sample_period));
    written_at_.fill(-1);
    unwritten_.fill(0);
    // A sample's frames: those sent every sample (period 0 or one sample period). A pause of the sender mid-sample is
    // not blindness; blind_periods samples' worth of frames with no sample is.
    int per_sample = 0;
    for (const FrameDef& f : cfg.bus.frames) per_sample += f.period_us <= int64_t(coef.sample_period * 1e6);
    blind_frames_ = int64_t(set_.blind_periods * std::max(per_sample, 1));
    for (auto& r : reasons_) r.fill('\0');  // touched here, not in the loop
    spacing_.fill(0);
    for (int i = 0; i < coef.n_outputs; ++i) is_pwm_[size_t(i)] = coef.channel_names[size_t(i)].rfind("pwm.", 0) == 0;
}

char* Watchdog::text(Fault f) noexcept { return reasons_[size_t(index_of(f))].data(); }

const char* Watchdog::reason(Fault f) const noexcept { return reasons_[size_t(index_of(f))].data(); }

void Watchdog::raise(Fault f) noexcept {
    const bool rising = !(active_ & uint32_t(f));
    active_ |= uint32_t(f);
    seen_ |= uint32_t(f);
    if (!rising) return;
    const int k = index_of(f);
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);  // the vDSO's: no system call
    const int64_t now = int64_t(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
    if (written_at_[size_t(k)] >= 0 && now - written_at_[size_t(k)] < 1000000) {
        ++unwritten_[size_t(k)];  // its rises within a second of its last line: counted on the next
        return;
    }
    char more[64] = "";
    if (unwritten_[size_t(k)] > 0)
        std::snprintf(more, sizeof more, " (and %lld rises since its last line)", (long long)unwritten_[size_t(k)]);
    written_at_[size_t(k)] = now;
    unwritten_[size_t(k)] = 0;
    char line[384];
    const int n = std::snprintf(line, sizeof line, "rt_monitor: fault: %s: %s%s\n", kNames[k], text(f), more);
    if (n > 0) {
        const ssize_t w = ::write(2, line, size_t(std::min(n, int(sizeof line) - 1)));
        (void)w;  // stderr closed: the status message still carries the fault
    }
}

void Watchdog::placed(bool interpolated, bool restart) noexcept {
    if (restart) {  // the detector restarts with the filter: a contact held is cut, its count over
        contact_samples_ = 0;
        clear(kLongContact);
    }
    bridged_ += interpolated;
    restarts_ += restart;
    if (++placed_ < bridge_block_) return;
    const double share = double(bridged_) / double(placed_);
    if (share > set_.bridged_share) {
        std::snprintf(text(kBridged), 256, "%.0f %% of the last %d samples bridged by interpolation (lost, or held "
                      "by a frame that did not come): a frame at another rate than the bus's, or frames dropped?",
                      100.0 * share, placed_);
        raise(kBridged);
    } else if (restarts_ >= set_.restarts_per_s) {
        std::snprintf(text(kBridged), 256, "the filter restarted %d times in the last %d samples (gaps too long to "
                      "bridge): a frame at a fraction of the bus's rate, or frames dropped?", restarts_, placed_);
        raise(kBridged);
    } else {
        clear(kBridged);
    }
    placed_ = bridged_ = restarts_ = 0;
}

void Watchdog::sample(const Sample& s) noexcept {
    if (s.stale) last_stale_slot_ = s.stale_slot;
    else if (!s.held) {  // fresh: one the sample clock may still hold (a late sender) is not blindness
        last_good_ = s.t_us;
        waiting_since_ = -1;
    }
    // The spacing's median over each block of period_samples samples (a lost sample's double spacing does not move it)
    if (last_sample_t_ >= 0) spacing_[size_t(n_spacing_++)] = s.t_us - last_sample_t_;
    if (n_spacing_ == period_block_) {
        std::nth_element(spacing_.begin(), spacing_.begin() + n_spacing_ / 2, spacing_.begin() + n_spacing_);
        const double median = double(spacing_[size_t(n_spacing_ / 2)]), want = coef_->sample_period * 1e6;
        n_spacing_ = 0;
        period_block_ = std::clamp(bridge_block_, set_.period_samples, int(spacing_.size()));
        if (std::abs(median / want - 1.0) > set_.period_tolerance) {
            std::snprintf(text(kPeriod), 256, "the samples come %.0f µs apart, the coefficient file's period is "
                          "%.0f µs: its filter and thresholds are for another rate (export with the robot's rate)",
                          median, want);
            raise(kPeriod);
        } else {
            clear(kPeriod);
        }
    }
    if (last_sample_t_ >= 0 && s.t_us <= last_sample_t_) {  // the sample clock restarts the filter at an equal stamp too
        if (s.t_us == last_sample_t_)
            std::snprintf(text(kTimeBack), 256, "a sample stamped the same µs as the one before it (a duplicate, a "
                          "sender's clock stuck?): the filter restarts there");
        else
            std::snprintf(text(kTimeBack), 256, "a sample stamped %.1f ms before the one before it (a sender's clock "
                          "reset, a log spliced?): the filter restarts there", double(last_sample_t_ - s.t_us) * 1e-3);
        raise(kTimeBack);
        in_order_ = 0;
    } else if (in_order_ < bridge_block_ && ++in_order_ == bridge_block_) {  // bounded: a monitor runs for months
        clear(kTimeBack);
    }
    last_sample_t_ = s.t_us;
    // A duty cycle beyond ±1, for consecutive samples: the PWM's scale or offset is wrong
    int duty = -1;
    for (int i = 0; i < coef_->n_outputs && duty < 0; ++i)
        if (is_pwm_[size_t(i)] && std::abs(s.y[size_t(i)]) > 1.0 + set_.duty_margin) duty = i;
    if (duty < 0) {
        duty_out_ = 0;
        clear(kDutyRange);
    } else if (++duty_out_ == set_.range_samples) {
        std::snprintf(text(kDutyRange), 256, "%.80s at %.4g, beyond ±1 duty: a wrong PWM scale or offset in the "
                      "configuration?", coef_->channel_names[size_t(duty)].c_str(), s.y[size_t(duty)]);
        raise(kDutyRange);
    }
    // A position beyond its joint's range by the margin, for consecutive samples: the encoder's scale or zero is wrong
    const int nj = coef_->n_joints;
    int out = -1;
    for (int j = 0; j < nj && out < 0; ++j)
        if (s.q[size_t(j)] < coef_->joint_lower[size_t(j)] - set_.range_margin ||
            s.q[size_t(j)] > coef_->joint_upper[size_t(j)] + set_.range_margin)
            out = j;
    if (out < 0) {
        out_of_range_ = 0;
        clear(kJointRange);
        return;
    }
    if (++out_of_range_ == set_.range_samples) {
        std::snprintf(text(kJointRange), 256, "%.80s at %.4g, outside its range [%.4g, %.4g] by more than %.3g: a wrong "
                      "encoder scale or zero in the configuration?", coef_->joint_names[size_t(out)].c_str(),
                      s.q[size_t(out)], coef_->joint_lower[size_t(out)], coef_->joint_upper[size_t(out)], set_.range_margin);
        raise(kJointRange);
    }
}

void Watchdog::evaluated(const Output& o, int64_t t_us) noexcept {
    last_evaluated_ = t_us;
    waiting_since_ = -1;
    clear(kBlind);
    const MonitorCounters& c = asm_->counters();
    unpaired_at_eval_ = c.unpaired_strain;
    samples_at_eval_ = c.samples;
    if (!o.ready) return;
    contact_samples_ = o.in_contact ? contact_samples_ + 1 : 0;
    if (contact_samples_ == contact_limit_) {
        std::snprintf(text(kLongContact), 256, "a contact held for %.1f s (contact_limit_s): more likely the model no "
                      "longer fitting (an encoder offset, a sensor's step, a load it lacks) than a touch; no new contact "
                      "makes an event until it ends", double(contact_limit_) * coef_->sample_period);
        raise(kLongContact);
    } else if (contact_samples_ == 0) {
        clear(kLongContact);
    }
    if (fit_evaluated_ < fit_samples_) {
        fit_above_ += o.above;
        if (++fit_evaluated_ == fit_samples_ && 4 * fit_above_ > 3 * fit_evaluated_) {
            std::snprintf(text(kStartFit), 256, "T² above T²_α on %d of the first %d samples (α allows %.2g %%): the "
                          "model or the configuration does not fit this robot (or it was touched all through the start)",
                          fit_above_, fit_evaluated_, 100 * (1 - coef_->alpha));
            raise(kStartFit);
        }
    }
    if (!std::isfinite(o.p.t2)) {
        int worst = -1;
        for (int i = 0; i < coef_->n_outputs && worst < 0; ++i)
            if (!std::isfinite(o.p.e[i])) worst = i;
        std::snprintf(text(kNotFinite), 256, "T² is %g%s%.80s: the model or a scale overflows", o.p.t2,
                      worst >= 0 ? ", first on channel " : "", worst >= 0 ? coef_->channel_names[size_t(worst)].c_str() : "");
        raise(kNotFinite);
    } else {
        clear(kNotFinite);
    }
}

void Watchdog::blind_reason(int64_t now_us) noexcept {
    const MonitorCounters& c = asm_->counters();
    const BusTable& b = cfg_->bus;
    char* r = text(kBlind);
    const double ms = double(now_us - std::max({last_evaluated_, last_good_, first_frame_})) / 1e3;
    const int64_t clock_seen = b.clock >= 0 ? asm_->last_seen(b.clock) : -1;
    if (b.clock >= 0 && (clock_seen < 0 || clock_seen <= std::max(last_evaluated_, last_good_))) {
        const FrameDef& f = b.frames[size_t(b.clock)];
        std::snprintf(r, 256, "no sample evaluated for %.1f ms: no clock frame %.60s (0x%X on %.16s)", ms, f.name.c_str(),
                      unsigned(f.id), cfg_->buses[size_t(f.bus)].c_str());
    } else if (c.unpaired_strain > unpaired_at_eval_ && asm_->last_pair_gap() >= 0) {
        std::snprintf(r, 256, "no sample evaluated for %.1f ms: the clock pair's halves are not paired (pair_us %lld µs; "
                      "the last pair refused came %lld µs apart)", ms, (long long)cfg_->pair_us,
                      (long long)asm_->last_pair_gap());
    } else if (c.unpaired_strain > unpaired_at_eval_) {
        std::snprintf(r, 256, "no sample evaluated for %.1f ms: the clock pair's halves are not paired (a first half came "
                      "again before its second: duplicated frames?)", ms);
    } else if (c.samples > samples_at_eval_ && last_stale_slot_ >= 0) {
        std::snprintf(r, 256, "no sample evaluated for %.1f ms: every sample is stale (%.80s not renewed within %lld µs, "
                      "or saturated)", ms, b.values[size_t(last_stale_slot_)].c_str(), (long long)cfg_->stale_us);
    } else {
        std::snprintf(r, 256, "no sample evaluated for %.1f ms while frames arrive (samples held or bridged)", ms);
    }
}

uint32_t Watchdog::check(int64_t now_us) noexcept {
    if (first_frame_ < 0) return active_;
    if (waiting_since_ >= 0 && frames_waiting_ > blind_frames_ && now_us - waiting_since_ > blind_us_) {
        if (!(active_ & kBlind)) {
            blind_reason(now_us);
            raise(kBlind);
        }
    }
    return active_;
}

uint32_t Watchdog::check_bus(int64_t now_us) noexcept {
    // Frames of the bus that never came within the first second, or stopped for a second.
    if (first_frame_ >= 0 && now_us - first_frame_ > set_.silent_us) {
        const BusTable& b = cfg_->bus;
        int silent = -1, count = 0;
        for (int f = 0; f < int(b.frames.size()); ++f) {
            const int64_t seen = asm_->last_seen(f);
            if (seen < 0 || now_us - seen > set_.silent_us) {
                if (silent < 0) silent = f;
                ++count;
            }
        }
        if (silent >= 0) {
            const FrameDef& f = b.frames[size_t(silent)];
            const int64_t seen = asm_->last_seen(silent);
            if (!(active_ & kSilent)) {
                std::snprintf(text(kSilent), 256, "frame %.60s (0x%X on %.16s) %s%s", f.name.c_str(), unsigned(f.id),
                              cfg_->buses[size_t(f.bus)].c_str(),
                              seen < 0 ? "never came within a second of the first frame" : "stopped for a second",
                              count > 1 ? " (and others of the bus)" : "");
                raise(kSilent);
            }
        } else {
            clear(kSilent);
        }
    }
    return active_;
}

void Watchdog::idle(int64_t idle_us) noexcept {
    if (first_frame_ < 0 || idle_us < set_.silent_us) {
        if (idle_us < set_.silent_us) clear(kStopped);
        return;
    }
    if (!(active_ & kStopped)) {
        std::snprintf(text(kStopped), 256, "no frame for %.1f s (every board silent, or the bus down)", double(idle_us) / 1e6);
        raise(kStopped);
    }
}

}  // namespace dynid::rt
