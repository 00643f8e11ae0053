/* Exact 1D and sliced Wasserstein distances, and the conversions shared by every method. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "transport/transport_internal.h"

consph_ot_options consph_ot_defaults(void)
{
    consph_ot_options o;
    memset(&o, 0, sizeof o);
    o.method = CONSPH_OT_EXACT;
    o.p = 1;
    o.directions = 64;
    o.seed = 1;
    o.eps = 1e-3;
    o.tol = 1e-6;
    o.max_iter = 20000;
    return o;
}

consph_ot_method consph_ot_param_method(consph_ot_param param)
{
    return param == CONSPH_OT_PARAM_DIRECTIONS || param == CONSPH_OT_PARAM_SEED
               ? CONSPH_OT_SLICED
               : CONSPH_OT_SINKHORN;
}

int consph_ot_param_read(consph_ot_method method, int dim, consph_ot_param param)
{
    if (consph_ot_param_method(param) != method) return 0;
    return !(method == CONSPH_OT_SLICED && dim == 1);
}

/* What the machine can give now: MemAvailable, else the free physical pages; +inf if unknown. */
static double memory_available(void)
{
    FILE *f = fopen("/proc/meminfo", "r");
    char line[256];
    double kb = -1.0;
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "MemAvailable: %lf kB", &kb) == 1) break;
    if (f) fclose(f);
    if (kb >= 0.0) return kb * 1024.0;
    long pages = sysconf(_SC_AVPHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    return pages > 0 && size > 0 ? (double)pages * (double)size : INFINITY;
}

int consph_memory_limit(double *limit, double *cap, double *available)
{
    double c = 4.0 * 1024 * 1024 * 1024;
    const char *v = getenv("CONSPH_MEMORY_LIMIT");
    if (v && *v) {
        char *end;
        double x = strtod(v, &end);
        double unit = *end == 'K'   ? 1024.0
                      : *end == 'M' ? 1048576.0
                      : *end == 'G' ? 1073741824.0
                                    : 1.0;
        if (unit > 1.0) ++end;
        if (end == v || *end || !(x > 0.0) || !isfinite(x))
            return consph_fail(CONSPH_EINVAL,
                               "CONSPH_MEMORY_LIMIT='%s' is not a size; allowed: bytes with an "
                               "optional K, M or G, e.g. 2G",
                               v);
        c = x * unit;
    }
    const double a = memory_available();
    if (cap) *cap = c;
    if (available) *available = a;
    *limit = fmin(c, a);
    return CONSPH_OK;
}

const char *consph_mass_origin_name(consph_mass_origin origin)
{
    switch (origin) {
    case CONSPH_MASS_FIELD:
        return "mass column";
    case CONSPH_MASS_VOLUME_RHO:
        return "volume*rho";
    default:
        return "equal";
    }
}

int consph_measure_from_particles(const consph_particles *p, consph_measure *mu, double **scratch,
                                  consph_mass_origin *origin)
{
    memset(mu, 0, sizeof *mu);
    *scratch = NULL;
    mu->dim = p->dim;
    mu->n = p->n;
    for (int a = 0; a < p->dim; ++a) mu->x[a] = p->x[a];
    const consph_field *m = consph_particles_find(p, "mass");
    const consph_field *vol = consph_particles_find(p, "volume");
    const consph_field *rho = consph_particles_find(p, "rho");
    if (m && m->ncomp == 1) {
        mu->w = m->data;
        if (origin) *origin = CONSPH_MASS_FIELD;
    } else if (vol && rho && vol->ncomp == 1 && rho->ncomp == 1) {
        double *w = consph_calloc(p->n ? p->n : 1, sizeof *w);
        if (!w) return CONSPH_ENOMEM;
        for (size_t i = 0; i < p->n; ++i) w[i] = vol->data[i] * rho->data[i];
        *scratch = w;
        mu->w = w;
        if (origin) *origin = CONSPH_MASS_VOLUME_RHO;
    } else if (origin) {
        *origin = CONSPH_MASS_EQUAL;
    }
    return CONSPH_OK;
}

void ot_points_free(ot_points *pts)
{
    free(pts->x);
    free(pts->w);
    memset(pts, 0, sizeof *pts);
}

int ot_points_make(const consph_measure *mu, const char *which, ot_points *pts)
{
    memset(pts, 0, sizeof *pts);
    if (mu->dim < 1 || mu->dim > CONSPH_MAX_DIM)
        return consph_fail(CONSPH_EINVAL, "the %s measure has dimension %d (allowed 1..%d)", which,
                           mu->dim, CONSPH_MAX_DIM);
    if (mu->n == 0) return consph_fail(CONSPH_EINVAL, "the %s measure is empty", which);
    int dim = mu->dim;
    size_t n = mu->n, kept = 0;
    for (size_t i = 0; i < n; ++i) {
        double wi = mu->w ? mu->w[i] : 1.0;
        if (!(wi >= 0.0) || !isfinite(wi))
            return consph_fail(CONSPH_EINVAL,
                               "the %s measure: weight %zu is %g (allowed: finite and >= 0)", which,
                               i, wi);
        for (int a = 0; a < dim; ++a)
            if (!isfinite(mu->x[a][i]))
                return consph_fail(CONSPH_EINVAL, "the %s measure: position %zu is not finite",
                                   which, i);
        if (wi > 0.0) ++kept;
    }
    if (kept == 0) return consph_fail(CONSPH_EINVAL, "the %s measure has total weight 0", which);
    pts->x = consph_calloc(kept * (size_t)dim, sizeof *pts->x);
    pts->w = consph_calloc(kept, sizeof *pts->w);
    if (!pts->x || !pts->w) {
        ot_points_free(pts);
        return CONSPH_ENOMEM;
    }
    pts->dim = dim;
    pts->n = kept;
    size_t k = 0;
    for (size_t i = 0; i < n; ++i) {
        double wi = mu->w ? mu->w[i] : 1.0;
        if (wi == 0.0) continue;
        for (int a = 0; a < dim; ++a) pts->x[k * (size_t)dim + (size_t)a] = mu->x[a][i];
        pts->w[k++] = wi;
    }
    double total = consph_sum(pts->w, kept);
    if (!(total > 0.0) || !isfinite(total)) {
        ot_points_free(pts);
        return consph_fail(CONSPH_EINVAL, "the %s measure: total weight %g is not usable", which,
                           total);
    }
    for (size_t i = 0; i < kept; ++i) pts->w[i] /= total;
    return CONSPH_OK;
}

/* The quantile functions of both measures are step functions of t in [0, 1]; walking their
 * breakpoints in order integrates |F^-1(t) - G^-1(t)|^p exactly. Neumaier summation keeps the
 * many small terms from losing digits; the walk is sequential, so the sum is deterministic. */
double ot_w1d_sorted_pow(const double *xa, const double *wa, size_t na, const double *xb,
                         const double *wb, size_t nb, int p)
{
    size_t i = 0, j = 0;
    double ra = wa[0], rb = wb[0];
    double sum = 0.0, comp = 0.0;
    while (i < na && j < nb) {
        double d = ra < rb ? ra : rb;
        double dx = fabs(xa[i] - xb[j]);
        double term = d * (p == 2 ? dx * dx : dx);
        double t = sum + term;
        comp += fabs(sum) >= fabs(term) ? (sum - t) + term : (term - t) + sum;
        sum = t;
        if (ra < rb) {
            rb -= ra;
            if (++i < na) ra = wa[i];
        } else if (rb < ra) {
            ra -= rb;
            if (++j < nb) rb = wb[j];
        } else {
            if (++i < na) ra = wa[i];
            if (++j < nb) rb = wb[j];
        }
    }
    return sum + comp;
}

typedef struct xw {
    double x, w;
} xw;

static int xw_cmp(const void *pa, const void *pb)
{
    const xw *a = pa, *b = pb;
    if (a->x < b->x) return -1;
    if (a->x > b->x) return 1;
    /* Points at one position are interchangeable for the quantile function; ordering them by
     * weight only makes the walk independent of qsort's tie handling. */
    return (a->w > b->w) - (a->w < b->w);
}

/* Sorts (x, w) pairs and splits them back into xs and ws. */
static int sort_split(xw *buf, size_t n, double *xs, double *ws)
{
    qsort(buf, n, sizeof *buf, xw_cmp);
    for (size_t i = 0; i < n; ++i) {
        xs[i] = buf[i].x;
        ws[i] = buf[i].w;
    }
    return CONSPH_OK;
}

/* W_p^p between the projections of a and b on direction theta. */
static int projected_pow(const ot_points *a, const ot_points *b, const double *theta, int p,
                         double *out)
{
    size_t nmax = a->n > b->n ? a->n : b->n;
    xw *buf = consph_calloc(nmax, sizeof *buf);
    double *v = consph_calloc(2 * (a->n + b->n), sizeof *v);
    if (!buf || !v) {
        free(buf);
        free(v);
        return CONSPH_ENOMEM;
    }
    double *xa = v, *wa = v + a->n, *xb = v + 2 * a->n, *wb = xb + b->n;
    const ot_points *m[2] = {a, b};
    double *xs[2] = {xa, xb}, *ws[2] = {wa, wb};
    for (int s = 0; s < 2; ++s) {
        int dim = m[s]->dim;
        for (size_t i = 0; i < m[s]->n; ++i) {
            double t = 0.0;
            for (int c = 0; c < dim; ++c) t += theta[c] * m[s]->x[i * (size_t)dim + (size_t)c];
            buf[i].x = t;
            buf[i].w = m[s]->w[i];
        }
        sort_split(buf, m[s]->n, xs[s], ws[s]);
    }
    *out = ot_w1d_sorted_pow(xa, wa, a->n, xb, wb, b->n, p);
    free(buf);
    free(v);
    return CONSPH_OK;
}

int consph_wasserstein_1d_pow(const double *xa, const double *wa, size_t na, const double *xb,
                              const double *wb, size_t nb, int p, double *wpp)
{
    if (p != 1 && p != 2) return consph_fail(CONSPH_EINVAL, "p = %d (allowed: 1, 2)", p);
    consph_measure ma = {1, na, {xa, NULL, NULL}, wa}, mb = {1, nb, {xb, NULL, NULL}, wb};
    ot_points a, b;
    int rc = ot_points_make(&ma, "first", &a);
    if (rc) return rc;
    rc = ot_points_make(&mb, "second", &b);
    if (rc) {
        ot_points_free(&a);
        return rc;
    }
    double one = 1.0;
    rc = projected_pow(&a, &b, &one, p, wpp);
    ot_points_free(&a);
    ot_points_free(&b);
    return rc;
}

/* A direction uniform on the unit sphere S^(dim-1), from two uniforms: in 3D z = cos(polar angle)
 * is uniform on [-1, 1] (Archimedes), in 2D the angle is uniform. */
static void random_direction(consph_rng *r, int dim, double *theta)
{
    double u = consph_rng_uniform(r), v = consph_rng_uniform(r);
    if (dim == 1) {
        theta[0] = 1.0;
    } else if (dim == 2) {
        theta[0] = cos(2.0 * M_PI * u);
        theta[1] = sin(2.0 * M_PI * u);
    } else {
        double z = 2.0 * u - 1.0, s = sqrt(fmax(0.0, 1.0 - z * z));
        theta[0] = s * cos(2.0 * M_PI * v);
        theta[1] = s * sin(2.0 * M_PI * v);
        theta[2] = z;
    }
}

static int sliced(const ot_points *a, const ot_points *b, const consph_ot_options *opt,
                  consph_ot_result *res)
{
    int dim = a->dim, k = opt->directions;
    double *theta = consph_calloc((size_t)k * CONSPH_MAX_DIM, sizeof *theta);
    double *val = consph_calloc((size_t)k, sizeof *val);
    if (!theta || !val) {
        free(theta);
        free(val);
        return CONSPH_ENOMEM;
    }
    /* Directions are drawn in order before the parallel loop, so each is the same whatever the
     * number of threads. */
    consph_rng rng;
    consph_rng_seed(&rng, opt->seed);
    for (int d = 0; d < k; ++d) random_direction(&rng, dim, theta + (size_t)d * CONSPH_MAX_DIM);
    int failed = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(| : failed)
    for (int d = 0; d < k; ++d)
        failed |= projected_pow(a, b, theta + (size_t)d * CONSPH_MAX_DIM, opt->p, &val[d]) != 0;
    if (failed) {
        free(theta);
        free(val);
        return consph_fail(CONSPH_ENOMEM, "out of memory in the sliced distance");
    }
    double mean = consph_sum(val, (size_t)k) / k;
    /* The directions are spent; their storage takes the squared deviations. */
    for (int d = 0; d < k; ++d) theta[d] = (val[d] - mean) * (val[d] - mean);
    double var = k > 1 ? consph_sum(theta, (size_t)k) / (k - 1) : 0.0;
    double se_pow = sqrt(var / k);
    res->distance = opt->p == 2 ? sqrt(mean) : mean;
    /* Delta method through the p-th root; at SW = 0 the root's slope is infinite and the square
     * root of the error of SW_p^p is the honest bound. */
    if (opt->p == 2)
        res->error = res->distance > 0.0 ? se_pow / (2.0 * res->distance) : sqrt(se_pow);
    else
        res->error = se_pow;
    free(theta);
    free(val);
    return CONSPH_OK;
}

int consph_wasserstein(const consph_measure *ma, const consph_measure *mb,
                       const consph_ot_options *opt, consph_ot_result *res)
{
    memset(res, 0, sizeof *res);
    if (opt->p != 1 && opt->p != 2)
        return consph_fail(CONSPH_EINVAL, "p = %d (allowed: 1, 2)", opt->p);
    if (ma->dim != mb->dim)
        return consph_fail(CONSPH_EINVAL, "the measures are %dD and %dD (they must agree)", ma->dim,
                           mb->dim);
    if (opt->method == CONSPH_OT_EXACT && ma->dim != 1)
        return consph_fail(CONSPH_EINVAL,
                           "exact transport is implemented in 1D only (these are %dD); use the "
                           "sliced or sinkhorn method",
                           ma->dim);
    if (opt->method == CONSPH_OT_SLICED && opt->directions < 2)
        return consph_fail(CONSPH_EINVAL, "directions = %d (allowed: 2 or more)", opt->directions);
    if (opt->method == CONSPH_OT_SINKHORN) {
        if (!(opt->eps > 0.0 && opt->eps <= 1.0))
            return consph_fail(CONSPH_EINVAL,
                               "eps = %g (allowed: 0 < eps <= 1, relative to the "
                               "largest cost)",
                               opt->eps);
        if (!(opt->tol > 0.0 && opt->tol < 1.0))
            return consph_fail(CONSPH_EINVAL, "tol = %g (allowed: 0 < tol < 1)", opt->tol);
        if (opt->max_iter < 1)
            return consph_fail(CONSPH_EINVAL, "max_iter = %ld (allowed: >= 1)", opt->max_iter);
    }
    if (opt->method != CONSPH_OT_EXACT && opt->method != CONSPH_OT_SLICED &&
        opt->method != CONSPH_OT_SINKHORN)
        return consph_fail(CONSPH_EINVAL, "unknown method %d (allowed: exact, sliced, sinkhorn)",
                           (int)opt->method);
    ot_points a, b;
    int rc = ot_points_make(ma, "first", &a);
    if (rc) return rc;
    rc = ot_points_make(mb, "second", &b);
    if (rc) {
        ot_points_free(&a);
        return rc;
    }
    res->converged = 1;
    /* In 1D every direction is ±1 and the sliced distance is the exact one, with no sampling
     * error. */
    if (opt->method == CONSPH_OT_EXACT || (opt->method == CONSPH_OT_SLICED && a.dim == 1)) {
        double one = 1.0, pow_p = 0.0;
        rc = projected_pow(&a, &b, &one, opt->p, &pow_p);
        res->distance = opt->p == 2 ? sqrt(pow_p) : pow_p;
    } else if (opt->method == CONSPH_OT_SLICED) {
        rc = sliced(&a, &b, opt, res);
    } else {
        rc = ot_sinkhorn(&a, &b, opt, res);
    }
    ot_points_free(&a);
    ot_points_free(&b);
    return rc;
}

/* Bytes of one projected_pow: projections and weights of both sets, and the sort buffer. */
static double projection_bytes(double na, double nb)
{
    return 8.0 * 2.0 * (na + nb) + 16.0 * fmax(na, nb);
}

consph_ot_estimate consph_wasserstein_estimate(const consph_ot_options *opt, int dim, double na,
                                               double nb, int threads)
{
    consph_ot_estimate e = {0.0, 0.0};
    const double n = na + nb, nmax = fmax(na, nb);
    const double t = threads > 0 ? threads : 1;
    /* Every method first copies both measures (ot_points). */
    e.bytes = 8.0 * (dim + 1) * n;
    const double sort = n * (log2(nmax > 2 ? nmax : 2) + 1.0) * OT_RATE_SORT;
    if (opt->method == CONSPH_OT_EXACT || (opt->method == CONSPH_OT_SLICED && dim == 1)) {
        e.bytes += projection_bytes(na, nb);
        e.seconds = sort;
    } else if (opt->method == CONSPH_OT_SLICED) {
        const int k = opt->directions > 0 ? opt->directions : 1;
        /* Each thread projects and sorts one direction at a time. */
        e.bytes += 8.0 * (CONSPH_MAX_DIM + 1) * k + (t < k ? t : k) * projection_bytes(na, nb);
        e.seconds = k * sort / (t < k ? t : k);
    } else {
        e.bytes += 8.0 * (4.0 * na + 3.0 * nb + nmax);
        /* Two half steps over every pair. */
        e.seconds = 2.0 * na * nb * OT_RATE_SINKHORN_PAIR / t;
    }
    return e;
}
