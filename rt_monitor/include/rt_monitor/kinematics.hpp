// The chain's joint placements, shared by the recursive Newton-Euler prediction (core.cpp) and the momentum terms
// (momentum.cpp): body i sits at R_i, r_i in its parent's frame (parent-from-child), moved by its joint.
#pragma once

#include "rt_monitor/coefficients.hpp"

#include <cmath>

namespace dynid::rt {

inline Mat3 axis_rotation(const Vec3& a, double angle) noexcept {
    const double s = std::sin(angle), co = std::cos(angle), t = 1.0 - co;
    Mat3 R;
    R << t * a.x() * a.x() + co, t * a.x() * a.y() - s * a.z(), t * a.x() * a.z() + s * a.y(),
        t * a.x() * a.y() + s * a.z(), t * a.y() * a.y() + co, t * a.y() * a.z() - s * a.x(),
        t * a.x() * a.z() - s * a.y(), t * a.y() * a.z() + s * a.x(), t * a.z() * a.z() + co;
    return R;
}

// Body i's placement in its parent at joint positions q: rotation R (parent-from-child) and origin r.
inline void joint_placement(const Coefficients& c, int i, const double* q, Mat3& R, Vec3& r) noexcept {
    const int j = c.joint_index[i];
    r = c.translation[i];
    switch (c.joint_type[i]) {
        case JointType::kRevolute: R.noalias() = c.rotation[i] * axis_rotation(c.axis[i], q[j]); break;
        case JointType::kPrismatic: R = c.rotation[i]; r.noalias() += c.rotation[i] * (c.axis[i] * q[j]); break;
        default: R = c.rotation[i]; break;
    }
}

}  // namespace dynid::rt
