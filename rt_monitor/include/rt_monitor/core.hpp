// The real-time evaluation core: per sample, the fixed-lag derivative filter and a fixed-size recursive
// Newton-Euler prediction of the F/T wrench and the motor inputs (the acceleration residuals), or the
// generalized-momentum observer (no q̈: dynid.detect.momentum), or both in the combined detector
// (dynid.detect.combined); then T², the debounced detector with hysteresis,
// the contact side, the wrench and, with the observer, the external joint torques and the isolated joint. After
// construction: no allocation, no locks, no exceptions, no I/O (rt_monitor/README.md, "Real-time core").
#pragma once

#include "rt_monitor/coefficients.hpp"
#include "rt_monitor/momentum.hpp"
#include "rt_monitor/sliding_moments.hpp"
#include "rt_monitor/sparse_rows.hpp"

namespace dynid::rt {

using VecO = Eigen::Matrix<double, kMaxOutputs, 1>;
// A ring row's capacity (Core): the widest row it keeps, every channel plus the 3 the filter may read past them
// (its blocks of 4), rounded up to a block.
constexpr int kRingStride = (kMaxJoints + kMaxOutputs + 3 + 3) / 4 * 4;

enum class Event : int8_t { kNone = 0, kOnset = 1, kEnd = 2 };
enum class Side : int8_t { kNone = 0, kDistal = 1, kProximal = -1 };  // of an F/T sensor

struct Prediction {
    VecO y_hat = VecO::Zero();   // predicted outputs (each F/T wrench in its sensor frame, then motor inputs)
    VecO y_model = VecO::Zero(); // the same before the supply ratio (differs on tracked motor inputs only)
    VecO e = VecO::Zero();       // residuals y − ŷ
    std::array<bool, kMaxOutputs> active{};  // channels in T² (motor channels at rest are left out)
    double t2 = 0;               // eᵀ Λ⁻¹ e over the active channels
    std::array<double, kMaxSensors> t2_sensor{};  // each F/T sensor's channels' share
    VecJ tau = VecJ::Zero();     // rigid-body joint torques (diagnostics)
};

struct Output {
    bool ready = false;          // the filter window is full; nothing below is valid before
    VecJ q = VecJ::Zero(), dq = VecJ::Zero(), ddq = VecJ::Zero();  // filtered, at sample k − lag
    VecO y = VecO::Zero();       // filtered measured outputs, at sample k − lag
    Prediction p;
    double t2_alpha = 0;         // the T²_α in force at this sample (the observer's rest one where every row rests;
                                 // 1 in the combined detector, whose p.t2 is s)
    bool above = false;          // T² > T²_α at this sample
    bool in_contact = false;     // the debounced detector's state
    Event event = Event::kNone;
    // Per F/T sensor, while above: distal if its channels fire, else proximal.
    std::array<Side, kMaxSensors> side{};
    // Per F/T sensor, the estimated external wrench at it (sensor frame): its residual.
    std::array<Vec6, kMaxSensors> wrench{};
    // The observer's output r per channel (before the static-friction band; zero with the acceleration residuals).
    VecO r = VecO::Zero();
    // The external joint torques (Nm): tau_map·r with the observer, tau_map·(divisor ⊙ e) with the acceleration
    // residuals; and the isolated joint: the most distal one whose |τ_ext| exceeds isolation_sigmas of its
    // calibration noise (the contact is on its link or beyond), −1 if none (or no variance was calibrated).
    VecJ tau_ext = VecJ::Zero();
    int joint = -1;
    // The combined detector: each residual's T² over its own T²_α (the observer's at this sample, the acceleration
    // residuals' at sample k − lag); p.t2 is then their sum over combined_scale, s, and the threshold 1; where every
    // row rests, the observer's ratio alone (its rest threshold; the acceleration residuals leave resting rows out).
    // Everything else above is the observer's. Zero with one residual.
    double observer_ratio = 0, acceleration_ratio = 0;
    // The contact's strongest sample since its onset (the first largest p.t2 / T²_α from the onset on): what its end
    // event reports, as dynid detect's events report their peak; an onset freezes its own sample, which a contact
    // growing on the other side of a sensor outgrows (the iCub leg's put-down). peak_now: this sample is it.
    struct Peak {
        double t2 = 0, ratio = 0;  // p.t2 there, and over the T²_α in force there
        VecO e = VecO::Zero();
        std::array<bool, kMaxOutputs> active{};
        std::array<Side, kMaxSensors> side{};
        std::array<Vec6, kMaxSensors> wrench{};
        VecJ tau_ext = VecJ::Zero();
        int joint = -1;
    } peak;
    bool peak_now = false;
};

struct DetectorSettings {
    int debounce_on = 1, debounce_off = 1;  // consecutive samples to confirm an onset / an end
    double hysteresis = 1.0;                // the end level, as a fraction of T²_α
};

class Core {
public:
    explicit Core(const Coefficients& c) noexcept;  // keeps a reference: `c` must outlive the core

    // One raw sample: q (n_joints) and the measured outputs y (n_outputs, the file's channel order); with a file whose
    // observer takes the robot's measured q̇ (measured_velocity), that q̇ (n_joints): the caller must give it (null:
    // the observer estimates q̇ from q, which the file's thresholds were not calibrated for).
    const Output& step(const double* q, const double* y) noexcept { return step(q, nullptr, y); }
    const Output& step(const double* q, const double* dq, const double* y) noexcept;
    // The model alone, on given states and (filtered) outputs: what the cross-language vectors check.
    void predict(const VecJ& q, const VecJ& dq, const VecJ& ddq, const VecO& y, Prediction& out) const noexcept;

    // Restart the filter, the observer and the detector (after a gap in the frames). The supply estimate survives:
    // a gap in the data does not change the boards' supply, and starting it over would put its drift back into e.
    void reset() noexcept;
    // Run another residual than the file selects (start-up only; it resets). False: the file carries no observer
    // (momentum), or no combined_scale (combined).
    bool set_residual(Residual r) noexcept;
    Residual residual() const noexcept { return residual_; }
    // Λ of channel i for the residual whose e the output carries (the observer's in the combined detector).
    double variance(int i) const noexcept {
        return residual_ == Residual::kAcceleration ? c_.variance[i] : c_.observer_variance[i];
    }
    // T²_α of p.t2 (1 in the combined detector: p.t2 is s).
    double threshold() const noexcept {
        return residual_ == Residual::kAcceleration ? c_.threshold
               : residual_ == Residual::kMomentum   ? c_.observer_threshold
                                                    : 1.0;
    }
    // The supply ratio r of output channel i (1 on untracked channels; dynid.identify.supply): the acceleration
    // residuals' tracker, or the observer's where only the observer runs.
    double supply_ratio(int i) const noexcept { return residual_ == Residual::kMomentum ? obs_ratio_[i] : ratio_[i]; }
    // The combined detector's acceleration residuals (its output's p, q, q̇, q̈, y at sample k − lag).
    const Output& acceleration_output() const noexcept { return acc_; }
    void set_detector(const DetectorSettings& s) noexcept { det_ = s; }
    const DetectorSettings& detector() const noexcept { return det_; }
    const Output& output() const noexcept { return out_; }

private:
    void rnea(const VecJ& q, const VecJ& dq, const VecJ& ddq, VecJ& tau,
              std::array<Vec6, kMaxSensors>& sensor_force) const noexcept;
    // The newest n samples of the ring, oldest first (n contiguous rows, stride_ apart).
    const double* newest(int n) const noexcept { return ring_.data() + size_t(slot_ + ring_rows_ - n) * size_t(stride_); }
    void accelerate(Output& o) noexcept;
    void combine(const double* q, const double* dq, const double* y) noexcept;
    // The observer into out_ (q̇ the measured `dq`, or estimated where it is null); returns its T²_α at this sample
    // (the rest threshold where every row rests).
    double observe(const double* q, const double* dq, const double* y) noexcept;
    // τ_ext from the rows' residuals, and the isolated joint: the most distal whose |τ_ext| exceeds its level (< 0:
    // no variance calibrated, never).
    void isolate(Output& o, const VecO& rows, const std::array<double, kMaxJoints>& level) noexcept;
    void detect(double threshold, const std::array<double, kMaxSensors>& ft_threshold) noexcept;
    void track_supply(const Output& o) noexcept;

    const Coefficients& c_;
    DetectorSettings det_;
    Residual residual_ = Residual::kAcceleration;
    // Per sample constants the file implies: 1/Λ of each residual's channels, each joint's isolation level
    // (isolation_sigmas·σ of its τ_ext, −1 where none was calibrated).
    std::array<double, kMaxOutputs> inverse_variance_{}, inverse_observer_variance_{};
    std::array<double, kMaxJoints> accel_isolation_{}, observer_isolation_{};
    // The row map (outputs × joints) and the external-torque map, transposed (outputs × joints), by their nonzeros.
    SparseRows<kMaxOutputs, kMaxJoints> row_map_, tau_map_;
    int width_ = 0;  // channels per raw sample: n_joints + n_outputs
    int window_ = 0;  // samples before a residual: the derivative filter's window, the observer's velocity window, or both
    int ring_rows_ = 0;  // samples in the ring: window_ + 1
    // The last samples, one row a sample: q, then y, then padding that the filter reads past its channels (it takes
    // the channels in blocks of 4). Each sample is stored twice, at rows slot and slot + ring_rows_, so the window is
    // always a contiguous block of rows; a row is stride_ values, a multiple of 4, so every row is 32-byte aligned.
    alignas(64) std::array<double, size_t(kRingStride) * 2 * (kMaxWindow + 1)> ring_{};
    // The derivative filter's sliding moments over the first sliding_channels_ channels of a row (0: none, the
    // joints', or every channel): the rest go through the convolution.
    SlidingMoments moments_;
    int sliding_channels_ = 0;
    int stride_ = 0;
    double* row(int s) noexcept { return ring_.data() + size_t(s) * size_t(stride_); }
    int slot_ = 0;
    long count_ = 0;
    int above_run_ = 0, below_run_ = 0;
    // Supply tracking: exponentially forgotten sums of ŷ y and ŷ², and their ratio r, per output channel; the
    // acceleration residuals' and the observer's each their own (the combined detector runs both).
    double lambda_ = 1.0;
    std::array<double, kMaxOutputs> num_{}, den_{}, ratio_{};
    std::array<double, kMaxOutputs> obs_num_{}, obs_den_{}, obs_ratio_{};
    // The observer: a = exp(−K_O·T), its output r, the previous momentum (joints, then the sensor's 6), the
    // low-passed inputs of the tracked channels.
    double decay_ = 0;
    bool observing_ = false;
    bool observer_all_rest_ = false;  // every row rested at the observer's last sample
    VecO r_ = VecO::Zero(), inputs_ = VecO::Zero();
    VecJ p_prev_ = VecJ::Zero();
    std::array<Vec6, kMaxSensors> ps_prev_{};
    MomentumTerms terms_;
    Output out_;
    Output acc_;  // the combined detector's acceleration residuals
};

}  // namespace dynid::rt
