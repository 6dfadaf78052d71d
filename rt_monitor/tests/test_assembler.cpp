// The generic frame decoder and sample assembly (bus_table.hpp, assembler.hpp) on tables that are no iCub's: bits in
// both byte orders, signs and IEEE floats by hand; a CANopen-style robot clocked by its last frame, with measured
// velocities, currents and an F/T sensor whose halves are paired but do not clock; every counter, held, stale,
// restarts and refusals. (ctest rt_assembler; the iCub arm end to end: tools/tests/test_can_e2e.py.)
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>

#include "rt_monitor/assembler.hpp"

using namespace dynid::rt;

namespace {

SignalDef sig(int start, int length, bool big_endian, SignalType type, double scale = 1, double offset = 0) {
    SignalDef s;
    s.start = start, s.length = length, s.big_endian = big_endian, s.type = type, s.scale = scale, s.offset = offset;
    FrameDecoder::place(s);
    return s;
}

}  // namespace

TEST(FrameDecoder, LittleEndianBitsSignsAndScales) {
    const uint8_t d[8] = {0x34, 0x12, 0xFE, 0xFF, 0xFF, 0xFF, 0x80, 0x01};
    EXPECT_EQ(FrameDecoder::raw_bits(sig(0, 16, false, SignalType::kUnsigned), d, 8), 0x1234u);
    EXPECT_EQ(FrameDecoder::raw_bits(sig(4, 8, false, SignalType::kUnsigned), d, 8), 0x23u);  // across a byte
    EXPECT_EQ(FrameDecoder::value(sig(16, 32, false, SignalType::kSigned), d, 8), -2.0);      // 0xFFFFFFFE
    EXPECT_EQ(FrameDecoder::value(sig(16, 32, false, SignalType::kUnsigned), d, 8), 4294967294.0);
    EXPECT_EQ(FrameDecoder::value(sig(48, 16, false, SignalType::kSigned, 0.5, 1.0), d, 8), 0x0180 * 0.5 + 1.0);
    EXPECT_EQ(FrameDecoder::value(sig(55, 1, false, SignalType::kUnsigned), d, 8), 1.0);
    EXPECT_EQ(FrameDecoder::value(sig(0, 64, false, SignalType::kUnsigned), d, 8), double(0x0180FFFFFFFE1234ull));
    // Bytes beyond the frame's length read as 0 (a short frame's optional signals).
    EXPECT_EQ(FrameDecoder::raw_bits(sig(48, 16, false, SignalType::kUnsigned), d, 6), 0u);
    // Offset binary, as the iCub strain board sends it: raw 0x8000 is 0.
    const uint8_t s[2] = {0x00, 0x80};
    EXPECT_EQ(FrameDecoder::value(sig(0, 16, false, SignalType::kUnsigned, 200.0 / 32768, -200.0), s, 2), 0.0);
}

TEST(FrameDecoder, BigEndianFollowsTheDbcsSawtoothNumbering) {
    // Motorola: the start bit is the MSB; bit 7 of byte 0 is 7, the next bits run down, then into byte 1's bit 7.
    const uint8_t d[8] = {0x12, 0x34, 0x56, 0x78, 0x9A, 0xBC, 0xDE, 0xF0};
    EXPECT_EQ(FrameDecoder::raw_bits(sig(7, 16, true, SignalType::kUnsigned), d, 8), 0x1234u);
    EXPECT_EQ(FrameDecoder::raw_bits(sig(7, 8, true, SignalType::kUnsigned), d, 8), 0x12u);
    EXPECT_EQ(FrameDecoder::raw_bits(sig(3, 8, true, SignalType::kUnsigned), d, 8), 0x23u);  // 0x2 of byte 0, 0x3 of 1
    EXPECT_EQ(FrameDecoder::raw_bits(sig(23, 32, true, SignalType::kUnsigned), d, 8), 0x56789ABCu);
    EXPECT_EQ(FrameDecoder::raw_bits(sig(7, 64, true, SignalType::kUnsigned), d, 8), 0x123456789ABCDEF0ull);
    EXPECT_EQ(FrameDecoder::value(sig(55, 16, true, SignalType::kSigned), d, 8), double(int16_t(0xDEF0)));
    EXPECT_EQ(FrameDecoder::raw_bits(sig(0, 1, true, SignalType::kUnsigned), d, 8), 0u);     // byte 0's LSB
    EXPECT_EQ(FrameDecoder::raw_bits(sig(12, 1, true, SignalType::kUnsigned), d, 8), 1u);    // 0x34: bit 4
}

TEST(FrameDecoder, IeeeFloats) {
    uint8_t d[8] = {};
    const float f = -1.25f;
    std::memcpy(d, &f, 4);
    EXPECT_EQ(FrameDecoder::value(sig(0, 32, false, SignalType::kFloat, 2.0, 0.5), d, 8), -2.0);
    const double x = 3.0e-7;
    std::memcpy(d, &x, 8);
    EXPECT_EQ(FrameDecoder::value(sig(0, 64, false, SignalType::kFloat), d, 8), x);
    const uint8_t be[4] = {0x3F, 0xC0, 0x00, 0x00};  // 1.5f, big-endian
    EXPECT_EQ(FrameDecoder::value(sig(7, 32, true, SignalType::kFloat), be, 4), 1.5);
}

namespace {

// A six-frame CANopen-style robot: two joints (position µrad, velocity µrad/s), two currents (mA) in the clock frame
// CUR, sent last; an F/T sensor in two frames paired (not clocking); a heartbeat with a 4-bit counter, a fault bit and
// reserved bits; a float (a torque sensor the coefficient file does not read). Node "drive" sends POS0, POS1 and the heartbeat.
const char* kTable =
    "robot arm\nbuses can0 can1\nstale_ms 5\npair_us 500\n"
    "frame POS0 can0 0x181 8 0 drive 0 -400\n"
    "signal POS0 0 32 le s 1e-06 0 q.j0\nsignal POS0 32 32 le s 1e-06 0 dq.j0\n"
    "frame POS1 can0 0x182 8 0 drive 0 -400\n"
    "signal POS1 0 32 le s 1e-06 0 q.j1\nsignal POS1 32 32 le s 1e-06 0 dq.j1\n"
    "frame HB can0 0x701 2 0 drive 100000 -450\n"
    "signal HB 0 4 le u 1 0 seq\nsignal HB 4 1 le u 1 0 fault\nsignal HB 5 3 le u 1 0 reserved\nsignal HB 8 8 le u 1 0 -\n"
    "frame FT_F can1 0x281 6 0 ft 0 -300\n"
    "signal FT_F 0 16 le s 0.01 0 ft.w.fx\nsignal FT_F 16 16 le s 0.01 0 ft.w.fy\nsignal FT_F 32 16 le s 0.01 0 ft.w.fz\n"
    "frame FT_T can1 0x282 7 0 ft 0 -200\n"
    "signal FT_T 0 16 le s 0.001 0 ft.w.tx\nsignal FT_T 16 16 le s 0.001 0 ft.w.ty\nsignal FT_T 32 16 le s 0.001 0 ft.w.tz\n"
    "signal FT_T 48 1 le u 1 0 saturated\n"
    "frame TEMP can1 0x381 4 0 temp 0 -100\nsignal TEMP 0 32 le f 1 0 tau.j1\n"
    "frame CUR can0 0x191 4 0 amps 0 0\n"
    "signal CUR 7 16 be s 0.001 0 current.m0\nsignal CUR 23 16 be s 0.001 0 current.m1\n"
    "clock CUR\npair FT_F FT_T\n";

struct Robot {
    MonitorConfig cfg;
    std::unique_ptr<Coefficients> coef = std::make_unique<Coefficients>();
    Assembler a;
    int64_t t = 1000000;
};

std::unique_ptr<Robot> robot(std::string& err, const char* joints[2] = nullptr) {
    auto r = std::make_unique<Robot>();
    if (!parse_monitor_config(kTable, "arm.conf", r->cfg, err)) return nullptr;
    r->coef->n_joints = 2;
    r->coef->joint_names[0] = joints ? joints[0] : "j0";
    r->coef->joint_names[1] = joints ? joints[1] : "j1";
    const char* channels[] = {"ft.w.fx", "ft.w.fy", "ft.w.fz", "ft.w.tx", "ft.w.ty", "ft.w.tz", "current.m1", "current.m0"};
    r->coef->n_outputs = 8;
    for (int i = 0; i < 8; ++i) r->coef->channel_names[size_t(i)] = channels[i];
    if (!r->a.init(r->cfg, *r->coef, err)) return nullptr;
    return r;
}

RxFrame frame(int bus, canid_t id, std::initializer_list<uint8_t> bytes, int64_t t) {
    RxFrame f;
    f.bus = bus, f.frame.can_id = id, f.t_us = t;
    f.frame.len = uint8_t(bytes.size());
    int i = 0;
    for (uint8_t b : bytes) f.frame.data[i++] = b;
    return f;
}

// One sample's frames: positions, heartbeat (if seq >= 0), F/T pair, currents (the clock). Returns the push's result.
bool sample(Robot& r, Sample& s, int32_t q0, int32_t q1, int16_t fx, int16_t i0, int seq = -1, bool send_q1 = true,
            bool ft = true) {
    auto le = [](int32_t a, int32_t b) {
        RxFrame f;
        f.frame.len = 8;
        std::memcpy(f.frame.data, &a, 4);
        std::memcpy(f.frame.data + 4, &b, 4);
        return f;
    };
    const int64_t t = r.t;
    r.t += 1000;
    RxFrame p = le(q0, 2 * q0);
    p.bus = 0, p.frame.can_id = 0x181, p.t_us = t - 400;
    r.a.push(p, s);
    if (send_q1) {
        p = le(q1, 2 * q1);
        p.bus = 0, p.frame.can_id = 0x182, p.t_us = t - 400;
        r.a.push(p, s);
    }
    if (seq >= 0) r.a.push(frame(0, 0x701, {uint8_t(seq & 0xF), 0}, t - 450), s);
    if (ft) {
        r.a.push(frame(1, 0x281, {uint8_t(fx), uint8_t(fx >> 8), 0, 0, 0, 0}, t - 300), s);
        r.a.push(frame(1, 0x282, {0, 0, 0, 0, 0, 0, 0}, t - 200), s);
    }
    return r.a.push(frame(0, 0x191, {uint8_t(uint16_t(i0) >> 8), uint8_t(i0), 0, 0}, t), s);
}

}  // namespace

TEST(Assembler, ARobotClockedByItsLastFrameGivesQDqAndYByName) {
    std::string err;
    auto r = robot(err);
    ASSERT_TRUE(r) << err;
    Sample s;
    ASSERT_TRUE(sample(*r, s, 1000000, -500000, 1234, -42));
    EXPECT_EQ(s.t_us, 1000000);
    EXPECT_FALSE(s.stale);
    EXPECT_DOUBLE_EQ(s.q[0], 1.0);
    EXPECT_DOUBLE_EQ(s.q[1], -0.5);
    ASSERT_TRUE(s.has_dq);
    EXPECT_DOUBLE_EQ(s.dq[0], 2.0);
    EXPECT_DOUBLE_EQ(s.dq[1], -1.0);
    EXPECT_DOUBLE_EQ(s.y[0], 12.34);   // ft.w.fx
    EXPECT_DOUBLE_EQ(s.y[6], 0.0);     // current.m1: the coefficient file's channel order, by name
    EXPECT_DOUBLE_EQ(s.y[7], -0.042);  // current.m0, big-endian
    const MonitorCounters& c = r->a.counters();
    EXPECT_EQ(c.frames, 5);
    EXPECT_EQ(c.strain_frames, 1);  // the clock frame
    EXPECT_EQ(c.position_frames, 2);
    EXPECT_EQ(c.sensor_frames, 2);  // the F/T pair, which does not clock
    EXPECT_EQ(c.samples, 1);
}

TEST(Assembler, HeldStaleAndTheOtherPairsLatestCompletePair) {
    std::string err;
    auto r = robot(err);
    ASSERT_TRUE(r) << err;
    Sample s;
    ASSERT_TRUE(sample(*r, s, 1000, 2000, 100, 1));
    // j1's position not renewed: held (this sample's frames came, but not that one), not stale within 5 ms.
    ASSERT_TRUE(sample(*r, s, 1100, 2100, 200, 1, -1, false));
    EXPECT_TRUE(s.held);
    EXPECT_FALSE(s.stale);
    EXPECT_DOUBLE_EQ(s.q[1], 0.002);
    // The F/T sensor's first half alone: not committed, the latest complete pair (fx 2.00) stays.
    Sample s2;
    r->a.push(frame(1, 0x281, {0x2C, 0x01, 0, 0, 0, 0}, r->t - 300), s2);  // fx 3.00, its second half lost
    ASSERT_TRUE(sample(*r, s, 1200, 2200, 0, 1, -1, true, false));
    EXPECT_DOUBLE_EQ(s.y[0], 2.0);
    EXPECT_FALSE(s.held);
    // A first half, then another first half: the first is unpaired; the pair of the second is used.
    r->a.push(frame(1, 0x281, {0x2C, 0x01, 0, 0, 0, 0}, r->t - 350), s2);
    ASSERT_TRUE(sample(*r, s, 1300, 2300, 400, 1));
    EXPECT_DOUBLE_EQ(s.y[0], 4.0);
    EXPECT_EQ(r->a.counters().unpaired_sensor, 2);
    EXPECT_EQ(r->a.counters().unpaired_strain, 0);
    // Six samples without j1: stale once its value is older than 5 ms.
    for (int k = 0; k < 6; ++k) ASSERT_TRUE(sample(*r, s, 1400, 0, 0, 1, -1, false));
    EXPECT_TRUE(s.stale);
    ASSERT_TRUE(sample(*r, s, 1400, 2400, 0, 1));
    EXPECT_FALSE(s.stale);
    EXPECT_EQ(r->a.counters().stale_samples, 2);  // j1 5.4 and 6.4 ms old at the stretch's 5th and 6th sample
}

TEST(Assembler, AThirtyTwoBitCounterWrapsAndRestartsAsANarrowOne) {
    // The configuration takes counters of up to 32 bits: past 2³¹ an int overflowed (undefined), and the wrap's
    // maximum became −1, so a counter back at 0 was never a restart.
    // The heartbeat five bytes long: the fault and reserved bits in its first, a 32-bit counter in the other four
    std::string text = kTable;
    const auto edit = [&text](const std::string& from, const std::string& to) { text.replace(text.find(from), from.size(), to); };
    edit("frame HB can0 0x701 2", "frame HB can0 0x701 5");
    edit("signal HB 0 4 le u 1 0 seq\n", "signal HB 8 32 le u 1 0 seq\n");
    edit("signal HB 8 8 le u 1 0 -\n", "");
    std::string err;
    auto r = std::make_unique<Robot>();
    ASSERT_TRUE(parse_monitor_config(text, "arm.conf", r->cfg, err)) << err;
    r->coef->n_joints = 2;
    r->coef->joint_names[0] = "j0";
    r->coef->joint_names[1] = "j1";
    const char* channels[] = {"ft.w.fx", "ft.w.fy", "ft.w.fz", "ft.w.tx", "ft.w.ty", "ft.w.tz", "current.m1", "current.m0"};
    r->coef->n_outputs = 8;
    for (int i = 0; i < 8; ++i) r->coef->channel_names[size_t(i)] = channels[i];
    ASSERT_TRUE(r->a.init(r->cfg, *r->coef, err)) << err;
    Sample s;
    const auto beat = [&](uint32_t seq) {
        r->a.push(frame(0, 0x701, {0, uint8_t(seq), uint8_t(seq >> 8), uint8_t(seq >> 16), uint8_t(seq >> 24)}, r->t), s);
    };
    for (uint32_t seq : {0x7FFFFFFEu, 0x7FFFFFFFu, 0x80000000u, 0xFFFFFFFEu, 0xFFFFFFFFu, 0u, 1u, 2u}) beat(seq);
    EXPECT_EQ(r->a.counters().board_restarts, 0);  // 2³¹ is a number, 2³² − 1 → 0 a wrap
    beat(0);
    EXPECT_EQ(r->a.counters().board_restarts, 1);  // back at 0 from 2, not due to wrap: a restart
    EXPECT_EQ(r->a.counters().bad_length, 0);
}

TEST(Assembler, RestartsFaultsSaturationAndBadFramesAreCounted) {
    std::string err;
    auto r = robot(err);
    ASSERT_TRUE(r) << err;
    Sample s;
    for (int seq = 0; seq < 6; ++seq) ASSERT_TRUE(sample(*r, s, 10, 20, 0, 1, seq));
    EXPECT_EQ(r->a.counters().board_restarts, 0);
    // The counter back to 0 before it was due to wrap (15): the drive restarted; its positions are dropped until fresh.
    r->a.push(frame(0, 0x701, {0x00, 0}, r->t - 900), s);
    EXPECT_EQ(r->a.counters().board_restarts, 1);
    ASSERT_TRUE(r->a.push(frame(0, 0x191, {0, 1, 0, 0}, r->t), s));
    r->t += 1000;
    EXPECT_TRUE(s.stale);
    // The same frame again (a duplicate) is no second restart; a wrap 15 -> 0, nor one with 14's successor lost.
    r->a.push(frame(0, 0x701, {0x00, 0}, r->t - 900), s);
    for (int seq = 1; seq <= 14; ++seq) r->a.push(frame(0, 0x701, {uint8_t(seq), 0}, r->t), s);
    r->a.push(frame(0, 0x701, {0x00, 0}, r->t), s);
    EXPECT_EQ(r->a.counters().board_restarts, 1);
    ASSERT_TRUE(sample(*r, s, 10, 20, 0, 1));
    EXPECT_FALSE(s.stale);
    // A fault bit is counted; reserved bits refuse the frame (a bad frame), as do a wrong length and a NaN float.
    r->a.push(frame(0, 0x701, {0x11, 0}, r->t), s);
    EXPECT_EQ(r->a.counters().board_faults, 1);
    const int64_t bad = r->a.counters().bad_length;
    r->a.push(frame(0, 0x701, {0x22, 0}, r->t), s);
    r->a.push(frame(0, 0x181, {0, 0, 0}, r->t), s);
    r->a.push(frame(1, 0x381, {0x00, 0x00, 0xC0, 0x7F}, r->t), s);  // NaN
    r->a.push(frame(1, 0x381, {0x00, 0x00, 0x80, 0x3F}, r->t), s);  // 1.0f: fine
    EXPECT_EQ(r->a.counters().bad_length, bad + 3);
    // A saturation flag on the F/T pair makes the sample stale, and is counted.
    r->a.push(frame(1, 0x281, {0, 0, 0, 0, 0, 0}, r->t - 300), s);
    r->a.push(frame(1, 0x282, {0, 0, 0, 0, 0, 0, 1}, r->t - 200), s);
    ASSERT_TRUE(sample(*r, s, 10, 20, 0, 1, -1, true, false));
    EXPECT_TRUE(s.stale);
    EXPECT_EQ(r->a.counters().saturated, 1);
    // Unknown: an ID of no frame, one on another bus, extended and remote frames; error frames have their own counter.
    r->a.push(frame(0, 0x182 | CAN_EFF_FLAG, {0, 0, 0, 0, 0, 0, 0, 0}, r->t), s);
    r->a.push(frame(0, 0x182 | CAN_RTR_FLAG, {}, r->t), s);
    r->a.push(frame(1, 0x182, {0, 0, 0, 0, 0, 0, 0, 0}, r->t), s);
    r->a.push(frame(5, 0x182, {0, 0, 0, 0, 0, 0, 0, 0}, r->t), s);
    r->a.push(frame(0, 0x183, {0, 0, 0, 0, 0, 0, 0, 0}, r->t), s);
    r->a.push(frame(0, CAN_ERR_FLAG | 0x4, {0, 0, 0, 0, 0, 0, 0, 0}, r->t), s);
    const MonitorCounters& c = r->a.counters();
    EXPECT_EQ(c.unknown_id, 5);
    EXPECT_EQ(c.error_frames, 1);
    EXPECT_EQ(c.frames, c.error_frames + c.unknown_id + c.bad_length + c.strain_frames + c.position_frames +
                            c.pid_frames + c.status_frames + c.skin_frames + c.sensor_frames);
    EXPECT_EQ(c.strain_frames, c.samples);  // a single clock frame: one per sample
}

TEST(Assembler, EveryJointAndChannelMustBeCarried) {
    std::string err;
    const char* joints[2] = {"j0", "elbow"};
    EXPECT_FALSE(robot(err, joints));
    EXPECT_EQ(err, "joint elbow of the coefficient file is carried by no signal of the configuration (target q.elbow)");
    auto r = std::make_unique<Robot>();
    ASSERT_TRUE(parse_monitor_config(kTable, "arm.conf", r->cfg, err)) << err;
    r->coef->n_joints = 1;
    r->coef->joint_names[0] = "j0";
    r->coef->n_outputs = 1;
    r->coef->channel_names[0] = "pwm.m0";
    EXPECT_FALSE(r->a.init(r->cfg, *r->coef, err));
    EXPECT_EQ(err, "channel pwm.m0 of the coefficient file is carried by no signal of the configuration");
    // Without every joint's velocity on the bus, a sample has no measured q̇.
    r->coef->channel_names[0] = "current.m0";
    ASSERT_TRUE(r->a.init(r->cfg, *r->coef, err)) << err;
    std::string text = kTable;
    text.replace(text.find("dq.j1"), 5, "-    ");
    ASSERT_TRUE(parse_monitor_config(text, "arm.conf", r->cfg, err)) << err;
    r->coef->n_joints = 2;
    r->coef->joint_names[1] = "j1";
    ASSERT_TRUE(r->a.init(r->cfg, *r->coef, err)) << err;
    Sample s;
    ASSERT_TRUE(sample(*r, s, 1, 2, 0, 1));
    EXPECT_FALSE(s.has_dq);
}
