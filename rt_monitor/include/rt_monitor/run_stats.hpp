// What rt_monitor reports about a run beside its counters (--stats-out, docs/benchmarks.md "Soak"): the process's heap
// allocations, and a latency histogram of fixed size. Both are set up before the loop; in it they only add.
#pragma once

#include <cstdint>
#include <cstdio>
#include <vector>

namespace dynid::rt {

// Heap allocations the process has made so far: every operator new (plain, array, aligned, nothrow) and, where no
// sanitizer owns the C allocator, malloc, calloc, realloc, posix_memalign, aligned_alloc, memalign, valloc and
// pvalloc (src/alloc_count.cpp, linked into rt_monitor: it replaces them with counting versions of glibc's own).
long long allocations() noexcept;
// Whether the C allocator is counted too (false in a sanitizer build, where only operator new is).
bool allocations_count_malloc() noexcept;

// Latencies in µs, in bins of kBinUs up to kBins·kBinUs (16.4 ms); the maximum is kept exactly, and so is the
// number above a threshold (the deadline), and the kWorst largest with a tag each (the sample's time). The bins are
// allocated by init(), before the loop.
class LatencyHistogram {
public:
    static constexpr double kBinUs = 0.25;
    static constexpr size_t kBins = 65536;
    static constexpr int kWorst = 8;

    void init(double threshold_us) {
        bins_.assign(kBins, 0);
        threshold_ = threshold_us;
    }
    void add(double us, int64_t tag) noexcept {
        if (bins_.empty()) return;
        const double b = us < 0 ? 0 : us / kBinUs;
        ++bins_[b >= double(kBins - 1) ? kBins - 1 : size_t(b)];
        ++n_;
        if (us > max_) max_ = us;
        if (us > threshold_) ++over_;
        if (n_worst_ < kWorst || us > worst_us_[kWorst - 1]) {  // kept sorted, largest first
            int i = n_worst_ < kWorst ? n_worst_++ : kWorst - 1;
            for (; i > 0 && worst_us_[i - 1] < us; --i) {
                worst_us_[i] = worst_us_[i - 1];
                worst_tag_[i] = worst_tag_[i - 1];
            }
            worst_us_[i] = us;
            worst_tag_[i] = tag;
        }
    }
    int64_t count() const noexcept { return n_; }
    int64_t over() const noexcept { return over_; }  // above the threshold
    double max() const noexcept { return max_; }
    int worst_count() const noexcept { return n_worst_; }
    double worst_us(int i) const noexcept { return worst_us_[i]; }
    int64_t worst_tag(int i) const noexcept { return worst_tag_[i]; }
    // The upper edge of the bin holding the q-quantile (at most the maximum); 0 when empty.
    double quantile(double q) const noexcept;

private:
    std::vector<int64_t> bins_;
    int64_t n_ = 0, over_ = 0;
    double max_ = 0, threshold_ = 0;
    double worst_us_[kWorst] = {};
    int64_t worst_tag_[kWorst] = {};
    int n_worst_ = 0;
};

// VmRSS and VmHWM of this process from /proc/self/status, kB (-1 where unreadable). Not for the loop: it reads a file.
void resident_kb(long long& rss, long long& hwm);

// A JSON object written with fprintf: key/value pairs, nested objects by name (open/close).
class JsonOut {
public:
    explicit JsonOut(std::FILE* f) : f_(f) { std::fputc('{', f_); }
    JsonOut& num(const char* key, long long v);
    JsonOut& real(const char* key, double v);
    JsonOut& flag(const char* key, bool v);
    JsonOut& str(const char* key, const char* v);  // escaped: " \ and control bytes
    JsonOut& open(const char* key);
    JsonOut& list(const char* key);  // an array of numbers: item()…, then close_list()
    JsonOut& item(double v);
    JsonOut& close_list();
    JsonOut& close();
    void end() { std::fputs("}\n", f_); }

private:
    void sep(const char* key);
    std::FILE* f_;
    bool first_ = true;
};

}  // namespace dynid::rt
