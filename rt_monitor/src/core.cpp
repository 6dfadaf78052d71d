#include "rt_monitor/core.hpp"

#include <cmath>

namespace dynid::rt {
namespace {

// Spatial vectors are (linear, angular), as Pinocchio's, split into two 3-vectors.
inline double friction(double v, const double* c) noexcept {
    // τ_f = fc⁺·[v>0] − fc⁻·[v<0] + fv⁺·max(v,0) + fv⁻·min(v,0)  (dynid.robot.regressors.friction)
    return (v > 0 ? c[0] + c[2] * v : 0.0) + (v < 0 ? -c[1] + c[3] * v : 0.0);
}

inline Mat3 axis_rotation(const Vec3& a, double angle) noexcept {
    const double s = std::sin(angle), co = std::cos(angle), t = 1.0 - co;
    Mat3 R;
    R << t * a.x() * a.x() + co, t * a.x() * a.y() - s * a.z(), t * a.x() * a.z() + s * a.y(),
        t * a.x() * a.y() + s * a.z(), t * a.y() * a.y() + co, t * a.y() * a.z() - s * a.x(),
        t * a.x() * a.z() - s * a.y(), t * a.y() * a.z() + s * a.x(), t * a.z() * a.z() + co;
    return R;
}

}  // namespace

Core::Core(const Coefficients& c) noexcept : c_(c) {
    det_.debounce_on = c.debounce_on;
    det_.debounce_off = c.debounce_off;
    det_.hysteresis = c.hysteresis;
    width_ = c.n_joints + c.n_outputs;
    if (c.supply_time_constant > 0) lambda_ = std::exp(-c.sample_period / c.supply_time_constant);
    ratio_.fill(1.0);  // stays 1 on every channel but the tracked motor inputs
    reset();
}

void Core::reset() noexcept {
    ring_.setZero();
    slot_ = 0;
    count_ = 0;
    above_run_ = below_run_ = 0;
    out_ = Output{};
}

void Core::rnea(const VecJ& q, const VecJ& dq, const VecJ& ddq, VecJ& tau, Vec6& sensor_force) const noexcept {
    // Forward pass: body velocities and accelerations in body frames; the base accelerates at −g.
    std::array<Mat3, kMaxBodies> R;  // orientation of body i in its parent (parent-from-child)
    std::array<Vec3, kMaxBodies> r, v, w, a, al, f, n;
    const int nb = c_.n_bodies;
    for (int i = 0; i < nb; ++i) {
        const int j = c_.joint_index[i], p = c_.parent[i];
        const Vec3& ax = c_.axis[i];
        r[i] = c_.translation[i];
        switch (c_.joint_type[i]) {
            case JointType::kRevolute: R[i].noalias() = c_.rotation[i] * axis_rotation(ax, q[j]); break;
            case JointType::kPrismatic: R[i] = c_.rotation[i]; r[i].noalias() += c_.rotation[i] * (ax * q[j]); break;
            default: R[i] = c_.rotation[i]; break;
        }
        Vec3 vp, wp, ap, alp;
        if (p < 0) {
            vp.setZero(); wp.setZero(); ap = -c_.gravity; alp.setZero();
        } else {
            vp = v[p]; wp = w[p]; ap = a[p]; alp = al[p];
        }
        // Transport the parent's motion to the child's origin and frame.
        w[i].noalias() = R[i].transpose() * wp;
        v[i].noalias() = R[i].transpose() * (vp + wp.cross(r[i]));
        al[i].noalias() = R[i].transpose() * alp;
        a[i].noalias() = R[i].transpose() * (ap + alp.cross(r[i]));
        if (c_.joint_type[i] == JointType::kRevolute) {
            const Vec3 s = ax * dq[j];
            // a += S q̈ + v × S q̇, with S q̇ = (0, s): linear w×0 + v×s, angular w×s
            a[i] += v[i].cross(s);
            al[i] += ax * ddq[j] + w[i].cross(s);
            w[i] += s;
        } else if (c_.joint_type[i] == JointType::kPrismatic) {
            const Vec3 s = ax * dq[j];
            a[i] += ax * ddq[j] + w[i].cross(s);
            v[i] += s;
        }
        // f = I a + v ×* (I v), with I·(v, ω) = (m v − h × ω, h × v + I_O ω), h = m c.
        const double m = c_.mass[i];
        const Vec3& h = c_.first_moment[i];
        const Mat3& I = c_.inertia[i];
        const Vec3 pl = m * v[i] - h.cross(w[i]);
        const Vec3 pa = h.cross(v[i]) + I * w[i];
        f[i] = m * a[i] - h.cross(al[i]) + w[i].cross(pl);
        n[i] = h.cross(a[i]) + I * al[i] + w[i].cross(pa) + v[i].cross(pl);
    }
    // Backward pass: each body's force onto its parent; a joint's torque is the axis component.
    for (int i = nb - 1; i >= 0; --i) {
        const int j = c_.joint_index[i], p = c_.parent[i];
        if (c_.joint_type[i] == JointType::kRevolute) tau[j] = c_.axis[i].dot(n[i]);
        else if (c_.joint_type[i] == JointType::kPrismatic) tau[j] = c_.axis[i].dot(f[i]);
        if (i == c_.sensor_body) {
            sensor_force.head<3>() = f[i];
            sensor_force.tail<3>() = n[i];
        }
        if (p >= 0) {
            const Vec3 fp = R[i] * f[i];
            f[p] += fp;
            n[p].noalias() += R[i] * n[i];
            n[p] += r[i].cross(fp);
        }
    }
}

void Core::predict(const VecJ& q, const VecJ& dq, const VecJ& ddq, const VecO& y, Prediction& out) const noexcept {
    Vec6 fs;
    out.tau.setZero();
    rnea(q, dq, ddq, out.tau, fs);
    // The sensor reports the wrench the distal sub-body exerts on the proximal one: minus the force it receives.
    out.y_hat.head<6>() = c_.ft_offset - fs;
    const int nj = c_.n_joints;
    VecJ load = out.tau;  // τ + τ_f
    for (int j = 0; j < nj; ++j) {
        const double jf[4] = {c_.joint_friction(j, 0), c_.joint_friction(j, 1), c_.joint_friction(j, 2),
                              c_.joint_friction(j, 3)};
        load[j] += friction(dq[j], jf);
    }
    // Effects of an augmented model (dynid.robot.effects.joint_torques): extra joint torques.
    for (int k = 0; k < c_.n_effects; ++k) {
        const int j = c_.effect_joint[k];
        const auto& p = c_.effect_param[k];
        if (c_.effect_kind[k] == EffectKind::kStribeck) {
            const double x = dq[j] / p[1];
            const double s = dq[j] > 0 ? 1.0 : (dq[j] < 0 ? -1.0 : 0.0);
            load[j] += p[0] * s * std::exp(-x * x);
        } else {
            load[j] += p[0] * (q[j] - p[1]);
        }
    }
    out.t2 = out.t2_ft = 0;
    for (int i = 0; i < c_.n_outputs; ++i) {
        out.active[i] = true;
        if (i >= 6) {
            double s = 0;
            for (int j = 0; j < nj; ++j) s += c_.row_map(i, j) * load[j];
            const int m = c_.channel_motor[i];
            if (m >= 0 && c_.motor_friction_on[m]) {
                double vm = 0;
                for (int j = 0; j < nj; ++j) vm += c_.motor_velocity(m, j) * dq[j];
                const double mf[4] = {c_.motor_friction(m, 0), c_.motor_friction(m, 1), c_.motor_friction(m, 2),
                                      c_.motor_friction(m, 3)};
                s += friction(vm, mf);
            }
            out.y_model[i] = s / c_.divisor[i];
            out.y_hat[i] = ratio_[i] * out.y_model[i];
            // Gate: a channel whose joints or motors rest carries static friction the model lacks.
            for (int j = 0; j < nj; ++j)
                if ((c_.gate_joints[i] >> j & 1u) && std::abs(dq[j]) < c_.min_speed) out.active[i] = false;
            for (int k = 0; k < c_.n_motors; ++k) {
                if (!(c_.gate_motors[i] >> k & 1u)) continue;
                double vm = 0;
                for (int j = 0; j < nj; ++j) vm += c_.motor_velocity(k, j) * dq[j];
                if (std::abs(vm) < c_.min_speed) out.active[i] = false;
            }
        } else {
            out.y_model[i] = out.y_hat[i];  // the F/T wrench
        }
        out.e[i] = y[i] - out.y_hat[i];
        const double z = out.e[i] * out.e[i] / c_.variance[i];
        if (out.active[i]) out.t2 += z;
        if (i < 6) out.t2_ft += z;
    }
}

const Output& Core::step(const double* q, const double* y) noexcept {
    const int W = c_.window, nj = c_.n_joints, no = c_.n_outputs;
    for (int k = 0; k < nj; ++k) ring_(k, slot_) = ring_(k, slot_ + W) = q[k];
    for (int k = 0; k < no; ++k) ring_(nj + k, slot_) = ring_(nj + k, slot_ + W) = y[k];
    slot_ = slot_ + 1 == W ? 0 : slot_ + 1;
    ++count_;
    out_.event = Event::kNone;
    if (count_ < W) {
        out_.ready = false;
        return out_;
    }
    // The window, oldest first, is columns slot_ … slot_ + W − 1: the same summation order as dynid.detect.online.
    out_.q.setZero(); out_.dq.setZero(); out_.ddq.setZero(); out_.y.setZero();
    for (int s = 0; s < W; ++s) {
        const double w0 = c_.filter(0, s), w1 = c_.filter(1, s), w2 = c_.filter(2, s);
        const auto col = ring_.col(slot_ + s);
        for (int k = 0; k < nj; ++k) {
            out_.q[k] += w0 * col[k];
            out_.dq[k] += w1 * col[k];
            out_.ddq[k] += w2 * col[k];
        }
        for (int k = 0; k < no; ++k) out_.y[k] += w0 * col[nj + k];
    }
    out_.ready = true;
    predict(out_.q, out_.dq, out_.ddq, out_.y, out_.p);
    detect();
    track_supply();  // after this sample's residual: the sample never explains itself
    return out_;
}

void Core::track_supply() noexcept {
    // dynid.identify.supply.SupplyTracker, term for term: only moving rows (in T²) whose residual is inside the gate.
    if (c_.supply_time_constant <= 0) return;
    const double a = 1.0 - lambda_;
    for (int i = 0; i < c_.n_outputs; ++i) {
        if (c_.channel_kind[i] != ChannelKind::kInput || !out_.p.active[i]) continue;
        if (!(std::abs(out_.p.e[i]) <= c_.supply_gate[i])) continue;  // outside the gate, or not a number
        const double p = out_.p.y_model[i], y = out_.y[i];
        num_[i] = lambda_ * num_[i] + a * p * y;
        den_[i] = lambda_ * den_[i] + a * p * p;
        ratio_[i] = (num_[i] + c_.supply_prior) / (den_[i] + c_.supply_prior);
    }
}

void Core::detect() noexcept {
    const double t2 = out_.p.t2;
    out_.above = t2 > c_.threshold;
    out_.wrench = out_.p.e.head<6>();
    out_.side = !out_.above ? Side::kNone : (out_.p.t2_ft > c_.ft_threshold ? Side::kDistal : Side::kProximal);
    if (!out_.in_contact) {
        above_run_ = out_.above ? above_run_ + 1 : 0;
        if (above_run_ >= det_.debounce_on) {
            out_.in_contact = true;
            out_.event = Event::kOnset;
            below_run_ = 0;
        }
    } else {
        below_run_ = t2 < det_.hysteresis * c_.threshold ? below_run_ + 1 : 0;
        if (below_run_ >= det_.debounce_off) {
            out_.in_contact = false;
            out_.event = Event::kEnd;
            above_run_ = 0;
        }
    }
}

}  // namespace dynid::rt
