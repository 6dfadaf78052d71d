// The fixed-lag Savitzky-Golay filter in O(order²) a sample instead of O(window): each of its weight columns is a
// polynomial of the fit's order in the tap index, so an estimate is a fixed combination of the window's polynomial
// moments μ_m = Σ_s φ_m(s)·x_s, and the moments slide with the window by a triangular shift. Rounding would build up
// in the sliding sums; a second set of moments, summed directly over the samples as they arrive, replaces them each
// time a whole window has passed, so rounding lasts at most two windows. Unlike the convolution, a sample's rounding
// stays until that replacement after it has left the window: a finite glitch of size G leaves about ulp(G)·Σ|w| in
// the estimates for up to a window more, a non-finite one poisons them for up to two (the assembler passes finite
// values only). Fixed-size, no allocation, noexcept (the core's rules); the direct convolution stays the reference
// (tests/test_sliding_moments.cpp compares the two; tests/test_core.cpp the core's outputs with it).
#pragma once

#include "rt_monitor/capacity.hpp"

#include <array>

namespace dynid::rt {

class SlidingMoments {
public:
    // Fits up to order 3, every bundled robot's: a higher order's moments cancel more, and its estimates drift from
    // the convolution's beyond 1e-12 of their terms (order 5 over 256 taps: 6e-12), so those convolve.
    static constexpr int kMaxMoments = 4;
    static constexpr int kMaxChannels = kMaxJoints + kMaxOutputs;
    static constexpr int kEstimates = 3;                      // value, slope, curvature

    // From the filter's weight columns (`columns` of them, each W taps oldest first, column r at weights + r·stride)
    // and the fit's order. False (and nothing configured) when a column is not a polynomial of that order in the tap
    // index to 1e-9 of its largest weight, or the order is above kMaxMoments − 1: the caller convolves.
    bool configure(const double* weights, int stride, int columns, int W, int order) noexcept;
    bool configured() const noexcept { return moments_ > 0; }
    // Back to an all-zero window (the core's ring after its reset).
    void reset() noexcept;
    // Slide by one sample over the first `blocks` blocks of 4 channels: `leaving` the row that leaves the window,
    // `entering` the new one (the core's ring rows, padded to whole blocks).
    void push(const double* leaving, const double* entering, int blocks) noexcept;
    // Estimate column r (< columns) of channels [first, first + n) into out.
    void estimate(int r, int first, int n, double* out) const noexcept;

private:
    static constexpr int kLanes = 4, kMaxBlocks = (kMaxChannels + kLanes - 1) / kLanes;
    template <int M>
    [[gnu::always_inline]] inline void slide(const double* leaving, const double* entering, int blocks) noexcept;
    double* block(std::array<double, kMaxBlocks * kMaxMoments * kLanes>& a, int b) noexcept {
        return a.data() + b * kMaxMoments * kLanes;
    }

    int window_ = 0, moments_ = 0, phase_ = 0;
    double center_ = 0, scale_ = 1;                           // u = (s − center)/scale ∈ [−1, 1]
    std::array<std::array<double, kMaxMoments>, kMaxMoments> shift_{};     // φ_m(s − 1) = Σ_l shift_[m][l] φ_l(s)
    std::array<double, kMaxMoments> leaving_weight_{};                     // φ_m(−1)
    std::array<std::array<double, kMaxMoments>, kEstimates> combination_{};  // w_r(s) = Σ_m combination_[r][m] φ_m(s)
    std::array<double, kEstimates> gain_{};                                  // Σ_s w_r(s): column r's gain on a constant
    // The moments, block by block: a block's kMaxMoments moments of its 4 channels, each moment's 4 lanes contiguous.
    alignas(64) std::array<double, kMaxBlocks * kMaxMoments * kLanes> sliding_{}, direct_{};
    // Each channel's reference: the sliding moments are of x − reference_, the direct sums of x − next_reference_.
    alignas(64) std::array<double, kMaxBlocks * kLanes> reference_{}, next_reference_{};
};

}  // namespace dynid::rt
