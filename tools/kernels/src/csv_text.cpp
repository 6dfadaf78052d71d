#include "csv_text.hpp"

#include <charconv>
#include <cmath>
#include <cstring>

namespace dynid {
namespace {

// The most characters one value takes: "-" + 17 digits + "." + "e-308", or an integer's 20.
constexpr size_t kMaxValue = 26;

char* put(char* p, const char* s, size_t n) {
    std::memcpy(p, s, n);
    return p + n;
}

// repr(x) of CPython (float_repr_style 'short') at p, returning its end: the shortest round-trip digits d1…dn with
// the decimal point after position `point` (x = 0.d1…dn × 10^point); fixed notation where −4 < point ≤ 16, ".0"
// where no digit follows the point; otherwise d1[.d2…dn]e±XX, at least two exponent digits.
char* put_repr(double x, char* p) {
    if (std::isnan(x)) return put(p, "nan", 3);
    if (std::isinf(x)) return x < 0 ? put(p, "-inf", 4) : put(p, "inf", 3);
    if (std::signbit(x)) *p++ = '-';
    x = std::fabs(x);
    if (x == 0) return put(p, "0.0", 3);
    // std::to_chars without a precision: the shortest digits that round-trip, the nearest to x among them (Ryu),
    // as "d[.ddd]e±XX"
    char sci[32];
    const char* end = std::to_chars(sci, sci + sizeof sci, x, std::chars_format::scientific).ptr;
    char digits[20];
    int n = 0;
    const char* s = sci;
    for (; s < end && *s != 'e'; ++s)
        if (*s != '.') digits[n++] = *s;
    int exponent = 0;
    std::from_chars(s + (s[1] == '+' ? 2 : 1), end, exponent);
    const int point = exponent + 1;
    if (point > -4 && point <= 16) {
        if (point <= 0) {
            p = put(p, "0.", 2);
            std::memset(p, '0', size_t(-point));
            return put(p - point, digits, size_t(n));
        }
        if (point < n) {
            p = put(p, digits, size_t(point));
            *p++ = '.';
            return put(p, digits + point, size_t(n - point));
        }
        p = put(p, digits, size_t(n));
        std::memset(p, '0', size_t(point - n));
        return put(p + (point - n), ".0", 2);
    }
    *p++ = digits[0];
    if (n > 1) {
        *p++ = '.';
        p = put(p, digits + 1, size_t(n - 1));
    }
    *p++ = 'e';
    *p++ = exponent < 0 ? '-' : '+';
    const int a = exponent < 0 ? -exponent : exponent;  // at most 324
    if (a >= 100) *p++ = char('0' + a / 100);
    *p++ = char('0' + a / 10 % 10);
    *p++ = char('0' + a % 10);
    return p;
}

}  // namespace

void append_csv_rows(const double* values, long n_rows, long n_cols, const bool* integer, std::string& out) {
    const size_t start = out.size();
    out.resize(start + size_t(n_rows) * size_t(n_cols) * (kMaxValue + 1) + size_t(n_rows));
    char* p = out.data() + start;
    for (long r = 0; r < n_rows; ++r) {
        const double* row = values + r * n_cols;
        for (long c = 0; c < n_cols; ++c) {
            if (c) *p++ = ',';
            p = integer[c] ? std::to_chars(p, p + kMaxValue, static_cast<long long>(row[c])).ptr : put_repr(row[c], p);
        }
        *p++ = '\n';
    }
    out.resize(size_t(p - out.data()));
}

}  // namespace dynid
