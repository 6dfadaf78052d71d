#include "rt_monitor/rt_settings.hpp"

#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace dynid::rt {

namespace {

std::string limit_text(int resource) {
    rlimit r{};
    if (getrlimit(resource, &r) != 0) return "?";
    return r.rlim_cur == RLIM_INFINITY ? "unlimited" : std::to_string(static_cast<unsigned long long>(r.rlim_cur));
}

// Ascending CPU numbers as "0-1,3".
std::string cpu_list_text(const std::vector<int>& cpus) {
    std::string out;
    for (size_t i = 0; i < cpus.size(); ++i) {
        size_t e = i;
        while (e + 1 < cpus.size() && cpus[e + 1] == cpus[e] + 1) ++e;
        out += (out.empty() ? "" : ",") + std::to_string(cpus[i]) + (e > i ? "-" + std::to_string(cpus[e]) : "");
        i = e;
    }
    return out;
}

// The CPUs this process may run on, as "0-1,3".
std::string allowed_cpus() {
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(0, sizeof set, &set) != 0) return "?";
    std::vector<int> cpus;
    for (int c = 0; c < CPU_SETSIZE; ++c)
        if (CPU_ISSET(c, &set)) cpus.push_back(c);
    return cpu_list_text(cpus);
}

constexpr int kMaxCpu = 1000000;

}  // namespace

bool parse_int(const std::string& text, long lo, long hi, int& out) {
    char* end = nullptr;
    errno = 0;
    const long v = std::strtol(text.c_str(), &end, 10);
    if (text.empty() || *end != '\0' || errno != 0 || v < lo || v > hi) return false;
    out = int(v);
    return true;
}

bool parse_cpu_list(const std::string& text, std::vector<int>& cpus) {
    cpus.clear();
    size_t start = 0;
    while (start <= text.size()) {
        const size_t comma = std::min(text.find(',', start), text.size());
        const std::string item = text.substr(start, comma - start);
        const size_t dash = item.find('-');
        int lo = 0, hi = 0;
        if (!parse_int(item.substr(0, dash), 0, kMaxCpu, lo)) return false;
        hi = lo;
        if (dash != std::string::npos && (!parse_int(item.substr(dash + 1), 0, kMaxCpu, hi) || hi < lo)) return false;
        if (!cpus.empty() && lo <= cpus.back()) return false;  // ascending, no repeats
        if (hi - lo >= CPU_SETSIZE) return false;
        for (int c = lo; c <= hi; ++c) cpus.push_back(c);
        start = comma + 1;
    }
    return !cpus.empty();
}

int apply_rt_settings(const RtSettings& s, std::string& err) {
    if (!s.cpus.empty()) {
        cpu_set_t set;
        CPU_ZERO(&set);
        bool representable = true;
        for (int c : s.cpus) {
            if (c < CPU_SETSIZE) CPU_SET(c, &set);
            else representable = false;
        }
        if (!representable || sched_setaffinity(0, sizeof set, &set) != 0) {
            const int e = representable ? errno : EINVAL;
            err = "--cpu " + cpu_list_text(s.cpus) + ": the system refused the CPU affinity (" + std::strerror(e) +
                  "): this process may run on CPUs " + allowed_cpus();
            return kExitCpuRefused;
        }
    }
    if (s.mlockall && mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
        const int e = errno;
        err = std::string("--mlockall: the system refused to lock the process's memory (") + std::strerror(e) +
              "): needs CAP_IPC_LOCK or an RLIMIT_MEMLOCK above the process's size (now " +
              limit_text(RLIMIT_MEMLOCK) + " bytes; ulimit -l, LimitMEMLOCK= in the unit)";
        return kExitMlockallRefused;
    }
    if (s.fifo) {
        sched_param p{};
        p.sched_priority = s.priority;
        if (sched_setscheduler(0, SCHED_FIFO, &p) != 0) {
            const int e = errno;
            const int lo = sched_get_priority_min(SCHED_FIFO), hi = sched_get_priority_max(SCHED_FIFO);
            err = "--priority " + std::to_string(s.priority) + ": the system refused SCHED_FIFO (" + std::strerror(e) +
                  "): " + (s.priority < lo || s.priority > hi
                               ? "its priorities are " + std::to_string(lo) + ".." + std::to_string(hi)
                               : "needs CAP_SYS_NICE or an RLIMIT_RTPRIO of at least " + std::to_string(s.priority) +
                                     " (now " + limit_text(RLIMIT_RTPRIO) + "; LimitRTPRIO= in the unit)");
            return kExitPriorityRefused;
        }
    }
    return 0;
}

std::string describe_rt_settings(const RtSettings& s) {
    return std::string("mlockall ") + (s.mlockall ? "on" : "off") + ", " +
           (s.fifo ? "SCHED_FIFO priority " + std::to_string(s.priority) : std::string("default scheduling")) +
           ", " + (s.cpus.size() == 1 ? "CPU " + std::to_string(s.cpus[0])
                                       : "CPUs " + (s.cpus.empty() ? allowed_cpus() : cpu_list_text(s.cpus)));
}

}  // namespace dynid::rt
