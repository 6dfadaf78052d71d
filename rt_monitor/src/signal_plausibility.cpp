// A value signal of the monitor's configuration against the sensors' plausible ranges (signal_plausibility.hpp).
#include "signal_plausibility.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "rt_monitor/plausibility.hpp"

namespace dynid::rt {
namespace {

std::string number(double v) {
    std::ostringstream o;
    o << v;
    return o.str();
}

}  // namespace

std::string implausible_signal(const std::string& t, const SignalDef& s) {
    namespace P = plausible;
    const double scale = std::abs(s.scale);
    if (s.type == SignalType::kFloat) {
        if (scale >= P::kMinFloatScale && scale <= P::kMaxFloatScale) return "";
        return "'" + t + "': a float signal's scale " + number(s.scale) + " is outside the plausible " +
               number(P::kMinFloatScale) + " to " + number(P::kMaxFloatScale);
    }
    const bool force = s.target == Target::kFt && (t.back() == 'x' || t.back() == 'y' || t.back() == 'z') &&
                       t[t.size() - 2] == 'f';
    double lo = 0, hi = 0, span_min = 0;
    const char* unit = "";
    switch (s.target) {
        case Target::kQ: lo = P::kMinPositionScale, hi = P::kMaxPositionScale, unit = "rad (or m) per count"; break;
        case Target::kDq: lo = P::kMinVelocityScale, hi = P::kMaxVelocityScale, unit = "rad/s per count"; break;
        case Target::kFt:
            lo = force ? P::kMinForceScale : P::kMinTorqueScale, hi = force ? P::kMaxForceScale : P::kMaxTorqueScale;
            span_min = force ? P::kMinForceSpan : P::kMinTorqueSpan, unit = force ? "N per count" : "Nm per count";
            break;
        case Target::kTau: lo = P::kMinTorqueScale, hi = P::kMaxTorqueScale, unit = "Nm per count"; break;
        case Target::kPwm: lo = P::kMinDutyScale, hi = P::kMaxDutyScale, span_min = P::kMinDutySpan, unit = "duty per count"; break;
        case Target::kCurrent: lo = P::kMinCurrentScale, hi = P::kMaxCurrentScale, unit = "A per count"; break;
        default: return "";
    }
    if (scale < lo || scale > hi)
        return "'" + t + "': scale " + number(s.scale) + " " + unit + " is outside the plausible " + number(lo) +
               " to " + number(hi) + " (rt_monitor/include/rt_monitor/plausibility.hpp): a full scale or a count per "
               "unit off by orders of magnitude";
    const double span = scale * (std::ldexp(1.0, s.length) - 1.0);
    if (span < span_min)
        return "'" + t + "': its " + std::to_string(s.length) + " bits at scale " + number(s.scale) + " span only " +
               number(span) + ", less than the plausible " + number(span_min) + " (a full scale far too small)";
    // A sensor that reads both ways (velocity, force, torque, duty, current) reads zero inside its range, and not
    // at an edge: an offset that puts zero outside the middle half of the decoded range is a wrong offset.
    if (s.target != Target::kQ) {
        const double first = s.type == SignalType::kSigned ? -std::ldexp(1.0, s.length - 1) : 0.0;
        const double low = std::min(first * s.scale, (first + std::ldexp(1.0, s.length) - 1.0) * s.scale) + s.offset;
        const double high = low + span;
        if (!(low + span / 4 <= 0 && 0 <= high - span / 4))
            return "'" + t + "': offset " + number(s.offset) + " puts its decoded range at " + number(low) + " to " +
                   number(high) + ": a sensor that reads both ways holds zero in the middle half of its range";
    }
    return "";
}

}  // namespace dynid::rt
