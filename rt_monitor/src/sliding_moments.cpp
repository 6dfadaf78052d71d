#include "rt_monitor/sliding_moments.hpp"

#include "rt_monitor/multiversion.hpp"
#include "vector4.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace dynid::rt {
namespace {

// φ_m(s) = u^m, u = (s − center)/scale: centred and scaled monomials keep the moments' normal equations well
// conditioned for every window up to kMaxWindow.
void powers(double u, int n, double* out) noexcept {
    double p = 1;
    for (int m = 0; m < n; ++m, p *= u) out[m] = p;
}

}  // namespace

bool SlidingMoments::configure(const double* weights, int stride, int columns, int W, int order) noexcept {
    moments_ = 0;
    const int n = order + 1;
    // W ≥ 3: the newest tap at u = 1 (the update adds it with weight 1), as the loader's smallest window
    if (order < 0 || n > kMaxMoments || W < std::max(n, 3) || W > kMaxWindow || columns < 1 || columns > kEstimates)
        return false;
    center_ = 0.5 * (W - 1);
    scale_ = std::max(center_, 1.0);
    using Square = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxMoments, kMaxMoments>;
    using Column = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxMoments, 1>;
    // Each column's polynomial by least squares over the taps: G b = Σ_s φ(s) w(s), G = Σ_s φ(s) φ(s)ᵀ.
    Square gram = Square::Zero(n, n);
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxMoments, kEstimates> rhs =
        decltype(rhs)::Zero(n, columns);
    double phi[kMaxMoments];
    for (int s = 0; s < W; ++s) {
        powers((s - center_) / scale_, n, phi);
        for (int a = 0; a < n; ++a) {
            for (int b = 0; b < n; ++b) gram(a, b) += phi[a] * phi[b];
            for (int r = 0; r < columns; ++r) rhs(a, r) += phi[a] * weights[r * stride + s];
        }
    }
    const Eigen::LDLT<Square> solver(gram);
    for (int r = 0; r < columns; ++r) {
        const Column b = solver.solve(rhs.col(r));
        double largest = 0;
        for (int s = 0; s < W; ++s) largest = std::max(largest, std::abs(weights[r * stride + s]));
        for (int s = 0; s < W; ++s) {
            powers((s - center_) / scale_, n, phi);
            double fit = 0;
            for (int m = 0; m < n; ++m) fit += b[m] * phi[m];
            // not this order's polynomial, or not a number
            if (!(std::abs(weights[r * stride + s] - fit) <= 1e-9 * largest)) return false;
        }
        gain_[r] = 0;
        for (int s = 0; s < W; ++s) gain_[r] += weights[r * stride + s];
        combination_[r].fill(0.0);
        for (int m = 0; m < n; ++m) combination_[r][m] = b[m];
    }
    // The shift: φ_m(s − 1) = (u − δ)^m = Σ_l C(m, l) (−δ)^(m−l) u^l, δ = 1/scale.
    const double delta = 1.0 / scale_;
    for (auto& row : shift_) row.fill(0.0);
    for (int m = 0; m < n; ++m) {
        double binomial = 1;  // C(m, l), l from m down
        for (int l = m; l >= 0; --l) {
            shift_[m][l] = binomial * std::pow(-delta, m - l);
            binomial = binomial * l / (m - l + 1);
        }
    }
    powers((-1 - center_) / scale_, n, leaving_weight_.data());
    window_ = W;
    moments_ = n;
    reset();
    return true;
}

void SlidingMoments::reset() noexcept {
    sliding_.fill(0.0);
    direct_.fill(0.0);
    reference_.fill(0.0);  // the moments of an all-zero window about 0
    next_reference_.fill(0.0);
    phase_ = 0;
}

template <int M>
inline void SlidingMoments::slide(const double* leaving, const double* entering, int blocks) noexcept {
    // μ_m ← Σ_{l≤m} shift[m][l] μ_l − φ_m(−1)·x_leaving + φ_m(W − 1)·x_new (φ_m(W − 1) = 1), from the highest moment
    // down so each reads the lower ones before they move; and the direct sums of the window that ends W − 1 − phase
    // samples from now, the new sample at tap `phase`. Each set of sums is of x minus its own reference, the first
    // sample of the direct sums' window: sums of what varies, not of offsets, round far less. A block's moments
    // stay in registers.
    double phi[kMaxMoments];
    powers((phase_ - center_) / scale_, M, phi);
    const bool first = phase_ == 0, complete = phase_ + 1 == window_;
    for (int b = 0; b < blocks; ++b) {
        V4Block* s = as_block(block(sliding_, b));
        V4Block* e = as_block(block(direct_, b));
        V4Block& reference = *as_block(reference_.data() + b * kLanes);
        V4Block& next = *as_block(next_reference_.data() + b * kLanes);
        const V4Block in = *as_block(entering + b * kLanes);
        if (first) next = in;
        const V4Block x = in - reference, out = *as_block(leaving + b * kLanes) - reference, d = in - next;
        for (int m = M - 1; m >= 0; --m) {
            V4Block mu = s[m];
            for (int l = 0; l < m; ++l) mu += shift_[m][l] * s[l];
            s[m] = mu + (x - leaving_weight_[m] * out);
            e[m] += phi[m] * d;
        }
        if (complete) {  // a whole window summed directly replaces the sliding moments: no rounding outlives a window
            for (int m = 0; m < M; ++m) s[m] = e[m], e[m] = V4Block{};
            reference = next;
        }
    }
    phase_ = complete ? 0 : phase_ + 1;
}

RT_MULTIVERSION
void SlidingMoments::push(const double* leaving, const double* entering, int blocks) noexcept {
    switch (moments_) {
        case 1: slide<1>(leaving, entering, blocks); break;
        case 2: slide<2>(leaving, entering, blocks); break;
        case 3: slide<3>(leaving, entering, blocks); break;
        case 4: slide<4>(leaving, entering, blocks); break;
        default: break;
    }
}

RT_MULTIVERSION
void SlidingMoments::estimate(int r, int first, int n, double* out) const noexcept {
    // Block by block, Σ_m c_m μ_m in one vector; the lanes inside [first, first + n) written out.
    const auto& c = combination_[r];
    for (int b = first / kLanes; b * kLanes < first + n; ++b) {
        const V4Block* mu = as_block(sliding_.data() + b * kMaxMoments * kLanes);
        V4 v = c[0] * mu[0];
        for (int m = 1; m < moments_; ++m) v += c[m] * mu[m];
        v += gain_[r] * *as_block(reference_.data() + b * kLanes);  // the estimate of x − x₀ and of x differ by x₀·Σ w_r
        const int lo = std::max(first, b * kLanes), hi = std::min(first + n, (b + 1) * kLanes);
        for (int k = lo; k < hi; ++k) out[k - first] = v[k - b * kLanes];
    }
}

}  // namespace dynid::rt
