/* Continuous densities as measures on the cell centres of a fine grid: the exact density of a
 * test, or the SPH kernel-smoothed density Σ_b m_b W(x − x_b, h) of 004, so that W between the
 * smoothed and the exact measure separates the kernel limit (h) from the particle limit (N). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "transport/transport_internal.h"

void consph_grid_measure_free(consph_grid_measure *g)
{
    free(g->storage);
    memset(g, 0, sizeof *g);
}

/* Allocates the grid and fills the cell centres; weights are left for the caller. */
static int grid_alloc(const consph_box *box, size_t cells, consph_grid_measure *g)
{
    memset(g, 0, sizeof *g);
    if (consph_box_check(box) != CONSPH_OK) return CONSPH_EINVAL;
    int dim = box->dim;
    if (cells < 1 || cells > (dim == 1 ? 100000000u : dim == 2 ? 10000u : 500u))
        return consph_fail(CONSPH_EINVAL, "cells = %zu per axis (allowed: 1..%u in %dD)", cells,
                           dim == 1   ? 100000000u
                           : dim == 2 ? 10000u
                                      : 500u,
                           dim);
    size_t n = 1;
    for (int a = 0; a < dim; ++a) n *= cells;
    g->storage = consph_calloc(n * (size_t)(dim + 1), sizeof *g->storage);
    if (!g->storage) return CONSPH_ENOMEM;
    g->mu.dim = dim;
    g->mu.n = n;
    double diag2 = 0.0, dx[CONSPH_MAX_DIM];
    for (int a = 0; a < dim; ++a) {
        dx[a] = consph_box_length(box, a) / (double)cells;
        diag2 += dx[a] * dx[a];
        g->mu.x[a] = g->storage + (size_t)a * n;
    }
    g->mu.w = g->storage + (size_t)dim * n;
    g->half_diagonal = 0.5 * sqrt(diag2);
    for (size_t i = 0; i < n; ++i) {
        size_t rest = i;
        for (int a = 0; a < dim; ++a) {
            ((double *)g->mu.x[a])[i] = box->lo[a] + ((double)(rest % cells) + 0.5) * dx[a];
            rest /= cells;
        }
    }
    return CONSPH_OK;
}

int consph_grid_measure_density(const consph_box *box, size_t cells, consph_density_fn density,
                                void *ctx, consph_grid_measure *g)
{
    int rc = grid_alloc(box, cells, g);
    if (rc) return rc;
    double *w = (double *)g->mu.w, x[CONSPH_MAX_DIM];
    for (size_t i = 0; i < g->mu.n; ++i) {
        for (int a = 0; a < box->dim; ++a) x[a] = g->mu.x[a][i];
        w[i] = density ? density(x, ctx) : 1.0;
        if (!(w[i] >= 0.0) || !isfinite(w[i])) {
            double bad = w[i];
            consph_grid_measure_free(g);
            return consph_fail(CONSPH_EINVAL,
                               "the density is %g at a grid point (allowed: finite "
                               "and >= 0)",
                               bad);
        }
    }
    return CONSPH_OK;
}

consph_ot_estimate consph_grid_measure_estimate(int dim, size_t cells, size_t particles,
                                                int threads)
{
    double n = pow((double)cells, dim);
    consph_ot_estimate e = {8.0 * (dim + 1) * n + 8.0 * (dim + 1) * (double)particles,
                            n * (double)(particles ? particles : 1) * OT_RATE_GRID_PAIR /
                                (threads > 0 ? threads : 1)};
    return e;
}

int consph_grid_measure_sph(const consph_box *box, size_t cells, const consph_measure *mu,
                            const consph_kernel *k, consph_grid_measure *g)
{
    return consph_grid_measure_sph_progress(box, cells, mu, k, g, NULL, NULL);
}

/* Cell-particle pairs per progress report (a tenth of a second): a block of cells is one parallel
 * loop, so reports come from the calling thread between blocks and each cell's sum is the same
 * as in one loop. */
#define GRID_PROGRESS_PAIRS 2e6

int consph_grid_measure_sph_progress(const consph_box *box, size_t cells, const consph_measure *mu,
                                     const consph_kernel *k, consph_grid_measure *g,
                                     void (*progress)(void *ctx, double done, double total),
                                     void *ctx)
{
    if (k->dim != mu->dim || box->dim != mu->dim)
        return consph_fail(CONSPH_EINVAL, "kernel %dD, box %dD, particles %dD (they must agree)",
                           k->dim, box->dim, mu->dim);
    ot_points pts;
    int rc = ot_points_make(mu, "particle", &pts);
    if (rc) return rc;
    rc = grid_alloc(box, cells, g);
    if (rc) {
        ot_points_free(&pts);
        return rc;
    }
    int dim = mu->dim;
    double len[CONSPH_MAX_DIM];
    for (int a = 0; a < dim; ++a) len[a] = consph_box_length(box, a);
    double *w = (double *)g->mu.w;
    long n = (long)g->mu.n;
    /* A gather into each grid point, particles in their fixed order: thread-independent. A
     * brute-force loop over particles (O(grid · N)) keeps this independent of the neighbour
     * search's cell sizes; the distance test skips the kernel outside its support. */
    long block = n > 0 ? n : 1;
    if (progress && pts.n > 0) block = (long)fmax(64.0, GRID_PROGRESS_PAIRS / (double)pts.n);
    for (long i0 = 0; i0 < n; i0 += block) {
        const long i1 = n - i0 > block ? i0 + block : n;
#pragma omp parallel for schedule(static)
        for (long i = i0; i < i1; ++i) {
            double s = 0.0, dx[CONSPH_MAX_DIM];
            for (size_t b = 0; b < pts.n; ++b) {
                double r2 = 0.0;
                for (int a = 0; a < dim; ++a) {
                    double d = g->mu.x[a][i] - pts.x[b * (size_t)dim + (size_t)a];
                    if (box->periodic[a]) d -= len[a] * nearbyint(d / len[a]);
                    dx[a] = d;
                    r2 += d * d;
                }
                if (r2 < k->radius * k->radius) s += pts.w[b] * consph_kernel_w_vec(k, dx);
            }
            w[i] = s;
        }
        if (progress) progress(ctx, (double)i1, (double)n);
    }
    ot_points_free(&pts);
    return CONSPH_OK;
}
