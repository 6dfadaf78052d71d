#include "rt_monitor/momentum.hpp"

#include "rt_monitor/kinematics.hpp"
#include "rt_monitor/multiversion.hpp"

namespace dynid::rt {

RT_MULTIVERSION
void momentum_terms(const Coefficients& c, const double* q, const double* dq, MomentumTerms& out) noexcept {
    // Forward: each body's velocity (v linear, w angular) and the acceleration −g in its own frame, then its momentum
    // h = I·(v, w) and the wrench I·(−g, 0) that holds it against gravity. Spatial vectors are (linear, angular).
    std::array<Mat3, kMaxBodies> R;
    std::array<Vec3, kMaxBodies> r, v, w, a, hl, ha, gl, ga;
    const int nb = c.n_bodies;
    for (int i = 0; i < nb; ++i) {
        joint_placement(c, i, q, R[i], r[i]);
        const int p = c.parent[i], j = c.joint_index[i];
        if (p < 0) {
            w[i].setZero();
            v[i].setZero();
            a[i].noalias() = R[i].transpose() * (-c.gravity);
        } else {
            w[i].noalias() = R[i].transpose() * w[p];
            v[i].noalias() = R[i].transpose() * (v[p] + w[p].cross(r[i]));
            a[i].noalias() = R[i].transpose() * a[p];  // a uniform field: no transport term
        }
        if (c.joint_type[i] == JointType::kRevolute) w[i] += c.axis[i] * dq[j];
        else if (c.joint_type[i] == JointType::kPrismatic) v[i] += c.axis[i] * dq[j];
        const double m = c.mass[i];
        const Vec3& h = c.first_moment[i];  // m·c
        hl[i] = m * v[i] - h.cross(w[i]);
        ha[i] = h.cross(v[i]) + c.inertia[i] * w[i];
        gl[i] = m * a[i];
        ga[i] = h.cross(a[i]);
    }
    // Backward: subtree sums carried into each parent's frame; each joint reads its axis' components.
    for (int i = nb - 1; i >= 0; --i) {
        const int j = c.joint_index[i], p = c.parent[i];
        const Vec3& ax = c.axis[i];
        if (c.joint_type[i] == JointType::kRevolute) {  // S = (0, ax): v × S = (v × ax, w × ax)
            out.p[j] = ax.dot(ha[i]);
            out.beta[j] = v[i].cross(ax).dot(hl[i]) + w[i].cross(ax).dot(ha[i]) - ax.dot(ga[i]);
        } else if (c.joint_type[i] == JointType::kPrismatic) {  // S = (ax, 0): v × S = (w × ax, 0)
            out.p[j] = ax.dot(hl[i]);
            out.beta[j] = w[i].cross(ax).dot(hl[i]) - ax.dot(gl[i]);
        }
        if (const int s = c.sensor_of_body[i]; s >= 0) {  // β = −v ×* h − f_g, v ×* h = (w × h_l, w × h_a + v × h_l)
            out.p_sensor[s] << hl[i], ha[i];
            out.beta_sensor[s] << -w[i].cross(hl[i]) - gl[i], -w[i].cross(ha[i]) - v[i].cross(hl[i]) - ga[i];
        }
        if (p >= 0) {
            const Vec3 fl = R[i] * hl[i], gp = R[i] * gl[i];
            hl[p] += fl;
            ha[p].noalias() += R[i] * ha[i];
            ha[p] += r[i].cross(fl);
            gl[p] += gp;
            ga[p].noalias() += R[i] * ga[i];
            ga[p] += r[i].cross(gp);
        }
    }
}

}  // namespace dynid::rt
