// The derivative filter's sliding moments (rt_monitor/src/sliding_moments.cpp) against the direct convolution with
// Savitzky-Golay weights built here from their definition, over runs many windows long: within 1e-12 of the size of
// the convolution's terms, its own rounding scale.
#include "rt_monitor/sliding_moments.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

using namespace dynid::rt;

namespace {

constexpr int kBlock = 4;

// The fixed-lag Savitzky-Golay weights, oldest tap first: the least-squares polynomial of `order` through the window,
// its value, slope and curvature at tap W − 1 − lag, for a sample period dt. Columns 0..2, kMaxWindow apart.
std::vector<double> savitzky_golay(int W, int order, int lag, double dt) {
    Eigen::MatrixXd V(W, order + 1);
    const double t0 = W - 1 - lag;
    for (int s = 0; s < W; ++s)
        for (int m = 0; m <= order; ++m) V(s, m) = std::pow((s - t0) * dt, m);
    const Eigen::MatrixXd H = (V.transpose() * V).ldlt().solve(V.transpose());  // rows: the coefficients
    std::vector<double> w(3 * kMaxWindow, 0.0);
    for (int s = 0; s < W; ++s) {
        w[s] = H(0, s);
        w[kMaxWindow + s] = H(1, s);
        w[2 * kMaxWindow + s] = 2.0 * H(2, s);
    }
    return w;
}

struct Case {
    int window, order, lag;
    double dt;
};

class SlidingMomentsVsConvolution : public testing::TestWithParam<Case> {};

}  // namespace

TEST_P(SlidingMomentsVsConvolution, AgreeOnEverySampleOfALongRun) {
    const Case k = GetParam();
    const std::vector<double> w = savitzky_golay(k.window, k.order, k.lag, k.dt);
    auto moments = std::make_unique<SlidingMoments>();
    ASSERT_TRUE(moments->configure(w.data(), kMaxWindow, 3, k.window, k.order));
    // Six channels in two blocks: joint-like angles with offsets, a force with a large offset, and noise.
    constexpr int n = 6, blocks = 2, stride = blocks * kBlock;
    const int samples = 40 * k.window + 1000;
    std::vector<double> rows(size_t(samples) * stride, 0.0);
    std::mt19937_64 rng(7);
    std::normal_distribution<double> noise(0.0, 1e-3);
    for (int t = 0; t < samples; ++t)
        for (int c = 0; c < n; ++c)
            rows[size_t(t) * stride + c] = (c == 5 ? 40.0 : 1.5 * c - 3.0) +
                                           std::sin(k.dt * t * (0.5 + c)) * (1 + c) + noise(rng);
    const std::vector<double> zero(stride, 0.0);
    double worst = 0;
    for (int t = 0; t < samples; ++t) {
        const double* leaving = t >= k.window ? &rows[size_t(t - k.window) * stride] : zero.data();
        moments->push(leaving, &rows[size_t(t) * stride], blocks);
        if (t + 1 < k.window) continue;
        for (int r = 0; r < 3; ++r) {
            double got[n];
            moments->estimate(r, 0, n, got);
            for (int c = 0; c < n; ++c) {
                double direct = 0, scale = 0;  // the convolution, and the size of its terms: its own rounding scale
                for (int s = 0; s < k.window; ++s) {
                    const double term = w[size_t(r) * kMaxWindow + s] * rows[size_t(t - k.window + 1 + s) * stride + c];
                    direct += term;
                    scale += std::abs(term);
                }
                worst = std::max(worst, std::abs(got[c] - direct) / scale);
            }
        }
    }
    EXPECT_LT(worst, 1e-12) << "window " << k.window << ", order " << k.order;
    // An estimate over part of a block (the outputs start after the joints) reads the same lanes.
    double whole[n], part[3];
    moments->estimate(0, 0, n, whole);
    moments->estimate(0, 3, 3, part);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(part[c], whole[3 + c]);
}

INSTANTIATE_TEST_SUITE_P(Windows, SlidingMomentsVsConvolution,
                         testing::Values(Case{151, 3, 37, 0.002}, Case{31, 3, 7, 0.001}, Case{15, 2, 3, 0.01},
                                         Case{256, 3, 0, 0.001}, Case{256, 2, 128, 0.001}, Case{11, 3, 5, 0.01}));

TEST(SlidingMoments, RefusesWeightsThatAreNotThePolynomialsOfTheOrder) {
    std::vector<double> w = savitzky_golay(31, 3, 7, 0.001);
    SlidingMoments moments;
    EXPECT_FALSE(moments.configure(w.data(), kMaxWindow, 3, 31, 2));  // a cubic fit is no quadratic
    w[10] += 1e-3;
    EXPECT_FALSE(moments.configure(w.data(), kMaxWindow, 3, 31, 3));
    EXPECT_FALSE(moments.configure(w.data(), kMaxWindow, 3, 31, SlidingMoments::kMaxMoments));  // above its capacity
    const std::vector<double> quartic = savitzky_golay(31, 4, 7, 0.001);  // a true quartic fit: above its capacity too
    EXPECT_FALSE(moments.configure(quartic.data(), kMaxWindow, 3, 31, 4));
    const std::vector<double> two(3 * kMaxWindow, 0.5);  // two taps of a line: the newest would not sit at u = 1
    EXPECT_FALSE(moments.configure(two.data(), kMaxWindow, 1, 2, 1));
    w[10] = std::nan("");
    EXPECT_FALSE(moments.configure(w.data(), kMaxWindow, 3, 31, 3));
    EXPECT_FALSE(moments.configured());
}
