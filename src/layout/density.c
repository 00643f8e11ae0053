/* Summation density and nearest-neighbour distances over a neighbour search, shared by the
 * packing iteration and the layout statistics. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "layout/layout_internal.h"

int consph_layout_pool_init(layout_nbr_pool *pool)
{
    pool->count = consph_num_threads();
    if (pool->count < 1) pool->count = 1;
    pool->nbrs = consph_calloc((size_t)pool->count, sizeof(consph_nbrs));
    if (!pool->nbrs) {
        pool->count = 0;
        return CONSPH_ENOMEM;
    }
    return CONSPH_OK;
}

void consph_layout_pool_free(layout_nbr_pool *pool)
{
    for (int t = 0; t < pool->count; ++t) consph_nbrs_free(&pool->nbrs[t]);
    free(pool->nbrs);
    memset(pool, 0, sizeof *pool);
}

int consph_layout_density(const consph_nnps *grid, const consph_kernel *kernel, size_t n,
                          double mass, layout_nbr_pool *pool, double *rho, double *nn_dist)
{
    int failed = 0;
#pragma omp parallel num_threads(pool->count)
    {
        consph_nbrs *nb = &pool->nbrs[layout_thread_id()];
#pragma omp for schedule(static)
        for (size_t i = 0; i < n; ++i) {
            size_t count = consph_nnps_query_particle(grid, i, nb);
            if (count == (size_t)-1) {
#pragma omp atomic write
                failed = 1;
                continue;
            }
            double w = 0.0, nearest = INFINITY;
            for (size_t q = 0; q < count; ++q) {
                double r = nb->r[q];
                if (rho && kernel->tensor) {
                    double dx[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
                    for (int a = 0; a < kernel->dim; ++a) dx[a] = nb->dx[a][q];
                    w += consph_kernel_w_vec(kernel, dx);
                } else if (rho) {
                    w += consph_kernel_w(kernel, r);
                }
                if (nn_dist && r < nearest && (r > 0.0 || nb->j[q] != i)) nearest = r;
            }
            if (rho) rho[i] = mass * w;
            if (nn_dist) nn_dist[i] = nearest;
        }
    }
    if (failed) return consph_fail(CONSPH_ENOMEM, "layout: neighbour query ran out of memory");
    return CONSPH_OK;
}

double consph_layout_spread(const double *rho, size_t n, double rho0)
{
    double spread = 0.0;
    for (size_t i = 0; i < n; ++i) {
        double e = fabs(rho[i] / rho0 - 1.0);
        if (isnan(e)) return e; /* a NaN density must not hide behind the finite ones */
        if (e > spread) spread = e;
    }
    return spread;
}
