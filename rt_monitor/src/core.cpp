#include "rt_monitor/core.hpp"

#include "rt_monitor/kinematics.hpp"

#include <algorithm>
#include <cmath>

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

// The fixed-lag filter over a window: for each of `channels` contiguous columns x (length W, `stride` apart),
// o_r = Σ_s w_r[s]·x[s] for the weight columns w_r given (w1, w2 null: the value only), the three in one pass over
// the column. The hot loop of a long window (151 samples at 500 Hz is 3 600 multiply-adds a sample). A plain running
// sum may not be reordered, so the compiler cannot vectorise it: `omp simd` allows that without -ffast-math, and the
// window's two halves are summed apart, two chains of additions side by side. Built twice, for x86-64-v3 (AVX2, FMA)
// and the baseline, the loader picking the one this CPU runs (GCC's function multi-versioning); the two round
// differently in the last bits (FMA), as two CPUs' BLAS do. Panda's 151-sample core: 1.03 → 0.85 µs (rt_bench).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#define RT_MULTIVERSION __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define RT_MULTIVERSION
#endif
#if defined(__GNUC__) && !defined(__clang__)  // GCC, with -fopenmp-simd (CMakeLists.txt); clang keeps plain loops
#define RT_SIMD_SUMS(...) _Pragma(RT_STRINGIFY(omp simd reduction(+ : __VA_ARGS__)))
#define RT_STRINGIFY(x) #x
#else
#define RT_SIMD_SUMS(...)
#endif

RT_MULTIVERSION
void filter_window(const double* x, int stride, int channels, int W, const double* w0, const double* w1,
                   const double* w2, double* o0, double* o1, double* o2) noexcept {
    const int h = W / 2;  // the second half starts at h (one more sample when W is odd: the last, added alone)
    for (int k = 0; k < channels; ++k) {
        const double* c = x + size_t(k) * size_t(stride);
        double a0 = 0, b0 = 0;
        if (w1 == nullptr) {
            RT_SIMD_SUMS(a0, b0)
            for (int i = 0; i < h; ++i) {
                a0 += c[i] * w0[i];
                b0 += c[h + i] * w0[h + i];
            }
        } else {
            double a1 = 0, b1 = 0, a2 = 0, b2 = 0;
            RT_SIMD_SUMS(a0, b0, a1, b1, a2, b2)
            for (int i = 0; i < h; ++i) {
                a0 += c[i] * w0[i];
                b0 += c[h + i] * w0[h + i];
                a1 += c[i] * w1[i];
                b1 += c[h + i] * w1[h + i];
                a2 += c[i] * w2[i];
                b2 += c[h + i] * w2[h + i];
            }
            if (W % 2 != 0) b1 += c[W - 1] * w1[W - 1], b2 += c[W - 1] * w2[W - 1];
            o1[k] = a1 + b1, o2[k] = a2 + b2;
        }
        if (W % 2 != 0) b0 += c[W - 1] * w0[W - 1];
        o0[k] = a0 + b0;
    }
}

}  // namespace

Core::Core(const Coefficients& c) noexcept : c_(c) {
    det_.debounce_on = c.debounce_on;
    det_.debounce_off = c.debounce_off;
    det_.hysteresis = c.hysteresis;
    width_ = c.n_joints + c.n_outputs;
    if (c.supply_time_constant > 0) lambda_ = std::exp(-c.sample_period / c.supply_time_constant);
    if (c.has_observer()) decay_ = std::exp(-2.0 * M_PI * c.observer_bandwidth * c.sample_period);
    ratio_.fill(1.0);  // stays 1 on every channel but the tracked motor inputs
    obs_ratio_.fill(1.0);
    residual_ = c.residual;
    if ((residual_ == Residual::kMomentum && !c.has_observer()) || (residual_ == Residual::kCombined && !c.has_combined()))
        residual_ = Residual::kAcceleration;  // the loader refuses such a file; a core built on one runs what it can
    reset();
}

void Core::reset() noexcept {
    ring_.setZero();
    slot_ = 0;
    count_ = 0;
    above_run_ = below_run_ = 0;
    window_ = residual_ == Residual::kMomentum   ? c_.velocity_window
              : residual_ == Residual::kCombined ? std::max(c_.window, c_.velocity_window)
                                                 : c_.window;
    observing_ = false;
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
    out.tau.setZero();
    rnea(q, dq, ddq, out.tau, fs);
    // A sensor reports the wrench its distal sub-body exerts on the proximal one: minus the force that receives.
    for (int k = 0; k < c_.n_sensors; ++k) out.y_hat.segment<6>(6 * k) = c_.ft_offset[k] - fs[k];
    const int nj = c_.n_joints, nft = c_.n_ft();
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
            const double s = dq[j] > kVelocityFloor ? 1.0 : (dq[j] < -kVelocityFloor ? -1.0 : 0.0);
            load[j] += p[0] * s * std::exp(-x * x);
        } else {
            load[j] += p[0] * (q[j] - p[1]);
        }
    }
    out.t2 = 0;
    out.t2_sensor.fill(0.0);
    for (int i = 0; i < c_.n_outputs; ++i) {
        out.active[i] = true;
        if (i >= nft) {
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
        if (i < nft) out.t2_sensor[i / 6] += z;
    }
}

const Output& Core::step(const double* q, const double* dq, const double* y) noexcept {
    const int W = window_, nj = c_.n_joints, no = c_.n_outputs;
    for (int k = 0; k < nj; ++k) ring_(slot_, k) = ring_(slot_ + W, k) = q[k];
    for (int k = 0; k < no; ++k) ring_(slot_, nj + k) = ring_(slot_ + W, nj + k) = y[k];
    slot_ = slot_ + 1 == W ? 0 : slot_ + 1;
    ++count_;
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
    // samples where both have run (dynid.detect.combined, its monitor pairing).
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
    out_.p.t2 = (out_.observer_ratio + out_.acceleration_ratio) / c_.combined_scale;
    out_.t2_alpha = 1.0;
    detect(1.0, c_.observer_ft_threshold);
}

void Core::accelerate(Output& o) noexcept {
    const int W = c_.window, nj = c_.n_joints, no = c_.n_outputs;
    // The window, oldest first: each estimate is a dot product over a channel's contiguous column, the three weights
    // of a joint in one pass over it.
    const double* window = newest(W);
    const int stride = int(ring_.outerStride());
    const double* w = c_.filter.data();  // columns: value, slope, curvature
    filter_window(window, stride, nj, W, w, w + kMaxWindow, w + 2 * kMaxWindow, o.q.data(), o.dq.data(),
                  o.ddq.data());
    filter_window(window + size_t(nj) * size_t(stride), stride, no, W, w, nullptr, nullptr, o.y.data(), nullptr,
                  nullptr);
    predict(o.q, o.dq, o.ddq, o.y, o.p);
    for (int k = 0; k < c_.n_sensors; ++k) o.wrench[k] = o.p.e.segment<6>(6 * k);
    // Each row's residual as a torque on it, τ_ext = tau_map · (divisor ⊙ e), over the rows in T² (a row at rest
    // carries the static friction the model lacks)
    VecO rows = VecO::Zero();
    for (int i = c_.n_ft(); i < c_.n_outputs; ++i) rows[i] = o.p.active[i] ? c_.divisor[i] * o.p.e[i] : 0.0;
    isolate(o, rows, c_.accel_tau_variance);
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
        filter_window(newest(W), int(ring_.outerStride()), nj, W, c_.velocity_filter.data(), nullptr, nullptr,
                      out_.dq.data(), nullptr, nullptr);
    for (int k = 0; k < nj; ++k) out_.q[k] = q[k];
    for (int k = 0; k < no; ++k) out_.y[k] = y[k];
    out_.ddq.setZero();
    const VecJ& dq = out_.dq;
    momentum_terms(c_, q, dq.data(), terms_);
    VecJ x_joint = terms_.beta;  // β − ṗ: minus the model's torque, per joint
    std::array<Vec6, kMaxSensors> x_sensor = terms_.beta_sensor;
    if (observing_) {
        x_joint -= (terms_.p - p_prev_) / T;
        for (int k = 0; k < c_.n_sensors; ++k) x_sensor[k] -= (terms_.p_sensor[k] - ps_prev_[k]) / T;
    }
    observing_ = true;
    p_prev_ = terms_.p;
    ps_prev_ = terms_.p_sensor;
    for (int j = 0; j < nj; ++j) x_joint[j] -= observed_friction(dq[j], c_.joint_friction.row(j), ms);
    std::array<double, kMaxMotors> vm{};  // q̇_m = T q̇, once per sample
    for (int k = 0; k < c_.n_motors; ++k) vm[k] = c_.motor_velocity.row(k).head(nj).dot(dq.head(nj));
    VecO x = VecO::Zero(), lo = VecO::Zero(), hi = VecO::Zero();
    std::array<bool, kMaxOutputs> rest{};
    bool all_rest = true;
    for (int i = 0; i < no; ++i) {
        if (i < nft) {  // a sensor's coordinate: τ_meas = −(w − w_O), its row w − ŵ = −(τ_meas − τ_model)
            x[i] = (y[i] - c_.ft_offset[i / 6][i % 6]) - x_sensor[i / 6][i % 6];
            all_rest = false;
            continue;
        }
        double s = c_.divisor[i] * y[i];  // the motors' (or a torque sensor's) torque on this row
        for (int j = 0; j < nj; ++j) s += c_.row_map(i, j) * x_joint[j];
        const int m = c_.channel_motor[i];
        if (m >= 0 && c_.motor_friction_on[m]) s -= observed_friction(vm[m], c_.motor_friction.row(m), ms);
        x[i] = s;
        // The static-friction band of every resting coordinate on this row.
        for (int j = 0; j < nj; ++j) {
            if (!(c_.gate_joints[i] >> j & 1u) || std::abs(dq[j]) >= ms) continue;
            rest[i] = true;
            const double a = c_.row_map(i, j) * c_.joint_band(j, 0), b = -c_.row_map(i, j) * c_.joint_band(j, 1);
            lo[i] += std::min(a, b);
            hi[i] += std::max(a, b);
        }
        for (int k = 0; k < c_.n_motors; ++k) {
            if (!(c_.gate_motors[i] >> k & 1u) || std::abs(vm[k]) >= ms) continue;
            rest[i] = true;
            lo[i] -= c_.motor_band(k, 1);
            hi[i] += c_.motor_band(k, 0);
        }
        all_rest = all_rest && rest[i];
    }
    const double a = decay_;
    r_.head(no) = a * r_.head(no) + (1.0 - a) * x.head(no);
    out_.r = r_;
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
        const double z = p.e[i] * p.e[i] / c_.observer_variance[i];
        p.t2 += z;
        if (i < nft) p.t2_sensor[i / 6] += z;
    }
    isolate(out_, out_.r, c_.tau_variance);
    for (int k = 0; k < c_.n_sensors; ++k) out_.wrench[k] = out_.r.segment<6>(6 * k);
    return all_rest ? c_.observer_rest_threshold : c_.observer_threshold;
}

void Core::isolate(Output& o, const VecO& rows, const std::array<double, kMaxJoints>& variance) noexcept {
    const int nj = c_.n_joints, no = c_.n_outputs;
    o.tau_ext.head(nj).noalias() = c_.tau_map.topLeftCorner(nj, no) * rows.head(no);
    o.joint = -1;
    for (int j = nj - 1; j >= 0 && o.joint < 0; --j)
        if (variance[j] > 0 && std::abs(o.tau_ext[j]) > c_.isolation_sigmas * std::sqrt(variance[j])) o.joint = j;
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
}

}  // namespace dynid::rt
