/* The hit test of the inline traversal over whole runs: consph_nnps_gather and the query's scan.
 *
 * Three implementations give the same hits, order and values bit for bit (the same separations
 * q - x, squared distance summed from axis 0 up without fused multiply-adds, ordered compare,
 * correctly rounded square root):
 *  - portable C: a branchless loop that writes every candidate and advances only on a hit;
 *  - SSE2 (baseline x86-64): four candidates per step; the hits' slots are stored through a
 *    table of positions by hit mask, their x_ij and r² recomputed per hit;
 *  - AVX2, chosen at run time: four candidates per vector, and slots, x_ij and r² compressed
 *    with one permutation per vector, so nothing is recomputed.
 * The vector paths read whole blocks of four slots; the coordinate arrays carry
 * CONSPH_NNPS_GATHER_SLACK padding entries, blocks past a run's end are masked, and the output
 * arrays take up to that many entries past the count. */
#include "nnps_internal.h"

#include <stdint.h>
#include <string.h>

#if defined(__x86_64__) && defined(__SSE2__)
#include <emmintrin.h>
#define NNPS_SSE2 1
#if defined(__GNUC__)
#include <immintrin.h>
#define NNPS_AVX2 1
#endif
#endif

#ifdef NNPS_SSE2
/* Positions of the set bits of a 4-bit hit mask, in order, and their number. */
static const unsigned char hit_count[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};
static const unsigned char hit_pos[16][4] = {
    {0, 0, 0, 0}, {0, 0, 0, 0}, {1, 0, 0, 0}, {0, 1, 0, 0}, {2, 0, 0, 0}, {0, 2, 0, 0},
    {1, 2, 0, 0}, {0, 1, 2, 0}, {3, 0, 0, 0}, {0, 3, 0, 0}, {1, 3, 0, 0}, {0, 1, 3, 0},
    {2, 3, 0, 0}, {0, 2, 3, 0}, {1, 2, 3, 0}, {0, 1, 2, 3}};
/* Hit mask of the lanes of a block that lie before the run's end. */
static inline int lanes_before(size_t s, size_t s1)
{
    size_t left = s1 - s;
    return left >= 4 ? 15 : (1 << left) - 1;
}
#endif

#if defined(__GNUC__)
#define NNPS_INLINE static inline __attribute__((always_inline))
#else
#define NNPS_INLINE static inline
#endif

/* x_ij and r² of the hits slot[n0..n) of one run (the SSE2 path stores only slots). */
NNPS_INLINE void fill_hits(const int dim, const double *const *x, const double *q,
                           const size_t *slot, size_t n0, size_t n, double *const *dx, double *r2)
{
    for (size_t k = n0; k < n; ++k) {
        const size_t s = slot[k];
        double d0 = q[0] - x[0][s], rr = d0 * d0;
        if (dx) dx[0][k] = d0;
        if (dim > 1) {
            double d1 = q[1] - x[1][s];
            rr += d1 * d1;
            if (dx) dx[1][k] = d1;
        }
        if (dim > 2) {
            double d2 = q[2] - x[2][s];
            rr += d2 * d2;
            if (dx) dx[2][k] = d2;
        }
        if (r2) r2[k] = rr;
    }
}

NNPS_INLINE size_t scan_c(const int dim, const double *const *x, const double *q, double r2max,
                          size_t s0, size_t s1, size_t *slot, double *const *dx, double *r2,
                          size_t n)
{
    for (size_t s = s0; s < s1; ++s) {
        double d0 = q[0] - x[0][s], rr = d0 * d0;
        if (dx) dx[0][n] = d0;
        if (dim > 1) {
            double d1 = q[1] - x[1][s];
            rr += d1 * d1;
            if (dx) dx[1][n] = d1;
        }
        if (dim > 2) {
            double d2 = q[2] - x[2][s];
            rr += d2 * d2;
            if (dx) dx[2][n] = d2;
        }
        slot[n] = s;
        if (r2) r2[n] = rr;
        n += rr < r2max;
    }
    return n;
}

#ifdef NNPS_SSE2
NNPS_INLINE size_t scan_sse2(const int dim, const double *const *x, const double *q, double r2max,
                             size_t s0, size_t s1, size_t *slot, size_t n)
{
    const __m128d lim = _mm_set1_pd(r2max), q0 = _mm_set1_pd(q[0]);
    const __m128d q1 = _mm_set1_pd(dim > 1 ? q[1] : 0.0), q2 = _mm_set1_pd(dim > 2 ? q[2] : 0.0);
    const double *x0 = x[0], *x1 = x[1], *x2 = x[2];
    for (size_t s = s0; s < s1; s += 4) {
        __m128d a = _mm_sub_pd(q0, _mm_loadu_pd(x0 + s));
        __m128d b = _mm_sub_pd(q0, _mm_loadu_pd(x0 + s + 2));
        __m128d ra = _mm_mul_pd(a, a), rb = _mm_mul_pd(b, b);
        if (dim > 1) {
            a = _mm_sub_pd(q1, _mm_loadu_pd(x1 + s));
            b = _mm_sub_pd(q1, _mm_loadu_pd(x1 + s + 2));
            ra = _mm_add_pd(ra, _mm_mul_pd(a, a));
            rb = _mm_add_pd(rb, _mm_mul_pd(b, b));
        }
        if (dim > 2) {
            a = _mm_sub_pd(q2, _mm_loadu_pd(x2 + s));
            b = _mm_sub_pd(q2, _mm_loadu_pd(x2 + s + 2));
            ra = _mm_add_pd(ra, _mm_mul_pd(a, a));
            rb = _mm_add_pd(rb, _mm_mul_pd(b, b));
        }
        int m =
            (_mm_movemask_pd(_mm_cmplt_pd(ra, lim)) | _mm_movemask_pd(_mm_cmplt_pd(rb, lim)) << 2) &
            lanes_before(s, s1);
        const unsigned char *pos = hit_pos[m];
        slot[n] = s + pos[0];
        slot[n + 1] = s + pos[1];
        slot[n + 2] = s + pos[2];
        slot[n + 3] = s + pos[3];
        n += hit_count[m];
    }
    return n;
}
#endif

/* One implementation over a list of runs, for a dimension known at compile time. */
NNPS_INLINE size_t gather_runs(const int isa, const int dim, const consph_nnps_slots *v,
                               const consph_nnps_run *run, size_t nruns, const double *xi,
                               size_t *slot, double *const *dx, double *r, size_t n)
{
    for (size_t k = 0; k < nruns; ++k) {
        double q[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        for (int a = 0; a < dim; ++a) q[a] = xi[a] - run[k].shift[a];
        const size_t n0 = n;
#ifdef NNPS_SSE2
        if (isa == NNPS_ISA_SSE2) {
            n = scan_sse2(dim, v->x, q, v->radius2, run[k].s0, run[k].s1, slot, n);
            if (dx || r) fill_hits(dim, v->x, q, slot, n0, n, dx, r);
            continue;
        }
#endif
        (void)n0;
        (void)isa;
        n = scan_c(dim, v->x, q, v->radius2, run[k].s0, run[k].s1, slot, dx, r, n);
    }
    return n;
}

const int32_t nnps_hit_permute[16][8] = {
    {0, 1, 2, 3, 4, 5, 6, 7}, {0, 1, 2, 3, 4, 5, 6, 7}, {2, 3, 0, 1, 4, 5, 6, 7},
    {0, 1, 2, 3, 4, 5, 6, 7}, {4, 5, 0, 1, 2, 3, 6, 7}, {0, 1, 4, 5, 2, 3, 6, 7},
    {2, 3, 4, 5, 0, 1, 6, 7}, {0, 1, 2, 3, 4, 5, 6, 7}, {6, 7, 0, 1, 2, 3, 4, 5},
    {0, 1, 6, 7, 2, 3, 4, 5}, {2, 3, 6, 7, 0, 1, 4, 5}, {0, 1, 2, 3, 6, 7, 4, 5},
    {4, 5, 6, 7, 0, 1, 2, 3}, {0, 1, 4, 5, 6, 7, 2, 3}, {2, 3, 4, 5, 6, 7, 0, 1},
    {0, 1, 2, 3, 4, 5, 6, 7}};

#ifdef NNPS_AVX2
__attribute__((target("avx2"))) static inline __m256i compress(__m256i v, __m256i perm)
{
    return _mm256_permutevar8x32_epi32(v, perm);
}

#define AVX2_STORE(dst, v, perm)                                                                   \
    _mm256_storeu_si256((__m256i *)(dst), compress(_mm256_castpd_si256(v), perm))

/* Where a block's hits go. The pointers are copied into locals: the vector stores may alias
 * anything, so pointers read through a structure would be reloaded after every store. */
typedef struct avx2_out {
    size_t *slot;
    double *r, *d0, *d1, *d2;
} avx2_out;

/* One block of four slots from s (their slot numbers in sl): tests them, keeps the lanes in
 * `valid` and appends the hits' slots, r² and, with_dx, x_ij compressed to the front. */
__attribute__((target("avx2"), always_inline)) static inline size_t
avx2_block(const int dim, const int with_dx, const double *x0, const double *x1, const double *x2,
           __m256d q0, __m256d q1, __m256d q2, __m256d lim, size_t s, __m256i sl, int valid,
           avx2_out o, size_t n)
{
    __m256d d0 = _mm256_sub_pd(q0, _mm256_loadu_pd(x0 + s)), d1 = d0, d2 = d0;
    __m256d rr = _mm256_mul_pd(d0, d0);
    if (dim > 1) {
        d1 = _mm256_sub_pd(q1, _mm256_loadu_pd(x1 + s));
        rr = _mm256_add_pd(rr, _mm256_mul_pd(d1, d1));
    }
    if (dim > 2) {
        d2 = _mm256_sub_pd(q2, _mm256_loadu_pd(x2 + s));
        rr = _mm256_add_pd(rr, _mm256_mul_pd(d2, d2));
    }
    int m = _mm256_movemask_pd(_mm256_cmp_pd(rr, lim, _CMP_LT_OQ));
    if (valid != 15) m &= valid;
    const __m256i perm = _mm256_loadu_si256((const __m256i *)nnps_hit_permute[m]);
    _mm256_storeu_si256((__m256i *)(o.slot + n), compress(sl, perm));
    AVX2_STORE(o.r + n, rr, perm);
    if (with_dx) {
        AVX2_STORE(o.d0 + n, d0, perm);
        if (dim > 1) AVX2_STORE(o.d1 + n, d1, perm);
        if (dim > 2) AVX2_STORE(o.d2 + n, d2, perm);
    }
    return n + hit_count[m];
}

/* r is required (it holds r² until the square roots at the end); without it the dispatcher
 * takes the SSE2 path. */
__attribute__((target("avx2"), always_inline)) static inline size_t
gather_avx2(const int dim, const int with_dx, const consph_nnps_slots *v,
            const consph_nnps_run *run, size_t nruns, const double *xi, size_t *slot,
            double *const *dx, double *r, size_t n)
{
    const __m256d lim = _mm256_set1_pd(v->radius2);
    const __m256i lanes = _mm256_set_epi64x(3, 2, 1, 0), four = _mm256_set1_epi64x(4);
    const double *x0 = v->x[0], *x1 = v->x[1], *x2 = v->x[2];
    avx2_out o = {slot, r, NULL, NULL, NULL};
    if (with_dx) {
        o.d0 = dx[0];
        o.d1 = dim > 1 ? dx[1] : NULL;
        o.d2 = dim > 2 ? dx[2] : NULL;
    }
    const size_t n_first = n;
    for (size_t k = 0; k < nruns; ++k) {
        const size_t s0 = run[k].s0, s1 = run[k].s1, full = s0 + ((s1 - s0) & ~(size_t)3);
        const __m256d q0 = _mm256_set1_pd(xi[0] - run[k].shift[0]);
        const __m256d q1 = _mm256_set1_pd(dim > 1 ? xi[1] - run[k].shift[1] : 0.0);
        const __m256d q2 = _mm256_set1_pd(dim > 2 ? xi[2] - run[k].shift[2] : 0.0);
        /* The slot numbers of the block's lanes, advanced by four per block. */
        __m256i sl = _mm256_add_epi64(_mm256_set1_epi64x((long long)s0), lanes);
        size_t s = s0;
        for (; s < full; s += 4) {
            n = avx2_block(dim, with_dx, x0, x1, x2, q0, q1, q2, lim, s, sl, 15, o, n);
            sl = _mm256_add_epi64(sl, four);
        }
        if (s < s1)
            n = avx2_block(dim, with_dx, x0, x1, x2, q0, q1, q2, lim, s, sl, lanes_before(s, s1), o,
                           n);
    }
    size_t k = n_first;
    for (; k + 4 <= n; k += 4) _mm256_storeu_pd(r + k, _mm256_sqrt_pd(_mm256_loadu_pd(r + k)));
    for (; k < n; ++k) _mm_store_sd(r + k, _mm_sqrt_sd(_mm_setzero_pd(), _mm_load_sd(r + k)));
    return n;
}

/* One function per dimension and per wanted output, so that each loop is straight-line. */
#define GATHER_AVX2(D, DX)                                                                         \
    __attribute__((target("avx2"))) static size_t gather_avx2_##D##_##DX(                          \
        const consph_nnps_slots *v, const consph_nnps_run *run, size_t nruns, const double *xi,    \
        size_t *slot, double *const *dx, double *r, size_t n)                                      \
    {                                                                                              \
        return gather_avx2(D, DX, v, run, nruns, xi, slot, dx, r, n);                              \
    }
GATHER_AVX2(1, 0)
GATHER_AVX2(1, 1)
GATHER_AVX2(2, 0)
GATHER_AVX2(2, 1)
GATHER_AVX2(3, 0)
GATHER_AVX2(3, 1)
#endif

int nnps_best_isa(void)
{
#ifdef NNPS_AVX2
    if (__builtin_cpu_supports("avx2")) return NNPS_ISA_AVX2;
#endif
#ifdef NNPS_SSE2
    return NNPS_ISA_SSE2;
#else
    return NNPS_ISA_C;
#endif
}

/* r = sqrt(r²) in place; packed square roots are correctly rounded like sqrt(). */
static void square_roots(double *r, size_t n0, size_t n)
{
    size_t k = n0;
#ifdef NNPS_SSE2
    for (; k + 2 <= n; k += 2) _mm_storeu_pd(r + k, _mm_sqrt_pd(_mm_loadu_pd(r + k)));
#endif
    for (; k < n; ++k) r[k] = sqrt(r[k]);
}

size_t nnps_gather_runs(int isa, const consph_nnps_slots *v, const consph_nnps_run *run,
                        size_t nruns, const double *xi, size_t *slot, double *const *dx, double *r,
                        size_t n)
{
    const size_t n0 = n;
#ifdef NNPS_AVX2
    if (isa == NNPS_ISA_AVX2 && r) {
        if (v->dim == 1)
            return dx ? gather_avx2_1_1(v, run, nruns, xi, slot, dx, r, n)
                      : gather_avx2_1_0(v, run, nruns, xi, slot, dx, r, n);
        if (v->dim == 2)
            return dx ? gather_avx2_2_1(v, run, nruns, xi, slot, dx, r, n)
                      : gather_avx2_2_0(v, run, nruns, xi, slot, dx, r, n);
        return dx ? gather_avx2_3_1(v, run, nruns, xi, slot, dx, r, n)
                  : gather_avx2_3_0(v, run, nruns, xi, slot, dx, r, n);
    }
#endif
#ifdef NNPS_SSE2
    if (isa != NNPS_ISA_C) isa = NNPS_ISA_SSE2;
#endif
    if (isa == NNPS_ISA_C) {
        if (v->dim == 1)
            n = gather_runs(NNPS_ISA_C, 1, v, run, nruns, xi, slot, dx, r, n);
        else if (v->dim == 2)
            n = gather_runs(NNPS_ISA_C, 2, v, run, nruns, xi, slot, dx, r, n);
        else
            n = gather_runs(NNPS_ISA_C, 3, v, run, nruns, xi, slot, dx, r, n);
    } else {
        if (v->dim == 1)
            n = gather_runs(NNPS_ISA_SSE2, 1, v, run, nruns, xi, slot, dx, r, n);
        else if (v->dim == 2)
            n = gather_runs(NNPS_ISA_SSE2, 2, v, run, nruns, xi, slot, dx, r, n);
        else
            n = gather_runs(NNPS_ISA_SSE2, 3, v, run, nruns, xi, slot, dx, r, n);
    }
    if (r) square_roots(r, n0, n);
    return n;
}

size_t consph_nnps_gather(const consph_nnps_slots *v, const consph_nnps_runs *runs,
                          const double *xi, size_t *slot, double *const *dx, double *r)
{
    return nnps_gather_runs(nnps_best_isa(), v, runs->run, runs->n, xi, slot, dx, r, 0);
}
