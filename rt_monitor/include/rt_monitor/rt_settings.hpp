// Real-time settings of the monitor process (rt_monitor --mlockall --priority N --cpu LIST), applied once at
// start-up, before the loop. Each one the system refuses is a clear message and its own exit code.
#pragma once

#include <string>
#include <vector>

namespace dynid::rt {

struct RtSettings {
    bool mlockall = false;  // lock current and future pages: no page faults in the loop
    bool fifo = false;      // switch to SCHED_FIFO at `priority` (false: leave the scheduling policy alone)
    int priority = 0;
    std::vector<int> cpus;  // pin to these CPUs; empty = any
};

// Exit codes of a refusal (distinct from 1 failure, 2 bad arguments, 10+ a refused coefficient file).
constexpr int kExitMlockallRefused = 3;
constexpr int kExitPriorityRefused = 4;
constexpr int kExitCpuRefused = 5;

// A whole decimal integer in [lo, hi], or false (the options' values).
bool parse_int(const std::string& text, long lo, long hi, int& out);

// Parses a CPU list as taskset -c takes it ("1", "0,2", "0-3,6"): ascending, no repeats. False on anything else.
bool parse_cpu_list(const std::string& text, std::vector<int>& cpus);

// Applies the affinity, then mlockall, then the priority (so the set-up before it does not run at RT priority).
// Returns 0, or the refusal's exit code with `err` one line naming the setting, the reason and the remedy.
int apply_rt_settings(const RtSettings& s, std::string& err);

// "mlockall on, SCHED_FIFO priority 50, CPU 1" or "…, CPUs 0-1" (the start-up line): what the process now runs with.
std::string describe_rt_settings(const RtSettings& s);

}  // namespace dynid::rt
