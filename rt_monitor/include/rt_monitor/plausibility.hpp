// What a coefficient file may hold, from physics and the sensors' ranges: a file that passes its CRC but carries an
// absurd value (an exporter bug, a hand edit) is refused at load with one line (LoadError::kImplausible), never run.
// A monitor that runs on such a file is blind or alarms forever, in silence (issue 31's sweep: rotation 1e200, mass
// 1e308, Λ 1e-300, threshold 1e300, gravity 0, debounce 2³¹−1).
//
// One place: the loader checks these (src/coefficient_checks.cpp), and dynid reads them from this file
// (dynid.export.plausible) to refuse writing such a file. Keep the form `constexpr double kName = value;`.
#pragma once

namespace dynid::rt::plausible {

// The chain: a robot's links are metres, not kilometres; its rotations are rotations.
constexpr double kMaxTranslation = 10.0;      // m, a joint frame's offset from its parent's
constexpr double kRotationTolerance = 1e-6;   // ‖RᵀR − I‖ and ‖axis‖ − 1
// Inertial parameters of one body (identified ones need not be physical one by one, only of the robot's scale).
constexpr double kMaxMass = 1000.0;           // kg
constexpr double kMaxFirstMoment = 1000.0;    // kg m
constexpr double kMaxInertia = 1000.0;        // kg m²
// The robot as a whole, though, has a length and a mass: all offsets or all masses zero is no robot.
constexpr double kMinChainLength = 0.01;      // m, the sum of the joint frames' offsets
constexpr double kMinTotalMass = 0.01;        // kg, |the sum of the bodies' masses|
// A joint's range: within ±1e6 (rad, or m; what a joint without limits is exported with), lower below upper.
constexpr double kMaxJointRange = 1e6;
// Gravity on Earth: 9.76–9.84 m/s² at its surface.
constexpr double kMinGravity = 9.7;
constexpr double kMaxGravity = 9.9;
// A residual's standard deviation √Λ, per channel kind (F/T force N, F/T torque Nm, motor input in duty or A, joint
// torque Nm): below the finest sensor's resolution, or above any sensor's range, Λ is not a calibration.
constexpr double kMinForceSigma = 1e-6;
constexpr double kMaxForceSigma = 1e4;
constexpr double kMinTorqueSigma = 1e-8;
constexpr double kMaxTorqueSigma = 1e3;
constexpr double kMinInputSigma = 1e-9;
constexpr double kMaxInputSigma = 1e3;
// T²_α per channel it sums: a χ² quantile of n channels lies between about 0.1·n (α small) and 10·n (α 0.9999).
constexpr double kMinThresholdPerChannel = 0.05;
constexpr double kMaxThresholdPerChannel = 1e4;
// Debounce: at most this many seconds of samples (2³¹ − 1 samples never raise an onset).
constexpr double kMaxDebounceSeconds = 10.0;
// A motor gain (a PWM duty or an ampere to Nm), a friction coefficient, an offset, a coupling ratio.
constexpr double kMinGain = 1e-6;
constexpr double kMaxGain = 1e6;
constexpr double kMaxFriction = 1e4;          // Nm, Nm·s/rad
constexpr double kMaxOffset = 1e5;            // N, Nm
constexpr double kMaxRatio = 1e3;             // row map, coupling
constexpr double kMinRatio = 1e-3;            // a motor's largest coupling ratio: a motor drives some joint
// A polynomial fit reproduces a constant, a ramp and a parabola: the value weights sum to 1, the derivatives' to 0;
// on t the slope weights give 1, on t² the curvature weights 2 (relative to the weights' size).
constexpr double kFilterSumTolerance = 1e-6;
constexpr double kMinObserverBandwidth = 0.1;  // Hz: slower, the observer's lag (above 1.6 s) hides every contact
// Effects: a Stribeck bump and a spring of a joint.
constexpr double kMaxEffectTorque = 1e3;      // Nm
constexpr double kMaxStribeckVelocity = 100;  // rad/s
constexpr double kMaxStiffness = 1e5;         // Nm/rad
constexpr double kMaxRest = 100;              // rad
// Detector settings.
constexpr double kMaxMinSpeed = 10;           // rad/s
constexpr double kMinAlpha = 0.5;
constexpr double kMaxSupplyTimeConstant = 1e4;  // s
constexpr double kMinSupplyPeriods = 10;      // a time constant on (not 0) spans at least this many sample periods
constexpr double kMinHysteresis = 0.05;       // the end level as a fraction of T²_α: below, no contact ever ends
constexpr double kMaxIsolationSigmas = 100;
// The combined detector's κ: the α-quantile of two statistics each 1 at its own α-quantile, summed, lies between
// about 1 (one of them always 0) and 2 (the two equal); far outside, the file is blind or alarms forever.
constexpr double kMinCombinedScale = 0.5;
constexpr double kMaxCombinedScale = 20;
constexpr double kMaxTauSigma = 1e4;          // Nm, the external joint torque's calibration noise

// The monitor's configuration: a value signal's scale (its resolution, physical units per count) and the span its
// counts can represent, per kind of target. A full scale of 1e-300 (every reading 0: a contact that never ends) or
// 1e300 is refused at load; a plausible but wrong one shows at run time (a joint out of its range, an F/T reading
// at the rails of its counts).
constexpr double kMinPositionScale = 1e-10;   // rad (or m) per count
constexpr double kMaxPositionScale = 0.1;
constexpr double kMinVelocityScale = 1e-10;   // rad/s per count
constexpr double kMaxVelocityScale = 1.0;
constexpr double kMinForceScale = 1e-7;       // N per count
constexpr double kMaxForceScale = 10.0;
constexpr double kMinForceSpan = 1.0;         // N: a sensor reads at least ±0.5 N
constexpr double kMinTorqueScale = 1e-9;      // Nm per count (F/T torques, joint torques)
constexpr double kMaxTorqueScale = 10.0;
constexpr double kMinTorqueSpan = 0.01;       // Nm
constexpr double kMinDutyScale = 1e-7;        // PWM duty per count
constexpr double kMaxDutyScale = 0.1;
constexpr double kMinDutySpan = 1.0;          // a PWM reads at least ±0.5 duty
constexpr double kMinCurrentScale = 1e-7;     // A per count
constexpr double kMaxCurrentScale = 10.0;
constexpr double kMinFloatScale = 1e-6;       // an IEEE float signal's scale (the float carries the value)
constexpr double kMaxFloatScale = 1e6;

}  // namespace dynid::rt::plausible
