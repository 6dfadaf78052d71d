// rt_monitor's run statistics (run_stats.hpp): the latency histogram's quantiles, the resident set, the JSON writer.
#include "rt_monitor/run_stats.hpp"

#include <cmath>
#include <cstring>

namespace dynid::rt {

double LatencyHistogram::quantile(double q) const noexcept {
    if (n_ == 0) return 0;
    const double want = std::ceil(q * double(n_));
    int64_t seen = 0;
    for (size_t b = 0; b < bins_.size(); ++b) {
        seen += bins_[b];
        if (double(seen) >= want && seen > 0) {
            const double edge = double(b + 1) * kBinUs;
            return edge < max_ ? edge : max_;
        }
    }
    return max_;
}

void resident_kb(long long& rss, long long& hwm) {
    rss = hwm = -1;
    std::FILE* f = std::fopen("/proc/self/status", "r");
    if (!f) return;
    char line[256];
    while (std::fgets(line, sizeof line, f)) {
        long long v = 0;
        if (std::sscanf(line, "VmRSS: %lld kB", &v) == 1) rss = v;
        if (std::sscanf(line, "VmHWM: %lld kB", &v) == 1) hwm = v;
    }
    std::fclose(f);
}

void JsonOut::sep(const char* key) {
    if (!first_) std::fputc(',', f_);
    first_ = false;
    std::fprintf(f_, "\"%s\":", key);
}
JsonOut& JsonOut::num(const char* key, long long v) {
    sep(key);
    std::fprintf(f_, "%lld", v);
    return *this;
}
JsonOut& JsonOut::real(const char* key, double v) {
    sep(key);
    if (std::isfinite(v)) std::fprintf(f_, "%.17g", v);
    else std::fputs("null", f_);
    return *this;
}
JsonOut& JsonOut::flag(const char* key, bool v) {
    sep(key);
    std::fputs(v ? "true" : "false", f_);
    return *this;
}
JsonOut& JsonOut::str(const char* key, const char* v) {
    sep(key);
    std::fputc('"', f_);
    for (const unsigned char* c = reinterpret_cast<const unsigned char*>(v); *c; ++c) {
        if (*c == '"' || *c == '\\') std::fprintf(f_, "\\%c", *c);
        else if (*c < 0x20) std::fprintf(f_, "\\u%04x", *c);
        else std::fputc(*c, f_);
    }
    std::fputc('"', f_);
    return *this;
}
JsonOut& JsonOut::open(const char* key) {
    sep(key);
    std::fputc('{', f_);
    first_ = true;
    return *this;
}
JsonOut& JsonOut::list(const char* key) {
    sep(key);
    std::fputc('[', f_);
    first_ = true;
    return *this;
}
JsonOut& JsonOut::item(double v) {
    if (!first_) std::fputc(',', f_);
    first_ = false;
    if (std::isfinite(v)) std::fprintf(f_, "%.17g", v);
    else std::fputs("null", f_);
    return *this;
}
JsonOut& JsonOut::close_list() {
    std::fputc(']', f_);
    first_ = false;
    return *this;
}
JsonOut& JsonOut::close() {
    std::fputc('}', f_);
    first_ = false;
    return *this;
}

}  // namespace dynid::rt
