/* Statistics of a particle set: summation-density spread, minimum pair distance,
 * nearest-neighbour distances and displacement from the lattice (the quantities of
 * docs/reference-values.md, "Packed files"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "layout/layout_internal.h"

static int check_particles(const consph_particles *p)
{
    if (!p || p->dim < 1 || p->dim > CONSPH_MAX_DIM || p->box.dim != p->dim)
        return consph_fail(CONSPH_EINVAL, "layout stats: particle set has no valid dimension");
    if (p->n == 0) return consph_fail(CONSPH_EINVAL, "layout stats: the particle set is empty");
    return consph_box_check(&p->box);
}

static double spacing_of(const consph_particles *p)
{
    if (p->spacing > 0.0) return p->spacing;
    return pow(consph_box_volume(&p->box) / (double)p->n, 1.0 / p->dim);
}

static double box_diagonal(const consph_box *b)
{
    double d2 = 0.0;
    for (int a = 0; a < b->dim; ++a) d2 += consph_box_length(b, a) * consph_box_length(b, a);
    return sqrt(d2);
}

/* Nearest-neighbour distance of every particle. Starts with `radius` and doubles it while some
 * particle has no neighbour, up to the box diagonal (beyond which a periodic box always holds an
 * image; in a closed box a lone particle keeps +inf). */
static int nearest_distances(const consph_particles *p, double radius, double *nn)
{
    int rc = CONSPH_OK;
    double diag = box_diagonal(&p->box);
    for (;;) {
        consph_kernel probe;
        rc = consph_layout_probe_kernel(p->dim, radius, &probe);
        if (rc) break;
        consph_nnps *grid = consph_nnps_create(&p->box, radius, 0);
        if (!grid) {
            rc = CONSPH_ENOMEM;
            break;
        }
        rc = consph_nnps_build(grid, p);
        consph_sys s;
        /* The passes only read the particles. */
        if (!rc) rc = consph_sys_wrap(&s, (consph_particles *)p, grid, &probe);
        if (!rc) rc = consph_layout_density(&s, 0.0, NULL, nn);
        consph_nnps_free(grid);
        if (rc) break;
        int missing = 0;
        for (size_t i = 0; i < p->n && !missing; ++i) missing = isinf(nn[i]);
        if (!missing || radius > diag) break;
        radius *= 2.0;
    }
    return rc;
}

int consph_layout_stats_compute(const consph_particles *p, const char *kernel, double hdx,
                                consph_layout_stats *st)
{
    memset(st, 0, sizeof *st);
    int rc = check_particles(p);
    if (rc) return rc;
    if (!(hdx > 0.0) || !isfinite(hdx))
        return consph_fail(CONSPH_EINVAL, "layout stats: h/Δs = %g must be positive", hdx);
    consph_kernel_id id;
    rc = consph_kernel_lookup(kernel ? kernel : "quintic", &id);
    if (rc) return rc;
    double ds = spacing_of(p);
    consph_kernel k;
    rc = consph_kernel_init(&k, id, p->dim, hdx * ds);
    if (rc) return rc;
    /* m = rho0 Δs^d with rho0 = 1 (001 gives neither; docs/deviations.md). */
    const double rho0 = 1.0;
    double mass = rho0 * pow(ds, p->dim);

    double *rho = consph_calloc(p->n, sizeof(double));
    double *nn = consph_calloc(p->n, sizeof(double));
    consph_nnps *grid = NULL;
    consph_sys sys;
    if (!rho || !nn) {
        rc = CONSPH_ENOMEM;
        goto done;
    }
    grid = consph_nnps_create(&p->box, consph_sys_reach(&k), 0);
    if (!grid) {
        rc = CONSPH_ENOMEM;
        goto done;
    }
    rc = consph_nnps_build(grid, p);
    if (rc) goto done;
    rc = consph_sys_wrap(&sys, (consph_particles *)p, grid, &k);
    if (rc) goto done;
    rc = consph_layout_density(&sys, mass, rho, nn);
    if (rc) goto done;
    st->n = p->n;
    st->rho_spread = consph_layout_spread(rho, p->n, rho0);
    st->rho_mean = consph_sum(rho, p->n) / (double)p->n;
    double dmin = INFINITY;
    for (size_t i = 0; i < p->n; ++i) dmin = fmin(dmin, nn[i]);
    if (isinf(dmin)) {
        /* No pair within the kernel support: search wider. */
        rc = nearest_distances(p, 2.0 * k.radius, nn);
        if (rc) goto done;
        for (size_t i = 0; i < p->n; ++i) dmin = fmin(dmin, nn[i]);
    }
    st->min_spacing = dmin;
done:
    consph_nnps_free(grid);
    free(rho);
    free(nn);
    return rc;
}

int consph_layout_nn_stats_compute(const consph_particles *p, consph_layout_nn_stats *st)
{
    memset(st, 0, sizeof *st);
    int rc = check_particles(p);
    if (rc) return rc;
    double ds = spacing_of(p);
    double *nn = consph_calloc(p->n, sizeof(double));
    double *tmp = consph_calloc(p->n, sizeof(double));
    if (!nn || !tmp) {
        free(nn);
        free(tmp);
        return CONSPH_ENOMEM;
    }
    /* 2Δs holds the nearest neighbour of all but very sparse sets; the search widens if not. */
    rc = nearest_distances(p, 2.0 * ds, nn);
    if (rc == CONSPH_OK) {
        size_t n = p->n;
        st->nn_min = INFINITY;
        for (size_t i = 0; i < n; ++i) {
            nn[i] /= ds;
            st->nn_min = fmin(st->nn_min, nn[i]);
            st->nn_max = fmax(st->nn_max, nn[i]);
        }
        st->nn_mean = consph_sum(nn, n) / (double)n;
        for (size_t i = 0; i < n; ++i) tmp[i] = (nn[i] - st->nn_mean) * (nn[i] - st->nn_mean);
        st->nn_std = sqrt(consph_sum(tmp, n) / (double)n);
        for (size_t i = 0; i < n; ++i) {
            double d2 = 0.0;
            for (int a = 0; a < p->dim; ++a) {
                double s = (p->x[a][i] - p->box.lo[a]) / ds;
                double off = s - (floor(s) + 0.5);
                d2 += off * off;
            }
            tmp[i] = sqrt(d2);
            st->disp_max = fmax(st->disp_max, tmp[i]);
        }
        st->disp_mean = consph_sum(tmp, n) / (double)n;
    }
    free(nn);
    free(tmp);
    return rc;
}
