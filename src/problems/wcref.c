/* The weakly-compressible reference (wcref.h): a pseudo-spectral solve of the equations the SPH
 * schemes discretise, so that a run's error can be taken against the solution of its own
 * continuum model rather than the incompressible one, which it misses at O(Ma²).
 *
 * Unknowns: the Fourier coefficients of ρ' = ρ - ρ_o, u and v on an n × n grid; a product is
 * formed on the grid and every coefficient with |k_x| or |k_y| above n/3 is dropped (Orszag's
 * 2/3 rule). The mass equation is written in conservation form, ∂ρ'/∂t = -ρ_o ∇·u - ∇·(ρ'u), so
 * the mean density is kept to round-off, and the pressure force as the gradient of the enthalpy,
 * ∇p/ρ = ∇h(ρ) (Tait: h = c_o²/(γ-1) ((ρ/ρ_o)^(γ-1) - 1); linear: h = c_o² ln(ρ/ρ_o)), which
 * holds for any barotropic p(ρ).
 *
 * In time: the linear acoustic operator L (ρ̂' = -iρ_o k·û, û = -i k c_o² ρ̂'/ρ_o) is a rotation
 * of each mode's (c_o ρ̂'/ρ_o, k·û/|k|) by the angle c_o |k| t, applied exactly; the rest (the
 * nonlinear terms, h - c_o²ρ'/ρ_o and ν∇²u) goes through Lawson's integrating-factor RK4. The
 * step is then bounded by the advective and viscous rates, not by c_o. */
#include "problems/wcref.h"

#include <complex.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "consph/core.h"

#ifdef _OPENMP
#include <omp.h>
#endif

enum { NF = 3, NMAX = 256, KMAX = NMAX / 3 };

typedef struct wctraj wctraj;

struct wcref {
    wcref_params p;
    int n, K; /* grid size, the largest kept |k| index */
    size_t nn;
    double t, dt;
    double *kx, *ky, *kk; /* per coefficient: k_x, k_y (2π index/len), |k|² */
    unsigned char *keep;  /* the 2/3 rule */
    double complex *tw;   /* e^{-2πi j/n}, j < n/2 */
    double complex *col;  /* n × n: the transpose of the 2D transform's rows */
    /* per field (ρ', u, v): the initial state, the state, the stages and their scratch */
    double complex *s0[NF], *s[NF], *e[NF], *a[NF], *b[NF], *y[NF], *k[4][NF], *tmp[NF];
    long j;               /* s is the state at t = j dt (the fixed time grid); e that at t */
    double complex *g[7]; /* grid arrays of the right-hand side */
    /* the exact rotations of L over h and h/2, for the h they were made for */
    double *cf, *sf, *ch, *sh, hrot;
    double complex *ret[NF]; /* the kept coefficients, (2K + 1)², for wcref_eval */
    double *ev; /* the rows b >= 0 of ret as wcref_eval's vector loop reads them (eval_layout) */
    wctraj *tr; /* the shared trajectory (NULL: unshared) */
};

/* ---- the process-wide share ----
 *
 * The state at t is a function of the parameters, the initial grid values and t alone
 * (wcref_advance), so references made from the same inputs may take it from one another bit
 * for bit. A trajectory, keyed on every field of wcref_params and every grid value, keeps the
 * furthest whole-step state any of its references reached and the coefficients handed out at
 * each time asked (up to MEMO_BYTES): the rows of a study at one dt ask the same times and
 * step the reference once between them. Each reference still steps its own copy of the state,
 * so a miss costs what it did unshared. Owner: the list below; a trajectory lives while a
 * reference holds it and, unheld, until KEEP_UNHELD newer ones are unheld or
 * wcref_share_clear. Every access is inside the critical section consph_wcref_share. */
enum { KEEP_UNHELD = 4 };
#define MEMO_BYTES ((size_t)16 << 20)

struct wctraj {
    wctraj *next;
    wcref_params p; /* the key: the parameters as given (unshared = 0) */
    double *grid;   /* the key: ρ, u, v at the grid points, 3 n² */
    int refs;
    unsigned long unheld_at; /* when refs fell to 0: the eviction order */
    long j;                  /* s is the state at t = j dt; 0: none yet */
    double complex *s[NF];
    size_t nmemo, capmemo, maxmemo; /* times asked, sorted, with their coefficients */
    double *mt;
    double complex **mret; /* NF blocks of (2K + 1)² each */
};

static wctraj *share_list;
static unsigned long share_hits, share_clock;

static int same_key(const wctraj *tr, const wcref_params *wp, const double *rho, const double *u,
                    const double *v)
{
    const size_t nn = (size_t)wp->n * (size_t)wp->n, b = nn * sizeof(double);
    const wcref_params *a = &tr->p;
    /* field by field, bitwise (padding and 0.0 / -0.0 must not decide) */
    return a->n == wp->n && a->linear == wp->linear && !memcmp(a->lo, wp->lo, sizeof a->lo) &&
           !memcmp(a->len, wp->len, sizeof a->len) && !memcmp(&a->c0, &wp->c0, sizeof a->c0) &&
           !memcmp(&a->rho0, &wp->rho0, sizeof a->rho0) &&
           !memcmp(&a->gamma, &wp->gamma, sizeof a->gamma) &&
           !memcmp(&a->nu, &wp->nu, sizeof a->nu) && !memcmp(&a->dt, &wp->dt, sizeof a->dt) &&
           !memcmp(tr->grid, rho, b) && !memcmp(tr->grid + nn, u, b) &&
           !memcmp(tr->grid + 2 * nn, v, b);
}

static void traj_free(wctraj *tr)
{
    for (size_t e = 0; e < tr->nmemo; ++e) free(tr->mret[e]);
    free(tr->mt);
    free(tr->mret);
    for (int f = 0; f < NF; ++f) free(tr->s[f]);
    free(tr->grid);
    free(tr);
}

/* Frees the unheld trajectories beyond the keep newest ones. */
static void share_trim(int keep)
{
    for (;;) {
        int unheld = 0;
        wctraj **oldest = NULL;
        for (wctraj **q = &share_list; *q; q = &(*q)->next)
            if (!(*q)->refs) {
                ++unheld;
                if (!oldest || (*q)->unheld_at < (*oldest)->unheld_at) oldest = q;
            }
        if (unheld <= keep) return;
        wctraj *tr = *oldest;
        *oldest = tr->next;
        traj_free(tr);
    }
}

/* The trajectory of these inputs, held; a new one if none (NULL when out of memory: the
 * reference then runs unshared). */
static wctraj *share_hold(const wcref_params *wp, const double *rho, const double *u,
                          const double *v, size_t mm)
{
    wctraj *tr = NULL;
#pragma omp critical(consph_wcref_share)
    {
        for (tr = share_list; tr && !same_key(tr, wp, rho, u, v); tr = tr->next) {
        }
        if (!tr) {
            const size_t nn = (size_t)wp->n * (size_t)wp->n;
            tr = calloc(1, sizeof *tr);
            if (tr && (tr->grid = malloc(3 * nn * sizeof(double)))) {
                tr->p = *wp;
                memcpy(tr->grid, rho, nn * sizeof(double));
                memcpy(tr->grid + nn, u, nn * sizeof(double));
                memcpy(tr->grid + 2 * nn, v, nn * sizeof(double));
                tr->maxmemo = MEMO_BYTES / (NF * mm * sizeof(double complex));
                tr->next = share_list;
                share_list = tr;
            } else {
                free(tr);
                tr = NULL;
            }
        }
        if (tr) ++tr->refs;
    }
    return tr;
}

static void share_release(wctraj *tr)
{
#pragma omp critical(consph_wcref_share)
    {
        if (--tr->refs == 0) {
            tr->unheld_at = ++share_clock;
            share_trim(KEEP_UNHELD);
        }
    }
}

/* Index of the first memo time >= t. */
static size_t memo_find(const wctraj *tr, double t)
{
    size_t lo = 0, hi = tr->nmemo;
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2;
        if (tr->mt[mid] < t)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

static size_t ret_count(const wcref *w)
{
    return (size_t)(2 * w->K + 1) * (size_t)(2 * w->K + 1);
}

/* w->ret from the memo if t was asked before: 1, else 0. */
static int share_lookup(wcref *w, double t)
{
    int hit = 0;
    const size_t mm = ret_count(w);
#pragma omp critical(consph_wcref_share)
    {
        const wctraj *tr = w->tr;
        const size_t e = memo_find(tr, t);
        if (e < tr->nmemo && tr->mt[e] == t) {
            for (int f = 0; f < NF; ++f)
                memcpy(w->ret[f], tr->mret[e] + (size_t)f * mm, mm * sizeof(double complex));
            hit = 1;
            ++share_hits;
        }
    }
    return hit;
}

/* Before stepping towards t: the trajectory's state if it is further on than w's and not
 * beyond t (the whole steps w would take itself). */
static void share_adopt(wcref *w, double t)
{
#pragma omp critical(consph_wcref_share)
    {
        const wctraj *tr = w->tr;
        if (tr->j > w->j && (double)tr->j * w->dt <= t) {
            for (int f = 0; f < NF; ++f) memcpy(w->s[f], tr->s[f], w->nn * sizeof(double complex));
            w->j = tr->j;
            ++share_hits;
        }
    }
}

/* After reaching t: w's whole-step state if it is the furthest, and w->ret for t. Out of
 * memory here only leaves the share smaller. */
static void share_publish(wcref *w, double t)
{
    const size_t mm = ret_count(w);
#pragma omp critical(consph_wcref_share)
    {
        wctraj *tr = w->tr;
        if (w->j > tr->j) {
            int ok = 1;
            for (int f = 0; ok && f < NF; ++f)
                ok = tr->s[f] || (tr->s[f] = malloc(w->nn * sizeof(double complex)));
            if (ok) {
                for (int f = 0; f < NF; ++f)
                    memcpy(tr->s[f], w->s[f], w->nn * sizeof(double complex));
                tr->j = w->j;
            }
        }
        const size_t e = memo_find(tr, t);
        if (!(e < tr->nmemo && tr->mt[e] == t) && tr->nmemo < tr->maxmemo) {
            if (tr->nmemo == tr->capmemo) {
                const size_t cap = tr->capmemo ? 2 * tr->capmemo : 64;
                double *mt = realloc(tr->mt, cap * sizeof *mt);
                if (mt) tr->mt = mt;
                double complex **mr = mt ? realloc(tr->mret, cap * sizeof *mr) : NULL;
                if (mr) {
                    tr->mret = mr;
                    tr->capmemo = cap;
                }
            }
            double complex *blk =
                tr->nmemo < tr->capmemo ? malloc(NF * mm * sizeof(double complex)) : NULL;
            if (blk) {
                for (int f = 0; f < NF; ++f)
                    memcpy(blk + (size_t)f * mm, w->ret[f], mm * sizeof(double complex));
                memmove(tr->mt + e + 1, tr->mt + e, (tr->nmemo - e) * sizeof *tr->mt);
                memmove(tr->mret + e + 1, tr->mret + e, (tr->nmemo - e) * sizeof *tr->mret);
                tr->mt[e] = t;
                tr->mret[e] = blk;
                ++tr->nmemo;
            }
        }
    }
}

unsigned long wcref_shared_hits(void)
{
    unsigned long h;
#pragma omp critical(consph_wcref_share)
    h = share_hits;
    return h;
}

void wcref_share_clear(void)
{
#pragma omp critical(consph_wcref_share)
    share_trim(0);
}

/* C11's CMPLX, which glibc's <complex.h> defines for GCC only (clang, e.g. `make fuzz`, finds
 * none): a complex number is laid out as an array of its real and imaginary parts (C11
 * 6.2.5p13), written through a union (re + im·I would turn an infinite im into a NaN). */
#ifndef CMPLX
static inline double complex wcref_cmplx(double re, double im)
{
    union {
        double part[2];
        double complex z;
    } u = {{re, im}};
    return u.z;
}
#define CMPLX(re, im) wcref_cmplx((re), (im))
#endif

/* Products written out: without -ffast-math (results must not depend on it) a complex `*` calls
 * the library's NaN-checking multiply, several times slower in these loops. */
static inline double complex cmul(double complex a, double complex b)
{
    return CMPLX(creal(a) * creal(b) - cimag(a) * cimag(b),
                 creal(a) * cimag(b) + cimag(a) * creal(b));
}

/* i k z */
static inline double complex imul(double k, double complex z)
{
    return CMPLX(-k * cimag(z), k * creal(z));
}

/* ---- a radix-2 FFT of our own (no dependency for a grid this small) ---- */

/* Straight vector loops: a generic x86-64 build also carries an AVX2 copy chosen at load time
 * (the same operations in the same order, hence the same values; no FMA is enabled, so nothing
 * is contracted), as consph_kernel_eval_batch. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__GLIBC__) &&       \
    !defined(__AVX2__)
#define WCREF_CLONES __attribute__((target_clones("avx2", "default")))
#define WCREF_DISPATCH 1
#else
#define WCREF_CLONES
#endif

/* The 1D transform (bit reversal, then in-place butterflies) of every column of the n × n array a
 * (index i + n j, along j) at once: each swap and butterfly is applied to whole rows, so every
 * column goes through the operations, in the order, of its own 1D transform, and the innermost
 * loop runs over contiguous memory. */
WCREF_CLONES static void fft_columns(const wcref *w, double complex *a, int inverse)
{
    const int n = w->n;
    const size_t rn = (size_t)n;
    for (int i = 1, j = 0; i < n; ++i) { /* bit reversal, of rows */
        int bit = n >> 1;
        for (; j & bit; bit >>= 1) j ^= bit;
        j ^= bit;
        if (i < j) {
            double complex *ri = a + (size_t)i * rn, *rj = a + (size_t)j * rn;
            for (size_t c = 0; c < rn; ++c) {
                const double complex t = ri[c];
                ri[c] = rj[c];
                rj[c] = t;
            }
        }
    }
    for (int len = 2; len <= n; len <<= 1) {
        const int half = len >> 1, step = n / len;
        for (int i = 0; i < n; i += len)
            for (int j = 0; j < half; ++j) {
                double complex tw = w->tw[j * step];
                if (inverse) tw = conj(tw);
                double complex *x0 = a + (size_t)(i + j) * rn, *x1 = x0 + (size_t)half * rn;
                for (size_t c = 0; c < rn; ++c) {
                    const double complex v = cmul(x1[c], tw);
                    x1[c] = x0[c] - v;
                    x0[c] += v;
                }
            }
    }
}

/* Forward (coefficients = Σ f e^{-ik·x} / n², kept modes only) or inverse (grid values of the
 * series Σ c e^{ik·x}) 2D transform in place. The row transforms are those of the transpose's
 * columns (fft_columns); a transpose copies values exactly. */
static void fft2(const wcref *w, double complex *a, int inverse)
{
    const size_t n = (size_t)w->n;
    double complex *t = w->col;
    for (size_t j = 0; j < n; ++j)
        for (size_t i = 0; i < n; ++i) t[j + i * n] = a[i + j * n];
    fft_columns(w, t, inverse);
    for (size_t j = 0; j < n; ++j)
        for (size_t i = 0; i < n; ++i) a[i + j * n] = t[j + i * n];
    fft_columns(w, a, inverse);
    if (!inverse) {
        const double s = 1.0 / (double)w->nn;
        for (size_t q = 0; q < w->nn; ++q) a[q] = w->keep[q] ? a[q] * s : 0.0;
    } else {
        for (size_t q = 0; q < w->nn; ++q) a[q] = creal(a[q]);
    }
}

/* ---- the right-hand side ---- */

/* h(ρ) - c_o² ρ'/ρ_o: the enthalpy less its linear part (which L carries), by expm1/log1p so
 * that nothing cancels at ρ'/ρ_o ~ Ma². */
static double enthalpy_nl(const wcref_params *p, double r)
{
    const double x = r / p->rho0, c2 = p->c0 * p->c0;
    if (p->linear) return c2 * (log1p(x) - x);
    const double g1 = p->gamma - 1.0;
    return c2 * (g1 != 0.0 ? expm1(g1 * log1p(x)) / g1 - x : log1p(x) - x);
}

/* out = N(in): the whole right-hand side less L. */
static void rhs(wcref *w, double complex *const in[NF], double complex *const out[NF])
{
    const size_t nn = w->nn;
    double complex **g = w->g;
    const double nu = w->p.nu;
    /* ρ', u, v, ∂u/∂x, ∂u/∂y, ∂v/∂x, ∂v/∂y on the grid */
    for (size_t q = 0; q < nn; ++q) {
        g[0][q] = in[0][q];
        g[1][q] = in[1][q];
        g[2][q] = in[2][q];
        g[3][q] = imul(w->kx[q], in[1][q]);
        g[4][q] = imul(w->ky[q], in[1][q]);
        g[5][q] = imul(w->kx[q], in[2][q]);
        g[6][q] = imul(w->ky[q], in[2][q]);
    }
    for (int f = 0; f < 7; ++f) fft2(w, g[f], 1);
    /* the products, in place: ρ'u, ρ'v, (u·∇)u, (u·∇)v, h_nl */
    for (size_t q = 0; q < nn; ++q) {
        const double r = creal(g[0][q]), u = creal(g[1][q]), v = creal(g[2][q]);
        const double ux = creal(g[3][q]), uy = creal(g[4][q]), vx = creal(g[5][q]),
                     vy = creal(g[6][q]);
        g[0][q] = r * u;
        g[1][q] = r * v;
        g[2][q] = u * ux + v * uy;
        g[3][q] = u * vx + v * vy;
        g[4][q] = enthalpy_nl(&w->p, r);
    }
    for (int f = 0; f < 5; ++f) fft2(w, g[f], 0);
    for (size_t q = 0; q < nn; ++q) {
        if (!w->keep[q]) {
            out[0][q] = out[1][q] = out[2][q] = 0.0;
            continue;
        }
        const double kx = w->kx[q], ky = w->ky[q];
        out[0][q] = imul(-1.0, kx * g[0][q] + ky * g[1][q]);
        out[1][q] = -g[2][q] - imul(kx, g[4][q]) - nu * w->kk[q] * in[1][q];
        out[2][q] = -g[3][q] - imul(ky, g[4][q]) - nu * w->kk[q] * in[2][q];
    }
}

/* ---- the exact acoustic propagator ---- */

static void rotations(wcref *w, double h)
{
    if (h == w->hrot) return;
    for (size_t q = 0; q < w->nn; ++q) {
        const double om = w->p.c0 * sqrt(w->kk[q]);
        w->cf[q] = cos(om * h);
        w->sf[q] = sin(om * h);
        w->ch[q] = cos(om * 0.5 * h);
        w->sh[q] = sin(om * 0.5 * h);
    }
    w->hrot = h;
}

/* z = e^{L h} z (full) or e^{L h/2} z: per mode, (q, u_l) = (c_o ρ̂'/ρ_o, k·û/|k|) turns as
 * q' = cos q - i sin u_l, u_l' = cos u_l - i sin q; the transverse part of û is left. */
static void propagate(const wcref *w, double complex *const z[NF], int full)
{
    const double *c = full ? w->cf : w->ch, *s = full ? w->sf : w->sh;
    const double cr = w->p.c0 / w->p.rho0;
    for (size_t q = 0; q < w->nn; ++q) {
        if (w->kk[q] == 0.0 || !w->keep[q]) continue;
        const double km = sqrt(w->kk[q]), ex = w->kx[q] / km, ey = w->ky[q] / km;
        const double complex r = z[0][q] * cr, ul = ex * z[1][q] + ey * z[2][q];
        const double complex r2 = c[q] * r - imul(s[q], ul), ul2 = c[q] * ul - imul(s[q], r);
        z[0][q] = r2 / cr;
        z[1][q] += ex * (ul2 - ul);
        z[2][q] += ey * (ul2 - ul);
    }
}

/* dst = x + c z, per field */
static void axpy(const wcref *w, double complex *const dst[NF], double complex *const x[NF],
                 double c, double complex *const z[NF])
{
    for (int f = 0; f < NF; ++f)
        for (size_t q = 0; q < w->nn; ++q) dst[f][q] = x[f][q] + c * z[f][q];
}

static void copy3(const wcref *w, double complex *const dst[NF], double complex *const src[NF])
{
    for (int f = 0; f < NF; ++f) memcpy(dst[f], src[f], w->nn * sizeof(double complex));
}

/* One step of Lawson's RK4 (the classical RK4 on e^{-Lt} z): with E = e^{Lh}, E½ = e^{Lh/2},
 * k1 = N(z), k2 = N(E½ z + h/2 E½ k1), k3 = N(E½ z + h/2 k2), k4 = N(E z + h E½ k3),
 * z' = E z + h/6 (E k1 + 2 E½ (k2 + k3) + k4). */
static void step(wcref *w, double complex *const z[NF], double h)
{
    rotations(w, h);
    double complex **k1 = w->k[0], **k2 = w->k[1], **k3 = w->k[2], **k4 = w->k[3];
    rhs(w, z, k1);
    copy3(w, w->a, z);
    propagate(w, w->a, 0); /* a = E½ z */
    copy3(w, w->tmp, k1);
    propagate(w, w->tmp, 0);
    axpy(w, w->y, w->a, 0.5 * h, w->tmp);
    rhs(w, w->y, k2);
    axpy(w, w->y, w->a, 0.5 * h, k2);
    rhs(w, w->y, k3);
    copy3(w, w->b, z);
    propagate(w, w->b, 1); /* b = E z */
    copy3(w, w->tmp, k3);
    propagate(w, w->tmp, 0);
    axpy(w, w->y, w->b, h, w->tmp);
    rhs(w, w->y, k4);
    /* z' = b + h/6 (E k1 + 2 E½ (k2 + k3) + k4) */
    propagate(w, k1, 1);
    axpy(w, k2, k2, 1.0, k3);
    propagate(w, k2, 0);
    for (int f = 0; f < NF; ++f)
        for (size_t q = 0; q < w->nn; ++q)
            z[f][q] = w->b[f][q] + h / 6.0 * (k1[f][q] + 2.0 * k2[f][q] + k4[f][q]);
}

/* The kept coefficients in a compact (2K + 1)² block, k_x fastest. */
static void refresh(wcref *w, double complex *const z[NF])
{
    const int K = w->K, m = 2 * K + 1, n = w->n;
    for (int f = 0; f < NF; ++f)
        for (int b = -K; b <= K; ++b)
            for (int a = -K; a <= K; ++a) {
                const size_t q = (size_t)((a + n) % n) + (size_t)n * (size_t)((b + n) % n);
                w->ret[f][(size_t)(a + K) + (size_t)m * (size_t)(b + K)] = z[f][q];
            }
}

/* wcref_eval's sums run two lanes per field, (Re, Im) of Σ_a c(a, b) e^{i a θ_x}: lane 0 adds
 * Re c cos - Im c sin as Re c cos + Im c (-sin), lane 1 Re c sin + Im c cos. x - y is x + (-y)
 * and y (-s) is -(y s) in IEEE arithmetic, so each lane's value is the scalar sum's bit for bit.
 * Per (b >= 0, a), 12 doubles: Re c and Im c of fields 0 and 1 duplicated, then of field 2. */
enum { EV_STRIDE = 12 };

static size_t ev_count(int K)
{
    return (size_t)(K + 1) * (size_t)(2 * K + 1) * EV_STRIDE;
}

static void eval_layout(wcref *w)
{
    const int K = w->K, m = 2 * K + 1;
    for (int b = 0; b <= K; ++b)
        for (int a = 0; a < m; ++a) {
            const size_t src = (size_t)a + (size_t)m * (size_t)(b + K);
            double *e = w->ev + ((size_t)b * (size_t)m + (size_t)a) * EV_STRIDE;
            const double complex c0 = w->ret[0][src], c1 = w->ret[1][src], c2 = w->ret[2][src];
            e[0] = e[1] = creal(c0);
            e[2] = e[3] = creal(c1);
            e[4] = e[5] = cimag(c0);
            e[6] = e[7] = cimag(c1);
            e[8] = e[9] = creal(c2);
            e[10] = e[11] = cimag(c2);
        }
}

/* ---- the interface ---- */

void wcref_free(wcref *w)
{
    if (!w) return;
    if (w->tr) share_release(w->tr);
    free(w->kx);
    free(w->ky);
    free(w->kk);
    free(w->keep);
    free(w->tw);
    free(w->col);
    free(w->cf);
    free(w->sf);
    free(w->ch);
    free(w->sh);
    for (int f = 0; f < NF; ++f) {
        free(w->s0[f]);
        free(w->s[f]);
        free(w->e[f]);
        free(w->a[f]);
        free(w->b[f]);
        free(w->y[f]);
        free(w->tmp[f]);
        free(w->ret[f]);
        for (int j = 0; j < 4; ++j) free(w->k[j][f]);
    }
    for (int f = 0; f < 7; ++f) free(w->g[f]);
    free(w->ev);
    free(w);
}

int wcref_create(wcref **out, const wcref_params *wp, const double *rho, const double *u,
                 const double *v)
{
    *out = NULL;
    const int n = wp->n;
    if (n < 8 || n > NMAX || (n & (n - 1)))
        return consph_fail(CONSPH_EINVAL, "wc reference: grid %d is not a power of two in 8..%d", n,
                           NMAX);
    if (!(wp->c0 > 0.0 && wp->rho0 > 0.0 && wp->len[0] > 0.0 && wp->len[1] > 0.0 && wp->nu >= 0.0 &&
          wp->dt >= 0.0))
        return consph_fail(CONSPH_EINVAL, "wc reference: c_o, ρ_o, the box and ν must be > 0");
    wcref *w = consph_calloc(1, sizeof *w);
    if (!w) return CONSPH_ENOMEM;
    w->p = *wp;
    w->n = n;
    w->K = n / 3;
    w->nn = (size_t)n * (size_t)n;
    const size_t nn = w->nn, zb = nn * sizeof(double complex);
    int ok = (w->kx = malloc(nn * sizeof(double))) && (w->ky = malloc(nn * sizeof(double))) &&
             (w->kk = malloc(nn * sizeof(double))) && (w->keep = malloc(nn)) &&
             (w->tw = malloc((size_t)n * sizeof(double complex))) &&
             (w->col = malloc(nn * sizeof(double complex))) &&
             (w->cf = malloc(nn * sizeof(double))) && (w->sf = malloc(nn * sizeof(double))) &&
             (w->ch = malloc(nn * sizeof(double))) && (w->sh = malloc(nn * sizeof(double)));
    const size_t mm = (size_t)(2 * w->K + 1) * (size_t)(2 * w->K + 1);
    for (int f = 0; ok && f < NF; ++f) {
        ok = (w->s0[f] = malloc(zb)) && (w->s[f] = malloc(zb)) && (w->e[f] = malloc(zb)) &&
             (w->a[f] = malloc(zb)) && (w->b[f] = malloc(zb)) && (w->y[f] = malloc(zb)) &&
             (w->tmp[f] = malloc(zb)) && (w->ret[f] = malloc(mm * sizeof(double complex)));
        for (int j = 0; ok && j < 4; ++j) ok = (w->k[j][f] = malloc(zb)) != NULL;
    }
    for (int f = 0; ok && f < 7; ++f) ok = (w->g[f] = malloc(zb)) != NULL;
    /* 32-byte aligned for the vector loads (EV_STRIDE doubles are a multiple of 32 bytes) */
    ok = ok && (w->ev = aligned_alloc(32, ev_count(w->K) * sizeof(double))) != NULL;
    if (!ok) {
        wcref_free(w);
        return consph_fail(CONSPH_ENOMEM, "out of memory for the wc reference");
    }
    for (int j = 0; j < n / 2; ++j) w->tw[j] = cexp(-2.0 * M_PI * I * (double)j / (double)n);
    double kmax2 = 0.0;
    for (int iy = 0; iy < n; ++iy)
        for (int ix = 0; ix < n; ++ix) {
            const size_t q = (size_t)ix + (size_t)n * (size_t)iy;
            const int jx = ix <= n / 2 ? ix : ix - n, jy = iy <= n / 2 ? iy : iy - n;
            w->keep[q] = abs(jx) <= w->K && abs(jy) <= w->K;
            w->kx[q] = 2.0 * M_PI * jx / wp->len[0];
            w->ky[q] = 2.0 * M_PI * jy / wp->len[1];
            w->kk[q] = w->kx[q] * w->kx[q] + w->ky[q] * w->ky[q];
            if (w->keep[q]) kmax2 = fmax(kmax2, w->kk[q]);
        }
    double umax = 0.0;
    for (size_t q = 0; q < nn; ++q) {
        w->s0[0][q] = rho[q] - wp->rho0;
        w->s0[1][q] = u[q];
        w->s0[2][q] = v[q];
        umax = fmax(umax, hypot(u[q], v[q]));
    }
    for (int f = 0; f < NF; ++f) fft2(w, w->s0[f], 0);
    /* The step: within RK4's stable range on the advective (|u| |k|) and viscous (ν |k|²) rates
     * of the kept modes, and short enough that the nonlinear terms, which oscillate with the
     * acoustic modes they act on, are followed: c_o |k| h <= 0.2 up to |k| = 4 (2π/len), where
     * the Taylor-Green data and the modes it feeds in the first products lie. Halving it changes
     * the state by < 1e-10 at c_o = 20 (docs/schemes.md; tests/test_wcref.c). */
    const double km = sqrt(kmax2), lmin = fmin(wp->len[0], wp->len[1]);
    w->dt = wp->dt > 0.0 ? wp->dt
                         : fmin(0.25 / (umax * km + wp->nu * kmax2 + 1e-300),
                                0.2 / (wp->c0 * 8.0 * M_PI / lmin));
    w->hrot = -1.0;
    copy3(w, w->s, w->s0);
    w->j = 0;
    w->t = 0.0;
    refresh(w, w->s);
    eval_layout(w);
    if (!wp->unshared) w->tr = share_hold(wp, rho, u, v, mm);
    *out = w;
    return CONSPH_OK;
}

int wcref_advance(wcref *w, double t)
{
    if (!(t >= 0.0) || !isfinite(t))
        return consph_fail(CONSPH_EINVAL, "wc reference: time %g is not >= 0", t);
    if (t == w->t) return CONSPH_OK;
    if (w->tr && share_lookup(w, t)) {
        eval_layout(w);
        w->t = t;
        return CONSPH_OK;
    }
    /* Whole steps on the fixed grid t_j = j dt, then one shorter step from the last t_j <= t
     * on a copy: the state at t depends on t alone, not on the times asked before it (so a
     * restarted run measures against the same numbers as one that never stopped). */
    if (t < (double)w->j * w->dt) {
        copy3(w, w->s, w->s0);
        w->j = 0;
    }
    if (w->tr) share_adopt(w, t);
    while ((double)(w->j + 1) * w->dt <= t) {
        step(w, w->s, w->dt);
        ++w->j;
    }
    const double rest = t - (double)w->j * w->dt;
    if (rest > 0.0) {
        copy3(w, w->e, w->s);
        step(w, w->e, rest);
        refresh(w, w->e);
    } else {
        refresh(w, w->s);
    }
    eval_layout(w);
    if (w->tr) share_publish(w, t);
    w->t = t;
    return CONSPH_OK;
}

double wcref_time(const wcref *w)
{
    return w->t;
}

double wcref_step(const wcref *w)
{
    return w->dt;
}

/* e^{i a θ_x} for a = -K..K at x (cx, sx: 2K + 1 each), by cos/sin of each multiple (no
 * recurrence to accumulate). The negative multiples mirror the positive ones: tx·(-a) = -(tx·a)
 * exactly, and the C library's cos is even and sin odd bit for bit (test_wcref checks the whole
 * evaluation against the direct sum). */
static inline void axis_x(const wcref *w, double x, double *cx, double *sx)
{
    const int K = w->K;
    const double tx = 2.0 * M_PI * (x - w->p.lo[0]) / w->p.len[0];
    cx[K] = cos(tx * 0);
    sx[K] = sin(tx * 0);
    for (int a = 1; a <= K; ++a) {
        const double c = cos(tx * a), s = sin(tx * a);
        cx[K + a] = c;
        sx[K + a] = s;
        cx[K - a] = c;
        sx[K - a] = -s;
    }
}

/* e^{i b θ_y} for b = 0..K at y (cy, sy: K + 1 each). */
static inline void axis_y(const wcref *w, double y, double *cy, double *sy)
{
    const double ty = 2.0 * M_PI * (y - w->p.lo[1]) / w->p.len[1];
    for (int b = 0; b <= w->K; ++b) {
        cy[b] = cos(ty * b);
        sy[b] = sin(ty * b);
    }
}

/* The fields from the point's axis factors (axis_x, axis_y). */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
eval_sums(const wcref *w, const double *cx, const double *sx, const double *cy, const double *sy,
          double u[2], double *rho)
{
    const int K = w->K, m = 2 * K + 1;
    /* The coefficients of a real field are Hermitian, c(-a, -b) = conj c(a, b): the rows b < 0
     * are the conjugates of the rows b > 0, so f = Re S_0 + 2 Σ_{b>0} Re S_b with
     * S_b = e^{i b θ_y} Σ_a c(a, b) e^{i a θ_x}. The three fields' sums side by side, each in
     * its own order (a, then b, ascending), so that their chains of additions overlap. */
    double out[NF] = {0.0, 0.0, 0.0};
#if defined(__GNUC__)
    /* eval_layout's two lanes per field: fields 0 and 1 in one 4-lane vector, field 2 in two */
    typedef double v4d __attribute__((vector_size(32)));
    typedef double v2d __attribute__((vector_size(16)));
    v4d cs4[2 * KMAX + 1], ns4[2 * KMAX + 1];
    v2d cs2[2 * KMAX + 1], ns2[2 * KMAX + 1];
    for (int a = 0; a < m; ++a) {
        const double c = cx[a], s = sx[a];
        cs4[a] = (v4d){c, s, c, s};
        ns4[a] = (v4d){-s, c, -s, c};
        cs2[a] = (v2d){c, s};
        ns2[a] = (v2d){-s, c};
    }
    for (int b = 0; b <= K; ++b) {
        const double *e = w->ev + (size_t)b * (size_t)m * EV_STRIDE;
        v4d acc01 = {0.0, 0.0, 0.0, 0.0};
        v2d acc2 = {0.0, 0.0};
        for (int a = 0; a < m; ++a, e += EV_STRIDE) {
            const v4d re01 = *(const v4d *)e, im01 = *(const v4d *)(e + 4);
            const v2d re2 = *(const v2d *)(e + 8), im2 = *(const v2d *)(e + 10);
            acc01 += re01 * cs4[a] + im01 * ns4[a];
            acc2 += re2 * cs2[a] + im2 * ns2[a];
        }
        const double re0 = acc01[0], im0 = acc01[1], re1 = acc01[2], im1 = acc01[3];
        const double re2 = acc2[0], im2 = acc2[1];
        const double wb = b ? 2.0 : 1.0;
        out[0] += wb * (re0 * cy[b] - im0 * sy[b]);
        out[1] += wb * (re1 * cy[b] - im1 * sy[b]);
        out[2] += wb * (re2 * cy[b] - im2 * sy[b]);
    }
#else
    for (int b = 0; b <= K; ++b) {
        const size_t off = (size_t)m * (size_t)(b + K);
        const double complex *r0 = w->ret[0] + off, *r1 = w->ret[1] + off, *r2 = w->ret[2] + off;
        double re0 = 0.0, im0 = 0.0, re1 = 0.0, im1 = 0.0, re2 = 0.0, im2 = 0.0;
        for (int a = 0; a < m; ++a) {
            const double c = cx[a], s = sx[a];
            re0 += creal(r0[a]) * c - cimag(r0[a]) * s;
            im0 += creal(r0[a]) * s + cimag(r0[a]) * c;
            re1 += creal(r1[a]) * c - cimag(r1[a]) * s;
            im1 += creal(r1[a]) * s + cimag(r1[a]) * c;
            re2 += creal(r2[a]) * c - cimag(r2[a]) * s;
            im2 += creal(r2[a]) * s + cimag(r2[a]) * c;
        }
        const double wb = b ? 2.0 : 1.0;
        out[0] += wb * (re0 * cy[b] - im0 * sy[b]);
        out[1] += wb * (re1 * cy[b] - im1 * sy[b]);
        out[2] += wb * (re2 * cy[b] - im2 * sy[b]);
    }
#endif
    *rho = w->p.rho0 + out[0];
    u[0] = out[1];
    u[1] = out[2];
}

/* ---- many points at once ----
 *
 * eval_sums at four points at once, a lane a point: each lane makes its point's operations in
 * eval_sums' order (the coefficients broadcast, not the factors), so that every value is that
 * point's eval_sums' bit for bit, in half of the vector operations (eval_sums spends its lanes
 * on the fields, which share the factors). Built for AVX2 only, where the vectors are the
 * machine's own: a compiler splits them into scalars elsewhere, which was 4-6 times slower
 * than eval_sums. The target enables no FMA (and ISO C contracts nothing). Axis factors: from
 * the tables or taken at the point. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) &&                             \
    (defined(WCREF_DISPATCH) || defined(__AVX2__))
#define WCREF_LANES4 1
enum { EVW = 4 }; /* the points of a vector */

__attribute__((target("avx2"))) static void eval_lanes4(const wcref *w, size_t i0, size_t i1,
                                                        const double *x, const double *y,
                                                        const double *tabx, const size_t *whichx,
                                                        const double *taby, const size_t *whichy,
                                                        double *u, double *v, double *rho)
{
    typedef double lanes __attribute__((vector_size(8 * EVW)));
    const int K = w->K, m = 2 * K + 1, my = K + 1;
    double fx[EVW][2 * (2 * KMAX + 1)], fy[EVW][2 * (KMAX + 1)];
    lanes C[2 * KMAX + 1], S[2 * KMAX + 1], NS[2 * KMAX + 1];
    for (size_t i = i0; i + EVW <= i1; i += EVW) {
        const double *ex[EVW], *ey[EVW];
        for (int k = 0; k < EVW; ++k) {
            const size_t j = i + (size_t)k;
            if (tabx) {
                ex[k] = tabx + 2 * (size_t)m * whichx[j];
            } else {
                axis_x(w, x[j], fx[k], fx[k] + m);
                ex[k] = fx[k];
            }
            if (taby) {
                ey[k] = taby + 2 * (size_t)my * whichy[j];
            } else {
                axis_y(w, y[j], fy[k], fy[k] + my);
                ey[k] = fy[k];
            }
        }
        for (int a = 0; a < m; ++a)
            for (int k = 0; k < EVW; ++k) {
                C[a][k] = ex[k][a];
                S[a][k] = ex[k][m + a];
                NS[a][k] = -ex[k][m + a];
            }
        lanes o0 = {0.0}, o1 = {0.0}, o2 = {0.0};
        for (int b = 0; b <= K; ++b) {
            const double *e = w->ev + (size_t)b * (size_t)m * EV_STRIDE;
            lanes r0 = {0.0}, q0 = {0.0}, r1 = {0.0}, q1 = {0.0}, r2 = {0.0}, q2 = {0.0};
            for (int a = 0; a < m; ++a, e += EV_STRIDE) {
                /* eval_layout's Re c0, Re c1, Im c0, Im c1, Re c2, Im c2 */
                const double cr0 = e[0], cr1 = e[2], ci0 = e[4], ci1 = e[6], cr2 = e[8],
                             ci2 = e[10];
                r0 += cr0 * C[a] + ci0 * NS[a];
                q0 += cr0 * S[a] + ci0 * C[a];
                r1 += cr1 * C[a] + ci1 * NS[a];
                q1 += cr1 * S[a] + ci1 * C[a];
                r2 += cr2 * C[a] + ci2 * NS[a];
                q2 += cr2 * S[a] + ci2 * C[a];
            }
            lanes cy, sy;
            for (int k = 0; k < EVW; ++k) {
                cy[k] = ey[k][b];
                sy[k] = ey[k][my + b];
            }
            const double wb = b ? 2.0 : 1.0;
            o0 += wb * (r0 * cy - q0 * sy);
            o1 += wb * (r1 * cy - q1 * sy);
            o2 += wb * (r2 * cy - q2 * sy);
        }
        for (int k = 0; k < EVW; ++k) {
            rho[i + (size_t)k] = w->p.rho0 + o0[k];
            u[i + (size_t)k] = o1[k];
            v[i + (size_t)k] = o2[k];
        }
    }
}
#endif

/* The points eval_many takes at once on this machine: 4 (AVX2), or 0 (each alone; also where
 * CONSPH_WCREF_LANES=0, a test hook: test_wcref runs both against wcref_eval). 8 lanes of
 * AVX-512 were slower than 4 on the machine measured (an AMD Zen 4: 117 against 105 ms at
 * 250 000 scattered points on one thread, 206 ms before any of this). */
static int eval_lanes(void)
{
    const char *cap = getenv("CONSPH_WCREF_LANES");
    if (cap && !strcmp(cap, "0")) return 0;
#if defined(WCREF_DISPATCH)
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") ? EVW : 0;
#elif defined(WCREF_LANES4)
    return EVW;
#else
    return 0;
#endif
}

WCREF_CLONES
void wcref_eval(const wcref *w, const double x[2], double u[2], double *rho)
{
    double cx[2 * KMAX + 1], sx[2 * KMAX + 1], cy[KMAX + 1], sy[KMAX + 1];
    axis_x(w, x[0], cx, sx);
    axis_y(w, x[1], cy, sy);
    eval_sums(w, cx, sx, cy, sy, u, rho);
}

/* ---- many points: each distinct coordinate's factors once ---- */

/* The distinct values of x[0..n) by bit pattern (so +0 and -0 stay apart: their sines differ
 * in sign): which[i] = the index of x[i]'s value in first-seen order; returns their count.
 * slot: a table of `size` (a power of 2, >= 2n) entries. */
static size_t distinct_values(const double *x, size_t n, size_t *which, size_t *first, size_t *slot,
                              size_t size)
{
    const size_t empty = (size_t)-1;
    for (size_t k = 0; k < size; ++k) slot[k] = empty;
    size_t count = 0;
    for (size_t i = 0; i < n; ++i) {
        uint64_t bits;
        memcpy(&bits, &x[i], sizeof bits);
        size_t h = (size_t)((bits * 0x9E3779B97F4A7C15ull) >> 20) & (size_t)(size - 1);
        for (;;) {
            const size_t e = slot[h];
            if (e == empty) {
                slot[h] = count;
                first[count] = i;
                which[i] = count++;
                break;
            }
            if (!memcmp(&x[first[e]], &x[i], sizeof(double))) {
                which[i] = e;
                break;
            }
            h = (h + 1) & (size - 1);
        }
    }
    return count;
}

/* The factors of one axis for wcref_eval_many: a table of each distinct value's (tab, which[i]
 * its row for point i) where the values repeat, as on a lattice (the Eulerian schemes' particles,
 * t = 0), else none (tab NULL): each point then takes its own, which is cheaper than hashing
 * values that are all distinct and keeps no table of 2(2K + 1) doubles a point. */
typedef struct {
    double *tab;
    size_t *which;
} eval_axis;

/* Points [i0, i1) of wcref_eval_many: each point's operations are wcref_eval's, its axis factors
 * from the table or taken at the point (the same function of the coordinate either way). */
WCREF_CLONES static void eval_points(const wcref *w, size_t i0, size_t i1, const double *x,
                                     const double *y, eval_axis ax, eval_axis ay, double *u,
                                     double *v, double *rho)
{
    const size_t mx = (size_t)(2 * w->K + 1), my = (size_t)(w->K + 1);
    double fx[2 * (2 * KMAX + 1)], fy[2 * (KMAX + 1)];
    for (size_t i = i0; i < i1; ++i) {
        const double *ex = fx, *ey = fy;
        if (ax.tab)
            ex = ax.tab + 2 * mx * ax.which[i];
        else
            axis_x(w, x[i], fx, fx + mx);
        if (ay.tab)
            ey = ay.tab + 2 * my * ay.which[i];
        else
            axis_y(w, y[i], fy, fy + my);
        double ui[2];
        eval_sums(w, ex, ex + mx, ey, ey + my, ui, &rho[i]);
        u[i] = ui[0];
        v[i] = ui[1];
    }
}

/* Points [i0, i1): whole groups of four at once where eval_lanes said so, the rest one by one. */
static void eval_range(const wcref *w, size_t i0, size_t i1, const double *x, const double *y,
                       eval_axis ax, eval_axis ay, double *u, double *v, double *rho, int lanes)
{
    size_t j = i0;
#if defined(WCREF_LANES4)
    if (lanes == EVW) {
        j = i0 + (i1 - i0) / EVW * EVW;
        eval_lanes4(w, i0, j, x, y, ax.tab, ax.which, ay.tab, ay.which, u, v, rho);
    }
#else
    (void)lanes;
#endif
    eval_points(w, j, i1, x, y, ax, ay, u, v, rho);
}

/* Whether an axis' values repeat enough for a table: at most half of the first PROBE distinct.
 * A guess from the first points (the particles are in cell order, so a lattice repeats its
 * rows or columns within them): either answer gives the same values, only the time differs. */
enum { PROBE = 1024 };

static int axis_repeats(const double *x, size_t n, size_t *scratch)
{
    const size_t m = n < PROBE ? n : PROBE;
    return 2 * distinct_values(x, m, scratch, scratch + m, scratch + 2 * m, 2 * PROBE) <= m;
}

/* The table of one axis (see eval_axis), its distinct values' factors split among threads;
 * tab stays NULL where the values do not repeat. CONSPH_ENOMEM on failure. */
static int axis_table(const wcref *w, int is_x, const double *x, size_t n, int parallel,
                      eval_axis *ax)
{
    (void)parallel; /* read by the OpenMP if alone */
    ax->tab = NULL;
    ax->which = NULL;
    size_t *probe = malloc((2 * PROBE + 2 * PROBE) * sizeof(size_t));
    if (!probe) return CONSPH_ENOMEM;
    const int repeats = axis_repeats(x, n, probe);
    free(probe);
    if (!repeats) return CONSPH_OK;
    size_t size = 16;
    while (size < 2 * n) size *= 2;
    size_t *which = malloc((2 * n + size) * sizeof(size_t));
    if (!which) return CONSPH_ENOMEM;
    size_t *first = which + n, *slot = which + 2 * n;
    const size_t count = distinct_values(x, n, which, first, slot, size);
    const size_t m = is_x ? (size_t)(2 * w->K + 1) : (size_t)(w->K + 1);
    double *tab = malloc(2 * m * (count ? count : 1) * sizeof(double));
    if (!tab) {
        free(which);
        return CONSPH_ENOMEM;
    }
#pragma omp parallel for schedule(static) if (parallel)
    for (size_t k = 0; k < count; ++k) {
        double *t = tab + 2 * m * k;
        if (is_x)
            axis_x(w, x[first[k]], t, t + m);
        else
            axis_y(w, x[first[k]], t, t + m);
    }
    ax->tab = tab;
    ax->which = which;
    return CONSPH_OK;
}

int wcref_eval_many(const wcref *w, size_t n, const double *x, const double *y, double *u,
                    double *v, double *rho, int parallel)
{
    if (n == 0) return CONSPH_OK;
    const int lanes = eval_lanes();
    eval_axis ax, ay = {NULL, NULL};
    int st = axis_table(w, 1, x, n, parallel, &ax);
    if (st == CONSPH_OK) st = axis_table(w, 0, y, n, parallel, &ay);
    if (st != CONSPH_OK) {
        free(ax.tab);
        free(ax.which);
        return consph_fail(CONSPH_ENOMEM, "out of memory for the wc reference at %zu points", n);
    }
#pragma omp parallel if (parallel)
    {
#ifdef _OPENMP
        const size_t nt = (size_t)omp_get_num_threads(), t = (size_t)omp_get_thread_num();
#else
        const size_t nt = 1, t = 0;
#endif
        eval_range(w, n * t / nt, n * (t + 1) / nt, x, y, ax, ay, u, v, rho, lanes);
    }
    free(ax.tab);
    free(ax.which);
    free(ay.tab);
    free(ay.which);
    return CONSPH_OK;
}

double wcref_pressure(const wcref *w, double rho)
{
    const double c2 = w->p.c0 * w->p.c0, r0 = w->p.rho0;
    if (w->p.linear) return c2 * (rho - r0);
    return r0 * c2 / w->p.gamma * (pow(rho / r0, w->p.gamma) - 1.0);
}
