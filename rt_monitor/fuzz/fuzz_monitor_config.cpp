// libFuzzer harness: the monitor's configuration parser (parse_monitor_config) on any text. A refusal is one line
// naming the file and a line; an accepted configuration is within the documented limits (assembler.hpp), maps no
// joint, motor or board slot twice, and the assembler sets up from it against the CAD coefficient file without
// touching memory outside its tables (the bundled arm's joint and channel names are in the dictionary).
#include <cstdint>
#include <cstdlib>
#include <set>
#include <string>
#include <tuple>

#include "rt_monitor/assembler.hpp"

#ifndef FUZZ_COEF
#error "FUZZ_COEF: the CAD coefficient file's path"
#endif

using namespace dynid::rt;

#define CHECK(cond) do { if (!(cond)) std::abort(); } while (0)

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static Coefficients* coef = [] {
        auto* c = new Coefficients;
        if (!load_coefficients(FUZZ_COEF, "", *c)) std::abort();
        return c;
    }();
    const std::string text(reinterpret_cast<const char*>(data), size);
    MonitorConfig cfg;
    std::string err;
    if (!parse_monitor_config(text, "fuzz.conf", cfg, err)) {
        CHECK(err.rfind("fuzz.conf:", 0) == 0 && err.size() > 12);
        for (const char ch : err) CHECK(static_cast<unsigned char>(ch) >= 0x20 && ch != 0x7F);  // one whole line
        return 0;
    }
    CHECK(!cfg.robot.empty() && !cfg.buses.empty() && cfg.buses.size() <= size_t(kMaxBuses));
    CHECK(cfg.stale_us >= 100 && cfg.stale_us <= 1000000);
    CHECK(cfg.pair_us >= kPairUsMin && cfg.pair_us <= kPairUsMax);
    CHECK(cfg.status_hz >= kStatusHzMin && cfg.status_hz <= kStatusHzMax);
    CHECK(status_period_us(cfg) >= 1000 && status_period_us(cfg) <= 10000000);  // as rt_monitor computes it
    CHECK(cfg.residual_every >= 1 && cfg.residual_every <= kResidualEveryMax);
    CHECK(cfg.skins.size() <= size_t(kMaxSkins));
    std::set<std::string> joints, motors;
    std::set<std::tuple<int, int, int>> axis_slots, pwm_slots;
    for (const auto& a : cfg.axes) {
        CHECK(joints.insert(a.joint).second && axis_slots.insert({a.bus, a.address, a.slot}).second);
        CHECK(a.ticks_per_degree >= kTicksPerDegreeMin && a.ticks_per_degree <= kTicksPerDegreeMax);
    }
    for (const auto& p : cfg.pwms) {
        CHECK(motors.insert(p.motor).second && pwm_slots.insert({p.bus, p.address, p.slot}).second);
        CHECK(p.full_scale > 0 && p.full_scale <= kPwmFullScaleMax);
    }
    Assembler a;
    if (a.init(cfg, *coef, err)) {
        // Every joint and channel is served: one sample of frames from every configured board.
        Sample s;
        RxFrame f;
        f.t_us = 1000;
        for (const auto& x : cfg.axes) {
            f.bus = x.bus;
            f.frame = can_frame{};
            f.frame.can_id = canid_t(0x100 | x.address << 4 | 1);
            f.frame.len = 8;
            a.push(f, s);
        }
        f.bus = cfg.strain_bus;
        f.frame = can_frame{};
        f.frame.len = 6;
        f.frame.can_id = canid_t(0x300 | cfg.strain_address << 4 | 0xA);
        a.push(f, s);
        f.frame.can_id = canid_t(0x300 | cfg.strain_address << 4 | 0xB);
        f.t_us += 100;
        a.push(f, s);
    } else {
        CHECK(!err.empty());
        for (const char ch : err) CHECK(static_cast<unsigned char>(ch) >= 0x20 && ch != 0x7F);
    }
    return 0;
}
