#include "rt_monitor/rt_settings.hpp"

#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>

#include <cerrno>
#include <cstring>
#include <string>

namespace dynid::rt {

namespace {

std::string limit_text(int resource) {
    rlimit r{};
    if (getrlimit(resource, &r) != 0) return "?";
    return r.rlim_cur == RLIM_INFINITY ? "unlimited" : std::to_string(static_cast<unsigned long long>(r.rlim_cur));
}

// The CPUs this process may run on, as "0-1,3".
std::string allowed_cpus() {
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(0, sizeof set, &set) != 0) return "?";
    std::string out;
    for (int c = 0; c < CPU_SETSIZE; ++c) {
        if (!CPU_ISSET(c, &set)) continue;
        int e = c;
        while (e + 1 < CPU_SETSIZE && CPU_ISSET(e + 1, &set)) ++e;
        out += (out.empty() ? "" : ",") + std::to_string(c) + (e > c ? "-" + std::to_string(e) : "");
        c = e;
    }
    return out;
}

}  // namespace

int apply_rt_settings(const RtSettings& s, std::string& err) {
    if (s.cpu >= 0) {
        cpu_set_t set;
        CPU_ZERO(&set);
        if (s.cpu < CPU_SETSIZE) CPU_SET(s.cpu, &set);
        if (s.cpu >= CPU_SETSIZE || sched_setaffinity(0, sizeof set, &set) != 0) {
            const int e = s.cpu >= CPU_SETSIZE ? EINVAL : errno;
            err = "--cpu " + std::to_string(s.cpu) + ": the system refused the CPU affinity (" + std::strerror(e) +
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
           ", " + (s.cpu >= 0 ? "CPU " + std::to_string(s.cpu) : "CPUs " + allowed_cpus());
}

}  // namespace dynid::rt
