// The monitor configuration (load_monitor_config): keys in any order give the same MonitorConfig; the bus
// lines' errors are one line naming the file, the line and the problem. (ctest rt_config; also under ASan.)
#include <gtest/gtest.h>

#include <fstream>
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
    EXPECT_EQ(error_of("bad_value", bad), dir + "bad_value.conf:12: bad 'pair_us' line: pair_us -4");
    bad = kShuffled;
    bad.replace(bad.find("skin can2 8"), 11, "skin can2 16");
    EXPECT_EQ(error_of("bad_address", bad), dir + "bad_address.conf:2: board address must be 0..15");
    EXPECT_EQ(error_of("unknown_key", std::string(kShuffled) + "colour blue\n"),
              dir + "unknown_key.conf:15: unknown key 'colour'");
}
