/* Correction matrices, one pass each, cached per particle in the context.
 *
 * Sign conventions (001 App. C, 002 eq. 15): x_ij = x_i - x_j (the search's dx), x_ji = -x_ij,
 * ∇W_ij = dwr * x_ij. A matrix that ops_invert rejects is replaced by its fallback (the
 * identity: the operator becomes the uncorrected one) and flagged. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"

size_t ops_mat_size(ops_mat m, int dim)
{
    size_t d = (size_t)dim, P = (size_t)ops_npairs(dim);
    switch (m) {
    case OPS_MAT_BONET:
    case OPS_MAT_FATEHI:
    case OPS_MAT_FATEHI_C:
    case OPS_MAT_IAD:
        return d * d;
    case OPS_MAT_LIU:
        return (d + 1) * (d + 1);
    case OPS_MAT_KORZ:
    case OPS_MAT_CSPM2:
        return P * P;
    case OPS_MAT_MSPH:
        return (1 + d + P) * (1 + d + P);
    case OPS_MAT_COUNT:
        break;
    }
    return 0;
}

static const char *mat_label[OPS_MAT_COUNT] = {
    [OPS_MAT_BONET] = "Bonet-Lok B",
    [OPS_MAT_LIU] = "Liu/FPM L",
    [OPS_MAT_FATEHI] = "Fatehi B-hat",
    [OPS_MAT_FATEHI_C] = "Fatehi_c B-hat",
    [OPS_MAT_KORZ] = "Korzilius Gamma",
    [OPS_MAT_CSPM2] = "CSPM second-derivative",
    [OPS_MAT_MSPH] = "MSPH",
    [OPS_MAT_IAD] = "IAD",
};

typedef struct mat_job {
    const consph_op_ctx *ctx;
    ops_mat m;
    int dim, P;
    size_t size;
    double *out;
    unsigned char *bad;
    double *cond;
    const double *bonet; /* B_i, for the matrices built on it */
    const unsigned char *bonet_bad;
} mat_job;

static void set_identity(double *a, int n)
{
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) a[r * n + c] = r == c ? 1.0 : 0.0;
}

/* Inverts a (n×n) into out, or stores the identity (cond 0) and returns 0. */
static int invert_or_identity(int n, const double *a, double *out, double cond_max, double *cond)
{
    *cond = 0.0;
    if (ops_invert(n, a, out, cond_max, cond)) return 1;
    set_identity(out, n);
    *cond = 0.0;
    return 0;
}

int consph_bonet_finalise(int d, const double *moment, double cond_max, double *B, double *cond)
{
    double c;
    int ok = invert_or_identity(d, moment, B, cond_max, &c);
    if (cond) *cond = c;
    return ok;
}

/* Inverts a (n×n) into out, or stores the identity and flags the particle. */
static void finish_inverse(const mat_job *job, size_t i, int n, const double *a)
{
    job->bad[i] =
        !invert_or_identity(n, a, job->out + i * job->size, job->ctx->cond_max, &job->cond[i]);
}

static void visit_bonet(mat_job *job, const ops_nbhd *nb)
{
    const int d = job->dim;
    const double *vol = job->ctx->volume;
    double M[9] = {0};
    term_bonet_moment_any(d, nb, vol, M);
    finish_inverse(job, nb->i, d, M);
}

static void visit_liu(mat_job *job, const ops_nbhd *nb)
{
    const int d = job->dim, n = d + 1;
    const double *vol = job->ctx->volume;
    double L[16], m1[3], g0[3], g1[9];
    if (d == 1)
        term_moments(1, 1, 1, nb, vol, &L[0], m1, g0, g1);
    else if (d == 2)
        term_moments(2, 1, 1, nb, vol, &L[0], m1, g0, g1);
    else
        term_moments(3, 1, 1, nb, vol, &L[0], m1, g0, g1);
    /* rows: test functions W, ∂^α W; columns: 1, (x_j - x_i)^β */
    for (int b = 0; b < d; ++b) L[1 + b] = m1[b];
    for (int a = 0; a < d; ++a) {
        L[(1 + a) * n] = g0[a];
        for (int b = 0; b < d; ++b) L[(1 + a) * n + 1 + b] = g1[a * d + b];
    }
    finish_inverse(job, nb->i, n, L);
}

static void visit_iad(mat_job *job, const ops_nbhd *nb)
{
    const int d = job->dim;
    const double *vol = job->ctx->volume;
    double A[9] = {0};
    term_iad_moment(d, nb, vol, A);
    /* IAD's matrix is a second moment, not a correction of ∇W: its fallback is the F2 gradient,
     * which the operator applies where the flag is set. */
    size_t i = nb->i;
    double cond = 0.0;
    if (ops_invert(d, A, job->out + i * job->size, job->ctx->cond_max, &cond)) {
        job->bad[i] = 0;
        job->cond[i] = cond;
    } else {
        memset(job->out + i * job->size, 0, job->size * sizeof(double));
        job->bad[i] = 1;
        job->cond[i] = 0.0;
    }
}

/* Fatehi-Manzari B̂ (002 eq. 40) in index form (002 leaves the index placement
 * implicit; every tensor below is fully symmetric, so it does not matter): with
 * T4^{αβημ} = Σ ω r e^α e^β e^η ∂^μW, S3^{ημγ} = Σ ω e^η e^γ ∂^μW, R3^{αβδ} = Σ ω x^α x^β ∂^δW and
 * Q^{αβημ} = T4 + S3^{ημγ} B^{γδ} R3^{αβδ}, solve B̂^{ημ} Q^{αβημ} = -δ^{αβ} for symmetric B̂
 * (P unknowns, one equation per symmetric pair αβ). */
static void visit_fatehi(mat_job *job, const ops_nbhd *nb)
{
    const int d = job->dim, P = job->P;
    const double *vol = job->ctx->volume;
    size_t i = nb->i;
    double *out = job->out + i * job->size;
    if (job->bonet_bad[i]) {
        set_identity(out, d);
        job->bad[i] = 1;
        job->cond[i] = 0.0;
        return;
    }
    int pl[OPS_MAX_P], pk[OPS_MAX_P];
    for (int p = 0; p < P; ++p) ops_pair_index(d, p, &pl[p], &pk[p]);
    double T4[OPS_MAX_P * OPS_MAX_P] = {0}, S3[27] = {0}, R3[27] = {0};
    term_fatehi_moments(d, P, pl, pk, nb, vol, T4, S3, R3);
    const double *B = job->bonet + i * (size_t)(d * d);
    double A[OPS_MAX_P * OPS_MAX_P], rhs[OPS_MAX_P];
    for (int a = 0; a < P; ++a) {
        int al = pl[a], be = pk[a];
        rhs[a] = al == be ? -1.0 : 0.0;
        for (int b = 0; b < P; ++b) {
            int eta = pl[b], mu = pk[b];
            double q = T4[a * P + b];
            for (int g = 0; g < d; ++g)
                for (int dl = 0; dl < d; ++dl)
                    q += S3[(eta * d + mu) * d + g] * B[g * d + dl] * R3[(al * d + be) * d + dl];
            /* B̂ symmetric: the off-diagonal unknown appears twice in the contraction. */
            A[a * P + b] = (eta == mu ? 1.0 : 2.0) * q;
        }
    }
    double Ainv[OPS_MAX_P * OPS_MAX_P], cond = 0.0;
    if (!ops_invert(P, A, Ainv, job->ctx->cond_max, &cond)) {
        set_identity(out, d);
        job->bad[i] = 1;
        job->cond[i] = 0.0;
        return;
    }
    for (int b = 0; b < P; ++b) {
        double v = 0.0;
        for (int a = 0; a < P; ++a) v += Ainv[b * P + a] * rhs[a];
        out[pl[b] * d + pk[b]] = v;
        out[pk[b] * d + pl[b]] = v;
    }
    job->bad[i] = 0;
    job->cond[i] = cond;
}

/* 001 eq. 13 (= C.13): B̂ = -(L2 + L3·(B L1))^{-1} with L1^θ = Σ ω r² ∂^θW,
 * L2^{ημ} = Σ ω x^η ∂^μW, L3^{ημα} = Σ ω e^η ∂^μW e^α (001 eq. C.12 traced over β = γ). */
static void visit_fatehi_c(mat_job *job, const ops_nbhd *nb)
{
    const int d = job->dim;
    const double *vol = job->ctx->volume;
    size_t i = nb->i;
    double *out = job->out + i * job->size;
    if (job->bonet_bad[i]) {
        set_identity(out, d);
        job->bad[i] = 1;
        job->cond[i] = 0.0;
        return;
    }
    double M[9];
    term_fatehi_c_matrix(d, nb, vol, job->bonet + i * (size_t)(d * d), M);
    finish_inverse(job, i, d, M);
}

/* The CSPM second-derivative matrix (000 eq. 32), B_{(sm),(lk)} = (1 - δ_lk/2) Σ ω x^l x^k
 * ∂_s∂_m W, and Korzilius' Γ̃ (001 eq. 15 with the fixes of docs/deviations.md: x_ji, B itself,
 * ζ = [x², 2xy, y²]) which subtracts (Σ ω ∂∂W x_ji^T) B (½ Σ ω ∇W ζ^T) from it. */
static void visit_second(mat_job *job, const ops_nbhd *nb)
{
    const int d = job->dim, P = job->P;
    const int korz = job->m == OPS_MAT_KORZ;
    const double *vol = job->ctx->volume;
    size_t i = nb->i;
    if (korz && job->bonet_bad[i]) {
        set_identity(job->out + i * job->size, P);
        job->bad[i] = 1;
        job->cond[i] = 0.0;
        return;
    }
    int pl[OPS_MAX_P], pk[OPS_MAX_P];
    double cq[OPS_MAX_P];
    for (int p = 0; p < P; ++p) {
        ops_pair_index(d, p, &pl[p], &pk[p]);
        cq[p] = term_taylor_c(pl[p], pk[p]);
    }
    double A[OPS_MAX_P * OPS_MAX_P] = {0};
    double Hx[OPS_MAX_P * 3] = {0}; /* Σ ω ∂∂W_p x_ji^α */
    double Gz[3 * OPS_MAX_P] = {0}; /* Σ ω ∂^α W c_q x^l x^k */
    term_second_moment(d, P, pl, pk, cq, korz, nb, vol, A, Hx, Gz);
    if (korz) term_korzilius_correct(d, P, Hx, Gz, job->bonet + i * (size_t)(d * d), A);
    finish_inverse(job, i, P, A);
}

/* MSPH (000 §3.3): unknowns [f, ∂f, ∂∂f (l <= k)], test functions [W, ∂W, ∂∂W], columns
 * [1, x_ji, (1 - δ_lk/2) x_ji^l x_ji^k], so the unknowns are the derivatives themselves. */
static void visit_msph(mat_job *job, const ops_nbhd *nb)
{
    const int d = job->dim, P = job->P, n = 1 + d + P;
    const double *vol = job->ctx->volume;
    int pl[OPS_MAX_P], pk[OPS_MAX_P];
    double cq[OPS_MAX_P];
    for (int p = 0; p < P; ++p) {
        ops_pair_index(d, p, &pl[p], &pk[p]);
        cq[p] = term_taylor_c(pl[p], pk[p]);
    }
    double A[OPS_MAX_MSPH * OPS_MAX_MSPH] = {0};
    term_msph_moment(d, P, pl, pk, cq, nb, vol, A);
    finish_inverse(job, nb->i, n, A);
}

static void visit_matrix(void *vjob, const ops_nbhd *nb)
{
    mat_job *job = vjob;
    switch (job->m) {
    case OPS_MAT_BONET:
        visit_bonet(job, nb);
        break;
    case OPS_MAT_LIU:
        visit_liu(job, nb);
        break;
    case OPS_MAT_IAD:
        visit_iad(job, nb);
        break;
    case OPS_MAT_FATEHI:
        visit_fatehi(job, nb);
        break;
    case OPS_MAT_FATEHI_C:
        visit_fatehi_c(job, nb);
        break;
    case OPS_MAT_KORZ:
    case OPS_MAT_CSPM2:
        visit_second(job, nb);
        break;
    case OPS_MAT_MSPH:
        visit_msph(job, nb);
        break;
    case OPS_MAT_COUNT:
        break;
    }
}

static unsigned mat_needs(ops_mat m)
{
    switch (m) {
    case OPS_MAT_LIU:
    case OPS_MAT_MSPH:
        return OPS_NEED_W | OPS_NEED_DW | OPS_NEED_D2W;
    case OPS_MAT_IAD:
        return OPS_NEED_W;
    case OPS_MAT_KORZ:
    case OPS_MAT_CSPM2:
        return OPS_NEED_DW | OPS_NEED_D2W;
    default:
        return OPS_NEED_DW;
    }
}

const double *ops_matrix(consph_op_ctx *ctx, ops_mat m, ops_call *call)
{
    struct consph_ops_cache *c = ctx->cache;
    call->used |= 1u << m;
    if (c->mat[m]) return c->mat[m];
    mat_job job;
    memset(&job, 0, sizeof job);
    job.ctx = ctx;
    job.m = m;
    job.dim = ctx->dim;
    job.P = ops_npairs(ctx->dim);
    job.size = ops_mat_size(m, ctx->dim);
    if (m == OPS_MAT_FATEHI || m == OPS_MAT_FATEHI_C || m == OPS_MAT_KORZ) {
        job.bonet = ops_matrix(ctx, OPS_MAT_BONET, call);
        if (!job.bonet) return NULL;
        job.bonet_bad = c->bad[OPS_MAT_BONET];
    }
    double *out = consph_calloc(ctx->n * job.size, sizeof(double));
    unsigned char *bad = consph_calloc(ctx->n, 1);
    double *cond = consph_calloc(ctx->n, sizeof(double));
    if (!out || !bad || !cond) {
        free(out);
        free(bad);
        free(cond);
        return NULL;
    }
    job.out = out;
    job.bad = bad;
    job.cond = cond;
    /* MSPH needs W'' at r = 0 through dwr's limit; mat_needs asks for it. */
    int st = ops_run(ctx, mat_needs(m), visit_matrix, &job, &call->pairs);
    if (st != CONSPH_OK) {
        free(out);
        free(bad);
        free(cond);
        char why[512];
        snprintf(why, sizeof why, "%s", consph_last_error());
        consph_fail(st, "%s matrices: %s", mat_label[m], why);
        return NULL;
    }
    size_t nbad = 0;
    double mx = 0.0;
    for (size_t i = 0; i < ctx->n; ++i) {
        nbad += bad[i] != 0;
        if (cond[i] > mx) mx = cond[i];
    }
    free(cond);
    c->mat[m] = out;
    c->bad[m] = bad;
    c->nbad[m] = nbad;
    c->max_cond[m] = mx;
    return out;
}

static const double *public_matrix(consph_op_ctx *ctx, ops_mat m, const unsigned char **bad)
{
    ops_call call = {0, 0};
    const double *a = ops_matrix(ctx, m, &call);
    if (bad) *bad = a ? ctx->cache->bad[m] : NULL;
    return a;
}

const double *consph_op_bonet(consph_op_ctx *ctx, const unsigned char **bad)
{
    return public_matrix(ctx, OPS_MAT_BONET, bad);
}
const double *consph_op_liu(consph_op_ctx *ctx, const unsigned char **bad)
{
    return public_matrix(ctx, OPS_MAT_LIU, bad);
}
const double *consph_op_fatehi(consph_op_ctx *ctx, const unsigned char **bad)
{
    return public_matrix(ctx, OPS_MAT_FATEHI, bad);
}
const double *consph_op_fatehi_c(consph_op_ctx *ctx, const unsigned char **bad)
{
    return public_matrix(ctx, OPS_MAT_FATEHI_C, bad);
}

/* ---- correction tensors written by a pass ---- */

static const struct {
    const char *name;
    ops_mat m;
} adoptable[] = {
    {"bonet", OPS_MAT_BONET},       {"liu", OPS_MAT_LIU},        {"fatehi", OPS_MAT_FATEHI},
    {"fatehi_c", OPS_MAT_FATEHI_C}, {"korzilius", OPS_MAT_KORZ},
};

void ops_cache_drop(struct consph_ops_cache *c, ops_mat m)
{
    free(c->mat[m]);
    free(c->bad[m]);
    c->mat[m] = NULL;
    c->bad[m] = NULL;
    c->nbad[m] = 0;
    c->max_cond[m] = 0.0;
}

int consph_op_ctx_adopt(consph_op_ctx *ctx, const char *name)
{
    int k = -1;
    for (size_t t = 0; t < sizeof adoptable / sizeof adoptable[0]; ++t)
        if (name && strcmp(name, adoptable[t].name) == 0) k = (int)t;
    if (k < 0)
        return consph_fail(CONSPH_EINVAL,
                           "adopt: unknown tensor '%s' (allowed: bonet, liu, fatehi, fatehi_c, "
                           "korzilius)",
                           name ? name : "(null)");
    const ops_mat m = adoptable[k].m;
    const size_t size = ops_mat_size(m, ctx->dim), n = ctx->n, cap = ctx->p->cap;
    const consph_field *f = consph_particles_find(ctx->p, name);
    if (!f || f->ncomp != (int)size)
        return consph_fail(CONSPH_EINVAL, "adopt: needs a particle field '%s' of %zu components",
                           name, size);
    char cname[CONSPH_FIELD_NAME_MAX + 8];
    snprintf(cname, sizeof cname, "%s_cond", name);
    const consph_field *fc = consph_particles_find(ctx->p, cname);
    if (fc && fc->ncomp != 1)
        return consph_fail(CONSPH_EINVAL, "adopt: field '%s' must have 1 component", cname);
    double *mat = consph_calloc(n * size, sizeof(double));
    unsigned char *bad = consph_calloc(n, 1);
    if (!mat || !bad) {
        free(mat);
        free(bad);
        return CONSPH_ENOMEM;
    }
    /* The field is component-major (stride cap), the cache one matrix per particle. */
    for (size_t c = 0; c < size; ++c)
        for (size_t i = 0; i < n; ++i) mat[i * size + c] = f->data[c * cap + i];
    size_t nbad = 0;
    double mx = 0.0;
    if (fc) {
        for (size_t i = 0; i < n; ++i) {
            const double cond = fc->data[i];
            bad[i] = !(cond > 0.0);
            nbad += bad[i];
            if (cond > mx) mx = cond;
        }
    }
    struct consph_ops_cache *cache = ctx->cache;
    ops_cache_drop(cache, m);
    /* Matrices built on B must be rebuilt on the adopted one. */
    if (m == OPS_MAT_BONET) {
        ops_cache_drop(cache, OPS_MAT_FATEHI);
        ops_cache_drop(cache, OPS_MAT_FATEHI_C);
        ops_cache_drop(cache, OPS_MAT_KORZ);
    }
    cache->mat[m] = mat;
    cache->bad[m] = bad;
    cache->nbad[m] = nbad;
    cache->max_cond[m] = mx;
    return CONSPH_OK;
}
