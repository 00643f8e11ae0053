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
 * Every pair sum is a pass (consph_pass_run) over systems wrapping the particles and one
 * neighbour search: W for the density, W'/r for the forces. Reproducibility: the passes are
 * gathers with neighbours in a fixed order and the only reductions are max/min, which are exact;
 * so the result does not depend on the number of threads. Particles are kept in cell order during
 * the iteration for memory locality and returned in lattice order: particle i of the result
 * started at lattice node i. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "layout/layout_internal.h"

static const double packing_rho0 = 1.0;
static const double packing_pb = 1.0;
static const double packing_dt_factor = 0.1;  /* Δt = factor · h / c0 */
static const double packing_polish_k = 300.0; /* K / p_b of stage 2 */
/* Stage 1 has stalled when its best spread has not improved by this factor for this many
 * steps. */
static const double packing_stall_gain = 0.9;
static const int packing_stall_steps = 200;
/* Re-sort the particles into cell order every this many steps: often enough that neighbours
 * stay close in memory, rarely enough that the permutations cost nothing. */
static const int packing_sort_every = 25;
/* packed, as [51]'s implementation runs it on free particles: the stopping test every this many
 * steps (its dfreq), honoured from this many tests on (its "more than 10"), the steps of its
 * time-step ramp (n_damp) and the step size it starts from rest with (its dt_adapt at t = 0). */
static const int packing_check_every = 50;
static const int packing_min_checks = 11;
static const int packing_ramp_steps = 10;
static const double packing_first_dt = 1e-7;

typedef struct pack_work {
    size_t n;
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
    return CONSPH_OK;
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
    const consph_sys *glass_sys;  /* stage 1: quintic, h = 1.2Δs */
    const consph_sys *target_sys; /* the caller's kernel: stopping test and stage 2 */
    double mass;
    int polish; /* 0: stage 1, background pressure; 1: stage 2, density-error gradient */
    repulsion rep;
} force_params;

/* rho (caller's kernel) and, when it differs, rho_glass (stage-1 kernel); rho_glass is needed only
 * in stage 1. */
static int compute_density(const force_params *fp, pack_work *w)
{
    int rc = consph_layout_density(fp->target_sys, fp->mass, w->rho, NULL);
    if (!rc && !fp->polish && w->rho_glass)
        rc = consph_layout_density(fp->glass_sys, fp->mass, w->rho_glass, NULL);
    return rc;
}

typedef struct accel_job {
    const force_params *fp;
    pack_work *w;
    const double *rho;
} accel_job;

/* Stage 1: a_i = -(p_b/m) V_i sum_j V_j ∇_i W_ij + repulsion, with ∇_i W_ij = (W'/r) x_ij.
 * Stage 2: a_i = -(K/rho0^2) m sum_j (e_i + e_j) ∇_i W_ij + repulsion. */
static void accel_visit(void *job, const consph_nbhd *nb)
{
    const accel_job *jb = job;
    const force_params *fp = jb->fp;
    pack_work *w = jb->w;
    const double *rho = jb->rho;
    const int dim = w->dim;
    const double mass = fp->mass, rho0 = packing_rho0;
    const size_t i = nb->i;
    double sum[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
    double rep[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
    const double ei = rho[i] / rho0 - 1.0;
    for (size_t q = 0; q < nb->n; ++q) {
        double r = nb->r[q];
        if (!(r > 0.0)) continue;
        double rho_j = rho[nb->j[q]];
        double weight = fp->polish ? ei + (rho_j / rho0 - 1.0) : mass / rho_j;
        double f = weight * nb->dwr[q];
        for (int a = 0; a < dim; ++a) sum[a] += f * nb->dx[a][q];
        if (r < fp->rep.range) {
            double g = repulsion_coef(&fp->rep, r);
            for (int a = 0; a < dim; ++a) rep[a] += g * nb->dx[a][q];
        }
    }
    double coef = fp->polish ? -packing_polish_k * packing_pb / (rho0 * rho0) * mass
                             : -packing_pb * (mass / rho[i]) / mass;
    for (int a = 0; a < dim; ++a) w->acc[a][i] = coef * sum[a] + rep[a];
}

static int compute_acceleration(const force_params *fp, pack_work *w)
{
    accel_job job = {fp, w, (fp->polish || !w->rho_glass) ? w->rho : w->rho_glass};
    const consph_pass pass = {"packing force", CONSPH_PASS_DW, accel_visit};
    return consph_pass_run(fp->polish ? fp->target_sys : fp->glass_sys, &pass, &job);
}

/* Damped Euler step, then wrap into the periodic box: u <- (1 - νΔt) u + Δt a, and x advanced
 * with the old velocity (explicit Euler, as [51]'s implementation integrates) or with the new one
 * (symplectic Euler, the polished kind). Returns max_i |u_i| after the step. */
static double advance(consph_particles *p, pack_work *w, double dt, double nu, int explicit_euler)
{
    const double damp = 1.0 - nu * dt;
    const int dim = w->dim;
    double lo[CONSPH_MAX_DIM], len[CONSPH_MAX_DIM];
    for (int a = 0; a < dim; ++a) {
        lo[a] = p->box.lo[a];
        len[a] = consph_box_length(&p->box, a);
    }
    double vmax2 = 0.0;
#pragma omp parallel for schedule(static) reduction(max : vmax2)
    for (size_t i = 0; i < w->n; ++i) {
        double v2 = 0.0;
        for (int a = 0; a < dim; ++a) {
            const double u0 = w->u[a][i], u1 = damp * u0 + dt * w->acc[a][i];
            w->u[a][i] = u1;
            p->x[a][i] = layout_wrap(p->x[a][i] + dt * (explicit_euler ? u0 : u1), lo[a], len[a]);
            v2 += u1 * u1;
        }
        if (v2 > vmax2) vmax2 = v2;
    }
    return sqrt(vmax2);
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

/* What both kinds set up: kernels, forces, work arrays, the search and the systems on it. */
typedef struct packer {
    consph_kernel target, glass;
    consph_sys target_sys, glass_sys;
    consph_nnps *grid;
    force_params fp;
    pack_work w;
    double nu;
    int hist_cap;
} packer;

static void packer_free(packer *pk)
{
    consph_nnps_free(pk->grid);
    work_free(&pk->w);
    memset(pk, 0, sizeof *pk);
}

static int packer_init(packer *pk, const consph_layout_params *lp, consph_particles *p,
                       consph_packing_report *report)
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

    consph_layout_perturb(lp, p, ds, pp->perturb);

    if (report && pp->history_every > 0) {
        pk->hist_cap = pp->max_iter / pp->history_every + 2;
        report->history_iter = consph_calloc((size_t)pk->hist_cap, sizeof(int));
        report->history_spread = consph_calloc((size_t)pk->hist_cap, sizeof(double));
        if (!report->history_iter || !report->history_spread) return CONSPH_ENOMEM;
    }
    rc = work_alloc(&pk->w, p->n, dim, !same_kernel);
    if (rc) return rc;
    pk->grid = consph_nnps_create(&p->box, fmax(pk->glass.radius, pk->target.radius), 0);
    if (!pk->grid) return CONSPH_ENOMEM;
    /* Both systems share the particles and the search, rebuilt in place every step. */
    rc = consph_sys_wrap(&pk->glass_sys, p, pk->grid, &pk->glass);
    if (!rc) rc = consph_sys_wrap(&pk->target_sys, p, pk->grid, &pk->target);
    fp->glass_sys = &pk->glass_sys;
    fp->target_sys = &pk->target_sys;
    return rc;
}

/* Rebuilds the search on the moved particles (re-sorting them every packing_sort_every steps),
 * computes the density and records the step in the report. */
static int step_density(packer *pk, const consph_layout_params *lp, consph_particles *p, int iter,
                        int last, consph_packing_report *report, double *spread)
{
    int rc;
    if (iter % packing_sort_every == 0) {
        rc = consph_nnps_sort(pk->grid, p, pk->w.perm);
        if (!rc) work_permute(&pk->w);
    } else {
        rc = consph_nnps_build(pk->grid, p);
    }
    if (!rc) rc = compute_density(&pk->fp, &pk->w);
    if (rc) return rc;
    *spread = consph_layout_spread(pk->w.rho, pk->w.n, packing_rho0);
    if (!isfinite(*spread))
        return consph_fail(CONSPH_ENUMERIC, "layout %s: non-finite density at step %d",
                           consph_layout_name(lp->kind), iter);
    if (iter == 0 && report) report->rho_spread_initial = *spread;
    const int every = lp->packing.history_every;
    if (report && every > 0 && (iter % every == 0 || last))
        record_history(report, pk->hist_cap, iter, *spread);
    return CONSPH_OK;
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
        rc = step_density(pk, lp, p, steps, last, report, &spread);
        if (rc || last) break;
        rc = compute_acceleration(&pk->fp, &pk->w);
        if (rc) break;
        const double vmax = advance(p, &pk->w, dt, nu, 1);
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
        rc = step_density(pk, lp, p, iter, 0, NULL, &spread);
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
        rc = compute_acceleration(fp, &pk->w);
        if (rc) break;
        advance(p, &pk->w, fp->polish ? dt_polish : dt_glass, pk->nu, 0);
    }
    if (report) {
        report->iterations = iter;
        report->rho_spread_final = spread;
        report->move_final = NAN;
        report->converged = spread < pp->tol;
    }
    return rc;
}

int consph_layout_pack(const consph_layout_params *lp, consph_particles *p,
                       consph_packing_report *report)
{
    const double t0 = consph_wtime();
    packer pk;
    int rc = packer_init(&pk, lp, p, report);
    if (!rc) {
        if (report) report->polish_start = -1;
        rc = lp->kind == CONSPH_LAYOUT_PACKED_POLISHED ? pack_polished(&pk, lp, p, report)
                                                       : pack_single(&pk, lp, p, report);
    }
    if (!rc) rc = restore_lattice_order(p, &pk.w);
    if (!rc && report) report->seconds = consph_wtime() - t0;
    packer_free(&pk);
    return rc;
}
