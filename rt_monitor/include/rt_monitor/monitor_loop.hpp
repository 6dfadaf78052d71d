// rt_monitor's loop: frames from a source, samples assembled, placed on the sample clock's grid, stepped through the
// core, events / residuals / status published, the watchdog told of everything. After run() starts: no allocation
// (but liblcm's provider inside lcm_publish), no lock, no exception; the I/O is the source's reads, the publishes
// and a watchdog's fault line on stderr (once per fault raised).
#pragma once

#include <csignal>
#include <cstdint>
#include <vector>

#include "rt_monitor/assembler.hpp"
#include "rt_monitor/core.hpp"
#include "rt_monitor/fit_coverage.hpp"
#include "rt_monitor/frame_source.hpp"
#include "rt_monitor/publisher.hpp"
#include "rt_monitor/run_stats.hpp"
#include "rt_monitor/sample_clock.hpp"
#include "rt_monitor/watchdog.hpp"

namespace dynid::rt {

struct LoopOptions {
    bool live = false;             // a live source (SocketCAN, loopback): response times from the kernel's stamps
    bool stats = false;            // keep the processing and response histograms (--stats-out)
    size_t latency_capacity = 0;   // onsets whose publish latency is kept (--latency-out), reserved at start-up
};

// What the loop counted, for the exit line and --stats-out.
struct LoopCounters {
    int64_t evaluated = 0, events = 0, onsets = 0, ends = 0, cut = 0, overruns = 0;  // events = onsets + ends + cut
    int64_t events_under_fault = 0;  // events published while a watchdog fault was active (they carry it)
    int64_t beyond_fit = 0;        // evaluated samples with a joint beyond the fit's range (FitCoverage)
    double loop_max_us = 0;
    long long allocations = 0;     // heap allocations from the first read to the last publish
};

class MonitorLoop {
public:
    MonitorLoop(const MonitorConfig& cfg, const Coefficients& coef, Core& core, Assembler& assembler,
                Publisher& publisher, Watchdog& watchdog, const LoopOptions& options);
    // Runs until the source ends, fails (1, its reason on stderr) or `stop` is set; 0 otherwise.
    int run(FrameSource& source, const volatile std::sig_atomic_t& stop);

    const LoopCounters& counters() const noexcept { return n_; }
    const SampleClock& clock() const noexcept { return clock_; }
    const LatencyHistogram& processing() const noexcept { return processing_; }
    const LatencyHistogram& response() const noexcept { return response_; }
    const std::vector<double>& latencies() const noexcept { return latency_; }
    double period_us() const noexcept { return period_us_; }

private:
    void place(const ClockStep& c) noexcept;
    void step(const Sample& x) noexcept;
    void fill_status(int64_t t_us) noexcept;

    const MonitorConfig& cfg_;
    Core& core_;
    Assembler& asm_;
    Publisher& pub_;
    Watchdog& dog_;
    LoopOptions opt_;
    FrameSource* src_ = nullptr;
    SampleClock clock_;
    FitCoverage coverage_;
    Sample sample_;
    LoopCounters n_;
    double period_us_ = 0, rx_mono_ = 0, loop_sum_ = 0, loop_max_ = 0;
    int64_t loop_n_ = 0, onset_utime_ = 0, peak_utime_ = 0, last_evaluated_utime_ = 0;
    uint64_t peak_beyond_ = 0;  // the joints beyond the fit's range at the sample the next event describes
    LatencyHistogram processing_, response_;
    std::vector<double> latency_;
};

double mono_us() noexcept;
double real_us() noexcept;  // CLOCK_REALTIME, the clock of the kernel's SO_TIMESTAMP stamps

}  // namespace dynid::rt
