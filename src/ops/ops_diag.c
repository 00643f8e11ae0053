/* Consistency diagnostics (discrete moments, 000 eqs. 15-16, 003 eqs. 11-12), the M0
 * histogram (003 Figs. 2-3) and the 1D boundary-integral derivatives (000 §3.4). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"

typedef struct moment_job {
    const consph_op_ctx *ctx;
    double *m0, *m1, *g0, *g1;
} moment_job;

/* The moments of one neighbourhood for a dimension known at compile time. */
TERM_INLINE void moment_sums(const int d, const moment_job *job, const ops_nbhd *nb)
{
    const size_t i = nb->i, N = job->ctx->n;
    double m0, m1[3], g0[3], g1[9];
    term_moments(d, 1, 1, nb, job->ctx->volume, &m0, m1, g0, g1);
    if (job->m0) job->m0[i] = m0;
    for (int a = 0; a < d; ++a) {
        if (job->m1) job->m1[a * N + i] = m1[a];
        if (job->g0) job->g0[a * N + i] = g0[a];
        if (job->g1)
            for (int b = 0; b < d; ++b) job->g1[(size_t)(a * d + b) * N + i] = g1[a * d + b];
    }
}

static void visit_moments(void *vjob, const ops_nbhd *nb)
{
    const moment_job *job = vjob;
    if (job->ctx->dim == 1)
        moment_sums(1, job, nb);
    else if (job->ctx->dim == 2)
        moment_sums(2, job, nb);
    else
        moment_sums(3, job, nb);
}

int consph_op_moments(consph_op_ctx *ctx, double *m0, double *m1, double *g0, double *g1,
                      consph_op_report *rep)
{
    double t0 = consph_wtime();
    moment_job job = {ctx, m0, m1, g0, g1};
    ops_call call = {0, 0};
    int st = ops_run(ctx, OPS_NEED_W | OPS_NEED_DW, visit_moments, &job, &call.pairs);
    if (st == CONSPH_OK) ops_report_fill(ctx, &call, t0, rep);
    return st;
}

int consph_histogram(const double *v, size_t n, double lo, double hi, int nbins, size_t *counts,
                     size_t *below, size_t *above, double *mean, double *stddev)
{
    if (nbins < 1 || !(hi > lo) || !isfinite(lo) || !isfinite(hi))
        return consph_fail(CONSPH_EINVAL, "histogram needs nbins >= 1 and finite lo < hi");
    size_t nb = 0, na = 0, nfin = 0;
    memset(counts, 0, (size_t)nbins * sizeof(size_t));
    const double scale = (double)nbins / (hi - lo);
    for (size_t i = 0; i < n; ++i) {
        double x = v[i];
        if (isnan(x)) continue;
        if (isfinite(x)) ++nfin;
        if (x < lo) {
            ++nb;
        } else if (x >= hi) {
            ++na;
        } else {
            int b = (int)((x - lo) * scale);
            if (b >= nbins) b = nbins - 1; /* rounding at the top edge */
            ++counts[b];
        }
    }
    if (below) *below = nb;
    if (above) *above = na;
    if (mean || stddev) {
        double mu = 0.0, sd = 0.0;
        if (nfin) {
            double *t = consph_calloc(n, sizeof(double));
            if (!t) return CONSPH_ENOMEM;
            for (size_t i = 0; i < n; ++i) t[i] = isfinite(v[i]) ? v[i] : 0.0;
            mu = consph_sum(t, n) / (double)nfin;
            for (size_t i = 0; i < n; ++i) t[i] = isfinite(v[i]) ? (v[i] - mu) * (v[i] - mu) : 0.0;
            sd = sqrt(consph_sum(t, n) / (double)nfin);
            free(t);
        }
        if (mean) *mean = mu;
        if (stddev) *stddev = sd;
    }
    return CONSPH_OK;
}

typedef struct boundary_job {
    const consph_op_ctx *ctx;
    const double *f;
    double A, B, fA, fB;
    double *d1, *d2;
} boundary_job;

/* 000 eqs. 45-46. The interval's end points are particles 1 and N of the paper; here they are
 * not in the particle set (they carry no volume), so every particle of the set is an interior b
 * and the sums run over all of them. */
static void visit_boundary(void *vjob, const ops_nbhd *nb)
{
    boundary_job *job = vjob;
    const consph_op_ctx *ctx = job->ctx;
    const size_t i = nb->i;
    const double fa = job->f[i], xa = ctx->p->x[0][i];
    double gamma, s1, s2;
    term_boundary_1d(nb, ctx->volume, job->f, &gamma, &s1, &s2);
    double wB = consph_kernel_w(&ctx->kernel, fabs(xa - job->B));
    double wA = consph_kernel_w(&ctx->kernel, fabs(xa - job->A));
    if (job->d1) job->d1[i] = (job->fB * wB - job->fA * wA + s1) / gamma;
    if (job->d2) {
        double bnd = (fa - job->fB) / (xa - job->B) * wB - (fa - job->fA) / (xa - job->A) * wA;
        job->d2[i] = 2.0 * (bnd + s2) / gamma;
    }
}

int consph_op_boundary_1d(consph_op_ctx *ctx, const double *in, double fA, double fB, double *d1,
                          double *d2, consph_op_report *rep)
{
    double t0 = consph_wtime();
    if (ctx->dim != 1)
        return consph_fail(CONSPH_EINVAL, "boundary-integral derivatives are 1D only (got %dD)",
                           ctx->dim);
    const consph_box *box = &ctx->p->box;
    if (box->periodic[0])
        return consph_fail(CONSPH_EINVAL,
                           "boundary-integral derivatives need a non-periodic interval");
    for (size_t i = 0; i < ctx->n; ++i) {
        double x = ctx->p->x[0][i];
        if (!(x > box->lo[0] && x < box->hi[0]))
            return consph_fail(CONSPH_EINVAL,
                               "particle %zu at x = %g is not inside the open interval (%g, %g)", i,
                               x, box->lo[0], box->hi[0]);
    }
    boundary_job job = {ctx, in, box->lo[0], box->hi[0], fA, fB, d1, d2};
    ops_call call = {0, 0};
    int st = ops_run(ctx, OPS_NEED_W | OPS_NEED_DW, visit_boundary, &job, &call.pairs);
    if (st == CONSPH_OK) ops_report_fill(ctx, &call, t0, rep);
    return st;
}
