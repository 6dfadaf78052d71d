// The coefficient file's checks beyond its wrapper (src/coefficients.cpp runs them in this order): the payload's
// shape before LCM's decoder, the momentum observer's section, and plausibility (rt_monitor/plausibility.hpp).
#pragma once

#include "rt_monitor/coefficients.hpp"

#include "dynid/coefficients_t.hpp"

#include <cmath>
#include <string>

namespace dynid::rt {

inline LoadResult fail(LoadError e, const std::string& msg) { return LoadResult{e, msg}; }

template <class V>
bool finite_all(const V& v) {
    for (const auto& x : v)
        if (!std::isfinite(double(x))) return false;
    return true;
}

inline std::string str(int v) { return std::to_string(v); }

// Counts and string lengths, walked without allocating: a count above the capacity is kCapacity, anything else that
// does not fit the bytes is kDecode.
LoadResult check_shape(const uint8_t* p, size_t n);
// The observer's section: absent unless selected; when present, complete and usable.
LoadResult check_observer(const dynid::coefficients_t& c);
// Every value within what physics and the sensors allow (plausibility.hpp): kImplausible, naming the first that is not.
LoadResult check_plausible(const dynid::coefficients_t& c);
// The known answers (src/known_answers.cpp): the core, built on the loaded `out`, run over the file's samples, gives
// the file's answers; kKnownAnswers naming the first sample and column that differ.
LoadResult check_known_answers(const dynid::coefficients_t& c, const Coefficients& out);

}  // namespace dynid::rt
