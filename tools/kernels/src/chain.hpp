// The rigid-body chain of dynid's identification model, in the form the batch kernels need (docs/design.md §3).
//
// Pinocchio's `computeJointTorqueRegressor` (the Python reference, dynid.robot.regressors.rigid_body) propagates each
// body's 6x10 regressor up the tree by one force transform per ancestor joint. Here each ancestor's motion axis is
// brought down to the body instead (a 6-vector, not a 6x10 block), which is what makes the kernel cheaper than the
// reference's C++; the suite checks the two agree sample by sample (tools/tests/test_kernels.py).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

namespace dynid {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using BodyRegressor = Eigen::Matrix<double, 6, 10>;

enum JointKind : int { Revolute = 0, Prismatic = 1, Held = 2 };  // Held: an F/T sensor's 6-DoF joint at identity

struct Joint {
    int parent = -1;  // index of the parent joint, -1 for the root
    int kind = Revolute;
    Mat3 R = Mat3::Identity();  // placement of the joint frame in the parent's frame
    Vec3 p = Vec3::Zero();
    Vec3 axis = Vec3::UnitZ();  // in the joint frame (revolute, prismatic)
    int q_col = -1;             // column of the joint's position in q (the configured joints), -1 when held
    int v_row = 0;              // first row in Pinocchio's velocity vector
    int nv = 1;                 // 1, or 6 when held
};

// Per-sample state of every joint (local frames, as Pinocchio's data.liMi, data.v, data.a_gf).
struct ChainState {
    std::vector<Mat3> R;  // liMi rotation
    std::vector<Vec3> p;  // liMi translation
    std::vector<Vec3> v_lin, v_ang, a_lin, a_ang;
    std::vector<Mat3> oR;  // world poses of the joint frames
    std::vector<Vec3> op;
    std::vector<Vec3> axis_lin, axis_ang;  // 1-DoF joints' axes in the world frame
    explicit ChainState(size_t n)
        : R(n), p(n), v_lin(n), v_ang(n), a_lin(n), a_ang(n), oR(n), op(n), axis_lin(n), axis_ang(n) {}
};

class Chain {
public:
    Chain(std::vector<Joint> joints, const Vec3& gravity);

    int nv() const { return nv_; }
    int n_bodies() const { return static_cast<int>(joints_.size()); }
    int n_joints_configured() const { return n_q_; }
    const std::vector<Joint>& joints() const { return joints_; }
    // ancestors_[i]: joint i and its ancestors, i first
    const std::vector<int>& ancestors(int i) const { return ancestors_[i]; }

    // Forward pass: placements, velocities and accelerations (gravity folded in) of every body. `gravity`: the
    // root-frame gravity of this sample, or null for the chain's own.
    void kinematics(const double* q, const double* dq, const double* ddq, const double* gravity, ChainState& s) const;

    // The full joint-torque regressor (nv, 10 n_bodies), row-major with row stride `ld`, every entry written:
    // Pinocchio's computeJointTorqueRegressor.
    void regressor(const double* q, const double* dq, const double* ddq, const double* gravity, ChainState& s,
                   double* Y, long ld) const;

private:
    std::vector<Joint> joints_;
    std::vector<std::vector<int>> ancestors_;
    Vec3 gravity_;
    int nv_ = 0;
    int n_q_ = 0;
};

// Pinocchio's bodyRegressor: the body's wrench (frame of the body) = Y(v, a) * [m, mc, I (6)].
void body_regressor(const Vec3& v_lin, const Vec3& w, const Vec3& a_lin, const Vec3& alpha, BodyRegressor& Y);

}  // namespace dynid
