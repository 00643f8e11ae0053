/* The operator context (particles, search, kernel, volumes), the parallel particle pass and the
 * cache of correction matrices. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"

/* ---- the pass driver ---- */

typedef struct pass_scratch {
    consph_nbrs nb;
    size_t cap;
    double *w, *dwr, *d2w;
} pass_scratch;

static int scratch_reserve(pass_scratch *s, size_t need)
{
    if (need <= s->cap) return CONSPH_OK;
    size_t cap = s->cap ? s->cap : 64;
    while (cap < need) cap *= 2;
    double *w = realloc(s->w, cap * sizeof(double));
    if (w) s->w = w;
    double *dwr = realloc(s->dwr, cap * sizeof(double));
    if (dwr) s->dwr = dwr;
    double *d2w = realloc(s->d2w, cap * sizeof(double));
    if (d2w) s->d2w = d2w;
    if (!w || !dwr || !d2w) return CONSPH_ENOMEM;
    s->cap = cap;
    return CONSPH_OK;
}

static void scratch_free(pass_scratch *s)
{
    consph_nbrs_free(&s->nb);
    free(s->w);
    free(s->dwr);
    free(s->d2w);
}

/* Kernel values of every pair of one neighbourhood. The kernel is chosen once, in
 * consph_kernel_init, as a triple of shape functions; here each pair costs one indirect call
 * per value needed and no branch on the kernel kind. */
static void eval_kernel(const consph_kernel *k, unsigned need, size_t m, const double *r, double *w,
                        double *dwr, double *d2w)
{
    const double inv_h = k->inv_h, support = k->support, norm = k->norm;
    const double norm1 = norm * inv_h, norm2 = norm * inv_h * inv_h;
    const consph_shape_fn f = k->f, df = k->df, d2f = k->d2f;
    if (need & OPS_NEED_W)
        for (size_t p = 0; p < m; ++p) {
            double q = r[p] * inv_h;
            w[p] = q < support ? norm * f(q) : 0.0;
        }
    if (need & (OPS_NEED_DW | OPS_NEED_D2W))
        for (size_t p = 0; p < m; ++p) {
            double q = r[p] * inv_h;
            if (!(q < support))
                dwr[p] = 0.0;
            else if (r[p] > 0.0)
                dwr[p] = norm1 * df(q) / r[p];
            else
                dwr[p] = norm2 * d2f(0.0);
        }
    if (need & OPS_NEED_D2W)
        for (size_t p = 0; p < m; ++p) {
            double q = r[p] * inv_h;
            d2w[p] = q < support ? norm2 * d2f(q) : 0.0;
        }
}

int ops_run(const consph_op_ctx *ctx, unsigned need, ops_visit_fn visit, void *job, size_t *pairs)
{
    const size_t n = ctx->n;
    int status = CONSPH_OK;
    size_t total = 0;
    /* consph_fail records per thread: a worker's message is copied out here. */
    char why[256] = "";
#pragma omp parallel if (n >= ctx->parallel_min)
    {
        pass_scratch s;
        memset(&s, 0, sizeof s);
        int my_status = CONSPH_OK;
        char my_why[256] = "";
        size_t my_pairs = 0;
#pragma omp for schedule(dynamic, 128)
        for (size_t i = 0; i < n; ++i) {
            if (my_status != CONSPH_OK) continue;
            size_t m = consph_nnps_query_particle(ctx->nnps, i, &s.nb);
            if (m == (size_t)-1) {
                my_status = CONSPH_EINVAL;
                snprintf(my_why, sizeof my_why, "neighbour query of particle %zu failed: %s", i,
                         consph_last_error());
                continue;
            }
            if (scratch_reserve(&s, m) != CONSPH_OK) {
                my_status = CONSPH_ENOMEM;
                snprintf(my_why, sizeof my_why, "out of memory for %zu neighbours", m);
                continue;
            }
            eval_kernel(&ctx->kernel, need, m, s.nb.r, s.w, s.dwr, s.d2w);
            ops_nbhd nb;
            nb.i = i;
            nb.n = m;
            nb.j = s.nb.j;
            for (int a = 0; a < CONSPH_MAX_DIM; ++a) nb.dx[a] = s.nb.dx[a];
            nb.r = s.nb.r;
            nb.w = s.w;
            nb.dwr = s.dwr;
            nb.d2w = s.d2w;
            visit(job, &nb);
            my_pairs += m;
        }
#pragma omp critical(consph_ops_run)
        {
            total += my_pairs;
            /* Several threads may fail; keep the lowest status so the message is reproducible. */
            if (my_status != CONSPH_OK && (status == CONSPH_OK || my_status < status)) {
                status = my_status;
                memcpy(why, my_why, sizeof why);
            }
        }
        scratch_free(&s);
    }
    if (pairs) *pairs += total;
    if (status != CONSPH_OK) return consph_fail(status, "operator pass: %s", why);
    return CONSPH_OK;
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
    double s = 0.0;
    if (job->mass) {
        for (size_t p = 0; p < nb->n; ++p) s += job->mass[nb->j[p]] * nb->w[p];
    } else {
        for (size_t p = 0; p < nb->n; ++p) s += nb->w[p];
    }
    job->sum[nb->i] = s;
}

static int compute_volumes(consph_op_ctx *ctx)
{
    const size_t n = ctx->n;
    const consph_particles *p = ctx->p;
    const consph_field *fmass = consph_particles_find(p, "mass");
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
    int st = ops_run(ctx, OPS_NEED_W, visit_density, &job, NULL);
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

static void cache_clear(struct consph_ops_cache *c)
{
    for (int m = 0; m < OPS_MAT_COUNT; ++m) {
        free(c->mat[m]);
        free(c->bad[m]);
        c->mat[m] = NULL;
        c->bad[m] = NULL;
        c->nbad[m] = 0;
        c->max_cond[m] = 0.0;
    }
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
    if (ctx->cache) cache_clear(ctx->cache);
    free(ctx->cache);
    free(ctx->mass);
    free(ctx->rho);
    free(ctx->volume);
    memset(ctx, 0, sizeof *ctx);
}

int consph_op_ctx_refresh(consph_op_ctx *ctx)
{
    if (ctx->p->n != ctx->n)
        return consph_fail(CONSPH_EINVAL,
                           "particle count changed from %zu to %zu; create a new context", ctx->n,
                           ctx->p->n);
    cache_clear(ctx->cache);
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
