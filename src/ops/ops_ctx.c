/* The operator context (particles, search, kernel, volumes) and the cache of correction
 * matrices; the particle pass is in ops_pass.c. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"

/* ---- the pass over the context's particles ---- */

int ops_run(const consph_op_ctx *ctx, unsigned need, ops_visit_fn visit, void *job, size_t *pairs)
{
    /* A view, not a copy: the context's particles and search are the system's. */
    consph_sys sys;
    memset(&sys, 0, sizeof sys);
    sys.p = (consph_particles *)ctx->p;
    sys.nnps = (consph_nnps *)ctx->nnps;
    sys.kernel = ctx->kernel;
    sys.parallel_min = ctx->parallel_min;
    const consph_pass pass = {"operator", need, visit};
    return consph_pass_run_counted(&sys, &pass, job, pairs);
}

/* ---- volumes ---- */

typedef struct density_job {
    const consph_op_ctx *ctx;
    double *sum;
    const double *mass; /* NULL: sum W */
} density_job;

static void visit_density(void *vjob, const ops_nbhd *nb)
{
    density_job *job = vjob;
    term_wsum(nb, job->mass, NULL, NULL, NULL, &job->sum[nb->i]);
}

static int compute_volumes(consph_op_ctx *ctx)
{
    const size_t n = ctx->n;
    const consph_particles *p = ctx->p;
    /* On a system the context created "mass" itself when it was absent. */
    const consph_field *fmass =
        ctx->cache->fields_of && !ctx->cache->mass_given ? NULL : consph_particles_find(p, "mass");
    if (fmass && fmass->ncomp != 1)
        return consph_fail(CONSPH_EINVAL, "field 'mass' has %d components, not 1", fmass->ncomp);
    if (ctx->volume_kind == CONSPH_VOLUME_GIVEN) {
        const consph_field *fv = consph_particles_find(p, "volume");
        if (!fv || fv->ncomp != 1)
            return consph_fail(CONSPH_EINVAL,
                               "volume 'given' needs a scalar particle field 'volume'");
        for (size_t i = 0; i < n; ++i) {
            double v = fv->data[i];
            if (!(v > 0.0) || !isfinite(v))
                return consph_fail(CONSPH_EINVAL, "field 'volume' of particle %zu is %g", i, v);
            ctx->volume[i] = v;
            /* Without masses the density is ρ0 = 1 everywhere. */
            ctx->mass[i] = fmass ? fmass->data[i] : v;
            ctx->rho[i] = ctx->mass[i] / v;
        }
        return CONSPH_OK;
    }
    double m0 = n ? consph_box_volume(&p->box) / (double)n : 0.0;
    for (size_t i = 0; i < n; ++i) ctx->mass[i] = fmass ? fmass->data[i] : m0;
    density_job job = {ctx, ctx->rho, NULL};
    if (ctx->volume_kind == CONSPH_VOLUME_SUMMATION) job.mass = ctx->mass;
    int st = ops_run(ctx, OPS_NEED_W | OPS_SKIP_DX, visit_density, &job, NULL);
    if (st != CONSPH_OK) return st;
    for (size_t i = 0; i < n; ++i) {
        if (ctx->volume_kind == CONSPH_VOLUME_SUMMATION) {
            /* rho holds Σ m W */
            ctx->volume[i] = ctx->mass[i] / ctx->rho[i];
        } else {
            /* rho holds Σ W (001 eq. 5) */
            ctx->volume[i] = 1.0 / ctx->rho[i];
            ctx->rho[i] = ctx->mass[i] / ctx->volume[i];
        }
        if (!(ctx->volume[i] > 0.0) || !isfinite(ctx->volume[i]))
            return consph_fail(CONSPH_ENUMERIC, "volume of particle %zu is %g", i, ctx->volume[i]);
    }
    return CONSPH_OK;
}

/* ---- context ---- */

/* The scalar field `name` of p, created when absent. */
static int scalar_field(consph_particles *p, const char *name, double **out)
{
    const int existed = consph_particles_find(p, name) != NULL;
    *out = consph_particles_field(p, name, 1);
    if (*out) return CONSPH_OK;
    /* a clash of components or a full set; otherwise the allocation failed */
    return existed || p->nfields == CONSPH_MAX_FIELDS ? CONSPH_EINVAL : CONSPH_ENOMEM;
}

/* Points mass, rho and volume at the fields of p, creating those that are absent. */
static int bind_fields(consph_op_ctx *ctx, consph_particles *p)
{
    double *m, *r, *v;
    int st = scalar_field(p, "mass", &m);
    if (st == CONSPH_OK) st = scalar_field(p, "rho", &r);
    if (st == CONSPH_OK) st = scalar_field(p, "volume", &v);
    if (st != CONSPH_OK) return st;
    ctx->mass = m;
    ctx->rho = r;
    ctx->volume = v;
    return CONSPH_OK;
}

static void cache_clear(struct consph_ops_cache *c)
{
    for (int m = 0; m < OPS_MAT_COUNT; ++m) ops_cache_drop(c, (ops_mat)m);
    free(c->ctilde);
    c->ctilde = NULL;
    c->ctilde_lambda = 0.0;
    c->ctilde_iterations = 0;
}

int consph_op_ctx_init(consph_op_ctx *ctx, const consph_particles *p, const consph_nnps *nnps,
                       const consph_kernel *kernel, consph_volume_kind volume_kind)
{
    memset(ctx, 0, sizeof *ctx);
    if (!p || !nnps || !kernel)
        return consph_fail(CONSPH_EINVAL, "operator context needs particles, nnps and kernel");
    if (kernel->dim != p->dim)
        return consph_fail(CONSPH_EINVAL, "kernel is bound to %dD but the particles are %dD",
                           kernel->dim, p->dim);
    if (kernel->tensor)
        return consph_fail(CONSPH_EINVAL,
                           "kernel '%s' is a tensor-product remeshing kernel; operators need a "
                           "radial kernel",
                           kernel->name);
    if (consph_nnps_radius(nnps) < kernel->radius * (1.0 - 1e-12))
        return consph_fail(CONSPH_EINVAL,
                           "neighbour search radius %g is below the kernel support radius %g",
                           consph_nnps_radius(nnps), kernel->radius);
    if ((int)volume_kind < 0 || volume_kind >= CONSPH_VOLUME_COUNT)
        return consph_fail(CONSPH_EINVAL, "unknown volume kind %d", (int)volume_kind);
    ctx->p = p;
    ctx->nnps = nnps;
    ctx->kernel = *kernel;
    ctx->volume_kind = volume_kind;
    ctx->dim = p->dim;
    ctx->n = p->n;
    ctx->cond_max = 1e8;
    ctx->parallel_min = 2048;
    ctx->mass = consph_calloc(p->n, sizeof(double));
    ctx->rho = consph_calloc(p->n, sizeof(double));
    ctx->volume = consph_calloc(p->n, sizeof(double));
    ctx->cache = consph_calloc(1, sizeof *ctx->cache);
    if (!ctx->mass || !ctx->rho || !ctx->volume || !ctx->cache) {
        consph_op_ctx_free(ctx);
        return CONSPH_ENOMEM;
    }
    int st = compute_volumes(ctx);
    if (st != CONSPH_OK) consph_op_ctx_free(ctx);
    return st;
}

void consph_op_ctx_free(consph_op_ctx *ctx)
{
    if (!ctx->cache || !ctx->cache->fields_of) {
        free(ctx->mass);
        free(ctx->rho);
        free(ctx->volume);
    }
    if (ctx->cache) cache_clear(ctx->cache);
    free(ctx->cache);
    memset(ctx, 0, sizeof *ctx);
}

int consph_op_ctx_refresh(consph_op_ctx *ctx)
{
    if (ctx->p->n != ctx->n)
        return consph_fail(CONSPH_EINVAL,
                           "particle count changed from %zu to %zu; create a new context", ctx->n,
                           ctx->p->n);
    cache_clear(ctx->cache);
    if (ctx->cache->fields_of) {
        /* Fields stay where they are when particles are sorted, but not when they grow. */
        int st = bind_fields(ctx, ctx->cache->fields_of);
        if (st != CONSPH_OK) return st;
    }
    return compute_volumes(ctx);
}

const unsigned char *ops_bad(const consph_op_ctx *ctx, ops_mat m)
{
    return ctx->cache->bad[m];
}

void ops_report_fill(const consph_op_ctx *ctx, const ops_call *call, double t0,
                     consph_op_report *rep)
{
    if (!rep) return;
    memset(rep, 0, sizeof *rep);
    rep->n = ctx->n;
    rep->pairs = call->pairs;
    /* A particle counts once however many of the call's matrices rejected it. */
    int nused = 0;
    const unsigned char *bad[OPS_MAT_COUNT];
    for (int m = 0; m < OPS_MAT_COUNT; ++m) {
        if (!(call->used & (1u << m)) || !ctx->cache->bad[m]) continue;
        if (ctx->cache->max_cond[m] > rep->max_cond) rep->max_cond = ctx->cache->max_cond[m];
        if (ctx->cache->nbad[m]) bad[nused++] = ctx->cache->bad[m];
    }
    size_t count = 0;
    if (nused) {
        for (size_t i = 0; i < ctx->n; ++i) {
            int any = 0;
            for (int u = 0; u < nused; ++u) any |= bad[u][i];
            count += any != 0;
        }
    }
    rep->fallbacks = count;
    rep->seconds = consph_wtime() - t0;
}

int consph_op_ctx_init_sys(consph_op_ctx *ctx, const consph_sys *sys,
                           consph_volume_kind volume_kind)
{
    if (!sys) return consph_fail(CONSPH_EINVAL, "operator context needs a system");
    const int mass_given = consph_particles_find(sys->p, "mass") != NULL;
    int rc = consph_op_ctx_init(ctx, sys->p, sys->nnps, &sys->kernel, volume_kind);
    if (rc != CONSPH_OK) return rc;
    ctx->parallel_min = sys->parallel_min;
    /* The context computed into its own arrays; from now on the system's fields are the
     * arrays, so a pass reads the same ω, m and ρ the operators do. */
    double *own[3] = {ctx->mass, ctx->rho, ctx->volume};
    rc = bind_fields(ctx, sys->p);
    if (rc != CONSPH_OK) {
        consph_op_ctx_free(ctx); /* still owns own[] */
        return rc;
    }
    memcpy(ctx->mass, own[0], ctx->n * sizeof(double));
    memcpy(ctx->rho, own[1], ctx->n * sizeof(double));
    memcpy(ctx->volume, own[2], ctx->n * sizeof(double));
    for (int k = 0; k < 3; ++k) free(own[k]);
    ctx->cache->fields_of = sys->p;
    ctx->cache->mass_given = mass_given;
    return CONSPH_OK;
}
