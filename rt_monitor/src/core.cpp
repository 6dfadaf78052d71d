#include "rt_monitor/core.hpp"

#include "rt_monitor/kinematics.hpp"
#include "rt_monitor/multiversion.hpp"
#include "vector4.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace dynid::rt {
namespace {

// Spatial vectors are (linear, angular), as Pinocchio's, split into two 3-vectors.

// A velocity this close to zero is zero for the sign of Coulomb friction: the filter's estimate at rest is ±1e-15 or
// 0 by the order of its sum (dynid.robot.regressors.friction.VELOCITY_FLOOR).
constexpr double kVelocityFloor = 1e-9;

inline double friction(double v, const double* c) noexcept {
    // τ_f = fc⁺·[v>0] − fc⁻·[v<0] + fv⁺·max(v,0) + fv⁻·min(v,0)  (dynid.robot.regressors.friction)
    return (v > 0 ? (v > kVelocityFloor ? c[0] : 0.0) + c[2] * v : 0.0) +
           (v < 0 ? (v < -kVelocityFloor ? -c[1] : 0.0) + c[3] * v : 0.0);
}

// The observer's friction: the law where the coordinate moves; at rest (|v| < min_speed) its viscous part only,
// Coulomb friction being the band (dynid.detect.momentum).
template <class Row>
inline double observed_friction(double v, const Row& row, double min_speed) noexcept {
    const double c[4] = {row(0), row(1), row(2), row(3)};
    if (std::abs(v) >= min_speed) return friction(v, c);
    return (v > 0 ? c[2] * v : 0.0) + (v < 0 ? c[3] * v : 0.0);
}

// The fixed-lag filter over a window: for each of `channels` channels, o_r[k] = Σ_s w_r[s]·x_s[k] for the weight
// columns w_r given (w1, w2 null: the value only), x_s the window's sample s (a row, the channels contiguous). The hot
// loop of a long window (the Panda's 151 samples: 7 joints' three estimates and 7 torques, 4 200 multiply-adds a
// sample). Four channels at a time in one vector, so no sum needs a horizontal reduction; each sum in two chains side
// by side (the window's halves, then added), and the value-only filter two blocks of channels at once, so the
// additions' latency overlaps. The channels are taken in blocks of 4: a row is read up to `channels` rounded up to 4
// (the ring's rows are padded for it); only the first `channels` outputs are written.
RT_MULTIVERSION
void filter_window(const double* x, int stride, int channels, int W, const double* w0, const double* w1,
                   const double* w2, double* o0, double* o1, double* o2) noexcept {
    const int h = W / 2, odd = W % 2;  // chain a: samples 0..h−1; chain b: h..2h−1, then the last when W is odd
    const auto row = [&](int s) { return x + size_t(s) * size_t(stride); };
    V4 u, v, u2, v2;
    if (w1 == nullptr) {
        int k = 0;
        for (; k + kPad < channels; k += 2 * kPad) {  // two blocks: channels k..k+3 in a, b; k+4..k+7 in c, d
            V4 a = {}, b = {}, c = {}, d = {};
            for (int s = 0; s < h; ++s) {
                load(u, row(s) + k), load(v, row(h + s) + k);
                load(u2, row(s) + k + kPad), load(v2, row(h + s) + k + kPad);
                a += w0[s] * u, b += w0[h + s] * v;
                c += w0[s] * u2, d += w0[h + s] * v2;
            }
            if (odd) {
                load(v, row(W - 1) + k), load(v2, row(W - 1) + k + kPad);
                b += w0[W - 1] * v, d += w0[W - 1] * v2;
            }
            a += b, c += d;
            store(a, o0 + k, kPad);
            store(c, o0 + k + kPad, std::min(kPad, channels - k - kPad));
        }
        if (k < channels) {  // the last block alone
            V4 a = {}, b = {};
            for (int s = 0; s < h; ++s) {
                load(u, row(s) + k), load(v, row(h + s) + k);
                a += w0[s] * u, b += w0[h + s] * v;
            }
            if (odd) load(v, row(W - 1) + k), b += w0[W - 1] * v;
            a += b;
            store(a, o0 + k, channels - k);
        }
        return;
    }
    for (int k = 0; k < channels; k += kPad) {
        V4 a0 = {}, b0 = {}, a1 = {}, b1 = {}, a2 = {}, b2 = {};
        for (int s = 0; s < h; ++s) {
            load(u, row(s) + k), load(v, row(h + s) + k);
            a0 += w0[s] * u, b0 += w0[h + s] * v;
            a1 += w1[s] * u, b1 += w1[h + s] * v;
            a2 += w2[s] * u, b2 += w2[h + s] * v;
        }
        if (odd) {
            load(v, row(W - 1) + k);
            b0 += w0[W - 1] * v, b1 += w1[W - 1] * v, b2 += w2[W - 1] * v;
        }
        const int n = std::min(kPad, channels - k);
        a0 += b0, a1 += b1, a2 += b2;
        store(a0, o0 + k, n), store(a1, o1 + k, n), store(a2, o2 + k, n);
    }
}

}  // namespace

Core::Core(const Coefficients& c) noexcept : c_(c) {
    det_.debounce_on = c.debounce_on;
    det_.debounce_off = c.debounce_off;
    det_.hysteresis = c.hysteresis;
    width_ = c.n_joints + c.n_outputs;
    stride_ = padded(width_ + kPad - 1);  // the filter reads the y block up to n_joints + padded(n_outputs)
    if (c.supply_time_constant > 0) lambda_ = std::exp(-c.sample_period / c.supply_time_constant);
    if (c.has_observer()) decay_ = std::exp(-2.0 * M_PI * c.observer_bandwidth * c.sample_period);
    for (int i = 0; i < c.n_outputs; ++i) {  // a product per channel and sample, not a division
        inverse_variance_[i] = 1.0 / c.variance[i];
        inverse_observer_variance_[i] = 1.0 / c.observer_variance[i];
    }
    for (int j = 0; j < c.n_joints; ++j) {
        accel_isolation_[j] = c.accel_tau_variance[j] > 0 ? c.isolation_sigmas * std::sqrt(c.accel_tau_variance[j]) : -1;
        observer_isolation_[j] = c.tau_variance[j] > 0 ? c.isolation_sigmas * std::sqrt(c.tau_variance[j]) : -1;
    }
    // The derivative filter as sliding moments where that takes fewer operations than the convolution: a block of
    // 4 channels slides in M(M − 1)/2 + 3M vector operations and gives an estimate in M more (M moments: the fit's
    // order + 1), where the convolution takes W per estimate. So the joints (three estimates) from a handful of
    // taps, the outputs (the value only) from a longer window.
    if (moments_.configure(c.filter.data(), kMaxWindow, 3, c.window, c.order)) {
        const int M = c.order + 1, slide = M * (M - 1) / 2 + 3 * M;
        if (slide + 3 * M < 3 * c.window) sliding_channels_ = c.n_joints;
        if (sliding_channels_ > 0 && slide + M < c.window) sliding_channels_ = width_;
    }
    row_map_.assign(c.row_map, c.n_outputs, c.n_joints);
    tau_map_.assign(c.tau_map.transpose(), c.n_outputs, c.n_joints);
    ratio_.fill(1.0);  // stays 1 on every channel but the tracked motor inputs
    obs_ratio_.fill(1.0);
    residual_ = c.residual;
    if ((residual_ == Residual::kMomentum && !c.has_observer()) || (residual_ == Residual::kCombined && !c.has_combined()))
        residual_ = Residual::kAcceleration;  // the loader refuses such a file; a core built on one runs what it can
    reset();
}

void Core::reset() noexcept {
    ring_.fill(0.0);
    moments_.reset();
    slot_ = 0;
    count_ = 0;
    above_run_ = below_run_ = 0;
    window_ = residual_ == Residual::kMomentum   ? c_.velocity_window
              : residual_ == Residual::kCombined ? std::max(c_.window, c_.velocity_window)
                                                 : c_.window;
    ring_rows_ = window_ + 1;  // one more: the sample leaving the filter's window is still there for the moments
    observing_ = false;
    observer_all_rest_ = false;
    r_.setZero();
    inputs_.setZero();
    out_ = Output{};
    acc_ = Output{};
}

bool Core::set_residual(Residual r) noexcept {
    if (r == Residual::kMomentum && !c_.has_observer()) return false;
    if (r == Residual::kCombined && !c_.has_combined()) return false;
    residual_ = r;
    reset();
    return true;
}

RT_MULTIVERSION
void Core::rnea(const VecJ& q, const VecJ& dq, const VecJ& ddq, VecJ& tau,
                std::array<Vec6, kMaxSensors>& sensor_force) const noexcept {
    // Forward pass: body velocities and accelerations in body frames; the base accelerates at −g.
    std::array<Mat3, kMaxBodies> R;  // orientation of body i in its parent (parent-from-child)
    std::array<Vec3, kMaxBodies> r, v, w, a, al, f, n;
    const int nb = c_.n_bodies;
    for (int i = 0; i < nb; ++i) {
        const int j = c_.joint_index[i], p = c_.parent[i];
        const Vec3& ax = c_.axis[i];
        joint_placement(c_, i, q.data(), R[i], r[i]);
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
        if (const int s = c_.sensor_of_body[i]; s >= 0) {
            sensor_force[s].head<3>() = f[i];
            sensor_force[s].tail<3>() = n[i];
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
    std::array<Vec6, kMaxSensors> fs;
    out.tau.head(c_.n_joints).setZero();
    rnea(q, dq, ddq, out.tau, fs);
    // A sensor reports the wrench its distal sub-body exerts on the proximal one: minus the force that receives.
    for (int k = 0; k < c_.n_sensors; ++k) out.y_hat.segment<6>(6 * k) = c_.ft_offset[k] - fs[k];
    const int nj = c_.n_joints, nft = c_.n_ft();
    VecJ load;  // τ + τ_f
    load.head(nj) = out.tau.head(nj);
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
            const double s = dq[j] > kVelocityFloor ? 1.0 : (dq[j] < -kVelocityFloor ? -1.0 : 0.0);
            load[j] += p[0] * s * std::exp(-x * x);
        } else {
            load[j] += p[0] * (q[j] - p[1]);
        }
    }
    // The coordinates at rest, as bits: joints (|q̇| < min_speed) and motors (|q̇_m| < min_speed, q̇_m = T q̇).
    uint64_t joints_resting = 0, motors_resting = 0;
    for (int j = 0; j < nj; ++j)
        if (std::abs(dq[j]) < c_.min_speed) joints_resting |= uint64_t(1) << j;
    std::array<double, kMaxMotors> vm;
    for (int k = 0; k < c_.n_motors; ++k) {
        vm[k] = 0;
        for (int j = 0; j < nj; ++j) vm[k] += c_.motor_velocity(k, j) * dq[j];
        if (std::abs(vm[k]) < c_.min_speed) motors_resting |= uint64_t(1) << k;
    }
    out.t2 = 0;
    out.t2_sensor.fill(0.0);
    for (int i = 0; i < c_.n_outputs; ++i) {
        out.active[i] = true;
        if (i >= nft) {
            double s = row_map_.dot(i, load.data());
            const int m = c_.channel_motor[i];
            if (m >= 0 && c_.motor_friction_on[m]) {
                const double mf[4] = {c_.motor_friction(m, 0), c_.motor_friction(m, 1), c_.motor_friction(m, 2),
                                      c_.motor_friction(m, 3)};
                s += friction(vm[m], mf);
            }
            out.y_model[i] = s / c_.divisor[i];
            out.y_hat[i] = ratio_[i] * out.y_model[i];
            // Gate: a channel whose joints or motors rest carries static friction the model lacks.
            out.active[i] = !(c_.gate_joints[i] & joints_resting) && !(c_.gate_motors[i] & motors_resting);
        } else {
            out.y_model[i] = out.y_hat[i];  // the F/T wrench
        }
        out.e[i] = y[i] - out.y_hat[i];
        const double z = out.e[i] * out.e[i] * inverse_variance_[i];
        if (out.active[i]) out.t2 += z;
        if (i < nft) out.t2_sensor[i / 6] += z;
    }
}

const Output& Core::step(const double* q, const double* dq, const double* y) noexcept {
    const int W = window_, R = ring_rows_, nj = c_.n_joints, no = c_.n_outputs;
    double *a = row(slot_), *b = row(slot_ + R);
    for (int k = 0; k < nj; ++k) a[k] = b[k] = q[k];
    for (int k = 0; k < no; ++k) a[nj + k] = b[nj + k] = y[k];
    slot_ = slot_ + 1 == R ? 0 : slot_ + 1;
    ++count_;
    if (sliding_channels_ > 0 && residual_ != Residual::kMomentum)
        moments_.push(newest(c_.window + 1), a, padded(sliding_channels_) / kPad);
    out_.event = Event::kNone;
    if (residual_ == Residual::kCombined) {
        combine(q, dq, y);
        return out_;
    }
    if (count_ < W) {
        out_.ready = false;
        return out_;
    }
    out_.ready = true;
    if (residual_ == Residual::kAcceleration) {
        accelerate(out_);
        out_.t2_alpha = c_.threshold;
        detect(c_.threshold, c_.ft_threshold);
        track_supply(out_);  // after this sample's residual: the sample never explains itself
    } else if (residual_ == Residual::kMomentum) {
        out_.t2_alpha = observe(q, dq, y);
        detect(out_.t2_alpha, c_.observer_ft_threshold);
    }
    return out_;
}

void Core::combine(const double* q, const double* dq, const double* y) noexcept {
    // Both residuals, each from its own window's start (as each alone would run: the observer from the sample its q̇
    // window fills, the filter from the sample its window fills), then s = (T²_o/T²_o,α + T²/T²_α)/κ on the
    // samples where both have run, T²_o/T²_o,α alone where every row rests (dynid.detect.combined, its monitor
    // pairing).
    double observer_threshold = 0;
    if (count_ >= c_.velocity_window) observer_threshold = observe(q, dq, y);
    if (count_ >= c_.window) {
        accelerate(acc_);
        track_supply(acc_);
    }
    out_.ready = count_ >= window_;
    if (!out_.ready) return;
    out_.observer_ratio = out_.p.t2 / observer_threshold;
    out_.acceleration_ratio = acc_.p.t2 / c_.threshold;
    // Where every row rests the observer's own test (its rest threshold) alone: κ is the sum's level where a row moves
    out_.p.t2 = observer_all_rest_ ? out_.observer_ratio
                                   : (out_.observer_ratio + out_.acceleration_ratio) / c_.combined_scale;
    out_.t2_alpha = 1.0;
    detect(1.0, c_.observer_ft_threshold);
}

void Core::accelerate(Output& o) noexcept {
    const int W = c_.window, nj = c_.n_joints, no = c_.n_outputs;
    // The window, oldest first: the joints' value, slope and curvature in one pass over its rows, then the outputs'.
    const double* window = newest(W);
    const double* w = c_.filter.data();  // columns: value, slope, curvature
    if (sliding_channels_ >= nj) {
        moments_.estimate(0, 0, nj, o.q.data());
        moments_.estimate(1, 0, nj, o.dq.data());
        moments_.estimate(2, 0, nj, o.ddq.data());
    } else {
        filter_window(window, stride_, nj, W, w, w + kMaxWindow, w + 2 * kMaxWindow, o.q.data(), o.dq.data(),
                      o.ddq.data());
    }
    if (sliding_channels_ == width_) moments_.estimate(0, nj, no, o.y.data());
    else filter_window(window + nj, stride_, no, W, w, nullptr, nullptr, o.y.data(), nullptr, nullptr);
    predict(o.q, o.dq, o.ddq, o.y, o.p);
    if (&o != &out_) return;  // the combined detector's acceleration half: its wrench and τ_ext are the observer's
    for (int k = 0; k < c_.n_sensors; ++k) o.wrench[k] = o.p.e.segment<6>(6 * k);
    // Each row's residual as a torque on it, τ_ext = tau_map · (divisor ⊙ e), over the rows in T² (a row at rest
    // carries the static friction the model lacks)
    VecO rows;
    for (int i = 0; i < c_.n_outputs; ++i) rows[i] = i >= c_.n_ft() && o.p.active[i] ? c_.divisor[i] * o.p.e[i] : 0.0;
    isolate(o, rows, accel_isolation_);
}

double Core::observe(const double* q, const double* measured_dq, const double* y) noexcept {
    // dynid.detect.momentum term for term: r = low-pass of τ_meas − τ_model with τ_model = ṗ − β (no q̈), on the raw
    // q and the robot's measured q̇ or the causal estimate; ṗ is the difference of p over the step (0 on the
    // observer's first sample).
    const int W = c_.velocity_window, nj = c_.n_joints, no = c_.n_outputs, nft = c_.n_ft();
    const double T = c_.sample_period, ms = c_.min_speed;
    if (measured_dq != nullptr && c_.measured_velocity)
        for (int k = 0; k < nj; ++k) out_.dq[k] = measured_dq[k];
    else
        filter_window(newest(W), stride_, nj, W, c_.velocity_filter.data(), nullptr, nullptr,
                      out_.dq.data(), nullptr, nullptr);
    for (int k = 0; k < nj; ++k) out_.q[k] = q[k];
    for (int k = 0; k < no; ++k) out_.y[k] = y[k];
    out_.ddq.head(nj).setZero();
    const VecJ& dq = out_.dq;
    momentum_terms(c_, q, dq.data(), terms_);
    // Sized to the robot, not the capacity: a full-capacity copy or clear is most of a small robot's step.
    const int ns = c_.n_sensors;
    VecJ x_joint;  // β − ṗ: minus the model's torque, per joint
    x_joint.head(nj) = terms_.beta.head(nj);
    std::array<Vec6, kMaxSensors> x_sensor;
    for (int k = 0; k < ns; ++k) x_sensor[k] = terms_.beta_sensor[k];
    if (observing_) {
        x_joint.head(nj) -= (terms_.p.head(nj) - p_prev_.head(nj)) / T;
        for (int k = 0; k < ns; ++k) x_sensor[k] -= (terms_.p_sensor[k] - ps_prev_[k]) / T;
    }
    observing_ = true;
    p_prev_.head(nj) = terms_.p.head(nj);
    for (int k = 0; k < ns; ++k) ps_prev_[k] = terms_.p_sensor[k];
    for (int j = 0; j < nj; ++j) x_joint[j] -= observed_friction(dq[j], c_.joint_friction.row(j), ms);
    // q̇_m = T q̇ once per sample, and the coordinates at rest as bits (not |v| ≥ min_speed: a NaN rests, as in
    // dynid.detect.momentum)
    std::array<double, kMaxMotors> vm;
    uint64_t joints_resting = 0, motors_resting = 0;
    for (int j = 0; j < nj; ++j)
        if (!(std::abs(dq[j]) >= ms)) joints_resting |= uint64_t(1) << j;
    for (int k = 0; k < c_.n_motors; ++k) {
        vm[k] = c_.motor_velocity.row(k).head(nj).dot(dq.head(nj));
        if (!(std::abs(vm[k]) >= ms)) motors_resting |= uint64_t(1) << k;
    }
    VecO x, lo, hi;
    std::array<bool, kMaxOutputs> rest;
    bool all_rest = true;
    for (int i = 0; i < no; ++i) {
        lo[i] = hi[i] = 0;
        rest[i] = false;
        if (i < nft) {  // a sensor's coordinate: τ_meas = −(w − w_O), its row w − ŵ = −(τ_meas − τ_model)
            x[i] = (y[i] - c_.ft_offset[i / 6][i % 6]) - x_sensor[i / 6][i % 6];
            all_rest = false;
            continue;
        }
        double s = c_.divisor[i] * y[i];  // the motors' (or a torque sensor's) torque on this row
        s = row_map_.dot(i, x_joint.data(), s);
        const int m = c_.channel_motor[i];
        if (m >= 0 && c_.motor_friction_on[m]) s -= observed_friction(vm[m], c_.motor_friction.row(m), ms);
        x[i] = s;
        // The static-friction band of every resting coordinate on this row.
        for (uint64_t bits = c_.gate_joints[i] & joints_resting; bits != 0; bits &= bits - 1) {
            const int j = __builtin_ctzll(bits);
            rest[i] = true;
            const double a = c_.row_map(i, j) * c_.joint_band(j, 0), b = -c_.row_map(i, j) * c_.joint_band(j, 1);
            lo[i] += std::min(a, b);
            hi[i] += std::max(a, b);
        }
        for (uint64_t bits = c_.gate_motors[i] & motors_resting; bits != 0; bits &= bits - 1) {
            const int k = __builtin_ctzll(bits);
            rest[i] = true;
            lo[i] -= c_.motor_band(k, 1);
            hi[i] += c_.motor_band(k, 0);
        }
        all_rest = all_rest && rest[i];
    }
    const double a = decay_;
    r_.head(no) = a * r_.head(no) + (1.0 - a) * x.head(no);
    out_.r.head(no) = r_.head(no);
    if (c_.supply_time_constant > 0) {  // the supply tracker on the low-passed inputs (dynid.detect.momentum._tracked)
        for (int i = 0; i < no; ++i) {
            if (!(c_.supply_gate[i] > 0)) continue;
            inputs_[i] = a * inputs_[i] + (1.0 - a) * y[i];
            const double g = c_.divisor[i], u = inputs_[i];
            const double predicted = u - r_[i] / g, residual = u - obs_ratio_[i] * predicted;
            out_.r[i] = residual * g;
            if (!rest[i] && std::abs(residual) <= c_.supply_gate[i]) {
                obs_num_[i] = lambda_ * obs_num_[i] + (1.0 - lambda_) * predicted * u;
                obs_den_[i] = lambda_ * obs_den_[i] + (1.0 - lambda_) * predicted * predicted;
                obs_ratio_[i] = (obs_num_[i] + c_.supply_prior) / (obs_den_[i] + c_.supply_prior);
            }
        }
    }
    Prediction& p = out_.p;
    p.t2 = 0;
    p.t2_sensor.fill(0.0);
    for (int i = 0; i < no; ++i) {
        const double ri = out_.r[i];
        p.e[i] = rest[i] ? ri - std::clamp(ri, lo[i], hi[i]) : ri;  // at rest: the distance outside the band
        p.active[i] = true;
        p.y_model[i] = p.y_hat[i] = 0;
        const double z = p.e[i] * p.e[i] * inverse_observer_variance_[i];
        p.t2 += z;
        if (i < nft) p.t2_sensor[i / 6] += z;
    }
    isolate(out_, out_.r, observer_isolation_);
    for (int k = 0; k < c_.n_sensors; ++k) out_.wrench[k] = out_.r.segment<6>(6 * k);
    observer_all_rest_ = all_rest;
    return all_rest ? c_.observer_rest_threshold : c_.observer_threshold;
}

void Core::isolate(Output& o, const VecO& rows, const std::array<double, kMaxJoints>& level) noexcept {
    const int nj = c_.n_joints, no = c_.n_outputs;
    // Over the map's nonzeros: Eigen's dense product of these run-time sizes goes through its general matrix-vector
    // kernel, whose set-up costs more than the robot's few dozen multiply-adds.
    o.tau_ext.head(nj).setZero();
    for (int i = 0; i < no; ++i) tau_map_.axpy(i, rows[i], o.tau_ext.data());
    o.joint = -1;
    for (int j = nj - 1; j >= 0 && o.joint < 0; --j)
        if (level[j] >= 0 && std::abs(o.tau_ext[j]) > level[j]) o.joint = j;
}

void Core::track_supply(const Output& o) noexcept {
    // dynid.identify.supply.SupplyTracker, term for term: only moving rows (in T²) whose residual is inside the gate.
    if (c_.supply_time_constant <= 0) return;
    const double a = 1.0 - lambda_;
    for (int i = 0; i < c_.n_outputs; ++i) {
        if (c_.channel_kind[i] != ChannelKind::kInput || !o.p.active[i]) continue;
        if (!(std::abs(o.p.e[i]) <= c_.supply_gate[i])) continue;  // outside the gate, or not a number
        const double p = o.p.y_model[i], y = o.y[i];
        num_[i] = lambda_ * num_[i] + a * p * y;
        den_[i] = lambda_ * den_[i] + a * p * p;
        ratio_[i] = (num_[i] + c_.supply_prior) / (den_[i] + c_.supply_prior);
    }
}

void Core::detect(double threshold, const std::array<double, kMaxSensors>& ft_threshold) noexcept {
    const double t2 = out_.p.t2;
    out_.above = t2 > threshold;
    for (int k = 0; k < c_.n_sensors; ++k)
        out_.side[k] = !out_.above ? Side::kNone : (out_.p.t2_sensor[k] > ft_threshold[k] ? Side::kDistal : Side::kProximal);
    if (!out_.in_contact) {
        above_run_ = out_.above ? above_run_ + 1 : 0;
        if (above_run_ >= det_.debounce_on) {
            out_.in_contact = true;
            out_.event = Event::kOnset;
            below_run_ = 0;
        }
    } else {
        below_run_ = t2 < det_.hysteresis * threshold ? below_run_ + 1 : 0;
        if (below_run_ >= det_.debounce_off) {
            out_.in_contact = false;
            out_.event = Event::kEnd;
            above_run_ = 0;
        }
    }
    // Strongest against the level in force (the observer's differs at rest and in motion), as dynid detect's
    // statistic T²/T²_α is
    const double ratio = t2 / threshold;
    out_.peak_now = out_.in_contact && (out_.event == Event::kOnset || ratio > out_.peak.ratio);
    if (out_.peak_now) {  // fixed-size copies: a handful a contact, on its way up
        Output::Peak& pk = out_.peak;
        pk.t2 = t2;
        pk.ratio = ratio;
        pk.e = out_.p.e;
        pk.active = out_.p.active;
        pk.side = out_.side;
        pk.wrench = out_.wrench;
        pk.tau_ext = out_.tau_ext;
        pk.joint = out_.joint;
    }
}

}  // namespace dynid::rt
