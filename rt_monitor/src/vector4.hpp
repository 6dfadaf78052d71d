// Four doubles in one vector (GCC's and clang's vector extension): the derivative filter's channel block, one AVX
// register in the x86-64-v3 build (multiversion.hpp). Internal to the core.
#pragma once

#include <cstring>

namespace dynid::rt {

constexpr int kPad = 4;  // a ring row's channels are read in blocks of this many
constexpr int padded(int n) noexcept { return (n + kPad - 1) / kPad * kPad; }

using V4 = double __attribute__((vector_size(kPad * sizeof(double))));
// Vectors go through references only: a vector passed or returned by value would have a different ABI in the AVX
// build and the baseline one (-Wpsabi).
inline void load(V4& v, const double* p) noexcept {
    std::memcpy(&v, p, sizeof v);  // an unaligned load: the outputs' block starts after the joints'
}
// A block in memory read and written as a vector, in place: allowed to alias the doubles it is made of, and to sit at
// any double's address (unaligned loads and stores, as fast as aligned ones where the block is aligned).
using V4Block = double __attribute__((vector_size(kPad * sizeof(double)), may_alias, aligned(alignof(double))));
inline V4Block* as_block(double* p) noexcept { return reinterpret_cast<V4Block*>(p); }
inline const V4Block* as_block(const double* p) noexcept { return reinterpret_cast<const V4Block*>(p); }
inline void store(const V4& v, double* out, int n) noexcept {
    for (int i = 0; i < n; ++i) out[i] = v[i];
}

}  // namespace dynid::rt
