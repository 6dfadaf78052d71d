// The Pinocchio algorithms the kernels call, behind plain functions defined in one translation unit
// (algorithms.cpp). Header-only Pinocchio instantiates an algorithm in every file that calls it, and each
// instantiation over the joint variant costs tens of seconds of compiling: made once here, the plant and the observer
// compile in parallel with it instead of each carrying them (the set-up's build, docs/benchmarks.md#the-suites-time).
// Every argument is a contiguous vector (Eigen::Ref: a VectorXd or a Map binds without a copy), so one instantiation
// serves every caller; the results are Pinocchio's own, in `data`.
#pragma once

#include <pinocchio/multibody.hpp>

namespace dynid::algo {

using Vector = Eigen::Ref<const Eigen::VectorXd>;
using Forces = pinocchio::container::aligned_vector<pinocchio::Force>;

// τ = M(q) a + C(q, v) v + g(q): pinocchio::rnea
const Eigen::VectorXd& rnea(const pinocchio::Model& m, pinocchio::Data& d, const Vector& q, const Vector& v,
                            const Vector& a);
// The same with external forces on the joints (in their local frames): pinocchio::rnea with fext
const Eigen::VectorXd& rnea(const pinocchio::Model& m, pinocchio::Data& d, const Vector& q, const Vector& v,
                            const Vector& a, const Forces& fext);
// M(q), its upper triangle (pinocchio::crba)
const Eigen::MatrixXd& crba(const pinocchio::Model& m, pinocchio::Data& d, const Vector& q);
// g(q): pinocchio::computeGeneralizedGravity
const Eigen::VectorXd& gravity(const pinocchio::Model& m, pinocchio::Data& d, const Vector& q);
// d.J, d.dJ, d.v, d.oMi at (q, v): pinocchio::computeJointJacobiansTimeVariation
void jacobians_time_variation(const pinocchio::Model& m, pinocchio::Data& d, const Vector& q, const Vector& v);

}  // namespace dynid::algo
