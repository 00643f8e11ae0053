/* The GPU solver's per-particle functions, written once for the host emulation (gpu.c) and the
 * CUDA kernels (cuda.cu): each is the body of one thread, over plain arrays (structure of arrays,
 * component-major with stride n) and the constants of a gpu_view. A CUDA kernel runs one of
 * them per thread; the emulation runs the same function in a loop over the particles (or cells).
 *
 * Every value is the CPU solver's bit for bit when both are compiled without contracting a
 * multiply and an add into an FMA (gcc -std=c11 does not contract; nvcc needs -fmad=false):
 *  - cell binning: src/nnps/nnps.c's cell_index and nnps_wrap, cell c = (c2 nc1 + c1) nc0 + c0;
 *  - the counting sort: counts, exclusive prefix sums, a scatter in any order, then each cell's
 *    slots sorted by particle index: the stable counting sort of consph_nnps_build;
 *  - the neighbour walk: unwrapped cells u in ascending (u2, u1, u0) within the search's reach,
 *    each cell's slots in order, x_ij = (x_i - shift) - x_j, r² summed from axis 0, hit when
 *    r² < R² (src/nnps/gather.c); the CPU walk prunes cells that hold no hit, which changes
 *    which cells are read, never the order of the hits;
 *  - the quintic kernel: src/kernels/kernels.c's quintic_f/df/d2f and eval_batch's selects;
 *  - the passes: src/schemes/pysph/scheme.c's visit_density and visit_tv_d (edac), job_fields'
 *    per-particle values and visit_wcsph_d (wcsph), summing the same pysph_tv_pair and
 *    pysph_wcsph_pair terms (src/schemes/pysph/iact.h) in the same neighbour order;
 *  - the integrator: src/integrators/integrators.c's set_fields and drift with edac's transport
 *    hook, the solver's wrap_positions and closures (edac's summation density, wcsph's EOS of
 *    src/solver/solver.c's solver_eos). */
#ifndef CONSPH_GPU_DEV_H
#define CONSPH_GPU_DEV_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "gpu/hd.h"
#include "schemes/negi/iact.h"
#include "schemes/negi/kit_pair.h"
#include "schemes/pysph/iact.h"

#if defined(__CUDACC__)
#define GPU_FN __host__ __device__ static inline
#define GPU_FN_INLINE __host__ __device__ static __forceinline__
#elif defined(__GNUC__)
#define GPU_FN static inline
#define GPU_FN_INLINE static inline __attribute__((always_inline))
#else
#define GPU_FN static inline
#define GPU_FN_INLINE static inline
#endif

/* The search grid, as src/nnps/nnps.c sets it up (gpu.c's grid_setup), padded to three axes. */
typedef struct gpu_grid {
    int dim;
    int periodic[3];
    int64_t nc[3], reach[3];
    double lo[3], hi[3], len[3], inv_h[3]; /* len = hi - lo */
    double h[3];                           /* cell edges, len / nc */
    double radius2;
    double prune2; /* (radius + 4 slack)²: a cell farther from the point holds no neighbour */
    size_t ncells;
} gpu_grid;

/* The quintic spline's constants (consph_kernel: norm, 1/h, support; eval_batch's products). */
typedef struct gpu_kern {
    double norm, inv_h, support, norm1, at_zero;
    double norm2; /* norm / h², of W'' */
} gpu_kern;

/* Indices of the solver's arrays in the view's block a (x first, then every particle field's
 * components in the particles' order: gpu.c maps them). */
enum {
    GA_X,
    GA_U,
    GA_P,
    GA_AU,
    GA_AQ,
    GA_AX,
    GA_AUHAT,
    GA_TVDU,
    GA_RHOS,
    GA_RHOF,
    GA_NUMD,
    GA_PAVG,
    GA_GRADP,
    GA_DIVU,
    GA_GRADU,
    GA_U0,
    GA_Q0,
    GA_X0,
    GA_Q, /* the evolved scalar: p (edac, pe-ipst-c) or ϱ (wcsph, l-ipst-c) */
    /* 001's family (src/schemes/negi/scheme.c's fields) */
    GA_VOL,   /* ω = 1/Σ W */
    GA_BONET, /* B_i, d × d */
    GA_GRADQ,
    GA_LAPU,
    GA_LAPQ,
    GA_SHIFT, /* δr of the last shift */
    GA_RHOC,  /* EWCSPH's frozen ϱ_c */
    GA_LAT,   /* L-RR-C's lattice point of each particle */
    GA_COUNT
};

/* The schemes the GPU runs. */
enum { GS_EDAC, GS_WCSPH, GS_NEGI };

typedef struct gpu_view {
    size_t n; /* particles, and the stride of every array */
    int d;
    int narr;         /* arrays in a (and b) */
    int grads;        /* ∇p and ∇u wanted by this evaluation (the solver's grads_skip unset) */
    int at[GA_COUNT]; /* first array of each quantity in a (-1: the scheme has none) */
    int scheme;       /* GS_* */
    /* wcsph: Monaghan's Π on (α > 0), Tait's EOS (tait: γ = 7, by multiplication) or the linear
     * one, ρ_o, c_o², γ, and the integer exponent of the sound speed's (ϱ/ρ_o)^((γ-1)/2) */
    int av, tait, cs_exp;
    double rho0, c2, gamma;
    gpu_grid g;
    gpu_kern k;
    pysph_consts c;
    double *a, *b;      /* narr arrays of n each; b: the target of a permutation */
    double *vol, *mrho; /* edac: 1/Σ W and m/ϱ of the density pass; wcsph: p/ϱ², m/ϱ (n each) */
    double *cs;         /* wcsph: Tait's sound speed of each particle (n) */
    double *xs;         /* d arrays of n: the coordinates in slot order */
    uint32_t *cell;     /* n: the cell of each particle */
    uint32_t *count;    /* ncells + 1: particles per cell, then the scatter's fill */
    uint32_t *start;    /* ncells + 1: the first slot of each cell */
    uint32_t *order;    /* n: the particle in each slot */
    /* 001's family (GS_NEGI): the terms of the scheme's rates, q = p (evolve_p) or ϱ, ν (Cleary's
     * ν ρ_o), the δ-term's D, the kit's cond_max; the sums of the kit's first pass now run (∇p,
     * G, ∇q, ∇·u stored) and its second (∇²u, ∇²q); IPST's h and h^d */
    negi_terms nt;
    int evolve_p, moves; /* moves: 0 for the Eulerian schemes (no drift, no x0, fixed ω) */
    int kit_p, kit_u, kit_q, kit_div, lap_u, lap_q;
    double nu, Dq, cond_max, ipst_h, ipst_hd;
    /* Sun et al.'s shifting (L-PST-C): -CFL Ma (2h)², 1/W(Δs), R and the cap on |δr| */
    double pst_coef, pst_inv_wds, pst_R, pst_cap;
    double c0_over_h;                     /* TV-C: δu = (c_o/h) δr */
    double m4_norm, m4_inv_h, m4_support; /* L-RR-C: the M4 kernel at h = Δs */
    /* d arrays of n each: a shift (IPST, PST; L-RR-C: the remeshed u) and IPST's sum of them */
    double *step, *total;
    double *chi;                 /* n: IPST's h^d Σ W of each particle; L-RR-C: the remeshed q */
    unsigned long long *chi_max; /* IPST: the bits of max χ (χ >= 0, so ordered as integers) */
    unsigned char *bonet_ok;     /* n: B_i accepted by the kit's first pass (Fatehi_c reads it) */
} gpu_view;

GPU_FN double *gv(const gpu_view *v, int q, int comp)
{
    return v->a + (size_t)(v->at[q] + comp) * v->n;
}

/* ---- the atomic increment of the counting sort ---- */
GPU_FN uint32_t gpu_atomic_inc(uint32_t *p)
{
#if defined(__CUDA_ARCH__)
    return atomicAdd((unsigned int *)p, 1u);
#else
    return (*p)++;
#endif
}

/* ---- cell binning (src/nnps/nnps.c) ---- */
GPU_FN double gpu_stored(const gpu_grid *g, int a, double x)
{
    if (!g->periodic[a]) return x;
    const double lo = g->lo[a], hi = g->hi[a];
    if (x >= lo && x < hi) return x;
    if (isnan(x)) return x;
    double w = x - floor((x - lo) / g->len[a]) * g->len[a];
    if (!(w >= lo && w < hi)) w = lo;
    return w;
}

GPU_FN int64_t gpu_cell_axis(const gpu_grid *g, int a, double x)
{
    double v = (x - g->lo[a]) * g->inv_h[a];
    if (!(v >= 0.0)) return 0;
    if (v >= (double)g->nc[a]) return g->nc[a] - 1;
    return (int64_t)v;
}

GPU_FN void dev_bin(const gpu_view *v, size_t i)
{
    const gpu_grid *g = &v->g;
    size_t c = 0;
    for (int a = g->dim - 1; a >= 0; --a)
        c = c * (size_t)g->nc[a] + (size_t)gpu_cell_axis(g, a, gpu_stored(g, a, gv(v, GA_X, a)[i]));
    v->cell[i] = (uint32_t)c;
}

GPU_FN void dev_count(const gpu_view *v, size_t i)
{
    gpu_atomic_inc(&v->count[v->cell[i]]);
}

/* Any order of the scatter: dev_cell_sort restores the particle order within each cell. */
GPU_FN void dev_scatter(const gpu_view *v, size_t i)
{
    const uint32_t c = v->cell[i];
    v->order[v->start[c] + gpu_atomic_inc(&v->count[c])] = (uint32_t)i;
}

/* Insertion sort of one cell's slots by particle index (a handful of particles per cell). */
GPU_FN void dev_cell_sort(const gpu_view *v, size_t c)
{
    uint32_t *o = v->order;
    const uint32_t s0 = v->start[c], s1 = v->start[c + 1];
    for (uint32_t s = s0 + 1; s < s1; ++s) {
        const uint32_t key = o[s];
        uint32_t t = s;
        while (t > s0 && o[t - 1] > key) {
            o[t] = o[t - 1];
            --t;
        }
        o[t] = key;
    }
}

/* The search's copy of the coordinates in slot order. */
GPU_FN void dev_slots(const gpu_view *v, size_t s)
{
    const uint32_t i = v->order[s];
    for (int a = 0; a < v->d; ++a)
        v->xs[(size_t)a * v->n + s] = gpu_stored(&v->g, a, gv(v, GA_X, a)[i]);
}

/* Re-sorting into cell order: b = a permuted, new[s] = old[order[s]] (consph_particles_permute
 * over positions and every field). */
GPU_FN void dev_permute(const gpu_view *v, size_t s)
{
    const size_t n = v->n, from = v->order[s];
    for (int k = 0; k < v->narr; ++k) v->b[(size_t)k * n + s] = v->a[(size_t)k * n + from];
}

/* ---- the integrator (pec: src/integrators/integrators.c) ---- */
GPU_FN void dev_save_start(const gpu_view *v, size_t i)
{
    gv(v, GA_Q0, 0)[i] = gv(v, GA_Q, 0)[i];
    for (int a = 0; a < v->d; ++a) {
        gv(v, GA_U0, a)[i] = gv(v, GA_U, a)[i];
        if (v->moves) gv(v, GA_X0, a)[i] = gv(v, GA_X, a)[i];
    }
}

/* wcsph's closure: the EOS of solver_eos (γ = 7 written out as there). */
GPU_FN double gpu_eos(const gpu_view *v, double rho)
{
    if (!v->tait) return v->c2 * (rho - v->rho0);
    const double x = rho / v->rho0, x2 = x * x, x4 = x2 * x2;
    return v->rho0 * v->c2 / v->gamma * (x * x2 * x4 - 1.0);
}

/* The closure of wcsph and 001's family (solver_eos): ϱ = p/c_o² + ρ_o where p evolves (eq. 31),
 * else p = EOS(ϱ). */
GPU_FN void gpu_close(const gpu_view *v, size_t i)
{
    if (v->evolve_p)
        gv(v, GA_RHOF, 0)[i] = gv(v, GA_P, 0)[i] / v->c2 + v->rho0;
    else
        gv(v, GA_P, 0)[i] = gpu_eos(v, gv(v, GA_RHOF, 0)[i]);
}

/* advance(c): u, q = u0, q0 + c (au, aq); edac's transport hook ũ - u = c ã and dx/dt = u + ũ - u
 * (wcsph: dx/dt as the rates left it); x = x0 + c dx/dt wrapped into the box; the closure (edac:
 * ϱ = the last summation density; wcsph: p = EOS(ϱ)). */
GPU_FN void dev_advance(const gpu_view *v, size_t i, double c)
{
    const gpu_grid *g = &v->g;
    const int edac = v->scheme == GS_EDAC;
    gv(v, GA_Q, 0)[i] = gv(v, GA_Q0, 0)[i] + c * gv(v, GA_AQ, 0)[i];
    for (int a = 0; a < v->d; ++a) {
        const double u = gv(v, GA_U0, a)[i] + c * gv(v, GA_AU, a)[i];
        gv(v, GA_U, a)[i] = u;
        double ax;
        if (edac) {
            const double du = c * gv(v, GA_AUHAT, a)[i];
            ax = u + du;
            gv(v, GA_TVDU, a)[i] = du;
            gv(v, GA_AX, a)[i] = ax;
        } else {
            if (!v->moves) continue;
            ax = gv(v, GA_AX, a)[i];
        }
        double x = gv(v, GA_X0, a)[i] + c * ax;
        if (g->periodic[a]) {
            const double lo = g->lo[a], L = g->len[a];
            if (x < lo || x >= lo + L) {
                x -= L * floor((x - lo) / L);
                if (x >= lo + L) x = lo;
            }
        }
        gv(v, GA_X, a)[i] = x;
    }
    if (edac)
        gv(v, GA_RHOF, 0)[i] = gv(v, GA_RHOS, 0)[i];
    else
        gpu_close(v, i);
}

/* ---- the neighbour walk ---- */
typedef struct gpu_walk {
    int64_t c[3], u[3], ua[3], ub[3];
    double xi[3], q[3];
    uint32_t s, s1;
} gpu_walk;

GPU_FN int64_t gpu_floor_div(int64_t u, int64_t d)
{
    if (u >= 0 && u < d) return 0;
    if (u < 0 && u >= -d) return -1;
    const int64_t q = u / d;
    return (u % d != 0 && u < 0) ? q - 1 : q;
}

/* Points the walk at its current unwrapped cell u: the cell's slots and the image shift; no slots
 * when the cell lies farther than the radius (widened by the rounding of binning, as the CPU's
 * walk widens it by its slack) from the point: such a cell holds no neighbour, so skipping it
 * changes which cells are read, never the neighbours or their order. */
GPU_FN void gpu_walk_cell(const gpu_view *v, gpu_walk *w)
{
    const gpu_grid *g = &v->g;
    double gap2 = 0.0;
    for (int a = 0; a < 3; ++a) { /* a constant trip count: the walk stays in registers */
        if (a >= g->dim) break;
        const double lo = g->lo[a] + (double)w->u[a] * g->h[a];
        const double hi = g->lo[a] + (double)(w->u[a] + 1) * g->h[a];
        const int open_lo = !g->periodic[a] && w->u[a] == 0;
        const int open_hi = !g->periodic[a] && w->u[a] == g->nc[a] - 1;
        const double x = w->xi[a];
        const double gap = (!open_lo && x < lo) ? lo - x : (!open_hi && x > hi) ? x - hi : 0.0;
        gap2 += gap * gap;
    }
    if (gap2 > g->prune2) {
        w->s = w->s1 = 0;
        return;
    }
    size_t cell = 0;
    double shift[3] = {0.0, 0.0, 0.0};
    for (int a = 2; a >= 0; --a) {
        int64_t ca = w->u[a];
        if (g->periodic[a]) {
            const int64_t m = gpu_floor_div(w->u[a], g->nc[a]);
            ca = w->u[a] - m * g->nc[a];
            shift[a] = (double)m * g->len[a];
        }
        cell = cell * (size_t)g->nc[a] + (size_t)ca;
    }
    for (int a = 0; a < 3; ++a) w->q[a] = a < g->dim ? w->xi[a] - shift[a] : 0.0;
    w->s = v->start[cell];
    w->s1 = v->start[cell + 1];
}

GPU_FN void gpu_walk_start(const gpu_view *v, size_t i, gpu_walk *w)
{
    const gpu_grid *g = &v->g;
    for (int a = 0; a < 3; ++a) {
        w->xi[a] = w->q[a] = 0.0;
        w->c[a] = 0;
        w->ua[a] = w->ub[a] = 0;
        if (a >= g->dim) continue;
        w->xi[a] = gpu_stored(g, a, gv(v, GA_X, a)[i]);
        w->c[a] = gpu_cell_axis(g, a, w->xi[a]);
        w->ua[a] = w->c[a] - g->reach[a];
        w->ub[a] = w->c[a] + g->reach[a];
        if (!g->periodic[a]) {
            if (w->ua[a] < 0) w->ua[a] = 0;
            if (w->ub[a] > g->nc[a] - 1) w->ub[a] = g->nc[a] - 1;
        }
    }
    for (int a = 0; a < 3; ++a) w->u[a] = w->ua[a];
    gpu_walk_cell(v, w);
}

/* The next neighbour j of the walk (i itself among them, at r = 0), with x_ij and r; 0 at the
 * end. */
GPU_FN int gpu_walk_next(const gpu_view *v, gpu_walk *w, uint32_t *j, double dx[3], double *r)
{
    const int d = v->d;
    const size_t n = v->n;
    for (;;) {
        while (w->s < w->s1) {
            const uint32_t s = w->s++;
            const double d0 = w->q[0] - v->xs[s];
            double rr = d0 * d0;
            dx[0] = d0;
            dx[1] = dx[2] = 0.0;
            if (d > 1) {
                const double d1 = w->q[1] - v->xs[n + s];
                rr += d1 * d1;
                dx[1] = d1;
            }
            if (d > 2) {
                const double d2 = w->q[2] - v->xs[2 * n + s];
                rr += d2 * d2;
                dx[2] = d2;
            }
            if (rr < v->g.radius2) {
                *j = v->order[s];
                *r = sqrt(rr);
                return 1;
            }
        }
        /* the next cell: axis 0 innermost, ascending */
        int a = 0;
        while (a < 3 && ++w->u[a] > w->ub[a]) {
            w->u[a] = w->ua[a];
            ++a;
        }
        if (a == 3) return 0;
        gpu_walk_cell(v, w);
    }
}

/* ---- the quintic spline (src/kernels/kernels.c) ---- */
GPU_FN double gpu_pos(double t)
{
    return t > 0.0 ? t : 0.0;
}
GPU_FN double gpu_pow5(double t)
{
    const double t2 = t * t;
    return t2 * t2 * t;
}
GPU_FN double gpu_pow4(double t)
{
    const double t2 = t * t;
    return t2 * t2;
}
GPU_FN double gpu_quintic_f(double q)
{
    const double w =
        gpu_pow5(3.0 - q) - 6.0 * gpu_pow5(gpu_pos(2.0 - q)) + 15.0 * gpu_pow5(gpu_pos(1.0 - q));
    return q >= 3.0 ? 0.0 : w;
}
GPU_FN double gpu_quintic_df(double q)
{
    const double w = -5.0 * gpu_pow4(3.0 - q) + 30.0 * gpu_pow4(gpu_pos(2.0 - q)) -
                     75.0 * gpu_pow4(gpu_pos(1.0 - q));
    return q >= 3.0 ? 0.0 : w;
}
GPU_FN double gpu_quintic_d2f(double q)
{
    const double t3 = 3.0 - q, t2 = gpu_pos(2.0 - q), t1 = gpu_pos(1.0 - q);
    const double w = 20.0 * t3 * t3 * t3 - 120.0 * t2 * t2 * t2 + 300.0 * t1 * t1 * t1;
    return q >= 3.0 ? 0.0 : w;
}
GPU_FN double gpu_w(const gpu_kern *k, double r)
{
    const double q = r * k->inv_h, v = k->norm * gpu_quintic_f(q);
    return q < k->support ? v : 0.0;
}
GPU_FN double gpu_dwr(const gpu_kern *k, double r)
{
    const double q = r * k->inv_h;
    const double v = k->norm1 * gpu_quintic_df(q) / (r > 0.0 ? r : 1.0);
    return !(q < k->support) ? 0.0 : r > 0.0 ? v : k->at_zero;
}

/* W''(r) (eval_batch's d2w select). */
GPU_FN double gpu_d2w(const gpu_kern *k, double r)
{
    const double q = r * k->inv_h, v = k->norm2 * gpu_quintic_d2f(q);
    return q < k->support ? v : 0.0;
}

/* ---- edac's passes (src/schemes/pysph/scheme.c) ---- */

/* Summation density ϱ = m Σ W, 1/V, m/ϱ and the neighbour average p̄ (visit_density). */
GPU_FN void dev_edac_density(const gpu_view *v, size_t i)
{
    const double *p = gv(v, GA_P, 0);
    gpu_walk w;
    gpu_walk_start(v, i, &w);
    double s = 0.0, ps = 0.0, dx[3], r;
    size_t cnt = 0;
    uint32_t j;
    while (gpu_walk_next(v, &w, &j, dx, &r)) {
        s += gpu_w(&v->k, r);
        ps += p[j];
        ++cnt;
    }
    const double m = v->c.m, rhos = m * s;
    gv(v, GA_NUMD, 0)[i] = s;
    gv(v, GA_RHOS, 0)[i] = rhos;
    v->vol[i] = 1.0 / s;
    v->mrho[i] = m / rhos;
    gv(v, GA_PAVG, 0)[i] = ps / (double)cnt;
}

/* The rates of tvf/edac at particle i (visit_tv_d with edac; the closure ϱ = m Σ W after), for
 * a dimension and gradients known at compile time: every small array is then registers. */
GPU_FN_INLINE void dev_edac_rates_d(const gpu_view *v, size_t i, const int d, const int grads)
{
    const pysph_consts *c = &v->c;
    const double *rho = gv(v, GA_RHOS, 0), *p = gv(v, GA_P, 0);
    const double rhoi = rho[i], pi = p[i], Vi = v->vol[i], pav = gv(v, GA_PAVG, 0)[i];
    double ui[3] = {0.0, 0.0, 0.0}, dui[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) {
        ui[a] = gv(v, GA_U, a)[i];
        dui[a] = gv(v, GA_TVDU, a)[i];
    }
    double f[3] = {0.0, 0.0, 0.0}, fb[3] = {0.0, 0.0, 0.0}, fp[3] = {0.0, 0.0, 0.0}, ap = 0.0;
    double G[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, div = 0.0;
    gpu_walk w;
    gpu_walk_start(v, i, &w);
    double xij[3], r;
    uint32_t j;
    while (gpu_walk_next(v, &w, &j, xij, &r)) {
        if (j == i) continue; /* ∇W_ii = 0: no force on itself */
        double uj[3] = {0.0, 0.0, 0.0}, duj[3] = {0.0, 0.0, 0.0};
        for (int a = 0; a < d; ++a) {
            uj[a] = gv(v, GA_U, a)[j];
            duj[a] = gv(v, GA_TVDU, a)[j];
        }
        pysph_pair o;
        pysph_tv_pair(d, 1, c, rhoi, pi, pav, Vi, ui, dui, rho[j], p[j], v->vol[j], v->mrho[j], uj,
                      duj, gpu_dwr(&v->k, r), xij, r, &o);
        for (int a = 0; a < d; ++a) {
            f[a] += o.f[a];
            fb[a] += o.fb[a];
            if (grads) fp[a] += o.fp[a];
        }
        if (grads)
            for (int e = 0; e < d * d; ++e) G[e] -= o.g[e];
        div -= o.div;
        ap += o.q1;
        ap += o.q2;
    }
    for (int a = 0; a < d; ++a) {
        gv(v, GA_AU, a)[i] = f[a] / c->m;
        gv(v, GA_AUHAT, a)[i] = fb[a] / c->m;
    }
    gv(v, GA_AQ, 0)[i] = ap;
    if (grads) {
        for (int a = 0; a < d; ++a) gv(v, GA_GRADP, a)[i] = -rhoi * fp[a];
        for (int e = 0; e < d * d; ++e) gv(v, GA_GRADU, e)[i] = G[e];
    }
    gv(v, GA_DIVU, 0)[i] = div;
    gv(v, GA_RHOF, 0)[i] = rhoi;
}

GPU_FN void dev_edac_rates_any(const gpu_view *v, size_t i)
{
    if (v->d == 2) {
        if (v->grads)
            dev_edac_rates_d(v, i, 2, 1);
        else
            dev_edac_rates_d(v, i, 2, 0);
    } else {
        if (v->grads)
            dev_edac_rates_d(v, i, 3, 1);
        else
            dev_edac_rates_d(v, i, 3, 0);
    }
}

/* ---- wcsph (src/schemes/pysph/scheme.c) ---- */

/* eos_ipow of src/solver/solver_internal.h: x^n by squaring, in its order. */
GPU_FN double gpu_ipow(double x, int n)
{
    double r = 1.0;
    for (; n; n >>= 1, x *= x)
        if (n & 1) r *= x;
    return r;
}

/* job_fields' per-particle values: p/ϱ², m/ϱ (with the gradients) and Tait's sound speed
 * c_o (ϱ/ρ_o)^((γ-1)/2) (with Monaghan's Π). */
GPU_FN void dev_wcsph_prep(const gpu_view *v, size_t i)
{
    const double rho = gv(v, GA_RHOF, 0)[i], p = gv(v, GA_P, 0)[i];
    v->vol[i] = p / (rho * rho);
    if (v->grads) v->mrho[i] = v->c.m / rho;
    if (v->av) v->cs[i] = v->c.c0 * gpu_ipow(rho / v->rho0, v->cs_exp);
}

/* visit_wcsph_d: the symmetric pressure force with Π_ij, the laminar viscosity, XSPH and the
 * continuity equation at particle i. */
GPU_FN_INLINE void dev_wcsph_rates_d(const gpu_view *v, size_t i, const int d, const int grads)
{
    const pysph_consts *c = &v->c;
    const double *rho = gv(v, GA_RHOF, 0), *pr2 = v->vol;
    const double rhoi = rho[i], ti = pr2[i];
    const int av = v->av;
    const double ci = av ? v->cs[i] : 0.0;
    double ui[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) ui[a] = gv(v, GA_U, a)[i];
    double f[3] = {0.0, 0.0, 0.0}, xs[3] = {0.0, 0.0, 0.0}, fp[3] = {0.0, 0.0, 0.0}, drho = 0.0;
    double G[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    gpu_walk w;
    gpu_walk_start(v, i, &w);
    double xij[3], r;
    uint32_t j;
    while (gpu_walk_next(v, &w, &j, xij, &r)) {
        if (j == i) continue;
        double uj[3] = {0.0, 0.0, 0.0};
        for (int a = 0; a < d; ++a) uj[a] = gv(v, GA_U, a)[j];
        const double inv_s = 1.0 / (rhoi + rho[j]), inv_r = 1.0 / (r * r + c->h2);
        double pij = 0.0;
        if (av) {
            double ux = 0.0;
            for (int a = 0; a < d; ++a) ux += (ui[a] - uj[a]) * xij[a];
            pij = pysph_monaghan_pi(c, ci, v->cs[j], ux, inv_r, inv_s);
        }
        pysph_pair o;
        pysph_wcsph_pair(d, c, ti, ui, pr2[j], grads ? v->mrho[j] : 0.0, uj, pij, gpu_w(&v->k, r),
                         gpu_dwr(&v->k, r), xij, inv_s, inv_r, &o);
        for (int a = 0; a < d; ++a) {
            f[a] += o.f[a];
            xs[a] -= o.fb[a];
            if (grads) fp[a] += o.fp[a];
        }
        drho += o.div;
        if (grads)
            for (int e = 0; e < d * d; ++e) G[e] -= o.g[e];
    }
    for (int a = 0; a < d; ++a) {
        gv(v, GA_AU, a)[i] = f[a];
        gv(v, GA_AX, a)[i] = ui[a] + xs[a];
    }
    gv(v, GA_AQ, 0)[i] = drho;
    if (grads) {
        for (int a = 0; a < d; ++a) gv(v, GA_GRADP, a)[i] = -rhoi * fp[a];
        for (int e = 0; e < d * d; ++e) gv(v, GA_GRADU, e)[i] = G[e];
    }
    gv(v, GA_DIVU, 0)[i] = -drho / rhoi;
}

#include "gpu/dev_negi.h"

/* The scheme's pass before the rates (edac: the density pass; wcsph: per-particle values) and
 * its rates, dispatched on the view. */
GPU_FN void dev_pre_rates(const gpu_view *v, size_t i)
{
    if (v->scheme == GS_EDAC)
        dev_edac_density(v, i);
    else
        dev_wcsph_prep(v, i);
}

GPU_FN void dev_rates(const gpu_view *v, size_t i)
{
    if (v->scheme == GS_EDAC) {
        dev_edac_rates_any(v, i);
    } else if (v->d == 2) {
        if (v->grads)
            dev_wcsph_rates_d(v, i, 2, 1);
        else
            dev_wcsph_rates_d(v, i, 2, 0);
    } else {
        if (v->grads)
            dev_wcsph_rates_d(v, i, 3, 1);
        else
            dev_wcsph_rates_d(v, i, 3, 0);
    }
}

#endif
