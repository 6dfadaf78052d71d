// The monitor's sample clock: which tick of the boards' 1 kHz each assembled sample belongs to, read from its
// stamp alone (the iCub frames carry no sample counter, docs/design.md §5), and so what the derivative filter is fed.
//
// Samples sit on a nominal grid t = origin + k·P. The origin follows the earliest stamps (a stamp is never early:
// the boards send on a timer, the bus and the kernel only delay) and leaks slowly later, so that a board clock a
// few hundred ppm off is followed. A sample stamped in or before the next slot is consecutive (a catch-up burst
// included). A sample stamped beyond a gap is ambiguous from its stamp: it is either late (its sender woke late,
// and one pacing on absolute deadlines then catches up in a burst) or on time after lost samples. So it is held,
// with the samples after it (up to kWindow in all), and the number of lost samples L before it is bounded by the
// stamps: no sample is stamped before its own tick, so with the held samples consecutive after the L lost ones,
// L ≤ min_j (slot_j − last − j) = L_max. As soon as L_max is 0 (a catch-up burst shows the sender was behind)
// the held samples are consecutive. Once the sender has kept the period twice in a row after the gap, within half
// a period of its ticks (it sleeps to each deadline, so it is on time), or kWindow samples are held, the bound is
// taken as tight: the first held sample had L_max samples lost before it, bridged by linear interpolation (at
// most kMaxBridge; a longer gap restarts the filter). The cost is a delay, only after a gap: two samples after a
// real loss, the catch-up burst after a stalled sender (its samples were late anyway). Stamps alone cannot tell
// every case: a loss right next to a late sample can be placed a sample off (the count stays right), a loss
// followed by samples each stamped most of a period late, with no burst, reads as lateness, and a sender that
// keeps the period a whole number of periods behind reads as losses.
//
// No allocation, locking, exceptions or I/O: fixed-size samples are copied in and out of fixed arrays.
#pragma once

#include <array>
#include <cstdint>

#include "rt_monitor/assembler.hpp"

namespace dynid::rt {

struct ClockStep {
    Sample sample;              // t_us: the sample's time on the nominal grid
    bool interpolated = false;  // a bridged sample (lost, or held by the assembler)
    bool restart = false;       // restart the filter before this one (after stale data, a long gap, time backwards)
};

// Every sample pushed that is not stale is taken onto the grid once, in order: as evaluated, or as `held` (an encoder
// value not renewed: bridged, not evaluated). So steps evaluated = taken − held + interpolated, with taken = pushed −
// stale. `lost`: empty slots of the grid between two samples taken (samples that never came); interpolated ≤ held +
// lost, the rest left out where a gap was longer than kMaxBridge or held samples were followed by stale data or the end.
struct ClockCounters {
    int64_t interpolated = 0, restarts = 0, late = 0;  // late: samples past a gap that later stamps showed were late
    int64_t taken = 0, held = 0, lost = 0;
};

class SampleClock {
public:
    static constexpr int kMaxBridge = 3;  // missing samples bridged; a longer gap restarts the filter
    static constexpr int kWindow = 64;    // at most this many samples held after a gap (a 60 ms stall's catch-up)
    static constexpr int kMaxSteps = (kWindow + 1) * (kMaxBridge + 1);

    explicit SampleClock(double period_us = 1000.0) noexcept : period_(period_us) {}
    // One assembled sample in; returns how many steps are ready, step(0) … step(n-1), to evaluate in order.
    int push(const Sample& s) noexcept;
    // End of input: samples still held are decided on the stamps there are.
    int flush() noexcept;
    const ClockStep& step(int i) const noexcept { return out_[size_t(i)]; }
    const ClockCounters& counters() const noexcept { return n_; }

private:
    int64_t slot(int64_t t_us) const noexcept;
    void anchor(int64_t t_us) noexcept;
    void commit(const Sample& s, int64_t idx) noexcept;
    void decide(bool all, int64_t extra_slot) noexcept;

    double period_;
    bool anchored_ = false;     // the grid is valid (false at start and after stale data)
    int64_t base_t_ = 0;        // grid origin = base_t_ + offset_ (µs; offset_ small, so double keeps sub-µs)
    double offset_ = 0;
    int64_t last_idx_ = -1;     // grid index of the last committed sample
    int64_t last_t_ = 0;        // stamp of the last sample taken (time running backwards restarts)
    bool have_good_ = false;    // good_: the last evaluated sample, the left end of a bridge
    Sample good_;
    int64_t good_idx_ = 0;
    std::array<Sample, kWindow> held_{};   // samples past a gap (a ring from head_), with their slots
    std::array<int64_t, kWindow> held_slot_{};
    int head_ = 0, n_held_ = 0;
    size_t at(int j) const noexcept { return size_t((head_ + j) % kWindow); }
    bool restart_next_ = false;
    std::array<ClockStep, kMaxSteps> out_{};
    int n_out_ = 0;
    ClockCounters n_;
};

}  // namespace dynid::rt
