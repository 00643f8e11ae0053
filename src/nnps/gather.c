/* The hit test of the inline traversal over whole runs: consph_nnps_gather and the query's scan.
 *
 * Four implementations give the same hits, order and values bit for bit (the same separations
 * q - x, squared distance summed from axis 0 up without fused multiply-adds, ordered compare,
 * correctly rounded square root):
 *  - portable C: a branchless loop that writes every candidate and advances only on a hit;
 *  - SSE2 (baseline x86-64): four candidates per step; the hits' slots are stored through a
 *    table of positions by hit mask, their x_ij and r² recomputed per hit;
 *  - AVX2, chosen at run time: four candidates per vector, and slots, x_ij and r² compressed
 *    with one permutation per vector, so nothing is recomputed;
 *  - AVX-512 (F), chosen at run time before AVX2: eight candidates per vector, moved to the
 *    front by the lane numbers that the compare's mask register compresses (no table); a run's
 *    last block is a masked load and store. Four particles of a cell can share one sweep
 *    (nnps_gather4).
 * The SSE2 and AVX2 paths read whole blocks of four slots; the coordinate arrays carry
 * CONSPH_NNPS_GATHER_SLACK padding entries, blocks past a run's end are masked, and the output
 * arrays take up to that many entries past the count (AVX-512 needs neither).
 * No fused multiply-add: the SSE2 and AVX2 targets have none, and the AVX-512 one, which has,
 * passes its products through square_unfused. */
#include "nnps_internal.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__x86_64__) && defined(__SSE2__)
#include <emmintrin.h>
#define NNPS_SSE2 1
#if defined(__GNUC__)
#include <immintrin.h>
#define NNPS_AVX2 1
/* AVX-512 intrinsics under a target attribute: GCC 7 and clang 8 have every one used here; the
 * slots are stored as 64-bit lanes. */
#if (defined(__clang__) ? __clang_major__ >= 8 : __GNUC__ >= 7) && __SIZEOF_SIZE_T__ == 8
#define NNPS_AVX512 1
#endif
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

#ifdef NNPS_SSE2
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
#endif

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

/* The outputs of a gather: slots and r always, x_ij per axis with with_dx. */
static inline avx2_out gather_out(const int dim, const int with_dx, size_t *slot, double *const *dx,
                                  double *r)
{
    avx2_out o = {slot, r, NULL, NULL, NULL};
    if (with_dx) {
        o.d0 = dx[0];
        o.d1 = dim > 1 ? dx[1] : NULL;
        o.d2 = dim > 2 ? dx[2] : NULL;
    }
    return o;
}

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
    const avx2_out o = gather_out(dim, with_dx, slot, dx, r);
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

#ifdef NNPS_AVX512
/* Every AVX-512 processor has POPCNT; the mask's hit count is one instruction. */
#define NNPS_AVX512_TARGET target("avx512f,popcnt")

/* d * d, kept apart from the sum it joins: the AVX-512 target makes FMA available, and a fused
 * multiply-add rounds once where the other paths round twice. The ISO C build (-std=c11)
 * already keeps GCC from contracting; the empty asm keeps the bits under any -ffp-contract. */
__attribute__((NNPS_AVX512_TARGET, always_inline)) static inline __m512d square_unfused(__m512d d)
{
    __m512d p = _mm512_mul_pd(d, d);
    __asm__("" : "+v"(p));
    return p;
}

/* Lane mask of the lanes of an 8-wide block that lie before the run's end. */
static inline __mmask8 lanes_before8(size_t s, size_t s1)
{
    const size_t left = s1 - s;
    return left >= 8 ? (__mmask8)0xff : (__mmask8)((1u << left) - 1);
}

/* One block of eight slots from s (sl: s in every lane; c0..c2: the candidates' coordinates):
 * avx2_block's operations in eight lanes, the hits moved to the front by the compare's own mask
 * (the lane numbers compressed into a register, then each output permuted and stored; the
 * memory form of a compress made the gather 7 times slower on AMD Zen 4). A full block reads
 * slots s..s+7 of
 * its run and stores eight entries from n; as n has advanced by at most the candidates before
 * the block, those stores end within the candidates' room. The run's last, partial block (tail)
 * loads only its `valid` lanes and stores only its hits, so it needs no padding and no slack at
 * all. */
__attribute__((NNPS_AVX512_TARGET, always_inline)) static inline size_t
avx512_hits(const int dim, const int with_dx, const int with_r, const int tail, __m512d c0,
            __m512d c1, __m512d c2, __m512d q0, __m512d q1, __m512d q2, __m512d lim, __m512i sl,
            __m512i lanes, __mmask8 valid, const size_t *map, avx2_out o, size_t n)
{
    __m512d d0 = _mm512_sub_pd(q0, c0), d1 = d0, d2 = d0;
    __m512d rr = square_unfused(d0);
    if (dim > 1) {
        d1 = _mm512_sub_pd(q1, c1);
        rr = _mm512_add_pd(rr, square_unfused(d1));
    }
    if (dim > 2) {
        d2 = _mm512_sub_pd(q2, c2);
        rr = _mm512_add_pd(rr, square_unfused(d2));
    }
    const __mmask8 m = tail ? _mm512_mask_cmp_pd_mask(valid, rr, lim, _CMP_LT_OQ)
                            : _mm512_cmp_pd_mask(rr, lim, _CMP_LT_OQ);
    const unsigned hits = (unsigned)__builtin_popcount(m);
    const __mmask8 keep = (__mmask8)((1u << hits) - 1);
    /* The hits' lane numbers in order, once; each output is then one permutation (one uop)
     * instead of a compress (two, and the bottleneck of the loop). Lanes past the hits hold
     * lane 0's values where the compress held zeros: stored past n, never handed out. */
    const __m512i idx = _mm512_maskz_compress_epi64(m, lanes);
#define AVX512_STORE(dst, v)                                                                       \
    do {                                                                                           \
        if (tail)                                                                                  \
            _mm512_mask_storeu_pd((dst), keep, _mm512_permutexvar_pd(idx, (v)));                   \
        else                                                                                       \
            _mm512_storeu_pd((dst), _mm512_permutexvar_pd(idx, (v)));                              \
    } while (0)
    /* map (the block's slots' particles, map[0] the first's): each hit's particle, permuted
     * as its other outputs */
    const __m512i id = !map   ? _mm512_add_epi64(sl, idx)
                       : tail ? _mm512_permutexvar_epi64(idx, _mm512_maskz_loadu_epi64(valid, map))
                              : _mm512_permutexvar_epi64(idx, _mm512_loadu_si512(map));
    if (tail)
        _mm512_mask_storeu_epi64(o.slot + n, keep, id);
    else
        _mm512_storeu_si512(o.slot + n, id);
    if (with_r) AVX512_STORE(o.r + n, rr);
    if (with_dx) {
        AVX512_STORE(o.d0 + n, d0);
        if (dim > 1) AVX512_STORE(o.d1 + n, d1);
        if (dim > 2) AVX512_STORE(o.d2 + n, d2);
    }
#undef AVX512_STORE
    return n + hits;
}

/* The candidates' coordinates of the block from s (a tail block: its `valid` lanes, the others
 * zero), for avx512_hits. */
#define AVX512_LOAD(p) (tail ? _mm512_maskz_loadu_pd(valid, (p)) : _mm512_loadu_pd(p))
#define AVX512_COORDS(c0, c1, c2)                                                                  \
    const __m512d c0 = AVX512_LOAD(x0 + s);                                                        \
    const __m512d c1 = dim > 1 ? AVX512_LOAD(x1 + s) : c0;                                         \
    const __m512d c2 = dim > 2 ? AVX512_LOAD(x2 + s) : c0

__attribute__((NNPS_AVX512_TARGET, always_inline)) static inline size_t
avx512_block(const int dim, const int with_dx, const int with_r, const int tail, const double *x0,
             const double *x1, const double *x2, __m512d q0, __m512d q1, __m512d q2, __m512d lim,
             size_t s, __m512i sl, __m512i lanes, __mmask8 valid, const size_t *map, avx2_out o,
             size_t n)
{
    AVX512_COORDS(c0, c1, c2);
    return avx512_hits(dim, with_dx, with_r, tail, c0, c1, c2, q0, q1, q2, lim, sl, lanes, valid,
                       map ? map + s : NULL, o, n);
}

/* r = sqrt(r²) for entries n0..n. */
__attribute__((NNPS_AVX512_TARGET, always_inline)) static inline void
avx512_roots(double *r, size_t n0, size_t n)
{
    size_t k = n0;
    for (; k + 8 <= n; k += 8) _mm512_storeu_pd(r + k, _mm512_sqrt_pd(_mm512_loadu_pd(r + k)));
    if (k < n) {
        const __mmask8 left = lanes_before8(k, n);
        _mm512_mask_storeu_pd(r + k, left, _mm512_sqrt_pd(_mm512_maskz_loadu_pd(left, r + k)));
    }
}

/* gather_avx2 in blocks of eight; r is optional here (the slots alone count neighbours). With
 * with_map (a compile-time choice), each hit's particle (the search's slot -> particle map)
 * instead of its slot. */
__attribute__((NNPS_AVX512_TARGET, always_inline)) static inline size_t
gather_avx512(const int dim, const int with_dx, const int with_r, const int with_map,
              const consph_nnps_slots *v, const consph_nnps_run *run, size_t nruns,
              const double *xi, size_t *slot, double *const *dx, double *r, size_t n)
{
    const size_t *map = with_map ? v->particle : NULL;
    const __m512d lim = _mm512_set1_pd(v->radius2);
    const __m512i lanes = _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0), eight = _mm512_set1_epi64(8);
    const double *x0 = v->x[0], *x1 = v->x[1], *x2 = v->x[2];
    const avx2_out o = gather_out(dim, with_dx, slot, dx, r);
    const size_t n_first = n;
    for (size_t k = 0; k < nruns; ++k) {
        const size_t s0 = run[k].s0, s1 = run[k].s1, full = s0 + ((s1 - s0) & ~(size_t)7);
        const __m512d q0 = _mm512_set1_pd(xi[0] - run[k].shift[0]);
        const __m512d q1 = _mm512_set1_pd(dim > 1 ? xi[1] - run[k].shift[1] : 0.0);
        const __m512d q2 = _mm512_set1_pd(dim > 2 ? xi[2] - run[k].shift[2] : 0.0);
        /* s in every lane: a hit's slot is s plus its lane */
        __m512i sl = _mm512_set1_epi64((long long)s0);
        size_t s = s0;
        for (; s < full; s += 8) {
            n = avx512_block(dim, with_dx, with_r, 0, x0, x1, x2, q0, q1, q2, lim, s, sl, lanes,
                             0xff, map, o, n);
            sl = _mm512_add_epi64(sl, eight);
        }
        if (s < s1)
            n = avx512_block(dim, with_dx, with_r, 1, x0, x1, x2, q0, q1, q2, lim, s, sl, lanes,
                             lanes_before8(s, s1), map, o, n);
    }
    if (with_r) avx512_roots(r, n_first, n);
    return n;
}

/* One function per dimension and per wanted output (x_ij, r), as for AVX2. */
#define GATHER_AVX512(D, DX, R)                                                                    \
    __attribute__((NNPS_AVX512_TARGET)) static size_t gather_avx512_##D##_##DX##R(                 \
        const consph_nnps_slots *v, const consph_nnps_run *run, size_t nruns, const double *xi,    \
        size_t *slot, double *const *dx, double *r, size_t n)                                      \
    {                                                                                              \
        return gather_avx512(D, DX, R, 0, v, run, nruns, xi, slot, dx, r, n);                      \
    }
#define GATHER_AVX512_DIM(D)                                                                       \
    GATHER_AVX512(D, 0, 0)                                                                         \
    GATHER_AVX512(D, 0, 1)                                                                         \
    GATHER_AVX512(D, 1, 0)                                                                         \
    GATHER_AVX512(D, 1, 1)
GATHER_AVX512_DIM(1)
GATHER_AVX512_DIM(2)
GATHER_AVX512_DIM(3)

/* The same with each hit's particle for its slot, x_ij and r wanted (nnps_gather_particles). */
#define GATHER_AVX512_MAP(D)                                                                       \
    __attribute__((NNPS_AVX512_TARGET)) static size_t gather_avx512_map_##D(                       \
        const consph_nnps_slots *v, const consph_nnps_run *run, size_t nruns, const double *xi,    \
        size_t *particle, double *const *dx, double *r)                                            \
    {                                                                                              \
        return gather_avx512(D, 1, 1, 1, v, run, nruns, xi, particle, dx, r, 0);                   \
    }
GATHER_AVX512_MAP(1)
GATHER_AVX512_MAP(2)
GATHER_AVX512_MAP(3)

typedef size_t (*gather_fn)(const consph_nnps_slots *, const consph_nnps_run *, size_t,
                            const double *, size_t *, double *const *, double *, size_t);
/* [dim - 1][x_ij wanted][r wanted] */
static const gather_fn gather_avx512_table[3][2][2] = {
    {{gather_avx512_1_00, gather_avx512_1_01}, {gather_avx512_1_10, gather_avx512_1_11}},
    {{gather_avx512_2_00, gather_avx512_2_01}, {gather_avx512_2_10, gather_avx512_2_11}},
    {{gather_avx512_3_00, gather_avx512_3_01}, {gather_avx512_3_10, gather_avx512_3_11}}};

/* nnps_gather4: gather_avx512's blocks with one load of the candidates for four points. The
 * lanes' counts and output pointers are kept in locals (see gather_out). */
__attribute__((NNPS_AVX512_TARGET, always_inline)) static inline void
gather4_avx512(const int dim, const int with_dx, const consph_nnps_slots *v,
               const consph_nnps_run *run, size_t nruns, size_t sl, const avx2_out *out,
               size_t *count)
{
    const __m512d lim = _mm512_set1_pd(v->radius2);
    const __m512i lanes = _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0), eight = _mm512_set1_epi64(8);
    const double *x0 = v->x[0], *x1 = v->x[1], *x2 = v->x[2];
    const avx2_out o0 = out[0], o1 = out[1], o2 = out[2], o3 = out[3];
    size_t n0 = 0, n1 = 0, n2 = 0, n3 = 0;
    for (size_t k = 0; k < nruns; ++k) {
        const size_t s0 = run[k].s0, s1 = run[k].s1, full = s0 + ((s1 - s0) & ~(size_t)7);
        /* gather_avx512's q = xi - shift, with xi the slot's coordinates as nbhd_gather takes */
#define Q(l, a) _mm512_set1_pd(dim > (a) ? v->x[a][sl + (l)] - run[k].shift[a] : 0.0)
        const __m512d q00 = Q(0, 0), q01 = Q(0, 1), q02 = Q(0, 2);
        const __m512d q10 = Q(1, 0), q11 = Q(1, 1), q12 = Q(1, 2);
        const __m512d q20 = Q(2, 0), q21 = Q(2, 1), q22 = Q(2, 2);
        const __m512d q30 = Q(3, 0), q31 = Q(3, 1), q32 = Q(3, 2);
#undef Q
#define HITS4(tail)                                                                                \
    do {                                                                                           \
        AVX512_COORDS(c0, c1, c2);                                                                 \
        n0 = avx512_hits(dim, with_dx, 1, tail, c0, c1, c2, q00, q01, q02, lim, sv, lanes, valid,  \
                         NULL, o0, n0);                                                            \
        n1 = avx512_hits(dim, with_dx, 1, tail, c0, c1, c2, q10, q11, q12, lim, sv, lanes, valid,  \
                         NULL, o1, n1);                                                            \
        n2 = avx512_hits(dim, with_dx, 1, tail, c0, c1, c2, q20, q21, q22, lim, sv, lanes, valid,  \
                         NULL, o2, n2);                                                            \
        n3 = avx512_hits(dim, with_dx, 1, tail, c0, c1, c2, q30, q31, q32, lim, sv, lanes, valid,  \
                         NULL, o3, n3);                                                            \
    } while (0)
        __m512i sv = _mm512_set1_epi64((long long)s0);
        size_t s = s0;
        for (; s < full; s += 8) {
            const int tail = 0;
            const __mmask8 valid = 0xff;
            HITS4(tail);
            sv = _mm512_add_epi64(sv, eight);
        }
        if (s < s1) {
            const int tail = 1;
            const __mmask8 valid = lanes_before8(s, s1);
            HITS4(tail);
        }
#undef HITS4
    }
    avx512_roots(o0.r, 0, n0);
    avx512_roots(o1.r, 0, n1);
    avx512_roots(o2.r, 0, n2);
    avx512_roots(o3.r, 0, n3);
    count[0] = n0;
    count[1] = n1;
    count[2] = n2;
    count[3] = n3;
}

#define GATHER4_AVX512(D, DX)                                                                      \
    __attribute__((NNPS_AVX512_TARGET)) static void gather4_avx512_##D##_##DX(                     \
        const consph_nnps_slots *v, const consph_nnps_run *run, size_t nruns, size_t sl,           \
        const avx2_out *out, size_t *count)                                                        \
    {                                                                                              \
        gather4_avx512(D, DX, v, run, nruns, sl, out, count);                                      \
    }
GATHER4_AVX512(1, 0)
GATHER4_AVX512(1, 1)
GATHER4_AVX512(2, 0)
GATHER4_AVX512(2, 1)
GATHER4_AVX512(3, 0)
GATHER4_AVX512(3, 1)

typedef void (*gather4_fn)(const consph_nnps_slots *, const consph_nnps_run *, size_t, size_t,
                           const avx2_out *, size_t *);
/* [dim - 1][x_ij wanted] */
static const gather4_fn gather4_avx512_table[3][2] = {{gather4_avx512_1_0, gather4_avx512_1_1},
                                                      {gather4_avx512_2_0, gather4_avx512_2_1},
                                                      {gather4_avx512_3_0, gather4_avx512_3_1}};
#endif

int nnps_machine_isa(void)
{
#ifdef NNPS_AVX512
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("popcnt"))
        return NNPS_ISA_AVX512;
#endif
#ifdef NNPS_AVX2
    if (__builtin_cpu_supports("avx2")) return NNPS_ISA_AVX2;
#endif
#ifdef NNPS_SSE2
    return NNPS_ISA_SSE2;
#else
    return NNPS_ISA_C;
#endif
}

#if defined(__GNUC__)
/* nnps_best_isa's answer, fixed before main (a library's constructor runs at load) so that the
 * per-gather call is a load. CONSPH_GATHER_ISA=c|sse2|avx2|avx512 caps it, to time one
 * implementation against another with one binary; every one gives the same bits. */
static int chosen_isa = NNPS_ISA_C;

__attribute__((constructor)) static void choose_isa(void)
{
#ifdef NNPS_SSE2
    __builtin_cpu_init();
#endif
    int isa = nnps_machine_isa();
    const char *cap = getenv("CONSPH_GATHER_ISA");
    if (cap && *cap) {
        static const char *const names[] = {"c", "sse2", "avx2", "avx512"};
        int k = 0;
        while (k < 4 && strcmp(cap, names[k]) != 0) ++k;
        if (k == 4)
            fprintf(stderr,
                    "consph: CONSPH_GATHER_ISA='%s' ignored: allowed values are c, sse2, avx2 "
                    "and avx512\n",
                    cap);
        else if (k < isa)
            isa = k;
    }
    chosen_isa = isa;
}

int nnps_best_isa(void)
{
    return chosen_isa;
}
#else
int nnps_best_isa(void)
{
    return nnps_machine_isa();
}
#endif

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
#ifdef NNPS_AVX512
    if (isa == NNPS_ISA_AVX512)
        return gather_avx512_table[v->dim - 1][dx != NULL][r != NULL](v, run, nruns, xi, slot, dx,
                                                                      r, n);
#endif
#ifdef NNPS_AVX2
    if (isa >= NNPS_ISA_AVX2 && r) {
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

int nnps_gather4(const consph_nnps_slots *v, const consph_nnps_run *run, size_t nruns, size_t sl,
                 size_t *const slot[4], double *const *const dx[4], double *const r[4], size_t n[4])
{
#ifdef NNPS_AVX512
    if (nnps_best_isa() == NNPS_ISA_AVX512) {
        const int with_dx = dx[0] != NULL;
        avx2_out out[4];
        for (int l = 0; l < 4; ++l) out[l] = gather_out(v->dim, with_dx, slot[l], dx[l], r[l]);
        gather4_avx512_table[v->dim - 1][with_dx](v, run, nruns, sl, out, n);
        return 1;
    }
#else
    (void)v, (void)run, (void)nruns, (void)sl, (void)slot, (void)dx, (void)r, (void)n;
#endif
    return 0;
}

size_t nnps_gather_particles(const consph_nnps_slots *v, const consph_nnps_runs *runs,
                             const double *xi, size_t *slot, size_t *particle, double *const *dx,
                             double *r)
{
#ifdef NNPS_AVX512
    if (v->particle && nnps_best_isa() == NNPS_ISA_AVX512) {
        if (v->dim == 1) return gather_avx512_map_1(v, runs->run, runs->n, xi, particle, dx, r);
        if (v->dim == 2) return gather_avx512_map_2(v, runs->run, runs->n, xi, particle, dx, r);
        return gather_avx512_map_3(v, runs->run, runs->n, xi, particle, dx, r);
    }
#endif
    if (!v->particle) return consph_nnps_gather(v, runs, xi, particle, dx, r);
    const size_t m = consph_nnps_gather(v, runs, xi, slot, dx, r);
    for (size_t k = 0; k < m; ++k) particle[k] = v->particle[slot[k]];
    return m;
}

size_t consph_nnps_gather(const consph_nnps_slots *v, const consph_nnps_runs *runs,
                          const double *xi, size_t *slot, double *const *dx, double *r)
{
    return nnps_gather_runs(nnps_best_isa(), v, runs->run, runs->n, xi, slot, dx, r, 0);
}
