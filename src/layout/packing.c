/* The packed (PP) arrangement of 001 §3: "particles slightly perturbed from a uniform mesh ...
 * allowed to settle into a distribution with a nearly constant density using a particle packing
 * algorithm [51]" ([51] = Negi & Ramachandran 2021, CPC 265:108008). Two layout kinds:
 *
 *   packed           [51]'s packing as its authors' implementation runs it on free particles
 *                    (PySPH tools/particle_packing.py, class ParticlePacking, with no boundary):
 *                    one stage and its stopping rule;
 *   packed-polished  consph's two-stage relaxation: that packing (with symplectic steps) until
 *                    it stalls, then a density polish to max|rho/rho0 - 1| < tol.
 *
 * Both start from the cell-centred lattice with every coordinate moved by perturb·Δs·(2U - 1),
 * U uniform in [0, 1) drawn from the seeded generator.
 *
 * [51]'s packing: damped motion under the "background pressure" force and a short-range
 * repulsion,
 *
 *     du_i/dt = -(p_b/m) sum_j V_i V_j ∇_i W_ij + sum_{j: r_ij < 1.5c} g(r_ij) x_ij - ν u_i,
 *     g(r) = 12 k (3c^2/r^5 - 2c/r^4) where positive, r floored at h/2,
 *
 * V_i = m/rho_i from the summation density rho_i = m sum_j W_ij, m = rho0 Δs^d. Parameters are
 * the defaults of that implementation: p_b = 1 with rho0 = 1 (c0 = sqrt(p_b/rho0) = 1);
 * ν = 0.2/Δs in 2D, 0.5/Δs in 3D; k = 0.004Δs in 2D, 0.006Δs in 3D (it sets none for 1D; 1D
 * takes the 2D values); c = (2/3)·0.95Δs (repulsion range 0.95Δs, whatever h). The boundary-node
 * machinery of [51] has nothing to do in a periodic box and is left out.
 *
 * packed runs this with the caller's kernel (default the quintic at h = 1.2Δs, [51]'s and 001's
 * setting), as the implementation runs with its solver's kernel and hdx, and integrates like it:
 * explicit Euler, x_{n+1} = x_n + Δt_n u_n, u_{n+1} = u_n + Δt_n (a_n - ν u_n), with its adaptive
 * step Δt_n = min(0.1 h/c0, min_i sqrt(0.1 h/(ν |u_i|))) computed from the new velocities (the
 * viscous limit binds only for |u| > 40 c0, i.e. never here), the fixed 1e-7 its step rule gives
 * at t = 0 for the first two steps, and its solver's start-up ramp (n_damp = 10: step n uses the
 * fraction (1 + sin(π((n + 1)/10 - 1/2)))/2 of its size, n < 10). Its stopping rule: after every
 * 50th step (steps 1, 51, 101, ...; its dfreq) the largest displacement of the step relative to h,
 * 100 max_i |u_i| Δt / h (in percent), is tested against move_tol (its tol, default 1e-2), and the
 * run stops at the first test that passes from the 11th test on; or after max_iter steps (its
 * max_steps, 40000; its final time tf = 200 is never reached first at these resolutions and is
 * left out). The result is a glass: with perturb = 0.5 its geometry is that of the authors'
 * packed files (docs/deviations.md: 2D nx = 100 and 200 give max|rho/rho0 - 1| 8.2e-3 / 1.0e-2,
 * nearest-neighbour mean 0.980 / 0.986Δs, mean distance to the lattice node 0.367 / 0.371Δs,
 * against 8.8e-3 / 9.2e-3, 0.972 / 0.981 and 0.357 / 0.364 on the files). Smaller perturbations
 * relax back towards the square lattice, a stable equilibrium of these forces (measured at
 * nx = 50 with the two-stage kind: mean distance to the node 0.02Δs at perturb = 0.25, 0.09Δs
 * at 0.3, 0.18Δs at 0.35, 0.34Δs at 0.5). The equilibrium is not uniform density: the spread
 * stalls at several 1e-3.
 *
 * packed with walls = L > 0: the same packing inside a frozen container, as the authors' packed
 * files were made. Those files (pysphApproximator approximator/data/nx*.npz: x and y only; the
 * repository has no script that makes them) keep every particle 0.37-0.38Δs inside the square
 * at all six resolutions and line a row of particles 0.4-0.6Δs from each wall, an empty band
 * 0.6-1Δs, the next row near 1.4Δs: the packing of a walled square, not of a periodic box. Read
 * as periodic (as 001's PP runs use them), two wall rows meet at each box edge, and all their
 * closest pairs (0.79-0.86Δs) are across that seam; two or more Δs inside, their nearest
 * neighbours are 0.93-0.94Δs apart at the closest, as here. PySPH's packing tool surrounds a
 * bounded domain with frozen lattice layers (tools/particle_packing.py,
 * create_frozen_container, default l = 3) that take part in both forces and never move; here
 * the container is L layers of the cell-centred lattice continued outside the box (PySPH's
 * function staggers alternate columns by Δs/2: not followed, the files do not tell which
 * container was used), in a periodic box enlarged by L layers per side (2L >= 4 layers across
 * its seam, at least the kernel's support: no free particle sees the images of the others),
 * free particles first. Everything
 * else (forces, steps, stopping rule, perturbation draws) is packed's; the reported density
 * spread includes the frozen particles. The free particles are returned in the original box,
 * which stays periodic.
 *
 * packed-polished, stage 1: the same forces with the quintic at h = 1.2Δs whatever kernel the
 * caller names (the caller's kernel is the one of the density target: kernels with many
 * neighbours pair particles in this stage, the quintic at h = 2Δs did: nearest-neighbour
 * distances down to 0.13Δs), Δt = 0.1 h/c0 = 0.12Δs throughout, and x advanced with the new
 * velocity (symplectic Euler).
 *
 * packed-polished, stage 2, density polishing (ours: asked for max|rho/rho0 - 1| < tol, which
 * stage 1 cannot reach): once stage 1 stalls (its best spread has not improved by 10% for 200
 * steps, or half of max_iter is spent), the background-pressure force is replaced by the gradient
 * of the density error E = (K/2) sum_i (rho_i/rho0 - 1)^2 with the caller's kernel,
 *
 *     du_i/dt = -(K/rho0^2) m sum_j (e_i + e_j) ∇_i W_ij + repulsion - ν u_i,  e = rho/rho0 - 1,
 *
 * i.e. weakly compressible SPH with the linear equation of state p = K(rho/rho0 - 1) and no
 * background pressure, damped; velocities restart from zero. Being a damped gradient flow of E
 * it cannot clump particles (that raises E). K = 300 p_b puts the sound speed at
 * sqrt(K/rho0) ≈ 17 c0; the step is Δt = 0.1 (R/3)/c0 with R the kernel's support radius (for
 * the quintic, whose support is 3h, this is stage 1's 0.1 h/c0), a Courant number 1.7 on the
 * support radius, inside the stability limit of the symplectic step (measured unstable near
 * K = 1000 for the quintic at h = 1.2Δs in 2D; scaling Δt with h rather than with the support
 * made Wendland kernels, whose support is 2h, unstable). It stops as soon as
 * max_i |rho_i/rho0 - 1| < tol, or after max_iter steps.
 *
 * The pair sums walk a private neighbour list (pairlist.c, a Verlet list): each particle's
 * neighbours within the kernel radius plus a skin of 0.05 radius, rebuilt (and the particles
 * re-sorted into cell order, for memory locality) only once a particle has moved half the skin
 * since the last build, with one walk of the search per build. The positions are wrapped into
 * the box at the builds only; a pair that the search found across the box's edge names a ghost,
 * the periodic image x_j + image·len of its particle, whose row is refreshed every step (the
 * particles' rows are written by the step that moves them), so a list entry is x_i - row with
 * no image arithmetic (the same values as adding the image's
 * shift per entry). The rows interleave the coordinates and the force's per-particle weight
 * (32 bytes a particle), so the force walk loads both at once. Per step, one walk computes the
 * densities and W'/r of the force's kernel (kept per list entry), with the distances in the same
 * loop; a second the separations again (in registers) and the forces. Four list entries at a
 * time (AVX2 where the processor has it; the portable loops give the same values), each
 * particle's sums in four interleaved partial sums in list order; the quintic density walk runs
 * eight entries at a time where the processor has AVX-512F (two blocks of four added to the
 * same partial sums: the same values), the force walk stays four-wide (an eight-wide copy
 * measured 19% slower: the transposes of the gathered rows cost more than the arithmetic it
 * saves). The force walk records the blocks with a pair within the repulsion's range instead of
 * branching on them (3.8% of the blocks over a 2D pack; a mispredicted branch there discarded
 * the work in flight behind it, a third of the walk's time) and adds their repulsion per chunk
 * afterwards. Measured against the loops before these changes (and the list build's single
 * walk), in one session on the 2 shared cores (the same positions bit for bit; minimum of two
 * runs): 2D nx 200, 2000 steps, one thread: 18.2 s -> 13.0 s of CPU; whole packs on two threads:
 * nx 100 15.1 s -> 10.6 s of CPU (7.7 s -> 5.7 s wall), nx 200 94 s -> 70 s of CPU (0.21 -> 0.16
 * core-µs per particle-step). Each pair's kernel values are computed from both sides: a list that
 * computed them once per pair and copied them to the mirror entry (j's entry for i) measured slower
 * here, the copies being scattered writes and the stored W an extra array (2D nx 200, two threads:
 * 168 against 96 s of CPU; nx 50, where the list fits the cache, even). The quintic density walk's
 * square root and division per entry are a large part of its time (replacing the division by a
 * multiplication, a timing only, made the walk 11% faster); folding the quintic's constants (three
 * multiplications fewer per entry, a round-off change) gained 1.5% and was not taken. The division
 * in W'/r stays: W'/r has no division-free form with the same values (f'(q)/q is a polynomial on q
 * < 1 only). Nor did a reciprocal square root pay, though it would have moved the positions only
 * at round-off (tried in all three paths, bit for bit alike; AMD EPYC with AVX-512, 2 shared
 * cores): y = h/r from a correctly rounded float start, 1/sqrtf((float)(r²/h²)), with two Newton
 * steps in double (or one third-order step), then q = r/h = (r²/h²) y and W'/r = (norm/h²) f'(q)
 * y, no square root or division in double. Alone it costs half of sqrt and division (0.42-0.47
 * against 0.88-0.90 ns an entry, eight-wide, in a loop of nothing else), yet the walk (timed
 * eleven times a step, 2D nx 100, one thread, minimum of five runs) ran 41-45% longer, likely
 * because its chain of dependent operations before the quintic is about twice sqrt's latency, more
 * than the processor overlaps; with the reciprocals of a particle's entries first written to a
 * buffer and the quintic taken from there, still 5% longer, and whole packs (2D nx 200, two
 * threads, three runs each, the same 11151 steps) took 72.6 -> 78.8 s of CPU. One division shared
 * by two entries (1/(r_a r_b), times r_b and r_a) ran the walk 6.5% longer, 1/r divided right after
 * the square root (off the polynomial's chain) times norm f'(q)/h 4% longer.
 *
 * The packed kind runs the two walks of a step as a wavefront (step_wavefront; 1D and 2D): each
 * thread takes a contiguous share of the chunks of 256 particles, computes a chunk's densities,
 * force weights and W'/r, and runs the force on a chunk as soon as its share holds the densities
 * of every chunk with a neighbour of it (about two rows of cells behind in 2D). W'/r goes to a
 * ring of the thread's, reused chunk after chunk, and the list's indices are read again while
 * cached: the list (12 bytes an entry, 135 MB at 2D nx 500) is streamed from memory once per step
 * instead of twice, and W'/r is neither written to nor read back from memory. The chunks with a
 * neighbour in another thread's share (the periodic images across the box, the shares' edges) keep
 * W'/r in the list's array and have their force after every thread's walk. The same sums in the
 * same order: the same positions bit for bit (test_packing_paths compares with the walks one after
 * the other). The list build keeps its per-thread buffers from build to build (fresh ones faulted
 * in their pages at every build: 1.5-3.5 s of system time in the first 300 steps at nx 500).
 * Measured against main, same session, 2 shared cores, load about 2 (these runs included), the
 * list build's image skip (pairlist.c) included in the later runs: 2D nx 500, 300 steps, two
 * threads 12.6 -> 9.8 s wall (22.0 -> 18.6 s of user + system CPU), one thread 22.7 -> 18.5 s;
 * 1500 steps, two threads 34.7-37.7 -> 31.0-34.4 s wall over three runs each (65.1-69.1 ->
 * 57.8-59.8 s of CPU), one thread 71.7 -> 60.3 s; whole pack nx 200, two threads 32.5 / 35.9 ->
 * 30.4 / 31.2 s wall (63.2 / 69.5 -> 59.2 / 60.1 s of CPU); nx 100 5.3 s both (its list fits the
 * caches). Under heavier load (3-9) nx 200 took 73.4 -> 66.0 and 64.3 -> 64.1 s of CPU; wall
 * times there say nothing. On these cores main's two threads at nx 500 ran 1.8-2.1 times as fast
 * as its one (not the 1.5 measured before on quiet cores): what the wavefront gains where memory
 * bandwidth binds remains to be timed on quiet cores. The wavefront's region also refreshes the
 * rows, takes the spread and makes the step (step_wavefront): one fork per step and no serial
 * pass over the particles, during which the other thread spun (2D nx 200, two threads, whole
 * packs, three alternating runs each, load 4-6: 63.2-63.9 -> 61.0-61.3 s of user CPU; libgomp's
 * share of perf's samples over 1500 steps 6.7% -> about 4%). Tried in the same session and not
 * taken (the same positions bit for bit, 2D nx 200, two threads, 1500 steps): running a block of
 * the force walk between the density walk's blocks, so that the processor overlaps the force's
 * loads with the density's square roots and divisions, made the two walks 14% slower (likely: more
 * branches per block, each misprediction discarding both walks' work in flight); leaving W'/r's
 * division to the force walk (the ring holding its numerator and r) moved 8% of the density walk's
 * time to the force walk, 0.5% in all; a branch-free, vectorised advance gained 0.2%. A chunk
 * with a neighbour a ring's length ahead is late too: at one thread, chunk 0 lists the
 * last chunks (the periodic images across the box), and waiting for them held every later
 * chunk's force to the end of the walk, most chunks' W'/r overflowing the ring into the list's
 * array (2D nx 300, one thread, 2000 steps, three alternating runs: 28.4-29.7 -> 26.7-27.7 s;
 * whole packs nx 150, 18.3-20.3 -> 18.5-19.2 s). Two threads lose little (each
 * thread's CPU time per phase over 600 steps, 2D): at nx 300 each takes 4.0-4.3 s for its walks
 * and steps against 8.4-8.9 s at one thread, spins 1.5% of that at the barriers, and the
 * threads' per-step differences (the waits on a quiet machine) sum to 0.17 s; whole packs at nx
 * 150 took 9.7-10.0 s on two threads against 18.3-20.3 s on one, quiet cores. Not taken, the
 * same positions bit for bit: each chunk's step right after its force, writing a second set of
 * rows swapped per step (ghosts included: no refresh pass, two barriers fewer per step): nx 150,
 * two threads, 9.7-10.0 s wall as main; nx 300 whole packs 73.0 against 70.6 s (the quietest of
 * three alternating pairs, the others under load from other jobs).
 *
 * Reproducibility: every sum is a gather into particle i in the fixed order of its list
 * and the only reductions are max, which are exact, so the result does not depend on the number of
 * threads. Changing the order of a sum or the operations of a term moves the positions at
 * round-off: bump CONSPH_LAYOUT_PACKING_VERSION (include/consph/layout.h), the cache's key.
 * Particles are returned in lattice order: particle i of the result started at lattice node i. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "layout/layout_internal.h"

/* The pair loops below vectorise only when sqrt needs no errno path and selects may be
 * if-converted; neither option changes a value (no reassociation, no contraction), and no
 * code here reads errno or the floating-point flags. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("no-trapping-math", "no-math-errno")
#endif

static const double packing_rho0 = 1.0;
static const double packing_pb = 1.0;
static const double packing_dt_factor = 0.1;  /* Δt = factor · h / c0 */
static const double packing_polish_k = 300.0; /* K / p_b of stage 2 */
/* Stage 1 has stalled when its best spread has not improved by this factor for this many
 * steps. */
static const double packing_stall_gain = 0.9;
static const int packing_stall_steps = 200;
/* The neighbour list's skin, a fraction of the kernel radius: the list holds the pairs within
 * (1 + skin) radius and is rebuilt (the particles re-sorted into cell order with it) once a
 * particle has moved skin·radius/2 since the last build. Wider skins mean fewer builds and more
 * pairs visited per step (2D nx = 40, one thread: 0.03 and 0.05 took 1.07 s, 0.1 1.12 s, 0.15
 * 1.19 s). */
static const double packing_skin = 0.05;
/* packed, as [51]'s implementation runs it on free particles: the stopping test every this many
 * steps (its dfreq), honoured from this many tests on (its "more than 10"), the steps of its
 * time-step ramp (n_damp) and the step size it starts from rest with (its dt_adapt at t = 0). */
static const int packing_check_every = 50;
static const int packing_min_checks = 11;
static const int packing_ramp_steps = 10;
static const double packing_first_dt = 1e-7;

typedef struct pack_work {
    size_t n;
    size_t n_free; /* particles whose origin index is n_free or more are frozen (walls) */
    int dim;
    double *u[CONSPH_MAX_DIM]; /* velocity */
    double *acc[CONSPH_MAX_DIM];
    double *rho;       /* summation density with the caller's kernel */
    double *rho_glass; /* with the stage-1 kernel; NULL when it is the caller's */
    size_t *origin;    /* lattice index of the particle now stored at i */
    size_t *origin_tmp;
    size_t *perm;
    double *scratch;
} pack_work;

static void work_free(pack_work *w)
{
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        free(w->u[a]);
        free(w->acc[a]);
    }
    free(w->rho);
    free(w->rho_glass);
    free(w->origin);
    free(w->origin_tmp);
    free(w->perm);
    free(w->scratch);
    memset(w, 0, sizeof *w);
}

static int work_alloc(pack_work *w, size_t n, int dim, int need_glass_rho)
{
    memset(w, 0, sizeof *w);
    w->n = n;
    w->n_free = n;
    w->dim = dim;
    int ok = 1;
    for (int a = 0; a < dim; ++a) {
        ok &= (w->u[a] = consph_calloc(n, sizeof(double))) != NULL;
        ok &= (w->acc[a] = consph_calloc(n, sizeof(double))) != NULL;
    }
    ok &= (w->rho = consph_calloc(n, sizeof(double))) != NULL;
    if (need_glass_rho) ok &= (w->rho_glass = consph_calloc(n, sizeof(double))) != NULL;
    ok &= (w->origin = consph_calloc(n, sizeof(size_t))) != NULL;
    ok &= (w->origin_tmp = consph_calloc(n, sizeof(size_t))) != NULL;
    ok &= (w->perm = consph_calloc(n, sizeof(size_t))) != NULL;
    ok &= (w->scratch = consph_calloc(n, sizeof(double))) != NULL;
    if (!ok) {
        work_free(w);
        return CONSPH_ENOMEM;
    }
    for (size_t i = 0; i < n; ++i) w->origin[i] = i;
    return CONSPH_OK;
}

/* Applies new[i] = old[perm[i]] to the velocity and the origin index (consph_nnps_sort has
 * already done it to the positions). */
static void work_permute(pack_work *w)
{
    for (int a = 0; a < w->dim; ++a) {
        for (size_t i = 0; i < w->n; ++i) w->scratch[i] = w->u[a][w->perm[i]];
        memcpy(w->u[a], w->scratch, w->n * sizeof(double));
    }
    for (size_t i = 0; i < w->n; ++i) w->origin_tmp[i] = w->origin[w->perm[i]];
    size_t *t = w->origin;
    w->origin = w->origin_tmp;
    w->origin_tmp = t;
}

int layout_min_walls(consph_kernel_id id, double hdx)
{
    return (int)ceil(0.5 * consph_kernel_info_get(id)->support * hdx);
}

static int check_packing(const consph_layout_params *lp, consph_kernel_id *id)
{
    const consph_packing_params *pp = &lp->packing;
    const char *name = consph_layout_name(lp->kind);
    for (int a = 0; a < lp->dim; ++a)
        if (!lp->box.periodic[a])
            return consph_fail(CONSPH_EINVAL,
                               "layout %s: axis %d is not periodic; the packing needs a "
                               "periodic box (001's PP arrangement is periodic)",
                               name, a);
    if (!(pp->hdx > 0.0 && pp->hdx <= 10.0))
        return consph_fail(CONSPH_EINVAL, "layout %s: hdx = %g is outside (0, 10]", name, pp->hdx);
    if (!(pp->perturb >= 0.0 && pp->perturb <= 0.5))
        return consph_fail(CONSPH_EINVAL, "layout %s: perturb = %g is outside [0, 0.5]", name,
                           pp->perturb);
    if (pp->max_iter < 0)
        return consph_fail(CONSPH_EINVAL, "layout %s: max_iter = %d is negative", name,
                           pp->max_iter);
    if (lp->kind == CONSPH_LAYOUT_PACKED_POLISHED && (!(pp->tol > 0.0) || !isfinite(pp->tol)))
        return consph_fail(CONSPH_EINVAL, "layout %s: tol = %g must be positive", name, pp->tol);
    if (lp->kind == CONSPH_LAYOUT_PACKED && (!(pp->move_tol > 0.0) || !isfinite(pp->move_tol)))
        return consph_fail(CONSPH_EINVAL, "layout %s: move_tol = %g must be positive", name,
                           pp->move_tol);
    if (pp->walls < 0 || pp->walls > 8)
        return consph_fail(CONSPH_EINVAL, "layout %s: walls = %d is outside [0, 8]", name,
                           pp->walls);
    if (pp->walls > 0 && lp->kind != CONSPH_LAYOUT_PACKED)
        return consph_fail(CONSPH_EINVAL, "layout %s: walls applies only to packed", name);
    if (pp->history_every < 0)
        return consph_fail(CONSPH_EINVAL, "layout %s: history_every = %d is negative", name,
                           pp->history_every);
    int rc = consph_kernel_lookup(pp->kernel ? pp->kernel : "quintic", id);
    if (rc) return rc;
    if (consph_kernel_info_get(*id)->tensor)
        return consph_fail(CONSPH_EINVAL,
                           "layout %s: kernel '%s' is a tensor-product remeshing kernel; the "
                           "packing needs a radial kernel",
                           name, pp->kernel);
    /* The container is 2·walls layers thick across the enlarged box's seam: at least the
     * kernel's support, or free particles would see the images of those across it. */
    const int min_walls = layout_min_walls(*id, pp->hdx);
    if (pp->walls > 0 && pp->walls < min_walls)
        return consph_fail(CONSPH_EINVAL,
                           "layout %s: walls = %d is thinner than the kernel's support (%s, "
                           "h/Δs %g); allowed: 0 or %d..8",
                           name, pp->walls, pp->kernel ? pp->kernel : "quintic", pp->hdx,
                           min_walls);
    return CONSPH_OK;
}

int layout_check_packing(const consph_layout_params *lp)
{
    consph_kernel_id id;
    return check_packing(lp, &id);
}

/* The short-range repulsion of stage 1 and 2. */
typedef struct repulsion {
    double k, c, range, r_floor;
} repulsion;

static inline double repulsion_coef(const repulsion *rp, double r)
{
    double rc = r > rp->r_floor ? r : rp->r_floor;
    double inv = 1.0 / rc, inv4 = inv * inv * inv * inv;
    double g = 12.0 * rp->k * (3.0 * rp->c * rp->c * inv4 * inv - 2.0 * rp->c * inv4);
    /* The force acts along x_ij with magnitude g·rc, also where r was floored. */
    return g > 0.0 ? g * rc / r : 0.0;
}

typedef struct force_params {
    const consph_kernel *glass;  /* stage 1: quintic, h = 1.2Δs */
    const consph_kernel *target; /* the caller's kernel: stopping test and stage 2 */
    double mass;
    int polish; /* 0: stage 1, background pressure; 1: stage 2, density-error gradient */
    repulsion rep;
} force_params;

/* Particles per chunk of the parallel loops. */
#define PACK_CHUNK 256

/* One past chunk c's last particle among n. */
static inline size_t chunk_end(size_t c, size_t n)
{
    return c * PACK_CHUNK + PACK_CHUNK < n ? c * PACK_CHUNK + PACK_CHUNK : n;
}

/* Per-thread buffers of one particle's list entries: distances, kernel values and separations. */
typedef struct pair_buf {
    double *r, *k, *dx[CONSPH_MAX_DIM];
    /* The force walk's blocks with a pair within the repulsion's range, in walk order: the
     * particle and the block's first list entry (see accel_avx2). */
    uint32_t *near_i;
    size_t *near_e;
} pair_buf;

static void pair_buf_free(pair_buf *b)
{
    free(b->r);
    free(b->k);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(b->dx[a]);
    free(b->near_i);
    free(b->near_e);
    memset(b, 0, sizeof *b);
}

static int pair_buf_alloc(pair_buf *b, size_t len, size_t chunk)
{
    memset(b, 0, sizeof *b);
    const size_t blocks = chunk * (len / 4 + 1);
    int ok = (b->near_i = malloc(blocks * sizeof *b->near_i)) != NULL;
    ok &= (b->near_e = malloc(blocks * sizeof *b->near_e)) != NULL;
    len += PACK_SLACK; /* whole blocks of four, and never a zero-size allocation */
    ok &= (b->r = malloc(len * sizeof(double))) != NULL;
    ok &= (b->k = malloc(len * sizeof(double))) != NULL;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a)
        ok &= (b->dx[a] = malloc(len * sizeof(double))) != NULL;
    if (!ok) pair_buf_free(b);
    return ok;
}

/* Set by tests: 1 the portable loops even where the processor has AVX2, 2 at most AVX2. */
static int pack_isa_cap;

void layout_pack_set_portable(int level)
{
    pack_isa_cap = level;
}

/* Set by tests: 1 runs the density and force walks one after the other instead of as a
 * wavefront (the same values); the wavefront's rings hold W'/r of this many chunks of the mean
 * length (more than a neighbourhood spans in 2D, two rows of cells; fewer tests the fallback). */
static int pack_wavefront_off;
static int pack_ring_chunks = 40;

void layout_pack_set_wavefront(int on, int ring_chunks)
{
    pack_wavefront_off = !on;
    pack_ring_chunks = ring_chunks > 0 ? ring_chunks : 40;
}

/* What the pair sums of one step read and write. */
typedef struct pack_sweep {
    const force_params *fp;
    const pack_list *L;
    const double *xv; /* the list's rows: coordinates, and the force's weights (PACK_XV_WEIGHT) */
    pack_work *w;
    int glass;                 /* density: also rho_glass */
    const consph_kernel *kern; /* the force's kernel */
    const double *rho;         /* force: the density it acts on */
    /* W'/r of list entry e at dwr[e - dwr_first]: the list's own array (dwr_first 0), or a
     * buffer holding a chunk's entries (step_wavefront) */
    double *dwr;
    size_t dwr_first;
    int avx2;          /* the processor has AVX2: the vector loops */
    int avx512;        /* and AVX-512F: the pair sums eight entries at a time */
    int fused_quintic; /* density: W and the force's W'/r are one quintic (AVX2) */
} pack_sweep;

#define XV(sw, row, slot) ((sw)->xv[PACK_XV_STRIDE * (size_t)(row) + (slot)])

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#include <immintrin.h>
#define PACK_AVX2 1
/* The coordinates of the rows J[0..3] of xv, one axis per vector, and with wj their weights:
 * whole rows loaded and transposed (2D without weights: the (x, y) halves only). */
__attribute__((target("avx2"), always_inline)) static inline void
load_rows_avx2(int dim, const double *xv, const uint32_t *J, __m256d xj[CONSPH_MAX_DIM],
               __m256d *wj)
{
    const double *p0 = xv + PACK_XV_STRIDE * (size_t)J[0];
    const double *p1 = xv + PACK_XV_STRIDE * (size_t)J[1];
    const double *p2 = xv + PACK_XV_STRIDE * (size_t)J[2];
    const double *p3 = xv + PACK_XV_STRIDE * (size_t)J[3];
    if (dim == 1) {
        xj[0] = _mm256_set_pd(p3[0], p2[0], p1[0], p0[0]);
        if (wj)
            *wj = _mm256_set_pd(p3[PACK_XV_WEIGHT], p2[PACK_XV_WEIGHT], p1[PACK_XV_WEIGHT],
                                p0[PACK_XV_WEIGHT]);
    } else if (dim == 2 && !wj) {
        /* lo = [x0 y0 x2 y2], hi = [x1 y1 x3 y3]: the unpacks give [x0 x1 x2 x3] */
        const __m256d lo =
            _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(p0)), _mm_load_pd(p2), 1);
        const __m256d hi =
            _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(p1)), _mm_load_pd(p3), 1);
        xj[0] = _mm256_unpacklo_pd(lo, hi);
        xj[1] = _mm256_unpackhi_pd(lo, hi);
    } else {
        /* rows [x y z w]: t0 = [x0 x1 z0 z1], t1 = [y0 y1 w0 w1], t2, t3 the same of rows 2, 3 */
        const __m256d r0 = _mm256_load_pd(p0), r1 = _mm256_load_pd(p1);
        const __m256d r2 = _mm256_load_pd(p2), r3 = _mm256_load_pd(p3);
        const __m256d t0 = _mm256_unpacklo_pd(r0, r1), t1 = _mm256_unpackhi_pd(r0, r1);
        const __m256d t2 = _mm256_unpacklo_pd(r2, r3), t3 = _mm256_unpackhi_pd(r2, r3);
        xj[0] = _mm256_permute2f128_pd(t0, t2, 0x20);
        xj[1] = _mm256_permute2f128_pd(t1, t3, 0x20);
        if (dim == 3) xj[2] = _mm256_permute2f128_pd(t0, t2, 0x31);
        if (wj) *wj = _mm256_permute2f128_pd(t1, t3, 0x31);
    }
}

/* x_ij of four entries per axis into d, and |x_ij|^2 (returned): the portable loops' operations
 * in their order. */
__attribute__((target("avx2"), always_inline)) static inline __m256d
separations_avx2(int dim, const __m256d xi[CONSPH_MAX_DIM], const __m256d xj[CONSPH_MAX_DIM],
                 __m256d d[CONSPH_MAX_DIM])
{
    __m256d rr = _mm256_setzero_pd();
    for (int a = 0; a < dim; ++a) {
        d[a] = _mm256_sub_pd(xi[a], xj[a]);
        rr = a == 0 ? _mm256_mul_pd(d[a], d[a]) : _mm256_add_pd(rr, _mm256_mul_pd(d[a], d[a]));
    }
    return rr;
}

/* Lanes l with q + l < m. */
__attribute__((target("avx2"), always_inline)) static inline __m256d lanes_below(size_t m, size_t q)
{
    const __m256i lane = _mm256_set_epi64x(3, 2, 1, 0);
    return _mm256_castsi256_pd(_mm256_cmpgt_epi64(_mm256_set1_epi64x((long long)(m - q)), lane));
}

/* list_geometry four entries at a time: the same operations in the same order (no fused
 * multiply-add; packed square roots are correctly rounded like sqrt), so the same values. It
 * reads and writes whole blocks of four: the list and the buffers carry PACK_SLACK entries past
 * the end. */
__attribute__((target("avx2"))) static size_t geometry_avx2(int dim, const pack_sweep *sw, size_t i,
                                                            pair_buf *b, int with_dx)
{
    const pack_list *L = sw->L;
    const size_t e0 = L->start[i], m = L->start[i + 1] - e0;
    const uint32_t *J = L->j + e0;
    __m256d xi[CONSPH_MAX_DIM];
    for (int a = 0; a < dim; ++a) xi[a] = _mm256_set1_pd(XV(sw, i, a));
    for (size_t q = 0; q < m; q += 4) {
        __m256d xj[CONSPH_MAX_DIM], d[CONSPH_MAX_DIM];
        load_rows_avx2(dim, sw->xv, J + q, xj, NULL);
        const __m256d rr = separations_avx2(dim, xi, xj, d);
        if (with_dx)
            for (int a = 0; a < dim; ++a) _mm256_storeu_pd(b->dx[a] + q, d[a]);
        _mm256_storeu_pd(b->r + q, with_dx ? rr : _mm256_sqrt_pd(rr));
    }
    return m;
}
#endif

/* The distances of particle i's list entries into the buffer, or with with_dx the separations
 * x_ij and the squared distances; returns the entry count m. The entries up to the next multiple
 * of four are filled too (from the list's next entries or its slack), so that loops over whole
 * blocks read finite values. dim is a constant where this is inlined. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline size_t
list_geometry(const int dim, const pack_sweep *sw, size_t i, pair_buf *b, const int with_dx)
{
#ifdef PACK_AVX2
    if (sw->avx2) return geometry_avx2(dim, sw, i, b, with_dx);
#endif
    const pack_list *L = sw->L;
    const size_t e0 = L->start[i], m = L->start[i + 1] - e0;
    const uint32_t *restrict J = L->j + e0;
    const double *restrict xv = sw->xv;
    const double xi0 = XV(sw, i, 0), xi1 = dim > 1 ? XV(sw, i, 1) : 0.0,
                 xi2 = dim > 2 ? XV(sw, i, 2) : 0.0;
    double *restrict r = b->r, *restrict d0p = b->dx[0], *restrict d1p = b->dx[1],
                     *restrict d2p = b->dx[2];
    const size_t m4 = (m + 3) & ~(size_t)3;
    for (size_t q = 0; q < m4; ++q) {
        const double *row = xv + PACK_XV_STRIDE * (size_t)J[q];
        const double d0 = xi0 - row[0];
        double rr = d0 * d0;
        if (with_dx) d0p[q] = d0;
        if (dim > 1) {
            const double d1 = xi1 - row[1];
            rr += d1 * d1;
            if (with_dx) d1p[q] = d1;
        }
        if (dim > 2) {
            const double d2 = xi2 - row[2];
            rr += d2 * d2;
            if (with_dx) d2p[q] = d2;
        }
        r[q] = with_dx ? rr : sqrt(rr);
    }
    return m;
}

/* sum_q v[q] in four interleaved partial sums (term q in sum q mod 4) combined in a fixed order:
 * independent of the number of threads, without one addition's latency per term, and what the
 * vector loops compute lane by lane. */
static inline double sum4(const double *v, size_t m)
{
    double a[4] = {0.0, 0.0, 0.0, 0.0};
    for (size_t q = 0; q < m; ++q) a[q & 3] += v[q];
    return (a[0] + a[1]) + (a[2] + a[3]);
}

#ifdef PACK_AVX2
/* The quintic's scalars the vector walks broadcast: 1/h, its norm, norm/h (W'/r's) and W'/r at
 * r = 0, W''(0) = norm h^-2 f''(0) with f''(0) = 20·27 - 120·8 + 300. */
typedef struct quintic_scalars {
    double inv_h, norm, norm1, at_zero;
} quintic_scalars;

static quintic_scalars quintic_scalars_of(const consph_kernel *k)
{
    const quintic_scalars q = {k->inv_h, k->norm, k->norm * k->inv_h,
                               k->norm * k->inv_h * k->inv_h *
                                   (20.0 * 3.0 * 3.0 * 3.0 - 120.0 * 2.0 * 2.0 * 2.0 + 300.0)};
    return q;
}

/* The quintic's constants for quintic_block_avx2. */
typedef struct quintic_avx2_consts {
    __m256d inv_h, norm, norm1, at_zero;
} quintic_avx2_consts;

/* The quintic's W (masked by `valid`, into *w) and W'/r (returned) of four distances r: the
 * operations of consph_kernel_eval_batch's quintic (src/kernels/kernels.c), so the same values,
 * with the powers shared. */
__attribute__((target("avx2"), always_inline)) static inline __m256d
quintic_block_avx2(const quintic_avx2_consts *c, __m256d rp, __m256d valid, int masked, __m256d *w)
{
    const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0);
    const __m256d c1 = _mm256_set1_pd(1.0), c2 = _mm256_set1_pd(2.0), c3 = _mm256_set1_pd(3.0);
    const __m256d c6 = _mm256_set1_pd(6.0), c15 = _mm256_set1_pd(15.0);
    const __m256d cm5 = _mm256_set1_pd(-5.0), c30 = _mm256_set1_pd(30.0),
                  c75 = _mm256_set1_pd(75.0);
    const __m256d x = _mm256_mul_pd(rp, c->inv_h);
    const __m256d t3 = _mm256_sub_pd(c3, x);
    /* max(t, 0) returns 0 where t is not above 0 (also -0 and NaN): kernels.c's t > 0 ? t : 0 */
    const __m256d t2 = _mm256_max_pd(_mm256_sub_pd(c2, x), zero);
    const __m256d t1 = _mm256_max_pd(_mm256_sub_pd(c1, x), zero);
    const __m256d s3 = _mm256_mul_pd(t3, t3), s2 = _mm256_mul_pd(t2, t2),
                  s1 = _mm256_mul_pd(t1, t1);
    const __m256d p3 = _mm256_mul_pd(s3, s3), p2 = _mm256_mul_pd(s2, s2),
                  p1 = _mm256_mul_pd(s1, s1);
    /* pow5(t) - 6 pow5(t2) + 15 pow5(t1), pow5 = (t²)² t */
    const __m256d f = _mm256_add_pd(
        _mm256_sub_pd(_mm256_mul_pd(p3, t3), _mm256_mul_pd(c6, _mm256_mul_pd(p2, t2))),
        _mm256_mul_pd(c15, _mm256_mul_pd(p1, t1)));
    /* -5 pow4(t) + 30 pow4(t2) - 75 pow4(t1) */
    const __m256d df = _mm256_sub_pd(_mm256_add_pd(_mm256_mul_pd(cm5, p3), _mm256_mul_pd(c30, p2)),
                                     _mm256_mul_pd(c75, p1));
    const __m256d inside = _mm256_cmp_pd(x, c3, _CMP_LT_OQ); /* q < support (and q >= 3: 0) */
    const __m256d wv = _mm256_and_pd(inside, _mm256_mul_pd(c->norm, f));
    *w = masked ? _mm256_and_pd(valid, wv) : wv;
    const __m256d pos = _mm256_cmp_pd(rp, zero, _CMP_GT_OQ);
    const __m256d v = _mm256_div_pd(_mm256_mul_pd(c->norm1, df), _mm256_blendv_pd(one, rp, pos));
    return _mm256_and_pd(inside, _mm256_blendv_pd(c->at_zero, v, pos));
}

/* Particle i's density sum of the quintic (sum4) and W'/r into its list entries, with the
 * distances computed in the same loop (geometry_avx2's operations): one walk of the list. */
__attribute__((target("avx2"))) static void density_quintic_avx2(int dim, const pack_sweep *sw,
                                                                 size_t i0, size_t i1)
{
    const pack_list *L = sw->L;
    const quintic_scalars q0 = quintic_scalars_of(sw->fp->target);
    const quintic_avx2_consts c = {_mm256_set1_pd(q0.inv_h), _mm256_set1_pd(q0.norm),
                                   _mm256_set1_pd(q0.norm1), _mm256_set1_pd(q0.at_zero)};
    for (size_t i = i0; i < i1; ++i) {
        const size_t e0 = L->start[i], m = L->start[i + 1] - e0;
        const uint32_t *J = L->j + e0;
        double *dwr = sw->dwr + (e0 - sw->dwr_first);
        __m256d xi[CONSPH_MAX_DIM];
        for (int a = 0; a < dim; ++a) xi[a] = _mm256_set1_pd(XV(sw, i, a));
        __m256d acc = _mm256_setzero_pd(), w;
        size_t q = 0;
        for (; q + 4 <= m; q += 4) {
            __m256d xj[CONSPH_MAX_DIM], d[CONSPH_MAX_DIM];
            load_rows_avx2(dim, sw->xv, J + q, xj, NULL);
            const __m256d r = _mm256_sqrt_pd(separations_avx2(dim, xi, xj, d));
            _mm256_storeu_pd(dwr + q, quintic_block_avx2(&c, r, r, 0, &w));
            acc = _mm256_add_pd(acc, w);
        }
        if (q < m) {
            /* The last block's entries past m are another particle's: W masked, W'/r not stored. */
            __m256d xj[CONSPH_MAX_DIM], d[CONSPH_MAX_DIM];
            load_rows_avx2(dim, sw->xv, J + q, xj, NULL);
            const __m256d r = _mm256_sqrt_pd(separations_avx2(dim, xi, xj, d));
            double tail[4];
            _mm256_storeu_pd(tail, quintic_block_avx2(&c, r, lanes_below(m, q), 1, &w));
            acc = _mm256_add_pd(acc, w);
            for (size_t e = q; e < m; ++e) dwr[e] = tail[e - q];
        }
        double a[4];
        _mm256_storeu_pd(a, acc);
        sw->w->rho[i] = sw->fp->mass * ((a[0] + a[1]) + (a[2] + a[3]));
    }
}
#endif

/* Adds the repulsion of one pair at squared distance r2 < range^2 to rep, in list order. */
static inline void repulsion_add(int dim, const repulsion *rp, double r2, double d0, double d1,
                                 double d2, double *rep)
{
    const double g = repulsion_coef(rp, sqrt(r2));
    rep[0] += g * d0;
    if (dim > 1) rep[1] += g * d1;
    if (dim > 2) rep[2] += g * d2;
}

#ifdef PACK_AVX2
/* The same loops eight entries at a time with AVX-512F: the same operations per entry in the
 * same order, the eight lanes added to the four partial sums as two blocks of four (entries q..q+3
 * then q+4..q+7), so the same values as the four-wide loops; fewer instructions per entry. */
#define PACK_AVX512 1

/* load_rows_avx2 for the rows J[0..7]. */
__attribute__((target("avx512f"), always_inline)) static inline void
load_rows_avx512(int dim, const double *xv, const uint32_t *J, __m512d xj[CONSPH_MAX_DIM],
                 __m512d *wj)
{
    const double *p[8];
    for (int l = 0; l < 8; ++l) p[l] = xv + PACK_XV_STRIDE * (size_t)J[l];
    if (dim == 1) {
        xj[0] =
            _mm512_set_pd(p[7][0], p[6][0], p[5][0], p[4][0], p[3][0], p[2][0], p[1][0], p[0][0]);
        if (wj)
            *wj = _mm512_set_pd(p[7][PACK_XV_WEIGHT], p[6][PACK_XV_WEIGHT], p[5][PACK_XV_WEIGHT],
                                p[4][PACK_XV_WEIGHT], p[3][PACK_XV_WEIGHT], p[2][PACK_XV_WEIGHT],
                                p[1][PACK_XV_WEIGHT], p[0][PACK_XV_WEIGHT]);
    } else if (dim == 2 && !wj) {
        /* A = [x0 y0 x2 y2 x4 y4 x6 y6], B the odd rows: the unpacks give [x0 .. x7] */
        const __m256d a0 =
            _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(p[0])), _mm_load_pd(p[2]), 1);
        const __m256d a1 =
            _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(p[4])), _mm_load_pd(p[6]), 1);
        const __m256d b0 =
            _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(p[1])), _mm_load_pd(p[3]), 1);
        const __m256d b1 =
            _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(p[5])), _mm_load_pd(p[7]), 1);
        const __m512d A = _mm512_insertf64x4(_mm512_castpd256_pd512(a0), a1, 1);
        const __m512d B = _mm512_insertf64x4(_mm512_castpd256_pd512(b0), b1, 1);
        xj[0] = _mm512_unpacklo_pd(A, B);
        xj[1] = _mm512_unpackhi_pd(A, B);
    } else {
        /* A = [row0 row4], B = [row1 row5], C = [row2 row6], D = [row3 row7];
         * t0 = [x0 x1 z0 z1 x4 x5 z4 z5], t1 = [y0 y1 w0 w1 y4 y5 w4 w5], t2, t3 the same of
         * C, D; the two-source permutes pick [x0 x1 x2 x3 x4 x5 x6 x7] and so on. */
        __m512d R[4];
        for (int l = 0; l < 4; ++l)
            R[l] = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_load_pd(p[l])),
                                      _mm256_load_pd(p[l + 4]), 1);
        const __m512d t0 = _mm512_unpacklo_pd(R[0], R[1]), t1 = _mm512_unpackhi_pd(R[0], R[1]);
        const __m512d t2 = _mm512_unpacklo_pd(R[2], R[3]), t3 = _mm512_unpackhi_pd(R[2], R[3]);
        const __m512i lo = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
        const __m512i hi = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
        xj[0] = _mm512_permutex2var_pd(t0, lo, t2);
        xj[1] = _mm512_permutex2var_pd(t1, lo, t3);
        if (dim == 3) xj[2] = _mm512_permutex2var_pd(t0, hi, t2);
        if (wj) *wj = _mm512_permutex2var_pd(t1, hi, t3);
    }
}

__attribute__((target("avx512f"), always_inline)) static inline __m512d
separations_avx512(int dim, const __m512d xi[CONSPH_MAX_DIM], const __m512d xj[CONSPH_MAX_DIM],
                   __m512d d[CONSPH_MAX_DIM])
{
    __m512d rr = _mm512_setzero_pd();
    for (int a = 0; a < dim; ++a) {
        d[a] = _mm512_sub_pd(xi[a], xj[a]);
        rr = a == 0 ? _mm512_mul_pd(d[a], d[a]) : _mm512_add_pd(rr, _mm512_mul_pd(d[a], d[a]));
    }
    return rr;
}

/* acc + lanes 0..3 of v, then + lanes 4..7: the order of two four-wide blocks. */
__attribute__((target("avx512f"), always_inline)) static inline __m256d add_halves(__m256d acc,
                                                                                   __m512d v)
{
    acc = _mm256_add_pd(acc, _mm512_castpd512_pd256(v));
    return _mm256_add_pd(acc, _mm512_extractf64x4_pd(v, 1));
}

typedef struct quintic_avx512_consts {
    __m512d inv_h, norm, norm1, at_zero;
} quintic_avx512_consts;

/* quintic_block_avx2 for eight distances; the lanes outside `valid` give W = 0. */
__attribute__((target("avx512f"), always_inline)) static inline __m512d
quintic_block_avx512(const quintic_avx512_consts *c, __m512d rp, __mmask8 valid, __m512d *w)
{
    const __m512d zero = _mm512_setzero_pd();
    const __m512d c1 = _mm512_set1_pd(1.0), c2 = _mm512_set1_pd(2.0), c3 = _mm512_set1_pd(3.0);
    const __m512d c6 = _mm512_set1_pd(6.0), c15 = _mm512_set1_pd(15.0);
    const __m512d cm5 = _mm512_set1_pd(-5.0), c30 = _mm512_set1_pd(30.0),
                  c75 = _mm512_set1_pd(75.0);
    const __m512d x = _mm512_mul_pd(rp, c->inv_h);
    const __m512d t3 = _mm512_sub_pd(c3, x);
    const __m512d t2 = _mm512_max_pd(_mm512_sub_pd(c2, x), zero);
    const __m512d t1 = _mm512_max_pd(_mm512_sub_pd(c1, x), zero);
    const __m512d s3 = _mm512_mul_pd(t3, t3), s2 = _mm512_mul_pd(t2, t2),
                  s1 = _mm512_mul_pd(t1, t1);
    const __m512d p3 = _mm512_mul_pd(s3, s3), p2 = _mm512_mul_pd(s2, s2),
                  p1 = _mm512_mul_pd(s1, s1);
    const __m512d f = _mm512_add_pd(
        _mm512_sub_pd(_mm512_mul_pd(p3, t3), _mm512_mul_pd(c6, _mm512_mul_pd(p2, t2))),
        _mm512_mul_pd(c15, _mm512_mul_pd(p1, t1)));
    const __m512d df = _mm512_sub_pd(_mm512_add_pd(_mm512_mul_pd(cm5, p3), _mm512_mul_pd(c30, p2)),
                                     _mm512_mul_pd(c75, p1));
    const __mmask8 inside = _mm512_cmp_pd_mask(x, c3, _CMP_LT_OQ);
    *w = _mm512_maskz_mul_pd(inside & valid, c->norm, f);
    const __mmask8 pos = _mm512_cmp_pd_mask(rp, zero, _CMP_GT_OQ);
    const __m512d v = _mm512_mask_div_pd(c->at_zero, pos, _mm512_mul_pd(c->norm1, df), rp);
    return _mm512_maskz_mov_pd(inside, v);
}

/* density_quintic_avx2 eight entries at a time. */
__attribute__((target("avx512f"))) static void density_quintic_avx512(int dim, const pack_sweep *sw,
                                                                      size_t i0, size_t i1)
{
    const pack_list *L = sw->L;
    const quintic_scalars q0 = quintic_scalars_of(sw->fp->target);
    const quintic_avx512_consts c = {_mm512_set1_pd(q0.inv_h), _mm512_set1_pd(q0.norm),
                                     _mm512_set1_pd(q0.norm1), _mm512_set1_pd(q0.at_zero)};
    for (size_t i = i0; i < i1; ++i) {
        const size_t e0 = L->start[i], m = L->start[i + 1] - e0;
        const uint32_t *J = L->j + e0;
        double *dwr = sw->dwr + (e0 - sw->dwr_first);
        __m512d xi[CONSPH_MAX_DIM];
        for (int a = 0; a < dim; ++a) xi[a] = _mm512_set1_pd(XV(sw, i, a));
        __m256d acc = _mm256_setzero_pd();
        __m512d w;
        size_t q = 0;
        for (; q + 8 <= m; q += 8) {
            __m512d xj[CONSPH_MAX_DIM], d[CONSPH_MAX_DIM];
            load_rows_avx512(dim, sw->xv, J + q, xj, NULL);
            const __m512d r = _mm512_sqrt_pd(separations_avx512(dim, xi, xj, d));
            _mm512_storeu_pd(dwr + q, quintic_block_avx512(&c, r, 0xff, &w));
            acc = add_halves(acc, w);
        }
        if (q < m) {
            const __mmask8 valid = (__mmask8)((1u << (m - q)) - 1u);
            __m512d xj[CONSPH_MAX_DIM], d[CONSPH_MAX_DIM];
            load_rows_avx512(dim, sw->xv, J + q, xj, NULL);
            const __m512d r = _mm512_sqrt_pd(separations_avx512(dim, xi, xj, d));
            _mm512_mask_storeu_pd(dwr + q, valid, quintic_block_avx512(&c, r, valid, &w));
            acc = add_halves(acc, w);
        }
        double a[4];
        _mm256_storeu_pd(a, acc);
        sw->w->rho[i] = sw->fp->mass * ((a[0] + a[1]) + (a[2] + a[3]));
    }
}

#endif

/* rho_i = m sum_j W_ij over the list with the kernel k (the entries past its support add exact
 * zeros). */
static double list_density(const consph_kernel *k, double mass, const pair_buf *b, size_t m)
{
    consph_kernel_eval_batch(k, m, b->r, b->k, NULL, NULL);
    return mass * sum4(b->k, m);
}

/* The densities, and W'/r of the force's kernel into the list (read by accel_range), so that
 * the force needs no square root and no kernel evaluation. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
density_range(const int dim, const pack_sweep *sw, size_t i0, size_t i1, pair_buf *b)
{
    const force_params *fp = sw->fp;
    for (size_t i = i0; i < i1; ++i) {
#ifdef PACK_AVX2
        if (sw->fused_quintic) {
            if (sw->avx512)
                density_quintic_avx512(dim, sw, i, i1);
            else
                density_quintic_avx2(dim, sw, i, i1);
            return;
        }
#endif
        const size_t m = list_geometry(dim, sw, i, b, 0);
        sw->w->rho[i] = list_density(fp->target, fp->mass, b, m);
        if (sw->glass) sw->w->rho_glass[i] = list_density(fp->glass, fp->mass, b, m);
        consph_kernel_eval_batch(sw->kern, m, b->r, NULL,
                                 sw->dwr + (sw->L->start[i] - sw->dwr_first), NULL);
    }
}

/* The factor of the pair sum in a_i: -(p_b/m) V_i (stage 1), -(K/rho0^2) m (stage 2). */
static inline double accel_coef(const force_params *fp, double rho_i)
{
    const double mass = fp->mass, rho0 = packing_rho0;
    return fp->polish ? -packing_polish_k * packing_pb / (rho0 * rho0) * mass
                      : -packing_pb * (mass / rho_i) / mass;
}

#ifdef PACK_AVX2
/* The constants of the force pass's vector loop. */
typedef struct accel_avx2_consts {
    __m256d range2, floor, k12, c3cc, c2;
} accel_avx2_consts;

/* One block of accel_avx2: the pair forces of four entries into acc; returns the mask of the
 * entries within the repulsion's range. */
__attribute__((target("avx2"), always_inline)) static inline int
accel_block_avx2(int dim, const pack_sweep *sw, const uint32_t *J, const double *dwr,
                 const __m256d xi[CONSPH_MAX_DIM], __m256d vei, int polish,
                 const accel_avx2_consts *c, __m256d valid, int masked, __m256d acc[CONSPH_MAX_DIM])
{
    __m256d xj[CONSPH_MAX_DIM], d[CONSPH_MAX_DIM], wq;
    load_rows_avx2(dim, sw->xv, J, xj, &wq);
    const __m256d rr = separations_avx2(dim, xi, xj, d);
    if (polish) wq = _mm256_add_pd(vei, wq);
    __m256d pos = _mm256_cmp_pd(rr, _mm256_setzero_pd(), _CMP_GT_OQ);
    if (masked) pos = _mm256_and_pd(valid, pos);
    const __m256d f = _mm256_and_pd(pos, _mm256_mul_pd(wq, _mm256_loadu_pd(dwr)));
    for (int a = 0; a < dim; ++a) acc[a] = _mm256_add_pd(acc[a], _mm256_mul_pd(f, d[a]));
    return _mm256_movemask_pd(_mm256_and_pd(pos, _mm256_cmp_pd(rr, c->range2, _CMP_LT_OQ)));
}

/* The repulsion of the blocks that accel_avx2 recorded, added to the accelerations: per
 * particle in list order from 0 (repulsion_add's sums); the coefficients of a block's pairs
 * computed together with repulsion_coef's operations, so the same values. */
__attribute__((target("avx2"))) static void repulsion_avx2(int dim, const pack_sweep *sw,
                                                           const accel_avx2_consts *c,
                                                           const pair_buf *b, size_t nrec)
{
    const pack_list *L = sw->L;
    size_t k = 0;
    while (k < nrec) {
        const size_t i = b->near_i[k], end = L->start[i + 1];
        __m256d xi[CONSPH_MAX_DIM];
        for (int a = 0; a < dim; ++a) xi[a] = _mm256_set1_pd(XV(sw, i, a));
        double rep[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        for (; k < nrec && b->near_i[k] == i; ++k) {
            const size_t e = b->near_e[k];
            __m256d xj[CONSPH_MAX_DIM], d[CONSPH_MAX_DIM];
            load_rows_avx2(dim, sw->xv, L->j + e, xj, NULL);
            const __m256d rr = separations_avx2(dim, xi, xj, d);
            const __m256d pos = _mm256_and_pd(lanes_below(end, e),
                                              _mm256_cmp_pd(rr, _mm256_setzero_pd(), _CMP_GT_OQ));
            int near =
                _mm256_movemask_pd(_mm256_and_pd(pos, _mm256_cmp_pd(rr, c->range2, _CMP_LT_OQ)));
            const __m256d r = _mm256_sqrt_pd(rr);
            const __m256d rc = _mm256_max_pd(r, c->floor); /* r > floor ? r : floor */
            const __m256d inv = _mm256_div_pd(_mm256_set1_pd(1.0), rc);
            const __m256d inv4 = _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(inv, inv), inv), inv);
            const __m256d g = _mm256_mul_pd(
                c->k12, _mm256_sub_pd(_mm256_mul_pd(_mm256_mul_pd(c->c3cc, inv4), inv),
                                      _mm256_mul_pd(c->c2, inv4)));
            const __m256d coef = _mm256_and_pd(_mm256_cmp_pd(g, _mm256_setzero_pd(), _CMP_GT_OQ),
                                               _mm256_div_pd(_mm256_mul_pd(g, rc), r));
            double cf[4], dx[CONSPH_MAX_DIM][4];
            _mm256_storeu_pd(cf, coef);
            for (int a = 0; a < dim; ++a) _mm256_storeu_pd(dx[a], d[a]);
            while (near) {
                const int l = __builtin_ctz((unsigned)near);
                near &= near - 1;
                for (int a = 0; a < dim; ++a) rep[a] += cf[l] * dx[a][l];
            }
        }
        for (int a = 0; a < dim; ++a) sw->w->acc[a][i] += rep[a];
    }
}

/* accel_range's pair sums and accelerations of particles i0..i1, four entries at a time, the
 * separations kept in registers and the weights loaded with the positions: the operations of
 * the portable loop in the same order, so the same values. (An eight-wide AVX-512 copy of this
 * loop measured slower: its transposes of the gathered rows cost more than the arithmetic it
 * saves.) */
__attribute__((target("avx2"))) static void accel_avx2(int dim, const pack_sweep *sw, size_t i0,
                                                       size_t i1, pair_buf *b)
{
    const pack_list *L = sw->L;
    const force_params *fp = sw->fp;
    const repulsion *rp = &fp->rep;
    const int polish = fp->polish;
    accel_avx2_consts c;
    c.range2 = _mm256_set1_pd(rp->range * rp->range);
    c.floor = _mm256_set1_pd(rp->r_floor);
    c.k12 = _mm256_set1_pd(12.0 * rp->k);
    c.c3cc = _mm256_set1_pd(3.0 * rp->c * rp->c);
    c.c2 = _mm256_set1_pd(2.0 * rp->c);
    const double rep0 = 0.0;
    size_t nrec = 0;
    for (size_t i = i0; i < i1; ++i) {
        const size_t e0 = L->start[i], m = L->start[i + 1] - e0;
        const uint32_t *J = L->j + e0;
        const double *dwr = sw->dwr + (e0 - sw->dwr_first);
        __m256d xi[CONSPH_MAX_DIM], acc[CONSPH_MAX_DIM];
        for (int a = 0; a < dim; ++a) {
            xi[a] = _mm256_set1_pd(XV(sw, i, a));
            acc[a] = _mm256_setzero_pd();
        }
        const __m256d vei = _mm256_set1_pd(polish ? XV(sw, i, PACK_XV_WEIGHT) : 0.0);
        /* The blocks with a pair within the repulsion's range are recorded, not branched on (a
         * mispredicted branch here costs the work of the blocks in flight behind it), and their
         * repulsion added afterwards by repulsion_avx2. */
        size_t q = 0;
        for (; q + 4 <= m; q += 4) {
            const int near =
                accel_block_avx2(dim, sw, J + q, dwr + q, xi, vei, polish, &c, vei, 0, acc);
            b->near_i[nrec] = (uint32_t)i;
            b->near_e[nrec] = e0 + q;
            nrec += near != 0;
        }
        if (q < m) {
            const int near = accel_block_avx2(dim, sw, J + q, dwr + q, xi, vei, polish, &c,
                                              lanes_below(m, q), 1, acc);
            b->near_i[nrec] = (uint32_t)i;
            b->near_e[nrec] = e0 + q;
            nrec += near != 0;
        }
        const double coef = accel_coef(fp, sw->rho[i]);
        for (int a = 0; a < dim; ++a) {
            double s[4];
            _mm256_storeu_pd(s, acc[a]);
            /* + 0.0: the repulsion's sum where it has no term (the portable loop's rep[a]) */
            sw->w->acc[a][i] = coef * ((s[0] + s[1]) + (s[2] + s[3])) + rep0;
        }
    }
    repulsion_avx2(dim, sw, &c, b, nrec);
}
#endif

/* Stage 1: a_i = -(p_b/m) V_i sum_j V_j ∇_i W_ij + repulsion, with ∇_i W_ij = (W'/r) x_ij.
 * Stage 2: a_i = -(K/rho0^2) m sum_j (e_i + e_j) ∇_i W_ij + repulsion. The pair at r = 0 (i
 * itself) adds nothing. The sums run in four interleaved partial sums (as sum4). The weights
 * V_j = m/rho_j or e_j are in the list's rows (PACK_XV_WEIGHT). */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
accel_range(const int dim, const pack_sweep *sw, size_t i0, size_t i1, pair_buf *b)
{
#ifdef PACK_AVX2
    if (sw->avx2) {
        accel_avx2(dim, sw, i0, i1, b);
        return;
    }
#endif
    const force_params *fp = sw->fp;
    const double range2 = fp->rep.range * fp->rep.range;
    const int polish = fp->polish;
    const double *restrict r2 = b->r;
    const double *d0 = b->dx[0], *d1 = b->dx[1], *d2 = b->dx[2];
    for (size_t i = i0; i < i1; ++i) {
        const size_t m = sw->L->start[i + 1] - sw->L->start[i];
        const uint32_t *restrict J = sw->L->j + sw->L->start[i];
        const double *restrict dwr = sw->dwr + (sw->L->start[i] - sw->dwr_first);
        const double ei = polish ? XV(sw, i, PACK_XV_WEIGHT) : 0.0;
        double s[CONSPH_MAX_DIM][4] = {{0.0}}, rep[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        list_geometry(dim, sw, i, b, 1);
        for (size_t q = 0; q < m; q += 4) {
            for (int l = 0; l < 4; ++l) {
                const size_t e = q + l;
                const double wj = XV(sw, J[e], PACK_XV_WEIGHT);
                const double wq = polish ? ei + wj : wj;
                const double f = e < m && r2[e] > 0.0 ? wq * dwr[e] : 0.0;
                s[0][l] += f * d0[e];
                if (dim > 1) s[1][l] += f * d1[e];
                if (dim > 2) s[2][l] += f * d2[e];
            }
            for (size_t e = q; e < q + 4 && e < m; ++e)
                if (r2[e] < range2 && r2[e] > 0.0)
                    repulsion_add(dim, &fp->rep, r2[e], d0[e], d1[e], d2[e], rep);
        }
        const double coef = accel_coef(fp, sw->rho[i]);
        pack_work *w = sw->w;
        for (int a = 0; a < dim; ++a)
            w->acc[a][i] = coef * ((s[a][0] + s[a][1]) + (s[a][2] + s[a][3])) + rep[a];
    }
}

/* The pair loops gather through the list; a generic x86-64 build also carries an AVX2 copy,
 * chosen at load time (no FMA is enabled, so both copies compute the same values). */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__GLIBC__) &&       \
    !defined(__AVX2__)
#define PACK_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define PACK_CLONES
#endif

PACK_CLONES
static void density_block(const pack_sweep *sw, size_t i0, size_t i1, pair_buf *b)
{
    switch (sw->L->dim) {
    case 1:
        density_range(1, sw, i0, i1, b);
        break;
    case 2:
        density_range(2, sw, i0, i1, b);
        break;
    default:
        density_range(3, sw, i0, i1, b);
    }
}

PACK_CLONES
static void accel_block(const pack_sweep *sw, size_t i0, size_t i1, pair_buf *b)
{
    switch (sw->L->dim) {
    case 1:
        accel_range(1, sw, i0, i1, b);
        break;
    case 2:
        accel_range(2, sw, i0, i1, b);
        break;
    default:
        accel_range(3, sw, i0, i1, b);
    }
}

/* Runs density_block (force = 0) or accel_block over every particle in chunks, in parallel.
 * Each particle's sums are gathered in its list's order: independent of the number of
 * threads. */
static int sweep_run(const pack_sweep *sw, int force)
{
    const size_t n = sw->w->n, nchunks = (n + PACK_CHUNK - 1) / PACK_CHUNK;
    int failed = 0;
#pragma omp parallel if (n >= 2048)
    {
        pair_buf b;
        if (!pair_buf_alloc(&b, sw->L->max_len, PACK_CHUNK)) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp barrier
        if (!failed) {
#pragma omp for schedule(dynamic, 4)
            for (size_t c = 0; c < nchunks; ++c) {
                const size_t i0 = c * PACK_CHUNK, i1 = chunk_end(c, n);
                if (force)
                    accel_block(sw, i0, i1, &b);
                else
                    density_block(sw, i0, i1, &b);
            }
        }
        pair_buf_free(&b);
    }
    return failed ? CONSPH_ENOMEM : CONSPH_OK;
}

static void sweep_init(pack_sweep *sw, const force_params *fp, const pack_list *L, pack_work *w)
{
    memset(sw, 0, sizeof *sw);
    sw->fp = fp;
    sw->L = L;
    sw->w = w;
    sw->xv = L->xv;
    sw->dwr = L->dwr;
#ifdef PACK_AVX2
    sw->avx2 = pack_isa_cap != 1 && __builtin_cpu_supports("avx2");
    sw->avx512 = sw->avx2 && pack_isa_cap == 0 && __builtin_cpu_supports("avx512f");
#endif
}

/* What the density walk reads and writes: rho (caller's kernel), rho_glass (stage-1 kernel)
 * when it differs and in stage 1 only, and W'/r of the force's kernel. */
static void density_sweep_init(pack_sweep *sw, const force_params *fp, const pack_list *L,
                               pack_work *w)
{
    sweep_init(sw, fp, L, w);
    sw->glass = !fp->polish && w->rho_glass;
    sw->kern = fp->polish ? fp->target : fp->glass;
    sw->fused_quintic = sw->avx2 && !sw->glass && fp->target->id == CONSPH_KERNEL_QUINTIC &&
                        sw->kern->id == CONSPH_KERNEL_QUINTIC && sw->kern->h == fp->target->h &&
                        sw->kern->dim == fp->target->dim;
}

static void force_sweep_init(pack_sweep *sw, const force_params *fp, const pack_list *L,
                             pack_work *w)
{
    sweep_init(sw, fp, L, w);
    sw->rho = (fp->polish || !w->rho_glass) ? w->rho : w->rho_glass;
}

/* The per-particle factor of each pair's weight in the force (V_i or e_i), kept once per
 * particle instead of per pair in the rows the force walk loads the positions from. */
static inline double force_weight(const force_params *fp, const double *rho, size_t i)
{
    return fp->polish ? rho[i] / packing_rho0 - 1.0 : fp->mass / rho[i];
}

static int compute_density(const force_params *fp, pack_list *L, const consph_particles *p,
                           pack_work *w)
{
    /* The rows of the particles and the ghosts, read by this pass and the force pass. */
    pack_list_fill_positions(L, p);
    pack_sweep sw;
    density_sweep_init(&sw, fp, L, w);
    return sweep_run(&sw, 0);
}

static int compute_acceleration(const force_params *fp, pack_list *L, pack_work *w)
{
    pack_sweep sw;
    force_sweep_init(&sw, fp, L, w);
    double *restrict xv = L->xv;
#pragma omp parallel for schedule(static) if (w->n >= 2048)
    for (size_t i = 0; i < w->n; ++i)
        xv[PACK_XV_STRIDE * i + PACK_XV_WEIGHT] = force_weight(fp, sw.rho, i);
    pack_list_fill_ghost_weights(L);
    return sweep_run(&sw, 1);
}

/* Damped Euler step: u <- (1 - νΔt) u + Δt a, and x advanced with the old velocity (explicit
 * Euler, as [51]'s implementation integrates) or with the new one (symplectic Euler, the polished
 * kind). The positions are not wrapped into the box here: the list's periodic images stay valid
 * while they move continuously, and step_density wraps them when it rebuilds the list. Returns
 * max_i |u_i| after the step, and in *moved2 the largest squared distance of a particle from
 * where it was when the list was built. advance_range makes the step of particles i0..i1,
 * raising *vmax2 and *dmax2 to their largest |u_i|^2 and squared move. */
static void advance_range(consph_particles *p, pack_work *w, pack_list *L, double dt, double damp,
                          int explicit_euler, size_t i0, size_t i1, double *vmax2, double *dmax2)
{
    const int dim = w->dim;
    double *restrict xv = L->xv;
    double vm = *vmax2, dm = *dmax2;
    for (size_t i = i0; i < i1; ++i) {
        if (w->origin[i] >= w->n_free) continue; /* frozen: no motion, u stays 0 */
        double v2 = 0.0, d2 = 0.0;
        for (int a = 0; a < dim; ++a) {
            const double u0 = w->u[a][i], u1 = damp * u0 + dt * w->acc[a][i];
            w->u[a][i] = u1;
            const double x = p->x[a][i] + dt * (explicit_euler ? u0 : u1);
            p->x[a][i] = x;
            xv[PACK_XV_STRIDE * i + (size_t)a] = x;
            v2 += u1 * u1;
            d2 += (x - L->x_ref[a][i]) * (x - L->x_ref[a][i]);
        }
        if (v2 > vm) vm = v2;
        if (d2 > dm) dm = d2;
    }
    *vmax2 = vm;
    *dmax2 = dm;
}

static double advance(consph_particles *p, pack_work *w, pack_list *L, double dt, double nu,
                      int explicit_euler, double *moved2)
{
    const double damp = 1.0 - nu * dt;
    double vmax2 = 0.0, dmax2 = 0.0;
    const size_t blocks = (w->n + PACK_CHUNK - 1) / PACK_CHUNK;
#pragma omp parallel for schedule(static) reduction(max : vmax2, dmax2) if (w->n >= 2048)
    for (size_t c = 0; c < blocks; ++c)
        advance_range(p, w, L, dt, damp, explicit_euler, c * PACK_CHUNK, chunk_end(c, w->n), &vmax2,
                      &dmax2);
    /* The particles' rows of the list hold the new positions (the frozen ones kept theirs):
     * pack_list_fill_positions need only refresh the ghosts. */
    L->rows_current = 1;
    *moved2 = dmax2;
    return sqrt(vmax2);
}

/* Brings every position back into the periodic box. */
static void wrap_positions(consph_particles *p)
{
    for (int a = 0; a < p->dim; ++a) {
        const double lo = p->box.lo[a], len = consph_box_length(&p->box, a);
        for (size_t i = 0; i < p->n; ++i) p->x[a][i] = layout_wrap(p->x[a][i], lo, len);
    }
}

static int record_history(consph_packing_report *r, int cap, int iter, double spread)
{
    if (!r || r->nhistory >= cap) return CONSPH_OK;
    r->history_iter[r->nhistory] = iter;
    r->history_spread[r->nhistory] = spread;
    r->nhistory++;
    return CONSPH_OK;
}

/* Puts particle i back at index origin[i], so the result is in lattice order. */
static int restore_lattice_order(consph_particles *p, pack_work *w)
{
    for (size_t i = 0; i < w->n; ++i) w->perm[w->origin[i]] = i;
    return consph_particles_permute(p, w->perm);
}

/* What both kinds set up: kernels, forces, work arrays, the search and the neighbour list. */
typedef struct packer {
    consph_kernel target, glass;
    consph_nnps *grid;
    pack_list list;
    double rebuild_move2; /* rebuild the list once a particle has moved this far (squared) */
    int rebuild;          /* the list is stale */
    force_params fp;
    pack_work w;
    double nu;
    int hist_cap;
    /* The wavefront (step_wavefront): per chunk of PACK_CHUNK particles, the chunks holding its
     * neighbours (a ghost's source particle) at the last build, [lo, hi], and whether its force
     * waits for the end of the walk. */
    size_t nchunks;
    size_t *chunk_lo, *chunk_hi;
    unsigned char *chunk_late;
    /* Per chunk, where its W'/r is kept: the offset in its thread's ring, or PACK_NO_RING (the
     * list's own array); the rings, one a thread, of ring_cap entries plus PACK_SLACK. */
    size_t *chunk_ring;
    double **rings;
    int nrings;
    size_t ring_cap;
} packer;

#define PACK_NO_RING SIZE_MAX

static void free_rings(packer *pk)
{
    for (int t = 0; t < pk->nrings; ++t) free(pk->rings[t]);
    free(pk->rings);
    pk->rings = NULL;
    pk->nrings = 0;
    pk->ring_cap = 0;
}

static void packer_free(packer *pk)
{
    free_rings(pk);
    free(pk->chunk_ring);
    free(pk->chunk_lo);
    free(pk->chunk_hi);
    free(pk->chunk_late);
    consph_nnps_free(pk->grid);
    pack_list_free(&pk->list);
    work_free(&pk->w);
    memset(pk, 0, sizeof *pk);
}

static int packer_init(packer *pk, const consph_layout_params *lp, consph_particles *p,
                       size_t n_free, consph_packing_report *report)
{
    const consph_packing_params *pp = &lp->packing;
    memset(pk, 0, sizeof *pk);
    consph_kernel_id id;
    int rc = check_packing(lp, &id);
    if (rc) return rc;
    const int dim = lp->dim;
    const double ds = p->spacing;
    rc = consph_kernel_init(&pk->target, id, dim, pp->hdx * ds);
    if (rc) return rc;
    /* packed runs [51]'s packing with the caller's kernel (quintic, h = 1.2Δs by default, as in
     * [51] and its implementation); the polished kind's first stage always uses that default. */
    int same_kernel = 1;
    pk->glass = pk->target;
    if (lp->kind == CONSPH_LAYOUT_PACKED_POLISHED) {
        rc = consph_kernel_init(&pk->glass, CONSPH_KERNEL_QUINTIC, dim, 1.2 * ds);
        if (rc) return rc;
        same_kernel = id == CONSPH_KERNEL_QUINTIC && pp->hdx == 1.2;
    }
    force_params *fp = &pk->fp;
    fp->mass = packing_rho0 * pow(ds, dim);
    fp->polish = 0;
    fp->rep.k = (dim == 3 ? 0.006 : 0.004) * ds;
    fp->rep.c = (2.0 / 3.0) * 0.95 * ds;
    fp->rep.range = 1.5 * fp->rep.c;
    fp->rep.r_floor = 0.5 * pk->glass.h;
    pk->nu = (dim == 3 ? 0.5 : 0.2) / ds;

    /* With walls the caller has perturbed the free particles and added the frozen ones. */
    if (n_free == p->n) consph_layout_perturb(lp, p, ds, pp->perturb);

    if (report && pp->history_every > 0) {
        pk->hist_cap = pp->max_iter / pp->history_every + 2;
        report->history_iter = consph_calloc((size_t)pk->hist_cap, sizeof(int));
        report->history_spread = consph_calloc((size_t)pk->hist_cap, sizeof(double));
        if (!report->history_iter || !report->history_spread) return CONSPH_ENOMEM;
    }
    rc = work_alloc(&pk->w, p->n, dim, !same_kernel);
    if (rc) return rc;
    pk->nchunks = (p->n + PACK_CHUNK - 1) / PACK_CHUNK;
    pk->chunk_lo = consph_calloc(pk->nchunks + 1, sizeof(size_t));
    pk->chunk_hi = consph_calloc(pk->nchunks + 1, sizeof(size_t));
    pk->chunk_late = consph_calloc(pk->nchunks + 1, 1);
    pk->chunk_ring = consph_calloc(pk->nchunks + 1, sizeof(size_t));
    if (!pk->chunk_lo || !pk->chunk_hi || !pk->chunk_late || !pk->chunk_ring) return CONSPH_ENOMEM;
    pk->w.n_free = n_free;
    /* A pair farther apart than the kernel radius at a build can come within it only after one
     * of the two has moved half the skin. */
    const double radius = fmax(pk->glass.radius, pk->target.radius);
    const double skin = packing_skin * radius;
    pk->rebuild_move2 = 0.25 * skin * skin;
    pk->rebuild = 1;
    pk->grid = consph_nnps_create(&p->box, radius + skin, 0);
    if (!pk->grid) return CONSPH_ENOMEM;
    fp->glass = &pk->glass;
    fp->target = &pk->target;
    return pack_list_init(&pk->list, p, radius + skin);
}

/* The chunks holding the neighbours of each chunk's particles in the list just built. */
static void chunk_bounds(packer *pk)
{
    const pack_list *L = &pk->list;
    const size_t n = L->n, nc = pk->nchunks;
    for (size_t c = 0; c < nc; ++c) {
        const size_t i0 = c * PACK_CHUNK, i1 = chunk_end(c, n);
        size_t lo = i0, hi = i1 - 1;
        for (size_t i = i0; i < i1; ++i) {
            lo = L->j_lo[i] < lo ? L->j_lo[i] : lo;
            hi = L->j_hi[i] > hi ? L->j_hi[i] : hi;
        }
        pk->chunk_lo[c] = lo / PACK_CHUNK;
        pk->chunk_hi[c] = hi / PACK_CHUNK;
    }
}

/* Rings of at least `cap` entries for `threads` threads, kept from step to step (fresh
 * allocations of this size would fault in their pages at every step). */
static int reserve_rings(packer *pk, int threads, size_t cap)
{
    if (threads <= pk->nrings && cap <= pk->ring_cap) return CONSPH_OK;
    if (cap < pk->ring_cap) cap = pk->ring_cap;
    cap += cap / 4;
    if (threads < pk->nrings) threads = pk->nrings;
    free_rings(pk);
    pk->rings = consph_calloc((size_t)threads, sizeof *pk->rings);
    if (!pk->rings) return CONSPH_ENOMEM;
    pk->nrings = threads;
    for (int t = 0; t < threads; ++t)
        if (!(pk->rings[t] = consph_calloc(cap + PACK_SLACK, sizeof(double)))) {
            free_rings(pk);
            return CONSPH_ENOMEM;
        }
    pk->ring_cap = cap;
    return CONSPH_OK;
}

/* Where chunk f's W'/r goes in a ring of `cap` entries whose next free entry is `head`: at
 * head, or at 0 where it does not fit before the end, unless that overlaps the entries of a
 * chunk in [pending, f) whose force has not read them yet; PACK_NO_RING then. */
static size_t ring_place(const packer *pk, size_t f, size_t pending, size_t head, size_t cap)
{
    const size_t *start = pk->list.start, n = pk->list.n;
    const size_t len = start[chunk_end(f, n)] - start[f * PACK_CHUNK];
    const size_t off = head + len <= cap ? head : 0;
    if (off + len > cap) return PACK_NO_RING;
    for (size_t k = pending; k < f; ++k) {
        const size_t o = pk->chunk_ring[k];
        if (o == PACK_NO_RING) continue;
        if (off < o + (start[chunk_end(k, n)] - start[k * PACK_CHUNK]) && o < off + len)
            return PACK_NO_RING;
    }
    return off;
}

/* Points the sweep's W'/r at the chunk starting at particle i0: at offset `off` of the ring, or
 * the list's own array where off is PACK_NO_RING. */
static inline void sweep_dwr_at(pack_sweep *sw, const pack_list *L, double *ring, size_t off,
                                size_t i0)
{
    sw->dwr = off == PACK_NO_RING ? L->dwr : ring + off;
    sw->dwr_first = off == PACK_NO_RING ? 0 : L->start[i0];
}

/* What step_wavefront also does after the forces: the damped step of advance (dt, nu,
 * explicit_euler in; max_i |u_i|^2 and the largest squared move since the build out), and the
 * density spread of consph_layout_spread (out). */
typedef struct wave_step {
    double dt, nu;
    int explicit_euler;
    double vmax2, moved2, spread;
} wave_step;

/* The density walk and the force walk of one step as a wavefront: each thread takes a contiguous
 * share of the chunks and computes their densities, force weights and W'/r chunk by chunk,
 * running the force on a chunk as soon as its share holds the densities of every chunk with a
 * neighbour of it, a neighbourhood's span of chunks behind. The chunk's W'/r goes to a small
 * ring of the thread's, reused chunk after chunk, and its list indices are read again while
 * still cached: the list is streamed from memory once per step instead of twice, and W'/r (two
 * thirds of its bytes) neither written to nor read back from memory (at 2D nx 500 the list is
 * 135 MB, far beyond the caches). A chunk with a neighbour in another thread's share (the
 * periodic images across the box, the shares' edges) keeps its W'/r in the list's array and has
 * its force after every thread's walk is over. Every sum reads what it reads in compute_density
 * then compute_acceleration, so the same values for any thread count. The same parallel region
 * refreshes the rows first and makes the step of advance last, each thread on its own share, and
 * takes the density spread chunk by chunk (maxima: exact), so that a step forks the threads once
 * and leaves no serial pass over the particles (a thread waiting on one spins). */
static int step_wavefront(packer *pk, consph_particles *p, wave_step *ws)
{
    pack_list *L = &pk->list;
    pack_work *w = &pk->w;
    const force_params *fp = &pk->fp;
    const size_t n = w->n, nc = pk->nchunks;
#ifdef _OPENMP
    const int max_threads = n >= 2048 ? omp_get_max_threads() : 1;
#else
    const int max_threads = 1;
#endif
    int rc = reserve_rings(pk, max_threads, (size_t)pack_ring_chunks * (L->start[n] / nc + 1));
    if (rc) return rc;
    pack_sweep sd, sf;
    density_sweep_init(&sd, fp, L, w);
    force_sweep_init(&sf, fp, L, w);
    const size_t *lo = pk->chunk_lo, *hi = pk->chunk_hi, *start = L->start;
    unsigned char *late = pk->chunk_late;
    size_t *ring_of = pk->chunk_ring;
    double *xv = L->xv;
    const size_t rows = n + L->n_ghost, first_row = L->rows_current ? n : 0;
    /* A chunk with a neighbour this many chunks ahead or more (at one thread, the periodic
     * images across the box) is late too: the ring cannot hold what its force would wait for,
     * and waiting would hold back every later chunk's force, their W'/r overflowing the ring
     * into the list's array. Half the ring would make every chunk late from 2D nx ~680 on (by
     * the geometry: a neighbourhood's two rows of cells span ~0.03 nx chunks), where the ring
     * still holds them. */
    const size_t reach = (size_t)pack_ring_chunks;
    const double damp = 1.0 - ws->nu * ws->dt;
    /* The spread as consph_layout_spread: the largest |rho/rho0 - 1|, or NaN where one is (the
     * maxima are exact: the same for any split) */
    double vmax2 = 0.0, dmax2 = 0.0, spread = 0.0;
    int nan_rho = 0;
    int failed = 0;
#pragma omp parallel if (n >= 2048) reduction(max : vmax2, dmax2, spread) reduction(| : nan_rho)
    {
#ifdef _OPENMP
        const size_t nt = (size_t)omp_get_num_threads(), t = (size_t)omp_get_thread_num();
#else
        const size_t nt = 1, t = 0;
#endif
        const size_t c0 = nc * t / nt, c1 = nc * (t + 1) / nt;
        double *ring = pk->rings[t];
        pack_sweep sdt = sd, sft = sf;
        pair_buf b;
        if (!pair_buf_alloc(&b, L->max_len, PACK_CHUNK)) {
#pragma omp atomic write
            failed = 1;
        }
        /* The rows the walks read (pack_list_fill_positions), each thread its part. */
        pack_list_fill_range(L, p, first_row + (rows - first_row) * t / nt,
                             first_row + (rows - first_row) * (t + 1) / nt);
#pragma omp barrier
        if (!failed) {
            size_t next = c0, head = 0; /* the first chunk without its force; the ring's next */
            for (size_t f = c0; f < c1; ++f) {
                const size_t i0 = f * PACK_CHUNK, i1 = chunk_end(f, n);
                late[f] = lo[f] < c0 || hi[f] >= c1 || hi[f] >= f + reach;
                const size_t off =
                    late[f] ? PACK_NO_RING : ring_place(pk, f, next, head, pk->ring_cap);
                ring_of[f] = off;
                sweep_dwr_at(&sdt, L, ring, off, i0);
                if (off != PACK_NO_RING) head = off + (start[i1] - start[i0]);
                density_block(&sdt, i0, i1, &b);
                for (size_t i = i0; i < i1; ++i) {
                    const double e = fabs(w->rho[i] / packing_rho0 - 1.0);
                    nan_rho |= isnan(e);
                    if (e > spread) spread = e;
                    const double wt = force_weight(fp, sf.rho, i);
                    xv[PACK_XV_STRIDE * i + PACK_XV_WEIGHT] = wt;
                    for (int32_t g = L->ghost_head[i]; g >= 0; g = L->ghost_next[g])
                        xv[PACK_XV_STRIDE * (n + (size_t)g) + PACK_XV_WEIGHT] = wt;
                }
                /* f + 1 == c1: every chunk of the share has its densities */
                for (; next <= f; ++next) {
                    if (late[next]) continue;
                    if (hi[next] > f && f + 1 < c1) break;
                    sweep_dwr_at(&sft, L, ring, ring_of[next], next * PACK_CHUNK);
                    accel_block(&sft, next * PACK_CHUNK, chunk_end(next, n), &b);
                }
            }
        }
#pragma omp barrier
        if (!failed)
            for (size_t c = c0; c < c1; ++c)
                if (late[c]) accel_block(&sf, c * PACK_CHUNK, chunk_end(c, n), &b);
        pair_buf_free(&b);
        /* advance's step of the share's particles, once no walk reads their rows */
#pragma omp barrier
        if (!failed && c0 < c1)
            advance_range(p, w, L, ws->dt, damp, ws->explicit_euler, c0 * PACK_CHUNK,
                          chunk_end(c1 - 1, n), &vmax2, &dmax2);
    }
    if (failed) return CONSPH_ENOMEM;
    L->rows_current = 1;
    ws->vmax2 = vmax2;
    ws->moved2 = dmax2;
    ws->spread = nan_rho ? NAN : spread;
    return CONSPH_OK;
}

/* Rebuilds the neighbour list when it is stale (wrapping the particles into the box and sorting
 * them into cell order first), computes the density and records the step in the report. With
 * `forced` non-NULL it also computes the accelerations and makes the step with ws's dt
 * (step_wavefront) where the wavefront is on, and sets *forced then. */
static int step_density(packer *pk, const consph_layout_params *lp, consph_particles *p, int iter,
                        int last, consph_packing_report *report, double *spread, int *forced,
                        wave_step *ws)
{
    int rc = CONSPH_OK;
    if (pk->rebuild) {
        wrap_positions(p);
        rc = consph_nnps_sort(pk->grid, p, pk->w.perm);
        if (!rc) {
            work_permute(&pk->w);
            rc = pack_list_build(&pk->list, pk->grid, p);
        }
        if (!rc) chunk_bounds(pk);
        pk->rebuild = 0;
    }
    /* Not in 3D: there the density walk loads whole 32-byte rows, the weight slot that the
     * wavefront writes at the same time included (unused, but a data race). */
    if (!rc && forced && !pack_wavefront_off && pk->w.dim < 3) {
        rc = step_wavefront(pk, p, ws);
        *forced = 1;
        *spread = ws->spread;
    } else if (!rc) {
        rc = compute_density(&pk->fp, &pk->list, p, &pk->w);
        if (!rc) *spread = consph_layout_spread(pk->w.rho, pk->w.n, packing_rho0);
    }
    if (rc) return rc;
    if (!isfinite(*spread))
        return consph_fail(CONSPH_ENUMERIC, "layout %s: non-finite density at step %d",
                           consph_layout_name(lp->kind), iter);
    if (iter == 0 && report) report->rho_spread_initial = *spread;
    const int every = lp->packing.history_every;
    if (report && every > 0 && (iter % every == 0 || last))
        record_history(report, pk->hist_cap, iter, *spread);
    return CONSPH_OK;
}

/* One step of the particles; marks the list stale when a particle has moved half the skin. */
static double step_advance(packer *pk, consph_particles *p, double dt, int explicit_euler)
{
    double moved2;
    double vmax = advance(p, &pk->w, &pk->list, dt, pk->nu, explicit_euler, &moved2);
    if (!(moved2 <= pk->rebuild_move2)) pk->rebuild = 1;
    return vmax;
}

/* [51]'s time-step ramp (its solver's n_damp = 10): step `count` uses this fraction of the step
 * size, rising as half a sine wave from ~0 to 1, so that the first steps from rest, where the
 * forces are largest, stay small. */
static double ramp(int count)
{
    if (count >= packing_ramp_steps) return 1.0;
    return 0.5 * (sin(M_PI * (-0.5 + (count + 1) / (double)packing_ramp_steps)) + 1.0);
}

static int pack_single(packer *pk, const consph_layout_params *lp, consph_particles *p,
                       consph_packing_report *report)
{
    const consph_packing_params *pp = &lp->packing;
    const double h = pk->glass.h, nu = pk->nu;
    const double dt_pb = packing_dt_factor * h / sqrt(packing_pb / packing_rho0);
    double dt = packing_first_dt * ramp(0), spread = INFINITY, move = NAN;
    int steps = 0, checks = 0, converged = 0, rc;
    for (;;) {
        const int last = converged || steps >= pp->max_iter;
        int forced = 0;
        wave_step ws = {dt, nu, 1, 0.0, 0.0, 0.0};
        rc = step_density(pk, lp, p, steps, last, report, &spread, last ? NULL : &forced, &ws);
        if (rc || last) break;
        double vmax;
        if (forced) {
            /* the wavefront has made advance's step too */
            vmax = sqrt(ws.vmax2);
            if (!(ws.moved2 <= pk->rebuild_move2)) pk->rebuild = 1;
        } else {
            rc = compute_acceleration(&pk->fp, &pk->list, &pk->w);
            if (rc) break;
            vmax = step_advance(pk, p, dt, 1);
        }
        if (steps % packing_check_every == 0) {
            ++checks;
            move = 100.0 * vmax * dt / h;
            converged = move <= pp->move_tol && checks >= packing_min_checks;
        }
        ++steps;
        /* The next step: 0.1h/c0, or the viscous limit sqrt(0.1h/(ν max|u|)) where smaller; the
         * step after the first from rest keeps the fixed start value. */
        double next = dt_pb;
        if (steps == 1)
            next = packing_first_dt;
        else if (vmax > 1e-14)
            next = fmin(dt_pb, sqrt(packing_dt_factor * h / nu / vmax));
        dt = next * ramp(steps);
    }
    if (report) {
        report->iterations = steps;
        report->rho_spread_final = spread;
        report->move_final = move;
        report->converged = converged;
    }
    return rc;
}

static int pack_polished(packer *pk, const consph_layout_params *lp, consph_particles *p,
                         consph_packing_report *report)
{
    const consph_packing_params *pp = &lp->packing;
    force_params *fp = &pk->fp;
    const double c0 = sqrt(packing_pb / packing_rho0);
    const double dt_glass = packing_dt_factor * pk->glass.h / c0;
    const double dt_polish = packing_dt_factor * (pk->target.radius / 3.0) / c0;
    int iter = 0, best_iter = 0, rc;
    double best = INFINITY, spread = INFINITY;
    if (report) report->polish_start = -1;
    for (;; ++iter) {
        /* The density decides whether this step is the last, so it is recorded once known. */
        rc = step_density(pk, lp, p, iter, 0, NULL, &spread, NULL, NULL);
        if (rc) break;
        if (iter == 0 && report) report->rho_spread_initial = spread;
        int done = spread < pp->tol || iter >= pp->max_iter;
        if (report && pp->history_every > 0 && (iter % pp->history_every == 0 || done))
            record_history(report, pk->hist_cap, iter, spread);
        if (done) break;
        if (!fp->polish) {
            /* Stage 1 acts on the stage-1 density, so its progress is judged on that. */
            double glass_spread = pk->w.rho_glass
                                      ? consph_layout_spread(pk->w.rho_glass, pk->w.n, packing_rho0)
                                      : spread;
            if (glass_spread < packing_stall_gain * best) {
                best = glass_spread;
                best_iter = iter;
            }
            if (iter - best_iter >= packing_stall_steps || 2 * iter >= pp->max_iter) {
                fp->polish = 1;
                for (int a = 0; a < pk->w.dim; ++a) memset(pk->w.u[a], 0, pk->w.n * sizeof(double));
                if (report) report->polish_start = iter;
            }
        }
        rc = compute_acceleration(fp, &pk->list, &pk->w);
        if (rc) break;
        step_advance(pk, p, fp->polish ? dt_polish : dt_glass, 0);
    }
    if (report) {
        report->iterations = iter;
        report->rho_spread_final = spread;
        report->move_final = NAN;
        report->converged = spread < pp->tol;
    }
    return rc;
}

/* The walled variant: the perturbed particles of the box plus a frozen container, `walls`
 * layers of the cell-centred lattice continued outside the box on every side, in a periodic box
 * enlarged by those layers. The container is 2·walls layers thick across the enlarged box's
 * seam, so with walls >= 2 (quintic, h = 1.2Δs: support 3.6Δs) no free particle sees the images
 * of the free particles on the other side: the packing is that of a walled square, as PySPH's
 * packing tool (tools/particle_packing.py, create_frozen_container: frozen lattice layers
 * around the domain, default l = 3, taking part in every force but never moving) does for a
 * bounded domain. The free particles are then returned in the original box, which the caller
 * treats as periodic: at its edges two wall-aligned rows meet. Returns the enlarged set in *q
 * (free particles first, in lattice order). */
static int build_walled(const consph_layout_params *lp, const consph_particles *p,
                        consph_particles *q)
{
    const int dim = lp->dim, L = lp->packing.walls;
    const double ds = p->spacing;
    consph_box box = p->box;
    size_t next[CONSPH_MAX_DIM], n_ext = 1;
    for (int a = 0; a < dim; ++a) {
        box.lo[a] -= L * ds;
        box.hi[a] += L * ds;
        box.periodic[a] = 1;
        next[a] = lp->nx[a] + 2 * (size_t)L;
        n_ext *= next[a];
    }
    int rc = consph_particles_init(q, dim, n_ext, &box);
    if (rc) return rc;
    q->spacing = ds;
    for (int a = 0; a < dim; ++a) memcpy(q->x[a], p->x[a], p->n * sizeof(double));
    size_t k = p->n;
    for (size_t c = 0; c < n_ext; ++c) {
        size_t rem = c, idx[CONSPH_MAX_DIM];
        int inside = 1;
        for (int a = 0; a < dim; ++a) {
            idx[a] = rem % next[a];
            rem /= next[a];
            inside &= idx[a] >= (size_t)L && idx[a] < (size_t)L + lp->nx[a];
        }
        if (inside) continue;
        for (int a = 0; a < dim; ++a) q->x[a][k] = box.lo[a] + ((double)idx[a] + 0.5) * ds;
        ++k;
    }
    return CONSPH_OK;
}

int consph_layout_pack(const consph_layout_params *lp, consph_particles *p,
                       consph_packing_report *report)
{
    const double t0 = consph_wtime();
    packer pk;
    memset(&pk, 0, sizeof pk);
    if (lp->kind == CONSPH_LAYOUT_PACKED && lp->packing.walls > 0) {
        consph_layout_params lw = *lp;
        int rc = check_packing(lp, &(consph_kernel_id){0});
        if (rc) return rc;
        consph_layout_perturb(lp, p, p->spacing, lp->packing.perturb);
        consph_particles q;
        memset(&q, 0, sizeof q);
        rc = build_walled(lp, p, &q);
        if (!rc) {
            lw.box = q.box;
            rc = packer_init(&pk, &lw, &q, p->n, report);
        }
        if (!rc) {
            if (report) report->polish_start = -1;
            rc = pack_single(&pk, &lw, &q, report);
        }
        if (!rc) {
            wrap_positions(&q);
            rc = restore_lattice_order(&q, &pk.w);
        }
        if (!rc) {
            for (int a = 0; a < lp->dim; ++a) memcpy(p->x[a], q.x[a], p->n * sizeof(double));
            wrap_positions(p);
        }
        if (!rc && report) report->seconds = consph_wtime() - t0;
        packer_free(&pk);
        consph_particles_free(&q);
        return rc;
    }
    int rc = packer_init(&pk, lp, p, p->n, report);
    if (!rc) {
        if (report) report->polish_start = -1;
        rc = lp->kind == CONSPH_LAYOUT_PACKED_POLISHED ? pack_polished(&pk, lp, p, report)
                                                       : pack_single(&pk, lp, p, report);
    }
    if (!rc) {
        wrap_positions(p);
        rc = restore_lattice_order(p, &pk.w);
    }
    if (!rc && report) report->seconds = consph_wtime() - t0;
    packer_free(&pk);
    return rc;
}
