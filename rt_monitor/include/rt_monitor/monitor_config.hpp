// The monitor's configuration file (docs/formats.md, "rt_monitor configuration"): settings, and the robot's bus as
// the compiled table dynid writes (bus_table.hpp). One `key values…` line each, `#` comments, keys in any order.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "rt_monitor/bus_table.hpp"

namespace dynid::rt {

struct MonitorConfig {
    std::string robot;
    std::vector<std::string> buses;
    std::string lcm_url;                 // empty: LCM's default (UDP multicast, ttl=0)
    int64_t stale_us = 5000, pair_us = 500;
    double status_hz = 10;
    int residual_every = 10;             // publish one residual message every N evaluated samples
    double contact_limit_s = 10;         // a contact held longer is a watchdog fault (kLongContact)
    BusTable bus;
};

// The configuration's limits: a value outside them is refused, not clamped.
constexpr double kStaleMsMin = 0.1, kStaleMsMax = 1000;  // beyond a second the staleness guard is as good as off
constexpr long long kPairUsMin = 1, kPairUsMax = 10000;  // two halves further apart are not one conversion
constexpr double kStatusHzMin = 0.1, kStatusHzMax = 1000;  // at most one status per 1 kHz sample
constexpr long long kResidualEveryMax = 100000;
constexpr double kContactLimitSMin = 0.1, kContactLimitSMax = 86400;  // from a tap to a day of holding
constexpr long long kPeriodUsMax = 60000000;    // a frame's period: up to a minute
constexpr long long kOffsetUsMin = -1000000;    // a frame's send time: up to a second before its sample

// The status message's period in CAN time, µs (status_hz within its limits: 1 000 to 10 000 000).
inline int64_t status_period_us(const MonitorConfig& c) noexcept { return int64_t(1e6 / c.status_hz); }

// Parses the configuration from its text; `path` names it in messages. False and one line naming the file, the line
// and the problem on error (line 0: the file as a whole).
bool parse_monitor_config(const std::string& text, const std::string& path, MonitorConfig& out, std::string& error);
// The same, read from the file at `path`.
bool load_monitor_config(const std::string& path, MonitorConfig& out, std::string& error);

// The IDs of the table's frames on bus `bus` (SocketCAN's per-socket filter list).
std::vector<uint32_t> bus_ids(const MonitorConfig& c, int bus);

}  // namespace dynid::rt
