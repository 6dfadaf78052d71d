// The monitor configuration (load_monitor_config): keys in any order give the same MonitorConfig; every refusal
// (bus lines, duplicated lines, values out of range, a missing robot line) is one line naming the file, the line
// and the problem. (ctest rt_config; also under ASan.)
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "rt_monitor/assembler.hpp"

using dynid::rt::load_monitor_config;
using dynid::rt::MonitorConfig;

namespace {

const char* kOrdered =
    "# ordered, as dynid writes it\n"
    "robot icub_right_arm\n"
    "buses can0 can1 can2\n"
    "lcm_url file:///tmp/x.lcmlog?mode=w\n"
    "stale_ms 7\n"
    "pair_us 400\n"
    "status_hz 20\n"
    "residual_every 5\n"
    "strain can0 13 200.0 200.0 200.0 10.0 10.0 10.0\n"
    "axis can0 1 0 r_shoulder_pitch 182.0 1.5\n"
    "pwm can0 1 0 m0 1333.0\n"
    "axis can1 2 1 r_elbow 100.0 0.0\n"
    "skin can2 8 hand distal\n"
    "skin can2 12 shoulder proximal\n";

// The same keys, buses last and the kinds interleaved; repeated keys in their order.
const char* kShuffled =
    "lcm_url file:///tmp/x.lcmlog?mode=w   # before buses\n"
    "skin can2 8 hand distal\n"
    "residual_every 5\n"
    "axis can0 1 0 r_shoulder_pitch 182.0 1.5\n"
    "skin can2 12 shoulder proximal\n"
    "status_hz 20\n"
    "strain can0 13 200.0 200.0 200.0 10.0 10.0 10.0\n"
    "pwm can0 1 0 m0 1333.0\n"
    "robot icub_right_arm\n"
    "\n"
    "axis can1 2 1 r_elbow 100.0 0.0\n"
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
    ASSERT_EQ(a.axes.size(), 2u);
    EXPECT_EQ(a.axes[1].bus, 1);
    EXPECT_EQ(a.axes[1].joint, "r_elbow");
    ASSERT_EQ(a.skins.size(), 2u);
    EXPECT_EQ(a.skins[1].bus, 2);
    EXPECT_EQ(a.skins[1].patch, "shoulder");  // the second skin line is skin board 2, in both orders

    EXPECT_EQ(b.robot, a.robot);
    EXPECT_EQ(b.buses, a.buses);
    EXPECT_EQ(b.lcm_url, a.lcm_url);
    EXPECT_EQ(b.stale_us, a.stale_us);
    EXPECT_EQ(b.pair_us, a.pair_us);
    EXPECT_EQ(b.status_hz, a.status_hz);
    EXPECT_EQ(b.residual_every, a.residual_every);
    EXPECT_EQ(b.strain_bus, a.strain_bus);
    EXPECT_EQ(b.strain_address, a.strain_address);
    EXPECT_EQ(b.full_scale, a.full_scale);
    ASSERT_EQ(b.axes.size(), a.axes.size());
    for (size_t i = 0; i < a.axes.size(); ++i) {
        EXPECT_EQ(b.axes[i].bus, a.axes[i].bus);
        EXPECT_EQ(b.axes[i].address, a.axes[i].address);
        EXPECT_EQ(b.axes[i].slot, a.axes[i].slot);
        EXPECT_EQ(b.axes[i].joint, a.axes[i].joint);
        EXPECT_EQ(b.axes[i].ticks_per_degree, a.axes[i].ticks_per_degree);
        EXPECT_EQ(b.axes[i].zero_deg, a.axes[i].zero_deg);
    }
    ASSERT_EQ(b.pwms.size(), 1u);
    EXPECT_EQ(b.pwms[0].bus, a.pwms[0].bus);
    EXPECT_EQ(b.pwms[0].motor, a.pwms[0].motor);
    EXPECT_EQ(b.pwms[0].full_scale, a.pwms[0].full_scale);
    ASSERT_EQ(b.skins.size(), a.skins.size());
    for (size_t i = 0; i < a.skins.size(); ++i) {
        EXPECT_EQ(b.skins[i].bus, a.skins[i].bus);
        EXPECT_EQ(b.skins[i].address, a.skins[i].address);
        EXPECT_EQ(b.skins[i].patch, a.skins[i].patch);
        EXPECT_EQ(b.skins[i].side, a.skins[i].side);
    }
}

TEST(MonitorConfig, BusErrorsNameTheFileTheLineAndTheProblem) {
    const std::string dir = ::testing::TempDir() + "rt_config_";
    std::string text = kShuffled;
    text.replace(text.find("axis can1"), 9, "axis can7");
    EXPECT_EQ(error_of("unknown_bus", text), dir + "unknown_bus.conf:11: bus 'can7' is not in the 'buses' line (can0 can1 can2)");
    EXPECT_EQ(error_of("no_buses", std::string(kShuffled).substr(0, std::string(kShuffled).find("buses can0"))),
              dir + "no_buses.conf:0: no 'buses' line");
    EXPECT_EQ(error_of("second_buses", std::string("buses can0\n") + kShuffled),
              dir + "second_buses.conf:15: a second 'buses' line (the first is line 1)");
    EXPECT_EQ(error_of("buses_last", std::string(kOrdered) + "buses can0 can0\n"),
              dir + "buses_last.conf:15: a second 'buses' line (the first is line 3)");
    std::string twice = kOrdered;
    twice.replace(twice.find("buses can0 can1 can2"), 20, "buses can0 can1 can1");
    EXPECT_EQ(error_of("named_twice", twice), dir + "named_twice.conf:3: bus 'can1' named twice");
    // The checks of the other lines are the same as before; their lines are still named.
    std::string bad = kShuffled;
    bad.replace(bad.find("pair_us 400"), 11, "pair_us -4");
    EXPECT_EQ(error_of("bad_value", bad), dir + "bad_value.conf:12: pair_us -4 is out of range: 1 to 10000 µs");
    bad = kShuffled;
    bad.replace(bad.find("skin can2 8"), 11, "skin can2 16");
    EXPECT_EQ(error_of("bad_address", bad), dir + "bad_address.conf:2: board address must be 0..15");
    EXPECT_EQ(error_of("unknown_key", std::string(kShuffled) + "colour blue\n"),
              dir + "unknown_key.conf:15: unknown key 'colour'");
}

namespace {

// kOrdered with line `at` (1-based) replaced by `line`, or with `line` added at the end (at = 0).
std::string with(const std::string& line, int at = 0) {
    std::istringstream in(kOrdered);
    std::string out;
    int n = 0;
    for (std::string l; std::getline(in, l);) out += (++n == at ? line : l) + "\n";
    if (at == 0) out += line + "\n";
    return out;
}

}  // namespace

// The list (#22): what a hostile user tried and the monitor took.
TEST(MonitorConfig, AJointOrABoardSlotMappedTwiceIsRefused) {
    const std::string d = ::testing::TempDir() + "rt_config_";
    // r_elbow onto another board's axis as well: before, the later line won and the monitor read the wrong encoder.
    EXPECT_EQ(error_of("joint_twice", with("axis can1 3 0 r_elbow 100.0 0.0")),
              d + "joint_twice.conf:15: joint 'r_elbow' has a second 'axis' line (the first is line 12)");
    // Another joint onto r_elbow's board slot.
    EXPECT_EQ(error_of("slot_twice", with("axis can1 2 1 r_wrist_pitch 100.0 0.0")),
              d + "slot_twice.conf:15: board can1 2 slot 1 has a second 'axis' line (the first is line 12)");
    // Every duplicated line: axis, pwm, strain, skin, and each setting.
    EXPECT_EQ(error_of("axis_dup", with("axis can0 1 0 r_shoulder_pitch 182.0 1.5")),
              d + "axis_dup.conf:15: joint 'r_shoulder_pitch' has a second 'axis' line (the first is line 10)");
    EXPECT_EQ(error_of("pwm_dup", with("pwm can0 1 0 m0 1333.0")),
              d + "pwm_dup.conf:15: motor 'm0' has a second 'pwm' line (the first is line 11)");
    EXPECT_EQ(error_of("pwm_slot", with("pwm can0 1 0 m1 1333.0")),
              d + "pwm_slot.conf:15: board can0 1 slot 0 has a second 'pwm' line (the first is line 11)");
    EXPECT_EQ(error_of("strain_dup", with("strain can1 13 200.0 200.0 200.0 10.0 10.0 10.0")),
              d + "strain_dup.conf:15: a second 'strain' line (the first is line 9)");
    EXPECT_EQ(error_of("skin_dup", with("skin can2 8 palm distal")),
              d + "skin_dup.conf:15: skin board can2 8 has a second 'skin' line (the first is line 13)");
    for (const char* line : {"robot icub_left_arm", "lcm_url memq://", "stale_ms 5", "pair_us 500", "status_hz 10",
                             "residual_every 10"}) {
        const std::string key = std::string(line).substr(0, std::string(line).find(' '));
        const int first = key == "robot" ? 2 : key == "lcm_url" ? 4 : key == "stale_ms" ? 5 : key == "pair_us" ? 6
                          : key == "status_hz" ? 7 : 8;
        EXPECT_EQ(error_of("dup_" + key, with(line)),
                  d + "dup_" + key + ".conf:15: a second '" + key + "' line (the first is line " +
                      std::to_string(first) + ")");
    }
    // The same joint on another bus is still the same joint; a motor's PWM beside its axis is not a duplicate.
    EXPECT_EQ(error_of("joint_other_bus", with("axis can2 5 0 r_elbow 100.0 0.0")),
              d + "joint_other_bus.conf:15: joint 'r_elbow' has a second 'axis' line (the first is line 12)");
    EXPECT_EQ(error_of("pwm_beside_axis", with("pwm can1 2 1 m3 1333.0")), "");
}

TEST(MonitorConfig, ValuesOutOfRangeAreRefusedWithTheRange) {
    const std::string d = ::testing::TempDir() + "rt_config_";
    // stale_ms 99999999999 turned the staleness guard off; stale_ms 0 answered with the usage line only.
    EXPECT_EQ(error_of("stale_huge", with("stale_ms 99999999999", 5)),
              d + "stale_huge.conf:5: stale_ms 99999999999 is out of range: 0.1 to 1000 ms");
    EXPECT_EQ(error_of("stale_zero", with("stale_ms 0", 5)), d + "stale_zero.conf:5: stale_ms 0 is out of range: 0.1 to 1000 ms");
    EXPECT_EQ(error_of("stale_neg", with("stale_ms -3", 5)), d + "stale_neg.conf:5: stale_ms -3 is out of range: 0.1 to 1000 ms");
    EXPECT_EQ(error_of("stale_nan", with("stale_ms nan", 5)), d + "stale_nan.conf:5: bad 'stale_ms' line: stale_ms nan");
    EXPECT_EQ(error_of("stale_word", with("stale_ms five", 5)), d + "stale_word.conf:5: bad 'stale_ms' line: stale_ms five");
    EXPECT_EQ(error_of("pair_huge", with("pair_us 99999999999", 6)),
              d + "pair_huge.conf:6: pair_us 99999999999 is out of range: 1 to 10000 µs");
    EXPECT_EQ(error_of("pair_beyond", with("pair_us 99999999999999999999999", 6)),
              d + "pair_beyond.conf:6: pair_us 99999999999999999999999 is out of range: 1 to 10000 µs");
    EXPECT_EQ(error_of("pair_zero", with("pair_us 0", 6)), d + "pair_zero.conf:6: pair_us 0 is out of range: 1 to 10000 µs");
    EXPECT_EQ(error_of("pair_frac", with("pair_us 2.5", 6)), d + "pair_frac.conf:6: pair_us must be a whole number, got 2.5");
    EXPECT_EQ(error_of("status_huge", with("status_hz 99999999999", 7)),
              d + "status_huge.conf:7: status_hz 99999999999 is out of range: 0.1 to 1000 Hz");
    // 1e-300 Hz: a status period of 1e306 µs, beyond int64 (undefined behaviour in the conversion before).
    EXPECT_EQ(error_of("status_tiny", with("status_hz 1e-300", 7)),
              d + "status_tiny.conf:7: status_hz 1e-300 is out of range: 0.1 to 1000 Hz");
    EXPECT_EQ(error_of("residual_zero", with("residual_every 0", 8)),
              d + "residual_zero.conf:8: residual_every 0 is out of range: 1 to 100000 samples");
    EXPECT_EQ(error_of("fs_huge", with("strain can0 13 200.0 200.0 200.0 10.0 1e300 10.0", 9)),
              d + "fs_huge.conf:9: strain full scale 1e300 is out of range: above 0, at most 1e+06");
    EXPECT_EQ(error_of("ticks_tiny", with("axis can0 1 0 r_shoulder_pitch 1e-300 1.5", 10)),
              d + "ticks_tiny.conf:10: ticks per degree 1e-300 is out of range: 0.001 to 1e+07");
    EXPECT_EQ(error_of("zero_huge", with("axis can0 1 0 r_shoulder_pitch 182.0 1e300", 10)),
              d + "zero_huge.conf:10: zero 1e300 is out of range: -3600 to 3600 degrees");
    EXPECT_EQ(error_of("pwm_fs", with("pwm can0 1 0 m0 40000", 11)),
              d + "pwm_fs.conf:11: PWM full scale 40000 is out of range: above 0, at most 32767");
    EXPECT_EQ(error_of("slot_two", with("axis can0 1 2 r_shoulder_pitch 182.0 1.5", 10)),
              d + "slot_two.conf:10: bad 'axis' line (the slot is 0 or 1): axis can0 1 2 r_shoulder_pitch 182.0 1.5");
    EXPECT_EQ(error_of("side", with("skin can2 8 hand inside", 13)),
              d + "side.conf:13: skin side must be distal or proximal, got 'inside'");
    // The limits themselves are accepted.
    MonitorConfig c;
    std::string t = with("stale_ms 0.1", 5);
    t = t.replace(t.find("pair_us 400"), 11, "pair_us 10000");
    t = t.replace(t.find("status_hz 20"), 12, "status_hz 1000");
    ASSERT_EQ(error_of("limits", t, &c), "");
    EXPECT_EQ(c.stale_us, 100);
    EXPECT_EQ(c.pair_us, 10000);
    EXPECT_EQ(c.status_hz, 1000);
}

TEST(MonitorConfig, TheRobotLineIsRequired) {
    const std::string d = ::testing::TempDir() + "rt_config_";
    // Without it the check against the coefficient file's robot was skipped.
    EXPECT_EQ(error_of("no_robot", with("# no robot", 2)),
              d + "no_robot.conf:0: no 'robot' line (the coefficient file's robot is checked against it)");
    EXPECT_EQ(error_of("robot_empty", with("robot", 2)), d + "robot_empty.conf:2: bad 'robot' line: robot");
    EXPECT_EQ(error_of("robot_two", with("robot a b", 2)), d + "robot_two.conf:2: bad 'robot' line: robot a b");
}

// Control bytes of the file in a message are escaped: one whole line, and a NUL does not cut it.
TEST(MonitorConfig, ARefusalIsOneLineWhateverTheFileHolds) {
    const std::string d = ::testing::TempDir() + "rt_config_";
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
    EXPECT_EQ(a.axes.size(), b.axes.size());
    EXPECT_EQ(a.robot, b.robot);
    // A NUL byte or a line without a newline at the end of the file is no problem.
    std::string nul = with("# a comment");
    nul[nul.size() - 3] = '\0';
    EXPECT_EQ(error_of("nul", nul), "");
    std::string last = kOrdered;
    last.pop_back();
    EXPECT_EQ(error_of("no_newline", last), "");
}
