// libFuzzer harness: the monitor's option values (--priority N: parse_int; --cpu LIST: parse_cpu_list) on any text
// up to the first NUL (an argv string). An accepted CPU list is ascending without repeats, and the start-up line's
// text of it parses back to the same list.
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "rt_monitor/rt_settings.hpp"

using namespace dynid::rt;

#define CHECK(cond) do { if (!(cond)) std::abort(); } while (0)

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::string text(reinterpret_cast<const char*>(data), size);
    text = text.substr(0, text.find('\0'));
    int v = 0;
    if (parse_int(text, -1000000, 1000000, v)) CHECK(v >= -1000000 && v <= 1000000 && std::to_string(v).size() <= text.size());
    RtSettings s;
    if (parse_cpu_list(text, s.cpus)) {
        CHECK(!s.cpus.empty());
        for (size_t i = 1; i < s.cpus.size(); ++i) CHECK(s.cpus[i] > s.cpus[i - 1]);
        // "mlockall off, default scheduling, CPU 3" or "..., CPUs 0-2,5": the list's text parses back the same.
        const std::string d = describe_rt_settings(s);
        const size_t at = d.find(s.cpus.size() == 1 ? ", CPU " : ", CPUs ");
        CHECK(at != std::string::npos);
        std::vector<int> back;
        CHECK(parse_cpu_list(d.substr(at + (s.cpus.size() == 1 ? 6 : 7)), back) && back == s.cpus);
    }
    return 0;
}
