#include "consph/core.h"

#include <stdio.h>
#include <string.h>
#include <time.h>
#ifdef CONSPH_HAVE_OPENMP
#include <omp.h>
#endif

/* Block length for consph_sum: large enough to vectorise, small enough that the tree is cheap. */
#define SUM_BLOCK 256

static double sum_tree(const double *a, size_t n, size_t stride)
{
    if (n <= SUM_BLOCK) {
        double s = 0.0;
        for (size_t i = 0; i < n; ++i) s += a[i * stride];
        return s;
    }
    /* Split on a block boundary so the tree shape depends on n alone. */
    size_t nblocks = (n + SUM_BLOCK - 1) / SUM_BLOCK;
    size_t left = (nblocks / 2) * SUM_BLOCK;
    return sum_tree(a, left, stride) + sum_tree(a + left * stride, n - left, stride);
}

double consph_sum(const double *a, size_t n)
{
    return sum_tree(a, n, 1);
}

double consph_sum_strided(const double *a, size_t n, size_t stride)
{
    return sum_tree(a, n, stride);
}

double consph_wtime(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void consph_set_num_threads(int n)
{
#ifdef CONSPH_HAVE_OPENMP
    if (n > 0) omp_set_num_threads(n);
#else
    (void)n;
#endif
}

int consph_num_threads(void)
{
#ifdef CONSPH_HAVE_OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

size_t consph_peak_rss(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    if (!f) return 0;
    char line[256];
    size_t kb = 0;
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "VmHWM:", 6) == 0) {
            sscanf(line + 6, "%zu", &kb);
            break;
        }
    }
    fclose(f);
    return kb * 1024;
}

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

void consph_rng_seed(consph_rng *r, uint64_t seed)
{
    uint64_t x = seed;
    for (int k = 0; k < 4; ++k) r->s[k] = splitmix64(&x);
}

static inline uint64_t rotl(uint64_t x, int k)
{
    return (x << k) | (x >> (64 - k));
}

uint64_t consph_rng_next(consph_rng *r)
{
    uint64_t *s = r->s;
    uint64_t result = rotl(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double consph_rng_uniform(consph_rng *r)
{
    return (double)(consph_rng_next(r) >> 11) * 0x1.0p-53;
}
