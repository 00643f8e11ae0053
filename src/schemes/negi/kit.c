/* The derivatives a scheme's right-hand side is made of, as fused passes over the solver's
 * system, with the operator terms of src/ops/terms.h (the code the static studies measure).
 *
 * Pass 1 (per particle, one run over the neighbours): the Bonet moment, inverted into B_i, and
 * the sums of ∇p (asym with bc, 001 Table 2), G = ∇u (the same form per component: f4), ∇·u
 * (div with bc, 001 eq. 11, as the trace of G) and ∇q of a scalar. Pass 2: the Laplacians, which
 * need G_j or ∇q_j at the neighbours (coupled_bc: Σ ω_j (G_j - G_i)·B_i∇W_ij), or at i only
 * (Fatehi_c, 001 eq. 13; Korzilius, 001 eqs. 14-15 with the fixes of docs/deviations.md), whose
 * matrices are summed and inverted in the same visit. A matrix that is singular or worse
 * conditioned than cond_max falls back to the identity, as the operators do. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"
#include "schemes/negi/kit_pair.h"
#include "solver/solver_internal.h"

typedef struct kit_job {
    const kit_req *rq;
    int d;
    size_t cap;
    const double *vol, *p, *u, *q;
    const double *rho; /* ϱ, for Cleary's Laplacian (else NULL) */
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

/* Pass 1 at one particle, for a dimension and a set of derivatives known at compile time: one
 * run over the neighbours sums the Bonet moment and the raw gradient sums Σ ω_j (f_j - f_i) ∇W_ij
 * of p, of every component of u and of q, with the arithmetic of term_moments and
 * term_grad_sums (src/ops/terms.h), so B_i, ∇p, G and ∇q are those of the per-quantity terms bit
 * for bit; B_i is applied after the run (term_apply_rule). ∇·u is the trace of G = B_i S_u, the
 * same sum as div_bc's Σ ω_j (u_j - u_i)·B_i∇W_ij (001 eq. 11) associated differently: it moves
 * at round-off against the per-pair form, the same for any thread count. */
TERM_INLINE void first_body(const kit_job *job, const consph_nbhd *nb, const int D,
                            const int with_p, const int with_u, const int with_q)
{
    const size_t i = nb->i, cap = job->cap;
    const double *vol = job->vol, *pf = job->p, *uf = job->u, *qf = job->q;
    const double *dx0 = nb->dx[0], *dx1 = D > 1 ? nb->dx[1] : NULL, *dx2 = D > 2 ? nb->dx[2] : NULL;
    const double *dwr = nb->dwr;
    /* sm is copied into mom after the run: mom's address goes to the inversion, and a sum whose
     * address is taken is stored to memory at every pair */
    double sm[9] = {0}, sp[3] = {0}, su[9] = {0}, sq[3] = {0}, ui[3] = {0};
    const double pi = with_p ? pf[i] : 0.0, qi = with_q ? qf[i] : 0.0;
    if (with_u)
        for (int a = 0; a < D; ++a) ui[a] = uf[a * cap + i];
    for (size_t k = 0; k < nb->n; ++k) {
        const size_t j = nb->j[k];
        double x[3], uj[3] = {0};
        x[0] = dx0[k];
        if (D > 1) x[1] = dx1[k];
        if (D > 2) x[2] = dx2[k];
        if (with_u)
            for (int a = 0; a < D; ++a) uj[a] = uf[a * cap + j];
        kit_first_pair(D, with_p, with_u, with_q, vol[j], dwr[k], x, with_p ? pf[j] : 0.0, pi, uj,
                       ui, with_q ? qf[j] : 0.0, qi, sm, sp, su, sq);
    }
    double mom[9], B[9], gp[3], G[9], div = 0.0, gq[3];
    for (int e = 0; e < D * D; ++e) mom[e] = sm[e];
    const int ok = kit_first_finish(D, with_p, with_u, with_q, mom, job->rq->cond_max, sp, su, sq,
                                    B, gp, G, &div, gq);
    if (job->bonet_ok) job->bonet_ok[i] = (unsigned char)ok;
    for (int e = 0; e < D * D; ++e) job->bonet[(size_t)e * cap + i] = B[e];
    if (with_p)
        for (int a = 0; a < D; ++a) job->gradp[a * cap + i] = gp[a];
    if (with_u) {
        if (job->gradu)
            for (int e = 0; e < D * D; ++e) job->gradu[(size_t)e * cap + i] = G[e];
        if (job->divu) job->divu[i] = div;
    }
    if (with_q)
        for (int a = 0; a < D; ++a) job->gradq[a * cap + i] = gq[a];
}

/* One visit function per (d, ∇p, ∇u or ∇·u, ∇q), chosen once per pass by kit_derivatives. */
#define FIRST_CLONE(D, P, U, Q)                                                                    \
    static void first_##D##P##U##Q(void *job, const consph_nbhd *nb)                               \
    {                                                                                              \
        first_body(job, nb, D, P, U, Q);                                                           \
    }
#define FIRST_CLONES_Q(D, P, U) FIRST_CLONE(D, P, U, 0) FIRST_CLONE(D, P, U, 1)
#define FIRST_CLONES_U(D, P) FIRST_CLONES_Q(D, P, 0) FIRST_CLONES_Q(D, P, 1)
#define FIRST_CLONES(D) FIRST_CLONES_U(D, 0) FIRST_CLONES_U(D, 1)
FIRST_CLONES(1)
FIRST_CLONES(2)
FIRST_CLONES(3)
#define FIRST_NAMES_Q(D, P, U)                                                                     \
    {                                                                                              \
        first_##D##P##U##0, first_##D##P##U##1                                                     \
    }
#define FIRST_NAMES_U(D, P)                                                                        \
    {                                                                                              \
        FIRST_NAMES_Q(D, P, 0), FIRST_NAMES_Q(D, P, 1)                                             \
    }
#define FIRST_NAMES(D)                                                                             \
    {                                                                                              \
        FIRST_NAMES_U(D, 0), FIRST_NAMES_U(D, 1)                                                   \
    }
static const consph_visit_fn first_visits[3][2][2][2] = {FIRST_NAMES(1), FIRST_NAMES(2),
                                                         FIRST_NAMES(3)};

/* coupled_bc (Σ ω_j (G_j - G_i)·B_i∇W_ij) of every component of u and of q in one run over the
 * neighbours, for a dimension known at compile time: B_i∇W_ij is formed once per pair and each
 * Laplacian summed with the arithmetic of term_corrected_div (src/ops/terms.h), so the results are
 * those of one term per quantity bit for bit. */
TERM_INLINE void coupled_body(const kit_job *job, const consph_nbhd *nb, const int D,
                              const int with_u, const int with_q)
{
    const size_t i = nb->i, cap = job->cap;
    const double *vol = job->vol, *gu = job->gradu, *gq = job->gradq;
    double B[9], Gi[9] = {0}, gqi[3] = {0}, acc[3] = {0}, accq = 0.0;
    for (int e = 0; e < D * D; ++e) B[e] = job->bonet[(size_t)e * cap + i];
    if (with_u)
        for (int e = 0; e < D * D; ++e) Gi[e] = gu[(size_t)e * cap + i];
    if (with_q)
        for (int b = 0; b < D; ++b) gqi[b] = gq[b * cap + i];
    for (size_t k = 0; k < nb->n; ++k) {
        const size_t j = nb->j[k];
        double x[3], Gj[9] = {0}, gqj[3] = {0};
        for (int b = 0; b < D; ++b) x[b] = nb->dx[b][k];
        if (with_u)
            for (int e = 0; e < D * D; ++e) Gj[e] = gu[(size_t)e * cap + j];
        if (with_q)
            for (int b = 0; b < D; ++b) gqj[b] = gq[b * cap + j];
        kit_coupled_pair(D, with_u, with_q, B, nb->dwr[k], x, vol[j], Gj, Gi, gqj, gqi, acc, &accq);
    }
    if (with_u)
        for (int a = 0; a < D; ++a) job->lapu[a * cap + i] = acc[a];
    if (with_q) job->lapq[i] = accq;
}

static void coupled_any(const kit_job *job, const consph_nbhd *nb, int with_u, int with_q)
{
#define COUPLED_D(D)                                                                               \
    do {                                                                                           \
        if (with_u && with_q)                                                                      \
            coupled_body(job, nb, D, 1, 1);                                                        \
        else if (with_u)                                                                           \
            coupled_body(job, nb, D, 1, 0);                                                        \
        else                                                                                       \
            coupled_body(job, nb, D, 0, 1);                                                        \
    } while (0)
    if (job->d == 1)
        COUPLED_D(1);
    else if (job->d == 2)
        COUPLED_D(2);
    else
        COUPLED_D(3);
#undef COUPLED_D
}

static void set_identity(double *a, int n)
{
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) a[r * n + c] = r == c ? 1.0 : 0.0;
}

/* Fatehi_c's B̂ (001 eq. 13 = C.13); the identity where B_i fell back, as the operator's
 * (src/ops/ops_corr.c). */
TERM_INLINE void fatehi_c_matrix(const int d, const consph_nbhd *nb, const double *vol,
                                 const double B[9], int bonet_ok, double cond_max, double Bh[9])
{
    double M[9] = {0}, cond;
    if (!bonet_ok) {
        set_identity(Bh, d);
        return;
    }
    term_fatehi_c_matrix(d, nb, vol, B, M);
    if (!ops_invert(d, M, Bh, cond_max, &cond)) set_identity(Bh, d);
}

/* Fatehi_c (001 eq. C.10 with B̂ of eq. 13) of every component of u in one run over the
 * neighbours: x_ij^T B̂ x_ij once per pair, each component with term_fatehi_lap's arithmetic
 * (src/ops/terms.h), so bit for bit that term per component. */
TERM_INLINE void fatehi_body(const kit_job *job, const consph_nbhd *nb, const int D,
                             const double Bh[9])
{
    const size_t i = nb->i, cap = job->cap;
    const double *vol = job->vol, *u = job->u;
    double G[9], ui[3], acc[3] = {0};
    for (int e = 0; e < D * D; ++e) G[e] = job->gradu[(size_t)e * cap + i];
    for (int a = 0; a < D; ++a) ui[a] = u[a * cap + i];
    for (size_t k = 0; k < nb->n; ++k) {
        const double r = nb->r[k];
        if (!(r > 0.0)) continue;
        const size_t j = nb->j[k];
        double x[3], uj[3];
        for (int a = 0; a < D; ++a) {
            x[a] = nb->dx[a][k];
            uj[a] = u[a * cap + j];
        }
        kit_fatehi_pair(D, Bh, r, nb->dwr[k], x, vol[j], G, ui, uj, acc);
    }
    for (int a = 0; a < D; ++a) job->lapu[a * cap + i] = acc[a];
}

/* Korzilius (001 eqs. 14-15) of every component of u in one run over the neighbours: the sums of
 * term_second_moment (A, Hx, Gz) and of term_hessian_rhs per component (src/ops/terms.h), with
 * their arithmetic and the kernel Hessian formed once per pair, so bit for bit those terms'; then
 * Γ̃^{-1} (001 eq. 15 with the fixes of docs/deviations.md), the identity where B_i fell back, as
 * the operator's (src/ops/ops_corr.c). d known at compile time. */
TERM_INLINE void korzilius_body(const kit_job *job, const consph_nbhd *nb, const int D,
                                const double B[9])
{
    enum { MP = OPS_MAX_P };
    const int P = D * (D + 1) / 2; /* ops_npairs */
    const size_t i = nb->i, cap = job->cap;
    const double *vol = job->vol, *u = job->u;
    int pl[MP], pk[MP];
    double cq[MP];
    for (int a = 0, q = 0; a < D; ++a)
        for (int b = a; b < D; ++b, ++q) {
            pl[q] = a; /* ops_pair_index's order */
            pk[q] = b;
            cq[q] = term_taylor_c(a, b);
        }
    double G[9], ui[3];
    for (int e = 0; e < D * D; ++e) G[e] = job->gradu[(size_t)e * cap + i];
    for (int a = 0; a < D; ++a) ui[a] = u[a * cap + i];
    double A[MP * MP] = {0}, Hx[MP * 3] = {0}, Gz[3 * MP] = {0}, rhs[3 * MP] = {0};
    for (size_t k = 0; k < nb->n; ++k) {
        const size_t j = nb->j[k];
        double x[3], uj[3];
        const double aee = term_pair_hess(D, nb, k, x);
        for (int a = 0; a < D; ++a) uj[a] = u[a * cap + j];
        kit_korzilius_pair(D, P, pl, pk, cq, vol[j], nb->dwr[k], aee, x, G, ui, uj, A, Hx, Gz, rhs);
    }
    double lap[3];
    kit_korzilius_finish(D, P, pl, pk, job->bonet_ok[i], Hx, Gz, B, A, rhs, job->rq->cond_max, lap);
    for (int a = 0; a < D; ++a) job->lapu[a * cap + i] = lap[a];
}

/* Cleary's Laplacian as 001's authors run EWCSPH (ewcsph.py, get_equations_ewcsph: their
 * ViscosityCleary, scheme_equation.py, after GradientCorrection, so with B_i∇W_ij): with
 * η = νϱ averaged harmonically, 2η_ij m_j/(ϱ_i ϱ_j) = 4ν m_j/(ϱ_i + ϱ_j), so
 *   ∇²u_i = Σ_j 4 m_j/(ϱ_i + ϱ_j) (x_ij·B_i∇W_ij)/r_ij² (u_i - u_j),
 * ν ρ_o applied by the rates: their m_j = ρ_o Δs² is ρ_o ω_j here (the kit's volumes), and
 * what is summed here is 4 ω_j/(ϱ_i + ϱ_j)...; pairs closer than 1e-14 are skipped, as theirs. */
TERM_INLINE void cleary_body(const kit_job *job, const consph_nbhd *nb, const int D,
                             const double B[9])
{
    const size_t i = nb->i, cap = job->cap;
    const double *vol = job->vol, *u = job->u, *rho = job->rho;
    double ui[3], acc[3] = {0};
    for (int a = 0; a < D; ++a) ui[a] = u[a * cap + i];
    for (size_t k = 0; k < nb->n; ++k) {
        const double r = nb->r[k];
        if (!(r > 1e-14)) continue;
        const size_t j = nb->j[k];
        double x[3], uj[3];
        for (int a = 0; a < D; ++a) {
            x[a] = nb->dx[a][k];
            uj[a] = u[a * cap + j];
        }
        kit_cleary_pair(D, B, r, nb->dwr[k], x, vol[j], rho[i], rho[j], ui, uj, acc);
    }
    for (int a = 0; a < D; ++a) job->lapu[a * cap + i] = acc[a];
}

/* ∇²u of Fatehi_c, Korzilius or Cleary at one particle, d known at compile time. */
TERM_INLINE void second_body(const kit_job *job, const consph_nbhd *nb, const int D)
{
    const size_t i = nb->i, cap = job->cap;
    double B[9];
    for (int e = 0; e < D * D; ++e) B[e] = job->bonet[(size_t)e * cap + i];
    if (job->rq->lap == KIT_LAP_FATEHI_C) {
        double Bh[9];
        fatehi_c_matrix(D, nb, job->vol, B, job->bonet_ok[i], job->rq->cond_max, Bh);
        fatehi_body(job, nb, D, Bh);
    } else if (job->rq->lap == KIT_LAP_CLEARY) {
        cleary_body(job, nb, D, B);
    } else {
        korzilius_body(job, nb, D, B);
    }
}

static void visit_second(void *vjob, const consph_nbhd *nb)
{
    const kit_job *job = vjob;
    const unsigned want = job->rq->want;
    if ((want & KIT_LAPU) && job->rq->lap == KIT_LAP_COUPLED) {
        coupled_any(job, nb, 1, (want & KIT_LAPQ) != 0);
        return;
    }
    if (want & KIT_LAPU) {
        if (job->d == 1)
            second_body(job, nb, 1);
        else if (job->d == 2)
            second_body(job, nb, 2);
        else
            second_body(job, nb, 3);
    }
    if (want & KIT_LAPQ) coupled_any(job, nb, 0, 1);
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
    if ((want & KIT_LAPU) && rq->lap == KIT_LAP_CLEARY) {
        const consph_field *fr = consph_particles_find(p, SF_RHOF);
        if (!fr) return consph_fail(CONSPH_EINVAL, "kit: no density field");
        job.rho = fr->data;
    }
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
    const consph_visit_fn visit_first =
        first_visits[d - 1][(want & KIT_GRADP) != 0][(want & (KIT_GRADU | KIT_DIVU)) != 0]
                    [(want & KIT_GRADQ) != 0];
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
