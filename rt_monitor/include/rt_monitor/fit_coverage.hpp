// The postures the fit saw (coefficient file version 8, fit_range): the joints a sample holds beyond the range they
// had in the model's fit data. Λ and T²_α were calibrated on postures inside, and a model is extrapolated outside
// (the iCub leg's first half held out of its fit: 49.6 % false positives where the ankle's roll leaves the fit's range;
// docs/detection.md#out-of-sample). Counted and told with every event, so that a reader can weigh it; never a fault (a
// robot may work beyond its excitation) and never a contact. No allocation: a bit mask over at most 64 joints.
#pragma once

#include <cstddef>
#include <cstdint>

#include "rt_monitor/coefficients.hpp"

namespace dynid::rt {

static_assert(kMaxJoints <= 64, "a joint mask is 64 bits");

class FitCoverage {
public:
    explicit FitCoverage(const Coefficients& c) noexcept : c_(c) {}

    // Bit j: q_j beyond [fit_lower_j, fit_upper_j] (a NaN too: not a posture the fit saw); a sample with any such
    // joint is counted.
    uint64_t check(const double* q) noexcept {
        uint64_t beyond = 0;
        for (int j = 0; j < c_.n_joints; ++j)
            if (!(q[j] >= c_.fit_lower[size_t(j)] && q[j] <= c_.fit_upper[size_t(j)])) beyond |= uint64_t(1) << j;
        last_ = beyond;
        samples_ += beyond != 0;
        return beyond;
    }
    uint64_t last() const noexcept { return last_; }        // the latest sample's joints beyond
    int64_t samples() const noexcept { return samples_; }   // samples with any, since the start

private:
    const Coefficients& c_;
    uint64_t last_ = 0;
    int64_t samples_ = 0;
};

}  // namespace dynid::rt
