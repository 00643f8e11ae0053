/* The packed (PP) arrangement of 001 B1.0: a perturbed lattice relaxed by the particle packing
 * of Negi & Ramachandran (2021, CPC 265:108008), the paper 001 cites as [51].
 *
 * Each particle feels the "background pressure" force of that paper and a viscous damping,
 *
 *     du_i/dt = -(p_b/m) sum_j V_i V_j ∇_i W_ij - ν u_i,   dx_i/dt = u_i,
 *
 * with V_i = m/rho_i from the summation density rho_i = m sum_j W_ij. The force is repulsive and
 * vanishes when every particle sees a balanced neighbourhood, so the damped motion settles into a
 * state of nearly uniform summation density. The paper's geometry machinery (boundary nodes,
 * frozen layers, the short-range repulsion against boundary nodes) does nothing in a periodic box
 * without boundaries and is left out.
 *
 * Parameters, taken from the authors' implementation (PySPH tools/particle_packing.py,
 * ParticlePacking defaults) where it has them: p_b = 1 with rho0 = 1 (so c = sqrt(p_b/rho0) = 1);
 * ν = 0.2/Δs in 1D and 2D and 0.5/Δs in 3D; time step Δt = 0.1 h / c. Integration is explicit
 * Euler as in that implementation (EulerIntegrator), except that the position is advanced with
 * the updated velocity (symplectic Euler), which keeps the oscillatory modes stable.
 * The initial state is the cell-centred lattice with every coordinate moved by
 * perturb·Δs·(2U - 1), U uniform in [0, 1) (the seed picks U). The iteration stops as soon as
 * max_i |rho_i/rho0 - 1| < tol, or after max_iter steps.
 *
 * Reproducibility: every loop is a gather (particle i reads its neighbours and writes only its
 * own entries), neighbours come in the fixed order of consph_nnps, and the only reductions are
 * max/min, which are exact; so the result does not depend on the number of threads. Particles
 * are kept in cell order during the iteration for memory locality and returned in lattice order:
 * particle i of the result started at lattice node i. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <stdio.h>

#include "layout/layout_internal.h"

static const double packing_rho0 = 1.0;
static const double packing_pb = 1.0;
static const double packing_dt_factor = 0.1; /* Δt = factor · h / c */
/* Re-sort the particles into cell order every this many steps: often enough that neighbours
 * stay close in memory, rarely enough that the permutations cost nothing. */
static const int packing_sort_every = 25;

typedef struct pack_work {
    size_t n;
    int dim;
    double *u[CONSPH_MAX_DIM]; /* velocity */
    double *acc[CONSPH_MAX_DIM];
    double *rho;
    size_t *origin; /* lattice index of the particle now stored at i */
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
    free(w->origin);
    free(w->origin_tmp);
    free(w->perm);
    free(w->scratch);
    memset(w, 0, sizeof *w);
}

static int work_alloc(pack_work *w, size_t n, int dim)
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
    return consph_kernel_lookup(pp->kernel ? pp->kernel : "quintic", id);
}

/* The short-range repulsion of the authors' implementation (RepulsionForce): for r < range,
 * a_i += 12 k (3c^2/r^5 - 2c/r^4) x_ij where positive, r floored at h/2. */
typedef struct repulsion {
    double k, c, range, r_floor;
} repulsion;

/* Acceleration a_i = -(p_b/m) sum_j V_i V_j ∇_i W_ij; ∇_i W_ij = W'(r) x_ij / r. */
static int compute_acceleration(const consph_nnps *grid, const consph_kernel *k, double mass,
                                const repulsion *rp, pack_work *w, layout_nbr_pool *pool, int polish, double rho_mean)
{
    double polish_gain = getenv("PG") ? atof(getenv("PG")) : 1.0;
    int polish_rep = getenv("PREP") ? atoi(getenv("PREP")) : 1;
    int failed = 0;
    const int dim = w->dim;
#pragma omp parallel num_threads(pool->count)
    {
        consph_nbrs *nb = &pool->nbrs[layout_thread_id()];
#pragma omp for schedule(static)
        for (size_t i = 0; i < w->n; ++i) {
            size_t count = consph_nnps_query_particle(grid, i, nb);
            if (count == (size_t)-1) {
#pragma omp atomic write
                failed = 1;
                continue;
            }
            double sum[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
            double rep[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
            for (size_t q = 0; q < count; ++q) {
                double r = nb->r[q];
                if (!(r > 0.0)) continue;
                double vj = mass / w->rho[nb->j[q]];
                double f = vj * consph_kernel_dw(k, r) / r;
                for (int a = 0; a < dim; ++a) sum[a] += f * nb->dx[a][q];
                if (r < rp->range) {
                    double rc = fmax(r, rp->r_floor);
                    double g = 12.0 * rp->k *
                               (3.0 * rp->c * rp->c / pow(rc, 5) - 2.0 * rp->c / pow(rc, 4)) *
                               (rc / r);
                    if (g > 0.0)
                        for (int a = 0; a < dim; ++a) rep[a] += g * nb->dx[a][q];
                }
            }
            double coef = -packing_pb * (mass / w->rho[i]) / mass;
            for (int a = 0; a < dim; ++a) w->acc[a][i] = coef * sum[a] + rep[a];
            if (polish) {
                double ei = w->rho[i] / rho_mean - 1.0;
                double g[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
                for (size_t q = 0; q < count; ++q) {
                    double r = nb->r[q];
                    if (!(r > 0.0)) continue;
                    double ej = w->rho[nb->j[q]] / rho_mean - 1.0;
                    double f = (ei + ej) * consph_kernel_dw(k, r) / r;
                    for (int a = 0; a < dim; ++a) g[a] += f * nb->dx[a][q];
                }
                for (int a = 0; a < dim; ++a) w->acc[a][i] = -polish_gain * mass * g[a] + (polish_rep ? rep[a] : 0.0);
            }
        }
    }
    if (failed) return consph_fail(CONSPH_ENOMEM, "layout packed: neighbour query out of memory");
    return CONSPH_OK;
}

/* Damped symplectic Euler step, then wrap into the periodic box. */
static void advance(consph_particles *p, pack_work *w, double dt, double nu)
{
    const double damp = 1.0 - nu * dt;
    for (int a = 0; a < w->dim; ++a) {
        double lo = p->box.lo[a], len = consph_box_length(&p->box, a);
        double *x = p->x[a], *u = w->u[a];
        const double *acc = w->acc[a];
#pragma omp parallel for schedule(static)
        for (size_t i = 0; i < w->n; ++i) {
            u[i] = damp * u[i] + dt * acc[i];
            x[i] = layout_wrap(x[i] + dt * u[i], lo, len);
        }
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
    consph_kernel k;
    rc = consph_kernel_init(&k, id, dim, pp->hdx * ds);
    if (rc) return rc;
    const double mass = packing_rho0 * pow(ds, dim);
    const double c = sqrt(packing_pb / packing_rho0);
    const double dt = packing_dt_factor * k.h / c;
    const double nu = (dim == 3 ? 0.5 : 0.2) / ds;
    repulsion rep;
    rep.k = (dim == 3 ? 0.006 : 0.004) * ds;
    rep.c = (2.0 / 3.0) * 0.95 * ds;
    rep.range = 1.5 * rep.c;
    rep.r_floor = 0.5 * k.h;

    consph_layout_perturb(lp, p, ds, pp->perturb);

    int hist_cap = 0;
    if (report && pp->history_every > 0) {
        hist_cap = pp->max_iter / pp->history_every + 2;
        report->history_iter = consph_calloc((size_t)hist_cap, sizeof(int));
        report->history_spread = consph_calloc((size_t)hist_cap, sizeof(double));
        if (!report->history_iter || !report->history_spread) return CONSPH_ENOMEM;
    }

    pack_work w;
    rc = work_alloc(&w, p->n, dim);
    if (rc) return rc;
    layout_nbr_pool pool = {0, NULL};
    consph_nnps *grid = consph_nnps_create(&p->box, k.radius, 0);
    if (!grid) rc = CONSPH_ENOMEM;
    if (!rc) rc = consph_layout_pool_init(&pool);

    int iter = 0, polish = 0, best_iter = 0, stall = getenv("STALL") ? atoi(getenv("STALL")) : 200;
    double best = INFINITY;
    double spread = INFINITY;
    for (; rc == CONSPH_OK; ++iter) {
        if (iter % packing_sort_every == 0) {
            rc = consph_nnps_sort(grid, p, w.perm);
            if (rc) break;
            work_permute(&w);
        } else {
            rc = consph_nnps_build(grid, p);
            if (rc) break;
        }
        rc = consph_layout_density(grid, &k, w.n, mass, &pool, w.rho, NULL);
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
        if (!polish && spread < best * (1.0 - (getenv("IMP") ? atof(getenv("IMP")) : 0.01))) { best = spread; best_iter = iter; }
        if (!polish && iter - best_iter > stall) { polish = 1; fprintf(stderr, "polish at %d\n", iter); }
        rc = compute_acceleration(grid, &k, mass, &rep, &w, &pool, polish, getenv("RBAR") ? consph_sum(w.rho, w.n) / (double)w.n : 1.0);
        if (rc) break;
        advance(p, &w, dt, nu);
    }
    if (!rc) rc = restore_lattice_order(p, &w);
    if (!rc && report) {
        report->iterations = iter;
        report->rho_spread_final = spread;
        report->seconds = consph_wtime() - t0;
    }
    consph_nnps_free(grid);
    consph_layout_pool_free(&pool);
    work_free(&w);
    return rc;
}
