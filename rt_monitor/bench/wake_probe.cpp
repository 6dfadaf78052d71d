// wake_probe: what the platform lets a real-time loop do (docs/benchmarks.md "Soak"). It sleeps to absolute deadlines
// every --period-us on CLOCK_MONOTONIC (as a 1 kHz loop waits for its next sample), optionally SCHED_FIFO at
// --priority (the monitor's), memory locked, and measures how late each wake-up is; SIGINT/SIGTERM end it, and it
// prints one JSON object: wake-ups, how many were later than one period, p50/p99/max lateness (µs).
//
//   wake_probe [--period-us US] [--priority P]
#include <sched.h>
#include <sys/mman.h>
#include <time.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {
volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }
}  // namespace

int main(int argc, char** argv) {
    long period_us = 1000;
    int priority = 0;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!std::strcmp(argv[i], "--period-us")) period_us = std::strtol(argv[i + 1], nullptr, 10);
        else if (!std::strcmp(argv[i], "--priority")) priority = int(std::strtol(argv[i + 1], nullptr, 10));
        else {
            std::fprintf(stderr, "usage: wake_probe [--period-us US] [--priority P]\n");
            return 2;
        }
    }
    if (period_us < 10) return 2;
    if (priority > 0) {
        sched_param sp{};
        sp.sched_priority = priority;
        if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0) {
            std::perror("wake_probe: SCHED_FIFO");
            return 4;
        }
    }
    std::vector<double> late;
    late.reserve(size_t(1) << 22);  // 70 min at 1 kHz; past that the figures cover the first 4 Mi wake-ups
    mlockall(MCL_CURRENT | MCL_FUTURE);
    struct sigaction sa {};
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
    timespec next{};
    clock_gettime(CLOCK_MONOTONIC, &next);
    long over = 0, n = 0;
    while (!g_stop) {
        next.tv_nsec += period_us * 1000;
        while (next.tv_nsec >= 1000000000) {
            next.tv_nsec -= 1000000000;
            ++next.tv_sec;
        }
        if (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr) != 0) continue;  // a signal
        timespec now{};
        clock_gettime(CLOCK_MONOTONIC, &now);
        const double us = double(now.tv_sec - next.tv_sec) * 1e6 + double(now.tv_nsec - next.tv_nsec) * 1e-3;
        ++n;
        over += us > double(period_us);
        if (late.size() < late.capacity()) late.push_back(us);
        if (us > double(period_us)) next = now;  // far behind: start again from now, no burst of catch-up wake-ups
    }
    std::sort(late.begin(), late.end());
    auto q = [&](double p) { return late.empty() ? 0.0 : late[size_t(p * double(late.size() - 1))]; };
    std::printf("{\"wakeups\":%ld,\"over_period\":%ld,\"period_us\":%ld,\"priority\":%d,\"p50\":%.1f,\"p99\":%.1f,"
                "\"p999\":%.1f,\"max\":%.1f}\n",
                n, over, period_us, priority, q(0.5), q(0.99), q(0.999), late.empty() ? 0.0 : late.back());
    return 0;
}
