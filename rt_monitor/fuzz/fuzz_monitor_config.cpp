// libFuzzer harness: the monitor's configuration parser (parse_monitor_config) and its compiled bus table on any
// text. A refusal is one line naming the file and a line; an accepted configuration is within the documented limits
// (monitor_config.hpp, capacity.hpp), its table is consistent (signals inside their frames without overlap, each value
// target carried once, the clock and pairs on its frames), and the assembler sets up from it against the CAD
// coefficient file and takes a frame of every table entry without touching memory outside its tables (the bundled
// arm's frame, joint and channel names are in the dictionary).
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>

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
    const BusTable& b = cfg.bus;
    CHECK(!b.frames.empty() && b.frames.size() <= size_t(kMaxFrames) && b.signals.size() <= size_t(kMaxSignals));
    CHECK(b.patches.size() <= size_t(kMaxSkins) && b.clock >= 0 && size_t(b.clock) < b.frames.size());
    CHECK(!b.frames[size_t(b.clock)].first_half);
    std::set<std::string> values;
    for (const std::string& v : b.values) CHECK(values.insert(v).second);
    std::set<std::pair<int, uint32_t>> ids;
    for (const FrameDef& f : b.frames) {
        CHECK(f.bus >= 0 && size_t(f.bus) < cfg.buses.size() && f.id <= 0x7FF && ids.insert({f.bus, f.id}).second);
        CHECK(f.dlc >= 0 && f.dlc <= 8 && (f.long_dlc == 0 || (f.long_dlc > f.dlc && f.long_dlc <= 8)));
        CHECK(f.n_signals >= 1 && f.n_signals <= 64 && f.first_signal + f.n_signals <= int(b.signals.size()));
        uint64_t used = 0;
        for (int i = 0; i < f.n_signals; ++i) {
            const SignalDef& s = b.signals[size_t(f.first_signal + i)];
            CHECK(s.length >= 1 && s.length <= 64 && s.scale != 0);
            // Its bits, as the decoder reads them: set every bit of a payload one at a time and see which it reads.
            uint64_t mine = 0;
            for (int bit = 0; bit < 64; ++bit) {
                uint8_t d[8] = {};
                d[bit / 8] = uint8_t(1u << (bit % 8));
                if (FrameDecoder::raw_bits(s, d, 8)) mine |= uint64_t(1) << bit;
            }
            CHECK(__builtin_popcountll(mine) == s.length && !(mine & used));
            CHECK(64 - __builtin_clzll(mine) <= 8 * (f.long_dlc ? f.long_dlc : f.dlc));
            used |= mine;
        }
    }
    Assembler a;
    if (a.init(cfg, *coef, err)) {
        // Every joint and channel is carried: one frame of every table entry, each length it takes, then the clock.
        Sample s;
        RxFrame f;
        f.t_us = 1000;
        for (const FrameDef& fr : b.frames) {
            f.bus = fr.bus;
            f.frame = can_frame{};
            f.frame.can_id = canid_t(fr.id);
            for (int len : {fr.dlc, fr.long_dlc ? fr.long_dlc : fr.dlc, 8}) {
                f.frame.len = uint8_t(len);
                std::memset(f.frame.data, 0xFF, 8);
                a.push(f, s);
                std::memset(f.frame.data, 0, 8);
                a.push(f, s);
                f.t_us += 10;
            }
        }
        const MonitorCounters& c = a.counters();
        CHECK(c.frames == 6 * int64_t(b.frames.size()) && c.unknown_id == 0);
    } else {
        CHECK(!err.empty());
        for (const char ch : err) CHECK(static_cast<unsigned char>(ch) >= 0x20 && ch != 0x7F);
    }
    return 0;
}
