// The generalized momentum p = M(q) q̇ and β = Cᵀ(q, q̇) q̇ − g(q) of the chain, in O(n) (no mass matrix): what the
// momentum observer integrates (dynid.detect.momentum; De Luca and Mattone 2003). Fixed-size, noexcept.
#pragma once

#include "rt_monitor/coefficients.hpp"

namespace dynid::rt {

using VecJ = Eigen::Matrix<double, kMaxJoints, 1>;

struct MomentumTerms {
    VecJ p = VecJ::Zero(), beta = VecJ::Zero();  // per joint (entries of q)
    // Each F/T sensor's 6 coordinates: its distal subtree's momentum, in the sensor frame (linear, angular about its
    // origin).
    std::array<Vec6, kMaxSensors> p_sensor{}, beta_sensor{};
};

// For every joint i: p_i = S_iᵀ h_i and β_i = (v_i × S_i)ᵀ h_i − S_iᵀ f_g,i, with h_i the spatial momentum of the
// subtree it moves, v_i its body's velocity and f_g,i the wrench that holds the subtree against gravity
// (∂T/∂q_i = (v_i × S_i)ᵀ h_i for a tree: Lagrange's ṗ = τ + ∂T/∂q − g with ∂T/∂q = Cᵀq̇). The sensor's
// coordinates, which never move: p = h, β = −v ×* h − f_g.
void momentum_terms(const Coefficients& c, const double* q, const double* dq, MomentumTerms& out) noexcept;

}  // namespace dynid::rt
