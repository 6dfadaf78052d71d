// RT_MULTIVERSION: a hot function built twice, for x86-64-v3 (AVX2, FMA) and the baseline x86-64, the loader picking
// the one this CPU runs (GCC's function multi-versioning), so one binary runs on any x86-64 and at full width on
// today's. The two round differently in the last bits (FMA contracts a·b + c), as two CPUs' BLAS do: the core's
// results are compared across machines with tolerances, never bit for bit. Not under ASan or clang (one build).
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#define RT_MULTIVERSION __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define RT_MULTIVERSION
#endif
