// A value signal of the monitor's configuration against the sensors' plausible ranges (rt_monitor/plausibility.hpp):
// its scale, the span its bits reach, and where its offset puts zero. Checked once, at start-up, by the parser.
#pragma once

#include <string>

#include "rt_monitor/bus_table.hpp"

namespace dynid::rt {

// "" if the signal carrying `target` (its text, e.g. ft.r_arm_ft.fx) is plausible for its kind of target, else one
// line saying why: a full scale or a count per unit off by orders of magnitude, a span too small, a wrong offset.
std::string implausible_signal(const std::string& target, const SignalDef& s);

}  // namespace dynid::rt
