// libFuzzer harness: candump -L input. The bytes are a log replayed by CandumpReplay (the 160-byte line buffer,
// overlong lines, a last line without a newline, NUL bytes) from a memory file; each line is also parsed on its own
// by parse_candump_line. Properties: every line is counted exactly once (frame, blank, bad or unknown bus); a frame
// has at most 8 data bytes, a valid ID for its flags, a non-negative stamp and a configured bus; and it formats to
// a candump line that parses back to the same frame.
#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "rt_monitor/frame_source.hpp"

using namespace dynid::rt;

#define CHECK(cond) do { if (!(cond)) std::abort(); } while (0)

namespace {

const std::vector<std::string> kBuses = {"can0", "can1", "can2"};

void check_frame(const RxFrame& f) {
    CHECK(f.bus >= 0 && f.bus < int(kBuses.size()) && f.t_us >= 0 && f.frame.len <= CAN_MAX_DLEN);
    const canid_t id = f.frame.can_id;
    if (!(id & (CAN_EFF_FLAG | CAN_ERR_FLAG))) CHECK((id & ~CAN_RTR_FLAG) <= CAN_SFF_MASK);
    RxFrame back;
    const std::string line = format_candump_line(f, kBuses);
    CHECK(parse_candump_line(line.c_str(), kBuses, back) == LineKind::kFrame);
    CHECK(back.bus == f.bus && back.t_us == f.t_us && back.frame.can_id == f.frame.can_id &&
          back.frame.len == f.frame.len && std::memcmp(back.frame.data, f.frame.data, f.frame.len) == 0);
}

// The input as a file the replay opens by path: a memfd, rewritten per input (no disk I/O).
std::string memory_file(const uint8_t* data, size_t size) {
    static int fd = memfd_create("fuzz_candump", 0);
    CHECK(fd >= 0);
    CHECK(ftruncate(fd, 0) == 0);
    CHECK(pwrite(fd, data, size, 0) == ssize_t(size));
    return "/proc/self/fd/" + std::to_string(fd);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    // Line by line, as the parser sees them (a NUL ends a line's text, as in the replay's buffer).
    size_t lines = 0;
    for (size_t at = 0; at < size;) {
        const uint8_t* nl = static_cast<const uint8_t*>(std::memchr(data + at, '\n', size - at));
        const size_t end = nl ? size_t(nl - data) + 1 : size;
        const std::string line(reinterpret_cast<const char*>(data + at), end - at);
        RxFrame f;
        if (parse_candump_line(line.c_str(), kBuses, f) == LineKind::kFrame) check_frame(f);
        ++lines;
        at = end;
    }
    // The replay: every line counted once (a line over the buffer is one bad line, however long).
    std::string err;
    auto r = CandumpReplay::open(memory_file(data, size), kBuses, false, err);
    CHECK(r != nullptr);
    RxFrame f;
    ReadStatus st;
    uint64_t frames = 0;
    while ((st = r->read(f, 0)) == ReadStatus::kFrame) {
        check_frame(f);
        ++frames;
    }
    CHECK(st == ReadStatus::kEnd);
    const SourceCounters& c = r->counters();
    CHECK(c.frames == frames && r->line_number() == lines);
    CHECK(c.frames + c.bad_lines + c.unknown_bus <= lines);
    return 0;
}
