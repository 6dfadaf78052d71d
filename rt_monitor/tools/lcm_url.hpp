// The monitor's LCM URL: checked before anything is opened (the same rules as dynid.export.monitor_config, tested
// together), opened with what liblcm says caught, and a replay's file:// log written beside its path and renamed into
// place when the replay runs to its end.
#pragma once

#include <lcm/lcm-cpp.hpp>

#include <memory>
#include <string>

namespace dynid::rt {

// The URL a file:// URL should have been to be written (mode=w), or "" if it is fine or no file:// URL.
std::string file_url_for_writing(const std::string& url);
// Why liblcm could not open `url` as the monitor's LCM (a provider it lacks, a multicast group outside 224.0.0.0/4,
// a port or ttl out of range), or "": a configuration error (exit 2).
std::string lcm_url_problem(const std::string& url);
// lcm::LCM(url), with what liblcm writes to fd 2 meanwhile returned in `said`, folded to one line.
std::unique_ptr<lcm::LCM> open_lcm(const std::string& url, std::string& said);

// A replay's log: written to `partial`, renamed to `path` when the replay ends whole, else to PATH.failed.
struct PartialLog {
    std::string path, partial;
};
// Points a file:// `url` (mode=w) at PATH.partial and fills `log`; false (the URL left as it is) where it does not
// apply: another provider, mode=a, a path liblcm would refuse, a link.
bool partial_log(std::string& url, PartialLog& log);

}  // namespace dynid::rt
