// The monitor configuration (load_monitor_config) and its compiled bus table: keys in any order give the same
// configuration; every refusal (buses, frames, signals, targets, the clock and pairs, duplicated lines, values out of
// range, a missing robot line, the old iCub-only lines, capacities) is one line naming the file, the line and the
// problem. (ctest rt_config; also under ASan.)
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "rt_monitor/monitor_config.hpp"

using dynid::rt::load_monitor_config;
using dynid::rt::MonitorConfig;
using dynid::rt::Target;

namespace {

// A small table in dynid's order: a strain pair clocking the samples, a position frame, a health frame, a skin frame.
const char* kOrdered =
    "# ordered, as dynid writes it\n"
    "robot icub_right_arm\n"                                           // 2
    "buses can0 can1 can2\n"                                           // 3
    "lcm_url file:///tmp/x.lcmlog?mode=w\n"                            // 4
    "stale_ms 7\n"                                                     // 5
    "pair_us 400\n"                                                    // 6
    "status_hz 20\n"                                                   // 7
    "residual_every 5\n"                                               // 8
    "frame MC_POSITION_1 can0 0x111 8 0 mc1 0 -300\n"                  // 9
    "signal MC_POSITION_1 0 32 le s 9.5e-05 0.0 q.r_shoulder_pitch\n"  // 10
    "signal MC_POSITION_1 32 32 le s 9.5e-05 0.0 q.r_elbow\n"          // 11
    "frame MC_STATUS_1 can0 0x113 4 0 mc1 10000 -250\n"                // 12
    "signal MC_STATUS_1 0 1 le u 1.0 0.0 fault.q.r_elbow\n"            // 13
    "signal MC_STATUS_1 16 1 le u 1.0 0.0 restart\n"                   // 14
    "signal MC_STATUS_1 24 8 le u 1.0 0.0 seq\n"                       // 15
    "frame SKIN_8 can2 0x480 2 0 skin8 0 -200\n"                       // 16
    "signal SKIN_8 0 16 le u 1.0 0.0 skin.hand\n"                      // 17
    "frame STRAIN_FORCE_13 can0 0x3DA 6 7 strain 0 -100\n"             // 18
    "signal STRAIN_FORCE_13 0 16 le u 0.006103515625 -200.0 ft.s.fx\n" // 19
    "signal STRAIN_FORCE_13 48 1 le u 1.0 0.0 saturated.ft.s.fx\n"     // 20
    "frame STRAIN_TORQUE_13 can0 0x3DB 6 0 strain 0 0\n"               // 21
    "signal STRAIN_TORQUE_13 0 16 be s 0.5 1.0 ft.s.tx\n"              // 22
    "clock STRAIN_TORQUE_13\n"                                         // 23
    "pair STRAIN_FORCE_13 STRAIN_TORQUE_13\n"                          // 24
    "patch hand s:distal\n"                                            // 25
    "patch shoulder s:proximal\n"                                      // 26
    "frame SKIN_12 can2 0x4C0 2 0 skin12 0 -200\n"                     // 27
    "signal SKIN_12 0 16 le u 1.0 0.0 skin.shoulder\n";                // 28

// The same lines with buses last and the kinds interleaved; repeated keys in their order.
const char* kShuffled =
    "lcm_url file:///tmp/x.lcmlog?mode=w   # before buses\n"
    "signal MC_POSITION_1 0 32 le s 9.5e-05 0.0 q.r_shoulder_pitch\n"
    "patch hand s:distal\n"
    "pair STRAIN_FORCE_13 STRAIN_TORQUE_13\n"
    "signal SKIN_12 0 16 le u 1.0 0.0 skin.shoulder\n"
    "residual_every 5\n"
    "clock STRAIN_TORQUE_13\n"
    "signal STRAIN_FORCE_13 0 16 le u 0.006103515625 -200.0 ft.s.fx\n"
    "signal MC_POSITION_1 32 32 le s 9.5e-05 0.0 q.r_elbow\n"
    "frame STRAIN_TORQUE_13 can0 0x3DB 6 0 strain 0 0\n"
    "signal MC_STATUS_1 0 1 le u 1.0 0.0 fault.q.r_elbow\n"
    "status_hz 20\n"
    "frame SKIN_8 can2 0x480 2 0 skin8 0 -200\n"
    "signal STRAIN_FORCE_13 48 1 le u 1.0 0.0 saturated.ft.s.fx\n"
    "frame MC_POSITION_1 can0 0x111 8 0 mc1 0 -300\n"
    "robot icub_right_arm\n"
    "signal MC_STATUS_1 16 1 le u 1.0 0.0 restart\n"
    "signal SKIN_8 0 16 le u 1.0 0.0 skin.hand\n"
    "\n"
    "frame STRAIN_FORCE_13 can0 0x3DA 6 7 strain 0 -100\n"
    "signal STRAIN_TORQUE_13 0 16 be s 0.5 1.0 ft.s.tx\n"
    "patch shoulder s:proximal\n"
    "signal MC_STATUS_1 24 8 le u 1.0 0.0 seq\n"
    "frame MC_STATUS_1 can0 0x113 4 0 mc1 10000 -250\n"
    "frame SKIN_12 can2 0x4C0 2 0 skin12 0 -200\n"
    "pair_us 400\n"
    "stale_ms 7\n"
    "buses can0 can1 can2\n";

std::string write(const std::string& name, const std::string& text) {
    const std::string path = ::testing::TempDir() + "rt_config_" + name + ".conf";
    std::ofstream(path) << text;
    return path;
}

// Loads `text`; the error (empty when it loads).
std::string error_of(const std::string& name, const std::string& text, MonitorConfig* out = nullptr) {
    MonitorConfig c;
    std::string err;
    if (load_monitor_config(write(name, text), c, err)) err.clear();
    if (out) *out = c;
    return err;
}

// kOrdered with line `at` (1-based) replaced by `line`, or with `line` added at the end (at = 0).
std::string with(const std::string& line, int at = 0) {
    std::istringstream in(kOrdered);
    std::string out;
    int n = 0;
    for (std::string l; std::getline(in, l);) out += (++n == at ? line : l) + "\n";
    if (at == 0) out += line + "\n";
    return out;
}

const std::string& dir() {
    static const std::string d = ::testing::TempDir() + "rt_config_";
    return d;
}

}  // namespace

TEST(MonitorConfig, KeysInAnyOrderGiveTheSameConfiguration) {
    MonitorConfig a, b;
    ASSERT_EQ(error_of("ordered", kOrdered, &a), "");
    ASSERT_EQ(error_of("shuffled", kShuffled, &b), "");
    EXPECT_EQ(a.robot, "icub_right_arm");
    EXPECT_EQ(a.buses, (std::vector<std::string>{"can0", "can1", "can2"}));
    EXPECT_EQ(a.lcm_url, "file:///tmp/x.lcmlog?mode=w");
    EXPECT_EQ(a.stale_us, 7000);
    EXPECT_EQ(a.pair_us, 400);
    EXPECT_EQ(a.status_hz, 20);
    EXPECT_EQ(a.residual_every, 5);
    ASSERT_EQ(a.bus.frames.size(), 6u);
    EXPECT_EQ(a.bus.frames[3].name, "STRAIN_FORCE_13");
    EXPECT_EQ(a.bus.frames[3].id, 0x3DAu);
    EXPECT_EQ(a.bus.frames[3].long_dlc, 7);
    EXPECT_EQ(a.bus.frames[1].period_us, 10000);
    EXPECT_EQ(a.bus.frames[2].bus, 2);
    EXPECT_EQ(a.bus.nodes, (std::vector<std::string>{"mc1", "skin8", "strain", "skin12"}));
    EXPECT_EQ(a.bus.clock, 4);
    EXPECT_EQ(a.bus.clock_pair, 0);
    ASSERT_EQ(a.bus.pairs.size(), 1u);
    EXPECT_EQ(a.bus.pairs[0], std::make_pair(3, 4));
    ASSERT_EQ(a.bus.patches.size(), 2u);
    EXPECT_EQ(a.bus.patches[1].name, "shoulder");  // the second patch line is bit 1 of the skin mask, in both orders
    EXPECT_EQ(a.bus.patches[1].sides[0], std::make_pair(std::string("s"), std::string("proximal")));
    EXPECT_EQ(a.bus.values, (std::vector<std::string>{"q.r_shoulder_pitch", "q.r_elbow", "ft.s.fx", "ft.s.tx"}));

    EXPECT_EQ(b.robot, a.robot);
    EXPECT_EQ(b.buses, a.buses);
    EXPECT_EQ(b.lcm_url, a.lcm_url);
    EXPECT_EQ(b.stale_us, a.stale_us);
    EXPECT_EQ(b.pair_us, a.pair_us);
    EXPECT_EQ(b.status_hz, a.status_hz);
    EXPECT_EQ(b.residual_every, a.residual_every);
    EXPECT_EQ(b.bus.clock, 0);  // the frame lines in their file order: STRAIN_TORQUE_13 first
    EXPECT_EQ(b.bus.frames[size_t(b.bus.clock)].name, "STRAIN_TORQUE_13");
    EXPECT_EQ(b.bus.patches[1].name, "shoulder");
    // Per frame, by name: the same signals in the same order, the same kind.
    for (const auto& fa : a.bus.frames) {
        const dynid::rt::FrameDef* fb = nullptr;
        for (const auto& f : b.bus.frames)
            if (f.name == fa.name) fb = &f;
        ASSERT_NE(fb, nullptr) << fa.name;
        EXPECT_EQ(fb->id, fa.id);
        EXPECT_EQ(fb->kind, fa.kind) << fa.name;
        ASSERT_EQ(fb->n_signals, fa.n_signals) << fa.name;
        for (int i = 0; i < fa.n_signals; ++i) {
            const auto& sa = a.bus.signals[size_t(fa.first_signal + i)];
            const auto& sb = b.bus.signals[size_t(fb->first_signal + i)];
            EXPECT_EQ(sb.name, sa.name);
            EXPECT_EQ(sb.start, sa.start);
            EXPECT_EQ(sb.big_endian, sa.big_endian);
            EXPECT_EQ(sb.scale, sa.scale);
            EXPECT_EQ(sb.offset, sa.offset);
            EXPECT_EQ(sb.target, sa.target);
        }
    }
    using dynid::rt::FrameKind;
    EXPECT_EQ(a.bus.frames[0].kind, FrameKind::kPosition);
    EXPECT_EQ(a.bus.frames[1].kind, FrameKind::kStatus);
    EXPECT_EQ(a.bus.frames[2].kind, FrameKind::kSkin);
    EXPECT_EQ(a.bus.frames[3].kind, FrameKind::kClock);
    EXPECT_EQ(a.bus.frames[4].kind, FrameKind::kClock);
    EXPECT_EQ(a.bus.signals[size_t(a.bus.frames[1].first_signal)].target, Target::kFault);
}

TEST(MonitorConfig, BusErrorsNameTheFileTheLineAndTheProblem) {
    const std::string& d = dir();
    EXPECT_EQ(error_of("unknown_bus", with("frame MC_POSITION_1 can7 0x111 8 0 mc1 0 -300", 9)),
              d + "unknown_bus.conf:9: bus 'can7' is not in the 'buses' line (can0 can1 can2)");
    EXPECT_EQ(error_of("no_buses", with("# none", 3)), d + "no_buses.conf: no 'buses' line (not an rt_monitor configuration? "
                                                       "`dynid export --robot CFG --monitor-config FILE` writes one)");
    EXPECT_EQ(error_of("second_buses", std::string("buses can0\n") + kShuffled),
              d + "second_buses.conf:29: a second 'buses' line (the first is line 1)");
    EXPECT_EQ(error_of("named_twice", with("buses can0 can1 can1", 3)), d + "named_twice.conf:3: bus 'can1' named twice");
    EXPECT_EQ(error_of("nine_buses", with("buses a b c d e f g h i", 3)),
              d + "nine_buses.conf:3: bad 'buses' line (1 to 8 bus names): buses a b c d e f g h i");
    EXPECT_EQ(error_of("bad_value", with("pair_us -4", 6)), d + "bad_value.conf:6: pair_us -4 is out of range: 1 to 10000 µs");
    EXPECT_EQ(error_of("unknown_key", with("colour blue")), d + "unknown_key.conf:29: unknown key 'colour'");
}

TEST(MonitorConfig, FramesAndSignalsOutsideTheirRulesAreRefused) {
    const std::string& d = dir();
    auto frame = [](const std::string& rest) { return with("frame MC_POSITION_1 " + rest, 9); };
    EXPECT_EQ(error_of("id_big", frame("can0 0x800 8 0 mc1 0 -300")),
              d + "id_big.conf:9: a frame's ID (11-bit, standard) must be an integer 0 to 2047, got '0x800'");
    EXPECT_EQ(error_of("id_word", frame("can0 0xZZ 8 0 mc1 0 -300")),
              d + "id_word.conf:9: a frame's ID (11-bit, standard) must be an integer 0 to 2047, got '0xZZ'");
    EXPECT_EQ(error_of("dlc", frame("can0 0x111 9 0 mc1 0 -300")),
              d + "dlc.conf:9: a frame's DLC must be an integer 0 to 8, got '9'");
    EXPECT_EQ(error_of("long", frame("can0 0x111 8 8 mc1 0 -300")),
              d + "long.conf:9: the long DLC 8 must be above the DLC 8 (or 0: no long form)");
    EXPECT_EQ(error_of("period", frame("can0 0x111 8 0 mc1 -1 -300")),
              d + "period.conf:9: a frame's period in µs must be an integer 0 to 60000000, got '-1'");
    EXPECT_EQ(error_of("offset", frame("can0 0x111 8 0 mc1 0 5")),
              d + "offset.conf:9: a frame's send offset in µs must be an integer -1000000 to 0, got '5'");
    EXPECT_EQ(error_of("short", frame("can0 0x111 8 0")), d + "short.conf:9: bad 'frame' line: frame MC_POSITION_1 can0 0x111 8 0");
    EXPECT_EQ(error_of("frame_twice", with("frame MC_POSITION_1 can1 0x211 8 0 mc1 0 -300")),
              d + "frame_twice.conf:29: a second frame 'MC_POSITION_1' (the first is line 9)");
    EXPECT_EQ(error_of("id_twice", with("frame OTHER can0 0x111 2 0 other 0 -300")),
              d + "id_twice.conf:29: ID 0x111 on can0 is frame 'MC_POSITION_1''s already (line 9)");
    EXPECT_EQ(error_of("id_other_bus", with("frame OTHER can1 0x111 2 0 other 0 -300") +
                       "signal OTHER 0 8 le u 1 0 -\n"), "");  // the same ID on another bus is another frame
    auto signal = [](const std::string& rest) { return with("signal MC_POSITION_1 " + rest, 11); };
    EXPECT_EQ(error_of("sig_frame", with("signal NOPE 0 8 le u 1 0 -", 11)),
              d + "sig_frame.conf:11: frame 'NOPE' is not defined by a 'frame' line");
    EXPECT_EQ(error_of("sig_out", signal("40 32 le s 1 0 q.r_elbow")),
              d + "sig_out.conf:11: the signal at bit 40 (32 bits, le) leaves frame 'MC_POSITION_1''s 8 bytes");
    EXPECT_EQ(error_of("sig_be_out", signal("56 16 be s 1 0 q.r_elbow")),
              d + "sig_be_out.conf:11: the signal at bit 56 (16 bits, be) leaves frame 'MC_POSITION_1''s 8 bytes");
    EXPECT_EQ(error_of("sig_overlap", signal("16 32 le s 1 0 q.r_elbow")),
              d + "sig_overlap.conf:11: the signal at bit 16 overlaps another signal of frame 'MC_POSITION_1'");
    EXPECT_EQ(error_of("sig_be_overlap", signal("7 8 be u 1 0 q.r_elbow")),  // Motorola: bits 7..0 of byte 0
              d + "sig_be_overlap.conf:11: the signal at bit 7 overlaps another signal of frame 'MC_POSITION_1'");
    EXPECT_EQ(error_of("sig_len", signal("32 65 le s 1 0 q.r_elbow")),
              d + "sig_len.conf:11: a signal's length must be an integer 1 to 64, got '65'");
    EXPECT_EQ(error_of("sig_order", signal("32 32 xe s 1 0 q.r_elbow")),
              d + "sig_order.conf:11: a signal's byte order is le (Intel) or be (Motorola), got 'xe'");
    EXPECT_EQ(error_of("sig_type", signal("32 32 le d 1 0 q.r_elbow")),
              d + "sig_type.conf:11: a signal's type is u, s or f (IEEE float), got 'd'");
    EXPECT_EQ(error_of("sig_float", signal("32 16 le f 1 0 q.r_elbow")),
              d + "sig_float.conf:11: an IEEE float signal is 32 or 64 bits, got 16");
    EXPECT_EQ(error_of("sig_scale", signal("32 32 le s 0 0 q.r_elbow")),
              d + "sig_scale.conf:11: a signal's scale must not be 0");
    EXPECT_EQ(error_of("sig_nan", signal("32 32 le s nan 0 q.r_elbow")),
              d + "sig_nan.conf:11: bad 'signal' line: signal MC_POSITION_1 32 32 le s nan 0 q.r_elbow");
    // Beyond the DLC is allowed in a frame's long form only.
    EXPECT_EQ(error_of("beyond_dlc", with("signal STRAIN_TORQUE_13 48 1 le u 1 0 saturated", 22)),
              d + "beyond_dlc.conf:22: the signal at bit 48 (1 bits, le) leaves frame 'STRAIN_TORQUE_13''s 6 bytes");
    EXPECT_EQ(error_of("no_signal", with("# gone", 17)), d + "no_signal.conf:16: frame 'SKIN_8' has no 'signal' line");
}

TEST(MonitorConfig, TargetsAreCheckedOneByOne) {
    const std::string& d = dir();
    auto signal = [](const std::string& target) { return with("signal MC_POSITION_1 32 32 le s 1 0 " + target, 11); };
    EXPECT_EQ(error_of("tgt_unknown", signal("speed.r_elbow")),
              d + "tgt_unknown.conf:11: 'speed.r_elbow' is no signal target: q.J dq.J pwm.M current.M tau.J ft.S.C "
                  "skin.P saturated[.T] fault[.T] restart seq reserved, or - (read by nobody)");
    EXPECT_EQ(error_of("tgt_ft", signal("ft.s.fw")), d + "tgt_ft.conf:11: 'ft.s.fw' is no signal target: q.J dq.J "
              "pwm.M current.M tau.J ft.S.C skin.P saturated[.T] fault[.T] restart seq reserved, or - (read by nobody)");
    EXPECT_EQ(error_of("tgt_twice", signal("q.r_shoulder_pitch")),
              d + "tgt_twice.conf:11: 'q.r_shoulder_pitch' is carried by another signal already (line 10)");
    EXPECT_EQ(error_of("tgt_patch", with("signal MC_POSITION_1 32 32 le s 2 0 skin.hand", 11)),
              d + "tgt_patch.conf:11: 'skin.hand' is a flag or a count: an integer signal with scale 1 and offset 0");
    EXPECT_EQ(error_of("tgt_patch2", with("signal MC_POSITION_1 32 32 le s 1 0 skin.palm", 11)),
              d + "tgt_patch2.conf:11: 'skin.palm' names a patch no 'patch' line defines");
    EXPECT_EQ(error_of("tgt_flag_scale", with("signal MC_STATUS_1 16 1 le u 2 0 restart", 14)),
              d + "tgt_flag_scale.conf:14: 'restart' is a flag or a count: an integer signal with scale 1 and offset 0");
    EXPECT_EQ(error_of("tgt_seq_len", with("signal MC_STATUS_1 24 1 le u 1 0 seq", 15)),
              d + "tgt_seq_len.conf:15: a sequence counter is 2 to 32 bits, got 1");
    EXPECT_EQ(error_of("tgt_seq_twice", with("signal MC_STATUS_1 8 8 le u 1 0 seq")),
              d + "tgt_seq_twice.conf:29: a second 'seq' signal in frame 'MC_STATUS_1'");
    EXPECT_EQ(error_of("tgt_fault_of", with("signal MC_STATUS_1 0 1 le u 1.0 0.0 fault.x", 13)),
              d + "tgt_fault_of.conf:13: 'fault.x': a flag's own target is a value target (q.J, dq.J, pwm.M, current.M, "
                  "tau.J, ft.S.C)");
    EXPECT_EQ(error_of("tgt_fault_absent", with("signal MC_STATUS_1 0 1 le u 1.0 0.0 fault.pwm.m0", 13)),
              d + "tgt_fault_absent.conf: 'fault.pwm.m0': no signal carries 'pwm.m0'");
    EXPECT_EQ(error_of("patch_empty", with("signal SKIN_12 0 16 le u 1.0 0.0 -", 28)),
              d + "patch_empty.conf:26: patch 'shoulder' is carried by no signal (target skin.shoulder)");
    EXPECT_EQ(error_of("patch_side", with("patch hand s:inside", 25)),
              d + "patch_side.conf:25: a patch's side is SENSOR:distal or SENSOR:proximal, got 's:inside'");
    EXPECT_EQ(error_of("patch_twice", with("patch hand s:proximal")),
              d + "patch_twice.conf:29: a second patch 'hand' (the first is line 25)");
}

TEST(MonitorConfig, TheClockAndThePairsAreChecked) {
    const std::string& d = dir();
    EXPECT_EQ(error_of("no_clock", with("# none", 23)),
              d + "no_clock.conf: no 'clock' line (the frame that completes a sample)");
    EXPECT_EQ(error_of("clock_twice", with("clock MC_POSITION_1")),
              d + "clock_twice.conf:29: a second 'clock' line (the first is line 23)");
    EXPECT_EQ(error_of("clock_unknown", with("clock NOPE", 23)),
              d + "clock_unknown.conf:23: frame 'NOPE' is not defined by a 'frame' line");
    EXPECT_EQ(error_of("clock_first", with("clock STRAIN_FORCE_13", 23)),
              d + "clock_first.conf:23: the clock frame 'STRAIN_FORCE_13' is the first half of a pair: the second half "
                  "completes a sample");
    EXPECT_EQ(error_of("pair_self", with("pair SKIN_8 SKIN_8")), d + "pair_self.conf:29: frame 'SKIN_8' is paired with itself");
    EXPECT_EQ(error_of("pair_again", with("pair STRAIN_FORCE_13 SKIN_8")),
              d + "pair_again.conf:29: frame 'STRAIN_FORCE_13' is in another pair already");
    EXPECT_EQ(error_of("pair_unknown", with("pair SKIN_8 NOPE")),
              d + "pair_unknown.conf:29: frame 'NOPE' is not defined by a 'frame' line");
    MonitorConfig c;  // a clock frame of its own, no pair: every position frame clocks (a CANopen SYNC's last TPDO)
    ASSERT_EQ(error_of("clock_alone", with("clock MC_POSITION_1", 23), &c), "");
    EXPECT_EQ(c.bus.clock_pair, -1);
    EXPECT_EQ(c.bus.frames[0].kind, dynid::rt::FrameKind::kClock);
    EXPECT_EQ(c.bus.frames[3].kind, dynid::rt::FrameKind::kSensor);  // an F/T pair that does not clock
}

TEST(MonitorConfig, TheOldICubOnlyLinesSayToRegenerate) {
    const std::string& d = dir();
    for (const char* line : {"strain can0 13 200 200 200 10 10 10", "axis can0 1 0 r_elbow 182 0", "pwm can0 1 0 m0 1333",
                             "skin can2 8 hand distal"}) {
        const std::string key = std::string(line).substr(0, std::string(line).find(' '));
        EXPECT_EQ(error_of("old_" + key, with(line)),
                  d + "old_" + key + ".conf:29: '" + key + "' is a line of the iCub-only format before the bus "
                      "description: write the configuration again (dynid export --robot ROBOT --monitor-config FILE)");
    }
}

TEST(MonitorConfig, SettingsGivenTwiceOrOutOfRangeAreRefused) {
    const std::string& d = dir();
    for (const char* line : {"robot icub_left_arm", "lcm_url memq://", "stale_ms 5", "pair_us 500", "status_hz 10",
                             "residual_every 10"}) {
        const std::string key = std::string(line).substr(0, std::string(line).find(' '));
        const int first = key == "robot" ? 2 : key == "lcm_url" ? 4 : key == "stale_ms" ? 5 : key == "pair_us" ? 6
                          : key == "status_hz" ? 7 : 8;
        EXPECT_EQ(error_of("dup_" + key, with(line)), d + "dup_" + key + ".conf:29: a second '" + key +
                  "' line (the first is line " + std::to_string(first) + ")");
    }
    // stale_ms 99999999999 turned the staleness guard off; stale_ms 0 answered with the usage line only.
    EXPECT_EQ(error_of("stale_huge", with("stale_ms 99999999999", 5)),
              d + "stale_huge.conf:5: stale_ms 99999999999 is out of range: 0.1 to 1000 ms");
    EXPECT_EQ(error_of("stale_zero", with("stale_ms 0", 5)), d + "stale_zero.conf:5: stale_ms 0 is out of range: 0.1 to 1000 ms");
    EXPECT_EQ(error_of("stale_nan", with("stale_ms nan", 5)), d + "stale_nan.conf:5: bad 'stale_ms' line: stale_ms nan");
    EXPECT_EQ(error_of("pair_beyond", with("pair_us 99999999999999999999999", 6)),
              d + "pair_beyond.conf:6: pair_us 99999999999999999999999 is out of range: 1 to 10000 µs");
    EXPECT_EQ(error_of("pair_frac", with("pair_us 2.5", 6)), d + "pair_frac.conf:6: pair_us must be a whole number, got 2.5");
    // 1e-300 Hz: a status period of 1e306 µs, beyond int64 (undefined behaviour in the conversion before).
    EXPECT_EQ(error_of("status_tiny", with("status_hz 1e-300", 7)),
              d + "status_tiny.conf:7: status_hz 1e-300 is out of range: 0.1 to 1000 Hz");
    EXPECT_EQ(error_of("residual_zero", with("residual_every 0", 8)),
              d + "residual_zero.conf:8: residual_every 0 is out of range: 1 to 100000 samples");
    MonitorConfig c;  // the limits themselves are accepted
    std::string t = with("stale_ms 0.1", 5);
    t = t.replace(t.find("pair_us 400"), 11, "pair_us 10000");
    t = t.replace(t.find("status_hz 20"), 12, "status_hz 1000");
    ASSERT_EQ(error_of("limits", t, &c), "");
    EXPECT_EQ(c.stale_us, 100);
    EXPECT_EQ(c.pair_us, 10000);
    EXPECT_EQ(c.status_hz, 1000);
}

TEST(MonitorConfig, CapacitiesAreRefusedNotTruncated) {
    const std::string& d = dir();
    std::string many = kOrdered;
    for (int i = 0; i < dynid::rt::kMaxFrames; ++i)
        many += "frame F" + std::to_string(i) + " can1 " + std::to_string(i) + " 1 0 n 0 -10\n";
    EXPECT_EQ(error_of("frames", many), d + "frames.conf:279: more than 256 frames (kMaxFrames, rt_monitor/capacity.hpp)");
    std::string bits = kOrdered;
    for (int i = 0; i < 17; ++i) {
        bits += "frame B" + std::to_string(i) + " can1 " + std::to_string(i) + " 8 0 n 0 -10\n";
        for (int k = 0; k < 64; ++k) bits += "signal B" + std::to_string(i) + " " + std::to_string(k) + " 1 le u 1 0 -\n";
    }
    EXPECT_EQ(error_of("signals", bits).substr(0, dir().size() + 12), d + "signals.conf");
    EXPECT_NE(error_of("signals", bits).find("more than 1024 signals (kMaxSignals, rt_monitor/capacity.hpp)"),
              std::string::npos);
    std::string patches = kOrdered;
    for (int i = 0; i < 15; ++i) patches += "patch p" + std::to_string(i) + "\n";
    EXPECT_EQ(error_of("patches", patches), d + "patches.conf:43: more than 16 skin patches (kMaxSkins, rt_monitor/capacity.hpp)");
}

TEST(MonitorConfig, TheRobotLineIsRequired) {
    const std::string& d = dir();
    // Without it the check against the coefficient file's robot was skipped.
    EXPECT_EQ(error_of("no_robot", with("# no robot", 2)),
              d + "no_robot.conf: no 'robot' line (the coefficient file's robot is checked against it)");
    EXPECT_EQ(error_of("robot_empty", with("robot", 2)), d + "robot_empty.conf:2: bad 'robot' line: robot");
    EXPECT_EQ(error_of("robot_two", with("robot a b", 2)), d + "robot_two.conf:2: bad 'robot' line: robot a b");
}

// Control bytes of the file in a message are escaped: one whole line, and a NUL does not cut it.
TEST(MonitorConfig, ARefusalIsOneLineWhateverTheFileHolds) {
    const std::string& d = dir();
    EXPECT_EQ(error_of("cr", with("stale_ms five\r", 5)), d + "cr.conf:5: bad 'stale_ms' line: stale_ms five\\x0D");
    std::string nul = with("colour", 5);
    nul.insert(nul.find("colour") + 3, 1, '\0');
    EXPECT_EQ(error_of("nul_key", nul), d + "nul_key.conf:5: unknown key 'col\\x00our'");
}

TEST(MonitorConfig, TextAndFileParseAlike) {
    MonitorConfig a, b;
    std::string ea, eb;
    ASSERT_TRUE(dynid::rt::parse_monitor_config(kShuffled, "x.conf", a, ea)) << ea;
    ASSERT_TRUE(load_monitor_config(write("text", kShuffled), b, eb)) << eb;
    EXPECT_EQ(a.bus.signals.size(), b.bus.signals.size());
    EXPECT_EQ(a.robot, b.robot);
    // A NUL byte or a line without a newline at the end of the file is no problem.
    std::string nul = with("# a comment");
    nul[nul.size() - 3] = '\0';
    EXPECT_EQ(error_of("nul", nul), "");
    std::string last = kOrdered;
    last.pop_back();
    EXPECT_EQ(error_of("no_newline", last), "");
}
