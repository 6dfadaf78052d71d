// The chain's joint placements, shared by the recursive Newton-Euler prediction (core.cpp) and the momentum terms
// (momentum.cpp): body i sits at R_i, r_i in its parent's frame (parent-from-child), moved by its joint.
#pragma once

#include "rt_monitor/coefficients.hpp"

#include <cmath>

namespace dynid::rt {

// Body i's placement in its parent at joint positions q: rotation R (parent-from-child) and origin r. A revolute
// joint turns by θ about its axis a: R = R₀·(cos θ·I + sin θ·[a]× + (1 − cos θ)·a aᵀ) (Rodrigues), summed from the
// two products the loader keeps rather than multiplied out each sample.
inline void joint_placement(const Coefficients& c, int i, const double* q, Mat3& R, Vec3& r) noexcept {
    const int j = c.joint_index[i];
    r = c.translation[i];
    switch (c.joint_type[i]) {
        case JointType::kRevolute: {
            const double s = std::sin(q[j]), co = std::cos(q[j]);
            R = co * c.rotation[i] + s * c.rotation_cross[i] + (1.0 - co) * c.rotation_outer[i];
            break;
        }
        case JointType::kPrismatic: R = c.rotation[i]; r.noalias() += c.rotation[i] * (c.axis[i] * q[j]); break;
        default: R = c.rotation[i]; break;
    }
}

}  // namespace dynid::rt
