// rt_monitor --model COEF --config CONFIG [--replay CANDUMP.log [--realtime]] [--loopback DIR] [--lcm-url URL]
//            [--mlockall] [--priority N] [--cpu LIST] [--latency-out FILE] [--help]
//
// Frames in (SocketCAN on the configured buses, a candump -L replay, or the loopback transport), samples
// assembled, the core stepped, contact events / status (10 Hz) / decimated residuals out on LCM.
// SIGINT and SIGTERM end the run cleanly; the final counters are printed on stdout either way.
// --mlockall, --priority N (SCHED_FIFO) and --cpu LIST (affinity) are applied once before the loop; the start-up line
// on stderr says what the process runs with.
// --latency-out (benchmarks): per contact onset, CLOCK_MONOTONIC µs from the return of the read of the frame
// that completed the onset sample to the return of its LCM publish, one per line, written at exit.
// Exit codes: 0 done, 2 bad arguments or configuration, 1 a source or LCM failure, 3 mlockall refused, 4 SCHED_FIFO
// refused, 5 CPU affinity refused, 10+ a refused coefficient file.
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

#include "dynid/contact_event_t.hpp"
#include "dynid/monitor_status_t.hpp"
#include "dynid/residual_t.hpp"
#include "icub_can.h"
#include "rt_monitor/assembler.hpp"
#include "rt_monitor/core.hpp"
#include "rt_monitor/rt_settings.hpp"
#include "rt_monitor/sample_clock.hpp"
#include "rt_monitor/status.hpp"

using namespace dynid::rt;

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

constexpr const char* kSynopsis =
    "usage: rt_monitor --model COEF --config CONFIG [--replay CANDUMP.log [--realtime]] [--loopback DIR] "
    "[--lcm-url URL] [--mlockall] [--priority N] [--cpu LIST] [--latency-out FILE] [--help]\n";

constexpr const char* kHelp = R"(
The real-time contact monitor: reads the boards' CAN frames, assembles samples (one per F/T strain pair),
predicts the F/T wrench and the PWMs with the identified model, computes Hotelling T2 and publishes contact
events, a status (counters, loop times, supply ratios) and decimated residuals on LCM (channels DYNID_CONTACT,
DYNID_STATUS, DYNID_RESIDUAL). SIGINT or SIGTERM ends the run; the final counters are printed on stdout.

required:
  --model COEF          the coefficient file written by `dynid export` (refused with exit 10 + the reason if
                        damaged, of another format version or exported for another robot)
  --config CONFIG       the monitor configuration: buses, which board serves which joint or channel, full
                        scales, timing, LCM URL (rt_monitor/README.md, "Configuration"; keys in any order)

frame source (default: SocketCAN raw sockets on the configured buses, kernel filters and timestamps):
  --replay CANDUMP.log  replay a `candump -L` log instead, as fast as possible
  --realtime            with --replay: at the log's own pace
  --loopback DIR        read the loopback transport: one datagram socket per bus at DIR/<bus>.can
                        (`boards --sink loopback:DIR --realtime` sends to it); excludes --replay

output:
  --lcm-url URL         LCM URL, overriding the configuration's lcm_url (default: LCM's own, UDP multicast);
                        tests use file://PATH?mode=w or memq://
  --latency-out FILE    benchmarks: per contact onset, the CLOCK_MONOTONIC microseconds from the read of the
                        frame completing the onset sample to the return of its publish, written at exit

real time (applied once before the loop; a refusal has its own exit code):
  --mlockall            lock the process's memory (mlockall MCL_CURRENT|MCL_FUTURE)
  --priority N          run SCHED_FIFO at priority N
  --cpu LIST            pin to the CPUs in LIST, as taskset -c takes it (1, 0,2 or 0-3)

  -h, --help            print this help on stdout and exit 0

exit codes: 0 done (end of input, or SIGINT/SIGTERM); 1 a source or LCM failure; 2 bad arguments or
configuration; 3 mlockall refused; 4 SCHED_FIFO refused; 5 CPU affinity refused; 10 + the reason a
coefficient file was refused (11 unreadable ... 20 another robot).
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
    if (stat(path.c_str(), &st) == 0) {
        if (!S_ISREG(st.st_mode)) {
            errno = S_ISDIR(st.st_mode) ? EISDIR : EINVAL;
            return false;
        }
        return true;
    }
    const size_t slash = path.rfind('/');
    const std::string dir = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
    if (stat(dir.c_str(), &st) != 0) return false;  // errno: ENOENT, ...
    if (!S_ISDIR(st.st_mode)) {
        errno = ENOTDIR;
        return false;
    }
    return true;
}

// lcm::LCM(url), with what liblcm writes to fd 2 meanwhile returned in `said` (whitespace folded to one line).
std::unique_ptr<lcm::LCM> open_lcm(const std::string& url, std::string& said) {
    std::fflush(stderr);
    std::FILE* tmp = std::tmpfile();
    const int saved = tmp ? dup(2) : -1;
    if (saved >= 0) dup2(fileno(tmp), 2);
    auto lc = std::make_unique<lcm::LCM>(url);
    if (saved >= 0) {
        std::fflush(stderr);
        dup2(saved, 2);
        close(saved);
        std::rewind(tmp);
        int ch = 0;
        bool space = false;
        while ((ch = std::fgetc(tmp)) != EOF) {
            if (ch == '\n' || ch == '\r' || ch == '\t' || ch == ' ') {
                space = !said.empty();
                continue;
            }
            if (space) said += ' ';
            space = false;
            said += char(ch);
        }
    }
    if (tmp) std::fclose(tmp);
    return lc;
}

double mono_us() {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return double(ts.tv_sec) * 1e6 + double(ts.tv_nsec) * 1e-3;
}

}  // namespace

int main(int argc, char** argv) {
    std::string model, config, replay, loopback, url, latency_out;
    std::string priority, cpu;
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
    // Range checks are the system's (SCHED_FIFO's priorities, the allowed CPUs): a refusal has its own exit code.
    if (rts.fifo && !parse_int(priority, -1000000, 1000000, rts.priority))
        return usage("--priority needs an integer, got '" + priority + "'");
    if (have_cpu && !parse_cpu_list(cpu, rts.cpus))
        return usage("--cpu needs a CPU list as taskset -c takes it (1, 0,2 or 0-3), got '" + cpu + "'");

    // The latency file is written at exit: an unwritable one was found only after the whole run (and left its
    // temporary file behind when it named a directory).
    if (!latency_out.empty()) {
        if (!writable_file(latency_out)) {  // one line, no synopsis: the arguments were well formed
            std::fprintf(stderr, "rt_monitor: error: --latency-out %s: %s\n", latency_out.c_str(), std::strerror(errno));
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
    Assembler asm_;
    if (!asm_.init(cfg, *coef, err)) return bad_config(config + ": " + err);

    // Before the source and LCM are opened: a refused --priority or --cpu left an empty file:// LCM log (and the
    // loopback's sockets) behind (issue 22's sweep). mlockall's MCL_FUTURE still locks what they allocate.
    const int refused = apply_rt_settings(rts, err);
    if (refused) {
        std::fprintf(stderr, "rt_monitor: error: %s\n", err.c_str());
        return refused;
    }

    std::unique_ptr<FrameSource> src;
    if (!replay.empty()) src = CandumpReplay::open(replay, cfg.buses, realtime, err);
    else if (!loopback.empty()) src = LoopbackSource::open(loopback, cfg.buses, err);
    else src = SocketCanSource::open(cfg.buses, socketcan_filters({ICUB_CAN_CLASS_MC, ICUB_CAN_CLASS_STRAIN,
                                                                     ICUB_CAN_CLASS_SKIN}), err);
    if (!src) {
        std::fprintf(stderr, "rt_monitor: error: %s\n", err.c_str());
        return replay.empty() ? 1 : 2;
    }
    if (!have_url) url = cfg.lcm_url;
    // liblcm writes its own reason to fd 2 ("Error: LCM provider ... not found"): caught and put on the one line.
    std::string lcm_said;
    std::unique_ptr<lcm::LCM> lcm_owner = open_lcm(url, lcm_said);
    lcm::LCM& lcm = *lcm_owner;
    if (!lcm.good()) {
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
    std::fprintf(stderr, "rt_monitor: running: %s; LCM %s; %s\n",
                 !replay.empty() ? ("replay of " + replay + (realtime ? " in real time" : "")).c_str()
                 : !loopback.empty() ? ("loopback transport in " + loopback).c_str() : "SocketCAN",
                 (url.empty() ? std::string("default URL") : url).c_str(),
                 describe_rt_settings(rts).c_str());

    auto core = std::make_unique<Core>(*coef);
    core->set_detector({coef->debounce_on, coef->debounce_off, coef->hysteresis});
    const int n_out = coef->n_outputs;
    dynid::contact_event_t ev;
    ev.n_channels = n_out;
    ev.channel.assign(coef->channel_names.begin(), coef->channel_names.begin() + n_out);
    ev.normalized_residual.assign(size_t(n_out), 0.0);
    dynid::residual_t res;
    res.n_channels = n_out;
    res.normalized_residual.assign(size_t(n_out), 0.0);
    res.threshold = coef->threshold;
    ev.threshold = coef->threshold;
    dynid::monitor_status_t st{};
    init_supply(*coef, st);  // sized here: the status's encoded size is fixed from here on
    // Channel residuals are published in units of their σ; σ once here, not per message.
    std::vector<double> sigma(static_cast<size_t>(n_out));
    for (int i = 0; i < n_out; ++i) sigma[size_t(i)] = std::sqrt(coef->variance[size_t(i)]);
    // One encode buffer for every message (their sizes are fixed from here on), so a publish does not allocate
    // the way lcm::LCM::publish(channel, const T*) does; channel names built once too.
    const std::string kContact = "DYNID_CONTACT", kResidual = "DYNID_RESIDUAL", kStatus = "DYNID_STATUS";
    std::vector<uint8_t> wire(size_t(std::max({ev.getEncodedSize(), res.getEncodedSize(), st.getEncodedSize()})));
    auto send = [&](const std::string& channel, const auto& msg) {
        const int n = msg.encode(wire.data(), 0, int(wire.size()));  // < 0 only if a size changed: not sent
        if (n > 0) lcm.publish(channel, wire.data(), unsigned(n));
    };

    const int64_t status_period_us = dynid::rt::status_period_us(cfg);
    const double period_us = coef->sample_period * 1e6;
    int64_t next_status = -1, evaluated = 0, onset_utime = 0, overruns = 0, events = 0;
    double loop_sum = 0, loop_max = 0;
    int64_t loop_n = 0;
    SampleClock clock(period_us);
    Sample s;
    RxFrame f;
    double rx_mono = 0;  // when the read of the current frame returned
    std::vector<double> latency;
    if (!latency_out.empty()) latency.reserve(size_t(1) << 20);  // allocated once: no allocation in the loop
    int rc = 0;

    auto fill_residual = [&](std::vector<double>& r, const Output& o) {
        for (int i = 0; i < n_out; ++i)
            r[size_t(i)] = o.p.active[size_t(i)] ? o.p.e[i] / sigma[size_t(i)] : 0.0;
    };
    auto publish_status = [&](int64_t utime) {
        const MonitorCounters& c = asm_.counters();
        const SourceCounters& sc = src->counters();
        st.utime = utime;
        st.frames = c.frames;
        st.samples = c.samples;
        st.samples_evaluated = evaluated;
        st.stale_samples = c.stale_samples;
        st.unknown_id = c.unknown_id;
        st.bad_length = c.bad_length;
        st.error_frames = c.error_frames;
        st.unpaired_strain = c.unpaired_strain;
        st.saturated = c.saturated;
        st.board_faults = c.board_faults;
        st.board_restarts = c.board_restarts;
        st.source_bad = int64_t(sc.bad_lines + sc.unknown_bus + sc.bad_size);
        st.interpolated = clock.counters().interpolated;
        st.late = clock.counters().late;
        st.filter_restarts = clock.counters().restarts;
        st.in_contact = core->output().in_contact;
        st.stale = s.stale;
        st.loop_us_mean = loop_n ? loop_sum / double(loop_n) : 0.0;
        st.loop_us_max = loop_max;
        st.overruns = overruns;
        fill_supply(*coef, *core, st);
        send(kStatus, st);
        loop_sum = loop_max = 0;
        loop_n = 0;
    };

    auto step = [&](const Sample& x) {
        const double t0 = mono_us();
        const Output& o = core->step(x.q.data(), x.y.data());
        const double dt = mono_us() - t0;
        loop_sum += dt;
        loop_max = dt > loop_max ? dt : loop_max;
        ++loop_n;
        if (dt > period_us) ++overruns;
        ++evaluated;
        if (o.event != Event::kNone) {
            ++events;
            if (o.event == Event::kOnset) onset_utime = x.t_us;
            ev.utime = x.t_us;
            ev.kind = int8_t(o.event);
            ev.side = int8_t(o.side);
            ev.onset_utime = onset_utime;
            ev.sample = evaluated - 1;
            ev.t2 = o.p.t2;
            fill_residual(ev.normalized_residual, o);
            for (int k = 0; k < 6; ++k) ev.wrench[k] = o.wrench[k];
            send(kContact, ev);
            if (o.event == Event::kOnset && latency.size() < latency.capacity()) latency.push_back(mono_us() - rx_mono);
        }
        if (o.ready && evaluated % cfg.residual_every == 0) {
            res.utime = x.t_us;
            res.t2 = o.p.t2;
            fill_residual(res.normalized_residual, o);
            send(kResidual, res);
        }
    };

    auto evaluate = [&](const ClockStep& c) {
        if (c.restart) core->reset();
        step(c.sample);
    };

    while (!g_stop) {
        const ReadStatus r = src->read(f, 100);
        if (r == ReadStatus::kEnd) break;
        if (r == ReadStatus::kTimeout) continue;
        rx_mono = mono_us();
        if (r == ReadStatus::kError) {
            std::fprintf(stderr, "rt_monitor: error: %s\n", src->error().c_str());
            rc = 1;
            break;
        }
        if (!asm_.push(f, s)) continue;
        // The sample clock decides which tick each sample is (jitter or loss, from the stamps), bridges real
        // gaps and says when the filter restarts; stale samples are not evaluated (no contact from stale data).
        for (int i = 0, n = clock.push(s); i < n; ++i) evaluate(clock.step(i));
        if (next_status < 0) next_status = s.t_us;
        if (s.t_us >= next_status) {
            publish_status(s.t_us);
            next_status += status_period_us;
            if (next_status <= s.t_us) next_status = s.t_us + status_period_us;
        }
    }
    for (int i = 0, n = clock.flush(); i < n; ++i) evaluate(clock.step(i));
    publish_status(s.t_us);
    const ClockCounters& cc = clock.counters();
    const MonitorCounters& c = asm_.counters();
    const SourceCounters& sc = src->counters();
    std::printf("rt_monitor: %s; frames %lld, samples %lld, evaluated %lld, stale %lld, events %lld, unknown id %lld, "
                "bad length %lld, error frames %lld, unpaired strain %lld, saturated %lld, board faults %lld, "
                "board restarts %lld, bad source input %llu, interpolated %lld, late %lld, filter restarts %lld, overruns %lld\n",
                g_stop ? "stopped by signal" : (rc ? "failed" : "end of input"), (long long)c.frames,
                (long long)c.samples, (long long)evaluated, (long long)c.stale_samples, (long long)events,
                (long long)c.unknown_id, (long long)c.bad_length, (long long)c.error_frames,
                (long long)c.unpaired_strain, (long long)c.saturated, (long long)c.board_faults,
                (long long)c.board_restarts, (unsigned long long)(sc.bad_lines + sc.unknown_bus + sc.bad_size),
                (long long)cc.interpolated, (long long)cc.late, (long long)cc.restarts, (long long)overruns);
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
    return rc;
}
