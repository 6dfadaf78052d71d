/*
 * check.h - the plain C99 check macros the firmware_like tests share: each failure is printed with its line and
 * counted; each test's main prints the counts and exits 1 on any failed check.
 */
#ifndef FIRMWARE_LIKE_TESTS_CHECK_H
#define FIRMWARE_LIKE_TESTS_CHECK_H

#include <stdint.h>
#include <stdio.h>
#include <string.h>

static unsigned g_checks;
static unsigned g_failed;

#define CHECK(cond)                                                              \
    do {                                                                         \
        ++g_checks;                                                              \
        if (!(cond)) {                                                           \
            ++g_failed;                                                          \
            printf("FAIL %s:%d: %s\n", __FILE__, __LINE__, #cond);               \
        }                                                                        \
    } while (0)

/* Integer equality, printing both sides (everything here fits long long). */
#define CHECK_EQ(a, b)                                                           \
    do {                                                                         \
        long long a_ = (long long)(a), b_ = (long long)(b);                      \
        ++g_checks;                                                              \
        if (a_ != b_) {                                                          \
            ++g_failed;                                                          \
            printf("FAIL %s:%d: %s == %s (%lld != %lld)\n", __FILE__, __LINE__, \
                   #a, #b, a_, b_);                                              \
        }                                                                        \
    } while (0)

/* The bytes at p equal the listed ones. */
#define CHECK_BYTES(p, ...)                                                      \
    do {                                                                         \
        static const uint8_t want_[] = {__VA_ARGS__};                            \
        ++g_checks;                                                              \
        if (memcmp((p), want_, sizeof want_) != 0) {                             \
            ++g_failed;                                                          \
            printf("FAIL %s:%d: bytes of %s\n", __FILE__, __LINE__, #p);         \
        }                                                                        \
    } while (0)

#endif
