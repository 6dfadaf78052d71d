// The coefficient file, loaded into fixed-capacity storage (rt_monitor/README.md, "The coefficient file").
// Loading happens once, at start-up: it may allocate (file bytes, the LCM decode) and never throws out.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <string>

#include "rt_monitor/capacity.hpp"

namespace dynid::rt {

// The sample period a file may give: 100 kHz to 1 Hz (the sample clock counts periods between µs stamps in int64).
constexpr double kMinSamplePeriod = 1e-5, kMaxSamplePeriod = 1.0;

constexpr char kMagic[8] = {'D', 'Y', 'N', 'I', 'D', 'C', 'O', 'F'};

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;

enum class JointType : int8_t { kFixed = 0, kRevolute = 1, kPrismatic = 2 };
enum class ChannelKind : int8_t { kFt = 0, kInput = 1, kTorque = 2 };
// Extra joint torques of an augmented model (`dynid gaps --out`), added to τ + τ_f of their joint:
// Stribeck p0·sign(q̇)·exp(−(q̇/p1)²), spring p0·(q − p1).
enum class EffectKind : int8_t { kStribeck = 1, kSpring = 2 };
// The residual the core runs: the acceleration residuals (fixed-lag filter, q̈), the momentum observer's, or both
// in the combined detector (dynid.detect.combined).
enum class Residual : int8_t { kAcceleration = 0, kMomentum = 1, kCombined = 2 };

struct Coefficients {
    std::string robot_name, config_digest, dynid_version, model_sha256, data_sha256, estimator;
    int n_joints = 0, n_bodies = 0, n_motors = 0, n_outputs = 0;

    std::array<int, kMaxBodies> parent{}, joint_index{};
    std::array<JointType, kMaxBodies> joint_type{};
    std::array<Vec3, kMaxBodies> axis{}, translation{};
    std::array<Mat3, kMaxBodies> rotation{};
    // Derived at load, for the joint's rotation by q without a product of rotations (kinematics.hpp): rotation·[a]×
    // and rotation·a·aᵀ, a the axis.
    std::array<Mat3, kMaxBodies> rotation_cross{}, rotation_outer{};
    std::array<double, kMaxBodies> mass{};  // φ: m,
    std::array<Vec3, kMaxBodies> first_moment{};  //    m·c,
    std::array<Mat3, kMaxBodies> inertia{};       //    I about the body frame origin
    Vec3 gravity = Vec3::Zero();
    // F/T sensors: the distal sub-body of each (its frame is the sensor frame); their 6·n_sensors channels come
    // first in the outputs, sensor by sensor (fx fy fz tx ty tz).
    int n_sensors = 0;
    std::array<int, kMaxSensors> sensor_body{};
    std::array<int, kMaxBodies> sensor_of_body{};  // derived at load: the sensor whose distal sub-body it is, or -1
    int n_ft() const { return 6 * n_sensors; }

    // The matrices the core reads a row at a time (a motor's, a joint's, an output's) are stored by rows.
    Eigen::Matrix<double, kMaxMotors, kMaxJoints, Eigen::RowMajor> motor_velocity = decltype(motor_velocity)::Zero();
    std::array<bool, kMaxMotors> motor_friction_on{};
    Eigen::Matrix<double, kMaxMotors, 4, Eigen::RowMajor> motor_friction = decltype(motor_friction)::Zero();
    Eigen::Matrix<double, kMaxJoints, 4, Eigen::RowMajor> joint_friction = decltype(joint_friction)::Zero();

    std::array<ChannelKind, kMaxOutputs> channel_kind{};
    std::array<Vec6, kMaxSensors> ft_offset{};
    Eigen::Matrix<double, kMaxOutputs, kMaxJoints, Eigen::RowMajor> row_map = decltype(row_map)::Zero();
    std::array<int, kMaxOutputs> channel_motor{};
    std::array<double, kMaxOutputs> divisor{}, variance{};
    std::array<uint64_t, kMaxOutputs> gate_joints{}, gate_motors{};
    double min_speed = 0, alpha = 0, threshold = 0, hysteresis = 1;
    std::array<double, kMaxSensors> ft_threshold{};   // per sensor: its channels' share of T² at α (its side)
    std::array<double, kMaxJoints> accel_tau_variance{};  // τ_ext from the acceleration residuals: its variance (Nm²)
    int calibration_samples = 0, debounce_on = 1, debounce_off = 1;

    double sample_period = 0;
    int window = 0, order = 0, lag = 0;
    // Weights, oldest sample first: one column each for the value, the first and the second derivative (contiguous:
    // the core takes dot products with them).
    Eigen::Matrix<double, kMaxWindow, 3> filter = decltype(filter)::Zero();

    int n_effects = 0;
    std::array<EffectKind, kMaxEffects> effect_kind{};
    std::array<int, kMaxEffects> effect_joint{};
    std::array<std::array<double, 3>, kMaxEffects> effect_param{};

    // Supply tracking of the input channels (dynid.identify.supply): time constant (s, 0 = off), prior weight, gates.
    double supply_time_constant = 0, supply_prior = 0;
    std::array<double, kMaxOutputs> supply_gate{};

    // The generalized-momentum observer (format version 4, dynid.detect.momentum); velocity_window 0: none.
    Residual residual = Residual::kAcceleration;
    double observer_bandwidth = 0;  // Hz
    int velocity_window = 0;
    // The observer's q̇ (format version 7): the robot's own, from the bus (a dq.J for every joint), or estimated from
    // q with velocity_filter. The acceleration residuals always take the fixed-lag filter's.
    bool measured_velocity = false;
    Eigen::Matrix<double, 1, kMaxWindow> velocity_filter = decltype(velocity_filter)::Zero();  // 1/s, oldest first
    Eigen::Matrix<double, kMaxJoints, 2> joint_band = decltype(joint_band)::Zero();  // static friction fc⁺, fc⁻ (Nm)
    Eigen::Matrix<double, kMaxMotors, 2> motor_band = decltype(motor_band)::Zero();
    std::array<double, kMaxOutputs> observer_variance{};
    double observer_threshold = 0, observer_rest_threshold = 0;
    std::array<double, kMaxSensors> observer_ft_threshold{};
    Eigen::Matrix<double, kMaxJoints, kMaxOutputs> tau_map = decltype(tau_map)::Zero();  // τ_ext = tau_map · r
    std::array<double, kMaxJoints> tau_variance{};
    double isolation_sigmas = 0;
    bool has_observer() const { return velocity_window > 0; }
    // The combined detector (format version 6): s = (T²_o/T²_o,α + T²/T²_α)/combined_scale; 0: not calibrated.
    double combined_scale = 0;
    bool has_combined() const { return has_observer() && combined_scale > 0; }

    std::array<std::string, kMaxJoints> joint_names;
    std::array<double, kMaxJoints> joint_lower{}, joint_upper{};  // each joint's range (rad, or m)
    std::array<double, kMaxJoints> fit_lower{}, fit_upper{};      // ... over the fit's data (format version 8)
    std::array<std::string, kMaxOutputs> channel_names;
    std::array<std::string, kMaxSensors> sensor_names;
    std::array<std::string, kMaxBodies> body_names;
};

// Why a file was refused; each has its own exit code (kExitBase + value) in the command-line tools.
enum class LoadError : int {
    kOk = 0,
    kIo = 1,
    kTruncated = 2,
    kMagic = 3,
    kVersion = 4,
    kCrc = 5,
    kDecode = 6,
    kCapacity = 7,
    kDimension = 8,
    kNotFinite = 9,
    kRobot = 10,
    kImplausible = 11,  // well formed, but a value no robot has (rt_monitor/plausibility.hpp)
    kKnownAnswers = 12,  // the core does not reproduce the file's known answers (src/known_answers.cpp)
};
constexpr int kExitBase = 10;

struct LoadResult {
    LoadError error = LoadError::kOk;
    std::string message;  // one line naming the problem
    explicit operator bool() const { return error == LoadError::kOk; }
};

uint32_t crc32(const uint8_t* data, size_t size);

// Outside text in a message, so that a refusal stays one whole line whatever the file holds (fuzzer finding: a robot
// name with a NUL and a newline in it): control bytes (newline, carriage return, NUL, …) as \xNN.
std::string escape_control(const std::string& s);
// The same for a name from a file, cut at 80 bytes ("…").
std::string shown_name(const std::string& s);

// Check and load a coefficient file. `expected_robot` empty: any robot. On failure `out` is unspecified.
LoadResult load_coefficients(const std::string& path, const std::string& expected_robot, Coefficients& out);
LoadResult load_coefficients_from_bytes(const uint8_t* data, size_t size, const std::string& expected_robot,
                                        Coefficients& out);

}  // namespace dynid::rt
