// Unit tests of the real-time core's detector on the CAD coefficient file: debounce, hysteresis, the contact's side of
// the F/T sensor, and the strongest sample an end event describes.
#include "core_fixture.hpp"
#include "rt_monitor/core.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>

using namespace dynid::rt;
using dynid::rt::testing::Scenario;

TEST(Detector, DebounceHysteresisAndSide) {
    Scenario s;
    s.core->set_detector({5, 20, 0.5});
    const double big = 5.0 * std::sqrt(s.c->threshold * s.c->variance[0]);  // fx alone: 25× T²_α
    VecO none = VecO::Zero(), push = VecO::Zero(), mid = VecO::Zero();
    push[0] = big;
    mid[0] = 0.85 * std::sqrt(s.c->threshold * s.c->variance[0]);  // T² ≈ 0.72 T²_α: between end and onset levels
    int k = 0, onset = -1, end = -1, first_above = -1;
    for (; k < 200; ++k) EXPECT_FALSE(s.step(k, none).above) << "false alarm at " << k << " T2 " << s.core->output().p.t2;
    for (; k < 400; ++k) {
        const Output& o = s.step(k, push);
        if (o.above && first_above < 0) first_above = k;
        if (o.event == Event::kOnset) {
            onset = k;
            EXPECT_EQ(o.side[0], Side::kDistal);
        }
        if (k == 399) {  // settled: the F/T residual is the external wrench
            EXPECT_NEAR(o.wrench[0][0], big, 1e-3 * big);
            EXPECT_NEAR(o.wrench[0].tail<5>().norm(), 0.0, 1e-3 * big);
        }
    }
    ASSERT_GE(first_above, 200);
    EXPECT_EQ(onset, first_above + 4) << "onset after 5 consecutive samples above";
    for (; k < 600; ++k) {
        const Output& o = s.step(k, mid);
        EXPECT_TRUE(o.in_contact) << "hysteresis: stays in contact above the end level, sample " << k;
        EXPECT_NE(o.event, Event::kEnd);
    }
    int first_low = -1;
    for (; k < 800; ++k) {
        const Output& o = s.step(k, none);
        if (first_low < 0 && o.p.t2 < 0.5 * s.c->threshold) first_low = k;
        if (o.event == Event::kEnd) end = k;
    }
    ASSERT_GE(first_low, 600);
    EXPECT_EQ(end, first_low + 19) << "end after 20 consecutive samples below the end level";
}

TEST(Detector, AnEndReportsTheContactsStrongestSample) {
    // A contact first seen on a motor channel alone (proximal of the sensor), then growing beyond the sensor (its fx):
    // the onset describes its own sample, the end the strongest one, as dynid detect's events take their peak.
    Scenario s;
    s.core->set_detector({5, 20, 0.5});
    VecO motor = VecO::Zero(), both = VecO::Zero();
    motor[9] = 3.0 * std::sqrt(s.c->threshold * s.c->variance[9]);
    both = motor;
    both[0] = 6.0 * std::sqrt(s.c->threshold * s.c->variance[0]);
    int k = 0;
    for (; k < 100; ++k) s.step(k, VecO::Zero());
    double strongest = 0;
    Vec6 wrench_there = Vec6::Zero();
    bool onset_seen = false;
    for (; k < 400; ++k) {
        const Output& o = s.step(k, k < 200 ? motor : both);
        if (o.event == Event::kOnset) {
            onset_seen = true;
            EXPECT_EQ(o.side[0], Side::kProximal);
            EXPECT_TRUE(o.peak_now);
        }
        if (o.in_contact && o.p.t2 > strongest) {
            EXPECT_TRUE(o.peak_now) << k;
            strongest = o.p.t2;
            wrench_there = o.wrench[0];
        } else {
            EXPECT_FALSE(o.peak_now && o.event != Event::kOnset) << k;
        }
    }
    ASSERT_TRUE(onset_seen);
    bool ended = false;
    for (; k < 600 && !ended; ++k) {
        const Output& o = s.step(k, VecO::Zero());
        if (o.event != Event::kEnd) continue;
        ended = true;
        EXPECT_EQ(o.side[0], Side::kNone) << "the end sample itself is under the level";
        EXPECT_EQ(o.peak.side[0], Side::kDistal);
        EXPECT_EQ(o.peak.t2, strongest);
        EXPECT_EQ((o.peak.wrench[0] - wrench_there).norm(), 0.0);
        EXPECT_GT(o.peak.wrench[0][0], 0.5 * both[0]);
    }
    EXPECT_TRUE(ended);
}

TEST(Detector, MotorChannelsAloneMeanProximal) {
    Scenario s;
    VecO push = VecO::Zero();
    push[9] = 5.0 * std::sqrt(s.c->threshold * s.c->variance[9]);  // the elbow motor's PWM only
    for (int k = 0; k < 100; ++k) s.step(k, VecO::Zero());
    bool seen = false;
    for (int k = 100; k < 200; ++k) {
        const Output& o = s.step(k, push);
        if (o.above) {
            seen = true;
            EXPECT_EQ(o.side[0], Side::kProximal);
        }
    }
    EXPECT_TRUE(seen);
}
