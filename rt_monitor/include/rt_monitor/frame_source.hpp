// Frame sources: where the monitor's CAN frames come from (docs/design.md §5). One interface, three transports:
// - SocketCAN raw sockets on one or more interfaces, with kernel filters and kernel timestamps (production);
// - candump -L log replay, as fast as possible or paced in real time (offline);
// - a loopback transport carrying the same `struct can_frame` bytes between processes as AF_UNIX datagrams,
//   one socket per bus (live tests on machines without AF_CAN).
// Every frame carries its bus index (the position of its interface in the configured bus list) and a
// timestamp in µs. Frames the source cannot parse are counted, never returned.
#pragma once

#include <linux/can.h>
#include <sys/un.h>

#include <cstdint>
#include <array>
#include <memory>
#include <string>
#include <vector>

namespace dynid::rt {

struct RxFrame {
    can_frame frame{};  // the kernel's layout: can_id with CAN_EFF/RTR/ERR flags, len, data
    int64_t t_us = 0;   // µs: the log's timestamp, the kernel's, or the receive time (CLOCK_REALTIME)
    int bus = 0;        // index into the configured bus names
};

enum class ReadStatus { kFrame, kTimeout, kEnd, kError };

struct SourceCounters {
    uint64_t frames = 0;       // returned to the caller
    uint64_t bad_lines = 0;    // replay: lines that are not a classic-CAN candump -L frame
    uint64_t unknown_bus = 0;  // replay: frames of an interface not in the bus list (skipped)
    uint64_t first_bad_line = 0;     // replay: the log's line number of the first bad line (0: none)
    uint64_t first_unknown_bus = 0;  // replay: the line of the first frame of an interface not in the list (0: none)
    uint64_t bad_size = 0;     // loopback: datagrams that are not one struct can_frame
    uint64_t kernel_drops = 0; // SocketCAN: frames the kernel dropped, the socket's receive queue full (SO_RXQ_OVFL)
};

class FrameSource {
public:
    virtual ~FrameSource() = default;
    // Waits up to timeout_ms (-1: forever) for one frame. kEnd: a replay is over. kError: see error().
    virtual ReadStatus read(RxFrame& out, int timeout_ms) noexcept = 0;
    const SourceCounters& counters() const noexcept { return counters_; }
    const std::string& error() const noexcept { return error_; }

protected:
    SourceCounters counters_;
    std::string error_;
};

// Shared by the loopback and SocketCAN sources: one frame read ahead per socket, so that frames queued on
// several buses come out in stamp order. A monitor that fell behind (preempted, or a late sender's burst)
// otherwise reads them bus by bus, and a strain pair read before the same sample's positions on another bus
// takes the previous sample's (held) positions.
struct DatagramQueue {
    static constexpr size_t kMaxFds = 16;
    std::array<RxFrame, kMaxFds> ahead{};
    std::array<bool, kMaxFds> has{};
    std::array<uint32_t, kMaxFds> drops{};  // each socket's drop count (SO_RXQ_OVFL) as last reported
};

// ---- candump -L ---------------------------------------------------------------------------------------
enum class LineKind { kFrame, kBlank, kBad, kUnknownBus };
// One line `(SECONDS.FRACTION) IFACE ID#DATA` (ID: 3 hex digits standard, 8 extended or an error frame with
// CAN_ERR_FLAG; `ID#R[len]` remote). CAN FD (`##`) is not classic CAN: kBad. Blank lines and `#` comments: kBlank.
LineKind parse_candump_line(const char* line, const std::vector<std::string>& buses, RxFrame& out) noexcept;
// The same frame as a candump -L line (no newline), as can-utils prints it.
std::string format_candump_line(const RxFrame& f, const std::vector<std::string>& buses);

class CandumpReplay final : public FrameSource {
public:
    // realtime: frames are released at their log time relative to the first one; else as fast as possible.
    static std::unique_ptr<CandumpReplay> open(const std::string& path, std::vector<std::string> buses,
                                               bool realtime, std::string& error);
    ~CandumpReplay() override;
    ReadStatus read(RxFrame& out, int timeout_ms) noexcept override;
    uint64_t line_number() const noexcept { return line_; }

private:
    // A classic-CAN candump -L line is < 80 characters; a longer one than this is a bad line (as fgets' 160-byte
    // buffer had it).
    static constexpr size_t kMaxLine = 158, kBufferSize = size_t(1) << 16;
    enum class Next { kLine, kOverlong, kEnd, kError };
    CandumpReplay() = default;
    // The next line in the buffer (its newline excluded; the log's last may have none), reading more as needed.
    Next next_line(char*& line, size_t& n) noexcept;
    void bad_line() noexcept {  // counted, the first one's line number kept for the run's end
        if (counters_.bad_lines++ == 0) counters_.first_bad_line = line_;
    }
    int fd_ = -1;
    std::vector<char> buffer_;  // the log's bytes, [begin_, end_) not yet handed out; allocated at open
    size_t begin_ = 0, end_ = 0;
    bool eof_ = false, skipping_ = false;  // skipping_: inside an overlong line, until its newline
    std::vector<std::string> buses_;
    bool realtime_ = false;
    int64_t t0_log_ = -1, t0_wall_ = 0;
    uint64_t line_ = 0;
};

// ---- loopback (AF_UNIX datagrams of struct can_frame) -------------------------------------------------
// The socket of bus `name` is `<dir>/<name>.can`.
std::string loopback_path(const std::string& dir, const std::string& bus);

class LoopbackSource final : public FrameSource {
public:
    static std::unique_ptr<LoopbackSource> open(const std::string& dir, std::vector<std::string> buses,
                                                std::string& error);
    ~LoopbackSource() override;
    ReadStatus read(RxFrame& out, int timeout_ms) noexcept override;

private:
    LoopbackSource() = default;
    std::vector<int> fds_;
    std::vector<std::string> paths_;
    DatagramQueue queue_;
};

class LoopbackSink {
public:
    static std::unique_ptr<LoopbackSink> open(const std::string& dir, const std::vector<std::string>& buses,
                                              std::string& error);
    ~LoopbackSink();
    // false if the datagram could not be sent (no monitor listening, or its queue is full).
    bool send(const can_frame& f, int bus) noexcept;

private:
    LoopbackSink() = default;
    int fd_ = -1;
    std::vector<sockaddr_un> addresses_;  // per bus, made at open
};

// ---- SocketCAN ---------------------------------------------------------------------------------------
// Kernel filters that pass the standard-ID data frames of the given IDs only (the bus table's frames on one bus: the
// kernel takes up to 512 per socket); error frames come through CAN_RAW_ERR_FILTER. The kernel passes a frame iff
// (id & mask) == (filter.id & mask) for one of them.
std::vector<can_filter> socketcan_filters(const std::vector<uint32_t>& ids);
bool socketcan_filter_passes(const std::vector<can_filter>& filters, canid_t id) noexcept;

class SocketCanSource final : public FrameSource {
public:
    // Opens one CAN_RAW socket per interface with its filters (filters[i] for interfaces[i]), error frames and
    // SO_TIMESTAMP. On failure, one line naming the interface and the call (e.g. no AF_CAN in this kernel).
    static std::unique_ptr<SocketCanSource> open(const std::vector<std::string>& interfaces,
                                                 const std::vector<std::vector<can_filter>>& filters,
                                                 std::string& error);
    ~SocketCanSource() override;
    ReadStatus read(RxFrame& out, int timeout_ms) noexcept override;

private:
    SocketCanSource() = default;
    std::vector<int> fds_;
    DatagramQueue queue_;
};

// Reads one datagram of struct can_frame: the earliest-stamped of those queued on `fds` (waiting up to
// timeout_ms for one). Timestamp: SO_TIMESTAMP's control message if present, else now. A socket's SO_RXQ_OVFL
// message (its frames dropped so far, the receive queue full) adds what it grew by to counters.kernel_drops.
ReadStatus read_datagram(const std::vector<int>& fds, DatagramQueue& q, int timeout_ms, RxFrame& out,
                         SourceCounters& counters, std::string& error) noexcept;

int64_t realtime_us() noexcept;

}  // namespace dynid::rt
