// Frame sources: candump -L replay, the AF_UNIX loopback transport, and the datagram reader they share with
// SocketCAN (socketcan.cpp). See frame_source.hpp.
#include "rt_monitor/frame_source.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <ctime>

namespace dynid::rt {

int64_t realtime_us() noexcept {
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    return int64_t(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}

namespace {

// A character's hex value, −1 if it is none: one load, not three range tests (an unpaced replay parses 15 frames a
// sample).
constexpr std::array<int8_t, 256> kHexValue = [] {
    std::array<int8_t, 256> v{};
    for (auto& x : v) x = -1;
    for (int c = 0; c < 10; ++c) v[size_t('0' + c)] = int8_t(c);
    for (int c = 0; c < 6; ++c) v[size_t('a' + c)] = v[size_t('A' + c)] = int8_t(10 + c);
    return v;
}();

int hex_digit(char c) noexcept { return kHexValue[static_cast<unsigned char>(c)]; }

// `(S.F)`: integer seconds and up to 9 fraction digits, to µs without floating point.
const char* parse_time(const char* p, int64_t& us) noexcept {
    // The most seconds whose µs, fraction included, fit int64 (9 223 372 036 853 s, 292 271 years). The bound was
    // checked before the last digit, which let 9 223 372 036 854..9 with a signed overflow through (fuzzer finding).
    constexpr int64_t kMaxSeconds = (INT64_MAX - 999999) / 1000000;
    if (*p++ != '(') return nullptr;
    int64_t s = 0;
    int digits = 0;
    for (; *p >= '0' && *p <= '9'; ++p, ++digits) {
        // would overflow as µs; checked from the 13th digit on (12 digits are < 10¹² s, inside the bound)
        if (digits >= 12 && s > (kMaxSeconds - (*p - '0')) / 10) return nullptr;
        s = s * 10 + (*p - '0');
    }
    if (digits == 0) return nullptr;
    int64_t frac = 0;
    if (*p == '.') {
        ++p;
        int n = 0;
        for (; *p >= '0' && *p <= '9'; ++p, ++n)
            if (n < 6) frac = frac * 10 + (*p - '0');
        if (n == 0 || n > 9) return nullptr;
        for (; n < 6; ++n) frac *= 10;
    }
    if (*p++ != ')') return nullptr;
    us = s * 1000000 + frac;
    return p;
}

}  // namespace

LineKind parse_candump_line(const char* line, const std::vector<std::string>& buses, RxFrame& out) noexcept {
    const char* p = line;
    while (*p == ' ' || *p == '\t') ++p;
    if (*p == '\0' || *p == '\n' || *p == '\r' || *p == '#') return LineKind::kBlank;
    int64_t t = 0;
    p = parse_time(p, t);
    if (!p || (*p != ' ' && *p != '\t')) return LineKind::kBad;
    while (*p == ' ' || *p == '\t') ++p;
    const char* iface = p;
    while (*p && *p != ' ' && *p != '\t' && *p != '\n') ++p;
    const size_t iface_len = size_t(p - iface);
    if (iface_len == 0) return LineKind::kBad;
    while (*p == ' ' || *p == '\t') ++p;

    const char* id0 = p;
    uint32_t id = 0;
    for (int d; (d = hex_digit(*p)) >= 0; ++p) id = id << 4 | uint32_t(d);
    const long id_digits = p - id0;
    if (*p++ != '#' || (id_digits != 3 && id_digits != 8)) return LineKind::kBad;
    if (*p == '#') return LineKind::kBad;  // CAN FD
    can_frame f{};
    if (id_digits == 3) {
        if (id > CAN_SFF_MASK) return LineKind::kBad;
        f.can_id = id;
    } else if (id & CAN_ERR_FLAG) {
        f.can_id = id & (CAN_ERR_FLAG | CAN_ERR_MASK);  // candump prints error frames with the flag in the ID
    } else {
        if (id > CAN_EFF_MASK) return LineKind::kBad;
        f.can_id = id | CAN_EFF_FLAG;
    }
    if (*p == 'R' || *p == 'r') {
        f.can_id |= CAN_RTR_FLAG;
        ++p;
        if (*p >= '0' && *p <= '8') f.len = uint8_t(*p++ - '0');
    } else {
        int n = 0;
        while (true) {
            if (*p == '.') { ++p; continue; }
            const int hi = hex_digit(*p);
            if (hi < 0) break;
            const int lo = hex_digit(p[1]);
            if (lo < 0 || n == CAN_MAX_DLEN) return LineKind::kBad;
            f.data[n++] = uint8_t(hi << 4 | lo);
            p += 2;
        }
        f.len = uint8_t(n);
    }
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') ++p;
    if (*p != '\0') return LineKind::kBad;  // trailing garbage (or a newer can-utils flag such as FD's)

    for (size_t b = 0; b < buses.size(); ++b) {
        if (buses[b].size() == iface_len && std::memcmp(buses[b].data(), iface, iface_len) == 0) {
            out.frame = f;
            out.t_us = t;
            out.bus = int(b);
            return LineKind::kFrame;
        }
    }
    return LineKind::kUnknownBus;
}

std::string format_candump_line(const RxFrame& f, const std::vector<std::string>& buses) {
    char buf[96];
    const canid_t id = f.frame.can_id;
    int n = std::snprintf(buf, sizeof buf, "(%lld.%06lld) %s ", static_cast<long long>(f.t_us / 1000000),
                          static_cast<long long>(f.t_us % 1000000), buses.at(size_t(f.bus)).c_str());
    if (id & CAN_ERR_FLAG)
        n += std::snprintf(buf + n, sizeof buf - size_t(n), "%08X#", id & (CAN_ERR_FLAG | CAN_ERR_MASK));
    else if (id & CAN_EFF_FLAG)
        n += std::snprintf(buf + n, sizeof buf - size_t(n), "%08X#", id & CAN_EFF_MASK);
    else
        n += std::snprintf(buf + n, sizeof buf - size_t(n), "%03X#", id & CAN_SFF_MASK);
    if (id & CAN_RTR_FLAG) {
        n += std::snprintf(buf + n, sizeof buf - size_t(n), "R");
        if (f.frame.len) n += std::snprintf(buf + n, sizeof buf - size_t(n), "%u", unsigned(f.frame.len));
    } else {
        for (int i = 0; i < f.frame.len && i < CAN_MAX_DLEN; ++i)
            n += std::snprintf(buf + n, sizeof buf - size_t(n), "%02X", unsigned(f.frame.data[i]));
    }
    return std::string(buf, size_t(n));
}

// ---- replay -------------------------------------------------------------------------------------------

std::unique_ptr<CandumpReplay> CandumpReplay::open(const std::string& path, std::vector<std::string> buses,
                                                   bool realtime, std::string& error) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        error = path + ": cannot open candump log: " + std::strerror(errno);
        return nullptr;
    }
    // A directory opens for reading and fails at the first read: refused here, as a bad argument, before the
    // monitor starts (it printed its start-up line, then "read error: Is a directory" and exit 1).
    struct stat st {};
    if (fstat(fd, &st) == 0 && S_ISDIR(st.st_mode)) {
        ::close(fd);
        error = path + ": cannot open candump log: " + std::strerror(EISDIR);
        return nullptr;
    }
    std::unique_ptr<CandumpReplay> r(new CandumpReplay());
    r->fd_ = fd;
    // The buffer the log is read into, lines parsed in place: made here, never in the loop. One byte more than it
    // reads, for the terminator of a last line without a newline.
    r->buffer_.assign(kBufferSize + 1, '\0');
    r->buses_ = std::move(buses);
    r->realtime_ = realtime;
    return r;
}

CandumpReplay::~CandumpReplay() {
    if (fd_ >= 0) ::close(fd_);
}

CandumpReplay::Next CandumpReplay::next_line(char*& line, size_t& n) noexcept {
    // Lines are found in the buffer with memchr and handed out in place: one read(2) per 64 KiB of log, no copy
    // of a line, no per-line stream lock or buffer clear (fgets, memset and memrchr were 9 % of an unpaced replay).
    while (true) {
        char* begin = buffer_.data() + begin_;
        const size_t have = end_ - begin_;
        if (auto* newline = static_cast<char*>(std::memchr(begin, '\n', have))) {
            n = size_t(newline - begin);
            line = begin;
            begin_ += n + 1;
            if (skipping_) {  // the end of an overlong line, already counted
                skipping_ = false;
                continue;
            }
            return n > kMaxLine ? Next::kOverlong : Next::kLine;
        }
        if (skipping_ || have > kMaxLine) {  // an overlong line without its end in the buffer: dropped as it comes
            const bool first = !skipping_;
            skipping_ = true;
            begin_ = end_ = 0;
            if (first) return Next::kOverlong;
        } else {  // a line's start: moved to the front, the rest read after it
            std::memmove(buffer_.data(), begin, have);
            begin_ = 0, end_ = have;
        }
        if (eof_) {
            if (end_ == begin_ || skipping_) return Next::kEnd;
            line = buffer_.data() + begin_, n = end_ - begin_;  // the last line, without a newline
            begin_ = end_;
            return Next::kLine;
        }
        const ssize_t got = ::read(fd_, buffer_.data() + end_, kBufferSize - end_);
        if (got < 0) {
            if (errno == EINTR) continue;
            error_ = std::string("candump log read error: ") + std::strerror(errno);
            return Next::kError;
        }
        if (got == 0) eof_ = true;
        end_ += size_t(got);
    }
}

ReadStatus CandumpReplay::read(RxFrame& out, int /*timeout_ms*/) noexcept {
    while (true) {
        char* line = nullptr;
        size_t n = 0;
        const Next next = next_line(line, n);
        if (next == Next::kEnd) return ReadStatus::kEnd;
        if (next == Next::kError) return ReadStatus::kError;
        ++line_;
        // An overlong line, or one with a NUL byte in it (strlen would end it early and read its rest as a line of
        // its own): one bad line.
        if (next == Next::kOverlong || std::memchr(line, '\0', n)) {
            bad_line();
            continue;
        }
        line[n] = '\0';  // the newline (or the spare byte after a last line) ends it
        switch (parse_candump_line(line, buses_, out)) {
            case LineKind::kBlank: continue;
            case LineKind::kBad: bad_line(); continue;
            case LineKind::kUnknownBus:
                if (counters_.unknown_bus++ == 0) counters_.first_unknown_bus = line_;
                continue;
            case LineKind::kFrame: break;
        }
        if (realtime_) {
            if (t0_log_ < 0) {
                t0_log_ = out.t_us;
                t0_wall_ = realtime_us();
            }
            const int64_t due = t0_wall_ + (out.t_us - t0_log_);
            timespec ts{time_t(due / 1000000), long(due % 1000000) * 1000};
            while (clock_nanosleep(CLOCK_REALTIME, TIMER_ABSTIME, &ts, nullptr) == EINTR) {}
        }
        ++counters_.frames;
        return ReadStatus::kFrame;
    }
}

// ---- datagrams (loopback and SocketCAN) ---------------------------------------------------------------

namespace {

enum class Got { kFrame, kNone, kBad, kError };

// One non-blocking read of one socket; `drops`: the socket's SO_RXQ_OVFL count, updated when the message has one.
Got read_one(int fd, RxFrame& out, uint32_t& drops, std::string& error) noexcept {
    can_frame f{};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timeval)) + CMSG_SPACE(sizeof(uint32_t))];
    iovec iov{&f, sizeof f};
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    const ssize_t got = recvmsg(fd, &msg, MSG_DONTWAIT);
    if (got < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return Got::kNone;
        error = std::string("recvmsg: ") + std::strerror(errno);
        return Got::kError;
    }
    if (size_t(got) != sizeof f || (msg.msg_flags & MSG_TRUNC) || f.len > CAN_MAX_DLEN) return Got::kBad;
    out.t_us = 0;
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_TIMESTAMP) {
            timeval tv{};
            std::memcpy(&tv, CMSG_DATA(c), sizeof tv);
            out.t_us = int64_t(tv.tv_sec) * 1000000 + tv.tv_usec;
        } else if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
            std::memcpy(&drops, CMSG_DATA(c), sizeof drops);
        }
    }
    if (out.t_us == 0) out.t_us = realtime_us();
    out.frame = f;
    return Got::kFrame;
}

}  // namespace

ReadStatus read_datagram(const std::vector<int>& fds, DatagramQueue& q, int timeout_ms, RxFrame& out,
                         SourceCounters& counters, std::string& error) noexcept {
    const size_t n = fds.size() < DatagramQueue::kMaxFds ? fds.size() : DatagramQueue::kMaxFds;
    pollfd pfd[DatagramQueue::kMaxFds];
    while (true) {
        // Top up: a frame ahead from every socket that has one queued (bad datagrams are counted and skipped).
        for (size_t i = 0; i < n; ++i) {
            while (!q.has[i]) {
                const uint32_t before = q.drops[i];
                const Got g = read_one(fds[i], q.ahead[i], q.drops[i], error);
                counters.kernel_drops += uint32_t(q.drops[i] - before);  // the kernel's count wraps at 2^32
                if (g == Got::kError) return ReadStatus::kError;
                if (g == Got::kNone) break;
                if (g == Got::kBad) {
                    ++counters.bad_size;
                    continue;
                }
                q.ahead[i].bus = int(i);
                q.has[i] = true;
            }
        }
        size_t best = n;
        for (size_t i = 0; i < n; ++i)
            if (q.has[i] && (best == n || q.ahead[i].t_us < q.ahead[best].t_us)) best = i;
        if (best < n) {
            out = q.ahead[best];
            q.has[best] = false;
            ++counters.frames;
            return ReadStatus::kFrame;
        }
        for (size_t i = 0; i < n; ++i) pfd[i] = pollfd{fds[i], POLLIN, 0};
        const int r = poll(pfd, nfds_t(n), timeout_ms);
        if (r < 0) {
            if (errno == EINTR) return ReadStatus::kTimeout;  // a signal: let the caller look at its flags
            error = std::string("poll: ") + std::strerror(errno);
            return ReadStatus::kError;
        }
        if (r == 0) return ReadStatus::kTimeout;
    }
}

// ---- loopback -----------------------------------------------------------------------------------------

std::string loopback_path(const std::string& dir, const std::string& bus) { return dir + "/" + bus + ".can"; }

namespace {
bool make_address(const std::string& path, sockaddr_un& a, std::string& error) {
    a = sockaddr_un{};
    a.sun_family = AF_UNIX;
    if (path.size() >= sizeof a.sun_path) {
        error = path + ": loopback socket path too long";
        return false;
    }
    std::memcpy(a.sun_path, path.c_str(), path.size() + 1);
    return true;
}
}  // namespace

std::unique_ptr<LoopbackSource> LoopbackSource::open(const std::string& dir, std::vector<std::string> buses,
                                                     std::string& error) {
    std::unique_ptr<LoopbackSource> s(new LoopbackSource());
    for (const auto& bus : buses) {
        const std::string path = loopback_path(dir, bus);
        sockaddr_un a;
        if (!make_address(path, a, error)) return nullptr;
        const int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
        if (fd < 0) {
            error = std::string("loopback: socket(AF_UNIX): ") + std::strerror(errno);
            return nullptr;
        }
        s->fds_.push_back(fd);
        const int on = 1;
        ::unlink(path.c_str());  // a stale socket of an earlier run
        if (setsockopt(fd, SOL_SOCKET, SO_TIMESTAMP, &on, sizeof on) != 0 ||
            bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
            error = path + ": loopback bind: " + std::strerror(errno);
            return nullptr;
        }
        s->paths_.push_back(path);
    }
    return s;
}

LoopbackSource::~LoopbackSource() {
    for (int fd : fds_) ::close(fd);
    for (const auto& p : paths_) ::unlink(p.c_str());
}

ReadStatus LoopbackSource::read(RxFrame& out, int timeout_ms) noexcept {
    return read_datagram(fds_, queue_, timeout_ms, out, counters_, error_);
}

std::unique_ptr<LoopbackSink> LoopbackSink::open(const std::string& dir, const std::vector<std::string>& buses,
                                                 std::string& error) {
    std::unique_ptr<LoopbackSink> s(new LoopbackSink());
    s->fd_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (s->fd_ < 0) {
        error = std::string("loopback: socket(AF_UNIX): ") + std::strerror(errno);
        return nullptr;
    }
    for (const auto& bus : buses) {  // addresses made once: send() is on the boards' paced path
        sockaddr_un a;
        if (!make_address(loopback_path(dir, bus), a, error)) return nullptr;
        s->addresses_.push_back(a);
    }
    return s;
}

LoopbackSink::~LoopbackSink() {
    if (fd_ >= 0) ::close(fd_);
}

bool LoopbackSink::send(const can_frame& f, int bus) noexcept {
    if (bus < 0 || size_t(bus) >= addresses_.size()) return false;
    const sockaddr_un& a = addresses_[size_t(bus)];
    return sendto(fd_, &f, sizeof f, 0, reinterpret_cast<const sockaddr*>(&a), sizeof a) == ssize_t(sizeof f);
}

}  // namespace dynid::rt
