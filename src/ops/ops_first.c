/* Function interpolation, gradient and divergence operators (001 eqs. 3, 8-11 and
 * App. A; 002 eqs. 2-6; 000 §3).
 *
 * Every form that uses the kernel gradient takes it through one corrected-gradient rule,
 * g̃_ij^α = c_i^α W_ij + M_i^{αβ} ∇^β W_ij, with (c, M) = (0, I) uncorrected, (0, B_i) for the
 * Bonet-Lok correction and the gradient rows of L_i^{-1} for the Liu correction (001 App. A).
 * The rule is linear in (W, ∇W), so the gradient forms sum Σ s_j ∇W_ij and Σ s_j W_ij over the
 * pairs and apply it once per particle; the divergence and sym_s1 (whose rule involves the
 * neighbour's matrix) apply it per pair. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"

typedef struct first_job {
    const consph_op_ctx *ctx;
    consph_op_form form;
    consph_op_corr corr;
    int dim;
    const double *in;  /* scalar, or dim components for the divergence */
    double *out;       /* function: 1, gradient: dim components */
    double *out_grad;  /* FPM/MSPH gradient (may be NULL) */
    double *out_hess;  /* MSPH second derivatives (may be NULL) */
    const double *mat; /* B, L^{-1}, IAD A^{-1} or MSPH inverse, per particle */
    size_t mat_size;
    const unsigned char *bad;
    const double *ctilde; /* consistent-Shepard factors */
} first_job;

static void visit_function(first_job *job, const ops_nbhd *nb)
{
    const size_t i = nb->i;
    double s = 0.0, s0 = 0.0;
    /* consistent Shepard: the volumes ω_b/c_b = ω_b c̃_b of 000 eq. 61 */
    term_wsum(nb, job->ctx->volume, job->ctilde, job->in, &s, &s0);
    /* 000 eq. 28: the Shepard (= CSPM) function divides by M0 = Σ ω W, which the self term
     * keeps positive. */
    job->out[i] = job->form == CONSPH_FORM_STANDARD ? s : s / s0;
}

/* FPM (001 eq. A.5) and MSPH (000 §3.3): right-hand sides Σ ω f_j T_ij for every test function,
 * then the cached inverse. */
static void visit_taylor(first_job *job, const ops_nbhd *nb)
{
    const int d = job->dim, P = ops_npairs(d);
    const int msph = job->form == CONSPH_FORM_MSPH;
    const int n = msph ? 1 + d + P : 1 + d;
    const size_t i = nb->i, N = job->ctx->n;
    int pl[OPS_MAX_P], pk[OPS_MAX_P];
    for (int p = 0; p < P; ++p) ops_pair_index(d, p, &pl[p], &pk[p]);
    double rhs[OPS_MAX_MSPH] = {0};
    term_taylor_rhs(d, msph, P, pl, pk, nb, job->ctx->volume, job->in, rhs);
    const double *Ainv = job->mat + i * job->mat_size;
    double sol[OPS_MAX_MSPH];
    for (int a = 0; a < n; ++a) {
        double v = 0.0;
        for (int b = 0; b < n; ++b) v += Ainv[a * n + b] * rhs[b];
        sol[a] = v;
    }
    if (job->out) job->out[i] = sol[0];
    if (job->out_grad)
        for (int a = 0; a < d; ++a) job->out_grad[a * N + i] = sol[1 + a];
    if (msph && job->out_hess)
        for (int p = 0; p < P; ++p) job->out_hess[p * N + i] = sol[1 + d + p];
}

static void visit_gradient(first_job *job, const ops_nbhd *nb)
{
    const int d = job->dim;
    const consph_op_ctx *ctx = job->ctx;
    const double *vol = ctx->volume, *mass = ctx->mass, *rho = ctx->rho, *f = job->in;
    const size_t i = nb->i, N = ctx->n;
    const double fi = f[i];
    double c[3], M[9], acc[3] = {0, 0, 0};
    term_grad_rule(job->dim, job->corr, job->mat, job->mat_size, i, c, M);
    switch (job->form) {
    case CONSPH_FORM_F1:
    case CONSPH_FORM_F2:
    case CONSPH_FORM_F3:
    case CONSPH_FORM_F4:
    case CONSPH_FORM_CSPM:
    case CONSPH_FORM_ASYM:
    case CONSPH_FORM_SYM1:
    case CONSPH_FORM_SYM2: {
        /* F1 (002 eq. 2) sums u_j; F2/F4/CSPM/asym (u_j - u_i); F3 and sym1 (u_j + u_i);
         * asym is (p_j - p_i)/ρ_i ω_j ∇W, sym1 (p_j + p_i)/(ρ_i ρ_j) m_j ∇W = ω_j (p_j + p_i)/ρ_i
         * ∇W and sym2 m_j (p_j/ρ_j² + p_i/ρ_i²) ∇W (001 Table 2). */
        const consph_op_form form = job->form;
        const int sym2 = form == CONSPH_FORM_SYM2;
        double shift = form == CONSPH_FORM_F1                               ? 0.0
                       : form == CONSPH_FORM_F3 || form == CONSPH_FORM_SYM1 ? -fi
                       : sym2                                               ? fi / (rho[i] * rho[i])
                                                                            : fi;
        double sg[3], sw;
        term_grad_sums_any(d, sym2 ? TERM_GRAD_SYM2 : TERM_GRAD_DIFF, job->corr == CONSPH_CORR_LC,
                           nb, vol, mass, rho, f, shift, sg, &sw);
        term_apply_rule(d, c, M, sg, sw, acc);
        if (form == CONSPH_FORM_ASYM || form == CONSPH_FORM_SYM1)
            for (int a = 0; a < d; ++a) acc[a] /= rho[i];
        break;
    }
    case CONSPH_FORM_SYM_S1: {
        /* 001 eq. 10 with the ½ it lacks as printed (docs/deviations.md): m_j (p_j + p_i)/(ρ_j ρ_i)
         * ½(L_i∇W_ij - L_j∇W_ji), where L_j∇W_ji applies j's Liu rows to (W, ∇W_ji = -∇W_ij). */
        term_sym_s1(d, job->corr, c, M, nb, mass, rho, f, job->mat, job->mat_size, acc);
        break;
    }
    case CONSPH_FORM_IAD: {
        /* 000 eqs. 50-52: A^{-1} Σ ω (f_j - f_i) x_ji W; F2 where A was rejected. */
        if (job->bad[i]) {
            double sw;
            term_grad_sums_any(d, TERM_GRAD_DIFF, 0, nb, vol, mass, rho, f, fi, acc, &sw);
            break;
        }
        double I[3] = {0, 0, 0};
        term_iad_rhs(d, nb, vol, f, fi, I);
        const double *Ainv = job->mat + i * job->mat_size;
        for (int a = 0; a < d; ++a)
            for (int b = 0; b < d; ++b) acc[a] += Ainv[a * d + b] * I[b];
        break;
    }
    default:
        break;
    }
    for (int a = 0; a < d; ++a) job->out[a * N + i] = acc[a];
}

static void visit_div(first_job *job, const ops_nbhd *nb)
{
    const int d = job->dim;
    const double *u = job->in;
    const size_t i = nb->i, N = job->ctx->n;
    double c[3], M[9], ui[3];
    term_grad_rule(job->dim, job->corr, job->mat, job->mat_size, i, c, M);
    for (int a = 0; a < d; ++a) ui[a] = u[a * N + i];
    job->out[i] = term_corrected_div_any(d, job->corr, c, M, nb, job->ctx->volume, u, N, ui);
}

static void visit_first(void *vjob, const ops_nbhd *nb)
{
    first_job *job = vjob;
    switch (job->form) {
    case CONSPH_FORM_STANDARD:
    case CONSPH_FORM_SHEPARD:
    case CONSPH_FORM_CSHEPARD:
        visit_function(job, nb);
        break;
    case CONSPH_FORM_FPM:
    case CONSPH_FORM_MSPH:
        visit_taylor(job, nb);
        break;
    case CONSPH_FORM_DIV:
        visit_div(job, nb);
        break;
    default:
        visit_gradient(job, nb);
        break;
    }
}

static unsigned first_needs(consph_op_form form, consph_op_corr corr)
{
    switch (form) {
    case CONSPH_FORM_STANDARD:
    case CONSPH_FORM_SHEPARD:
    case CONSPH_FORM_CSHEPARD:
        return OPS_NEED_W | OPS_SKIP_DX;
    case CONSPH_FORM_IAD:
        return OPS_NEED_W | OPS_NEED_DW;
    case CONSPH_FORM_FPM:
    case CONSPH_FORM_SYM_S1:
        return OPS_NEED_W | OPS_NEED_DW;
    case CONSPH_FORM_MSPH:
        return OPS_NEED_W | OPS_NEED_DW | OPS_NEED_D2W;
    default:
        return corr == CONSPH_CORR_LC ? (OPS_NEED_W | OPS_NEED_DW) : OPS_NEED_DW;
    }
}

/* Runs a first-derivative family operator. `op` selects which of the FPM/MSPH outputs `out`
 * receives when the caller uses the single entry point. */
static int run_first(consph_op_ctx *ctx, consph_op_form form, consph_op_corr corr, const double *in,
                     double *out, double *out_grad, double *out_hess, ops_call *call)
{
    first_job job;
    memset(&job, 0, sizeof job);
    job.ctx = ctx;
    job.form = form;
    job.corr = corr;
    job.dim = ctx->dim;
    job.in = in;
    job.out = out;
    job.out_grad = out_grad;
    job.out_hess = out_hess;
    ops_mat m = OPS_MAT_COUNT;
    if (form == CONSPH_FORM_F4 || form == CONSPH_FORM_CSPM) {
        /* F4 = F2 with B_i (002 eqs. 5-6); CSPM's A F' = b (000 eqs. 29-30) is the same
         * operator, B = A^{-1}. */
        job.corr = CONSPH_CORR_BC;
        m = OPS_MAT_BONET;
    } else if (form == CONSPH_FORM_FPM || form == CONSPH_FORM_SYM_S1) {
        m = OPS_MAT_LIU;
        if (form == CONSPH_FORM_SYM_S1) job.corr = CONSPH_CORR_LC;
    } else if (form == CONSPH_FORM_MSPH) {
        m = OPS_MAT_MSPH;
    } else if (form == CONSPH_FORM_CSHEPARD) {
        int st = ops_ctilde(ctx, call, &job.ctilde);
        if (st != CONSPH_OK) return st;
    } else if (form == CONSPH_FORM_IAD) {
        m = OPS_MAT_IAD;
    } else if (corr == CONSPH_CORR_BC) {
        m = OPS_MAT_BONET;
    } else if (corr == CONSPH_CORR_LC) {
        m = OPS_MAT_LIU;
    }
    if (m != OPS_MAT_COUNT) {
        job.mat = ops_matrix(ctx, m, call);
        if (!job.mat) return CONSPH_ENOMEM;
        job.mat_size = ops_mat_size(m, ctx->dim);
        job.bad = ops_bad(ctx, m);
    }
    return ops_run(ctx, first_needs(form, job.corr), visit_first, &job, &call->pairs);
}

int ops_first(consph_op_ctx *ctx, consph_op op, consph_op_form form, consph_op_corr corr,
              const double *in, double *out, ops_call *call)
{
    if (form == CONSPH_FORM_FPM || form == CONSPH_FORM_MSPH) {
        double *f = op == CONSPH_OP_FUNCTION ? out : NULL;
        double *g = op == CONSPH_OP_GRAD ? out : NULL;
        double *h = op == CONSPH_OP_HESSIAN ? out : NULL;
        return run_first(ctx, form, corr, in, f, g, h, call);
    }
    if (op == CONSPH_OP_FUNCTION && form == CONSPH_FORM_CSPM) form = CONSPH_FORM_SHEPARD;
    return run_first(ctx, form, corr, in, out, NULL, NULL, call);
}

int ops_grad_f4(consph_op_ctx *ctx, const double *in, double *g, ops_call *call)
{
    return run_first(ctx, CONSPH_FORM_F4, CONSPH_CORR_NONE, in, g, NULL, NULL, call);
}

int consph_op_fpm(consph_op_ctx *ctx, const double *in, double *f, double *grad,
                  consph_op_report *rep)
{
    double t0 = consph_wtime();
    ops_call call = {0, 0};
    int st = run_first(ctx, CONSPH_FORM_FPM, CONSPH_CORR_NONE, in, f, grad, NULL, &call);
    if (st == CONSPH_OK) ops_report_fill(ctx, &call, t0, rep);
    return st;
}

int consph_op_msph(consph_op_ctx *ctx, const double *in, double *f, double *grad, double *hess,
                   consph_op_report *rep)
{
    double t0 = consph_wtime();
    ops_call call = {0, 0};
    int st = run_first(ctx, CONSPH_FORM_MSPH, CONSPH_CORR_NONE, in, f, grad, hess, &call);
    if (st == CONSPH_OK) ops_report_fill(ctx, &call, t0, rep);
    return st;
}
