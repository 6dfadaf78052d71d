// The monitor's sample clock (sample_clock.hpp).
#include "rt_monitor/sample_clock.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace dynid::rt {

namespace {
// A stamp up to a quarter period before its slot still counts in it (the origin lags a faster board clock by
// less than that); one up to 0.75 period after it is in it too, beyond that it reads as the next slot.
constexpr double kEarly = 0.25;
// The origin leaks later by 1/512 of a sample's lateness when that is under P/4 (a sample later than that was
// delayed, not a sign of drift): a board clock 100 ppm slow (0.1 µs per sample) is followed with a steady lag of
// ~50 µs, and no burst of late samples moves it.
constexpr double kLeak = 1.0 / 512.0, kLeakBelow = 0.25;
}  // namespace

int64_t SampleClock::slot(int64_t t_us) const noexcept {
    return int64_t(std::floor((double(t_us - base_t_) - offset_) / period_ + kEarly));
}

void SampleClock::anchor(int64_t t_us) noexcept {
    anchored_ = true;
    base_t_ = t_us;
    offset_ = 0;
    last_idx_ = -1;
    have_good_ = false;
    restart_next_ = true;
}

void SampleClock::commit(const Sample& s, int64_t idx) noexcept {
    // Track the origin: snap to a stamp earlier than its slot's time, leak slowly towards later ones.
    const double late = (double(s.t_us - base_t_) - offset_) - double(idx) * period_;
    if (late < 0) offset_ += late;
    else if (late < kLeakBelow * period_) offset_ += kLeak * late;
    ++n_.taken;
    n_.lost += idx - last_idx_ - 1;  // last_idx_ is -1 at an anchor, whose sample is slot 0
    last_idx_ = idx;
    if (s.held) {  // not evaluated: bridged when the next good sample comes (or the filter restarts)
        ++n_.held;
        return;
    }
    const int64_t missing = have_good_ ? idx - good_idx_ - 1 : 0;
    if (missing > kMaxBridge) {
        restart_next_ = true;
    } else {
        for (int64_t m = 1; m <= missing; ++m) {
            const double w = double(m) / double(missing + 1);
            ClockStep& o = out_[size_t(n_out_++)];
            o.sample = good_;
            o.sample.t_us = base_t_ + std::llround(offset_ + double(good_idx_ + m) * period_);
            for (size_t j = 0; j < o.sample.q.size(); ++j) o.sample.q[j] += w * (s.q[j] - good_.q[j]);
            for (size_t i = 0; i < o.sample.y.size(); ++i) o.sample.y[i] += w * (s.y[i] - good_.y[i]);
            for (size_t j = 0; j < o.sample.dq.size(); ++j) o.sample.dq[j] += w * (s.dq[j] - good_.dq[j]);
            o.sample.held = false;
            o.interpolated = true;
            o.restart = false;
            ++n_.interpolated;
        }
    }
    ClockStep& o = out_[size_t(n_out_++)];
    o.sample = s;
    o.sample.t_us = base_t_ + std::llround(offset_ + double(idx) * period_);
    o.interpolated = false;
    o.restart = restart_next_;
    if (restart_next_) ++n_.restarts;
    restart_next_ = false;
    have_good_ = true;
    good_ = o.sample;
    good_idx_ = idx;
}

// Commits held samples: the oldest one whenever the stamps leave no room for a loss before it (L_max ≤ 0), else
// when the window is full or `all` (no more evidence will come: stale data, time backwards, end of input).
// extra_slot (≥ 0 when given): the slot of one more sample after the held ones, a bound like theirs.
void SampleClock::decide(bool all, int64_t extra_slot) noexcept {
    while (n_held_ > 0) {
        int64_t l_max = INT64_MAX;
        for (int j = 0; j < n_held_; ++j) l_max = std::min(l_max, held_slot_[at(j)] - last_idx_ - 1 - j);
        if (extra_slot >= 0) l_max = std::min(l_max, extra_slot - last_idx_ - 1 - n_held_);
        // The sender is taken as on time again (the bound as tight) once it kept the sample period twice in a row
        // after the gap, on its ticks: the last two held samples 0.5 to 1.5 periods apart (a catch-up burst sends
        // back to back) and each within half a period of its tick with L_max lost (a sender preempted twice inside
        // its catch-up keeps a period but stays behind).
        auto on_tick = [&](int j) {
            const double d = double(held_[at(j)].t_us - held_[at(j - 1)].t_us);
            const double tick = offset_ + double(last_idx_ + 1 + l_max + j) * period_;
            const double late = double(held_[at(j)].t_us - base_t_) - tick;
            return d >= 0.5 * period_ && d <= 1.5 * period_ && late < 0.5 * period_;
        };
        const bool paced = n_held_ >= 3 && on_tick(n_held_ - 1) && on_tick(n_held_ - 2);
        if (l_max > 0 && !all && !paced && n_held_ < kWindow) return;
        if (l_max <= 0 && held_slot_[at(0)] > last_idx_ + 1) ++n_.late;  // it looked past a gap: it was late
        commit(held_[at(0)], last_idx_ + 1 + std::max<int64_t>(l_max, 0));
        head_ = (head_ + 1) % kWindow;
        --n_held_;
    }
}

int SampleClock::push(const Sample& s) noexcept {
    n_out_ = 0;
    const bool backwards = anchored_ && s.t_us <= last_t_;
    if (s.stale || backwards) {
        decide(true, anchored_ && !backwards ? slot(s.t_us) : -1);  // a stale sample's stamp is evidence too
        if (s.stale) {
            anchored_ = false;  // no contact from stale data; the filter restarts when good data come back
            return n_out_;
        }
    }
    if (!anchored_ || backwards) {
        anchor(s.t_us);
        last_t_ = s.t_us;
        commit(s, 0);
        return n_out_;
    }
    last_t_ = s.t_us;
    const int64_t k = slot(s.t_us);
    if (n_held_ == 0 && k <= last_idx_ + 1) {
        commit(s, last_idx_ + 1);
        return n_out_;
    }
    held_[at(n_held_)] = s;
    held_slot_[at(n_held_)] = k;
    ++n_held_;
    decide(false, -1);
    return n_out_;
}

int SampleClock::flush() noexcept {
    n_out_ = 0;
    decide(true, -1);
    return n_out_;
}

}  // namespace dynid::rt
