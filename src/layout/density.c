/* Summation density and nearest-neighbour distances as one pass, shared by the packing
 * iteration and the layout statistics. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "layout/layout_internal.h"

typedef struct density_job {
    double mass;
    double *rho, *nn_dist;
} density_job;

static void density_visit(void *job, const consph_nbhd *nb)
{
    const density_job *d = job;
    if (d->rho) {
        double w = 0.0;
        for (size_t q = 0; q < nb->n; ++q) w += nb->w[q];
        d->rho[nb->i] = d->mass * w;
    }
    if (d->nn_dist) {
        /* i's own entry is the one at r = 0 with j = i; a coincident other particle is not. */
        double nearest = INFINITY;
        for (size_t q = 0; q < nb->n; ++q) {
            double r = nb->r[q];
            if (r < nearest && (r > 0.0 || nb->j[q] != nb->i)) nearest = r;
        }
        d->nn_dist[nb->i] = nearest;
    }
}

int consph_layout_density(const consph_sys *s, double mass, double *rho, double *nn_dist)
{
    density_job job = {mass, rho, nn_dist};
    const consph_pass pass = {"layout density", (rho ? CONSPH_PASS_W : 0u) | CONSPH_PASS_NO_DX,
                              density_visit};
    return consph_pass_run(s, &pass, &job);
}

int consph_layout_probe_kernel(int dim, double radius, consph_kernel *k)
{
    return consph_kernel_init(k, CONSPH_KERNEL_QUINTIC, dim,
                              radius / consph_kernel_info_get(CONSPH_KERNEL_QUINTIC)->support);
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
