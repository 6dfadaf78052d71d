// Counts the process's heap allocations (run_stats.hpp, allocations()): rt_monitor links this file so that its
// --stats-out can say how many allocations the loop made after start-up. Each replacement adds one to a relaxed
// atomic counter and calls glibc's own allocator (its __libc_* entry points, as tests/test_core.cpp does); free and
// operator delete are not counted. Where a sanitizer owns the C allocator, only operator new is counted.
#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

#include "rt_monitor/run_stats.hpp"

namespace {
std::atomic<long long> g_allocations{0};
inline void count() noexcept { g_allocations.fetch_add(1, std::memory_order_relaxed); }

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define RT_NO_MALLOC_HOOKS 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define RT_NO_MALLOC_HOOKS 1
#endif
#endif
#if !defined(RT_NO_MALLOC_HOOKS) && !defined(__GLIBC__)
#define RT_NO_MALLOC_HOOKS 1
#endif
}  // namespace

#ifndef RT_NO_MALLOC_HOOKS
// glibc lets a program interpose its allocator; __libc_* are the real ones.
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void* __libc_valloc(std::size_t);
void* __libc_pvalloc(std::size_t);

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
void* memalign(std::size_t align, std::size_t n) {
    count();
    return __libc_memalign(align, n);
}
void* aligned_alloc(std::size_t align, std::size_t n) {
    count();
    return __libc_memalign(align, n);
}
int posix_memalign(void** out, std::size_t align, std::size_t n) {
    if (align < sizeof(void*) || (align & (align - 1)) != 0) return EINVAL;
    count();
    void* p = __libc_memalign(align, n);
    if (!p) return ENOMEM;
    *out = p;
    return 0;
}
void* valloc(std::size_t n) {
    count();
    return __libc_valloc(n);
}
void* pvalloc(std::size_t n) {
    count();
    return __libc_pvalloc(n);
}
}
#endif

namespace {
void* aligned(std::size_t n, std::size_t align) noexcept {
    void* p = nullptr;
    // posix_memalign needs at least pointer alignment; counted there (or here, in a sanitizer build).
#ifdef RT_NO_MALLOC_HOOKS
    count();
#endif
    return posix_memalign(&p, align < sizeof(void*) ? sizeof(void*) : align, n ? n : 1) == 0 ? p : nullptr;
}
void* plain(std::size_t n) noexcept {
#ifdef RT_NO_MALLOC_HOOKS
    count();
#endif
    return std::malloc(n ? n : 1);
}
}  // namespace

void* operator new(std::size_t n) {
    if (void* p = plain(n)) return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return plain(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return plain(n); }
void* operator new(std::size_t n, std::align_val_t a) {
    if (void* p = aligned(n, std::size_t(a))) return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t a) { return operator new(n, a); }
void* operator new(std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept { return aligned(n, std::size_t(a)); }
void* operator new[](std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
    return aligned(n, std::size_t(a));
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }

namespace dynid::rt {
long long allocations() noexcept { return g_allocations.load(std::memory_order_relaxed); }
bool allocations_count_malloc() noexcept {
#ifdef RT_NO_MALLOC_HOOKS
    return false;
#else
    return true;
#endif
}
}  // namespace dynid::rt
