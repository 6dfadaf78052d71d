// Unit tests of the real-time core on the CAD coefficient file (tests/data/icub_cad.dcoef, made by
// `dynid export --cad`): loader refusals on damaged bytes, zero heap allocations over 100 000 samples (core, sample
// clock, and the status message's fill and encode), supply tracking (the detector's own: test_detector.cpp).
// Cross-language equality is tested from Python (tests/test_rt_core.py) against dynid's own residuals.
#include "core_fixture.hpp"
#include "rt_monitor/core.hpp"
#include "rt_monitor/fit_coverage.hpp"
#include "rt_monitor/sample_clock.hpp"
#include "rt_monitor/status.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <new>
#include <vector>

using namespace dynid::rt;
using dynid::rt::testing::joint_vector;
using dynid::rt::testing::load_fixture;
using dynid::rt::testing::Scenario;

// ---- allocation counting: every operator new, and malloc where no sanitizer owns it -------------------------
namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
inline void count() {
    if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

void* operator new(std::size_t n) {
    count();
    if (void* p = std::malloc(n ? n : 1)) return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
    count();
    return std::malloc(n ? n : 1);
}
void* operator new[](std::size_t n, const std::nothrow_t& t) noexcept { return operator new(n, t); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

#if !defined(__SANITIZE_ADDRESS__) && defined(__GLIBC__)
// glibc lets a program interpose malloc; __libc_* are the real ones. (ASan interposes these itself.)
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* malloc(std::size_t n) {
    count();
    return __libc_malloc(n);
}
void* calloc(std::size_t a, std::size_t b) {
    count();
    return __libc_calloc(a, b);
}
void* realloc(void* p, std::size_t n) {
    count();
    return __libc_realloc(p, n);
}
}
#define RT_COUNTS_MALLOC 1
#endif

namespace {

std::vector<uint8_t> fixture_bytes() {
    std::ifstream f(RT_TEST_COEF, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

void put_le32(std::vector<uint8_t>& b, size_t at, uint32_t v) {
    for (int k = 0; k < 4; ++k) b[at + k] = uint8_t(v >> (8 * k));
}

void reseal(std::vector<uint8_t>& b) { put_le32(b, b.size() - 4, crc32(b.data(), b.size() - 4)); }

}  // namespace

TEST(Crc32, MatchesTheStandardCheckValue) {
    const char* s = "123456789";  // CRC-32/ISO-HDLC check value
    EXPECT_EQ(crc32(reinterpret_cast<const uint8_t*>(s), 9), 0xCBF43926u);
}

TEST(Loader, AcceptsTheFixture) {
    auto c = load_fixture();
    EXPECT_EQ(c->n_joints, 7);
    EXPECT_EQ(c->n_bodies, 8);
    EXPECT_EQ(c->n_outputs, 10);
    EXPECT_EQ(c->channel_names[6], "pwm.m0");
}

TEST(Loader, RefusesDamagedBytes) {
    const std::vector<uint8_t> good = fixture_bytes();
    ASSERT_GT(good.size(), 100u);
    Coefficients c;
    struct Case {
        const char* what;
        std::vector<uint8_t> bytes;
        LoadError error;
        std::string message;
    };
    std::vector<Case> cases;
    cases.push_back({"truncated", {good.begin(), good.end() - 1}, LoadError::kTruncated, "truncated"});
    cases.push_back({"header only", {good.begin(), good.begin() + 10}, LoadError::kTruncated, "truncated"});
    auto crc = good;
    crc[200] ^= 0x40;
    cases.push_back({"flipped bit", crc, LoadError::kCrc, "CRC mismatch"});
    auto version = good;
    put_le32(version, 8, kFileVersion - 1);  // a file of the format before this one: refused, not misread
    reseal(version);
    cases.push_back({"previous version", version, LoadError::kVersion,
                     "format version " + std::to_string(kFileVersion - 1) + ", this monitor reads " +
                         std::to_string(kFileVersion) + ": export the model again"});
    auto magic = good;
    magic[0] = 'X';
    cases.push_back({"magic", magic, LoadError::kMagic, "bad magic"});
    auto fingerprint = good;
    fingerprint[16] ^= 1;  // the LCM type's fingerprint
    reseal(fingerprint);
    cases.push_back({"fingerprint", fingerprint, LoadError::kDecode, "not a dynid.coefficients_t"});
    for (const Case& k : cases) {
        const LoadResult r = load_coefficients_from_bytes(k.bytes.data(), k.bytes.size(), "", c);
        EXPECT_EQ(r.error, k.error) << k.what << ": " << r.message;
        EXPECT_NE(r.message.find(k.message), std::string::npos) << k.what << ": " << r.message;
    }
    const LoadResult robot = load_coefficients_from_bytes(good.data(), good.size(), "another_arm", c);
    EXPECT_EQ(robot.error, LoadError::kRobot);
    EXPECT_NE(robot.message.find("not for 'another_arm'"), std::string::npos) << robot.message;
}

// The payload's counts and string lengths are walked before LCM's decoder runs (issue 22, found by the fuzzer): a
// count of 2³¹ − 1 joints made the decoder ask for gigabytes before reading one, a string length of −2³¹ overflowed
// int inside it. Each is now refused from the counts alone, with the reason.
TEST(Loader, RefusesAbsurdCountsBeforeDecoding) {
    const std::vector<uint8_t> good = fixture_bytes();
    auto be32 = [](std::vector<uint8_t>& b, size_t at, uint32_t v) {
        for (int k = 0; k < 4; ++k) b[at + size_t(k)] = uint8_t(v >> (8 * (3 - k)));
    };
    size_t at = 16 + 8;  // the header, the LCM fingerprint: then six strings, then n_joints
    const size_t first_string = at;
    for (int k = 0; k < 6; ++k)
        at += 4 + (size_t(good[at]) << 24 | size_t(good[at + 1]) << 16 | size_t(good[at + 2]) << 8 | good[at + 3]);
    const size_t n_joints = at;
    ASSERT_EQ(good[n_joints + 3], 7);  // the fixture's seven joints
    struct Case {
        const char* what;
        size_t at;
        uint32_t value;
        LoadError error;
        std::string message;
    };
    const Case cases[] = {
        {"2^31 - 1 joints", n_joints, 0x7FFFFFFFu, LoadError::kCapacity,
         "too many joints: 2147483647 (this build's capacity is " + std::to_string(kMaxJoints) + ")"},
        {"-1 joints", n_joints, 0xFFFFFFFFu, LoadError::kDecode, "not a dynid.coefficients_t"},
        {"string length -2^31", first_string, 0x80000000u, LoadError::kDecode, "not a dynid.coefficients_t"},
        {"string length 0", first_string, 0, LoadError::kDecode, "not a dynid.coefficients_t"},
        {"string past the end", first_string, 0x7FFFFFFFu, LoadError::kDecode, "not a dynid.coefficients_t"},
    };
    Coefficients c;
    for (const Case& k : cases) {
        auto b = good;
        be32(b, k.at, k.value);
        reseal(b);
        const LoadResult r = load_coefficients_from_bytes(b.data(), b.size(), "", c);
        EXPECT_EQ(r.error, k.error) << k.what << ": " << r.message;
        EXPECT_NE(r.message.find(k.message), std::string::npos) << k.what << ": " << r.message;
    }
}

// Names from the file are shown with their control bytes escaped, so a refusal stays one whole line (fuzzer finding:
// a robot name holding a NUL and a newline cut the message, and split it).
TEST(Loader, ARefusalIsOneLineWhateverTheNames) {
    std::vector<uint8_t> b = fixture_bytes();
    const std::string name = "icub_right_arm";
    const auto it = std::search(b.begin(), b.end(), name.begin(), name.end());
    ASSERT_NE(it, b.end());
    const std::string bad("icub\nri\0ht_arm", name.size());
    std::copy(bad.begin(), bad.end(), it);
    reseal(b);
    Coefficients c;
    const LoadResult r = load_coefficients_from_bytes(b.data(), b.size(), "icub_right_arm", c);
    EXPECT_EQ(r.error, LoadError::kRobot);
    EXPECT_EQ(r.message, "exported for robot 'icub\\x0Ari\\x00ht_arm', not for 'icub_right_arm'");
    EXPECT_EQ(dynid::rt::shown_name(std::string(100, 'a')), std::string(80, 'a') + "…");
}

// A sample period outside 1e-5..1 s is refused (fuzzer finding: 1e-300 s passed the loader, and the sample clock's
// count of periods between two stamps overflowed int64, undefined behaviour).
TEST(Loader, RefusesASamplePeriodOutOfRange) {
    const std::vector<uint8_t> good = fixture_bytes();
    // The period's 8 bytes (big-endian 0.001) come just before the filter window's count (31); find them.
    ASSERT_EQ(load_fixture()->window, 31);
    const uint8_t ms[12] = {0x3F, 0x50, 0x62, 0x4D, 0xD2, 0xF1, 0xA9, 0xFC, 0, 0, 0, 31};
    const auto it = std::search(good.begin() + 16, good.end() - 4, std::begin(ms), std::end(ms));
    ASSERT_NE(it, good.end() - 4);
    for (const double period : {1e-300, 5e-6, 2.0}) {
        auto b = good;
        uint64_t bits = 0;
        std::memcpy(&bits, &period, 8);
        for (int k = 0; k < 8; ++k) b[size_t(it - good.begin()) + size_t(k)] = uint8_t(bits >> (8 * (7 - k)));
        reseal(b);
        Coefficients c;
        const LoadResult r = load_coefficients_from_bytes(b.data(), b.size(), "", c);
        EXPECT_EQ(r.error, LoadError::kDimension) << period << ": " << r.message;
        EXPECT_NE(r.message.find("sample period"), std::string::npos) << r.message;
        EXPECT_NE(r.message.find("out of range: 1e-05 to 1 s"), std::string::npos) << r.message;
    }
}

// The loop as rt_monitor runs it, counted: the acceleration residuals (with effects and supply tracking on) or the
// momentum observer (with supply tracking; it has no form for effects).
void no_allocation_over_100000_samples(Residual residual) {
    auto c = load_fixture();
    // With an augmented model's effects on (the CAD fixture has none): their evaluation allocates nothing either.
    c->n_effects = residual == Residual::kAcceleration ? 2 : 0;
    if (residual == Residual::kCombined) c->combined_scale = 1.5;  // the CAD fixture carries none
    c->effect_kind[0] = EffectKind::kStribeck;
    c->effect_joint[0] = 6;
    c->effect_param[0] = {0.3, 0.05, 0.0};
    c->effect_kind[1] = EffectKind::kSpring;
    c->effect_joint[1] = 1;
    c->effect_param[1] = {1.0, 0.2, 0.0};
    c->supply_time_constant = 1.0;  // and supply tracking on the motor inputs
    c->supply_prior = 1e-4;
    for (int i = 6; i < c->n_outputs; ++i) c->supply_gate[i] = 0.02;
    auto core = std::make_unique<Core>(*c);
    ASSERT_TRUE(core->set_residual(residual));
    // Through the monitor's sample clock, with late stamps (held, then caught up) and lost samples (bridged).
    auto clock = std::make_unique<SampleClock>(1000.0);
    // The status message as rt_monitor publishes it: supply array and encode buffer sized once, here.
    auto status = std::make_unique<dynid::monitor_status_t>();
    init_supply(*c, *status);
    std::vector<uint8_t> wire(size_t(status->getEncodedSize()));
    long encoded = 0;
    auto publish = [&] {
        status->late = clock->counters().late;
        fill_supply(*c, *core, *status);
        encoded += status->encode(wire.data(), 0, int(wire.size())) == int(wire.size());
    };
    Sample s;
    long alarms = 0;
    g_allocations = 0;
    g_counting = true;
    for (int k = 0; k < 100000; ++k) {
        if (k % 100 == 0) publish();  // a status at 10 Hz
        if (k % 997 == 500) continue;  // lost
        const double t = 1e-3 * k;
        // a sender woken 1.8 periods late now and then, catching up back to back (20 µs apart)
        s.t_us = std::max(s.t_us + 20, 1'700'000'000'000'000 + 1000 * int64_t(k) + (k % 1009 == 7 ? 1800 : 0));
        for (int j = 0; j < 7; ++j) s.q[size_t(j)] = 0.3 * std::sin(0.7 * t * (j + 1) + j);  // both velocity signs
        for (int i = 0; i < 10; ++i) s.y[size_t(i)] = 0.01 * std::cos(3.0 * t + i);
        for (int i = 0, n = clock->push(s); i < n; ++i) {
            const ClockStep& st = clock->step(i);
            if (st.restart) core->reset();
            alarms += core->step(st.sample.q.data(), st.sample.y.data()).above;
        }
    }
    publish();  // the final one
    g_counting = false;
    EXPECT_EQ(encoded, 1001);  // every status fitted the start-up buffer
    EXPECT_EQ(status->n_supply, 4);
    for (int i = 6, k = 0; i < c->n_outputs; ++i, ++k) EXPECT_EQ(status->supply_ratio[size_t(k)], core->supply_ratio(i));
    EXPECT_NE(status->supply_ratio[0], 1.0);  // the tracker did run
    EXPECT_GT(clock->counters().interpolated, 90);  // the clock did bridge and hold
    EXPECT_GT(clock->counters().late, 90);
    EXPECT_EQ(g_allocations.load(), 0) << "heap allocations in the loop";
    EXPECT_GT(alarms, 0);  // the loop did real work: these outputs are not what the arm would produce
#ifdef RT_COUNTS_MALLOC
    // The hook must be able to see an allocation at all, or zero above means nothing.
    g_counting = true;
    void* volatile p = std::malloc(16);
    g_counting = false;
    std::free(p);
    EXPECT_EQ(g_allocations.load(), 1);
#endif
    g_allocations = 0;
    g_counting = true;
    auto* v = new std::vector<int>(3);
    g_counting = false;
    delete v;
    EXPECT_GE(g_allocations.load(), 1);
}

TEST(Core, NoHeapAllocationOver100000Samples) { no_allocation_over_100000_samples(Residual::kAcceleration); }
TEST(Core, NoHeapAllocationOver100000SamplesWithTheObserver) { no_allocation_over_100000_samples(Residual::kMomentum); }
TEST(Core, NoHeapAllocationOver100000SamplesCombined) { no_allocation_over_100000_samples(Residual::kCombined); }

TEST(Core, SupplyTrackingFollowsASagAndIgnoresAPush) {
    // The motors' measured inputs are ŷ/0.95 (a 5 % supply sag): r must reach 1/0.95 (dynid.identify.supply), its first
    // update must be the recurrence's, and a push beyond the gate must leave it where it was.
    auto c = load_fixture();
    c->supply_time_constant = 0.5;
    c->supply_prior = 1e-10;  // a weak prior: the estimate is the data's (the CAD fixture's inputs are small)
    for (int i = 6; i < c->n_outputs; ++i) c->supply_gate[i] = 0.01;
    auto core = std::make_unique<Core>(*c);
    const VecJ q0 = joint_vector({0.1, 0.4, 0.2, 0.8, 0.0, 0.1, -0.1});
    const VecJ v = joint_vector({0.2, -0.15, 0.25, 0.3, -0.2, 0.1, 0.15});
    const double lambda = std::exp(-c->sample_period / c->supply_time_constant);
    auto step = [&](int k, double push) -> const Output& {
        const VecJ q = q0 + v * (1e-3 * k);
        Prediction p;
        core->predict(q, v, VecJ::Zero(), VecO::Zero(), p);
        VecO y = p.y_model;
        for (int i = 6; i < c->n_outputs; ++i) y[i] = p.y_model[i] / 0.95 + (i == 9 ? push : 0.0);
        return core->step(q.data(), y.data());
    };
    int k = 0;
    while (!step(k, 0.0).ready) ++k;
    const Output& first = core->output();
    for (int i = 6; i < c->n_outputs; ++i) {
        ASSERT_TRUE(first.p.active[i]) << "every motor moves in this scenario";
        const double pm = first.p.y_model[i], y = first.y[i];
        const double expected = ((1 - lambda) * pm * y + c->supply_prior) / ((1 - lambda) * pm * pm + c->supply_prior);
        EXPECT_NEAR(core->supply_ratio(i), expected, 1e-15 * std::abs(expected)) << c->channel_names[i];
        EXPECT_NE(core->supply_ratio(i), 1.0);
    }
    for (++k; k < 6000; ++k) step(k, 0.0);
    for (int i = 6; i < c->n_outputs; ++i) EXPECT_NEAR(core->supply_ratio(i), 1 / 0.95, 1e-6) << c->channel_names[i];
    EXPECT_NEAR(core->output().p.e[9], 0.0, 1e-6);
    // A push of 5× the gate on the elbow motor: while it enters the filter window the residual ramps up and the
    // first samples, still inside the gate, count; once it is in, nothing does.
    const double before = core->supply_ratio(9);
    for (int end = k + c->window; k < end; ++k) step(k, 0.05);
    const double entered = core->supply_ratio(9);
    for (int end = k + 500; k < end; ++k) step(k, 0.05);
    EXPECT_EQ(core->supply_ratio(9), entered);
    EXPECT_NEAR(entered, before, 0.02 * (before - 1.0)) << "the ramp moved it by at most 2 % of the sag";
    EXPECT_NEAR(core->output().p.e[9], 0.05, 0.02 * 0.05) << "the push stays in the residual";

    c->supply_time_constant = 0;  // off: constant gains
    auto plain = std::make_unique<Core>(*c);
    core = std::move(plain);
    for (k = 0; k < 500; ++k) step(k, 0.0);
    for (int i = 6; i < c->n_outputs; ++i) EXPECT_EQ(core->supply_ratio(i), 1.0);
}

// The momentum observer on exact model outputs (q linear in time, so the causal q̇ is exact): r stays below 1e-3 of
// its noise (ṗ is a difference quotient over the step);
// a constant disturbance d on the elbow motor's PWM then shows as r = gain·d·(1 − e^(−K_O t)) on its row
// (dynid.detect.momentum), the external joint torques τ_ext = tau_map·r, an onset after the debounce, proximal, and
// the isolated joint is the elbow (the most distal joint with a row).
TEST(Observer, ExactDataThenAFirstOrderStepOnAPush) {
    Scenario s;
    ASSERT_TRUE(s.core->set_residual(Residual::kMomentum));
    const Coefficients& c = *s.c;
    s.core->set_detector({3, 20, 0.5});
    const int no = c.n_outputs, W = c.velocity_window;
    int k = 0;
    for (; k < 300; ++k) {
        const Output& o = s.step(k, VecO::Zero());
        EXPECT_EQ(o.ready, k >= W - 1) << k;
        if (!o.ready) continue;
        EXPECT_FALSE(o.above) << "false alarm at " << k << " T2 " << o.p.t2;
        if (k < W + 100) continue;  // the start: ṗ is unknown on the first sample, a transient of e^(−K_O t)
        for (int i = 0; i < no; ++i) EXPECT_NEAR(o.r[i], 0.0, 1e-3 * std::sqrt(c.observer_variance[i])) << k << " " << i;
    }
    const double d = 0.05, gain = c.divisor[9], a = std::exp(-2 * M_PI * c.observer_bandwidth * c.sample_period);
    VecO push = VecO::Zero();
    push[9] = d;
    const VecO r_before = s.core->output().r;
    int onset = -1;
    for (int n = 1; n <= 200; ++n, ++k) {
        const Output& o = s.step(k, push);
        // x jumps by gain·d: r_n = r_0 + gain·d·(1 − aⁿ) on the row, nothing elsewhere
        EXPECT_NEAR(o.r[9] - r_before[9], gain * d * (1 - std::pow(a, n)), 1e-4 * gain * d) << n;
        for (int i = 0; i < 9; ++i) EXPECT_NEAR(o.r[i], r_before[i], 1e-3 * std::sqrt(c.observer_variance[i])) << i;
        if (o.event == Event::kOnset) {
            onset = n;
            EXPECT_EQ(o.side[0], Side::kProximal);
        }
    }
    const Output& o = s.core->output();
    const int nj = c.n_joints;
    VecJ expected = VecJ::Zero();
    expected.head(nj) = c.tau_map.topLeftCorner(nj, no) * o.r.head(no);
    for (int j = 0; j < nj; ++j) EXPECT_NEAR(o.tau_ext[j], expected[j], 1e-12) << j;
    EXPECT_GT(std::abs(o.tau_ext[3]), 0.5 * gain * d);
    EXPECT_EQ(o.joint, 3) << "the elbow: the most distal joint with a significant external torque";
    // T² crosses T²_α when gain·d·(1 − aⁿ) reaches sqrt(T²_α Λ), then 3 samples of debounce
    const double level = std::sqrt(c.observer_threshold * c.observer_variance[9]) / (gain * d);
    ASSERT_LT(level, 1.0);
    const int cross = int(std::ceil(std::log(1 - level) / std::log(a)));
    EXPECT_NEAR(onset, cross + 2, 1) << "onset 3 samples after the crossing";
}

TEST(Observer, RefusedWhereTheFileHasNone) {
    auto c = load_fixture();
    c->velocity_window = 0;  // a file without the observer's section
    Core core(*c);
    EXPECT_FALSE(core.set_residual(Residual::kMomentum));
    EXPECT_EQ(core.residual(), Residual::kAcceleration);
}

// The combined detector runs both residuals as each alone would (the observer from its q̇ window, the filter from its
// window, each with its own supply tracker), and its statistic is their normalised T² summed over κ.
TEST(Combined, IsTheSumOfBothResidualsRunAlone) {
    auto c = load_fixture();
    c->combined_scale = 1.7;
    c->supply_time_constant = 1.0;
    c->supply_prior = 1e-4;
    for (int i = 6; i < c->n_outputs; ++i) c->supply_gate[i] = 0.02;
    Core combined(*c), observer(*c), filter(*c);
    ASSERT_TRUE(combined.set_residual(Residual::kCombined));
    ASSERT_TRUE(observer.set_residual(Residual::kMomentum));
    ASSERT_TRUE(filter.set_residual(Residual::kAcceleration));
    EXPECT_EQ(combined.threshold(), 1.0);
    const int first = std::max(c->window, c->velocity_window) - 1;
    std::array<double, kMaxJoints> q{};
    std::array<double, kMaxOutputs> y{};
    int compared = 0;
    for (int k = 0; k < 3000; ++k) {
        const double t = 1e-3 * k;
        for (int j = 0; j < 7; ++j) q[size_t(j)] = 0.3 * std::sin(0.7 * t * (j + 1) + j);
        for (int i = 0; i < 10; ++i) y[size_t(i)] = 0.01 * std::cos(3.0 * t + i) + (k > 2000 && i == 8 ? 0.05 : 0.0);
        const Output& s = combined.step(q.data(), y.data());
        const Output& o = observer.step(q.data(), y.data());
        const Output& a = filter.step(q.data(), y.data());
        ASSERT_EQ(s.ready, k >= first) << k;
        if (!s.ready) continue;
        ASSERT_TRUE(o.ready && a.ready);
        // the observer's T² over its threshold (all rows rest nowhere here: the moving arm)
        const double m = o.p.t2 / c->observer_threshold, acc = a.p.t2 / c->threshold;
        EXPECT_DOUBLE_EQ(s.observer_ratio, m);
        EXPECT_DOUBLE_EQ(s.acceleration_ratio, acc);
        EXPECT_NEAR(s.p.t2, (m + acc) / c->combined_scale, 1e-12 * (1 + s.p.t2));
        EXPECT_EQ(s.above, s.p.t2 > 1.0);
        for (int i = 0; i < c->n_outputs; ++i) EXPECT_EQ(s.p.e[i], o.p.e[i]);  // the output is the observer's
        EXPECT_EQ(combined.acceleration_output().p.t2, a.p.t2);
        ++compared;
    }
    EXPECT_EQ(compared, 3000 - first);
}

TEST(Combined, FilterIsTheConvolutionWhateverTheRingLength) {
    // An observer window longer than the filter's (60 against 31 samples) makes the combined core's ring longer than
    // the acceleration core's: the sample leaving the filter's window must still be the one 31 back. Both cores'
    // estimates must agree to the bit, and with the convolution of the file's weights, across a reset mid-window.
    auto c = load_fixture();
    c->combined_scale = 1.7;
    c->velocity_window = 60;
    ASSERT_GT(c->velocity_window, c->window);
    Core combined(*c), filter(*c);
    ASSERT_TRUE(combined.set_residual(Residual::kCombined));
    ASSERT_TRUE(filter.set_residual(Residual::kAcceleration));
    const int W = c->window, nj = c->n_joints, no = c->n_outputs;
    std::vector<std::vector<double>> rows;  // the raw samples since the last reset: q, then y
    double worst = 0;
    int compared = 0;
    for (int k = 0; k < 2500; ++k) {
        if (k == 1000) {  // a gap in the frames: both restart, mid-way through a window of the moments
            combined.reset(), filter.reset(), rows.clear();
        }
        const double t = 1e-3 * k;
        std::vector<double> x(size_t(nj + no));
        for (int j = 0; j < nj; ++j) x[size_t(j)] = 1.5 + 0.3 * std::sin(0.7 * t * (j + 1) + j);
        for (int i = 0; i < no; ++i) x[size_t(nj + i)] = (i < 6 ? 20.0 : 0.0) + 0.01 * std::cos(3.0 * t + i);
        rows.push_back(x);
        combined.step(x.data(), x.data() + nj);
        const Output& a = filter.step(x.data(), x.data() + nj);
        if (!a.ready || !combined.output().ready) continue;
        const Output& b = combined.acceleration_output();
        for (int j = 0; j < nj; ++j)
            ASSERT_TRUE(a.q[j] == b.q[j] && a.dq[j] == b.dq[j] && a.ddq[j] == b.ddq[j]) << k;
        for (int i = 0; i < no; ++i) ASSERT_EQ(a.y[i], b.y[i]) << k;
        const size_t n = rows.size();
        for (int r = 0; r < 3; ++r)
            for (int ch = 0; ch < nj + (r == 0 ? no : 0); ++ch) {
                double direct = 0, scale = 0;
                for (int s = 0; s < W; ++s) {
                    const double term = c->filter(s, r) * rows[n - size_t(W) + size_t(s)][size_t(ch)];
                    direct += term, scale += std::abs(term);
                }
                const double got = ch < nj ? (r == 0 ? a.q[ch] : r == 1 ? a.dq[ch] : a.ddq[ch]) : a.y[ch - nj];
                worst = std::max(worst, std::abs(got - direct) / scale);
            }
        ++compared;
    }
    EXPECT_GT(compared, 2000);
    EXPECT_LT(worst, 1e-12);
}

TEST(Combined, RefusedWhereTheFileHasNoScale) {
    auto c = load_fixture();
    Core core(*c);  // the CAD fixture: an observer, no combined_scale
    EXPECT_FALSE(core.set_residual(Residual::kCombined));
    EXPECT_EQ(core.residual(), Residual::kAcceleration);
}

// The postures the fit saw (format version 8): the joints beyond the file's fit range, a NaN among them, counted.
TEST(FitCoverage, MarksTheJointsBeyondTheFitsRangeAndCountsTheSamples) {
    auto c = load_fixture();
    ASSERT_EQ(c->n_joints, 7);
    for (int j = 0; j < 7; ++j) c->fit_lower[size_t(j)] = -0.5, c->fit_upper[size_t(j)] = 0.5;
    dynid::rt::FitCoverage coverage(*c);
    double q[7] = {0, 0.5, -0.5, 0, 0, 0, 0};  // the ends are inside
    EXPECT_EQ(coverage.check(q), 0u);
    q[1] = 0.51, q[6] = std::nan("");
    EXPECT_EQ(coverage.check(q), (1u << 1) | (1u << 6));
    EXPECT_EQ(coverage.last(), (1u << 1) | (1u << 6));
    EXPECT_EQ(coverage.samples(), 1);
}
