// The monitor's compile-time capacity, in one place: the core, the loader, the assembler and the bus tables size
// their storage from these, and dynid reads them from this file (dynid.export.capacity) to refuse, before it writes
// anything, a robot the monitor could not take. A file or configuration that needs more is refused, never truncated.
//
// The coefficient file's format version lives here too (kFileVersion, read by dynid.export.capacity the same way).
//
// Sized for every bundled robot with room to spare: a whole iCub carries six F/T sensors (arms, legs, feet) and
// about 32 joints without its hands; the bundled set-ups need at most 12 joints (the iCub standing on one leg), 2
// sensors and a 151-sample filter window (the UR10e's 0.3 s at 500 Hz). Keep the form `constexpr int kName = N;`:
// dynid parses it.
#pragma once

namespace dynid::rt {

constexpr int kMaxJoints = 32;              // moving joints (entries of q)
constexpr int kMaxSensors = 6;              // F/T sensors inside the chain
constexpr int kMaxBodies = 48;              // bodies of the tree: one per joint, one more per F/T split, fixed ones
constexpr int kMaxMotors = 32;
constexpr int kMaxOutputs = 72;             // 6 per F/T sensor, then one per motor input or joint torque
constexpr int kMaxWindow = 256;             // samples of the derivative filter and of the observer's q̇
constexpr int kMaxEffects = 16;             // Stribeck and spring effects of an augmented model
constexpr int kMaxBuses = 8;                // CAN interfaces the monitor reads
constexpr int kMaxFrames = 256;             // CAN frames of the robot's bus description
constexpr int kMaxSignals = 1024;           // signals in those frames
constexpr int kMaxSkins = 16;               // skin patches (bits of a sample's contact mask)
constexpr int kMaxKnown = 2048;             // samples of the coefficient file's known answers (windows + 1000)

// The coefficient file's format version: 2 effects (Stribeck, spring) of an augmented model; 3 supply tracking; 4 the
// momentum observer; 5 any number of F/T sensors, the acceleration residuals' external-torque variance, the joints'
// ranges; 6 the combined detector (residual 2, combined_scale); 7 the known answers the loader checks the core against;
// 8 the postures the fit saw (fit_range). A file of another version is refused, named.
constexpr int kFileVersion = 8;

}  // namespace dynid::rt
