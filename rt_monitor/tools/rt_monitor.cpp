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
#include "rt_monitor/assembler.hpp"
#include "rt_monitor/core.hpp"
#include "rt_monitor/rt_settings.hpp"
#include "rt_monitor/run_stats.hpp"
#include "rt_monitor/sample_clock.hpp"
#include "rt_monitor/status.hpp"

using namespace dynid::rt;

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

constexpr const char* kSynopsis =
    "usage: rt_monitor --model COEF --config CONFIG [--replay CANDUMP.log [--realtime]] [--loopback DIR] "
    "[--lcm-url URL] [--residual acceleration|momentum] [--mlockall] [--priority N] [--cpu LIST] [--latency-out FILE] [--stats-out FILE] [--help]\n";

constexpr const char* kHelp = R"(
The real-time contact monitor: reads the boards' CAN frames, assembles samples (one per F/T strain pair),
predicts the F/T wrench and the PWMs with the identified model (the acceleration residuals) or runs its momentum
observer (the file says which, --residual overrides), computes Hotelling T2 and publishes contact events (with the
observer: the external joint torques and the isolated joint), a status (counters, loop times, supply ratios) and
decimated residuals on LCM (channels DYNID_CONTACT, DYNID_STATUS, DYNID_RESIDUAL). SIGINT or SIGTERM ends the
run; the final counters are printed on stdout.

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

detection:
  --residual R          acceleration or momentum: run this residual instead of the one the file selects (momentum
                        needs a file that carries the observer: `dynid export` writes it)

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

double real_us() {  // CLOCK_REALTIME, the clock of the kernel's SO_TIMESTAMP stamps
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    return double(ts.tv_sec) * 1e6 + double(ts.tv_nsec) * 1e-3;
}

struct Allocations {
    long long in_loop, in_publish;
};

// --stats-out: the JSON object (the body's keys, then the allocations and the resident set), written beside the path
// and renamed into place.
template <class Body>
bool write_stats(const std::string& path, Allocations a, Body body) {
    long long rss = 0, hwm = 0;
    resident_kb(rss, hwm);
    const std::string tmp = path + ".tmp";
    std::FILE* f = std::fopen(tmp.c_str(), "w");
    if (!f) return false;
    JsonOut j(f);
    body(j);
    j.open("allocations")  // after start-up: from the first read to the last publish
        .num("after_startup", a.in_loop).num("in_lcm_publish", a.in_publish)
        .num("elsewhere", a.in_loop - a.in_publish).flag("malloc_counted", allocations_count_malloc())
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
    if (!residual.empty() && residual != "acceleration" && residual != "momentum")
        return usage("--residual is acceleration or momentum, not '" + residual + "'");
    // Range checks are the system's (SCHED_FIFO's priorities, the allowed CPUs): a refusal has its own exit code.
    if (rts.fifo && !parse_int(priority, -1000000, 1000000, rts.priority))
        return usage("--priority needs an integer, got '" + priority + "'");
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
    else {
        std::vector<std::vector<can_filter>> filters;  // per bus, the table's IDs on it
        for (size_t b = 0; b < cfg.buses.size(); ++b) filters.push_back(socketcan_filters(bus_ids(cfg, int(b))));
        src = SocketCanSource::open(cfg.buses, filters, err);
    }
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
    auto core = std::make_unique<Core>(*coef);
    if (!residual.empty()) core->set_residual(residual == "momentum" ? Residual::kMomentum : Residual::kAcceleration);
    core->set_detector({coef->debounce_on, coef->debounce_off, coef->hysteresis});
    const bool momentum = core->residual() == Residual::kMomentum;
    std::fprintf(stderr, "rt_monitor: running: %s; LCM %s; %s; %s residuals\n",
                 !replay.empty() ? ("replay of " + replay + (realtime ? " in real time" : "")).c_str()
                 : !loopback.empty() ? ("loopback transport in " + loopback).c_str() : "SocketCAN",
                 (url.empty() ? std::string("default URL") : url).c_str(),
                 describe_rt_settings(rts).c_str(), momentum ? "momentum-observer" : "acceleration");
    const int n_out = coef->n_outputs, n_joints = coef->n_joints;
    dynid::contact_event_t ev;
    ev.n_channels = n_out;
    ev.channel.assign(coef->channel_names.begin(), coef->channel_names.begin() + n_out);
    ev.normalized_residual.assign(size_t(n_out), 0.0);
    ev.residual = int8_t(momentum);
    ev.n_joints = n_joints;
    ev.joint.assign(coef->joint_names.begin(), coef->joint_names.begin() + n_joints);
    ev.tau_ext.assign(size_t(n_joints), 0.0);
    ev.isolated_joint = -1;
    const int n_sensors = coef->n_sensors;
    ev.n_sensors = n_sensors;
    ev.sensor.assign(coef->sensor_names.begin(), coef->sensor_names.begin() + n_sensors);
    ev.side.assign(size_t(n_sensors), 0);
    ev.wrench.assign(size_t(n_sensors), std::vector<double>(6, 0.0));
    // The link each joint moves (the isolated link's name), and room for the longest: the event's size then never
    // grows in the loop (its string keeps its capacity, the encode buffer is sized for it).
    std::vector<std::string> link_of_joint(static_cast<size_t>(n_joints));
    for (int i = 0; i < coef->n_bodies; ++i)
        if (coef->joint_index[i] >= 0) link_of_joint[size_t(coef->joint_index[i])] = coef->body_names[i];
    size_t longest_link = 0;
    for (const auto& l : link_of_joint) longest_link = std::max(longest_link, l.size());
    ev.isolated_link.assign(longest_link, ' ');
    const int event_size = ev.getEncodedSize();
    ev.isolated_link.clear();
    dynid::residual_t res;
    res.n_channels = n_out;
    res.normalized_residual.assign(size_t(n_out), 0.0);
    res.threshold = core->threshold();
    ev.threshold = core->threshold();
    dynid::monitor_status_t st{};
    init_supply(*coef, st);  // sized here: the status's encoded size is fixed from here on
    // Channel residuals are published in units of their σ; σ once here, not per message.
    std::vector<double> sigma(static_cast<size_t>(n_out));
    for (int i = 0; i < n_out; ++i) sigma[size_t(i)] = std::sqrt(core->variance(i));
    // One encode buffer for every message (their sizes are fixed from here on), so a publish does not allocate
    // the way lcm::LCM::publish(channel, const T*) does; channel names built once too.
    enum { kContact, kResidual, kStatus };
    const std::string channels[3] = {"DYNID_CONTACT", "DYNID_RESIDUAL", "DYNID_STATUS"};
    std::vector<uint8_t> wire(size_t(std::max({event_size, res.getEncodedSize(), st.getEncodedSize()})));
    // Per channel: messages published, and refused (lcm_publish's error); allocations made inside lcm_publish (the
    // provider's: liblcm's file:// provider mallocs an event record per message, its udpm provider nothing).
    int64_t published[3] = {}, publish_failed = 0, unencoded = 0;
    long long publish_allocations = 0;
    auto send = [&](int channel, const auto& msg) {
        const int n = msg.encode(wire.data(), 0, int(wire.size()));  // < 0 only if a size changed: not sent
        if (n <= 0) {
            ++unencoded;
            return;
        }
        const long long a0 = allocations();
        const int rc = lcm.publish(channels[channel], wire.data(), unsigned(n));
        publish_allocations += allocations() - a0;
        if (rc == 0) ++published[channel];
        else ++publish_failed;
    };

    const int64_t status_period_us = dynid::rt::status_period_us(cfg);
    const double period_us = coef->sample_period * 1e6;
    int64_t next_status = -1, evaluated = 0, onset_utime = 0, overruns = 0, events = 0;
    double loop_sum = 0, loop_max = 0, loop_max_run = 0;
    int64_t loop_n = 0;
    SampleClock clock(period_us);
    Sample s;
    RxFrame f;
    double rx_mono = 0;  // when the read of the current frame returned
    std::vector<double> latency;
    if (!latency_out.empty()) latency.reserve(size_t(1) << 20);  // allocated once: no allocation in the loop
    // Each completed sample's processing time: from the return of the read of the frame that completed it to the end
    // of its processing (the sample clock, the core steps it released, every message published for them); above
    // one period, a loop overrun. Its response time (live sources): from the kernel's stamp of that frame
    // (CLOCK_REALTIME) to the same end, the wait for the monitor to be woken and read it included; above one period,
    // a missed deadline. A replay has no stamps of its own: its response time is its processing time.
    const bool live = replay.empty();
    LatencyHistogram response, processing;
    if (!stats_out.empty()) {
        response.init(period_us);
        processing.init(period_us);
    }
    int64_t onsets = 0, ends = 0;
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
        loop_max_run = dt > loop_max_run ? dt : loop_max_run;
        ++loop_n;
        if (dt > period_us) ++overruns;
        ++evaluated;
        if (o.event != Event::kNone) {
            ++events;
            ++(o.event == Event::kOnset ? onsets : ends);
            if (o.event == Event::kOnset) onset_utime = x.t_us;
            ev.utime = x.t_us;
            ev.kind = int8_t(o.event);
            ev.onset_utime = onset_utime;
            ev.sample = evaluated - 1;
            ev.t2 = o.p.t2;
            fill_residual(ev.normalized_residual, o);
            for (int k = 0; k < n_sensors; ++k) {
                ev.side[size_t(k)] = int8_t(o.side[k]);
                for (int m = 0; m < 6; ++m) ev.wrench[size_t(k)][size_t(m)] = o.wrench[k][m];
            }
            for (int j = 0; j < n_joints; ++j) ev.tau_ext[size_t(j)] = o.tau_ext[j];
            ev.isolated_joint = o.joint;
            ev.isolated_link.assign(o.joint >= 0 ? link_of_joint[size_t(o.joint)] : std::string());  // within capacity
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

    // A filter restart (stale data, a long gap) resets the detector: a contact open then gets no end event.
    int64_t contacts_cut = 0;
    auto evaluate = [&](const ClockStep& c) {
        if (c.restart) {
            contacts_cut += core->output().in_contact;
            core->reset();
        }
        step(c.sample);
    };

    const long long allocations_at_start = allocations();  // start-up is over: from here on, the loop
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
        const double done = mono_us();
        processing.add(done - rx_mono, s.t_us);
        response.add(live ? real_us() - double(f.t_us) : done - rx_mono, s.t_us);
    }
    for (int i = 0, n = clock.flush(); i < n; ++i) evaluate(clock.step(i));
    publish_status(s.t_us);
    const long long allocations_in_loop = allocations() - allocations_at_start;
    const ClockCounters& cc = clock.counters();
    const MonitorCounters& c = asm_.counters();
    const SourceCounters& sc = src->counters();
    std::printf("rt_monitor: %s; frames %lld, samples %lld, evaluated %lld, stale %lld, events %lld, unknown id %lld, "
                "bad length %lld, error frames %lld, unpaired strain %lld, saturated %lld, board faults %lld, "
                "board restarts %lld, bad source input %llu, interpolated %lld, late %lld, filter restarts %lld, overruns %lld, "
                "kernel drops %llu\n",
                g_stop ? "stopped by signal" : (rc ? "failed" : "end of input"), (long long)c.frames,
                (long long)c.samples, (long long)evaluated, (long long)c.stale_samples, (long long)events,
                (long long)c.unknown_id, (long long)c.bad_length, (long long)c.error_frames,
                (long long)c.unpaired_strain, (long long)c.saturated, (long long)c.board_faults,
                (long long)c.board_restarts, (unsigned long long)(sc.bad_lines + sc.unknown_bus + sc.bad_size),
                (long long)cc.interpolated, (long long)cc.late, (long long)cc.restarts, (long long)overruns,
                (unsigned long long)sc.kernel_drops);
    if (!stats_out.empty() && !write_stats(stats_out, {allocations_in_loop, publish_allocations}, [&](JsonOut& j) {
            j.str("source", !replay.empty() ? (realtime ? "replay, real time" : "replay")
                            : !loopback.empty() ? "loopback" : "socketcan")
                .str("stopped", g_stop ? "signal" : (rc ? "failed" : "end of input"))
                .real("period_us", period_us);
            // frames = error + unknown_id + bad_length + strain + position + pid + status + skin + sensor (by what the
            // bus table says each carries: strain the clock pair's halves, pid the inputs, sensor other F/T pairs)
            j.open("frames")
                .num("total", c.frames).num("error", c.error_frames).num("unknown_id", c.unknown_id)
                .num("bad_length", c.bad_length).num("strain", c.strain_frames).num("position", c.position_frames)
                .num("pid", c.pid_frames).num("status", c.status_frames).num("skin", c.skin_frames)
                .num("sensor", c.sensor_frames).num("unpaired_sensor", c.unpaired_sensor)
                .num("saturated", c.saturated).num("unpaired_strain", c.unpaired_strain)
                .num("pending_strain", asm_.pending_strain()).num("board_faults", c.board_faults)
                .num("board_restarts", c.board_restarts)
                .close();
            j.open("source_counters")
                .num("frames", (long long)sc.frames).num("bad_lines", (long long)sc.bad_lines)
                .num("unknown_bus", (long long)sc.unknown_bus).num("bad_size", (long long)sc.bad_size)
                .num("kernel_drops", (long long)sc.kernel_drops)
                .close();
            j.open("samples")  // evaluated = taken − held + interpolated; taken = assembled − stale
                .num("assembled", c.samples).num("stale", c.stale_samples).num("taken", cc.taken).num("held", cc.held)
                .num("lost", cc.lost).num("interpolated", cc.interpolated).num("late", cc.late)
                .num("evaluated", evaluated).num("filter_restarts", cc.restarts)
                .close();
            // onsets = ends + cut (open at a filter restart) + in_contact (open at the end)
            j.open("events").num("total", events).num("onsets", onsets).num("ends", ends).num("cut", contacts_cut)
                .num("in_contact", core->output().in_contact).close();
            j.open("published")
                .num("contact", published[kContact]).num("residual", published[kResidual])
                .num("status", published[kStatus]).num("failed", publish_failed).num("unencoded", unencoded)
                .close();
            j.open("core_step_us").real("max", loop_max_run).num("over_period", overruns).close();
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
            histogram("processing_us", "return of the read of the completing frame", processing);
            histogram("response_us", live ? "kernel stamp of the completing frame" : "return of the read", response);
        })) {
        std::fprintf(stderr, "rt_monitor: error: cannot write %s\n", stats_out.c_str());
        rc = rc ? rc : 1;
    }
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
