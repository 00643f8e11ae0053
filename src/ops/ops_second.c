/* Laplacian and second-derivative operators (002 eqs. 7-13, 40-41; 001 eqs. 13-15, Table 4,
 * App. C; 000 eqs. 31-32).
 *
 * Forms whose inner gradient is needed at the neighbours (S1, coupled) run an F4 pass first
 * and keep G (O(N·d)); forms that need it at i only (Fatehi, Korzilius, CSPM) compute G_i in
 * a first loop over the same neighbourhood and then the operator in a second one, sharing the
 * pair geometry and kernel values. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"

typedef struct second_job {
    const consph_op_ctx *ctx;
    consph_op op;
    consph_op_form form;
    consph_op_corr corr;
    int dim;
    const double *in;
    double *out;
    const double *G;     /* F4 gradient of every particle (S1, coupled) */
    const double *bonet; /* B_i for the inner gradient */
    const double *mat;   /* the form's own matrix (B, L^{-1}, B̂, Γ̃^{-1}, CSPM^{-1}) */
    size_t mat_size;
} second_job;

/* G_i = B_i Σ ω (u_j - u_i) ∇W_ij (F4; F2 where B fell back, since B is then the identity). */
static void inner_gradient(const second_job *job, const ops_nbhd *nb, double G[3])
{
    const int d = job->dim;
    term_f4_grad(d, nb, job->ctx->volume, job->in, job->bonet + nb->i * (size_t)(d * d), G);
}

static void visit_s1(second_job *job, const ops_nbhd *nb)
{
    const int d = job->dim;
    const double *G = job->G;
    const size_t i = nb->i, N = job->ctx->n;
    double c[3], M[9], Gi[3];
    term_grad_rule(job->dim, job->corr, job->mat, job->mat_size, i, c, M);
    /* s1 (002 eq. 7) sums G_j, s1_diff/coupled (eq. 8) G_j - G_i, s1_sum (eq. 9) G_j + G_i. */
    double sign = job->form == CONSPH_FORM_S1 ? 0.0 : job->form == CONSPH_FORM_S1_SUM ? -1.0 : 1.0;
    for (int a = 0; a < d; ++a) Gi[a] = sign * G[a * N + i];
    job->out[i] = term_corrected_div_any(d, job->corr, c, M, nb, job->ctx->volume, G, N, Gi);
}

static void visit_s2(second_job *job, const ops_nbhd *nb)
{
    const double *u = job->in;
    const size_t i = nb->i;
    double shift = job->form == CONSPH_FORM_S2       ? 0.0
                   : job->form == CONSPH_FORM_S2_SUM ? -u[i]
                                                     : u[i];
    job->out[i] = term_s2(job->dim, nb, job->ctx->volume, u, shift);
}

/* Cleary/Brookshaw (002 eq. 13) and tvf (001 Table 4), with the kernel gradient corrected. */
static void visit_cleary(second_job *job, const ops_nbhd *nb)
{
    const consph_op_ctx *ctx = job->ctx;
    const int tvf = job->form == CONSPH_FORM_TVF;
    double c[3], M[9];
    term_grad_rule(job->dim, job->corr, job->mat, job->mat_size, nb->i, c, M);
    double acc = term_cleary(job->dim, tvf, job->corr, c, M, nb, ctx->volume, job->in);
    job->out[nb->i] = tvf ? acc / ctx->mass[nb->i] : acc;
}

/* Fatehi (001 eq. C.8), S4 (002 eq. 41, corr fatehi) and fatehi_c (001 eq. C.10): all are
 * Σ_j 2ω_j W'/r ((u_i - u_j) - x_ij·G_i) (x_ij^T B̂ x_ij)/r², with B̂ = I, eq. 40 or eq. 13. */
static void visit_fatehi(second_job *job, const ops_nbhd *nb)
{
    const int d = job->dim;
    const size_t i = nb->i;
    double G[3], Bh[9];
    inner_gradient(job, nb, G);
    if (job->mat)
        memcpy(Bh, job->mat + i * job->mat_size, (size_t)(d * d) * sizeof(double));
    else
        for (int a = 0; a < d; ++a)
            for (int b = 0; b < d; ++b) Bh[a * d + b] = a == b ? 1.0 : 0.0;
    job->out[i] = term_fatehi_lap(d, nb, job->ctx->volume, job->in, G, Bh);
}

/* Korzilius (001 eq. 14 with the fixes of docs/deviations.md) and CSPM (000 eqs. 31-32) second
 * derivatives share the right-hand side Σ ω ((u_j - u_i) - x_ji·G_i) ∂∂W_ij and differ in the
 * matrix. */
static void visit_hessian(second_job *job, const ops_nbhd *nb)
{
    const int d = job->dim, P = ops_npairs(d);
    const size_t i = nb->i, N = job->ctx->n;
    int pl[OPS_MAX_P], pk[OPS_MAX_P];
    for (int p = 0; p < P; ++p) ops_pair_index(d, p, &pl[p], &pk[p]);
    double G[3], rhs[OPS_MAX_P] = {0};
    inner_gradient(job, nb, G);
    term_hessian_rhs(d, P, pl, pk, nb, job->ctx->volume, job->in, G, rhs);
    const double *Ainv = job->mat + i * job->mat_size;
    double H[OPS_MAX_P];
    for (int a = 0; a < P; ++a) {
        double v = 0.0;
        for (int b = 0; b < P; ++b) v += Ainv[a * P + b] * rhs[b];
        H[a] = v;
    }
    if (job->op == CONSPH_OP_HESSIAN) {
        for (int p = 0; p < P; ++p) job->out[p * N + i] = H[p];
    } else {
        double lap = 0.0;
        for (int p = 0; p < P; ++p)
            if (pl[p] == pk[p]) lap += H[p];
        job->out[i] = lap;
    }
}

static void visit_second(void *vjob, const ops_nbhd *nb)
{
    second_job *job = vjob;
    switch (job->form) {
    case CONSPH_FORM_S1:
    case CONSPH_FORM_S1_DIFF:
    case CONSPH_FORM_S1_SUM:
    case CONSPH_FORM_COUPLED:
        visit_s1(job, nb);
        break;
    case CONSPH_FORM_S2:
    case CONSPH_FORM_S2_DIFF:
    case CONSPH_FORM_S2_SUM:
        visit_s2(job, nb);
        break;
    case CONSPH_FORM_CLEARY:
    case CONSPH_FORM_TVF:
        visit_cleary(job, nb);
        break;
    case CONSPH_FORM_FATEHI:
    case CONSPH_FORM_FATEHI_C:
        visit_fatehi(job, nb);
        break;
    case CONSPH_FORM_KORZILIUS:
    case CONSPH_FORM_CSPM:
        visit_hessian(job, nb);
        break;
    default:
        break;
    }
}

int ops_second(consph_op_ctx *ctx, consph_op op, consph_op_form form, consph_op_corr corr,
               const double *in, double *out, ops_call *call)
{
    if (form == CONSPH_FORM_MSPH) {
        /* MSPH solves for every derivative at once; the Laplacian is the trace. */
        if (op == CONSPH_OP_HESSIAN) return ops_first(ctx, op, form, corr, in, out, call);
        const int d = ctx->dim, P = ops_npairs(d);
        double *h = consph_calloc(ctx->n * (size_t)P, sizeof(double));
        if (!h) return CONSPH_ENOMEM;
        int st = ops_first(ctx, CONSPH_OP_HESSIAN, form, corr, in, h, call);
        if (st == CONSPH_OK) {
            for (size_t i = 0; i < ctx->n; ++i) out[i] = 0.0;
            for (int p = 0; p < P; ++p) {
                int l, k;
                ops_pair_index(d, p, &l, &k);
                if (l != k) continue;
                for (size_t i = 0; i < ctx->n; ++i) out[i] += h[(size_t)p * ctx->n + i];
            }
        }
        free(h);
        return st;
    }
    second_job job;
    memset(&job, 0, sizeof job);
    job.ctx = ctx;
    job.op = op;
    job.form = form;
    job.corr = corr;
    job.dim = ctx->dim;
    job.in = in;
    job.out = out;
    unsigned need = OPS_NEED_DW;
    double *G = NULL;
    ops_mat m = OPS_MAT_COUNT;
    switch (form) {
    case CONSPH_FORM_S1:
    case CONSPH_FORM_S1_DIFF:
    case CONSPH_FORM_S1_SUM:
    case CONSPH_FORM_COUPLED:
        G = consph_calloc(ctx->n * (size_t)ctx->dim, sizeof(double));
        if (!G) return CONSPH_ENOMEM;
        {
            int st = ops_grad_f4(ctx, in, G, call);
            if (st != CONSPH_OK) {
                free(G);
                return st;
            }
        }
        job.G = G;
        /* The outer sum takes the Bonet/Liu correction like Cleary's. */
        /* fall through */
    case CONSPH_FORM_CLEARY:
    case CONSPH_FORM_TVF:
        if (corr == CONSPH_CORR_BC) m = OPS_MAT_BONET;
        if (corr == CONSPH_CORR_LC) {
            m = OPS_MAT_LIU;
            need |= OPS_NEED_W;
        }
        break;
    case CONSPH_FORM_S2:
    case CONSPH_FORM_S2_DIFF:
    case CONSPH_FORM_S2_SUM:
        need |= OPS_NEED_D2W;
        break;
    case CONSPH_FORM_FATEHI:
        if (corr == CONSPH_CORR_FATEHI) m = OPS_MAT_FATEHI;
        break;
    case CONSPH_FORM_FATEHI_C:
        m = OPS_MAT_FATEHI_C;
        break;
    case CONSPH_FORM_KORZILIUS:
        m = OPS_MAT_KORZ;
        need |= OPS_NEED_D2W;
        break;
    case CONSPH_FORM_CSPM:
        m = OPS_MAT_CSPM2;
        need |= OPS_NEED_D2W;
        break;
    default:
        return consph_fail(CONSPH_EINVAL, "form %s is not a second-derivative form",
                           consph_form_name(form));
    }
    if (form == CONSPH_FORM_FATEHI || form == CONSPH_FORM_FATEHI_C ||
        form == CONSPH_FORM_KORZILIUS || form == CONSPH_FORM_CSPM) {
        job.bonet = ops_matrix(ctx, OPS_MAT_BONET, call);
        if (!job.bonet) return CONSPH_ENOMEM;
    }
    if (m != OPS_MAT_COUNT) {
        job.mat = ops_matrix(ctx, m, call);
        if (!job.mat) {
            free(G);
            return CONSPH_ENOMEM;
        }
        job.mat_size = ops_mat_size(m, ctx->dim);
    }
    int st = ops_run(ctx, need, visit_second, &job, &call->pairs);
    free(G);
    return st;
}

int consph_op_korzilius(consph_op_ctx *ctx, const double *in, double *hess, double *lap,
                        consph_op_report *rep)
{
    double t0 = consph_wtime();
    ops_call call = {0, 0};
    int st = CONSPH_OK;
    if (hess)
        st = ops_second(ctx, CONSPH_OP_HESSIAN, CONSPH_FORM_KORZILIUS, CONSPH_CORR_NONE, in, hess,
                        &call);
    if (st == CONSPH_OK && lap)
        st = ops_second(ctx, CONSPH_OP_LAPLACIAN, CONSPH_FORM_KORZILIUS, CONSPH_CORR_NONE, in, lap,
                        &call);
    if (st == CONSPH_OK) ops_report_fill(ctx, &call, t0, rep);
    return st;
}
