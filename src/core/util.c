#include "consph/core.h"

#include <stdio.h>
#include <string.h>
#include <time.h>
#ifdef CONSPH_HAVE_OPENMP
#include <omp.h>
#endif

/* Block length for consph_sum: large enough to vectorise, small enough that the tree is cheap. */
#define SUM_BLOCK 256

static double sum_block(const double *a, size_t n, size_t stride)
{
    double s = 0.0;
    for (size_t i = 0; i < n; ++i) s += a[i * stride];
    return s;
}

/* sum_tree of at most 4 blocks: four whole blocks' chains of additions run side by side (each
 * its own values in its own order: the same sums), where one after the other each addition
 * waited on the last; then the tree's additions over them, (l0 + l1) + (l2 + l3), or l0 + (l1 +
 * l2) for three blocks. */
static double sum_leaves(const double *a, size_t n, size_t stride)
{
    const size_t nb = (n + SUM_BLOCK - 1) / SUM_BLOCK;
    double l[4];
    if (n == 4 * SUM_BLOCK) {
        const size_t o = SUM_BLOCK * stride;
        double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
        for (size_t i = 0; i < SUM_BLOCK; ++i) {
            const double *q = a + i * stride;
            s0 += q[0];
            s1 += q[o];
            s2 += q[2 * o];
            s3 += q[3 * o];
        }
        l[0] = s0, l[1] = s1, l[2] = s2, l[3] = s3;
    } else {
        for (size_t k = 0; k < nb; ++k) {
            const size_t m = n - k * SUM_BLOCK < SUM_BLOCK ? n - k * SUM_BLOCK : SUM_BLOCK;
            l[k] = sum_block(a + k * SUM_BLOCK * stride, m, stride);
        }
    }
    switch (nb) {
    case 0:
        return 0.0;
    case 1:
        return l[0];
    case 2:
        return l[0] + l[1];
    case 3:
        return l[0] + (l[1] + l[2]);
    default:
        return (l[0] + l[1]) + (l[2] + l[3]);
    }
}

static double sum_tree(const double *a, size_t n, size_t stride)
{
    if (n <= 4 * SUM_BLOCK) return sum_leaves(a, n, stride);
    /* Split on a block boundary so the tree shape depends on n alone. */
    size_t nblocks = (n + SUM_BLOCK - 1) / SUM_BLOCK;
    size_t left = (nblocks / 2) * SUM_BLOCK;
    return sum_tree(a, left, stride) + sum_tree(a + left * stride, n - left, stride);
}

/* From this many values on, the subtrees SUM_SPLIT levels below the root are summed on the
 * threads and then added up as sum_tree adds them: the same tree, the same bits, for any thread
 * count. (A block's sum is a chain of dependent additions, ~4 cycles each: 60 000 values take
 * ~80 µs on one core, a part of every step that no thread count would shorten.) */
#define SUM_PARALLEL_MIN 8192
#define SUM_SPLIT 4

#ifdef CONSPH_HAVE_OPENMP
/* The subtrees of sum_tree `depth` levels down (fewer where a subtree is one block), left to
 * right. */
static void sum_subtrees(const double *a, size_t n, size_t stride, int depth, const double **at,
                         size_t *len, int *k)
{
    if (depth == 0 || n <= SUM_BLOCK) {
        at[*k] = a;
        len[(*k)++] = n;
        return;
    }
    size_t nblocks = (n + SUM_BLOCK - 1) / SUM_BLOCK;
    size_t left = (nblocks / 2) * SUM_BLOCK;
    sum_subtrees(a, left, stride, depth - 1, at, len, k);
    sum_subtrees(a + left * stride, n - left, stride, depth - 1, at, len, k);
}

/* sum_tree's additions above those subtrees, over their sums part[] */
static double sum_above(const double *part, size_t n, int depth, int *k)
{
    if (depth == 0 || n <= SUM_BLOCK) return part[(*k)++];
    size_t nblocks = (n + SUM_BLOCK - 1) / SUM_BLOCK;
    size_t left = (nblocks / 2) * SUM_BLOCK;
    const double l = sum_above(part, left, depth - 1, k);
    return l + sum_above(part, n - left, depth - 1, k);
}
#endif

static double sum_any(const double *a, size_t n, size_t stride)
{
#ifdef CONSPH_HAVE_OPENMP
    if (n >= SUM_PARALLEL_MIN && !omp_in_parallel() && omp_get_max_threads() > 1) {
        const double *at[1 << SUM_SPLIT];
        size_t len[1 << SUM_SPLIT];
        double part[1 << SUM_SPLIT];
        int nsub = 0;
        sum_subtrees(a, n, stride, SUM_SPLIT, at, len, &nsub);
#pragma omp parallel for schedule(static)
        for (int k = 0; k < nsub; ++k) part[k] = sum_tree(at[k], len[k], stride);
        int k = 0;
        return sum_above(part, n, SUM_SPLIT, &k);
    }
#endif
    return sum_tree(a, n, stride);
}

double consph_sum(const double *a, size_t n)
{
    return sum_any(a, n, 1);
}

double consph_sum_strided(const double *a, size_t n, size_t stride)
{
    return sum_any(a, n, stride);
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
