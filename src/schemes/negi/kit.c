/* The derivatives a scheme's right-hand side is made of, as fused passes over the solver's
 * system, with the operator terms of src/ops/terms.h (the code the static studies measure).
 *
 * Pass 1 (per particle, one traversal): the Bonet moment, inverted into B_i, then with the same
 * pair geometry ∇p (asym with bc, 001 Table 2), G = ∇u (the same form per component: f4), ∇·u
 * (div with bc, 001 eq. 11) and ∇q of a scalar. Pass 2: the Laplacians, which need G_j or ∇q_j
 * at the neighbours (coupled_bc: Σ ω_j (G_j - G_i)·B_i∇W_ij), or at i only (Fatehi_c, 001
 * eq. 13; Korzilius, 001 eqs. 14-15 with the fixes of docs/deviations.md), whose matrices are
 * summed and inverted in the same visit. A matrix that is singular or worse conditioned than
 * cond_max falls back to the identity, as the operators do. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"
#include "solver/solver_internal.h"

typedef struct kit_job {
    const kit_req *rq;
    int d;
    size_t cap;
    const double *vol, *p, *u, *q;
    double *bonet, *gradp, *gradu, *divu, *gradq, *lapu, *lapq;
    unsigned char *bonet_ok; /* B_i accepted, for Fatehi_c and Korzilius (else NULL) */
} kit_job;

static void visit_volume(void *vjob, const consph_nbhd *nb)
{
    double *vol = vjob, s = 0.0;
    for (size_t k = 0; k < nb->n; ++k) s += nb->w[k];
    vol[nb->i] = 1.0 / s;
}

int kit_volumes(consph_sys *s, size_t *pairs)
{
    double *vol = consph_particles_field(s->p, SF_VOL, 1);
    if (!vol) return CONSPH_ENOMEM;
    const consph_pass pass = {"volumes 1/sum W", CONSPH_PASS_W | CONSPH_PASS_NO_DX, visit_volume};
    return consph_pass_run_counted(s, &pass, vol, pairs);
}

/* B_i Σ ω_j (f_j - f_i) ∇W_ij */
static void corrected_gradient(int d, const consph_nbhd *nb, const double *vol, const double *f,
                               const double B[9], double out[3])
{
    const double zero[3] = {0.0, 0.0, 0.0};
    double sg[3], sw;
    term_grad_sums_any(d, TERM_GRAD_DIFF, 0, nb, vol, NULL, NULL, f, f[nb->i], sg, &sw);
    term_apply_rule(d, zero, B, sg, sw, out);
}

static void visit_first(void *vjob, const consph_nbhd *nb)
{
    const kit_job *job = vjob;
    const int d = job->d;
    const unsigned want = job->rq->want;
    const size_t i = nb->i, cap = job->cap;
    double moment[9], B[9], out[3];
    term_bonet_moment_any(d, nb, job->vol, moment);
    const int ok = consph_bonet_finalise(d, moment, job->rq->cond_max, B, NULL);
    if (job->bonet_ok) job->bonet_ok[i] = (unsigned char)ok;
    for (int e = 0; e < d * d; ++e) job->bonet[(size_t)e * cap + i] = B[e];
    if (want & KIT_GRADP) {
        corrected_gradient(d, nb, job->vol, job->p, B, out);
        for (int a = 0; a < d; ++a) job->gradp[a * cap + i] = out[a];
    }
    if (want & KIT_GRADU)
        for (int a = 0; a < d; ++a) {
            corrected_gradient(d, nb, job->vol, job->u + a * cap, B, out);
            for (int b = 0; b < d; ++b) job->gradu[(size_t)(a * d + b) * cap + i] = out[b];
        }
    if (want & KIT_DIVU) {
        const double zero[3] = {0.0, 0.0, 0.0};
        double ui[3];
        for (int a = 0; a < d; ++a) ui[a] = job->u[a * cap + i];
        job->divu[i] =
            term_corrected_div_any(d, CONSPH_CORR_BC, zero, B, nb, job->vol, job->u, cap, ui);
    }
    if (want & KIT_GRADQ) {
        corrected_gradient(d, nb, job->vol, job->q, B, out);
        for (int a = 0; a < d; ++a) job->gradq[a * cap + i] = out[a];
    }
}

/* coupled_bc of a scalar whose gradient field (d components, stride cap) is g. */
static double coupled(int d, const consph_nbhd *nb, const double *vol, const double *B,
                      const double *g, size_t cap)
{
    const double zero[3] = {0.0, 0.0, 0.0};
    double gi[3];
    for (int b = 0; b < d; ++b) gi[b] = g[b * cap + nb->i];
    return term_corrected_div_any(d, CONSPH_CORR_BC, zero, B, nb, vol, g, cap, gi);
}

static void set_identity(double *a, int n)
{
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) a[r * n + c] = r == c ? 1.0 : 0.0;
}

/* Fatehi_c's B̂ (001 eq. 13 = C.13); the identity where B_i fell back, as the operator's
 * (src/ops/ops_corr.c). */
static void fatehi_c_matrix(int d, const consph_nbhd *nb, const double *vol, const double B[9],
                            int bonet_ok, double cond_max, double Bh[9])
{
    double M[9] = {0}, cond;
    if (!bonet_ok) {
        set_identity(Bh, d);
        return;
    }
    term_fatehi_c_matrix(d, nb, vol, B, M);
    if (!ops_invert(d, M, Bh, cond_max, &cond)) set_identity(Bh, d);
}

/* Korzilius' Γ̃^{-1} (001 eq. 15 with the fixes of docs/deviations.md); the identity where B_i fell
 * back, as the operator's (src/ops/ops_corr.c). */
static void korzilius_matrix(int d, int P, const int *pl, const int *pk, const consph_nbhd *nb,
                             const double *vol, const double B[9], int bonet_ok, double cond_max,
                             double *Ainv)
{
    if (!bonet_ok) {
        set_identity(Ainv, P);
        return;
    }
    double cq[OPS_MAX_P];
    for (int p = 0; p < P; ++p) cq[p] = term_taylor_c(pl[p], pk[p]);
    double A[OPS_MAX_P * OPS_MAX_P] = {0}, Hx[OPS_MAX_P * 3] = {0}, Gz[3 * OPS_MAX_P] = {0};
    term_second_moment(d, P, pl, pk, cq, 1, nb, vol, A, Hx, Gz);
    term_korzilius_correct(d, P, Hx, Gz, B, A);
    double cond;
    if (!ops_invert(P, A, Ainv, cond_max, &cond)) set_identity(Ainv, P);
}

static void visit_second(void *vjob, const consph_nbhd *nb)
{
    const kit_job *job = vjob;
    const int d = job->d;
    const unsigned want = job->rq->want;
    const size_t i = nb->i, cap = job->cap;
    double B[9];
    for (int e = 0; e < d * d; ++e) B[e] = job->bonet[(size_t)e * cap + i];
    if (want & KIT_LAPU) {
        if (job->rq->lap == KIT_LAP_COUPLED) {
            for (int a = 0; a < d; ++a)
                job->lapu[a * cap + i] =
                    coupled(d, nb, job->vol, B, job->gradu + (size_t)a * d * cap, cap);
        } else if (job->rq->lap == KIT_LAP_FATEHI_C) {
            double Bh[9], G[3];
            fatehi_c_matrix(d, nb, job->vol, B, job->bonet_ok[i], job->rq->cond_max, Bh);
            for (int a = 0; a < d; ++a) {
                for (int b = 0; b < d; ++b) G[b] = job->gradu[(size_t)(a * d + b) * cap + i];
                job->lapu[a * cap + i] = term_fatehi_lap(d, nb, job->vol, job->u + a * cap, G, Bh);
            }
        } else {
            const int P = ops_npairs(d);
            int pl[OPS_MAX_P], pk[OPS_MAX_P];
            for (int p = 0; p < P; ++p) ops_pair_index(d, p, &pl[p], &pk[p]);
            double Ainv[OPS_MAX_P * OPS_MAX_P], G[3];
            korzilius_matrix(d, P, pl, pk, nb, job->vol, B, job->bonet_ok[i], job->rq->cond_max,
                             Ainv);
            for (int a = 0; a < d; ++a) {
                double rhs[OPS_MAX_P] = {0}, lap = 0.0;
                for (int b = 0; b < d; ++b) G[b] = job->gradu[(size_t)(a * d + b) * cap + i];
                term_hessian_rhs(d, P, pl, pk, nb, job->vol, job->u + a * cap, G, rhs);
                for (int r = 0; r < P; ++r)
                    if (pl[r] == pk[r])
                        for (int c = 0; c < P; ++c) lap += Ainv[r * P + c] * rhs[c];
                job->lapu[a * cap + i] = lap;
            }
        }
    }
    if (want & KIT_LAPQ) job->lapq[i] = coupled(d, nb, job->vol, B, job->gradq, cap);
}

int kit_derivatives(consph_sys *s, const kit_req *rq, size_t *pairs, int *passes)
{
    consph_particles *p = s->p;
    const int d = p->dim;
    unsigned want = rq->want;
    if (want & KIT_LAPU) want |= KIT_GRADU;
    if (want & KIT_LAPQ) want |= KIT_GRADQ;
    kit_req r = *rq;
    r.want = want;
    kit_job job = {.rq = &r, .d = d, .cap = p->cap};
    const consph_field *f = consph_particles_find(p, SF_VOL);
    if (!f) return consph_fail(CONSPH_EINVAL, "kit: the particles have no volumes");
    job.vol = f->data;
    job.bonet = consph_particles_field(p, SF_BONET, d * d);
    if (!job.bonet) return CONSPH_ENOMEM;
    if (want & (KIT_GRADP)) {
        const consph_field *fp = consph_particles_find(p, SF_P);
        job.p = fp ? fp->data : NULL;
        job.gradp = consph_particles_field(p, SF_GRADP, d);
        if (!job.p || !job.gradp) return consph_fail(CONSPH_EINVAL, "kit: no pressure field");
    }
    if (want & (KIT_GRADU | KIT_DIVU | KIT_LAPU)) {
        const consph_field *fu = consph_particles_find(p, SF_U);
        if (!fu || fu->ncomp != d) return consph_fail(CONSPH_EINVAL, "kit: no velocity field");
        job.u = fu->data;
    }
    if (want & KIT_GRADU) job.gradu = consph_particles_field(p, SF_GRADU, d * d);
    if (want & KIT_DIVU) job.divu = consph_particles_field(p, SF_DIVU, 1);
    if (want & KIT_GRADQ) {
        const consph_field *fq = rq->q ? consph_particles_find(p, rq->q) : NULL;
        if (!fq) return consph_fail(CONSPH_EINVAL, "kit: no scalar field '%s'", rq->q ? rq->q : "");
        job.q = fq->data;
        job.gradq = consph_particles_field(p, SF_GRADQ, d);
    }
    if (want & KIT_LAPU) job.lapu = consph_particles_field(p, SF_LAPU, d);
    if (want & KIT_LAPQ) job.lapq = consph_particles_field(p, SF_LAPQ, 1);
    if (((want & KIT_GRADU) && !job.gradu) || ((want & KIT_DIVU) && !job.divu) ||
        ((want & KIT_GRADQ) && !job.gradq) || ((want & KIT_LAPU) && !job.lapu) ||
        ((want & KIT_LAPQ) && !job.lapq))
        return CONSPH_ENOMEM;
    /* Fields may have been created above, which can move no data (fields are separate
     * allocations), so the pointers taken before stay valid. */
    if ((want & KIT_LAPU) && rq->lap != KIT_LAP_COUPLED) {
        job.bonet_ok = malloc(p->n ? p->n : 1);
        if (!job.bonet_ok) return CONSPH_ENOMEM;
    }
    const consph_pass first = {"kit: bonet, gradients, divergence", CONSPH_PASS_DW, visit_first};
    int st = consph_pass_run_counted(s, &first, &job, pairs);
    if (st == CONSPH_OK) ++*passes;
    if (st == CONSPH_OK && (want & (KIT_LAPU | KIT_LAPQ))) {
        unsigned need = CONSPH_PASS_DW;
        if ((want & KIT_LAPU) && rq->lap == KIT_LAP_KORZILIUS) need |= CONSPH_PASS_D2W;
        const consph_pass second = {"kit: laplacians", need, visit_second};
        st = consph_pass_run_counted(s, &second, &job, pairs);
        if (st == CONSPH_OK) ++*passes;
    }
    free(job.bonet_ok);
    return st;
}
