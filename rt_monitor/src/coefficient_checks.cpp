// The coefficient file's shape, observer and plausibility checks (coefficient_checks.hpp).
#include "coefficient_checks.hpp"

#include "rt_monitor/plausibility.hpp"

#include <algorithm>
#include <sstream>

namespace dynid::rt {

// The payload's shape, walked before LCM's decoder sees it: lcm-gen's decoder sizes each array from its count field
// before it reads one element (a 4-byte count of 2³¹ − 1 asked for gigabytes) and computes a string's length minus
// one in int (undefined for a length of −2³¹). This walk reads the counts and lengths in the order of
// lcmtypes/coefficients_t.lcm, allocating nothing: a count above this build's capacity is refused as such (kCapacity,
// the loader's message), a negative count, a string length below 1 or anything running past the end as not this
// type (kDecode). The decoder then only runs on payloads whose every array fits the capacity and the bytes.
namespace {

class Shape {
public:
    Shape(const uint8_t* p, size_t n) : p_(p), n_(n) {}
    bool ok() const { return ok_; }
    size_t at() const { return at_; }
    void skip(uint64_t k) {
        if (ok_ && k <= n_ - at_) at_ += size_t(k);
        else ok_ = false;
    }
    uint64_t u64() {
        uint64_t v = 0;
        if (ok_ && n_ - at_ >= 8)
            for (int i = 0; i < 8; ++i) v = v << 8 | p_[at_ + size_t(i)];  // LCM is big-endian
        skip(8);
        return v;
    }
    int32_t i32() {
        uint32_t v = 0;
        if (ok_ && n_ - at_ >= 4)
            for (int i = 0; i < 4; ++i) v = v << 8 | p_[at_ + size_t(i)];
        skip(4);
        return int32_t(v);
    }
    void strings(int64_t count) {
        for (int64_t k = 0; k < count && ok_; ++k) {
            const int32_t len = i32();
            if (len < 1) ok_ = false;
            skip(uint64_t(len < 1 ? 0 : len));
        }
    }
    // count elements of `size` bytes; count is within the capacity here (at most 64), so no product overflows.
    void array(int64_t count, uint64_t size) { skip(uint64_t(count) * size); }
    // A count field: negative is not this type; above the capacity is refused as too many.
    bool count(int32_t& n, const char* what, int max, LoadResult& r) {
        n = i32();
        if (!ok_ || n < 0) {
            ok_ = false;
            return false;
        }
        if (n > max) {
            r = fail(LoadError::kCapacity, std::string("too many ") + what + ": " + str(n) + " (this build's capacity is " +
                                               str(max) + ")");
            return false;
        }
        return true;
    }

private:
    const uint8_t* p_;
    size_t n_, at_ = 0;
    bool ok_ = true;
};

}  // namespace

LoadResult check_shape(const uint8_t* p, size_t n) {
    const LoadResult not_this = fail(LoadError::kDecode, "payload is not a dynid.coefficients_t (fingerprint or size)");
    Shape w(p, n);
    LoadResult r;
    if (w.u64() != uint64_t(dynid::coefficients_t::getHash())) return not_this;
    w.strings(6);  // robot_name … estimator
    int32_t nj = 0, nb = 0, ns = 0, nm = 0, no = 0, win = 0, ne = 0;
    if (!w.count(nj, "joints", kMaxJoints, r)) return r ? not_this : r;
    w.strings(nj);
    w.array(int64_t(nj) * 2, 8);                    // joint_limits
    if (!w.count(nb, "bodies", kMaxBodies, r)) return r ? not_this : r;
    w.strings(nb);
    w.array(nb, 4 + 1 + 4 + 8 * (3 + 9 + 3 + 10));  // parent, joint_type, joint_index, axis, rotation, translation, φ
    w.array(3, 8);                                  // gravity
    if (!w.count(ns, "F/T sensors", kMaxSensors, r)) return r ? not_this : r;
    w.strings(ns);                                  // sensor_names
    w.array(ns, 4);                                 // sensor_body
    if (!w.count(nm, "motors", kMaxMotors, r)) return r ? not_this : r;
    w.strings(nm);
    w.array(int64_t(nm) * nj, 8);                   // motor_velocity
    w.array(nm, 1 + 8 * 4);                         // motor_friction_on, motor_friction
    w.array(nj, 8 * 4);                             // joint_friction
    if (!w.count(no, "outputs", kMaxOutputs, r)) return r ? not_this : r;
    w.strings(no);
    w.array(no, 1);                                 // channel_kind
    w.array(int64_t(ns) * 6, 8);                    // ft_offset
    w.array(int64_t(no) * nj, 8);                   // row_map
    w.array(no, 4 + 8 + 8 + 8 + 8);                 // channel_motor, divisor, residual_variance, gate_joints, gate_motors
    w.array(3, 8);                                  // min_speed, alpha, threshold
    w.array(ns, 8);                                 // ft_threshold
    w.array(nj, 8);                                 // accel_tau_variance
    w.array(1, 3 * 4 + 8 + 8);                      // calibration_samples, debounce_on/off, hysteresis, sample_period
    if (!w.count(win, "filter samples", kMaxWindow, r)) return r ? not_this : r;
    w.array(2, 4);                                  // order, lag
    w.array(int64_t(3) * win, 8);                   // filter
    if (!w.count(ne, "effects", kMaxEffects, r)) return r ? not_this : r;
    w.array(ne, 1 + 4 + 3 * 8);                     // effect_kind, effect_joint, effect_param
    w.array(2, 8);                                  // supply_time_constant, supply_prior
    w.array(no, 8);                                 // supply_gate
    int32_t vw = 0;
    w.array(1, 1 + 8);                              // residual, observer_bandwidth
    if (!w.count(vw, "velocity filter samples", kMaxWindow, r)) return r ? not_this : r;
    w.array(vw, 8);                                 // velocity_filter
    w.array(1, 1);                                  // observer_velocity
    w.array(int64_t(nj + nm) * 2, 8);               // joint_band, motor_band
    w.array(no, 8);                                 // observer_variance
    w.array(2, 8);                                  // observer_threshold, observer_rest_threshold
    w.array(ns, 8);                                 // observer_ft_threshold
    w.array(int64_t(nj) * no + nj + 1, 8);          // tau_map, tau_variance, isolation_sigmas
    w.array(1, 8);                                  // combined_scale
    int32_t nk = 0, kw = 0, kc = 0;
    if (!w.count(nk, "known-answer samples", kMaxKnown, r)) return r ? not_this : r;
    if (!w.count(kw, "known-answer channels", kMaxJoints + kMaxOutputs, r)) return r ? not_this : r;
    w.array(int64_t(nk) * kw, 8);                   // known_input
    if (!w.count(kc, "known-answer columns", 3 + 2 * kMaxSensors, r)) return r ? not_this : r;
    w.array(int64_t(nk) * kc, 8);                   // known_answer
    w.array(int64_t(nj) * 2, 8);                    // fit_range
    if (!w.ok() || w.at() != n) return not_this;
    return LoadResult{};
}

// The observer's section: absent (velocity_window 0) unless the file selects it; when present, complete and usable.
LoadResult check_observer(const dynid::coefficients_t& c) {
    auto dim = [](const std::string& m) { return fail(LoadError::kDimension, m); };
    if (c.residual != 0 && c.residual != 1 && c.residual != 2)
        return dim("unknown residual " + str(c.residual) + " (this monitor knows 0 acceleration, 1 momentum, 2 combined)");
    if (!std::isfinite(c.combined_scale)) return fail(LoadError::kNotFinite, "non-finite combined_scale");
    if (c.combined_scale < 0) return dim("combined_scale must be ≥ 0 (0: no combined detector)");
    if (c.residual == 2 && !(c.combined_scale > 0)) return dim("the file selects the combined detector but carries no combined_scale");
    if (c.observer_velocity != 0 && c.observer_velocity != 1)
        return dim("unknown observer velocity " + str(c.observer_velocity) + " (0 estimated from q, 1 measured)");
    if (c.velocity_window == 0) {
        if (c.observer_velocity != 0) return dim("a measured q̇ for the observer without an observer");
        if (c.residual == 1 || c.residual == 2)
            return dim(std::string("the file selects the ") + (c.residual == 1 ? "momentum residual" : "combined detector") +
                       " but carries no observer");
        if (c.combined_scale > 0) return dim("combined_scale without an observer");
        return LoadResult{};
    }
    if (c.residual != 0 && c.n_effects > 0) return dim("the momentum observer has no form for named effects");
    if (c.velocity_window < 3) return dim("velocity filter window " + str(c.velocity_window) + " below 3 samples");
    auto nf = [](const char* what) { return fail(LoadError::kNotFinite, std::string("non-finite value in ") + what); };
    if (!finite_all(c.velocity_filter) || !finite_all(c.observer_variance) || !finite_all(c.tau_variance))
        return nf("the momentum observer");
    for (const auto& b : c.joint_band)
        if (!finite_all(b)) return nf("the static-friction band");
    for (const auto& b : c.motor_band)
        if (!finite_all(b)) return nf("the static-friction band");
    for (const auto& row : c.tau_map)
        if (!finite_all(row)) return nf("the external-torque map");
    for (double v : {c.observer_bandwidth, c.observer_threshold, c.observer_rest_threshold, c.isolation_sigmas})
        if (!std::isfinite(v)) return nf("the momentum observer's settings");
    if (!finite_all(c.observer_ft_threshold)) return nf("the momentum observer's settings");
    bool sides = true;
    for (double v : c.observer_ft_threshold) sides = sides && v > 0;
    if (!(c.observer_bandwidth > 0) || !(c.observer_threshold > 0) || !(c.observer_rest_threshold > 0) || !sides ||
        !(c.isolation_sigmas > 0))
        return dim("momentum observer settings out of range (bandwidth, thresholds, isolation level must be positive)");
    for (int i = 0; i < c.n_outputs; ++i)
        if (!(c.observer_variance[i] > 0)) return dim("observer Λ of " + shown_name(c.channel_names[i]) + " is not positive");
    for (int j = 0; j < c.n_joints; ++j) {
        if (!(c.tau_variance[j] > 0))
            return dim("joint " + shown_name(c.joint_names[j]) + ": the τ_ext variance must be positive");
        if (c.joint_band[j][0] < 0 || c.joint_band[j][1] < 0)
            return dim("joint " + shown_name(c.joint_names[j]) + ": its static-friction band must be ≥ 0");
    }
    for (int k = 0; k < c.n_motors; ++k)
        if (c.motor_band[k][0] < 0 || c.motor_band[k][1] < 0)
            return dim("motor " + shown_name(c.motor_names[k]) + ": its static-friction band must be ≥ 0");
    return LoadResult{};
}


namespace {

// One line naming what is out of range, with the value and the range.
LoadResult implausible(const std::string& what, double value, double lo, double hi, const char* unit) {
    const std::string u = *unit ? std::string(" ") + unit : std::string();
    std::ostringstream m;
    m << what << " is " << value << u << ", outside the plausible " << lo << " to " << hi << u
      << " (rt_monitor/include/rt_monitor/plausibility.hpp): an exporter bug or an edited file; export the model again";
    return fail(LoadError::kImplausible, m.str());
}

bool within(double v, double lo, double hi) { return v >= lo && v <= hi; }

// A joint's range [lower, upper] (rad or m): each end within ±kMaxJointRange, then in order (`strict`: lower < upper).
// The end at fault is the one named.
LoadResult check_range(const std::vector<double>& r, const std::string& what, bool strict) {
    namespace P = plausible;
    for (int end = 0; end < 2; ++end)
        if (!within(r[end], -P::kMaxJointRange, P::kMaxJointRange))
            return implausible(what + (end ? "'s upper end" : "'s lower end"), r[end], -P::kMaxJointRange,
                               P::kMaxJointRange, "rad or m");
    if (strict ? !(r[0] < r[1]) : !(r[0] <= r[1]))
        return implausible(what + "'s lower end", r[0], -P::kMaxJointRange, r[1], "rad or m");
    return LoadResult{};
}

// A residual's plausible standard deviation on output channel i: an input (duty or A), a force or a torque.
struct SigmaRange {
    double lo, hi;
    const char* unit;
};
SigmaRange sigma_range(const dynid::coefficients_t& c, int i) {
    namespace P = plausible;
    if (c.channel_kind[i] == 1) return {P::kMinInputSigma, P::kMaxInputSigma, "(duty or A)"};
    if (c.channel_kind[i] == 0 && i % 6 < 3) return {P::kMinForceSigma, P::kMaxForceSigma, "N"};  // an F/T force
    return {P::kMinTorqueSigma, P::kMaxTorqueSigma, "Nm"};
}

// Σ w[s]·(s·T)^power over a filter's weights (oldest first, T apart), and the same of |w[s]|: a derivative filter on
// a ramp (power 1) gives 1, a curvature filter on a parabola (power 2) gives 2.
struct Moment {
    double value, size;
};
Moment moment(const std::vector<double>& w, int n, double T, int power) {
    Moment m{0, 0};
    for (int s = 0; s < n; ++s) {
        const double t = s * T, x = w[size_t(s)] * (power == 1 ? t : t * t);
        m.value += x, m.size += std::abs(x);
    }
    return m;
}

}  // namespace

LoadResult check_plausible(const dynid::coefficients_t& c) {
    namespace P = plausible;
    for (int i = 0; i < c.n_bodies; ++i) {
        const std::string body = "body " + shown_name(c.body_names[i]);
        double rt_r = 0, axis = 0;  // ‖RᵀR − I‖_max, ‖a‖
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) {
                double dot = 0;
                for (int m = 0; m < 3; ++m) dot += c.rotation[i][3 * m + r] * c.rotation[i][3 * m + k];
                rt_r = std::max(rt_r, std::abs(dot - (r == k ? 1.0 : 0.0)));
            }
        for (int k = 0; k < 3; ++k) axis += c.axis[i][k] * c.axis[i][k];
        if (!(rt_r <= P::kRotationTolerance)) return implausible(body + ": its rotation's |RᵀR − I|", rt_r, 0, P::kRotationTolerance, "");
        if (c.joint_type[i] != 0 && !(std::abs(std::sqrt(axis) - 1) <= P::kRotationTolerance))
            return implausible(body + ": its joint axis' norm", std::sqrt(axis), 1 - P::kRotationTolerance, 1 + P::kRotationTolerance, "");
        for (int k = 0; k < 3; ++k)
            if (!within(c.translation[i][k], -P::kMaxTranslation, P::kMaxTranslation))
                return implausible(body + ": its joint frame's offset", c.translation[i][k], -P::kMaxTranslation, P::kMaxTranslation, "m");
        const auto& p = c.inertial[i];
        if (!within(p[0], -P::kMaxMass, P::kMaxMass)) return implausible(body + ": its mass", p[0], -P::kMaxMass, P::kMaxMass, "kg");
        for (int k = 1; k < 4; ++k)
            if (!within(p[k], -P::kMaxFirstMoment, P::kMaxFirstMoment))
                return implausible(body + ": its first moment m·c", p[k], -P::kMaxFirstMoment, P::kMaxFirstMoment, "kg m");
        for (int k = 4; k < 10; ++k)
            if (!within(p[k], -P::kMaxInertia, P::kMaxInertia))
                return implausible(body + ": its inertia", p[k], -P::kMaxInertia, P::kMaxInertia, "kg m²");
    }
    double length = 0, mass = 0;
    for (int i = 0; i < c.n_bodies; ++i) {
        length += std::sqrt(c.translation[i][0] * c.translation[i][0] + c.translation[i][1] * c.translation[i][1] +
                            c.translation[i][2] * c.translation[i][2]);
        mass += c.inertial[i][0];
    }
    if (!(length >= P::kMinChainLength))
        return implausible("the chain's length (its joint frames' offsets summed)", length, P::kMinChainLength, P::kMaxTranslation * c.n_bodies, "m");
    // By magnitude: an unconstrained fit's full φ is one representative of its base parameters, and its bodies' masses
    // need not be physical, nor their sum positive (a 10 s run of the arm gives −12 kg); all of them zero is no robot.
    if (!(std::abs(mass) >= P::kMinTotalMass))
        return implausible("the robot's total mass |Σm|", std::abs(mass), P::kMinTotalMass, P::kMaxMass * c.n_bodies, "kg");
    for (int j = 0; j < c.n_joints; ++j)
        if (LoadResult r = check_range(c.joint_limits[j], "joint " + shown_name(c.joint_names[j]) + ": its range", true); !r)
            return r;
    for (int j = 0; j < c.n_joints; ++j)  // the fit's data may pass the URDF's limits: only an order and a magnitude
        if (LoadResult r = check_range(c.fit_range[j], "joint " + shown_name(c.joint_names[j]) + ": the fit's range", false); !r)
            return r;
    const double g = std::sqrt(c.gravity[0] * c.gravity[0] + c.gravity[1] * c.gravity[1] + c.gravity[2] * c.gravity[2]);
    if (!within(g, P::kMinGravity, P::kMaxGravity)) return implausible("gravity |g|", g, P::kMinGravity, P::kMaxGravity, "m/s²");
    for (int k = 0; k < c.n_motors; ++k) {
        for (int j = 0; j < c.n_joints; ++j)
            if (!within(c.motor_velocity[k][j], -P::kMaxRatio, P::kMaxRatio))
                return implausible("motor " + shown_name(c.motor_names[k]) + ": a coupling ratio", c.motor_velocity[k][j], -P::kMaxRatio, P::kMaxRatio, "");
        double largest = 0;
        for (int j = 0; j < c.n_joints; ++j) largest = std::max(largest, std::abs(c.motor_velocity[k][j]));
        if (!(largest >= P::kMinRatio))
            return implausible("motor " + shown_name(c.motor_names[k]) + ": its largest coupling ratio (it drives no joint)",
                               largest, P::kMinRatio, P::kMaxRatio, "");
        for (double f : c.motor_friction[k])
            if (!within(f, -P::kMaxFriction, P::kMaxFriction))
                return implausible("motor " + shown_name(c.motor_names[k]) + ": a friction coefficient", f, -P::kMaxFriction, P::kMaxFriction, "Nm or Nm·s/rad");
    }
    for (int j = 0; j < c.n_joints; ++j)
        for (double f : c.joint_friction[j])
            if (!within(f, -P::kMaxFriction, P::kMaxFriction))
                return implausible("joint " + shown_name(c.joint_names[j]) + ": a friction coefficient", f, -P::kMaxFriction, P::kMaxFriction, "Nm or Nm·s/rad");
    for (int s = 0; s < c.n_sensors; ++s)
        for (double o : c.ft_offset[s])
            if (!within(o, -P::kMaxOffset, P::kMaxOffset))
                return implausible("F/T sensor " + shown_name(c.sensor_names[s]) + ": an offset", o, -P::kMaxOffset, P::kMaxOffset, "N or Nm");
    int counted = 0;  // channels in T²: every one, for the threshold's scale
    for (int i = 0; i < c.n_outputs; ++i) {
        const std::string ch = "channel " + shown_name(c.channel_names[i]);
        for (int j = 0; j < c.n_joints; ++j)
            if (!within(c.row_map[i][j], -P::kMaxRatio, P::kMaxRatio))
                return implausible(ch + ": a row-map entry", c.row_map[i][j], -P::kMaxRatio, P::kMaxRatio, "");
        const double d = std::abs(c.divisor[i]);
        if (!within(d, P::kMinGain, P::kMaxGain)) return implausible(ch + ": its gain |divisor|", d, P::kMinGain, P::kMaxGain, "");
        const SigmaRange r = sigma_range(c, i);
        if (!within(std::sqrt(c.residual_variance[i]), r.lo, r.hi))
            return implausible(ch + ": its residual's √Λ", std::sqrt(c.residual_variance[i]), r.lo, r.hi, r.unit);
        ++counted;
    }
    const double per = c.threshold / std::max(counted, 1);
    if (!within(per, P::kMinThresholdPerChannel, P::kMaxThresholdPerChannel))
        return implausible("T²_α per channel", per, P::kMinThresholdPerChannel, P::kMaxThresholdPerChannel, "");
    for (int s = 0; s < c.n_sensors; ++s)
        if (!within(c.ft_threshold[s] / 6, P::kMinThresholdPerChannel, P::kMaxThresholdPerChannel))
            return implausible("F/T sensor " + shown_name(c.sensor_names[s]) + ": its side threshold per channel",
                               c.ft_threshold[s] / 6, P::kMinThresholdPerChannel, P::kMaxThresholdPerChannel, "");
    const double most = P::kMaxDebounceSeconds / c.sample_period;
    if (c.debounce_on > most || c.debounce_off > most)
        return implausible("a debounce count", double(std::max(c.debounce_on, c.debounce_off)), 1, most,
                           "samples (10 s at this file's period)");
    if (!within(c.min_speed, 0, P::kMaxMinSpeed)) return implausible("min_speed", c.min_speed, 0, P::kMaxMinSpeed, "rad/s");
    if (!within(c.alpha, P::kMinAlpha, 1)) return implausible("α", c.alpha, P::kMinAlpha, 1, "");
    if (!within(c.supply_time_constant, 0, P::kMaxSupplyTimeConstant))
        return implausible("the supply tracking's time constant", c.supply_time_constant, 0, P::kMaxSupplyTimeConstant, "s");
    if (c.supply_time_constant > 0 && !(c.supply_time_constant >= P::kMinSupplyPeriods * c.sample_period))
        return implausible("the supply tracking's time constant (0: off)", c.supply_time_constant,
                           P::kMinSupplyPeriods * c.sample_period, P::kMaxSupplyTimeConstant, "s");
    if (!within(c.hysteresis, P::kMinHysteresis, 1))
        return implausible("the end level (hysteresis, a fraction of T²_α)", c.hysteresis, P::kMinHysteresis, 1, "");
    // The filter's weights: a fitted polynomial reproduces a constant (value weights sum to 1, derivatives' to 0), and
    // the derivatives of a ramp and a parabola (slope weights on t give 1, curvature weights on t² give 2).
    for (int r = 0; r < 3; ++r) {
        double sum = 0, size = 0;
        for (int s = 0; s < c.window; ++s) sum += c.filter[r][s], size += std::abs(c.filter[r][s]);
        const double want = r == 0 ? 1.0 : 0.0;
        const char* name = r == 0 ? "value" : r == 1 ? "slope" : "curvature";
        if (!(std::abs(sum - want) <= P::kFilterSumTolerance * std::max(1.0, size)))
            return implausible(std::string("the filter's ") + name + " weights' sum", sum, want, want, "");
        if (r == 0) continue;
        const Moment m = moment(c.filter[r], c.window, c.sample_period, r);
        const double gain = r == 1 ? 1.0 : 2.0;
        if (!(std::abs(m.value - gain) <= P::kFilterSumTolerance * std::max(1.0, m.size)))
            return implausible(std::string("the filter's ") + name + " on " + (r == 1 ? "t" : "t²"), m.value, gain, gain, "");
    }
    for (int k = 0; k < c.n_effects; ++k) {
        const auto& p = c.effect_param[k];
        const std::string e = "effect " + str(k);
        const double most = c.effect_kind[k] == 1 ? P::kMaxEffectTorque : P::kMaxStiffness;
        if (!within(p[0], -most, most))
            return implausible(e + (c.effect_kind[k] == 1 ? ": its extra static torque" : ": its stiffness"), p[0], -most,
                               most, c.effect_kind[k] == 1 ? "Nm" : "Nm/rad");
        if (c.effect_kind[k] == 1 && !within(p[1], 0, P::kMaxStribeckVelocity))
            return implausible(e + ": its Stribeck velocity", p[1], 0, P::kMaxStribeckVelocity, "rad/s");
        if (c.effect_kind[k] == 2 && !within(p[1], -P::kMaxRest, P::kMaxRest))
            return implausible(e + ": its rest position", p[1], -P::kMaxRest, P::kMaxRest, "rad");
    }
    for (int j = 0; j < c.n_joints; ++j)
        if (!within(std::sqrt(c.accel_tau_variance[j]), 0, P::kMaxTauSigma))
            return implausible("joint " + shown_name(c.joint_names[j]) + ": its τ_ext noise", std::sqrt(c.accel_tau_variance[j]), 0, P::kMaxTauSigma, "Nm");
    if (!within(c.isolation_sigmas, 0, P::kMaxIsolationSigmas))
        return implausible("the isolation level", c.isolation_sigmas, 0, P::kMaxIsolationSigmas, "standard deviations");
    if (c.velocity_window > 0) {
        double sum = 0, size = 0;
        for (int s = 0; s < c.velocity_window; ++s) sum += c.velocity_filter[s], size += std::abs(c.velocity_filter[s]);
        if (!(std::abs(sum) <= P::kFilterSumTolerance * std::max(1.0, size)))
            return implausible("the observer's q̇ weights' sum", sum, 0, 0, "");
        const Moment m = moment(c.velocity_filter, c.velocity_window, c.sample_period, 1);
        if (!(std::abs(m.value - 1.0) <= P::kFilterSumTolerance * std::max(1.0, m.size)))
            return implausible("the observer's q̇ weights on t", m.value, 1, 1, "");
        const double nyquist = 0.5 / c.sample_period;
        if (!within(c.observer_bandwidth, P::kMinObserverBandwidth, nyquist))
            return implausible("the observer's bandwidth", c.observer_bandwidth, P::kMinObserverBandwidth, nyquist,
                               "Hz (Nyquist)");
        for (int i = 0; i < c.n_outputs; ++i) {
            const SigmaRange r = sigma_range(c, i);
            if (!within(std::sqrt(c.observer_variance[i]), r.lo, r.hi))
                return implausible("channel " + shown_name(c.channel_names[i]) + ": the observer's √Λ",
                                   std::sqrt(c.observer_variance[i]), r.lo, r.hi, r.unit);
        }
        const double obs = c.observer_threshold / std::max(c.n_outputs, 1), rest = c.observer_rest_threshold / std::max(c.n_outputs, 1);
        if (!within(obs, P::kMinThresholdPerChannel, P::kMaxThresholdPerChannel))
            return implausible("the observer's T²_α per channel", obs, P::kMinThresholdPerChannel, P::kMaxThresholdPerChannel, "");
        if (!within(rest, P::kMinThresholdPerChannel, P::kMaxThresholdPerChannel))
            return implausible("the observer's rest T²_α per channel", rest, P::kMinThresholdPerChannel, P::kMaxThresholdPerChannel, "");
        for (int j = 0; j < c.n_joints; ++j)
            if (!within(std::sqrt(c.tau_variance[j]), 0, P::kMaxTauSigma))
                return implausible("joint " + shown_name(c.joint_names[j]) + ": the observer's τ_ext noise", std::sqrt(c.tau_variance[j]), 0, P::kMaxTauSigma, "Nm");
        if (c.combined_scale > 0 && !within(c.combined_scale, P::kMinCombinedScale, P::kMaxCombinedScale))
            return implausible("the combined detector's κ", c.combined_scale, P::kMinCombinedScale, P::kMaxCombinedScale, "");
    }
    return LoadResult{};
}

}  // namespace dynid::rt
