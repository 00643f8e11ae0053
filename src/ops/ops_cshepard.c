/* Consistent Shepard interpolation and its gradient (Reinhardt et al.; 000 §4.2, eqs. 59-67).
 *
 * The factors c̃ solve c̃_a = Σ_b c̃_b ω_b W_ab (eq. 62), an eigenproblem that the paper solves by
 * power iteration (eq. 63) without naming the norm. The dominant eigenvalue of A is close to,
 * but not exactly, 1 on a real particle set (000's "column stochastic" holds only roughly), so
 * the iteration fixes the scale by Σ_a ω_a c̃_a = Σ_a ω_a and the interpolant (eqs. 60, 61, 64)
 * is written with the normalisation it implies at the fixed point, Σ_b ω_b c̃_b W_ab = λ c̃_a:
 *     f_a = Σ_b ω_b c̃_b f_b W_ab / Σ_b ω_b c̃_b W_ab,
 * which reproduces constants exactly whether or not the iteration has fully converged. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"

typedef struct power_job {
    const consph_op_ctx *ctx;
    const double *c;
    double *y;
} power_job;

static void visit_power(void *vjob, const ops_nbhd *nb)
{
    power_job *job = vjob;
    term_wsum(nb, job->ctx->volume, job->c, NULL, NULL, &job->y[nb->i]);
}

static int power_iteration(consph_op_ctx *ctx, double tol, int max_iter, double *c, int *iters,
                           double *lambda, size_t *pairs)
{
    const size_t n = ctx->n;
    double *y = consph_calloc(n, sizeof(double)), *t = consph_calloc(n, sizeof(double));
    if (!y || !t) {
        free(y);
        free(t);
        return CONSPH_ENOMEM;
    }
    for (size_t i = 0; i < n; ++i) c[i] = 1.0;
    const double vtot = consph_sum(ctx->volume, n);
    int it = 0, st = CONSPH_OK;
    double s = 1.0;
    while (it < max_iter) {
        power_job job = {ctx, c, y};
        st = ops_run(ctx, OPS_NEED_W | OPS_SKIP_DX, visit_power, &job, pairs);
        if (st != CONSPH_OK) break;
        ++it;
        for (size_t i = 0; i < n; ++i) t[i] = ctx->volume[i] * y[i];
        s = consph_sum(t, n) / vtot;
        double change = 0.0;
        for (size_t i = 0; i < n; ++i) {
            double v = y[i] / s;
            double d = fabs(v - c[i]);
            if (!(d <= change)) change = d;
            c[i] = v;
        }
        if (!isfinite(change)) {
            st = consph_fail(CONSPH_ENUMERIC, "consistent Shepard: non-finite factors");
            break;
        }
        if (change < tol) break;
    }
    free(y);
    free(t);
    if (iters) *iters = it;
    if (lambda) *lambda = s;
    return st;
}

int consph_op_cshepard_factors(consph_op_ctx *ctx, double tol, int max_iter, double *ctilde,
                               int *iterations, double *lambda)
{
    if (!(tol > 0.0) || max_iter < 1)
        return consph_fail(CONSPH_EINVAL, "consistent Shepard: need tol > 0 and max_iter >= 1");
    double *c = ctilde ? ctilde : consph_calloc(ctx->n, sizeof(double));
    if (!c) return CONSPH_ENOMEM;
    size_t pairs = 0;
    int st = power_iteration(ctx, tol, max_iter, c, iterations, lambda, &pairs);
    if (!ctilde) free(c);
    return st;
}

int ops_ctilde(consph_op_ctx *ctx, ops_call *call, const double **ctilde)
{
    struct consph_ops_cache *cache = ctx->cache;
    if (!cache->ctilde) {
        double *c = consph_calloc(ctx->n, sizeof(double));
        if (!c) return CONSPH_ENOMEM;
        int st = power_iteration(ctx, 1e-10, 2000, c, &cache->ctilde_iterations,
                                 &cache->ctilde_lambda, &call->pairs);
        if (st != CONSPH_OK) {
            free(c);
            return st;
        }
        cache->ctilde = c;
    }
    *ctilde = cache->ctilde;
    return CONSPH_OK;
}

/* ---- gradient, 000 eqs. 65-68 ----
 *
 * c̃_a in eqs. 65-66 is taken as eq. 62 writes it, S_a = Σ_b ω_b c̃_b W_ab (the denominator of
 * the function form above): eq. 66, ∇c̃_a = Σ_b ω_b c̃_b ∇W_ab, is the gradient of exactly that
 * sum, whereas the iterate c̃_a equals it only up to the eigenvalue λ ≠ 1. With S_a, eq. 65 is
 * the exact derivative (c̃_b held fixed) of the weights W̃_ab = W_ab / S_a that the function
 * form uses, and the volumes ω_b/c_b of eq. 67 are ω_b c̃_b (c_b = 1/c̃_b, eq. 61).
 *
 * Eq. 68's ξ_a = Σ_b m_b (1/ρ_b² + 1/ρ_a²) ∇W̃_ab does not have the units of eq. 67's first
 * sum divided by A as printed. We take ξ_a = Σ_b (ω_b/c_b) ∇W̃_ab, the same sum
 * with A = 1, so the gradient of a constant vanishes identically: the purpose 000 gives the
 * zero-order fix. Eq. 67 then reads ∇A_a = Σ_b ω_b c̃_b (A_b - A_a) ∇W̃_ab, which is how it is
 * summed (the difference makes the constant case exactly zero, not zero up to rounding). */

typedef struct cgrad_job {
    const consph_op_ctx *ctx;
    const double *c;  /* c̃ */
    const double *in; /* A */
    double *s;        /* S_a = Σ ω c̃ W, n values */
    double *gs;       /* ∇S_a, dim components */
    double *out;      /* ∇A, dim components */
} cgrad_job;

static void visit_cshepard_sum(void *vjob, const ops_nbhd *nb)
{
    cgrad_job *job = vjob;
    const int d = job->ctx->dim;
    const size_t n = job->ctx->n, i = nb->i;
    double s, g[3];
    term_grad_sums_any(d, TERM_GRAD_PROD, 1, nb, job->ctx->volume, NULL, NULL, job->c, 0.0, g, &s);
    job->s[i] = s;
    for (int a = 0; a < d; ++a) job->gs[(size_t)a * n + i] = g[a];
}

static void visit_cshepard_grad(void *vjob, const ops_nbhd *nb)
{
    cgrad_job *job = vjob;
    const int d = job->ctx->dim;
    const size_t n = job->ctx->n, i = nb->i;
    /* the self term keeps S_a > 0 */
    const double inv_s = 1.0 / job->s[i];
    double q[3], g[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) q[a] = job->gs[(size_t)a * n + i] * inv_s;
    term_cshepard_grad(d, nb, job->ctx->volume, job->c, job->in, q, g);
    for (int a = 0; a < d; ++a) job->out[(size_t)a * n + i] = g[a] * inv_s;
}

int ops_grad_cshepard(consph_op_ctx *ctx, const double *in, double *out, ops_call *call)
{
    const double *c = NULL;
    int st = ops_ctilde(ctx, call, &c);
    if (st != CONSPH_OK) return st;
    double *s = consph_calloc(ctx->n * (size_t)(1 + ctx->dim), sizeof(double));
    if (!s) return CONSPH_ENOMEM;
    cgrad_job job = {ctx, c, in, s, s + ctx->n, out};
    st = ops_run(ctx, OPS_NEED_W | OPS_NEED_DW, visit_cshepard_sum, &job, &call->pairs);
    if (st == CONSPH_OK)
        st = ops_run(ctx, OPS_NEED_W | OPS_NEED_DW, visit_cshepard_grad, &job, &call->pairs);
    free(s);
    return st;
}
