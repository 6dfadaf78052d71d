// libFuzzer harness: the coefficient file loader (load_coefficients_from_bytes) on any bytes, twice: as a whole
// file, and as the payload of a wrapper made valid (magic, version, length, CRC), so that the search reaches the
// LCM decoder and every check behind the CRC. A refusal names its reason in one line; a file it accepts runs: the
// core steps through a filter window and more on the file's own dimensions, and the sample clock takes stamps at the
// file's sample period.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "rt_monitor/coefficients.hpp"
#include "rt_monitor/core.hpp"
#include "rt_monitor/sample_clock.hpp"

using namespace dynid::rt;

#define CHECK(cond) do { if (!(cond)) std::abort(); } while (0)

namespace {

void run(const Coefficients& c) {
    CHECK(c.n_joints >= 1 && c.n_joints <= kMaxJoints && c.n_outputs >= 6 && c.n_outputs <= kMaxOutputs);
    CHECK(c.window >= 3 && c.window <= kMaxWindow && c.n_bodies <= kMaxBodies && c.n_motors <= kMaxMotors);
    auto core = std::make_unique<Core>(c);
    core->set_detector({c.debounce_on, c.debounce_off, c.hysteresis});
    Sample s;
    SampleClock clock(c.sample_period * 1e6);
    for (int k = 0; k < c.window + 8; ++k) {
        for (int j = 0; j < c.n_joints; ++j) s.q[size_t(j)] = 0.01 * k * (j + 1) - 0.3;
        for (int i = 0; i < c.n_outputs; ++i) s.y[size_t(i)] = k % 5 == 0 ? 1e3 : 0.1 * i;
        // Stamps 1 ms apart (the monitor's clock takes the file's period for them), a late one, a jump.
        s.t_us = 1700000000000000 + int64_t(k) * 1000 + (k == 7 ? 3000 : 0) + (k > 20 ? 1000000 : 0);
        const int n = clock.push(s);
        for (int i = 0; i < n; ++i) {
            const ClockStep& st = clock.step(i);
            if (st.restart) core->reset();
            core->step(st.sample.q.data(), st.sample.y.data());
        }
        const Output& o = core->step(s.q.data(), s.y.data());
        CHECK(o.event == Event::kNone || o.ready);
    }
    for (int i = 0; i < c.n_outputs; ++i) (void)core->supply_ratio(i);
}

void check_refusal(const LoadResult& r) {
    CHECK(r.error != LoadError::kOk && int(r.error) >= 2 && int(r.error) <= int(LoadError::kKnownAnswers));
    CHECK(!r.message.empty());
    for (const char ch : r.message) CHECK(static_cast<unsigned char>(ch) >= 0x20 && ch != 0x7F);  // one whole line
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static Coefficients* c = new Coefficients;
    // As a file.
    LoadResult r = load_coefficients_from_bytes(data, size, "", *c);
    if (r) run(*c);
    else check_refusal(r);
    // As a payload, in a valid wrapper, for the bundled arm's robot.
    std::vector<uint8_t> file(16 + size + 4);
    std::memcpy(file.data(), kMagic, 8);
    const uint32_t head[2] = {kFileVersion, uint32_t(size)};
    for (int k = 0; k < 8; ++k) file[size_t(8 + k)] = uint8_t(head[k / 4] >> (8 * (k % 4)));
    if (size) std::memcpy(file.data() + 16, data, size);
    const uint32_t crc = crc32(file.data(), 16 + size);
    for (int k = 0; k < 4; ++k) file[16 + size + size_t(k)] = uint8_t(crc >> (8 * k));
    r = load_coefficients_from_bytes(file.data(), file.size(), "icub_right_arm", *c);
    if (r) run(*c);
    else check_refusal(r);
    return 0;
}
