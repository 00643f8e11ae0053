/* Minimal assertion helpers for consph tests: each failed check prints where and why; main
 * returns check_summary(), non-zero when any check failed. */
#ifndef CONSPH_TESTS_CHECK_H
#define CONSPH_TESTS_CHECK_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/core.h"

#ifdef _OPENMP
#include <omp.h>
#endif

/* The thread count of the next parallel regions, for tests that compare 1 and 2 threads (a
 * no-op without OpenMP). */
static inline void check_set_threads(int n)
{
#ifdef _OPENMP
    omp_set_num_threads(n);
#else
    (void)n;
#endif
}

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

/* The whole file in a malloc'd buffer with a NUL after its *size bytes; NULL (and *size 0) when
 * it cannot be read. */
static inline unsigned char *check_load_file(const char *path, size_t *size)
{
    *size = 0;
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *b = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (b && fread(b, 1, (size_t)n, f) != (size_t)n) {
        free(b);
        b = NULL;
    }
    fclose(f);
    if (b) {
        b[n] = '\0';
        *size = (size_t)n;
    }
    return b;
}

/* Whether two files hold the same bytes (0 when either cannot be read). */
static inline int check_same_file(const char *a, const char *b)
{
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    int same = fa && fb;
    while (same) {
        const int ca = fgetc(fa), cb = fgetc(fb);
        if (ca != cb) same = 0;
        if (ca == EOF || cb == EOF) break;
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return same;
}

/* 1 when both particle sets hold the same positions and fields bit for bit. */
static inline int check_particles_equal(const consph_particles *a, const consph_particles *b)
{
    if (a->n != b->n || a->dim != b->dim || a->nfields != b->nfields) return 0;
    for (int d = 0; d < a->dim; ++d)
        if (memcmp(a->x[d], b->x[d], a->n * sizeof(double))) return 0;
    for (int f = 0; f < a->nfields; ++f) {
        const consph_field *fb = consph_particles_find(b, a->fields[f].name);
        if (!fb || fb->ncomp != a->fields[f].ncomp) return 0;
        for (int c = 0; c < fb->ncomp; ++c)
            if (memcmp(a->fields[f].data + (size_t)c * a->cap, fb->data + (size_t)c * b->cap,
                       a->n * sizeof(double)))
                return 0;
    }
    return 1;
}

#endif
