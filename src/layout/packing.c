/* The packed (PP) arrangement of 001 B1.0: "particles slightly perturbed from a uniform mesh ...
 * allowed to settle into a distribution with a nearly constant density using a particle packing
 * algorithm [51]" ([51] = Negi & Ramachandran 2021, CPC 265:108008).
 *
 * Initial state: the cell-centred lattice with every coordinate moved by perturb·Δs·(2U - 1),
 * U uniform in [0, 1) drawn from the seeded generator.
 *
 * Stage 1, the packing of [51] as its authors implement it (PySPH tools/particle_packing.py,
 * class ParticlePacking, for the free particles): damped motion under the "background pressure"
 * force and a short-range repulsion,
 *
 *     du_i/dt = -(p_b/m) sum_j V_i V_j ∇_i W_ij + sum_{j: r_ij < 1.5c} g(r_ij) x_ij - ν u_i,
 *     g(r) = 12 k (3c^2/r^5 - 2c/r^4) where positive, r floored at h/2,
 *
 * V_i = m/rho_i from the summation density rho_i = m sum_j W_ij, m = rho0 Δs^d. This stage always
 * uses the quintic spline with h = 1.2Δs, the setting of [51] and of 001, whatever kernel the
 * caller names: the caller's kernel is "the kernel for the density estimate" (stage 2 and the
 * stopping test), and kernels with many neighbours pair particles in this stage (the quintic
 * at h = 2Δs did: nearest-neighbour distances down to 0.13Δs). Parameters are the defaults of
 * that implementation: p_b = 1 with rho0 = 1 (c0 = sqrt(p_b/rho0) = 1); ν = 0.2/Δs in 1D and 2D,
 * 0.5/Δs in 3D; k = 0.004Δs in 1D and 2D, 0.006Δs in 3D; c = (2/3)·0.95Δs (repulsion range
 * 0.95Δs); Δt = 0.1 h/c0 = 0.12Δs. The boundary-node machinery of [51] has nothing to do in a
 * periodic box and is left out. Integration is the damped explicit Euler step of that
 * implementation except that x is advanced with the new velocity (symplectic Euler).
 * This stage turns the perturbed lattice into a glass: with perturb = 0.5 its geometry matches
 * the author's packed files (catalogue Z7: mean distance to the nearest lattice node ≈ 0.34Δs).
 * Smaller perturbations relax back towards the square lattice, which is a stable equilibrium
 * of these forces (measured at nx = 50: mean distance to the node 0.02Δs at perturb = 0.25,
 * 0.09Δs at 0.3, 0.18Δs at 0.35, 0.34Δs at 0.5). The equilibrium of stage 1 is not uniform
 * density, though: its spread stalls at a few 1e-3.
 *
 * Stage 2, density polishing (ours: the packing is asked for max|rho/rho0 - 1| < tol, which stage
 * 1 cannot reach): once stage 1 stalls (its best spread has not improved by 10% for 200 steps,
 * or half of max_iter is spent), the background-pressure force is replaced by the gradient of
 * the density error E = (K/2) sum_i (rho_i/rho0 - 1)^2 with the caller's kernel,
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
 * made Wendland kernels, whose support is 2h, unstable).
 *
 * The iteration stops as soon as max_i |rho_i/rho0 - 1| < tol, or after max_iter steps.
 *
 * Reproducibility: every loop is a gather (particle i reads its neighbours and writes only its
 * own entries), neighbours come in the fixed order of consph_nnps, and the only reductions are
 * max/min, which are exact; so the result does not depend on the number of threads. Particles
 * are kept in cell order during the iteration for memory locality and returned in lattice order:
 * particle i of the result started at lattice node i. */
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
    for (int a = 0; a < lp->dim; ++a)
        if (!lp->box.periodic[a])
            return consph_fail(CONSPH_EINVAL,
                               "layout packed: axis %d is not periodic; the packing needs a "
                               "periodic box (001's PP arrangement is periodic)",
                               a);
    if (!(pp->hdx > 0.0 && pp->hdx <= 10.0))
        return consph_fail(CONSPH_EINVAL, "layout packed: hdx = %g is outside (0, 10]", pp->hdx);
    if (!(pp->perturb >= 0.0 && pp->perturb <= 0.5))
        return consph_fail(CONSPH_EINVAL, "layout packed: perturb = %g is outside [0, 0.5]",
                           pp->perturb);
    if (pp->max_iter < 0)
        return consph_fail(CONSPH_EINVAL, "layout packed: max_iter = %d is negative", pp->max_iter);
    if (!(pp->tol > 0.0) || !isfinite(pp->tol))
        return consph_fail(CONSPH_EINVAL, "layout packed: tol = %g must be positive", pp->tol);
    if (pp->history_every < 0)
        return consph_fail(CONSPH_EINVAL, "layout packed: history_every = %d is negative",
                           pp->history_every);
    int rc = consph_kernel_lookup(pp->kernel ? pp->kernel : "quintic", id);
    if (rc) return rc;
    if (consph_kernel_info_get(*id)->tensor)
        return consph_fail(CONSPH_EINVAL,
                           "layout packed: kernel '%s' is a tensor-product remeshing kernel; the "
                           "packing needs a radial kernel",
                           pp->kernel);
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

/* Damped symplectic Euler step, then wrap into the periodic box. */
static void advance(consph_particles *p, pack_work *w, double dt, double nu)
{
    const double damp = 1.0 - nu * dt;
    const int dim = w->dim;
    double lo[CONSPH_MAX_DIM], len[CONSPH_MAX_DIM];
    for (int a = 0; a < dim; ++a) {
        lo[a] = p->box.lo[a];
        len[a] = consph_box_length(&p->box, a);
    }
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < w->n; ++i)
        for (int a = 0; a < dim; ++a) {
            w->u[a][i] = damp * w->u[a][i] + dt * w->acc[a][i];
            p->x[a][i] = layout_wrap(p->x[a][i] + dt * w->u[a][i], lo[a], len[a]);
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

int consph_layout_pack(const consph_layout_params *lp, consph_particles *p,
                       consph_packing_report *report)
{
    const consph_packing_params *pp = &lp->packing;
    consph_kernel_id id;
    int rc = check_packing(lp, &id);
    if (rc) return rc;
    const double t0 = consph_wtime();
    const int dim = lp->dim;
    const double ds = p->spacing;
    consph_kernel target, glass;
    rc = consph_kernel_init(&target, id, dim, pp->hdx * ds);
    if (!rc) rc = consph_kernel_init(&glass, CONSPH_KERNEL_QUINTIC, dim, 1.2 * ds);
    if (rc) return rc;
    const int same_kernel = id == CONSPH_KERNEL_QUINTIC && pp->hdx == 1.2;
    force_params fp;
    fp.mass = packing_rho0 * pow(ds, dim);
    fp.polish = 0;
    fp.rep.k = (dim == 3 ? 0.006 : 0.004) * ds;
    fp.rep.c = (2.0 / 3.0) * 0.95 * ds;
    fp.rep.range = 1.5 * fp.rep.c;
    fp.rep.r_floor = 0.5 * glass.h;
    const double c0 = sqrt(packing_pb / packing_rho0);
    const double dt_glass = packing_dt_factor * glass.h / c0;
    const double dt_polish = packing_dt_factor * (target.radius / 3.0) / c0;
    const double nu = (dim == 3 ? 0.5 : 0.2) / ds;

    consph_layout_perturb(lp, p, ds, pp->perturb);

    int hist_cap = 0;
    if (report && pp->history_every > 0) {
        hist_cap = pp->max_iter / pp->history_every + 2;
        report->history_iter = consph_calloc((size_t)hist_cap, sizeof(int));
        report->history_spread = consph_calloc((size_t)hist_cap, sizeof(double));
        if (!report->history_iter || !report->history_spread) return CONSPH_ENOMEM;
    }

    pack_work w;
    rc = work_alloc(&w, p->n, dim, !same_kernel);
    if (rc) return rc;
    consph_nnps *grid = consph_nnps_create(&p->box, fmax(glass.radius, target.radius), 0);
    consph_sys glass_sys, target_sys;
    if (!grid) rc = CONSPH_ENOMEM;
    /* Both systems share the particles and the search, rebuilt in place every step. */
    if (!rc) rc = consph_sys_wrap(&glass_sys, p, grid, &glass);
    if (!rc) rc = consph_sys_wrap(&target_sys, p, grid, &target);
    fp.glass_sys = &glass_sys;
    fp.target_sys = &target_sys;

    int iter = 0, best_iter = 0;
    double best = INFINITY, spread = INFINITY;
    if (report) report->polish_start = -1;
    for (; rc == CONSPH_OK; ++iter) {
        if (iter % packing_sort_every == 0) {
            rc = consph_nnps_sort(grid, p, w.perm);
            if (rc) break;
            work_permute(&w);
        } else {
            rc = consph_nnps_build(grid, p);
            if (rc) break;
        }
        rc = compute_density(&fp, &w);
        if (rc) break;
        spread = consph_layout_spread(w.rho, w.n, packing_rho0);
        if (!isfinite(spread)) {
            rc = consph_fail(CONSPH_ENUMERIC, "layout packed: non-finite density at step %d", iter);
            break;
        }
        if (iter == 0 && report) report->rho_spread_initial = spread;
        int done = spread < pp->tol || iter >= pp->max_iter;
        if (report && pp->history_every > 0 && (iter % pp->history_every == 0 || done))
            record_history(report, hist_cap, iter, spread);
        if (done) break;
        if (!fp.polish) {
            /* Stage 1 acts on the stage-1 density, so its progress is judged on that. */
            double glass_spread =
                w.rho_glass ? consph_layout_spread(w.rho_glass, w.n, packing_rho0) : spread;
            if (glass_spread < packing_stall_gain * best) {
                best = glass_spread;
                best_iter = iter;
            }
            if (iter - best_iter >= packing_stall_steps || 2 * iter >= pp->max_iter) {
                fp.polish = 1;
                for (int a = 0; a < dim; ++a) memset(w.u[a], 0, w.n * sizeof(double));
                if (report) report->polish_start = iter;
            }
        }
        rc = compute_acceleration(&fp, &w);
        if (rc) break;
        advance(p, &w, fp.polish ? dt_polish : dt_glass, nu);
    }
    if (!rc) rc = restore_lattice_order(p, &w);
    if (!rc && report) {
        report->iterations = iter;
        report->rho_spread_final = spread;
        report->seconds = consph_wtime() - t0;
    }
    consph_nnps_free(grid);
    work_free(&w);
    return rc;
}
