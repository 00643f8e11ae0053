/* Minimal assertion helpers for consph tests: each failed check prints where and why; main
 * returns check_summary(), non-zero when any check failed. */
#ifndef CONSPH_TESTS_CHECK_H
#define CONSPH_TESTS_CHECK_H

#include <math.h>
#include <stdio.h>

static int check_failures = 0;
static int check_count = 0;

#define CHECK(cond, ...)                                                                           \
    do {                                                                                           \
        ++check_count;                                                                             \
        if (!(cond)) {                                                                             \
            ++check_failures;                                                                      \
            fprintf(stderr, "%s:%d: check failed: %s: ", __FILE__, __LINE__, #cond);               \
            fprintf(stderr, __VA_ARGS__);                                                          \
            fputc('\n', stderr);                                                                   \
        }                                                                                          \
    } while (0)

/* |a - b| <= tol, reporting both values. */
#define CHECK_NEAR(a, b, tol, ...)                                                                 \
    do {                                                                                           \
        double check_a_ = (a), check_b_ = (b);                                                     \
        ++check_count;                                                                             \
        if (!(fabs(check_a_ - check_b_) <= (tol))) {                                               \
            ++check_failures;                                                                      \
            fprintf(                                                                               \
                stderr, "%s:%d: %s = %.17g vs %s = %.17g (|diff| %.3g > tol %.3g): ", __FILE__,    \
                __LINE__, #a, check_a_, #b, check_b_, fabs(check_a_ - check_b_), (double)(tol));   \
            fprintf(stderr, __VA_ARGS__);                                                          \
            fputc('\n', stderr);                                                                   \
        }                                                                                          \
    } while (0)

static inline int check_summary(const char *name)
{
    printf("%s: %d checks, %d failed\n", name, check_count, check_failures);
    return check_failures ? 1 : 0;
}

#endif
