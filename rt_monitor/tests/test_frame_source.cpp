// Frame sources: candump -L parsing and replay, the AF_UNIX loopback transport, SocketCAN filters, and the
// SocketCAN/vcan integration where the kernel has AF_CAN (skipped, with the reason, where it has not).
#include <gtest/gtest.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <string>

#include "rt_monitor/frame_source.hpp"

using namespace dynid::rt;

namespace {

const std::vector<std::string> kBuses = {"can0", "can1", "can2"};

std::string temp_dir() {
    char tmpl[] = "/tmp/rt_fs_XXXXXX";
    const char* d = mkdtemp(tmpl);
    EXPECT_NE(d, nullptr);
    return d ? d : "/tmp";
}

bool same(const can_frame& a, const can_frame& b) {
    return a.can_id == b.can_id && a.len == b.len && std::memcmp(a.data, b.data, a.len) == 0;
}

}  // namespace

TEST(Candump, ParsesStandardExtendedRemoteAndErrorFrames) {
    RxFrame f;
    ASSERT_EQ(parse_candump_line("(1700000000.000001) can1 3DA#00800180FF7F05\n", kBuses, f), LineKind::kFrame);
    EXPECT_EQ(f.t_us, 1700000000000001LL);
    EXPECT_EQ(f.bus, 1);
    EXPECT_EQ(f.frame.can_id, 0x3DAu);
    ASSERT_EQ(f.frame.len, 7);
    const uint8_t want[7] = {0x00, 0x80, 0x01, 0x80, 0xFF, 0x7F, 0x05};
    EXPECT_EQ(std::memcmp(f.frame.data, want, 7), 0);

    ASSERT_EQ(parse_candump_line("(12.5) can2 1234ABCD#", kBuses, f), LineKind::kFrame);
    EXPECT_EQ(f.t_us, 12500000);
    EXPECT_EQ(f.frame.can_id, 0x1234ABCDu | CAN_EFF_FLAG);
    EXPECT_EQ(f.frame.len, 0);

    ASSERT_EQ(parse_candump_line("(1.000000) can0 113#R4", kBuses, f), LineKind::kFrame);
    EXPECT_EQ(f.frame.can_id, 0x113u | CAN_RTR_FLAG);
    EXPECT_EQ(f.frame.len, 4);

    // candump prints an error frame with CAN_ERR_FLAG in an 8-digit ID.
    ASSERT_EQ(parse_candump_line("(1.000000) can0 20000004#0004000000000000", kBuses, f), LineKind::kFrame);
    EXPECT_EQ(f.frame.can_id, CAN_ERR_FLAG | 0x4u);
    EXPECT_EQ(f.frame.len, 8);
    EXPECT_EQ(f.frame.data[1], 0x04);
}

TEST(Candump, RefusesWhatIsNotAClassicFrame) {
    RxFrame f;
    for (const char* bad : {
             "can0 111#00",                              // no time
             "(1.0 can0 111#00",                         // unclosed time
             "(1.) can0 111#00",                         // empty fraction
             "(1.0) can0 11#00",                         // 2-digit ID
             "(1.0) can0 800#00",                        // 3 digits but above 0x7FF
             "(1.0) can0 111#000",                       // odd number of digits
             "(1.0) can0 111#001122334455667788",        // 9 bytes
             "(1.0) can0 111##10011",                    // CAN FD
             "(1.0) can0 111#0G",                        // not hex
             "(1.0) can0 111#00 x",                      // trailing garbage
             "(1.0) can0 111",                           // no '#'
         }) {
        EXPECT_EQ(parse_candump_line(bad, kBuses, f), LineKind::kBad) << bad;
    }
    EXPECT_EQ(parse_candump_line("(1.0) vcan9 111#00", kBuses, f), LineKind::kUnknownBus);
    EXPECT_EQ(parse_candump_line("   \n", kBuses, f), LineKind::kBlank);
    EXPECT_EQ(parse_candump_line("# a comment", kBuses, f), LineKind::kBlank);
    EXPECT_EQ(parse_candump_line("(1.0) can0 111#00.11.22", kBuses, f), LineKind::kFrame);  // cansend's dots
    EXPECT_EQ(f.frame.len, 3);
}

TEST(Candump, FormatParsesBackToTheSameFrame) {
    std::mt19937 rng(7);
    for (int i = 0; i < 2000; ++i) {
        RxFrame a;
        const unsigned kind = rng() % 4;
        a.frame.can_id = kind == 0 ? (rng() & CAN_EFF_MASK) | CAN_EFF_FLAG
                       : kind == 1 ? (rng() & CAN_ERR_MASK) | CAN_ERR_FLAG
                                   : rng() & CAN_SFF_MASK;
        if (kind == 3) a.frame.can_id |= CAN_RTR_FLAG;
        a.frame.len = uint8_t(rng() % 9);
        if (kind != 3)
            for (int k = 0; k < a.frame.len; ++k) a.frame.data[k] = uint8_t(rng());
        a.t_us = int64_t(rng()) * 1000 + rng() % 1000;
        a.bus = int(rng() % 3);
        RxFrame b;
        const std::string line = format_candump_line(a, kBuses);
        ASSERT_EQ(parse_candump_line(line.c_str(), kBuses, b), LineKind::kFrame) << line;
        EXPECT_TRUE(same(a.frame, b.frame)) << line;
        EXPECT_EQ(a.t_us, b.t_us) << line;
        EXPECT_EQ(a.bus, b.bus) << line;
    }
}

// The largest stamp whose µs fit int64 parses; one second more is a bad line (fuzzer finding: 9223372036854 to
// 9223372036859 s passed the old bound and overflowed int64 when scaled to µs).
TEST(Candump, StampsUpToTheInt64LimitAndNoFurther) {
    RxFrame f;
    ASSERT_EQ(parse_candump_line("(9223372036853.999999) can0 111#00", kBuses, f), LineKind::kFrame);
    EXPECT_EQ(f.t_us, INT64_C(9223372036853999999));
    for (const char* bad : {"(9223372036854.000000) can0 111#00", "(9223372036857) can0 111#00",
                            "(9223372036859.5) can0 111#00", "(92233720368547758070) can0 111#00"})
        EXPECT_EQ(parse_candump_line(bad, kBuses, f), LineKind::kBad) << bad;
}

// Opens the log and reads it to its end (or its first non-frame status): the frames' IDs, and the replay for its
// counters. Null if it does not open (the reason printed).
std::unique_ptr<CandumpReplay> replay_all(const std::string& path, std::vector<canid_t>& ids) {
    std::string err;
    auto r = CandumpReplay::open(path, kBuses, false, err);
    if (!r) {
        ADD_FAILURE() << err;
        return r;
    }
    RxFrame f;
    while (r->read(f, 0) == ReadStatus::kFrame) ids.push_back(f.frame.can_id);
    return r;
}

TEST(Candump, ReplayCountsBadLinesAndEnds) {
    const std::string path = temp_dir() + "/x.log";
    std::ofstream(path) << "(1.000000) can0 3DA#008000800080\n"
                           "garbage\n"
                           "(1.000100) can7 3DB#008000800080\n"
                           "(1.000200) can1 111#0000000000000000\n"
                        << "(1.0003) can1 112#" << std::string(400, '0') << "\n"  // overlong
                        << "(1.000400) can2 480#0100";  // no final newline
    std::vector<canid_t> ids;
    auto r = replay_all(path, ids);
    ASSERT_TRUE(r);
    EXPECT_EQ(ids, (std::vector<canid_t>{0x3DA, 0x111, 0x480}));
    EXPECT_EQ(r->counters().frames, 3u);
    EXPECT_EQ(r->counters().bad_lines, 2u);
    EXPECT_EQ(r->counters().unknown_bus, 1u);
    RxFrame f;
    EXPECT_EQ(r->read(f, 0), ReadStatus::kEnd);

    std::string err;
    EXPECT_FALSE(CandumpReplay::open("/nonexistent/x.log", kBuses, false, err));
    EXPECT_NE(err.find("/nonexistent/x.log: cannot open candump log"), std::string::npos) << err;
}

// A damaged log (issue 22, found by the fuzzer): a line with a NUL byte whose rest is a frame. fgets + strlen ended
// the line's text at the NUL, and once the line was longer than the buffer its rest was read as a line of its own:
// here a frame out of a line that is not one. Now such a line is one bad line, however long, and nothing else.
TEST(Candump, ALineWithANulByteIsOneBadLine) {
    const std::string path = temp_dir() + "/nul.log";
    std::string text = "(1.000000) can0 111#00";
    text += '\0';
    text += std::string(150, 'x') + "(1.000100) can1 112#0000\n";  // past the 160-byte buffer
    text += "(1.000200) can0 3DA#00";
    text += '\0';
    text += "80\n(1.000300) can2 480#0100\n";  // short, a NUL in it
    std::ofstream(path, std::ios::binary) << text;
    std::vector<canid_t> ids;
    auto r = replay_all(path, ids);
    ASSERT_TRUE(r);
    EXPECT_EQ(ids, (std::vector<canid_t>{0x480}));
    EXPECT_EQ(r->counters().bad_lines, 2u);
    EXPECT_EQ(r->line_number(), 3u);
}

// The replay reads the log in 64 KiB blocks and finds lines in place: a line that spans blocks is whole, and one
// longer than a block (a damaged log) is one bad line however many blocks it spans, the lines after it intact.
TEST(Candump, LinesAcrossTheReadBufferAndLongerThanIt) {
    const std::string path = temp_dir() + "/blocks.log";
    std::string text;
    int frames = 0;
    while (text.size() < 65536 - 10) text += "(1.000000) can0 111#0011223344556677\n", ++frames;  // one spans the edge
    text += "(1.000100) can1 112#" + std::string(200000, '0') + "\n";  // over three blocks
    text += "(1.000200) can2 480#0100\n";
    std::ofstream(path) << text;
    std::vector<canid_t> ids;
    auto r = replay_all(path, ids);
    ASSERT_TRUE(r);
    ASSERT_EQ(ids.size(), size_t(frames) + 1);
    EXPECT_EQ(ids.back(), 0x480u);
    EXPECT_EQ(r->counters().bad_lines, 1u);
    EXPECT_EQ(r->line_number(), uint64_t(frames) + 2);
}

TEST(Candump, RealTimeReplayKeepsTheLogsPace) {
    const std::string path = temp_dir() + "/rt.log";
    std::ofstream(path) << "(100.000000) can0 111#00\n(100.030000) can0 111#01\n(100.060000) can0 111#02\n";
    std::string err;
    auto r = CandumpReplay::open(path, kBuses, true, err);
    ASSERT_TRUE(r) << err;
    RxFrame f;
    const auto t0 = std::chrono::steady_clock::now();
    int n = 0;
    while (r->read(f, 0) == ReadStatus::kFrame) ++n;
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(n, 3);
    EXPECT_GE(ms, 59.0);
    EXPECT_LT(ms, 1000.0);
}

// A monitor's loopback source and a boards' sink on the same directory.
static void open_loopback(const std::string& dir, std::unique_ptr<LoopbackSource>& src,
                          std::unique_ptr<LoopbackSink>& sink) {
    std::string err;
    src = LoopbackSource::open(dir, kBuses, err);
    ASSERT_TRUE(src) << err;
    sink = LoopbackSink::open(dir, kBuses, err);
    ASSERT_TRUE(sink) << err;
}

TEST(Loopback, CarriesCanFrameBytesPerBusWithTimestamps) {
    const std::string dir = temp_dir();
    std::unique_ptr<LoopbackSource> src;
    std::unique_ptr<LoopbackSink> sink;
    ASSERT_NO_FATAL_FAILURE(open_loopback(dir, src, sink));
    RxFrame f;
    EXPECT_EQ(src->read(f, 10), ReadStatus::kTimeout);

    can_frame a{};
    a.can_id = 0x3DB;
    a.len = 6;
    for (int i = 0; i < 6; ++i) a.data[i] = uint8_t(0x10 * i + 1);
    can_frame b{};
    b.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
    b.len = 8;
    const int64_t before = realtime_us();
    ASSERT_TRUE(sink->send(a, 2));
    ASSERT_TRUE(sink->send(b, 0));
    EXPECT_FALSE(sink->send(b, 3));  // no such bus

    std::vector<std::pair<int, canid_t>> got;
    for (int i = 0; i < 2; ++i) {
        ASSERT_EQ(src->read(f, 1000), ReadStatus::kFrame);
        EXPECT_GE(f.t_us, before);
        EXPECT_LE(f.t_us, realtime_us());
        EXPECT_TRUE(same(f.frame, f.bus == 2 ? a : b));
        got.emplace_back(f.bus, f.frame.can_id);
    }
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, (std::vector<std::pair<int, canid_t>>{{0, b.can_id}, {2, 0x3DB}}));

    // A datagram that is not one struct can_frame is counted and dropped.
    const int fd = socket(AF_UNIX, SOCK_DGRAM, 0);
    sockaddr_un to{};
    to.sun_family = AF_UNIX;
    std::strcpy(to.sun_path, loopback_path(dir, "can1").c_str());
    const char junk[5] = {1, 2, 3, 4, 5};
    ASSERT_EQ(sendto(fd, junk, sizeof junk, 0, reinterpret_cast<sockaddr*>(&to), sizeof to), 5);
    ::close(fd);
    ASSERT_TRUE(sink->send(a, 1));
    ASSERT_EQ(src->read(f, 1000), ReadStatus::kFrame);
    EXPECT_EQ(f.bus, 1);
    EXPECT_EQ(src->counters().bad_size, 1u);
    EXPECT_EQ(src->counters().frames, 3u);
}

TEST(Loopback, FramesQueuedOnSeveralBusesComeOutInStampOrder) {
    // A monitor that fell behind finds a sample's frames queued on three buses: it must read them as they were
    // sent (the strain pair after the positions of the same sample), not bus by bus.
    const std::string dir = temp_dir();
    std::unique_ptr<LoopbackSource> src;
    std::unique_ptr<LoopbackSink> sink;
    ASSERT_NO_FATAL_FAILURE(open_loopback(dir, src, sink));
    const int order[] = {2, 1, 0, 2, 0, 1, 1, 2, 0, 0, 2};
    for (size_t k = 0; k < sizeof order / sizeof order[0]; ++k) {
        can_frame f{};
        f.can_id = canid_t(0x100 + k);
        f.len = 1;
        ASSERT_TRUE(sink->send(f, order[k]));
        const int64_t t = realtime_us();
        while (realtime_us() == t) {}  // distinct µs stamps
    }
    RxFrame f;
    for (size_t k = 0; k < sizeof order / sizeof order[0]; ++k) {
        ASSERT_EQ(src->read(f, 1000), ReadStatus::kFrame);
        EXPECT_EQ(f.frame.can_id, canid_t(0x100 + k));
        EXPECT_EQ(f.bus, order[k]);
    }
    EXPECT_EQ(src->read(f, 10), ReadStatus::kTimeout);
}

TEST(SocketCan, FiltersPassOnlyStandardDataFramesOfTheTablesIds) {
    const auto filters = socketcan_filters({0x3DA, 0x3DB, 0x111, 0x480, 0x7FF, 0x000});
    ASSERT_EQ(filters.size(), 6u);
    for (canid_t id : {0x3DAu, 0x3DBu, 0x111u, 0x480u, 0x7FFu, 0x000u})
        EXPECT_TRUE(socketcan_filter_passes(filters, id)) << std::hex << id;
    for (canid_t id : {0x3DCu, 0x1F3u, 0x112u, 0x481u, 0x514u, 0x3DAu | CAN_EFF_FLAG, 0x111u | CAN_RTR_FLAG,
                       0x7FEu, 0x1000u | 0x111u | CAN_EFF_FLAG})
        EXPECT_FALSE(socketcan_filter_passes(filters, id)) << std::hex << id;
    EXPECT_FALSE(socketcan_filter_passes(socketcan_filters({}), 0x3DA));  // a bus with no frame: nothing passes
}

// The vcan integration test: where AF_CAN exists and vcan0 is up, a frame sent on it is read back with a
// kernel timestamp. Elsewhere it reports itself skipped, with the reason.
TEST(SocketCan, VcanRoundTrip) {
    const int probe = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (probe < 0) GTEST_SKIP() << "AF_CAN unsupported by this kernel (" << std::strerror(errno) << "): no SocketCAN";
    ::close(probe);
    if (if_nametoindex("vcan0") == 0) GTEST_SKIP() << "no vcan0 interface (ip link add dev vcan0 type vcan)";
    std::string err;
    auto src = SocketCanSource::open({"vcan0"}, {socketcan_filters({0x3DA, 0x3DB, 0x111})}, err);
    ASSERT_TRUE(src) << err;
    const int tx = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    sockaddr_can a{};
    a.can_family = AF_CAN;
    a.can_ifindex = int(if_nametoindex("vcan0"));
    ASSERT_EQ(bind(tx, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    can_frame out{};
    out.can_id = 0x514;  // filtered out
    ASSERT_EQ(write(tx, &out, sizeof out), ssize_t(sizeof out));
    out.can_id = 0x3DA;
    out.len = 6;
    const int64_t before = realtime_us();
    ASSERT_EQ(write(tx, &out, sizeof out), ssize_t(sizeof out));
    RxFrame f;
    ASSERT_EQ(src->read(f, 1000), ReadStatus::kFrame);
    EXPECT_EQ(f.frame.can_id, 0x3DAu);
    EXPECT_GE(f.t_us, before);
    ::close(tx);
}

TEST(SocketCan, FramesTheKernelDroppedAreCounted) {
    // A monitor that does not read while the bus runs on: its socket's receive queue fills and the kernel drops the
    // frames after that (SO_RXQ_OVFL reports how many, on the next frame queued once there is room again).
    const int probe = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (probe < 0) GTEST_SKIP() << "AF_CAN unsupported by this kernel (" << std::strerror(errno) << "): no SocketCAN";
    ::close(probe);
    if (if_nametoindex("vcan0") == 0) GTEST_SKIP() << "no vcan0 interface (ip link add dev vcan0 type vcan)";
    std::string err;
    auto src = SocketCanSource::open({"vcan0"}, {socketcan_filters({0x3DA})}, err);
    ASSERT_TRUE(src) << err;
    const int tx = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    sockaddr_can a{};
    a.can_family = AF_CAN;
    a.can_ifindex = int(if_nametoindex("vcan0"));
    ASSERT_EQ(bind(tx, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    can_frame out{};
    out.can_id = 0x3DA;
    out.len = 6;
    const int sent = 20000;  // far more than a default receive buffer holds
    for (int i = 0; i < sent; ++i) ASSERT_EQ(write(tx, &out, sizeof out), ssize_t(sizeof out)) << i;
    RxFrame f;
    int got = 0;
    while (src->read(f, 200) == ReadStatus::kFrame) ++got;
    ASSERT_GT(got, 0);
    ASSERT_LT(got, sent);
    ASSERT_EQ(write(tx, &out, sizeof out), ssize_t(sizeof out));  // one more, queued with the count
    ASSERT_EQ(src->read(f, 1000), ReadStatus::kFrame);
    EXPECT_EQ(src->counters().kernel_drops, uint64_t(sent - got));
    EXPECT_EQ(src->counters().frames, uint64_t(got + 1));
    ::close(tx);
}

TEST(SocketCan, OpenFailsWithOneLineNamingTheProblem) {
    std::string err;
    auto src = SocketCanSource::open({"nosuchcan7"}, {socketcan_filters({0x111})}, err);
    ASSERT_FALSE(src);
    EXPECT_EQ(err.find('\n'), std::string::npos);
    EXPECT_EQ(err.rfind("nosuchcan7: ", 0), 0u) << err;
    const int probe = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (probe < 0) {
        EXPECT_NE(err.find("this kernel has no SocketCAN"), std::string::npos) << err;
    } else {
        ::close(probe);
        EXPECT_NE(err.find("no such CAN interface"), std::string::npos) << err;
    }
}
