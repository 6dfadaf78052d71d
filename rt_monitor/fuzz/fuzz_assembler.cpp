// libFuzzer harness: frames from the bus through the monitor's loop as rt_monitor runs it, for the bundled arm's
// configuration (its compiled bus table) and the CAD coefficient file: the table's decoder and the sample assembler
// (every frame of the table, and what is none: error, remote and extended frames, unknown IDs, wrong lengths,
// reserved bits), the sample clock on the frames' stamps (late, early, repeated, backwards, far jumps), and the core
// on what they assemble.
//
// Input: 16-byte records, one frame each: byte 0 the bus index (mod 8: unconfigured indices too), bytes 1-2 the
// ID's low 16 bits and byte 3 bits 0-2 its EFF/RTR/ERR flags, byte 4 the length (low 4 bits: up to 15, as no source
// delivers), bytes 5-6 the stamp's step in µs (int16: backwards too) and byte 7 bit 0 a jump of 10⁹ µs,
// bytes 8-15 the payload. Properties: every frame counted; no sample without a strain pair; a sample's stamp is its
// torque half's; the counters add up, to the frames, and the clock's halves to 2 samples + unpaired + pending.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include "rt_monitor/assembler.hpp"
#include "rt_monitor/core.hpp"
#include "rt_monitor/sample_clock.hpp"

#ifndef FUZZ_COEF
#error "FUZZ_COEF: the CAD coefficient file's path"
#endif
#ifndef FUZZ_MONITOR_CONF
#error "FUZZ_MONITOR_CONF: the bundled configuration's path"
#endif

using namespace dynid::rt;

#define CHECK(cond) do { if (!(cond)) std::abort(); } while (0)

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static Coefficients* coef = [] {
        auto* c = new Coefficients;
        if (!load_coefficients(FUZZ_COEF, "", *c)) std::abort();
        return c;
    }();
    static MonitorConfig* cfg = [] {
        auto* m = new MonitorConfig;
        std::string err;
        if (!load_monitor_config(FUZZ_MONITOR_CONF, *m, err)) std::abort();
        return m;
    }();
    Assembler a;
    std::string err;
    CHECK(a.init(*cfg, *coef, err));
    auto core = std::make_unique<Core>(*coef);
    core->set_detector({coef->debounce_on, coef->debounce_off, coef->hysteresis});
    SampleClock clock(coef->sample_period * 1e6);
    Sample s;
    RxFrame f;
    int64_t t = 1700000000000000, frames = 0, samples = 0, steps = 0;
    auto evaluate = [&](int n) {
        for (int i = 0; i < n; ++i) {
            const ClockStep& c = clock.step(i);
            if (c.restart) core->reset();
            const Output& o = core->step(c.sample.q.data(), c.sample.y.data());
            CHECK(o.event == Event::kNone || o.ready);
            ++steps;
        }
    };
    for (size_t at = 0; at + 16 <= size; at += 16) {
        const uint8_t* r = data + at;
        f = RxFrame{};
        f.bus = r[0] % 8;
        f.frame.can_id = canid_t(r[1] | r[2] << 8);
        if (r[3] & 1) f.frame.can_id |= CAN_EFF_FLAG;
        if (r[3] & 2) f.frame.can_id |= CAN_RTR_FLAG;
        if (r[3] & 4) f.frame.can_id |= CAN_ERR_FLAG;
        f.frame.len = uint8_t(r[4] & 0x0F);
        t += int16_t(uint16_t(r[5] | r[6] << 8));
        if (r[7] & 1) t += 1000000000;
        f.t_us = t;
        std::memcpy(f.frame.data, r + 8, 8);
        ++frames;
        if (!a.push(f, s)) continue;
        ++samples;
        CHECK(s.t_us == f.t_us);
        const int n = clock.push(s);
        CHECK(n >= 0 && n <= SampleClock::kMaxSteps);
        evaluate(n);
    }
    const int n = clock.flush();
    CHECK(n >= 0 && n <= SampleClock::kMaxSteps);
    evaluate(n);
    const MonitorCounters& c = a.counters();
    CHECK(c.frames == frames && c.samples == samples && c.stale_samples <= c.samples);
    CHECK(c.samples + c.unknown_id + c.bad_length + c.error_frames <= c.frames);
    CHECK(c.frames == c.error_frames + c.unknown_id + c.bad_length + c.strain_frames + c.position_frames + c.pid_frames +
                          c.status_frames + c.skin_frames + c.sensor_frames);
    CHECK(c.strain_frames == 2 * c.samples + c.unpaired_strain + a.pending_strain());
    const ClockCounters& k = clock.counters();
    CHECK(k.interpolated >= 0 && k.late >= 0 && k.restarts >= 0 && steps >= k.interpolated);
    return 0;
}
