// rt_monitor --model COEF --config CONFIG [--replay CANDUMP.log [--realtime]] [--loopback DIR] [--lcm-url URL]
//            [--mlockall] [--priority N] [--cpu LIST] [--latency-out FILE] [--stats-out FILE] [--help]
//
// Frames in (SocketCAN on the configured buses, a candump -L replay, or the loopback transport), samples
// assembled, the core stepped, contact events / status (10 Hz) / decimated residuals out on LCM.
// SIGINT and SIGTERM end the run cleanly; the final counters are printed on stdout either way.
// --mlockall, --priority N (SCHED_FIFO) and --cpu LIST (affinity) are applied once before the loop; the start-up line
// on stderr says what the process runs with.
// --latency-out (benchmarks): per contact onset, CLOCK_MONOTONIC µs from the return of the read of the frame
// that completed the onset sample to the return of its LCM publish, one per line, written at exit.
// --stats-out (soak, docs/benchmarks.md "Soak"): at exit, a JSON object with every counter (frames by kind, the sample
// clock's taken/held/lost), the heap allocations made after start-up (all, and those inside lcm_publish), the
// samples' processing and response times (loop overruns, missed deadlines), the messages published, the resident set.
// A replay's file:// log (mode=w) is renamed into place when the replay runs to its end; a failed one's is PATH.failed.
// Exit codes: 0 done, 2 bad arguments or configuration, 1 a source or LCM failure, 3 mlockall refused, 4 SCHED_FIFO
// refused, 5 CPU affinity refused, 6 nothing evaluated or ended blind (the watchdog), 7 a replay that raised a fault,
// 10+ a refused coefficient file.
#include <sched.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <string>
#include <vector>

#include "rt_monitor/assembler.hpp"
#include "rt_monitor/core.hpp"
#include "rt_monitor/monitor_loop.hpp"
#include "rt_monitor/publisher.hpp"
#include "rt_monitor/rt_settings.hpp"
#include "rt_monitor/run_stats.hpp"
#include "rt_monitor/watchdog.hpp"

#include "lcm_url.hpp"

using namespace dynid::rt;

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

constexpr const char* kSynopsis =
    "usage: rt_monitor --model COEF --config CONFIG [--replay CANDUMP.log [--realtime]] [--loopback DIR] "
    "[--lcm-url URL] [--residual acceleration|momentum|combined] [--mlockall] [--priority N] [--cpu LIST] [--latency-out FILE] [--stats-out FILE] [--help]\n";

constexpr const char* kHelp = R"(
The real-time contact monitor: reads the robot's CAN frames, decodes them through the configuration's bus table
(any protocol: `dynid export --monitor-config` compiles the robot's bus description), assembles a sample at each
clock frame, predicts the measured outputs (every F/T sensor's wrench, every motor input: PWM, current or joint
torque) with the identified model (the acceleration residuals), runs its momentum observer, or both in the combined
detector (the file says which, --residual overrides), computes Hotelling T2 and publishes contact events (every
sensor's side and residual wrench, the external joint torques, the isolated link), a status (counters, loop times,
supply ratios, faults) and decimated residuals on LCM (channels DYNID_CONTACT, DYNID_STATUS, DYNID_RESIDUAL).
SIGINT or SIGTERM ends the run; the final counters are printed on stdout.

required:
  --model COEF          the coefficient file written by `dynid export` (refused with exit 10 + the reason if
                        damaged, of another format version or exported for another robot)
  --config CONFIG       the monitor configuration: buses, the bus table (which frame and bits carry which
                        joint or channel, scale and offset), the sample clock, timing, LCM URL (written by
                        `dynid export --monitor-config`; rt_monitor/README.md, "The monitor program")

frame source (default: SocketCAN raw sockets on the configured buses, kernel filters and timestamps):
  --replay CANDUMP.log  replay a `candump -L` log instead, as fast as possible
  --realtime            with --replay: at the log's own pace
  --loopback DIR        read the loopback transport: one datagram socket per bus at DIR/<bus>.can
                        (`boards --sink loopback:DIR --realtime` sends to it); excludes --replay

detection:
  --residual R          acceleration, momentum or combined: run this instead of what the file selects (momentum
                        needs a file that carries the observer, combined one with its combined_scale too:
                        `dynid export` writes them)

output:
  --lcm-url URL         LCM URL, overriding the configuration's lcm_url (default: LCM's own, UDP multicast);
                        tests use file://PATH?mode=w or memq://
  --latency-out FILE    benchmarks: per contact onset, the CLOCK_MONOTONIC microseconds from the read of the
                        frame completing the onset sample to the return of its publish, written at exit
  --stats-out FILE      soak and benchmarks: at exit, a JSON object with every counter (frames by kind, the
                        sample clock's), the heap allocations after start-up, each sample's processing time
                        (from the read of its completing frame to the end of its processing and publishing)
                        and response time (from that frame's kernel stamp; live sources), their p50, p99, max
                        and how many exceeded one sample period, the messages published and the resident set

real time (applied once before the loop; a refusal has its own exit code):
  --mlockall            lock the process's memory (mlockall MCL_CURRENT|MCL_FUTURE)
  --priority N          run SCHED_FIFO at priority N
  --cpu LIST            pin to the CPUs in LIST, as taskset -c takes it (1, 0,2 or 0-3)

  -h, --help            print this help on stdout and exit 0

exit codes: 0 done (end of input, or SIGINT/SIGTERM); 1 a source or LCM failure; 2 bad arguments or
configuration; 3 mlockall refused; 4 SCHED_FIFO refused; 5 CPU affinity refused; 6 the run evaluated no sample,
or ended blind (the watchdog's reason on stderr); 7 a replay read to its end that raised a watchdog fault (one
line names them; its LCM log is written, and each contact event carries the faults active then); 10 + the reason
a coefficient file was refused (11 unreadable ... 20 another robot, 21 a value no robot has, 22 the core does not
reproduce the file's known answers).

the watchdog: frames arriving with no sample evaluated for 5 sample periods, a frame of the bus silent for a
second, T2 not finite, the stream's sample period not the file's, a joint position or a PWM duty out of its range,
a live source stopped, T2 above its level through the start, samples bridged, stamps going back, a contact held
longer than contact_limit_s: each is a status fault (DYNID_STATUS faults, faults_seen; on a contact event, those
active) and one line on stderr with its reason, never a contact.
)";

int usage(const std::string& why) {
    std::fprintf(stderr, "rt_monitor: error: %s\n%s", why.c_str(), kSynopsis);
    return 2;
}

int help() {
    std::fputs(kSynopsis, stdout);
    std::fputs(kHelp, stdout);
    return std::fflush(stdout) == 0 ? 0 : 1;
}

// The parent directory exists and the path is not a directory (or another non-file): what rename() needs.
bool writable_file(const std::string& path) {
    struct stat st {};
    if (stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
        errno = S_ISDIR(st.st_mode) ? EISDIR : EINVAL;
        return false;
    }
    const size_t slash = path.rfind('/');
    const std::string dir = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
    if (stat(dir.c_str(), &st) != 0) return false;  // errno: ENOENT, ...
    if (!S_ISDIR(st.st_mode)) {
        errno = ENOTDIR;
        return false;
    }
    // written beside, then renamed into place: the folder must take a new file (errno: EACCES, EROFS)
    return access(dir.c_str(), W_OK | X_OK) == 0;
}

constexpr int kExitBlind = 6;  // a run that evaluated no sample, or ended blind (the watchdog's reason)
// A replay read to its end whose watchdog raised a fault: its events (each carrying the faults then active) came from
// data the monitor suspected. Not for a live run, which ends by a signal and whose sources stop before it does.
constexpr int kExitFaulted = 7;

std::unique_ptr<FrameSource> open_source(const MonitorConfig& cfg, const std::string& replay, const std::string& loopback,
                                         bool realtime, std::string& err) {
    if (!replay.empty()) return CandumpReplay::open(replay, cfg.buses, realtime, err);
    if (!loopback.empty()) return LoopbackSource::open(loopback, cfg.buses, err);
    std::vector<std::vector<can_filter>> filters;  // per bus, the table's IDs on it
    for (size_t b = 0; b < cfg.buses.size(); ++b) filters.push_back(socketcan_filters(bus_ids(cfg, int(b))));
    return SocketCanSource::open(cfg.buses, filters, err);
}

// The final counters on stdout, one line (the same whatever ended the run).
void print_exit_line(const char* how, const Assembler& a, const FrameSource& src, const MonitorLoop& loop,
                     const Publisher& pub) {
    const ClockCounters& cc = loop.clock().counters();
    const MonitorCounters& c = a.counters();
    const SourceCounters& sc = src.counters();
    const LoopCounters& n = loop.counters();
    std::printf("rt_monitor: %s; frames %lld, samples %lld, evaluated %lld, stale %lld, events %lld, unknown id %lld, "
                "bad length %lld, error frames %lld, unpaired halves %lld, saturated %lld, board faults %lld, "
                "board restarts %lld, bad source input %llu, interpolated %lld, late %lld, filter restarts %lld, overruns %lld, "
                "kernel drops %llu, beyond the fit's postures %lld, publish failures %lld\n",
                how, (long long)c.frames, (long long)c.samples, (long long)n.evaluated, (long long)c.stale_samples,
                (long long)n.events, (long long)c.unknown_id, (long long)c.bad_length, (long long)c.error_frames,
                (long long)c.unpaired_strain, (long long)c.saturated, (long long)c.board_faults,
                (long long)c.board_restarts, (unsigned long long)(sc.bad_lines + sc.unknown_bus + sc.bad_size),
                (long long)cc.interpolated, (long long)cc.late, (long long)cc.restarts, (long long)n.overruns,
                (unsigned long long)sc.kernel_drops, (long long)n.beyond_fit,
                (long long)(pub.failed() + pub.unencoded()));
}

// --stats-out: one JSON object with every counter (their identities: rt_monitor/README.md, "Accounting"), the heap
// allocations after start-up and the resident set, written beside the path and renamed into place.
bool write_stats(const std::string& path, const Assembler& a, const FrameSource& src, const MonitorLoop& loop,
                 const Publisher& pub, const Core& core, bool signalled, int rc, const std::string& replay,
                 bool realtime, const std::string& loopback) {
    long long rss = 0, hwm = 0;
    resident_kb(rss, hwm);
    const std::string tmp = path + ".tmp";
    std::FILE* f = std::fopen(tmp.c_str(), "w");
    if (!f) return false;
    const ClockCounters& cc = loop.clock().counters();
    const MonitorCounters& c = a.counters();
    const SourceCounters& sc = src.counters();
    const LoopCounters& n = loop.counters();
    JsonOut j(f);
    j.str("source", !replay.empty() ? (realtime ? "replay, real time" : "replay") : !loopback.empty() ? "loopback" : "socketcan")
        .str("stopped", signalled ? "signal" : (rc ? "failed" : "end of input"))
        .real("period_us", loop.period_us());
    // frames = error + unknown_id + bad_length + strain + position + pid + status + skin + sensor (by what the bus
    // table says each carries: strain the clock pair's halves, pid the inputs, sensor other F/T pairs)
    j.open("frames")
        .num("total", c.frames).num("error", c.error_frames).num("unknown_id", c.unknown_id)
        .num("bad_length", c.bad_length).num("strain", c.strain_frames).num("position", c.position_frames)
        .num("pid", c.pid_frames).num("status", c.status_frames).num("skin", c.skin_frames)
        .num("sensor", c.sensor_frames).num("unpaired_sensor", c.unpaired_sensor)
        .num("saturated", c.saturated).num("unpaired_strain", c.unpaired_strain)
        .num("pending_strain", a.pending_strain()).num("board_faults", c.board_faults)
        .num("board_restarts", c.board_restarts)
        .close();
    j.open("source_counters")
        .num("frames", (long long)sc.frames).num("bad_lines", (long long)sc.bad_lines)
        .num("unknown_bus", (long long)sc.unknown_bus).num("bad_size", (long long)sc.bad_size)
        .num("kernel_drops", (long long)sc.kernel_drops).num("first_bad_line", (long long)sc.first_bad_line)
        .num("first_unknown_bus", (long long)sc.first_unknown_bus)
        .close();
    j.open("samples")  // evaluated = taken − held + interpolated; taken = assembled − stale
        .num("assembled", c.samples).num("stale", c.stale_samples).num("taken", cc.taken).num("held", cc.held)
        .num("lost", cc.lost).num("interpolated", cc.interpolated).num("late", cc.late)
        .num("evaluated", n.evaluated).num("filter_restarts", cc.restarts).num("beyond_fit", n.beyond_fit)
        .close();
    // onsets = ends + cut (open at a filter restart) + in_contact (open at the end)
    j.open("events").num("total", n.events).num("onsets", n.onsets).num("ends", n.ends).num("cut", n.cut)
        .num("under_fault", n.events_under_fault)
        .num("in_contact", core.output().in_contact).close();
    j.open("published")
        .num("contact", pub.published(Publisher::kContact)).num("residual", pub.published(Publisher::kResidual))
        .num("status", pub.published(Publisher::kStatus)).num("failed", pub.failed()).num("unencoded", pub.unencoded())
        .close();
    j.open("core_step_us").real("max", n.loop_max_us).num("over_period", n.overruns).close();
    auto histogram = [&](const char* name, const char* from, const LatencyHistogram& h) {
        j.open(name).str("from", from).num("samples", h.count()).real("p50", h.quantile(0.5))
            .real("p99", h.quantile(0.99)).real("p999", h.quantile(0.999)).real("max", h.max())
            .num("over_period", h.over());
        j.list("worst");  // the largest, with their samples' CAN time (s)
        for (int i = 0; i < h.worst_count(); ++i) j.item(h.worst_us(i));
        j.close_list().list("worst_at_s");
        for (int i = 0; i < h.worst_count(); ++i) j.item(double(h.worst_tag(i)) * 1e-6);
        j.close_list().close();
    };
    const bool live = replay.empty();
    histogram("processing_us", "return of the read of the completing frame", loop.processing());
    histogram("response_us", live ? "kernel stamp of the completing frame" : "return of the read", loop.response());
    j.open("allocations")  // after start-up: from the first read to the last publish
        .num("after_startup", n.allocations).num("in_lcm_publish", pub.allocations_in_publish())
        .num("elsewhere", n.allocations - pub.allocations_in_publish()).flag("malloc_counted", allocations_count_malloc())
        .close();
    j.num("rss_kb", rss).num("hwm_kb", hwm);
    j.end();
    const bool ok = std::fclose(f) == 0;
    return ok && std::rename(tmp.c_str(), path.c_str()) == 0;
}

}  // namespace

int main(int argc, char** argv) {
    std::string model, config, replay, loopback, url, latency_out, stats_out;
    std::string priority, cpu, residual;
    bool have_url = false, have_cpu = false, realtime = false;
    RtSettings rts;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&](std::string& v) {
            if (i + 1 >= argc) return false;
            v = argv[++i];
            return true;
        };
        // A path option's empty value is none: `--replay ""` fell through to SocketCAN (issue 22's sweep).
        auto path = [&](std::string& v) { return value(v) && !v.empty(); };
        bool ok = true;
        if (a == "--model") ok = path(model);
        else if (a == "--config") ok = path(config);
        else if (a == "--replay") ok = path(replay);
        else if (a == "--loopback") ok = path(loopback);
        else if (a == "--lcm-url") ok = have_url = value(url);
        else if (a == "--latency-out") ok = path(latency_out);
        else if (a == "--stats-out") ok = path(stats_out);
        else if (a == "--residual") ok = value(residual);
        else if (a == "--realtime") realtime = true;
        else if (a == "--mlockall") rts.mlockall = true;
        else if (a == "--priority") ok = rts.fifo = value(priority);
        else if (a == "--cpu") ok = have_cpu = value(cpu);
        else if (a == "--help" || a == "-h") return help();
        else return usage("unknown argument '" + a + "'");
        if (!ok) return usage("'" + a + "' needs a value");
    }
    if (model.empty() || config.empty()) return usage("--model and --config are required");
    if (!replay.empty() && !loopback.empty()) return usage("--replay and --loopback exclude each other");
    if (realtime && replay.empty()) return usage("--realtime paces a --replay: give the log to replay");
    if (!residual.empty() && residual != "acceleration" && residual != "momentum" && residual != "combined")
        return usage("--residual is acceleration, momentum or combined, not '" + residual + "'");
    // A priority outside SCHED_FIFO's range (which the system states, unprivileged) is a bad value, exit 2; what the
    // system refuses at start-up (a priority beyond RLIMIT_RTPRIO, a CPU not allowed) has an exit code of its own.
    if (rts.fifo && !parse_int(priority, -1000000, 1000000, rts.priority))
        return usage("--priority needs an integer, got '" + priority + "'");
    if (rts.fifo) {
        const int lo = sched_get_priority_min(SCHED_FIFO), hi = sched_get_priority_max(SCHED_FIFO);
        if (rts.priority < lo || rts.priority > hi)
            return usage("--priority " + priority + ": SCHED_FIFO's priorities are " + std::to_string(lo) + ".." +
                         std::to_string(hi));
    }
    if (have_cpu && !parse_cpu_list(cpu, rts.cpus))
        return usage("--cpu needs a CPU list as taskset -c takes it (1, 0,2 or 0-3), got '" + cpu + "'");

    // The latency file is written at exit: an unwritable one was found only after the whole run (and left its
    // temporary file behind when it named a directory).
    for (const auto& [flag, out] : {std::pair<const char*, const std::string*>{"--latency-out", &latency_out},
                                    {"--stats-out", &stats_out}}) {
        if (!out->empty() && !writable_file(*out)) {  // one line, no synopsis: the arguments were well formed
            std::fprintf(stderr, "rt_monitor: error: %s %s: %s\n", flag, out->c_str(), std::strerror(errno));
            return 2;
        }
    }

    std::string err;
    MonitorConfig cfg;
    // A refused configuration is one line naming the file, the line and the problem (no usage: the arguments were fine).
    auto bad_config = [](const std::string& why) {
        std::fprintf(stderr, "rt_monitor: error: %s\n", why.c_str());
        return 2;
    };
    if (!load_monitor_config(config, cfg, err)) return bad_config(err);
    auto coef = std::make_unique<Coefficients>();
    const LoadResult lr = load_coefficients(model, cfg.robot, *coef);
    if (lr.error != LoadError::kOk) {
        std::fprintf(stderr, "rt_monitor: error: %s\n", lr.message.c_str());
        return kExitBase + int(lr.error);
    }
    if (residual == "momentum" && !coef->has_observer())
        return bad_config(model + ": carries no momentum observer (export it again with dynid export), so "
                          "--residual momentum cannot run");
    if (residual == "combined" && !coef->has_combined())
        return bad_config(model + ": carries no combined detector (export it again with dynid export, from a model "
                          "whose observer it can calibrate), so --residual combined cannot run");
    Assembler asm_;
    if (!asm_.init(cfg, *coef, err)) return bad_config(config + ": " + err);

    if (!have_url) url = cfg.lcm_url;
    if (const std::string why = lcm_url_problem(url); !why.empty()) {
        std::fprintf(stderr, "rt_monitor: error: LCM URL '%s': %s\n", url.c_str(), why.c_str());
        return 2;
    }
    if (const std::string fixed = file_url_for_writing(url); !fixed.empty()) {
        std::fprintf(stderr,
                     "rt_monitor: error: LCM URL '%s' opens its file for reading (LCM's default without mode=w or "
                     "mode=a), and the monitor writes: %s\n", url.c_str(), fixed.c_str());
        return 2;
    }
    // Before the source and LCM are opened: a refused --priority or --cpu left an empty file:// LCM log (and the
    // loopback's sockets) behind (issue 22's sweep). mlockall's MCL_FUTURE still locks what they allocate.
    const int refused = apply_rt_settings(rts, err);
    if (refused) {
        std::fprintf(stderr, "rt_monitor: error: %s\n", err.c_str());
        return refused;
    }
    std::unique_ptr<FrameSource> src = open_source(cfg, replay, loopback, realtime, err);
    if (!src) {
        std::fprintf(stderr, "rt_monitor: error: %s\n", err.c_str());
        return replay.empty() ? 1 : 2;
    }
    PartialLog partial;
    const std::string given_url = url;  // what the start-up line names
    const bool in_parts = !replay.empty() && partial_log(url, partial);
    // liblcm writes its own reason to fd 2 ("Error: LCM provider ... not found"): caught and put on the one line.
    std::string lcm_said;
    std::unique_ptr<lcm::LCM> lcm = open_lcm(url, lcm_said);
    if (!lcm->good()) {
        std::fprintf(stderr, "rt_monitor: error: cannot open LCM at '%s'%s%s\n", url.c_str(),
                     lcm_said.empty() ? "" : ": ", lcm_said.c_str());
        return 1;
    }
    if (!lcm_said.empty()) std::fprintf(stderr, "rt_monitor: liblcm: %s\n", lcm_said.c_str());

    // Before the start-up line: a SIGTERM sent once it is read always ends in a clean stop with counters.
    struct sigaction sa {};
    sa.sa_handler = on_signal;  // no SA_RESTART: poll() returns, the loop sees the flag
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
    auto core = std::make_unique<Core>(*coef);
    if (!residual.empty())
        core->set_residual(residual == "momentum"   ? Residual::kMomentum
                           : residual == "combined" ? Residual::kCombined
                                                    : Residual::kAcceleration);
    core->set_detector({coef->debounce_on, coef->debounce_off, coef->hysteresis});
    std::fprintf(stderr, "rt_monitor: running: %s; LCM %s; %s; %s residuals%s\n",
                 !replay.empty() ? ("replay of " + replay + (realtime ? " in real time" : "")).c_str()
                 : !loopback.empty() ? ("loopback transport in " + loopback).c_str() : "SocketCAN",
                 (given_url.empty() ? std::string("default URL") : given_url).c_str(), describe_rt_settings(rts).c_str(),
                 core->residual() == Residual::kMomentum   ? "momentum-observer"
                 : core->residual() == Residual::kCombined ? "combined (momentum-observer and acceleration)"
                                                           : "acceleration",
                 // the loader checks a fitted file's core against its known answers; a CAD export has none to check
                 coef->estimator == "cad" ? "; a CAD export's file: no known answers to check the core against" : "");
    Publisher publisher(*lcm, *coef, *core);
    auto watchdog = std::make_unique<Watchdog>();
    watchdog->init(cfg, *coef, asm_);
    const LoopOptions options{replay.empty(), !stats_out.empty(), latency_out.empty() ? 0 : size_t(1) << 20};
    auto loop = std::make_unique<MonitorLoop>(cfg, *coef, *core, asm_, publisher, *watchdog, options);
    int rc = loop->run(*src, g_stop);

    print_exit_line(g_stop ? "stopped by signal" : (rc ? "failed" : "end of input"), asm_, *src, *loop, publisher);
    // Messages LCM refused (its provider's send failed, a full queue) or that did not encode: nobody saw them, and the
    // status that would say so went the same way. Said here, and never exit 0 (a provider that swallows its write
    // errors, as file:// on a full disk does, is beyond this count).
    if (const int64_t lost = publisher.failed() + publisher.unencoded(); lost > 0) {
        std::fprintf(stderr, "rt_monitor: error: %lld LCM messages were not published (%lld contact events, %lld "
                     "status, %lld residuals sent): the LCM URL's provider refused them\n", (long long)lost,
                     (long long)publisher.published(Publisher::kContact), (long long)publisher.published(Publisher::kStatus),
                     (long long)publisher.published(Publisher::kResidual));
        rc = rc ? rc : 1;
    }
    // A monitor that evaluated nothing, or ended blind, watched nothing: never exit 0 then (one line, the reason).
    const bool blind = rc == 0 && !g_stop && (loop->counters().evaluated == 0 || (watchdog->active() & kBlind));
    if (blind) rc = kExitBlind;
    if (in_parts) {  // the replay's log into place, or beside it (its LCM closed first: nothing publishes after the loop)
        lcm.reset();
        const bool whole = rc == 0 && !g_stop;  // the log replayed to its end, nothing failed
        if (whole && std::rename(partial.partial.c_str(), partial.path.c_str()) != 0) {
            std::fprintf(stderr, "rt_monitor: error: cannot write %s: %s\n", partial.path.c_str(), std::strerror(errno));
            rc = 1;
        }
        if (!whole || rc != 0) {  // its own log, for its status messages, beside the one it would have replaced
            const std::string failed = partial.path + ".failed";
            if (std::rename(partial.partial.c_str(), failed.c_str()) == 0)
                std::fprintf(stderr, "rt_monitor: the replay %s: its LCM log is %s, %s is left as it was\n",
                             g_stop ? "was stopped" : "failed", failed.c_str(), partial.path.c_str());
            else
                std::remove(partial.partial.c_str());
        }
    }
    // Read to its end with a fault raised: exit 7 (after the log went into place: it is whole), unless a write below
    // fails, whose exit (1) says more
    const bool faulted = rc == 0 && !g_stop && !replay.empty() && watchdog->seen() != 0;
    if (faulted) {
        std::string names;
        for (int bit = 0; bit < kFaultKinds; ++bit)
            if (watchdog->seen() & (1u << bit)) names += std::string(names.empty() ? "" : ", ") + Watchdog::name(bit);
        // the events published while a fault held (a walkthrough: "its 9 events" when none was, the fault rising 5 s
        // into the last contact)
        std::fprintf(stderr, "rt_monitor: warning: the replay raised faults (%s; DYNID_STATUS faults_seen %u): %lld of "
                     "its %lld events came while one held, from data the monitor suspected (each carries the faults "
                     "active then)\n", names.c_str(), unsigned(watchdog->seen()),
                     (long long)loop->counters().events_under_fault, (long long)loop->counters().events);
    }
    const SourceCounters& sc = src->counters();
    if (!replay.empty()) {  // skipped, counted: said once, with where to look
        const auto skipped = [&](uint64_t n, uint64_t line, const char* one, const char* many) {
            if (n == 1)
                std::fprintf(stderr, "rt_monitor: warning: %s: line %llu is %s, skipped\n", replay.c_str(),
                             (unsigned long long)line, one);
            else if (n > 1)
                std::fprintf(stderr, "rt_monitor: warning: %s: %llu lines (the first: line %llu) are %s, skipped\n",
                             replay.c_str(), (unsigned long long)n, (unsigned long long)line, many);
        };
        skipped(sc.bad_lines, sc.first_bad_line, "not a classic-CAN candump -L frame",
                "not classic-CAN candump -L frames");
        skipped(sc.unknown_bus, sc.first_unknown_bus, "a frame of an interface not among the configuration's buses",
                "frames of interfaces not among the configuration's buses");
    }
    if (blind && !replay.empty() && sc.frames == 0)
        std::fprintf(stderr, "rt_monitor: error: evaluated no sample: %s holds no candump -L frame of the "
                     "configuration's buses\n", replay.c_str());
    else if (blind)
        std::fprintf(stderr, "rt_monitor: error: %s: %s\n",
                     loop->counters().evaluated == 0 ? "evaluated no sample" : "ended blind",
                     *watchdog->reason(kBlind) ? watchdog->reason(kBlind) : "no sample was completed");
    if (!stats_out.empty() && !write_stats(stats_out, asm_, *src, *loop, publisher, *core, g_stop, rc, replay,
                                           realtime, loopback)) {
        std::fprintf(stderr, "rt_monitor: error: cannot write %s\n", stats_out.c_str());
        rc = rc ? rc : 1;
    }
    const std::vector<double>& latency = loop->latencies();
    if (!latency_out.empty()) {
        const std::string tmp = latency_out + ".tmp";
        bool written = false;
        {
            std::ofstream out(tmp);
            for (double v : latency) out << v << '\n';
            out.flush();
            written = bool(out);  // a short write (a full disk) must not be renamed into place
        }
        if (!written || std::rename(tmp.c_str(), latency_out.c_str()) != 0) {
            std::remove(tmp.c_str());  // nothing half-written left behind
            std::fprintf(stderr, "rt_monitor: error: cannot write %s\n", latency_out.c_str());
            rc = rc ? rc : 1;
        }
    }
    return rc == 0 && faulted ? kExitFaulted : rc;
}
