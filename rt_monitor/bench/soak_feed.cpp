// soak_feed: the soak's fault injector (docs/benchmarks.md "Soak", tools/benchmarks/soak.py). It reads the boards'
// candump -L stream (`boards --sink candump:-`) on stdin, injects bus faults on a fixed schedule, and passes the
// frames on: as a candump -L stream on stdout (for `rt_monitor --replay /dev/stdin`), or paced in real time as
// struct can_frame datagrams to the loopback transport (`rt_monitor --loopback DIR`). At the end it writes a JSON
// report of what it passed and injected, from which soak.py derives every counter the monitor must show.
//
//   soak_feed [--every N] [--first K] [--until K] [--stall ADDR@SAMPLE:COUNT] [--guard FROM:TO]...
//             [--stale-us US] [--late-us US] [--report FILE] [--loopback DIR [--priority P]]
//
// A sample is the group of frames the boards send for it, ending with the strain torque half. From sample --first
// on, one fault every --every samples (none in a --guard range, nor from --until on, nor within 50 samples of the
// stall), the kinds taken in turn:
//   drop the force half, the torque half, both halves, a POSITION, a PID_VAL, a STATUS (every other one the
//   frame of sequence 255, at the counter's wrap), a skin frame; duplicate the force half, the torque half, a
//   POSITION, a STATUS (every other one a frame of sequence 0), a skin frame, a PID_VAL; swap two adjacent frames
//   of the sample (not the two strain halves: their stamps then run backwards); a late sender (the sample's frames
//   stamped --late-us late, the next ones 20 µs apart until caught up; paced: the sender sleeps that much more);
//   an error frame, a frame of an unknown class, a malformed line (paced: a datagram of the wrong size), a skin
//   frame one byte too long.
// --stall: the motor-control board at ADDR sends nothing for COUNT samples from SAMPLE (prolonged by a sample while
// its first STATUS back would carry sequence 0, which reads as a restart).
// Standard C++ and POSIX only; not real-time code (it allocates at will).
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <sched.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace {

enum Kind { kDropForce, kDropTorque, kDropPair, kDropPosition, kDropPid, kDropStatus, kDropSkin, kDupForce,
            kDupTorque, kDupPosition, kDupStatus, kDupSkin, kDupPid, kSwap, kLate, kErrorFrame, kUnknownId,
            kBadInput, kBadLength, kKinds };
const char* const kKindName[kKinds] = {
    "drop_force", "drop_torque", "drop_pair", "drop_position", "drop_pid", "drop_status", "drop_skin", "dup_force",
    "dup_torque", "dup_position", "dup_status", "dup_skin", "dup_pid", "swap", "late", "error_frame", "unknown_id",
    "bad_input", "bad_length"};

enum FrameKind { kStrainForce, kStrainTorque, kPosition, kPid, kStatus, kSkin, kError, kUnknown, kFrameKinds };

struct Frame {
    int64_t t_us = 0;
    std::string bus;
    uint32_t id = 0;  // with CAN_ERR_FLAG for error frames
    uint8_t len = 0;
    uint8_t data[8] = {};
    bool bad_line = false;  // an injected malformed line / wrong-size datagram

    FrameKind kind() const {
        if (id & CAN_ERR_FLAG) return kError;
        const unsigned cls = (id >> 8) & 7u, type = id & 0xFu;
        if (id > 0x7FF) return kUnknown;
        if (cls == 3 && type == 0xA) return kStrainForce;
        if (cls == 3 && type == 0xB) return kStrainTorque;
        if (cls == 1 && type == 1) return kPosition;
        if (cls == 1 && type == 2) return kPid;
        if (cls == 1 && type == 3) return kStatus;
        if (cls == 4 && type == 0) return kSkin;
        return kUnknown;
    }
    unsigned source() const { return (id >> 4) & 0xFu; }
};

bool parse(const char* line, Frame& f) {
    long long sec = 0, usec = 0;
    char bus[32], rest[64];
    if (std::sscanf(line, "(%lld.%lld) %31s %63s", &sec, &usec, bus, rest) != 4) return false;
    f.t_us = sec * 1000000 + usec;
    f.bus = bus;
    char* hash = std::strchr(rest, '#');
    if (!hash) return false;
    *hash = '\0';
    f.id = uint32_t(std::strtoul(rest, nullptr, 16));
    const char* hex = hash + 1;
    const size_t n = std::strlen(hex) / 2;
    if (n > 8) return false;
    f.len = uint8_t(n);
    for (size_t i = 0; i < n; ++i) {
        unsigned v = 0;
        std::sscanf(hex + 2 * i, "%2x", &v);
        f.data[i] = uint8_t(v);
    }
    return true;
}

struct Options {
    long every = 1000, first = 200, until = -1;
    int stall_address = -1;
    long stall_from = -1, stall_count = 0;
    std::vector<std::pair<long, long>> guards;
    long stale_us = 5000, late_us = 1800;
    std::string report, loopback;
    int priority = 0;
};

// Where the frames go: a candump stream on stdout, or paced datagrams.
class Sink {
public:
    explicit Sink(const Options& o) : o_(o) {
        if (o.loopback.empty()) {
            static char buf[1 << 16];
            std::setvbuf(stdout, buf, _IOFBF, sizeof buf);
            return;
        }
        fd_ = socket(AF_UNIX, SOCK_DGRAM, 0);
        if (fd_ < 0) die("socket(AF_UNIX)");
    }
    // Paced: before a sample, sleep until its first frame's time (relative to the first sample's), plus `extra_us`.
    void pace(int64_t t_us, int64_t extra_us) {
        if (fd_ < 0) return;
        if (t0_ < 0) {
            t0_ = t_us;
            clock_gettime(CLOCK_MONOTONIC, &start_);
        }
        const int64_t off = t_us - t0_ + extra_us;
        timespec at = start_;
        const int64_t ns = int64_t(at.tv_nsec) + (off % 1000000) * 1000;
        at.tv_sec += time_t(off / 1000000 + ns / 1000000000);
        at.tv_nsec = long(ns % 1000000000);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, nullptr) == EINTR) {}
    }
    // The CLOCK_REALTIME µs of the last send (paced), the monitor's SO_TIMESTAMP clock; else the frame's own stamp.
    int64_t send(const Frame& f) {
        if (fd_ < 0) {
            if (f.bad_line) {
                std::fputs("this line is no candump -L frame (soak_feed)\n", stdout);
                return f.t_us;
            }
            char hex[17];
            for (int i = 0; i < f.len; ++i) std::snprintf(hex + 2 * i, 3, "%02X", f.data[i]);
            hex[2 * f.len] = '\0';
            if (f.id & CAN_ERR_FLAG) {
                std::printf("(%lld.%06lld) %s %08X#%s\n", (long long)(f.t_us / 1000000), (long long)(f.t_us % 1000000),
                            f.bus.c_str(), unsigned(f.id), hex);
            } else {
                std::printf("(%lld.%06lld) %s %03X#%s\n", (long long)(f.t_us / 1000000), (long long)(f.t_us % 1000000),
                            f.bus.c_str(), unsigned(f.id), hex);
            }
            return f.t_us;
        }
        can_frame cf{};
        cf.can_id = f.id;
        cf.len = f.len;
        std::memcpy(cf.data, f.data, 8);
        const sockaddr_un& a = address(f.bus);
        // Blocking: a full queue makes the feed wait for the monitor, nothing is dropped.
        const size_t n = f.bad_line ? 5 : sizeof cf;
        if (sendto(fd_, &cf, n, 0, reinterpret_cast<const sockaddr*>(&a), sizeof a) != ssize_t(n)) die("sendto");
        timespec ts{};
        clock_gettime(CLOCK_REALTIME, &ts);
        return int64_t(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
    }
    void finish() {
        if (fd_ < 0 && std::fflush(stdout) != 0) die("stdout");
    }
    static void die(const char* what) {
        std::fprintf(stderr, "soak_feed: error: %s: %s\n", what, std::strerror(errno));
        std::exit(1);
    }

private:
    const sockaddr_un& address(const std::string& bus) {
        auto it = addr_.find(bus);
        if (it != addr_.end()) return it->second;
        sockaddr_un a{};
        a.sun_family = AF_UNIX;
        std::snprintf(a.sun_path, sizeof a.sun_path, "%s/%s.can", o_.loopback.c_str(), bus.c_str());
        return addr_.emplace(bus, a).first->second;
    }
    const Options& o_;
    int fd_ = -1;
    int64_t t0_ = -1;
    timespec start_{};
    std::map<std::string, sockaddr_un> addr_;
};

struct Report {
    long samples = 0, frames_in = 0, frames_out = 0, bad_input = 0;
    long out[kFrameKinds] = {};
    long injected[kKinds] = {};
    long bad_length = 0;            // frames sent with a wrong length (counted in out[] too: kind by ID)
    long strain_lost_samples = 0;   // samples with a strain half dropped (never assembled)
    long strain_one_half = 0;       // of those, with one half dropped (the other is unpaired)
    long position_dropped = 0;      // samples with a POSITION dropped (held)
    long late_samples = 0;          // samples whose torque half is stamped ≥ 0.75 period after its own time
    long restarts = 0;              // STATUS frames passed with the RESTARTED flag, first copies
    long seq_zero_after_gap = 0;    // STATUS of sequence 0 without the flag after a gap in the sequence
    long status_faults = 0;         // STATUS frames passed with a fault bit
    long saturated = 0, saturated_samples = 0;
    long seq255_dropped = 0, seq0_duplicated = 0;
    long stall_samples = 0, stall_held = 0, stall_stale = 0, stall_frames = 0;
    std::vector<long> restart_samples;
};

bool near_guard(const Options& o, long k) {
    for (const auto& g : o.guards)
        if (k >= g.first && k <= g.second) return true;
    if (o.stall_from >= 0 && k >= o.stall_from - 50 && k <= o.stall_from + o.stall_count + 50) return true;
    return o.until >= 0 && k >= o.until;
}

int usage(const char* why) {
    std::fprintf(stderr,
                 "soak_feed: error: %s\nusage: soak_feed [--every N] [--first K] [--until K] [--stall ADDR@SAMPLE:COUNT] "
                 "[--guard FROM:TO]... [--stale-us US] [--late-us US] [--report FILE] [--loopback DIR [--priority P]]\n",
                 why);
    return 2;
}

}  // namespace

int main(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (i + 1 >= argc) return usage(("'" + a + "' needs a value").c_str());
        const char* v = argv[++i];
        char* end = nullptr;
        if (a == "--every") o.every = std::strtol(v, &end, 10);
        else if (a == "--first") o.first = std::strtol(v, &end, 10);
        else if (a == "--until") o.until = std::strtol(v, &end, 10);
        else if (a == "--stale-us") o.stale_us = std::strtol(v, &end, 10);
        else if (a == "--late-us") o.late_us = std::strtol(v, &end, 10);
        else if (a == "--priority") o.priority = int(std::strtol(v, &end, 10));
        else if (a == "--report") o.report = v, end = const_cast<char*>("");
        else if (a == "--loopback") o.loopback = v, end = const_cast<char*>("");
        else if (a == "--stall") {
            if (std::sscanf(v, "%d@%ld:%ld", &o.stall_address, &o.stall_from, &o.stall_count) != 3)
                return usage("--stall ADDR@SAMPLE:COUNT");
            end = const_cast<char*>("");
        } else if (a == "--guard") {
            long from = 0, to = 0;
            if (std::sscanf(v, "%ld:%ld", &from, &to) != 2) return usage("--guard FROM:TO");
            o.guards.emplace_back(from, to);
            end = const_cast<char*>("");
        } else {
            return usage(("unknown argument '" + a + "'").c_str());
        }
        if (!end || *end) return usage(("bad value for " + a).c_str());
    }
    if (o.every < 10) return usage("--every must be at least 10");
    if (o.priority > 0) {
        sched_param sp{};
        sp.sched_priority = o.priority;
        if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0) Sink::die("SCHED_FIFO");
    }

    Sink sink(o);
    Report r;
    std::map<unsigned, int> last_seq;  // per motor-control board address: the last STATUS sequence passed
    int64_t stall_last_us = -1;        // the stalled board's last frame before the stall (its values' age)
    long stall_end = o.stall_from >= 0 ? o.stall_from + o.stall_count : -1;
    long next_fault = o.first;
    int kind = 0, status_drop_turn = 0, status_dup_turn = 0;
    int64_t prev_out = INT64_MIN;  // the last stamp sent (the late sender's catch-up)
    bool catching_up = false;      // a late sender's stamps: no earlier than the frame before + 20 µs
    int64_t period_us = 1000;
    int64_t last_torque_in = -1;

    std::vector<Frame> group;
    char line[256];
    bool eof = false;
    while (!eof) {
        // ---- read one sample's frames -----------------------------------------------------------------------
        group.clear();
        while (true) {
            if (!std::fgets(line, sizeof line, stdin)) {
                eof = true;
                break;
            }
            Frame f;
            if (!parse(line, f)) {
                std::fprintf(stderr, "soak_feed: error: not a candump -L line: %s", line);
                return 1;
            }
            ++r.frames_in;
            group.push_back(f);
            if (f.kind() == kStrainTorque) break;
        }
        if (group.empty()) break;
        const long k = r.samples++;
        const int64_t t_nominal = group.back().t_us;  // the torque half's stamp: the sample's time
        if (last_torque_in >= 0 && t_nominal > last_torque_in) period_us = t_nominal - last_torque_in;
        last_torque_in = t_nominal;

        // ---- the stall ---------------------------------------------------------------------------------------
        auto stalled = [&](const Frame& f) {
            return f.kind() >= kPosition && f.kind() <= kStatus && int(f.source()) == o.stall_address;
        };
        if (o.stall_from >= 0 && k == stall_end) {
            for (const Frame& f : group)  // the first STATUS back would read as a restart: one sample more
                if (stalled(f) && f.kind() == kStatus && f.data[3] == 0) ++stall_end;
        }
        const bool in_stall = o.stall_from >= 0 && k >= o.stall_from && k < stall_end;
        if (in_stall) {
            std::vector<Frame> kept;
            for (const Frame& f : group) {
                if (stalled(f)) ++r.stall_frames;
                else kept.push_back(f);
            }
            group.swap(kept);
            ++r.stall_samples;
        }

        // ---- this sample's fault ------------------------------------------------------------------------------
        bool strain_lost = false, position_dropped = false;
        int strain_dropped = 0;
        int64_t extra_sleep = 0;
        bool restart_here = false;
        for (const Frame& f : group)
            if (f.kind() == kStatus && (f.data[2] & 1u)) restart_here = true;
        if (k >= next_fault && !near_guard(o, k) && !restart_here) {
            auto find = [&](FrameKind fk, int seq = -1) -> int {
                int hits = 0;
                for (const Frame& f : group) hits += f.kind() == fk && (seq < 0 || f.data[3] == seq);
                if (hits == 0) return -1;
                int want = int(k % hits);  // a different board from one fault to the next
                for (size_t i = 0; i < group.size(); ++i)
                    if (group[i].kind() == fk && (seq < 0 || group[i].data[3] == seq) && want-- == 0) return int(i);
                return -1;
            };
            int at = -1;
            bool done = true;
            const Frame first = group.front();
            switch (Kind(kind)) {
                case kDropForce: case kDropTorque: case kDropPair: {
                    const int fi = find(kStrainForce), ti = find(kStrainTorque);
                    if (fi < 0 || ti < 0) { done = false; break; }
                    strain_dropped = kind == kDropPair ? 2 : 1;
                    if (kind != kDropForce) group.erase(group.begin() + ti);
                    if (kind != kDropTorque) group.erase(group.begin() + fi);
                    strain_lost = true;
                    break;
                }
                case kDropPosition: case kDropPid: case kDropSkin:
                    at = find(kind == kDropPosition ? kPosition : kind == kDropPid ? kPid : kSkin);
                    if (at < 0) { done = false; break; }
                    group.erase(group.begin() + at);
                    position_dropped = kind == kDropPosition;
                    break;
                case kDropStatus:  // every other time the frame of sequence 255, at the wrap
                    at = find(kStatus, status_drop_turn % 2 ? 255 : -1);
                    if (at < 0) { done = false; break; }
                    r.seq255_dropped += group[size_t(at)].data[3] == 255;
                    group.erase(group.begin() + at);
                    ++status_drop_turn;
                    break;
                case kDupForce: case kDupTorque: case kDupPosition: case kDupSkin: case kDupPid: case kDupStatus: {
                    const FrameKind fk = kind == kDupForce ? kStrainForce : kind == kDupTorque ? kStrainTorque
                                       : kind == kDupPosition ? kPosition : kind == kDupSkin ? kSkin
                                       : kind == kDupPid ? kPid : kStatus;
                    at = find(fk, kind == kDupStatus && status_dup_turn % 2 ? 0 : -1);
                    if (at < 0) { done = false; break; }
                    if (kind == kDupStatus) {
                        r.seq0_duplicated += group[size_t(at)].data[3] == 0;
                        ++status_dup_turn;
                    }
                    group.insert(group.begin() + at + 1, group[size_t(at)]);
                    break;
                }
                case kSwap: {
                    // Two adjacent frames, not the two strain halves (group.size() ≥ 3: the last two are those).
                    const size_t i = size_t(k % long(group.size() - 2));
                    std::swap(group[i], group[i + 1]);
                    break;
                }
                case kLate:
                    extra_sleep = o.late_us;
                    break;
                case kErrorFrame: case kUnknownId: case kBadInput: {
                    Frame x = first;
                    if (kind == kErrorFrame) {
                        x.id = CAN_ERR_FLAG | CAN_ERR_CRTL;  // controller problems: rx warning
                        x.len = 8;
                        std::memset(x.data, 0, 8);
                        x.data[1] = CAN_ERR_CRTL_RX_WARNING;
                    } else if (kind == kUnknownId) {
                        x.id = 0x514;  // class 5: no board of the monitor's
                        x.len = 2;
                        x.data[0] = 1, x.data[1] = 2;
                    } else {
                        x.bad_line = true;
                    }
                    group.insert(group.begin() + 1, x);
                    break;
                }
                case kBadLength:
                    at = find(kSkin);
                    if (at < 0) { done = false; break; }
                    group[size_t(at)].data[group[size_t(at)].len] = 0;
                    group[size_t(at)].len = uint8_t(group[size_t(at)].len + 1);
                    ++r.bad_length;
                    break;
                case kKinds: break;
            }
            if (done) {
                ++r.injected[kind];
                kind = (kind + 1) % kKinds;
                next_fault = k + o.every;
            }
        }
        if (strain_lost) {
            ++r.strain_lost_samples;
            r.strain_one_half += strain_dropped == 1;
        }
        r.position_dropped += position_dropped;

        // ---- out -------------------------------------------------------------------------------------------------
        // A late sender (candump stream): this sample's frames stamped late_us late, then every frame no earlier than
        // the one before + 20 µs until the stamps are their own again. Paced, the sender sleeps late_us more instead,
        // then sends the samples whose time has passed back to back: the kernel stamps them so.
        const bool paced = !o.loopback.empty();
        sink.pace(group.front().t_us, paced ? extra_sleep : 0);
        if (!paced && extra_sleep) catching_up = true;
        bool saturated = false;
        int64_t torque_out = -1;
        for (Frame& f : group) {
            if (catching_up && !f.bad_line) {
                const int64_t t = f.t_us + (extra_sleep ? extra_sleep : 0);
                if (prev_out != INT64_MIN && t < prev_out + 20) f.t_us = prev_out + 20;
                else if (extra_sleep) f.t_us = t;
                else catching_up = false;  // its own stamp is later than the catch-up's: caught up
            }
            const int64_t sent = sink.send(f);
            if (f.bad_line) {
                ++r.bad_input;
                continue;
            }
            prev_out = f.t_us;
            ++r.frames_out;
            const FrameKind fk = f.kind();
            ++r.out[fk];
            if ((fk == kStrainForce || fk == kStrainTorque) && f.len == 7 && f.data[6]) {
                ++r.saturated;
                saturated = true;
            }
            if (fk == kStrainTorque) torque_out = sent;
            if (fk == kStatus && f.len == 4) {
                const unsigned src = f.source();
                const auto it = last_seq.find(src);
                const int last = it == last_seq.end() ? -1 : it->second;
                const int seq = f.data[3];
                if (f.data[0] || f.data[1]) ++r.status_faults;
                if ((f.data[2] & 1u) && seq != last) {
                    ++r.restarts;
                    r.restart_samples.push_back(k);
                } else if (!(f.data[2] & 1u) && seq == 0 && last >= 0 && last < 254 && last != 0) {
                    ++r.seq_zero_after_gap;
                }
                last_seq[src] = seq;
            }
            if (o.stall_from >= 0 && k < o.stall_from && stalled(f)) stall_last_us = sent;
        }
        // In the stall, the board's values are held while younger than stale_us, then stale (assembler.hpp); its age
        // is the strain pair's stamp (or, paced, its send time) against the board's last frame's.
        if (in_stall && torque_out >= 0) ++(torque_out - stall_last_us > o.stale_us ? r.stall_stale : r.stall_held);
        // Late: stamped 3/4 of a period or more after its time, it reads as past a gap (sample_clock.hpp) until the
        // catch-up shows it late. Paced, the kernel's stamps decide: not predicted here.
        if (!paced && torque_out >= 0 && 4 * (torque_out - t_nominal) >= 3 * period_us) ++r.late_samples;
        r.saturated_samples += saturated;
    }
    sink.finish();

    if (!o.report.empty()) {
        std::FILE* f = std::fopen(o.report.c_str(), "w");
        if (!f) Sink::die(o.report.c_str());
        std::fprintf(f, "{\"samples\":%ld,\"frames_in\":%ld,\"frames_out\":%ld,\"bad_input\":%ld,\"out\":{", r.samples,
                     r.frames_in, r.frames_out, r.bad_input);
        const char* fk[kFrameKinds] = {"strain_force", "strain_torque", "position", "pid", "status", "skin", "error",
                                       "unknown"};
        for (int i = 0; i < kFrameKinds; ++i) std::fprintf(f, "%s\"%s\":%ld", i ? "," : "", fk[i], r.out[i]);
        std::fprintf(f, "},\"injected\":{");
        for (int i = 0; i < kKinds; ++i) std::fprintf(f, "%s\"%s\":%ld", i ? "," : "", kKindName[i], r.injected[i]);
        std::fprintf(f,
                     "},\"bad_length\":%ld,\"strain_lost_samples\":%ld,\"strain_one_half\":%ld,\"position_dropped\":%ld,"
                     "\"late_samples\":%ld,\"restarts\":%ld,\"seq_zero_after_gap\":%ld,\"status_faults\":%ld,"
                     "\"saturated\":%ld,\"saturated_samples\":%ld,\"seq255_dropped\":%ld,\"seq0_duplicated\":%ld,"
                     "\"stall\":{\"address\":%d,\"from\":%ld,\"samples\":%ld,\"frames\":%ld,\"held\":%ld,\"stale\":%ld},"
                     "\"restart_samples\":[",
                     r.bad_length, r.strain_lost_samples, r.strain_one_half, r.position_dropped, r.late_samples,
                     r.restarts, r.seq_zero_after_gap, r.status_faults, r.saturated, r.saturated_samples,
                     r.seq255_dropped, r.seq0_duplicated, o.stall_address, o.stall_from, r.stall_samples,
                     r.stall_frames, r.stall_held, r.stall_stale);
        for (size_t i = 0; i < r.restart_samples.size(); ++i) std::fprintf(f, "%s%ld", i ? "," : "", r.restart_samples[i]);
        std::fprintf(f, "],\"paced\":%s}\n", o.loopback.empty() ? "false" : "true");
        if (std::fclose(f) != 0) Sink::die(o.report.c_str());
    }
    return 0;
}
