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
 *  - the passes: src/schemes/pysph/scheme.c's visit_density and visit_tv_d (edac, tvf), job_fields'
 *    per-particle values and visit_wcsph_d (wcsph), summing the same pysph_tv_pair and
 *    pysph_wcsph_pair terms (src/schemes/pysph/iact.h) in the same neighbour order;
 *  - the integrator: src/integrators/integrators.c's set_fields and drift with edac's transport
 *    hook (pec), step_kdk with tvf's (kdk), the solver's wrap_positions and closures (edac's and
 *    tvf's summation density, wcsph's EOS of src/solver/solver.c's solver_eos). */
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

/* NAME(v, i): BODY(v, i, D) for the view's dimension, BODY written with D a compile-time
 * constant once inlined (its small arrays then stay in registers). */
#define GPU_BY_DIM(name, body)                                                                     \
    GPU_FN void name(const gpu_view *v, size_t i)                                                  \
    {                                                                                              \
        if (v->d == 2)                                                                             \
            body(v, i, 2);                                                                         \
        else                                                                                       \
            body(v, i, 3);                                                                         \
    }

/* A load of what no thread of the kernel writes, through the GPU's read-only data path. */
#if defined(__CUDA_ARCH__)
#define GPU_LDG(p) __ldg(p)
#else
#define GPU_LDG(p) (*(p))
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
    GA_MASS,  /* the δ-SPH family's masses m_i = ρ_i(0) Δs^d */
    GA_COUNT
};

/* The schemes the GPU runs (GS_TVF: tvf, edac's passes without p̄ and dp/dt, under kdk). */
enum { GS_EDAC, GS_WCSPH, GS_NEGI, GS_TVF, GS_DELTA };

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
    /* n records of 4 doubles in slot order: the coordinates and edac's p (x, y, p, 0 in 2D;
     * x, y, z, p in 3D), what the walk of the passes reads of each candidate in 16-byte loads */
    double *xp;
    uint32_t *slot_of; /* n: the slot of each particle (order's inverse) */
    /* n records of gpu_pack_width doubles in slot order: what the rate pass reads of each
     * neighbour (written by the pass before it), so that a pair reads one record, not one value
     * from each of a dozen arrays */
    double *pack;
    uint32_t *cell;  /* n: the cell of each particle */
    uint32_t *count; /* ncells + 1: particles per cell, then the scatter's fill */
    uint32_t *start; /* ncells + 1: the first slot of each cell */
    uint32_t *order; /* n: the particle in each slot */
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
    /* n: the neighbours (i itself among them) of the passes the CPU counts in consph_solver's
     * pairs, summed per particle index over the run (each thread adds its own; the total is the
     * run's whatever the re-sorts did to the indices), and their sums per GPU_PAIR_CHUNK */
    unsigned long long *pairs, *pair_chunks;
    /* the δ-SPH family (GS_DELTA, dev_delta.h; its δ h c_o in Dq, its L_i in the bonet field,
     * ⟨∇ρ⟩^L in GA_GRADQ, δu in GA_SHIFT): the shifting form (iact.h's DELTA_SHIFT_*), the
     * viscosity's (α h c_o + 2(d + 2) ν) ρ_o, and 1/Δt of the step (δu = δr/Δt) */
    int dshift;
    double dvisc, dinv_dt;
} gpu_view;

GPU_FN double *gv(const gpu_view *v, int q, int comp)
{
    return v->a + (size_t)(v->at[q] + comp) * v->n;
}

/* A counted pass's neighbours of particle i (consph_pass_run_counted's Σ nb.n). */
GPU_FN_INLINE void gpu_pairs_add(const gpu_view *v, size_t i, size_t hits)
{
    v->pairs[i] += (unsigned long long)hits;
}

/* The particles one thread of dev_pair_sum adds up. */
#define GPU_PAIR_CHUNK 1024

/* The pair counts of particles [t GPU_PAIR_CHUNK, (t + 1) GPU_PAIR_CHUNK) into pair_chunks[t]:
 * integers, so the total is exact in any order (no atomics). */
GPU_FN void dev_pair_sum(const gpu_view *v, size_t t)
{
    const size_t i0 = t * GPU_PAIR_CHUNK;
    const size_t i1 = i0 + GPU_PAIR_CHUNK < v->n ? i0 + GPU_PAIR_CHUNK : v->n;
    unsigned long long s = 0;
    for (size_t i = i0; i < i1; ++i) s += v->pairs[i];
    v->pair_chunks[t] = s;
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

/* The search's copy of the coordinates in slot order (xp, with edac's p beside them: the
 * density pass reads its neighbours' p), and each particle's slot. */
GPU_FN void dev_slots(const gpu_view *v, size_t s)
{
    const uint32_t i = v->order[s];
    double *rec = v->xp + 4 * s;
    rec[2] = rec[3] = 0.0;
    for (int a = 0; a < v->d; ++a) {
        const double x = gpu_stored(&v->g, a, gv(v, GA_X, a)[i]);
        rec[a] = x;
    }
    if (v->scheme == GS_EDAC) rec[v->d] = gv(v, GA_P, 0)[i];
    v->slot_of[i] = (uint32_t)s;
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

/* A drifted coordinate wrapped into a periodic box (the solver's wrap_positions). */
GPU_FN double gpu_wrap(const gpu_grid *g, int a, double x)
{
    if (g->periodic[a]) {
        const double lo = g->lo[a], L = g->len[a];
        if (x < lo || x >= lo + L) {
            x -= L * floor((x - lo) / L);
            if (x >= lo + L) x = lo; /* rounding of a tiny negative offset */
        }
    }
    return x;
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
        gv(v, GA_X, a)[i] = gpu_wrap(g, a, gv(v, GA_X0, a)[i] + c * ax);
    }
    if (edac)
        gv(v, GA_RHOF, 0)[i] = gv(v, GA_RHOS, 0)[i];
    else
        gpu_close(v, i);
}

/* ---- tvf's kick-drift-kick (src/integrators/integrators.c's step_kdk) ----
 * The first half kick of u0, q0 with the rates the previous step left, u = u0, tvf's transport
 * hook (ũ - u = Δt/2 ã, dx/dt = u + ũ - u: scheme.c's tv_transport), the drift x = x0 + Δt dx/dt
 * wrapped as the solver's wrap_positions, q = q0 and the closure ϱ = m Σ W. */
GPU_FN void dev_kdk_drift(const gpu_view *v, size_t i, double dt)
{
    const gpu_grid *g = &v->g;
    const double c = 0.5 * dt;
    double *q0 = gv(v, GA_Q0, 0);
    q0[i] += 0.5 * dt * gv(v, GA_AQ, 0)[i];
    for (int a = 0; a < v->d; ++a) {
        double *u0 = gv(v, GA_U0, a);
        u0[i] += 0.5 * dt * gv(v, GA_AU, a)[i];
        const double u = u0[i], du = c * gv(v, GA_AUHAT, a)[i], ax = u + du;
        gv(v, GA_U, a)[i] = u;
        gv(v, GA_TVDU, a)[i] = du;
        gv(v, GA_AX, a)[i] = ax;
        gv(v, GA_X, a)[i] = gpu_wrap(g, a, gv(v, GA_X0, a)[i] + dt * ax);
    }
    gv(v, GA_Q, 0)[i] = q0[i];
    gv(v, GA_RHOF, 0)[i] = gv(v, GA_RHOS, 0)[i];
}

/* The second kick (set_fields with c = Δt/2: u, q = u0, q0 + c (au, aq)) and the closure; the
 * particles stay where the drift put them. */
GPU_FN void dev_kdk_kick(const gpu_view *v, size_t i, double c)
{
    gv(v, GA_Q, 0)[i] = gv(v, GA_Q0, 0)[i] + c * gv(v, GA_AQ, 0)[i];
    for (int a = 0; a < v->d; ++a) gv(v, GA_U, a)[i] = gv(v, GA_U0, a)[i] + c * gv(v, GA_AU, a)[i];
    gv(v, GA_RHOF, 0)[i] = gv(v, GA_RHOS, 0)[i];
}

/* ---- the neighbour walk, for a dimension known at compile time, by rows of cells ----
 * Every pair pass walks particle i's neighbours in the CPU search's order: the cells of reach
 * around i's, unwrapped (a periodic axis gives images), axis 0 innermost and ascending, each
 * cell's slots in order, i itself among the neighbours at r = 0. A cell farther than the radius
 * (widened by the rounding of binning, as the CPU's walk widens it by its slack) holds no
 * neighbour; skipping it changes which cells are read, never the neighbours or their order.
 * The walk goes by rows of cells along axis 0: cells u0 .. u0 + k of a row are adjacent in the
 * counting sort, so their slots are one range, read as one (split only where a periodic axis 0
 * wraps, the image shift changing). A row is skipped when its gap along axes 1 and 2 alone puts
 * every cell of it beyond the radius, and trimmed at each end by the cell test (gpu_walkr_far),
 * so that every cell that may hold a neighbour is read (rounding is monotone: a row's bound never
 * exceeds a cell's gap), and the few cells between read more are only extra candidates, never
 * neighbours. tests/test_gpu_walk.c holds the walk to a cell-by-cell one. D is a constant once
 * inlined (the loops over axes unroll), the cell coordinates are 32-bit (gpu_attach bounds the
 * reach), and the walk yields slots: edac's and wcsph's passes read their neighbours' values in
 * slot order (xp, pack), 001's family through the particle index (dev_negi.h). */
typedef struct gpu_walkr {
    int u[3], ua[3], ub[3]; /* u[1], u[2]: the current row */
    int u0, last0;          /* the row's next cell along axis 0, and its last */
    double xi[3], q[3];
    double g1, g2; /* the row's squared gaps along axes 1 and 2 */
    size_t row;    /* the row's first cell index without axis 0: (c2 nc1 + c1) nc0 */
    uint32_t s, s1;
    uint32_t hits; /* neighbours yielded so far, i's own images among them (gpu_pairs_add) */
} gpu_walkr;

GPU_FN int gpu_floor_div32(int u, int d)
{
    if (u >= 0 && u < d) return 0;
    if (u < 0 && u >= -d) return -1;
    const int q = u / d;
    return (u % d != 0 && u < 0) ? q - 1 : q;
}

/* The gap of cell u along axis a from x (0 inside it, and beyond a wall's open side). */
GPU_FN_INLINE double gpu_gap(const gpu_grid *g, int a, int u, double x)
{
    const double lo = g->lo[a] + (double)u * g->h[a];
    const double hi = g->lo[a] + (double)(u + 1) * g->h[a];
    const int open_lo = !g->periodic[a] && u == 0;
    const int open_hi = !g->periodic[a] && u == (int)g->nc[a] - 1;
    return (!open_lo && x < lo) ? lo - x : (!open_hi && x > hi) ? x - hi : 0.0;
}

/* The cell test: cell u0 of the current row lies beyond the pruning radius. */
GPU_FN_INLINE int gpu_walkr_far(const gpu_view *v, const gpu_walkr *w, int u0, const int D)
{
    const double g0 = gpu_gap(&v->g, 0, u0, w->xi[0]);
    double gap2 = 0.0;
    gap2 += g0 * g0;
    if (D > 1) gap2 += w->g1;
    if (D > 2) gap2 += w->g2;
    return gap2 > v->g.prune2;
}

/* Sets the walk on row (u[1], u[2]); 0 when no cell of it can hold a neighbour. */
GPU_FN_INLINE int gpu_walkr_row(const gpu_view *v, gpu_walkr *w, const int D)
{
    const gpu_grid *g = &v->g;
    w->g1 = w->g2 = 0.0;
    if (D > 1) {
        const double g1 = gpu_gap(g, 1, w->u[1], w->xi[1]);
        w->g1 = g1 * g1;
    }
    if (D > 2) {
        const double g2 = gpu_gap(g, 2, w->u[2], w->xi[2]);
        w->g2 = g2 * g2;
    }
    double bound = 0.0;
    if (D > 1) bound += w->g1;
    if (D > 2) bound += w->g2;
    if (bound > g->prune2) return 0;
    int first = w->ua[0], last = w->ub[0];
    while (first <= last && gpu_walkr_far(v, w, first, D)) ++first;
    while (last >= first && gpu_walkr_far(v, w, last, D)) --last;
    if (first > last) return 0;
    size_t row = 0;
    for (int a = D - 1; a >= 1; --a) {
        const int nc = (int)g->nc[a];
        int ca = w->u[a];
        double shift = 0.0;
        if (g->periodic[a]) {
            const int m = gpu_floor_div32(w->u[a], nc);
            ca = w->u[a] - m * nc;
            shift = (double)m * g->len[a];
        }
        row = row * (size_t)nc + (size_t)ca;
        w->q[a] = w->xi[a] - shift;
    }
    w->row = row * (size_t)g->nc[0];
    w->u0 = first;
    w->last0 = last;
    return 1;
}

/* The next range of slots of the row: its cells from u0 to the row's last or the wrap of a
 * periodic axis 0, whichever comes first. */
GPU_FN_INLINE void gpu_walkr_range(const gpu_view *v, gpu_walkr *w)
{
    const gpu_grid *g = &v->g;
    const int nc = (int)g->nc[0];
    int c0 = w->u0;
    double shift = 0.0;
    if (g->periodic[0]) {
        const int m = gpu_floor_div32(w->u0, nc);
        c0 = w->u0 - m * nc;
        shift = (double)m * g->len[0];
    }
    int k = w->last0 - w->u0; /* cells after the first */
    if (k > nc - 1 - c0) k = nc - 1 - c0;
    w->q[0] = w->xi[0] - shift;
    w->s = GPU_LDG(&v->start[w->row + (size_t)c0]);
    w->s1 = GPU_LDG(&v->start[w->row + (size_t)(c0 + k + 1)]);
    w->u0 += k + 1;
}

/* Moves to the next row that may hold a neighbour, from the current one; 0 at the end. */
GPU_FN_INLINE int gpu_walkr_seek(const gpu_view *v, gpu_walkr *w, const int D)
{
    for (;;) {
        if (gpu_walkr_row(v, w, D)) return 1;
        int a = 1;
        while (a < D && ++w->u[a] > w->ub[a]) {
            w->u[a] = w->ua[a];
            ++a;
        }
        if (a == D) return 0;
    }
}

/* A candidate's coordinates from its xp record (one 16-byte load in 2D, two in 3D). */
GPU_FN_INLINE void gpu_xp_read(const double *rec, double x[4], const int D)
{
#if defined(__CUDA_ARCH__)
    const double2 a = __ldg((const double2 *)rec);
    x[0] = a.x;
    x[1] = a.y;
    x[2] = x[3] = 0.0;
    if (D > 2) {
        const double2 b = __ldg((const double2 *)(rec + 2));
        x[2] = b.x;
    }
#else
    for (int a = 0; a < 4; ++a) x[a] = a < D ? rec[a] : 0.0;
#endif
}

/* Starts the walk of particle i at its first row. */
GPU_FN_INLINE void gpu_walkr_start(const gpu_view *v, size_t i, gpu_walkr *w, const int D)
{
    const gpu_grid *g = &v->g;
    for (int a = 0; a < D; ++a) {
        const int nc = (int)g->nc[a], reach = (int)g->reach[a];
        w->xi[a] = gpu_stored(g, a, gv(v, GA_X, a)[i]);
        w->q[a] = 0.0; /* set by every row and range that is read */
        const int c = (int)gpu_cell_axis(g, a, w->xi[a]);
        w->ua[a] = c - reach;
        w->ub[a] = c + reach;
        if (!g->periodic[a]) {
            if (w->ua[a] < 0) w->ua[a] = 0;
            if (w->ub[a] > nc - 1) w->ub[a] = nc - 1;
        }
        w->u[a] = w->ua[a];
    }
    w->s = w->s1 = 0;
    w->hits = 0;
    w->row = 0;
    w->u0 = 1;
    w->last0 = 0;
    gpu_walkr_seek(v, w, D); /* i's own cell is never pruned: a row is found */
}

/* The next neighbour's slot (i's own among them, at r = 0), with x_ij and r; 0 at the end. */
GPU_FN_INLINE int gpu_walkr_next(const gpu_view *v, gpu_walkr *w, const int D, uint32_t *slot,
                                 double dx[3], double *r)
{
    for (;;) {
        while (w->s < w->s1) {
            const uint32_t s = w->s++;
            double x[4];
            gpu_xp_read(v->xp + 4 * (size_t)s, x, D);
            const double d0 = w->q[0] - x[0];
            double rr = d0 * d0;
            dx[0] = d0;
            dx[1] = dx[2] = 0.0;
            if (D > 1) {
                const double d1 = w->q[1] - x[1];
                rr += d1 * d1;
                dx[1] = d1;
            }
            if (D > 2) {
                const double d2 = w->q[2] - x[2];
                rr += d2 * d2;
                dx[2] = d2;
            }
            if (rr < v->g.radius2) {
                *slot = s;
                *r = sqrt(rr);
                ++w->hits;
                return 1;
            }
        }
        if (w->u0 <= w->last0) {
            gpu_walkr_range(v, w);
            continue;
        }
        /* the next row: axis 1 innermost, ascending */
        int a = 1;
        while (a < D && ++w->u[a] > w->ub[a]) {
            w->u[a] = w->ua[a];
            ++a;
        }
        if (a == D || !gpu_walkr_seek(v, w, D)) return 0;
    }
}

/* The next neighbour other than i itself (slot self): the rate passes' sums leave out j = i,
 * where ∇W_ii = 0. */
GPU_FN_INLINE int gpu_walkr_other(const gpu_view *v, gpu_walkr *w, const int D, uint32_t self,
                                  uint32_t *slot, double dx[3], double *r)
{
    while (gpu_walkr_next(v, w, D, slot, dx, r))
        if (*slot != self) return 1; /* every image of i is left out, as j == i is on the CPU */
    return 0;
}

/* Neighbours whose pair terms a rate pass computes at once (1 or 2): two independent pair
 * computations give the GPU two chains of divisions and square roots to interleave, where one
 * thread's chain would wait on each; the sums still add the pairs one at a time, in the
 * neighbour order, so the results are the same bits either way. */
#ifndef CONSPH_GPU_PAIRS
#define CONSPH_GPU_PAIRS 1
#endif

/* The second neighbour of a two-at-once step: 1 when there is one; else 0, and the first is
 * repeated, so that its pair term is computed (the two chains stay alike) and not added. */
GPU_FN_INLINE int gpu_walkr_second(const gpu_view *v, gpu_walkr *w, const int D, uint32_t self,
                                   uint32_t sa, const double xa[3], double ra, uint32_t *sb,
                                   double xb[3], double *rb)
{
    if (gpu_walkr_other(v, w, D, self, sb, xb, rb)) return 1;
    *sb = sa;
    *rb = ra;
    for (int a = 0; a < 3; ++a) xb[a] = xa[a];
    return 0;
}

/* ---- the neighbour records (gpu_view's pack) ----
 * edac and tvf: ϱ, p, V, m/ϱ, u, ũ - u (4 + 2d); wcsph: ϱ, p/ϱ², m/ϱ, c_s, u (4 + d, padded to
 * even): an even width keeps every record on 16 bytes, read in pairs of doubles. */
GPU_FN int gpu_pack_width(int scheme, int d)
{
    return scheme == GS_EDAC || scheme == GS_TVF ? 4 + 2 * d : (4 + d + 1) & ~1;
}

GPU_FN_INLINE void gpu_pack_read(const double *rec, double *q, const int K)
{
#if defined(__CUDA_ARCH__)
    for (int k = 0; k < K; k += 2) {
        const double2 t = __ldg((const double2 *)(rec + k));
        q[k] = t.x;
        q[k + 1] = t.y;
    }
#else
    for (int k = 0; k < K; ++k) q[k] = rec[k];
#endif
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

/* Summation density ϱ = m Σ W, 1/V, m/ϱ and edac's neighbour average p̄ or tvf's
 * p = p_o (ϱ/ρ_o - 1) (visit_density, p_o = c_o² ρ_o as job_fields has it); then the particle's
 * record for the rate pass. */
GPU_FN_INLINE void dev_tv_density_d(const gpu_view *v, size_t i, const int D, const int edac)
{
    const double *ps = v->xp + D; /* edac's p in slot order, stride 4 */
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, D);
    double s = 0.0, psum = 0.0, dx[3], r;
    size_t cnt = 0;
    uint32_t sl;
    while (gpu_walkr_next(v, &w, D, &sl, dx, &r)) {
        s += gpu_w(&v->k, r);
        if (edac) psum += GPU_LDG(&ps[4 * (size_t)sl]);
        ++cnt;
    }
    /* this pass's neighbours and the rate pass's: it walks the same ones (the same positions and
     * cell lists), and a counter there costs the capped rate kernels spills */
    gpu_pairs_add(v, i, 2 * cnt);
    const double m = v->c.m, rhos = m * s, vol = 1.0 / s, mrho = m / rhos;
    gv(v, GA_NUMD, 0)[i] = s;
    gv(v, GA_RHOS, 0)[i] = rhos;
    v->vol[i] = vol;
    v->mrho[i] = mrho;
    double pi;
    if (edac) {
        gv(v, GA_PAVG, 0)[i] = psum / (double)cnt;
        pi = gv(v, GA_P, 0)[i];
    } else {
        pi = v->c2 * v->rho0 * (rhos / v->rho0 - 1.0);
        gv(v, GA_P, 0)[i] = pi;
    }
    double *rec = v->pack + (size_t)v->slot_of[i] * (size_t)(4 + 2 * D);
    rec[0] = rhos;
    rec[1] = pi;
    rec[2] = vol;
    rec[3] = mrho;
    for (int a = 0; a < D; ++a) {
        rec[4 + a] = gv(v, GA_U, a)[i];
        rec[4 + D + a] = gv(v, GA_TVDU, a)[i];
    }
}

GPU_FN_INLINE void dev_edac_density_d(const gpu_view *v, size_t i, const int D)
{
    dev_tv_density_d(v, i, D, 1);
}

GPU_FN void dev_tv_density(const gpu_view *v, size_t i)
{
    const int edac = v->scheme == GS_EDAC;
    if (v->d == 2)
        edac ? dev_tv_density_d(v, i, 2, 1) : dev_tv_density_d(v, i, 2, 0);
    else
        edac ? dev_tv_density_d(v, i, 3, 1) : dev_tv_density_d(v, i, 3, 0);
}

/* edac's or tvf's pair term of i and the neighbour in slot sl (its values from the slot's
 * record). */
GPU_FN_INLINE void gpu_edac_pair(const gpu_view *v, const int d, const int edac, double rhoi,
                                 double pi, double pav, double Vi, const double ui[3],
                                 const double dui[3], uint32_t sl, const double xij[3], double r,
                                 pysph_pair *o)
{
    double q[10], uj[3] = {0.0, 0.0, 0.0}, duj[3] = {0.0, 0.0, 0.0};
    gpu_pack_read(v->pack + (size_t)sl * (size_t)(4 + 2 * d), q, 4 + 2 * d);
    for (int a = 0; a < d; ++a) {
        uj[a] = q[4 + a];
        duj[a] = q[4 + d + a];
    }
    pysph_tv_pair(d, edac, &v->c, rhoi, pi, pav, Vi, ui, dui, q[0], q[1], q[2], q[3], uj, duj,
                  gpu_dwr(&v->k, r), xij, r, o);
}

/* One pair added into edac's or tvf's sums, each in visit_tv_d's order (tvf adds nothing to
 * dp/dt). */
GPU_FN_INLINE void gpu_edac_add(const pysph_pair *o, const int d, const int edac, const int grads,
                                double f[3], double fb[3], double fp[3], double G[9], double *div,
                                double *ap)
{
    for (int a = 0; a < d; ++a) {
        f[a] += o->f[a];
        fb[a] += o->fb[a];
        if (grads) fp[a] += o->fp[a];
    }
    if (grads)
        for (int e = 0; e < d * d; ++e) G[e] -= o->g[e];
    *div -= o->div;
    if (edac) {
        *ap += o->q1;
        *ap += o->q2;
    }
}

/* The rates of edac or tvf at particle i (visit_tv_d; the closure ϱ = m Σ W after), for a
 * dimension, scheme and gradients known at compile time: every small array is then registers. */
GPU_FN_INLINE void dev_tv_rates_d(const gpu_view *v, size_t i, const int d, const int edac,
                                  const int grads)
{
    const pysph_consts *c = &v->c;
    const double *rho = gv(v, GA_RHOS, 0), *p = gv(v, GA_P, 0);
    const double rhoi = rho[i], pi = p[i], Vi = v->vol[i];
    const double pav = edac ? gv(v, GA_PAVG, 0)[i] : 0.0;
    double ui[3] = {0.0, 0.0, 0.0}, dui[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) {
        ui[a] = gv(v, GA_U, a)[i];
        dui[a] = gv(v, GA_TVDU, a)[i];
    }
    double f[3] = {0.0, 0.0, 0.0}, fb[3] = {0.0, 0.0, 0.0}, fp[3] = {0.0, 0.0, 0.0}, ap = 0.0;
    double G[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, div = 0.0;
    const uint32_t self = v->slot_of[i];
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, d);
    double xa[3], xb[3], ra, rb;
    uint32_t sa, sb;
    while (gpu_walkr_other(v, &w, d, self, &sa, xa, &ra)) {
        const int hb =
            CONSPH_GPU_PAIRS == 2 && gpu_walkr_second(v, &w, d, self, sa, xa, ra, &sb, xb, &rb);
        pysph_pair oa, ob;
        gpu_edac_pair(v, d, edac, rhoi, pi, pav, Vi, ui, dui, sa, xa, ra, &oa);
        if (CONSPH_GPU_PAIRS == 2)
            gpu_edac_pair(v, d, edac, rhoi, pi, pav, Vi, ui, dui, sb, xb, rb, &ob);
        gpu_edac_add(&oa, d, edac, grads, f, fb, fp, G, &div, &ap);
        if (CONSPH_GPU_PAIRS == 2) {
            if (!hb) break;
            gpu_edac_add(&ob, d, edac, grads, f, fb, fp, G, &div, &ap);
        }
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

GPU_FN_INLINE void dev_edac_rates_d(const gpu_view *v, size_t i, const int d, const int grads)
{
    dev_tv_rates_d(v, i, d, 1, grads);
}

GPU_FN_INLINE void dev_tvf_rates_d(const gpu_view *v, size_t i, const int d, const int grads)
{
    dev_tv_rates_d(v, i, d, 0, grads);
}

GPU_FN void dev_tv_rates_any(const gpu_view *v, size_t i)
{
    const int edac = v->scheme == GS_EDAC;
    if (v->d == 2) {
        if (v->grads)
            edac ? dev_edac_rates_d(v, i, 2, 1) : dev_tvf_rates_d(v, i, 2, 1);
        else
            edac ? dev_edac_rates_d(v, i, 2, 0) : dev_tvf_rates_d(v, i, 2, 0);
    } else {
        if (v->grads)
            edac ? dev_edac_rates_d(v, i, 3, 1) : dev_tvf_rates_d(v, i, 3, 1);
        else
            edac ? dev_edac_rates_d(v, i, 3, 0) : dev_tvf_rates_d(v, i, 3, 0);
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
    const double pr2 = p / (rho * rho);
    const double mrho = v->grads ? v->c.m / rho : 0.0;
    const double cs = v->av ? v->c.c0 * gpu_ipow(rho / v->rho0, v->cs_exp) : 0.0;
    v->vol[i] = pr2;
    if (v->grads) v->mrho[i] = mrho;
    if (v->av) v->cs[i] = cs;
    double *rec = v->pack + (size_t)v->slot_of[i] * (size_t)gpu_pack_width(GS_WCSPH, v->d);
    rec[0] = rho;
    rec[1] = pr2;
    rec[2] = mrho;
    rec[3] = cs;
    for (int a = 0; a < v->d; ++a) rec[4 + a] = gv(v, GA_U, a)[i];
    if (v->d == 3) rec[7] = 0.0;
}

/* wcsph's pair term of i and the neighbour in slot sl (its values from the slot's record), with
 * Monaghan's Π where α > 0. */
GPU_FN_INLINE void gpu_wcsph_pair(const gpu_view *v, const int d, const int grads, double rhoi,
                                  double ti, double ci, const double ui[3], uint32_t sl,
                                  const double xij[3], double r, pysph_pair *o)
{
    const pysph_consts *c = &v->c;
    const int K = (4 + d + 1) & ~1; /* gpu_pack_width */
    double q[8], uj[3] = {0.0, 0.0, 0.0};
    gpu_pack_read(v->pack + (size_t)sl * (size_t)K, q, K);
    for (int a = 0; a < d; ++a) uj[a] = q[4 + a];
    const double inv_s = 1.0 / (rhoi + q[0]), inv_r = 1.0 / (r * r + c->h2);
    double pij = 0.0;
    if (v->av) {
        double ux = 0.0;
        for (int a = 0; a < d; ++a) ux += (ui[a] - uj[a]) * xij[a];
        pij = pysph_monaghan_pi(c, ci, q[3], ux, inv_r, inv_s);
    }
    pysph_wcsph_pair(d, c, ti, ui, q[1], grads ? q[2] : 0.0, uj, pij, gpu_w(&v->k, r),
                     gpu_dwr(&v->k, r), xij, inv_s, inv_r, o);
}

/* One pair added into wcsph's sums, each in visit_wcsph_d's order. */
GPU_FN_INLINE void gpu_wcsph_add(const pysph_pair *o, const int d, const int grads, double f[3],
                                 double xs[3], double fp[3], double G[9], double *drho)
{
    for (int a = 0; a < d; ++a) {
        f[a] += o->f[a];
        xs[a] -= o->fb[a];
        if (grads) fp[a] += o->fp[a];
    }
    *drho += o->div;
    if (grads)
        for (int e = 0; e < d * d; ++e) G[e] -= o->g[e];
}

/* visit_wcsph_d: the symmetric pressure force with Π_ij, the laminar viscosity, XSPH and the
 * continuity equation at particle i. */
GPU_FN_INLINE void dev_wcsph_rates_d(const gpu_view *v, size_t i, const int d, const int grads)
{
    const double *rho = gv(v, GA_RHOF, 0), *pr2 = v->vol;
    const double rhoi = rho[i], ti = pr2[i];
    const int av = v->av;
    const double ci = av ? v->cs[i] : 0.0;
    double ui[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) ui[a] = gv(v, GA_U, a)[i];
    double f[3] = {0.0, 0.0, 0.0}, xs[3] = {0.0, 0.0, 0.0}, fp[3] = {0.0, 0.0, 0.0}, drho = 0.0;
    double G[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    const uint32_t self = v->slot_of[i];
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, d);
    double xa[3], xb[3], ra, rb;
    uint32_t sa, sb;
    while (gpu_walkr_other(v, &w, d, self, &sa, xa, &ra)) {
        const int hb =
            CONSPH_GPU_PAIRS == 2 && gpu_walkr_second(v, &w, d, self, sa, xa, ra, &sb, xb, &rb);
        pysph_pair oa, ob;
        gpu_wcsph_pair(v, d, grads, rhoi, ti, ci, ui, sa, xa, ra, &oa);
        if (CONSPH_GPU_PAIRS == 2) gpu_wcsph_pair(v, d, grads, rhoi, ti, ci, ui, sb, xb, rb, &ob);
        gpu_wcsph_add(&oa, d, grads, f, xs, fp, G, &drho);
        if (CONSPH_GPU_PAIRS == 2) {
            if (!hb) break;
            gpu_wcsph_add(&ob, d, grads, f, xs, fp, G, &drho);
        }
    }
    gpu_pairs_add(v, i, w.hits);
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
#include "gpu/dev_delta.h"

/* The scheme's pass before the rates (edac: the density pass; wcsph: per-particle values) and
 * its rates, dispatched on the view. */
GPU_FN void dev_pre_rates(const gpu_view *v, size_t i)
{
    if (v->scheme == GS_EDAC || v->scheme == GS_TVF)
        dev_tv_density(v, i);
    else
        dev_wcsph_prep(v, i);
}

GPU_FN void dev_rates(const gpu_view *v, size_t i)
{
    if (v->scheme == GS_EDAC || v->scheme == GS_TVF) {
        dev_tv_rates_any(v, i);
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
