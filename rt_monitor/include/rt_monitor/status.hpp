// The supply ratios of rt_monitor's status message (dynid.monitor_status_t): one per input channel of the
// coefficient file, in its channel order. The array is sized once at start-up; filling it in the loop only writes
// doubles, so the message's encoded size, and the encode buffer sized from it, never change.
// Needs the lcm-gen C++ headers on the include path (build/rt_monitor/lcmgen).
#pragma once

#include "dynid/monitor_status_t.hpp"
#include "rt_monitor/core.hpp"

namespace dynid::rt {

// Start-up (allocates): n_supply = the number of input channels, every ratio 1.
inline void init_supply(const Coefficients& c, dynid::monitor_status_t& st) {
    int n = 0;
    for (int i = 0; i < c.n_outputs; ++i) n += c.channel_kind[size_t(i)] == ChannelKind::kInput;
    st.n_supply = int16_t(n);
    st.supply_ratio.assign(size_t(n), 1.0);
}

// In the loop (no allocation): the core's current ratio of each input channel.
inline void fill_supply(const Coefficients& c, const Core& core, dynid::monitor_status_t& st) noexcept {
    size_t k = 0;
    for (int i = 0; i < c.n_outputs && k < st.supply_ratio.size(); ++i)
        if (c.channel_kind[size_t(i)] == ChannelKind::kInput) st.supply_ratio[k++] = core.supply_ratio(i);
}

}  // namespace dynid::rt
