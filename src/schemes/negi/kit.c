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
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"
#include "pass/group.h"
#include "pass/lanes4.h"
#include "pass/nlist.h"
#include "schemes/negi/kit_pair.h"
#include "solver/solver_internal.h"

/* The hot visits' AVX-512 and AVX2 copies (LANE4_CLONES, src/pass/lanes4.h): pass 1's lanes'
 * sums and values exceed AVX2's 16 vector registers. */
#ifdef LANE4_CLONES
#define KIT_CLONES LANE4_CLONES
#else
#define KIT_CLONES
#endif

typedef struct kit_job {
    const kit_req *rq;
    int d;
    size_t cap;
    const double *vol, *p, *u, *q;
    const double *rho; /* ϱ, for Cleary's Laplacian (else NULL) */
    double *bonet, *gradp, *gradu, *divu, *gradq, *lapu, *lapq;
    unsigned char *bonet_ok; /* B_i accepted, for Fatehi_c and Korzilius (else NULL) */
    /* The values the group visits read at the neighbours, packed per particle so that a lane's
     * are one or two vector loads instead of one load per value (kit_pack1, kit_pack2): pass 1's
     * {ω, p, u, q} (stride s1, written where ω is), coupled_bc's {G, ∇q, ω} (stride s2, written by
     * pass 1; ω at pk2_vol where the stride leaves room, else read from vol; pk2_u and pk2_q the
     * Laplacians it serves; pk2_cols: 3D per particle, G by columns, each with ∇q's entry or 0
     * as its fourth, stride 12: coupled_pk_31). NULL where no group visit reads them. */
    double *pk1, *pk2;
    int s1, s2, pk2_vol, pk2_u, pk2_q, pk2_cols;
} kit_job;

/* Pass 1's pack: ω, then p, u and q where pass 1 sums them, to a multiple of four. */
static inline int kit_pack1_stride(const int D, const int with_p, const int with_u,
                                   const int with_q)
{
    return (1 + with_p + with_u * D + with_q + 3) & ~3;
}

static inline void kit_pack1(const kit_job *job, const size_t i, const double om)
{
    const size_t cap = job->cap;
    double *q = job->pk1 + i * (size_t)job->s1;
    int o = 0;
    q[o++] = om;
    if (job->p) q[o++] = job->p[i];
    if (job->u)
        for (int a = 0; a < job->d; ++a) q[o++] = job->u[(size_t)a * cap + i];
    if (job->q) q[o++] = job->q[i];
}

/* coupled_bc's pack: G (with_u), ∇q (with_q), then ω where the multiple of four leaves room
 * (*vol its offset, else -1). */
static inline int kit_pack2_stride(const int D, const int with_u, const int with_q, int *vol)
{
    const int n = with_u * D * D + with_q * D;
    *vol = n % 4 ? n : -1;
    return (n + 3) & ~3;
}

/* coupled_bc's pack at particle i: G (D x D, where with_u and the pack holds it), ∇q (D, where
 * with_q and the pack holds it), ω where the stride leaves room. */
static inline void kit_pack2(const kit_job *job, const size_t i, const int D, const int with_u,
                             const int with_q, const double *G, const double *gq)
{
    double *pk = job->pk2 + i * (size_t)job->s2;
    if (D == 3 && job->pk2_cols) {
        for (int b = 0; b < 3; ++b) {
            for (int a = 0; a < 3; ++a) pk[4 * b + a] = with_u && job->pk2_u ? G[a * 3 + b] : 0.0;
            pk[4 * b + 3] = with_q && job->pk2_q ? gq[b] : 0.0;
        }
        return;
    }
    int o = 0;
    if (with_u && job->pk2_u)
        for (int e = 0; e < D * D; ++e) pk[o++] = G[e];
    if (with_q && job->pk2_q)
        for (int a = 0; a < D; ++a) pk[o++] = gq[a];
    if (job->pk2_vol >= 0) pk[job->pk2_vol] = job->vol[i];
}

/* The volume visits' job: the volumes, and the kit's job whose pass-1 pack they fill (NULL: none).
 */
typedef struct kit_vol_job {
    double *vol;
    const kit_job *kit;
} kit_vol_job;

static void visit_volume(void *vjob, const consph_nbhd *nb)
{
    const kit_vol_job *vj = vjob;
    double s = 0.0;
    for (size_t k = 0; k < nb->n; ++k) s += nb->w[k];
    vj->vol[nb->i] = 1.0 / s;
    if (vj->kit && vj->kit->pk1) kit_pack1(vj->kit, nb->i, vj->vol[nb->i]);
}

/* Pass 1's results at particle i written into the job's fields (and coupled_bc's pack) */
TERM_INLINE void first_write(const kit_job *job, const size_t i, const int D, const int with_p,
                             const int with_u, const int with_q, const int ok, const double B[9],
                             const double gp[3], const double G[9], const double div,
                             const double gq[3])
{
    const size_t cap = job->cap;
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
    if (job->pk2) kit_pack2(job, i, D, with_u, with_q, G, gq);
}

/* Pass 1's finish at particle i from its sums, written into the job's fields. */
TERM_INLINE void first_store(const kit_job *job, const size_t i, const int D, const int with_p,
                             const int with_u, const int with_q, const double sm[9],
                             const double sp[3], const double su[9], const double sq[3])
{
    double mom[9], B[9], gp[3], G[9], div = 0.0, gq[3];
    for (int e = 0; e < D * D; ++e) mom[e] = sm[e];
    const int ok = kit_first_finish(D, with_p, with_u, with_q, mom, job->rq->cond_max, sp, su, sq,
                                    B, gp, G, &div, gq);
    first_write(job, i, D, with_p, with_u, with_q, ok, B, gp, G, div, gq);
}

/* first_store with B_i kept (kit_req.bonet_kept), ∇p and G asked for: B_i from its field instead
 * of the moment's inverse, no bonet_ok to write (pass 1 per particle from its pack, 2D and 3D) */
TERM_INLINE void first_store_kept(const kit_job *job, const size_t i, const int D, const int with_q,
                                  const double sp[3], const double su[9], const double sq[3])
{
    const size_t cap = job->cap;
    double B[9] = {0.0}, gp[3] = {0.0}, G[9] = {0.0}, div = 0.0, gq[3] = {0.0};
    for (int e = 0; e < D * D; ++e) B[e] = job->bonet[(size_t)e * cap + i];
    kit_first_apply(D, 1, 1, with_q, B, sp, su, sq, gp, G, &div, gq);
    first_write(job, i, D, 1, 1, with_q, 1, B, gp, G, div, gq);
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
    first_store(job, i, D, with_p, with_u, with_q, sm, sp, su, sq);
}

/* One visit function per (d, ∇p, ∇u or ∇·u, ∇q), chosen once per pass by kit_derivatives. */
#define FIRST_CLONE(D, P, U, Q)                                                                    \
    static void first_##D##P##U##Q(void *job, const consph_nbhd *nb)                               \
    {                                                                                              \
        first_body(job, nb, D, P, U, Q);                                                           \
    }
/* M(D, P, U, Q) for every (∇p, ∇u or ∇·u, ∇q) of dimension D; the table of the functions
 * PFX##D##P##U##Q that M defines, indexed [P][U][Q] */
#define FIRST_EACH_Q(M, D, P, U) M(D, P, U, 0) M(D, P, U, 1)
#define FIRST_EACH_U(M, D, P) FIRST_EACH_Q(M, D, P, 0) FIRST_EACH_Q(M, D, P, 1)
#define FIRST_EACH(M, D) FIRST_EACH_U(M, D, 0) FIRST_EACH_U(M, D, 1)
#define FIRST_TABLE(PFX, D)                                                                        \
    {                                                                                              \
        {{PFX##D##000, PFX##D##001}, {PFX##D##010, PFX##D##011}},                                  \
            {{PFX##D##100, PFX##D##101}, {PFX##D##110, PFX##D##111}},                              \
    }
FIRST_EACH(FIRST_CLONE, 1)
FIRST_EACH(FIRST_CLONE, 2)
FIRST_EACH(FIRST_CLONE, 3)
static const consph_visit_fn first_visits[3][2][2][2] = {
    FIRST_TABLE(first_, 1), FIRST_TABLE(first_, 2), FIRST_TABLE(first_, 3)};

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

#ifdef CONSPH_LANES4
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
/* What kit_fatehi_pair and kit_cleary_pair compute first, for entries k..k+3 of a neighbourhood
 * in the lanes: the separations x, x·M x with their operations (M = B̂_i or B_i) and ω_j. */
TERM_INLINE void kv_pair_head4(const int D, const double M[9], const consph_nbhd *nb,
                               const size_t k, const double *vol, lane4 x[3], lane4 *xmx, lane4 *om)
{
    lane4 s = {0.0, 0.0, 0.0, 0.0};
    for (int a = 0; a < D; ++a) x[a] = *(const lane4u *)(nb->dx[a] + k);
    for (int a = 0; a < D; ++a)
        for (int b = 0; b < D; ++b) {
            const double e = M[a * D + b];
            s += x[a] * (lane4){e, e, e, e} * x[b];
        }
    *xmx = s;
    const size_t *j = nb->j + k;
    *om = (lane4){vol[j[0]], vol[j[1]], vol[j[2]], vol[j[3]]};
}

/* kit_fatehi_pair's terms of entries k..k+3 at once, t[a][l] what entry k + l adds to component a,
 * each lane its pair's operations in kit_fatehi_pair's order (the same values bit for bit; a lane
 * at r = 0, which the caller skips, divides by zero unread): d divisions per pair bounded the
 * per-pair loop. */
TERM_INLINE void fatehi_terms4(const int D, const double Bh[9], const double G[9],
                               const double ui[3], const consph_nbhd *nb, const size_t k,
                               const double *vol, const double *u, const size_t cap, double t[3][4])
{
    lane4 x[3], xBx, om;
    kv_pair_head4(D, Bh, nb, k, vol, x, &xBx, &om);
    const size_t *j = nb->j + k;
    const lane4 r = *(const lane4u *)(nb->r + k), w1 = *(const lane4u *)(nb->dwr + k);
    const lane4 two = {2.0, 2.0, 2.0, 2.0}, c = two * om * w1, r2 = r * r;
    for (int a = 0; a < D; ++a) {
        lane4 xG = {0.0, 0.0, 0.0, 0.0};
        for (int b = 0; b < D; ++b) {
            const double g = G[a * D + b];
            xG += x[b] * (lane4){g, g, g, g};
        }
        const double *ua = u + (size_t)a * cap;
        const lane4 uj = {ua[j[0]], ua[j[1]], ua[j[2]], ua[j[3]]};
        const lane4 uia = {ui[a], ui[a], ui[a], ui[a]};
        const lane4 ta = c * ((uia - uj) - xG) * xBx / r2;
        for (int l = 0; l < 4; ++l) t[a][l] = ta[l];
    }
}

/* kit_cleary_pair's coefficient 4 ω_j/(ϱ_i + ϱ_j) W'/r (x·B_i x)/r² of entries k..k+3 of a
 * neighbourhood at once, each lane its pair's operations in kit_cleary_pair's order (the same
 * values bit for bit; a lane at r <= 1e-14, which the caller skips, divides by zero unread). Its
 * two divisions bounded the per-pair loop; a vector of four divides at about the price of one. */
TERM_INLINE void cleary_coeffs4(const int D, const double B[9], const consph_nbhd *nb,
                                const size_t k, const double *vol, const double *rho,
                                const double rhoi, double c[4])
{
    lane4 x[3], xBx, om;
    kv_pair_head4(D, B, nb, k, vol, x, &xBx, &om);
    const size_t *j = nb->j + k;
    const lane4 rj = {rho[j[0]], rho[j[1]], rho[j[2]], rho[j[3]]};
    const lane4 r = *(const lane4u *)(nb->r + k), w1 = *(const lane4u *)(nb->dwr + k);
    const lane4 four = {4.0, 4.0, 4.0, 4.0}, ri = {rhoi, rhoi, rhoi, rhoi};
    const lane4 cc = four * om / (ri + rj) * w1 * xBx / (r * r);
    for (int l = 0; l < 4; ++l) c[l] = cc[l];
}
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

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
    size_t k0 = 0;
#ifdef CONSPH_LANES4
    for (; k0 + 4 <= nb->n; k0 += 4) {
        double t[3][4];
        fatehi_terms4(D, Bh, G, ui, nb, k0, vol, u, cap, t);
        for (size_t e = 0; e < 4; ++e) {
            if (!(nb->r[k0 + e] > 0.0)) continue;
            for (int a = 0; a < D; ++a) acc[a] += t[a][e];
        }
    }
#endif
    for (size_t k = k0; k < nb->n; ++k) {
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

#ifdef CONSPH_LANES4
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
/* korzilius_body in 2D (P = 3) with its 27 sums in the lanes of nine vectors: A's rows, Hx and Gz
 * by columns, rhs by component; each lane's term is kit_korzilius_pair's with its operations in
 * their order ((ω H_a) ζ_b, ((ω W'/r) x_a) ζ_b, (0 + x_0 G_a0) + x_1 G_a1, ...), and each sum adds
 * its pairs in their order, so the sums, and the finish, are korzilius_body's bit for bit; the
 * kernel Hessian's radial factor of four entries at once (a division per pair). The scalar loop
 * ran about 100 flops per pair one at a time. */
TERM_INLINE void korzilius_body2(const kit_job *job, const consph_nbhd *nb, const double B[9])
{
    const size_t i = nb->i, cap = job->cap, n = nb->n;
    const double *vol = job->vol, *u = job->u, *gu = job->gradu;
    const double *dx0 = nb->dx[0], *dx1 = nb->dx[1], *dwr = nb->dwr;
    const lane4 zero = {0.0, 0.0, 0.0, 0.0};
    /* ops_pair_index's order (0,0), (0,1), (1,1) */
    const int pl[6] = {0, 0, 1, 0, 0, 0}, pk[6] = {0, 1, 1, 0, 0, 0};
    const lane4 cq = {term_taylor_c(0, 0), term_taylor_c(0, 1), term_taylor_c(1, 1), 0.0};
    const lane4 ga = {gu[i], gu[2 * cap + i], 0.0, 0.0},
                gb = {gu[cap + i], gu[3 * cap + i], 0.0, 0.0};
    const lane4 ui = {u[i], u[cap + i], 0.0, 0.0};
    lane4 a0 = zero, a1 = zero, a2 = zero, hx01 = zero, hx2 = zero, gz0 = zero, gz1 = zero;
    lane4 r0 = zero, r1 = zero;
    for (size_t k0 = 0; k0 < n; k0 += 4) {
        double aee[4];
        const size_t m = n - k0 < 4 ? n - k0 : 4;
        if (m == 4) {
            const lane4 r = *(const lane4u *)(nb->r + k0), w1 = *(const lane4u *)(dwr + k0);
            const lane4 w2 = *(const lane4u *)(nb->d2w + k0);
            /* term_hess_radial; a lane at r = 0 divides by zero, and the selection drops it */
            const lane4 h = LANE4_SEL((lane4i)(r > 0.0), (w2 - w1) / (r * r), zero);
            for (int l = 0; l < 4; ++l) aee[l] = h[l];
        } else {
            for (size_t l = 0; l < m; ++l)
                aee[l] = term_hess_radial(nb->r[k0 + l], dwr[k0 + l], nb->d2w[k0 + l]);
        }
        for (size_t l = 0; l < m; ++l) {
            const size_t k = k0 + l, j = nb->j[k];
            const double x0 = dx0[k], x1 = dx1[k], w1 = dwr[k], om = vol[j], e = aee[l];
            const lane4 xl = {x0, x0, x1, 0.0}, xk = {x0, x1, x1, 0.0};
            const lane4 zeta = cq * xl * xk;
            const lane4 h = (lane4){e, e, e, e} * xl * xk + (lane4){w1, 0.0, w1, 0.0};
            const lane4 oh = (lane4){om, om, om, om} * h;
            a0 += LANE4_SHUF(oh, oh, 0, 0, 0, 0) * zeta;
            a1 += LANE4_SHUF(oh, oh, 1, 1, 1, 1) * zeta;
            a2 += LANE4_SHUF(oh, oh, 2, 2, 2, 2) * zeta;
            const lane4 xx = {x0, x1, x0, x1};
            hx01 -= LANE4_SHUF(oh, oh, 0, 0, 1, 1) * xx;
            hx2 -= LANE4_SHUF(oh, oh, 2, 2, 2, 2) * xx;
            const double od = om * w1, g0 = od * x0, g1 = od * x1;
            gz0 += (lane4){g0, g0, g0, g0} * zeta;
            gz1 += (lane4){g1, g1, g1, g1} * zeta;
            /* x_ji·G = -x_ij·G */
            const lane4 xg = (zero + (lane4){x0, x0, x0, x0} * ga) + (lane4){x1, x1, x1, x1} * gb;
            const lane4 uj = {u[j], u[cap + j], 0.0, 0.0};
            const lane4 sa = (lane4){om, om, om, om} * ((uj - ui) + xg);
            r0 += LANE4_SHUF(sa, sa, 0, 0, 0, 0) * h;
            r1 += LANE4_SHUF(sa, sa, 1, 1, 1, 1) * h;
        }
    }
    /* the layouts of korzilius_body's sums (A[a P + b], Hx[a d + b], Gz[a P + b], rhs[a P + q]),
     * at the sizes kit_korzilius_finish declares */
    double A[36] = {a0[0], a0[1], a0[2], a1[0], a1[1], a1[2], a2[0], a2[1], a2[2]};
    const double Hx[18] = {hx01[0], hx01[1], hx01[2], hx01[3], hx2[0], hx2[1]};
    const double Gz[18] = {gz0[0], gz0[1], gz0[2], gz1[0], gz1[1], gz1[2]};
    const double rhs[18] = {r0[0], r0[1], r0[2], r1[0], r1[1], r1[2]};
    double lap[3];
    kit_korzilius_finish(2, 3, pl, pk, job->bonet_ok[i], Hx, Gz, B, A, rhs, job->rq->cond_max, lap);
    job->lapu[i] = lap[0];
    job->lapu[cap + i] = lap[1];
}
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

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
    size_t k0 = 0;
#ifdef CONSPH_LANES4
    for (; k0 + 4 <= nb->n; k0 += 4) {
        double c[4];
        cleary_coeffs4(D, B, nb, k0, vol, rho, rho[i], c);
        for (size_t e = 0; e < 4; ++e) {
            if (!(nb->r[k0 + e] > 1e-14)) continue;
            const size_t j = nb->j[k0 + e];
            for (int a = 0; a < D; ++a) acc[a] += c[e] * (ui[a] - u[a * cap + j]);
        }
    }
#endif
    for (size_t k = k0; k < nb->n; ++k) {
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
#ifdef CONSPH_LANES4
        if (D == 2) {
            korzilius_body2(job, nb, B);
            return;
        }
#endif
        korzilius_body(job, nb, D, B);
    }
}

KIT_CLONES static void visit_second(void *vjob, const consph_nbhd *nb)
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

/* ---- the volumes over groups of particles (src/pass/group.h) ----
 *
 * visit_volume's sum is one chain of dependent additions. The group visit runs PASS_GROUP
 * particles side by side, one per lane of a vector of four doubles, each lane adding its own
 * particle's W in its own neighbour order, so every volume is the per-particle visit's bit for
 * bit (tests/test_kit_group.c). A lane that has run out of neighbours reads its last one again
 * and keeps its sum (PASS_GROUP_UNPADDED: the neighbour list hands its cache over as it is). The
 * list runs it only on the blocks it has just filled (src/pass/nlist.c, nlist_group_run: four
 * lanes streaming four ranges from memory ran slower than one). GCC's and clang's vector
 * extensions; other compilers run the per-particle visit. */
int kit_group_visits = 1;
unsigned long kit_group_passes = 0;
/* Whether the volumes and derivatives run chained where the list allows (0: one after the
 * other, the same values; tests/test_kit_group.c compares the two), and how many chains ran. */
int kit_chain_passes = 1;
/* Passes 1 and coupled_bc that ran over groups, and coupled_bc passes that ran per particle
 * from pass 1's pack (coupled_pk_of) (for tests: that they did). */
unsigned long kit_group_firsts = 0, kit_group_coupled = 0, kit_coupled_packed = 0;
/* Passes 1 that ran per particle from their pack (first_pk_of), and those of them with B_i kept
 * (kit_req.bonet_kept) (for tests) */
unsigned long kit_first_packed = 0, kit_first_kept = 0;
/* Whether pass 1 applies a kept B_i where kit_req.bonet_kept allows (0: it computes B_i again,
 * the same values; tests compare the two) */
int kit_keep_bonet = 1;
/* coupled_bc's group visit reads four lanes' pairs side by side; the chained pass runs a few
 * neighbourhoods behind the fill, and once the state's pair cache is larger than about this many
 * bytes those pairs come from the last-level cache, where the per-particle visit's single
 * stream is prefetched better: measured on a 2-core AMD EPYC (1 MiB L2 per core), L-IPST-C's
 * coupled pass ran 13-20 % faster in groups at nx 20-40 and 5-25 % slower at nx 60-250 (again
 * 4 % slower at nx 250 with the per-particle visit reading G_j packed, coupled_pk_210, and the
 * chain recycling its pair arrays). Pass 1 does more arithmetic per pair and runs in groups at
 * every size. The same values either way;
 * tests set it to compare the group visit at any size. */
double kit_coupled_lanes_bytes = 3.0 * 1024 * 1024;
unsigned long kit_chains = 0;

static int coupled_lanes_pay(const consph_sys *s)
{
    consph_nlist_info info;
    consph_sys_nlist_info(s, &info);
    return !info.on || info.bytes * (double)s->p->n <= kit_coupled_lanes_bytes;
}

#ifdef CONSPH_LANES4
#define KIT_GROUPS 1
/* GCC builds a vector from scalars by inserting them into the destination's old value, and then
 * warns that the old value may be uninitialised (it is never read) */
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

/* The packed values (stride S) of the lanes' neighbours j: c[o] = {pk[j[0] S + o], ...} */
TERM_INLINE void kv_unpack(const double *pk, const int S, const size_t j[PASS_GROUP], lane4 c[12])
{
    const double *q[PASS_GROUP] = {pk + j[0] * (size_t)S, pk + j[1] * (size_t)S,
                                   pk + j[2] * (size_t)S, pk + j[3] * (size_t)S};
    for (int o = 0; o < S; o += 4) lane4_transpose(q, (size_t)o, c + o);
}

/* visit_volume over a group */
KIT_CLONES static void group_volume(void *vjob, const consph_nbhd *nb, int count)
{
    const kit_vol_job *vj = vjob;
    double *vol = vj->vol;
    size_t n[PASS_GROUP], kmin = nb[0].n, kmax = nb[0].n;
    for (int l = 0; l < PASS_GROUP; ++l) {
        n[l] = nb[l].n;
        if (n[l] < kmin) kmin = n[l];
        if (n[l] > kmax) kmax = n[l];
    }
    lane4 s = {0.0, 0.0, 0.0, 0.0};
    size_t k = 0;
    for (; k + 4 <= kmin; k += 4) {
        lane4 f[4];
        const double *q[PASS_GROUP] = {nb[0].w + k, nb[1].w + k, nb[2].w + k, nb[3].w + k};
        lane4_transpose(q, 0, f);
        s += f[0];
        s += f[1];
        s += f[2];
        s += f[3];
    }
    const lane4i nv = {(long long)n[0], (long long)n[1], (long long)n[2], (long long)n[3]};
    for (; k < kmax; ++k) {
        size_t e[PASS_GROUP];
        for (int l = 0; l < PASS_GROUP; ++l) e[l] = k < n[l] ? k : n[l] - 1;
        const lane4 w = {nb[0].w[e[0]], nb[1].w[e[1]], nb[2].w[e[2]], nb[3].w[e[3]]};
        const lane4i kv = {(long long)k, (long long)k, (long long)k, (long long)k};
        s = LANE4_SEL((lane4i)(kv < nv), s + w, s);
    }
    for (int l = 0; l < count; ++l) {
        vol[nb[l].i] = 1.0 / s[l];
        if (vj->kit && vj->kit->pk1) kit_pack1(vj->kit, nb[l].i, vol[nb[l].i]);
    }
}

/* ---- pass 1 and coupled_bc over groups ----
 *
 * first_body's and coupled_body's sums are, per particle, chains of dependent additions (the
 * moment's, each gradient's, each Laplacian's). The group visits below run four particles in the
 * lanes of a vector, kit_first_pair's and kit_coupled_pair's operations in their order (kit_pair.h)
 * per lane, each lane over its own neighbours in its own order; a lane that has run out reads its
 * last neighbour again and keeps its sums (KV_ACC's mask), so every result is the per-particle
 * visit's bit for bit (tests/test_kit_group.c). The values at the neighbours are loaded lane by
 * lane. */

/* acc op t in the lanes of m where masked (the tail past the shortest lane), else in all */
#define KV_ACC(acc, op, t) ((acc) = masked ? LANE4_SEL(m, (acc)op(t), (acc)) : (acc)op(t))
#define KV_AT(arr, j) ((lane4){(arr)[(j)[0]], (arr)[(j)[1]], (arr)[(j)[2]], (arr)[(j)[3]]})
#define KV_NB(nb, field, e)                                                                        \
    ((lane4){(nb)[0].field[(e)[0]], (nb)[1].field[(e)[1]], (nb)[2].field[(e)[2]],                  \
             (nb)[3].field[(e)[3]]})
#define KV_I(arr, nb)                                                                              \
    ((lane4){(arr)[(nb)[0].i], (arr)[(nb)[1].i], (arr)[(nb)[2].i], (arr)[(nb)[3].i]})

/* The group's shortest and longest lane; 0 where a lane has no neighbour at all (then the
 * per-particle visits run: a lane needs an entry to read again). */
TERM_INLINE int kv_extent(const consph_nbhd *nb, size_t *kmin, size_t *kmax, lane4i *nv)
{
    *kmin = *kmax = nb[0].n;
    for (int l = 0; l < PASS_GROUP; ++l) {
        if (nb[l].n == 0) return 0;
        if (nb[l].n < *kmin) *kmin = nb[l].n;
        if (nb[l].n > *kmax) *kmax = nb[l].n;
        (*nv)[l] = (long long)nb[l].n;
    }
    return 1;
}

/* kit_first_pair over the lanes: neighbours j, separations x, W'/r w1 */
TERM_INLINE void first_lanes(const kit_job *job, const size_t j[PASS_GROUP], const lane4 x[3],
                             const lane4 *w1p, const int masked, const lane4i *mp, const int D,
                             const int with_p, const int with_u, const int with_q, const lane4 *pip,
                             const lane4 ui[3], const lane4 *qip, lane4 sm[9], lane4 sp[3],
                             lane4 su[9], lane4 sq[3])
{
    const lane4 w1 = *w1p, pi = *pip, qi = *qip;
    const lane4i m = *mp;
    lane4 c[12];
    kv_unpack(job->pk1, kit_pack1_stride(D, with_p, with_u, with_q), j, c);
    const lane4 om = c[0];
    const lane4 g = om * w1;
    for (int a = 0; a < D; ++a)
        for (int b = 0; b < D; ++b) KV_ACC(sm[a * D + b], -, g * x[a] * x[b]);
    if (with_p) {
        const lane4 t = om * (c[1] - pi) * w1;
        for (int b = 0; b < D; ++b) KV_ACC(sp[b], +, t * x[b]);
    }
    if (with_u)
        for (int a = 0; a < D; ++a) {
            const lane4 t = om * (c[1 + with_p + a] - ui[a]) * w1;
            for (int b = 0; b < D; ++b) KV_ACC(su[a * D + b], +, t * x[b]);
        }
    if (with_q) {
        const lane4 t = om * (c[1 + with_p + with_u * D] - qi) * w1;
        for (int b = 0; b < D; ++b) KV_ACC(sq[b], +, t * x[b]);
    }
}

/* Entries k..k+3 of every lane (all within every lane): neighbours j[c], separations x[c] and
 * W'/r w1[c] of entry k + c, read four at a time per lane and transposed. */
TERM_INLINE void kv_entries4(const consph_nbhd *nb, size_t k, const int D, size_t j[4][PASS_GROUP],
                             lane4 x[4][3], lane4 w1[4])
{
    lane4 f[4];
    for (int a = 0; a < D; ++a) {
        const double *q[PASS_GROUP] = {nb[0].dx[a] + k, nb[1].dx[a] + k, nb[2].dx[a] + k,
                                       nb[3].dx[a] + k};
        lane4_transpose(q, 0, f);
        for (int c = 0; c < 4; ++c) x[c][a] = f[c];
    }
    const double *q[PASS_GROUP] = {nb[0].dwr + k, nb[1].dwr + k, nb[2].dwr + k, nb[3].dwr + k};
    lane4_transpose(q, 0, w1);
    for (int l = 0; l < PASS_GROUP; ++l)
        for (int c = 0; c < 4; ++c) j[c][l] = nb[l].j[k + (size_t)c];
}

/* Entry k of every lane where masked, clamped to the lane's last one: j, x, w1 and the lanes
 * that count it (m) */
TERM_INLINE void kv_entry1(const consph_nbhd *nb, size_t k, const int D, const lane4i *nv,
                           size_t j[PASS_GROUP], lane4 x[3], lane4 *w1, lane4i *m)
{
    size_t e[PASS_GROUP];
    for (int l = 0; l < PASS_GROUP; ++l) e[l] = k < nb[l].n ? k : nb[l].n - 1;
    for (int l = 0; l < PASS_GROUP; ++l) j[l] = nb[l].j[e[l]];
    for (int a = 0; a < D; ++a) x[a] = KV_NB(nb, dx[a], e);
    *w1 = KV_NB(nb, dwr, e);
    const lane4i kv = {(long long)k, (long long)k, (long long)k, (long long)k};
    *m = (lane4i)(kv < *nv);
}

/* the lanes where x is finite (isfinite: false for an infinity and for a NaN) */
#define KV_FINITE(x) ((lane4i)(LANE4_ABS(x) <= (lane4){DBL_MAX, DBL_MAX, DBL_MAX, DBL_MAX}))

/* ops_norm1 per lane (into *out: a function returning a vector has another ABI in the clone
 * without AVX) */
TERM_INLINE void kv_norm1(const int n, const lane4 *a, lane4 *out)
{
    lane4 best = {0.0, 0.0, 0.0, 0.0};
    for (int c = 0; c < n; ++c) {
        lane4 s = {0.0, 0.0, 0.0, 0.0};
        for (int r = 0; r < n; ++r) s += LANE4_ABS(a[r * n + c]);
        best = LANE4_SEL((lane4i)(s > best), s, best);
    }
    *out = best;
}

/* ops_invert_n of four lanes' n × n matrices at once (n = 2, 3): each lane runs ops_invert_n's
 * operations in their order, its branches (a pivot's row swap, a zero factor's skipped row) as
 * selections and its early returns as a lane marked failed whose arithmetic goes on unread, so
 * a lane's inverse is ops_invert_n's bit for bit where that succeeds. *okp: the lanes where it
 * succeeds (all bits set), as ops_invert_n's 1. As four scalar inversions after the group's pair
 * sums, pass 1's finish took about a quarter of the group visit's samples; side by side the
 * visit takes 12 % less time (docs/pass.md). */
TERM_INLINE void kv_invert(const int n, const lane4 *a, const double cond_max, lane4 *ainv,
                           lane4i *okp)
{
    const lane4 zero = {0.0, 0.0, 0.0, 0.0}, one = {1.0, 1.0, 1.0, 1.0};
    lane4i ok = {-1, -1, -1, -1};
    lane4 rs[3], cs[3], m[9], inv[9];
    for (int r = 0; r < n; ++r) {
        lane4 mx = zero;
        for (int c = 0; c < n; ++c) {
            const lane4 v = a[r * n + c], av = LANE4_ABS(v);
            ok &= KV_FINITE(v);
            mx = LANE4_SEL((lane4i)(av > mx), av, mx);
        }
        ok &= (lane4i)(mx != zero);
        rs[r] = one / mx;
    }
    for (int c = 0; c < n; ++c) {
        lane4 mx = zero;
        for (int r = 0; r < n; ++r) {
            const lane4 av = LANE4_ABS(rs[r] * a[r * n + c]);
            mx = LANE4_SEL((lane4i)(av > mx), av, mx);
        }
        ok &= (lane4i)(mx != zero);
        cs[c] = one / mx;
    }
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) {
            m[r * n + c] = rs[r] * a[r * n + c] * cs[c];
            inv[r * n + c] = r == c ? one : zero;
        }
    lane4 anorm, ninv;
    kv_norm1(n, m, &anorm);
    for (int k = 0; k < n; ++k) {
        lane4i piv = {k, k, k, k};
        lane4 pv = LANE4_ABS(m[k * n + k]);
        for (int r = k + 1; r < n; ++r) {
            const lane4 av = LANE4_ABS(m[r * n + k]);
            const lane4i more = (lane4i)(av > pv);
            piv = (more & (lane4i){r, r, r, r}) | (~more & piv);
            pv = LANE4_SEL(more, av, pv);
        }
        ok &= (lane4i)(pv > zero);
        for (int r = k + 1; r < n; ++r) {
            const lane4i sw = piv == (lane4i){r, r, r, r};
            for (int c = 0; c < n; ++c) {
                const lane4 mk = m[k * n + c], ik = inv[k * n + c];
                m[k * n + c] = LANE4_SEL(sw, m[r * n + c], mk);
                m[r * n + c] = LANE4_SEL(sw, mk, m[r * n + c]);
                inv[k * n + c] = LANE4_SEL(sw, inv[r * n + c], ik);
                inv[r * n + c] = LANE4_SEL(sw, ik, inv[r * n + c]);
            }
        }
        const lane4 d = one / m[k * n + k];
        for (int c = 0; c < n; ++c) {
            m[k * n + c] *= d;
            inv[k * n + c] *= d;
        }
        for (int r = 0; r < n; ++r) {
            if (r == k) continue;
            const lane4 f = m[r * n + k];
            const lane4i skip = (lane4i)(f == zero);
            for (int c = 0; c < n; ++c) {
                m[r * n + c] = LANE4_SEL(skip, m[r * n + c], m[r * n + c] - f * m[k * n + c]);
                inv[r * n + c] =
                    LANE4_SEL(skip, inv[r * n + c], inv[r * n + c] - f * inv[k * n + c]);
            }
        }
    }
    kv_norm1(n, inv, &ninv);
    const lane4 kappa = anorm * ninv;
    const lane4 cm = {cond_max, cond_max, cond_max, cond_max};
    ok &= KV_FINITE(kappa) & ~(lane4i)(kappa > cm);
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) ainv[r * n + c] = cs[r] * inv[r * n + c] * rs[c];
    *okp = ok;
}

/* For tests (tests/test_kit_invert.c): kv_invert of the four row-major n × n matrices a[l n² ..],
 * into ainv[l n² ..] and ok[l] (1 where it succeeded); the copy the processor runs (KIT_CLONES). */
KIT_CLONES int kit_invert_lanes(int n, const double *a, double cond_max, double *ainv, int ok[4])
{
    if (n < 2 || n > 3) return 0;
    lane4 A[9], R[9];
    lane4i okv;
    for (int e = 0; e < n * n; ++e)
        A[e] = (lane4){a[e], a[n * n + e], a[2 * n * n + e], a[3 * n * n + e]};
    kv_invert(n, A, cond_max, R, &okv);
    for (int l = 0; l < 4; ++l) {
        ok[l] = okv[l] != 0;
        for (int e = 0; e < n * n; ++e) ainv[l * n * n + e] = R[e][l];
    }
    return 1;
}

/* term_apply_rule with c = 0 per lane: out = (0 sw) + M sg, sw = 0 */
TERM_INLINE void kv_apply(const int D, const lane4 *M, const lane4 *sg, lane4 *out)
{
    for (int a = 0; a < D; ++a) {
        lane4 v = {0.0, 0.0, 0.0, 0.0};
        for (int b = 0; b < D; ++b) v += M[a * D + b] * sg[b];
        out[a] = v;
    }
}

/* first_store of a group's count lanes from their sums (kit_first_finish's arithmetic per lane,
 * the inversion kv_invert's), bit for bit the per-lane first_store */
TERM_INLINE void first_store_lanes(const kit_job *job, const consph_nbhd *nb, const int count,
                                   const int D, const int with_p, const int with_u,
                                   const int with_q, const lane4 *sm, const lane4 *sp,
                                   const lane4 *su, const lane4 *sq)
{
    const lane4 zero = {0.0, 0.0, 0.0, 0.0}, one = {1.0, 1.0, 1.0, 1.0};
    lane4 B[9], gp[3], G[9], div = zero, gq[3];
    lane4i ok;
    kv_invert(D, sm, job->rq->cond_max, B, &ok);
    for (int r = 0; r < D; ++r)
        for (int c = 0; c < D; ++c) B[r * D + c] = LANE4_SEL(ok, B[r * D + c], r == c ? one : zero);
    if (with_p) kv_apply(D, B, sp, gp);
    if (with_u)
        for (int a = 0; a < D; ++a) {
            kv_apply(D, B, su + a * D, G + a * D);
            div += G[a * D + a];
        }
    if (with_q) kv_apply(D, B, sq, gq);
    for (int l = 0; l < count; ++l) {
        double Bl[9], gpl[3] = {0.0}, Gl[9] = {0.0}, gql[3] = {0.0};
        for (int e = 0; e < D * D; ++e) Bl[e] = B[e][l];
        if (with_p)
            for (int a = 0; a < D; ++a) gpl[a] = gp[a][l];
        if (with_u)
            for (int e = 0; e < D * D; ++e) Gl[e] = G[e][l];
        if (with_q)
            for (int a = 0; a < D; ++a) gql[a] = gq[a][l];
        first_write(job, nb[l].i, D, with_p, with_u, with_q, ok[l] != 0, Bl, gpl, Gl, div[l], gql);
    }
}

/* first_body over a group */
TERM_INLINE void group_first_body(const kit_job *job, const consph_nbhd *nb, const int count,
                                  const int D, const int with_p, const int with_u, const int with_q)
{
    size_t kmin, kmax;
    lane4i nv = {0, 0, 0, 0}, m = nv;
    if (!kv_extent(nb, &kmin, &kmax, &nv)) {
        for (int l = 0; l < count; ++l) first_body(job, &nb[l], D, with_p, with_u, with_q);
        return;
    }
    const size_t cap = job->cap;
    const lane4 zero = {0.0, 0.0, 0.0, 0.0};
    const lane4 pi = with_p ? KV_I(job->p, nb) : zero, qi = with_q ? KV_I(job->q, nb) : zero;
    lane4 ui[3] = {zero, zero, zero};
    if (with_u)
        for (int a = 0; a < D; ++a) ui[a] = KV_I(job->u + (size_t)a * cap, nb);
    lane4 sm[9], sp[3], su[9], sq[3];
    for (int c = 0; c < 9; ++c) sm[c] = su[c] = zero;
    for (int c = 0; c < 3; ++c) sp[c] = sq[c] = zero;
    size_t k = 0;
    for (; k + 4 <= kmin; k += 4) {
        size_t j[4][PASS_GROUP];
        lane4 x[4][3], w1[4];
        kv_entries4(nb, k, D, j, x, w1);
        for (int c = 0; c < 4; ++c)
            first_lanes(job, j[c], x[c], &w1[c], 0, &m, D, with_p, with_u, with_q, &pi, ui, &qi, sm,
                        sp, su, sq);
    }
    for (; k < kmax; ++k) {
        size_t j[PASS_GROUP];
        lane4 x[3], w1;
        kv_entry1(nb, k, D, &nv, j, x, &w1, &m);
        first_lanes(job, j, x, &w1, 1, &m, D, with_p, with_u, with_q, &pi, ui, &qi, sm, sp, su, sq);
    }
    first_store_lanes(job, nb, count, D, with_p, with_u, with_q, sm, sp, su, sq);
}

#define GROUP_FIRST_CLONE(D, P, U, Q)                                                              \
    KIT_CLONES static void group_first_##D##P##U##Q(void *job, const consph_nbhd *nb, int count)   \
    {                                                                                              \
        group_first_body(job, nb, count, D, P, U, Q);                                              \
    }
FIRST_EACH(GROUP_FIRST_CLONE, 2)
FIRST_EACH(GROUP_FIRST_CLONE, 3)
/* 1D runs the per-particle visits */
static const pass_group_fn group_firsts[3][2][2][2] = {
    {{{NULL, NULL}, {NULL, NULL}}, {{NULL, NULL}, {NULL, NULL}}},
    FIRST_TABLE(group_first_, 2),
    FIRST_TABLE(group_first_, 3)};

/* kit_coupled_pair over the lanes: neighbours j, separations x, W'/r w1 */
TERM_INLINE void coupled_lanes(const kit_job *job, const size_t j[PASS_GROUP], const lane4 x[3],
                               const lane4 *w1p, const int masked, const lane4i *mp, const int D,
                               const int with_u, const int with_q, const lane4 B[9],
                               const lane4 Gi[9], const lane4 gqi[3], lane4 acc[3], lane4 *accq)
{
    const lane4 zero = {0.0, 0.0, 0.0, 0.0}, w1 = *w1p;
    const lane4i m = *mp;
    int vo;
    const int S = kit_pack2_stride(D, with_u, with_q, &vo);
    lane4 c[12];
    kv_unpack(job->pk2, S, j, c);
    const lane4 om = vo >= 0 ? c[vo] : KV_AT(job->vol, j);
    lane4 gr[3], g[3];
    for (int b = 0; b < D; ++b) gr[b] = w1 * x[b];
    for (int a = 0; a < D; ++a) {
        lane4 v = zero;
        for (int b = 0; b < D; ++b) v += B[a * D + b] * gr[b];
        g[a] = v;
    }
    if (with_u)
        for (int a = 0; a < D; ++a) {
            lane4 sa = zero;
            for (int b = 0; b < D; ++b) sa += (c[a * D + b] - Gi[a * D + b]) * g[b];
            KV_ACC(acc[a], +, om * sa);
        }
    if (with_q) {
        lane4 s = zero;
        for (int b = 0; b < D; ++b) s += (c[with_u * D * D + b] - gqi[b]) * g[b];
        KV_ACC(*accq, +, om * s);
    }
}

/* coupled_body over a group */
TERM_INLINE void group_coupled_body(const kit_job *job, const consph_nbhd *nb, const int count,
                                    const int D, const int with_u, const int with_q)
{
    size_t kmin, kmax;
    lane4i nv = {0, 0, 0, 0}, m = nv;
    if (!kv_extent(nb, &kmin, &kmax, &nv)) {
        for (int l = 0; l < count; ++l) coupled_body(job, &nb[l], D, with_u, with_q);
        return;
    }
    const size_t cap = job->cap;
    const lane4 zero = {0.0, 0.0, 0.0, 0.0};
    lane4 B[9], Gi[9], gqi[3], acc[3] = {zero, zero, zero}, accq = zero;
    for (int c = 0; c < D * D; ++c) {
        B[c] = KV_I(job->bonet + (size_t)c * cap, nb);
        Gi[c] = with_u ? KV_I(job->gradu + (size_t)c * cap, nb) : zero;
    }
    for (int b = 0; b < D; ++b) gqi[b] = with_q ? KV_I(job->gradq + (size_t)b * cap, nb) : zero;
    size_t k = 0;
    for (; k + 4 <= kmin; k += 4) {
        size_t j[4][PASS_GROUP];
        lane4 x[4][3], w1[4];
        kv_entries4(nb, k, D, j, x, w1);
        for (int c = 0; c < 4; ++c)
            coupled_lanes(job, j[c], x[c], &w1[c], 0, &m, D, with_u, with_q, B, Gi, gqi, acc,
                          &accq);
    }
    for (; k < kmax; ++k) {
        size_t j[PASS_GROUP];
        lane4 x[3], w1;
        kv_entry1(nb, k, D, &nv, j, x, &w1, &m);
        coupled_lanes(job, j, x, &w1, 1, &m, D, with_u, with_q, B, Gi, gqi, acc, &accq);
    }
    for (int l = 0; l < count; ++l) {
        const size_t i = nb[l].i;
        if (with_u)
            for (int a = 0; a < D; ++a) job->lapu[(size_t)a * cap + i] = acc[a][l];
        if (with_q) job->lapq[i] = accq[l];
    }
}

#define GROUP_COUPLED_CLONE(D, U, Q)                                                               \
    KIT_CLONES static void group_coupled_##D##U##Q(void *job, const consph_nbhd *nb, int count)    \
    {                                                                                              \
        group_coupled_body(job, nb, count, D, U, Q);                                               \
    }
GROUP_COUPLED_CLONE(2, 1, 0)
GROUP_COUPLED_CLONE(2, 1, 1)
GROUP_COUPLED_CLONE(2, 0, 1)
GROUP_COUPLED_CLONE(3, 1, 0)
GROUP_COUPLED_CLONE(3, 1, 1)
GROUP_COUPLED_CLONE(3, 0, 1)

/* coupled_body of ∇²u alone in 2D at one particle (the visit of the state's pairs once they no
 * longer fit the processor's caches, coupled_lanes_pay), over the four entries of G at once: G_j
 * one vector load from pass 1's pack (pk2) instead of four loads from four fields. Per pair the
 * lanes hold (a, b) = (0, 0), (0, 1), (1, 0), (1, 1); adding z = {0, -0, 0, -0} is the scalar sums'
 * 0.0 + (first term) in lanes b = 0 and leaves lanes b = 1 as they are (x + -0 = x for every x), so
 * each sum of two lanes is kit_coupled_pair's (0.0 + t_a0) + t_a1, and acc's lanes 0 and 1 (2 and 3
 * hold the same values again) its sums, bit for bit. */
KIT_CLONES static void coupled_pk_210(void *vjob, const consph_nbhd *nb)
{
    const kit_job *job = vjob;
    const size_t i = nb->i, cap = job->cap;
    const double *vol = job->vol, *pk = job->pk2, *dx0 = nb->dx[0], *dx1 = nb->dx[1];
    const double *dwr = nb->dwr, *bo = job->bonet, *gu = job->gradu;
    const lane4 B = {bo[i], bo[cap + i], bo[2 * cap + i], bo[3 * cap + i]};
    const lane4 Gi = {gu[i], gu[cap + i], gu[2 * cap + i], gu[3 * cap + i]};
    const lane4 z = {0.0, -0.0, 0.0, -0.0};
    lane4 acc = {0.0, 0.0, 0.0, 0.0};
    for (size_t k = 0; k < nb->n; ++k) {
        const size_t j = nb->j[k];
        const double w1 = dwr[k];
        const lane4 gr = (lane4){w1, w1, w1, w1} * (lane4){dx0[k], dx1[k], dx0[k], dx1[k]};
        const lane4 t = B * gr + z;
        const lane4 g = LANE4_SHUF(t, t, 0, 2, 0, 2) + LANE4_SHUF(t, t, 1, 3, 1, 3);
        /* stride 4: the pack holds G alone (kit_pack2_stride) */
        const lane4 d = (*(const lane4u *)(pk + 4 * j) - Gi) * g + z;
        const double om = vol[j];
        acc +=
            (lane4){om, om, om, om} * (LANE4_SHUF(d, d, 0, 2, 0, 2) + LANE4_SHUF(d, d, 1, 3, 1, 3));
    }
    job->lapu[i] = acc[0];
    job->lapu[cap + i] = acc[1];
}

/* coupled_pk_210 with ∇²q beside ∇²u (2D: TV-C, PE-IPST-C, E-C), from the pack {G, ∇q, ω, -}
 * (stride 8, kit_pack2_stride): the second vector load brings ∇q_j and ω_j, so no field is read at
 * j. ∇q's two products take lanes 0 and 1 of e as G's rows take d's, and the lanes' sums are
 * gathered side by side, S = {Σ_b row 0, Σ_b row 1, Σ_b ∇q, -}, so acc's lane 2 is
 * kit_coupled_pair's accq bit for bit (lane 3, from the pack's unused slot, is never stored). */
KIT_CLONES static void coupled_pk_211(void *vjob, const consph_nbhd *nb)
{
    const kit_job *job = vjob;
    const size_t i = nb->i, cap = job->cap;
    const double *pk = job->pk2, *dx0 = nb->dx[0], *dx1 = nb->dx[1];
    const double *dwr = nb->dwr, *bo = job->bonet, *gu = job->gradu, *gq = job->gradq;
    const lane4 B = {bo[i], bo[cap + i], bo[2 * cap + i], bo[3 * cap + i]};
    const lane4 Gi = {gu[i], gu[cap + i], gu[2 * cap + i], gu[3 * cap + i]};
    const lane4 qi = {gq[i], gq[cap + i], 0.0, 0.0};
    const lane4 z = {0.0, -0.0, 0.0, -0.0};
    lane4 acc = {0.0, 0.0, 0.0, 0.0};
    for (size_t k = 0; k < nb->n; ++k) {
        const size_t j = nb->j[k];
        const double w1 = dwr[k];
        const lane4 gr = (lane4){w1, w1, w1, w1} * (lane4){dx0[k], dx1[k], dx0[k], dx1[k]};
        const lane4 t = B * gr + z;
        const lane4 g = LANE4_SHUF(t, t, 0, 2, 0, 2) + LANE4_SHUF(t, t, 1, 3, 1, 3);
        const lane4 c = *(const lane4u *)(pk + 8 * j + 4);
        const lane4 d = (*(const lane4u *)(pk + 8 * j) - Gi) * g + z;
        const lane4 e = (c - qi) * g + z;
        const double om = c[2];
        acc +=
            (lane4){om, om, om, om} * (LANE4_SHUF(d, e, 0, 2, 4, 4) + LANE4_SHUF(d, e, 1, 3, 5, 5));
    }
    job->lapu[i] = acc[0];
    job->lapu[cap + i] = acc[1];
    job->lapq[i] = acc[2];
}

/* visit_second over groups where it runs coupled_bc only (∇²u coupled, or ∇²q alone); NULL for
 * the other Laplacians and 1D (the per-particle visits) */
static pass_group_fn group_second_of(const kit_req *rq, int d)
{
    const int lapu = (rq->want & KIT_LAPU) != 0, lapq = (rq->want & KIT_LAPQ) != 0;
    if (d < 2 || (lapu && rq->lap != KIT_LAP_COUPLED) || !(lapu || lapq)) return NULL;
    if (d == 2) return lapu ? (lapq ? group_coupled_211 : group_coupled_210) : group_coupled_201;
    return lapu ? (lapq ? group_coupled_311 : group_coupled_310) : group_coupled_301;
}

static pass_group_fn group_first_of(int d, int with_p, int with_u, int with_q)
{
    return group_firsts[d - 1][with_p][with_u][with_q];
}

/* first_body in 2D with ∇p and G (and ∇q: Q) at one particle, for a pass 1 that runs per particle
 * (E-C's and EWCSPH's, over the pair cache filled once for the run): the values at j from pass
 * 1's pack, {ω, p, u_0, u_1} (and q next), in one vector load, and each pair's terms four at a
 * time. Lanes {1, p_j - p_i, u_j - u_i} times ω_j then W'/r give {g, t_p, t_u0, t_u1} of
 * kit_first_pair (ω_j 1 = ω_j exactly); the moment's terms are (g x_a) x_b, the gradients'
 * t x_b, each lane's sum runs over the pairs in their order, so the sums, and first_store's
 * results, are first_body's bit for bit (lanes 0 and 1 of sp sum g x, never read). */
TERM_INLINE void first_pk_2(const kit_job *job, const consph_nbhd *nb, const int Q, const int KEPT)
{
    const size_t i = nb->i, cap = job->cap;
    const int S = job->s1;
    const double *pk = job->pk1, *dx0 = nb->dx[0], *dx1 = nb->dx[1], *dwr = nb->dwr;
    const lane4 zero = {0.0, 0.0, 0.0, 0.0}, one = {1.0, 1.0, 1.0, 1.0};
    const lane4 fi = {0.0, job->p[i], job->u[i], job->u[cap + i]};
    const double qi = Q ? job->q[i] : 0.0;
    lane4 SM = zero, SP = zero, SU = zero, SQ = zero;
    for (size_t k = 0; k < nb->n; ++k) {
        const double *v = pk + nb->j[k] * (size_t)S;
        const lane4 f = *(const lane4u *)v;
        const double om = f[0], w1 = dwr[k];
        const lane4 x = {dx0[k], dx1[k], dx0[k], dx1[k]};
        const lane4 d = LANE4_SHUF(one, f - fi, 0, 5, 6, 7);
        const lane4 t = (lane4){om, om, om, om} * d * (lane4){w1, w1, w1, w1};
        const lane4 a = LANE4_SHUF(t, t, 0, 0, 1, 1) * x;
        if (!KEPT) SM = SM - LANE4_SHUF(a, a, 0, 0, 1, 1) * x;
        SP = SP + a;
        SU = SU + LANE4_SHUF(t, t, 2, 2, 3, 3) * x;
        if (Q) {
            const double tq = om * (v[4] - qi) * w1;
            SQ = SQ + (lane4){tq, tq, tq, tq} * x;
        }
    }
    const double sm[9] = {SM[0], SM[1], SM[2], SM[3]}, sp[3] = {SP[2], SP[3], 0.0};
    const double su[9] = {SU[0], SU[1], SU[2], SU[3]}, sq[3] = {SQ[0], SQ[1], 0.0};
    if (KEPT)
        first_store_kept(job, i, 2, Q, sp, su, sq);
    else
        first_store(job, i, 2, 1, 1, Q, sm, sp, su, sq);
}

/* first_body in 3D with ∇p and G (and ∇q: Q) at one particle from pass 1's pack {ω, p, u_0, u_1,
 * u_2, q}: lanes {1, p_j - p_i, u_j - u_i} times ω_j then W'/r are {g, t_p, t_u0, t_u1} of
 * kit_first_pair (ω_j 1 = ω_j exactly), and t_u2, t_q the same in a second vector; each sum over
 * b (the moment's rows from g x_a, the gradients' from t) takes lanes b = 0, 1, 2 of one vector,
 * t x with x = {x_0, x_1, x_2, 0}, so every sum, and the finish, is first_body's bit for bit.
 * Two vector loads per pair from one particle's row instead of six loads from six fields. KEPT:
 * B_i kept (kit_req.bonet_kept), the moment not summed. */
TERM_INLINE void first_pk_3(const kit_job *job, const consph_nbhd *nb, const int Q, const int KEPT)
{
    const size_t i = nb->i, cap = job->cap;
    const int S = job->s1;
    const double *pk = job->pk1, *dx0 = nb->dx[0], *dx1 = nb->dx[1], *dx2 = nb->dx[2];
    const double *dwr = nb->dwr;
    const lane4 zero = {0.0, 0.0, 0.0, 0.0}, one = {1.0, 1.0, 1.0, 1.0};
    const double *u = job->u;
    const lane4 fi = {0.0, job->p[i], u[i], u[cap + i]};
    const double u2i = u[2 * cap + i], qi = Q ? job->q[i] : 0.0;
    lane4 M0 = zero, M1 = zero, M2 = zero, SP = zero, U0 = zero, U1 = zero, U2 = zero, SQ = zero;
    for (size_t k = 0; k < nb->n; ++k) {
        const double *v = pk + nb->j[k] * (size_t)S;
        const lane4 f = *(const lane4u *)v;
        const double om = f[0], w1 = dwr[k], x0 = dx0[k], x1 = dx1[k], x2 = dx2[k];
        const lane4 x = {x0, x1, x2, 0.0};
        const lane4 oo = {om, om, om, om}, ww = {w1, w1, w1, w1};
        const lane4 t = oo * LANE4_SHUF(one, f - fi, 0, 5, 6, 7) * ww;
        const lane4 t2 = oo * (lane4){v[4] - u2i, Q ? v[5] - qi : 0.0, 0.0, 0.0} * ww;
        if (!KEPT) {
            const double g = t[0];
            M0 = M0 - (lane4){g * x0, g * x0, g * x0, g * x0} * x;
            M1 = M1 - (lane4){g * x1, g * x1, g * x1, g * x1} * x;
            M2 = M2 - (lane4){g * x2, g * x2, g * x2, g * x2} * x;
        }
        SP = SP + LANE4_SHUF(t, t, 1, 1, 1, 1) * x;
        U0 = U0 + LANE4_SHUF(t, t, 2, 2, 2, 2) * x;
        U1 = U1 + LANE4_SHUF(t, t, 3, 3, 3, 3) * x;
        U2 = U2 + LANE4_SHUF(t2, t2, 0, 0, 0, 0) * x;
        if (Q) SQ = SQ + LANE4_SHUF(t2, t2, 1, 1, 1, 1) * x;
    }
    const double sp[3] = {SP[0], SP[1], SP[2]}, sq[3] = {SQ[0], SQ[1], SQ[2]};
    const double su[9] = {U0[0], U0[1], U0[2], U1[0], U1[1], U1[2], U2[0], U2[1], U2[2]};
    const double sm[9] = {M0[0], M0[1], M0[2], M1[0], M1[1], M1[2], M2[0], M2[1], M2[2]};
    if (KEPT)
        first_store_kept(job, i, 3, Q, sp, su, sq);
    else
        first_store(job, i, 3, 1, 1, Q, sm, sp, su, sq);
}

/* The visits first_pk_D11Q (B_i computed) and first_pk_kept_D11Q (B_i kept) of first_pk_D. */
#define FIRST_PK_VISITS(D, Q)                                                                      \
    KIT_CLONES static void first_pk_##D##11##Q(void *job, const consph_nbhd *nb)                   \
    {                                                                                              \
        first_pk_##D(job, nb, Q, 0);                                                               \
    }                                                                                              \
    KIT_CLONES static void first_pk_kept_##D##11##Q(void *job, const consph_nbhd *nb)              \
    {                                                                                              \
        first_pk_##D(job, nb, Q, 1);                                                               \
    }
FIRST_PK_VISITS(2, 0)
FIRST_PK_VISITS(2, 1)
FIRST_PK_VISITS(3, 0)
FIRST_PK_VISITS(3, 1)
#undef FIRST_PK_VISITS

/* pass 1 per particle from its pack: 2D and 3D with ∇p and G (or ∇·u), with or without ∇q; kept:
 * with B_i kept (kit_req.bonet_kept), the moment neither summed nor inverted */
static consph_visit_fn first_pk_of(int d, int with_p, int with_u, int with_q, int kept)
{
    if (d < 2 || !with_p || !with_u) return NULL;
    if (d == 3)
        return kept ? (with_q ? first_pk_kept_3111 : first_pk_kept_3110)
                    : (with_q ? first_pk_3111 : first_pk_3110);
    if (kept) return with_q ? first_pk_kept_2111 : first_pk_kept_2110;
    return with_q ? first_pk_2111 : first_pk_2110;
}

/* coupled_body of ∇²u (and ∇²q: Q) in 3D at one particle from the pack by columns (pk2_cols):
 * lane a of the vectors is row a of kit_coupled_pair's sums and lane 3 the sum of ∇²q, each with
 * its operations in their order: g = ((0 + B_a0 w x_0) + B_a1 w x_1) + B_a2 w x_2 by B's columns,
 * then ((0 + d_a0 g_0) + d_a1 g_1) + d_a2 g_2 with d = G_j - G_i by columns (∇q_j - ∇q_i in lane
 * 3), times ω_j, added to each sum in the pairs' order: bit for bit coupled_body's. G_j and ∇q_j
 * are three vector loads from one particle's 96 bytes instead of twelve loads from twelve fields
 * (the per-particle visit where the state's pairs outgrow the caches, coupled_lanes_pay). */
TERM_INLINE void coupled_pk_3(const kit_job *job, const consph_nbhd *nb, const int Q)
{
    const size_t i = nb->i, cap = job->cap;
    const double *vol = job->vol, *pk = job->pk2, *bo = job->bonet, *gu = job->gradu;
    const double *dx0 = nb->dx[0], *dx1 = nb->dx[1], *dx2 = nb->dx[2], *dwr = nb->dwr;
    const lane4 zero = {0.0, 0.0, 0.0, 0.0};
    lane4 Bc[3], Gc[3];
    for (int b = 0; b < 3; ++b) {
        Bc[b] = (lane4){bo[(size_t)b * cap + i], bo[(size_t)(3 + b) * cap + i],
                        bo[(size_t)(6 + b) * cap + i], 0.0};
        Gc[b] = (lane4){gu[(size_t)b * cap + i], gu[(size_t)(3 + b) * cap + i],
                        gu[(size_t)(6 + b) * cap + i], Q ? job->gradq[(size_t)b * cap + i] : 0.0};
    }
    lane4 acc = zero;
    for (size_t k = 0; k < nb->n; ++k) {
        const size_t j = nb->j[k];
        const double w1 = dwr[k], r0 = w1 * dx0[k], r1 = w1 * dx1[k], r2 = w1 * dx2[k];
        const lane4 g =
            ((zero + Bc[0] * (lane4){r0, r0, r0, r0}) + Bc[1] * (lane4){r1, r1, r1, r1}) +
            Bc[2] * (lane4){r2, r2, r2, r2};
        const double *q = pk + 12 * j;
        const lane4 d0 = *(const lane4u *)q - Gc[0], d1 = *(const lane4u *)(q + 4) - Gc[1];
        const lane4 d2 = *(const lane4u *)(q + 8) - Gc[2];
        const lane4 g0 = LANE4_SHUF(g, g, 0, 0, 0, 0), g1 = LANE4_SHUF(g, g, 1, 1, 1, 1);
        const lane4 g2 = LANE4_SHUF(g, g, 2, 2, 2, 2);
        const lane4 sa = ((zero + d0 * g0) + d1 * g1) + d2 * g2;
        const double om = vol[j];
        acc += (lane4){om, om, om, om} * sa;
    }
    job->lapu[i] = acc[0];
    job->lapu[cap + i] = acc[1];
    job->lapu[2 * cap + i] = acc[2];
    if (Q) job->lapq[i] = acc[3];
}

KIT_CLONES static void coupled_pk_310(void *vjob, const consph_nbhd *nb)
{
    coupled_pk_3(vjob, nb, 0);
}
KIT_CLONES static void coupled_pk_311(void *vjob, const consph_nbhd *nb)
{
    coupled_pk_3(vjob, nb, 1);
}

/* coupled_bc's ∇²u, alone or with ∇²q, per particle from the pack (2D and 3D) */
static consph_visit_fn coupled_pk_of(int d, int with_q)
{
    if (d == 3) return with_q ? coupled_pk_311 : coupled_pk_310;
    return d == 2 ? (with_q ? coupled_pk_211 : coupled_pk_210) : NULL;
}
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#else
int kit_invert_lanes(int n, const double *a, double cond_max, double *ainv, int ok[4])
{
    (void)n, (void)a, (void)cond_max, (void)ainv, (void)ok;
    return 0;
}
#define group_volume NULL
#define group_first_of(d, with_p, with_u, with_q)                                                  \
    ((void)(d), (void)(with_p), (void)(with_u), (void)(with_q), (pass_group_fn)NULL)
#define group_second_of(rq, d) ((void)(rq), (void)(d), (pass_group_fn)NULL)
#define coupled_pk_of(d, with_q) ((void)(d), (void)(with_q), (consph_visit_fn)NULL)
#define first_pk_of(d, with_p, with_u, with_q, kept)                                               \
    ((void)(d), (void)(with_p), (void)(with_u), (void)(with_q), (void)(kept), (consph_visit_fn)NULL)
#endif

/* A pass with its group visit where the system and the compiler allow one, else per particle;
 * *grouped (may be NULL): whether the group visit ran it. */
static int kit_run_grouped(consph_sys *s, const consph_pass *pass, pass_group_fn group, void *job,
                           size_t *pairs, int *grouped)
{
    if (grouped) *grouped = 0;
    if (kit_group_visits && group) {
        const int st =
            pass_run_groups(s, pass->name, pass->need | PASS_GROUP_UNPADDED, group, job, pairs);
        if (st != PASS_GROUP_UNSERVED) {
            if (st == CONSPH_OK) {
                __atomic_fetch_add(&kit_group_passes, 1, __ATOMIC_RELAXED);
                if (grouped) *grouped = 1;
            }
            return st;
        }
    }
    return consph_pass_run_counted(s, pass, job, pairs);
}

static int kit_run(consph_sys *s, const consph_pass *pass, pass_group_fn group, void *job,
                   size_t *pairs)
{
    return kit_run_grouped(s, pass, group, job, pairs, NULL);
}

static const consph_pass volume_pass = {"volumes 1/sum W", CONSPH_PASS_W | CONSPH_PASS_NO_DX,
                                        visit_volume};

/* The volumes read W alone at the neighbours: the separations of the current search, whose
 * halo positions the refresh at consph_sys_update brought. */
static const consph_sys_reads volume_reads = {0, 0, {NULL}, {0}};
static const consph_sys_reads then_reads = {0, 0, {SF_VOL}, {0}};

int kit_volumes(consph_sys *s, size_t *pairs)
{
    kit_vol_job vj = {consph_particles_field(s->p, SF_VOL, 1), NULL};
    if (!vj.vol) return CONSPH_ENOMEM;
    consph_sys_next_reads(s, &volume_reads);
    return kit_run(s, &volume_pass, group_volume, &vj, pairs);
}

/* The rows of pass 1's pack (which 1) or coupled_bc's (2) of the particles outside the destination
 * mask, which no visit writes (a decomposed system's halo: sources only), from their fields:
 * after the refresh of the pass that reads them (pass_halo_refresh, which that pass then does not
 * repeat), so they are the owners' values, those the visits wrote there (kit_pack1, kit_pack2).
 */
static int kit_pack_sources(consph_sys *s, const kit_job *job, int which)
{
    const unsigned char *dest = s->dest;
    if (!dest) return CONSPH_OK;
    const int st = pass_halo_refresh(s);
    if (st != CONSPH_OK) return st;
    const size_t n = s->p->n, cap = job->cap;
    const int D = job->d;
    for (size_t i = 0; i < n; ++i) {
        if (dest[i]) continue;
        if (which == 1) {
            kit_pack1(job, i, job->vol[i]);
            continue;
        }
        double G[9] = {0.0}, gq[3] = {0.0};
        if (job->pk2_u)
            for (int e = 0; e < D * D; ++e) G[e] = job->gradu[(size_t)e * cap + i];
        if (job->pk2_q)
            for (int a = 0; a < D; ++a) gq[a] = job->gradq[a * cap + i];
        kit_pack2(job, i, D, 1, 1, G, gq);
    }
    return CONSPH_OK;
}

/* One pass's refresh on a decomposed system: its reads declared, then the refresh and, where it
 * reads a pack (which 1: pass 1's, 2: coupled_bc's), the halo's rows of it; which 0: the refresh
 * alone. The chain calls it (block_visitor_in.prepare) where the passes one by one make it. */
typedef struct kit_prep {
    const kit_job *job;
    const consph_sys_reads *reads;
    int which;
} kit_prep;

static int kit_prepare(consph_sys *s, void *ctx)
{
    const kit_prep *k = ctx;
    consph_sys_next_reads(s, k->reads);
    return k->which ? kit_pack_sources(s, k->job, k->which) : pass_halo_refresh(s);
}

/* The volumes (with_volumes), then pass 1 and the Laplacians: chained on the neighbour list's
 * pair cache where it serves them (src/pass/nlist.c, nlist_chain_run), else one after the
 * other. */
static int kit_passes(consph_sys *s, const kit_req *rq, size_t *pairs, int *passes,
                      const int with_volumes, const consph_pass *then, void *then_job)
{
    consph_particles *p = s->p;
    const int d = p->dim;
    unsigned want = rq->want;
    if (want & KIT_LAPU) want |= KIT_GRADU;
    if (want & KIT_LAPQ) want |= KIT_GRADQ;
    kit_req r = *rq;
    r.want = want;
    kit_job job = {.rq = &r, .d = d, .cap = p->cap};
    double *vol = with_volumes ? consph_particles_field(p, SF_VOL, 1) : NULL;
    if (with_volumes && !vol) return CONSPH_ENOMEM;
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
    /* the Laplacians that read whether B_i was accepted */
    if ((want & KIT_LAPU) && (rq->lap == KIT_LAP_FATEHI_C || rq->lap == KIT_LAP_KORZILIUS)) {
        job.bonet_ok = malloc(p->n ? p->n : 1);
        if (!job.bonet_ok) return CONSPH_ENOMEM;
    }
    const consph_visit_fn visit_first =
        first_visits[d - 1][(want & KIT_GRADP) != 0][(want & (KIT_GRADU | KIT_DIVU)) != 0]
                    [(want & KIT_GRADQ) != 0];
    const int gp = (want & KIT_GRADP) != 0, gu = (want & (KIT_GRADU | KIT_DIVU)) != 0,
              gq = (want & KIT_GRADQ) != 0;
    /* Under a destination mask (a decomposed system's halo) too: the packs' rows of the
     * particles no visit writes (sources only) are filled from their fields before the pass
     * that reads them (kit_pack_sources), after the refresh that brings their owners' values. */
    const int lanes = kit_group_visits;
    const pass_group_fn group_first = lanes ? group_first_of(d, gp, gu, gq) : NULL;
    /* where pass 1 runs per particle (over a filled cache), it reads its pack too (2D:
     * first_pk_of) */
    const int kept = kit_keep_bonet && r.bonet_kept && !job.bonet_ok;
    const consph_visit_fn visit_first_pk = group_first ? first_pk_of(d, gp, gu, gq, kept) : NULL;
    const consph_pass first = {"kit: bonet, gradients, divergence", CONSPH_PASS_DW,
                               visit_first_pk ? visit_first_pk : visit_first};
    unsigned need2 = CONSPH_PASS_DW;
    if ((want & KIT_LAPU) && rq->lap == KIT_LAP_KORZILIUS) need2 |= CONSPH_PASS_D2W;
    /* Not on a decomposed system: its chain runs only where the pair cache is large (a small
     * halo beside the owned particles, nlist_chain_split_halo), where the lanes do not pay, and
     * its passes one by one never read the blocks they have just filled: per particle from the
     * pack (coupled_pk_of) there. */
    const pass_group_fn group_second =
        lanes && !s->split && coupled_lanes_pay(s) ? group_second_of(&r, d) : NULL;
    /* where coupled_bc's ∇²u (and ∇²q) runs per particle, it reads G_j (and ∇q_j, ω_j) from
     * pass 1's pack (2D: coupled_pk_of) */
    const consph_visit_fn visit_pk =
        lanes && !group_second && (want & KIT_LAPU) && rq->lap == KIT_LAP_COUPLED
            ? coupled_pk_of(d, (want & KIT_LAPQ) != 0)
            : NULL;
    const consph_pass second = {"kit: laplacians", need2, visit_pk ? visit_pk : visit_second};
    /* the packs the group visits read: pass 1's filled by the volume visits or from the fixed
     * volumes here, coupled_bc's by pass 1 (first_store) */
    if (group_first) job.s1 = kit_pack1_stride(d, gp, gu, gq);
    if (group_second || visit_pk) {
        job.pk2_u = (want & KIT_LAPU) != 0;
        job.pk2_q = (want & KIT_LAPQ) != 0;
        job.s2 = kit_pack2_stride(d, job.pk2_u, job.pk2_q, &job.pk2_vol);
        if (d == 3 && visit_pk) {
            /* coupled_pk_31's columns (ω read from vol) */
            job.pk2_cols = 1;
            job.s2 = 12;
            job.pk2_vol = -1;
        }
    }
    if (group_first || job.s2) {
        /* a decomposed system's refresh carries the scratch as columns of n values, which would
         * write over the packs' rows: a buffer of their own there */
        const size_t count = (p->n ? p->n : 1) * (size_t)(job.s1 + job.s2);
        double *pk = s->split ? sys_pack_buffer(s, count) : consph_sys_scratch(s, count);
        if (!pk) {
            free(job.bonet_ok);
            return CONSPH_ENOMEM;
        }
        job.pk1 = group_first ? pk : NULL;
        job.pk2 = job.s2 ? pk + p->n * (size_t)job.s1 : NULL;
    }
    /* What pass 1 and the Laplacians read at the neighbours (their visits and the packs' halo
     * rows): ω_j and the f_j of the gradients; coupled_bc the gradients G_j and ∇q_j, the
     * other Laplacians u_j (and Cleary's ϱ_j). A decomposed system's refresh before each brings
     * those columns alone. */
    consph_sys_reads first_reads = {0, 0, {SF_VOL}, {0}};
    int nr = 1;
    if (gp) first_reads.fields[nr++] = SF_P;
    if (gu) first_reads.fields[nr++] = SF_U;
    if (gq) first_reads.fields[nr++] = rq->q; /* checked above */
    consph_sys_reads second_reads = {0, 0, {SF_VOL}, {0}};
    nr = 1;
    if ((want & KIT_LAPU) && rq->lap == KIT_LAP_COUPLED) {
        second_reads.fields[nr++] = SF_GRADU;
    } else if (want & KIT_LAPU) {
        second_reads.fields[nr++] = SF_U;
        if (rq->lap == KIT_LAP_CLEARY) second_reads.fields[nr++] = SF_RHOF;
    }
    if (want & KIT_LAPQ) second_reads.fields[nr++] = SF_GRADQ;
    /* With the volumes, the refresh before them brings what pass 1 and the Laplacians read in
     * the halo that none of these passes makes (p, u, q; the other Laplacians' u, ϱ): the chain
     * on a decomposed system runs pass 1 in its sweep wherever the volumes are known at every
     * neighbour, so these must be there first. */
    consph_sys_reads pre_reads = {0, 0, {NULL}, {0}};
    nr = 0;
    if (gp) pre_reads.fields[nr++] = SF_P;
    if (gu) pre_reads.fields[nr++] = SF_U;
    if (gq) pre_reads.fields[nr++] = rq->q;
    if ((want & KIT_LAPU) && rq->lap != KIT_LAP_COUPLED) {
        pre_reads.fields[nr++] = SF_U;
        if (rq->lap == KIT_LAP_CLEARY) pre_reads.fields[nr++] = SF_RHOF;
    }
    if (job.pk1 && !with_volumes) {
        /* from the values pass 1's refresh brings, on a decomposed system */
        consph_sys_next_reads(s, &first_reads);
        const int rc = pass_halo_refresh(s);
        if (rc != CONSPH_OK) {
            free(job.bonet_ok);
            return rc;
        }
        for (size_t i = 0; i < p->n; ++i) kit_pack1(&job, i, job.vol[i]);
    }
    kit_vol_job vj = {vol, &job};
    const int with_second = (want & (KIT_LAPU | KIT_LAPQ)) != 0;
    int st = CONSPH_OK;
    /* with the volumes fixed (E-C, EWCSPH: the cache filled once for the run), pass 1 and the
     * Laplacians one after the other: chained over the filled cache they ran 15-30 % slower at nx
     * 250 (2 pairs each, 2-core AMD EPYC), with pass 1 over groups or per particle */
    if (with_volumes && kit_chain_passes && s->nlist && nlist_serves(s->nlist, p->n)) {
        /* the refreshes of the passes below, in their order */
        kit_prep prep[4] = {{&job, &pre_reads, 0},
                            {&job, &first_reads, job.pk1 ? 1 : 0},
                            {&job, &second_reads, job.pk2 ? 2 : 0},
                            {&job, &then_reads, 0}};
        block_visitor_in chain[4];
        int count = 0;
        chain[count++] = (block_visitor_in){
            &volume_pass, kit_group_visits ? group_volume : NULL, &vj, 0, kit_prepare, &prep[0]};
        chain[count++] = (block_visitor_in){&first, group_first, &job, 0, kit_prepare, &prep[1]};
        if (with_second)
            chain[count++] =
                (block_visitor_in){&second, group_second, &job, 0, kit_prepare, &prep[2]};
        const int kit_count = count;
        /* then last: it reads the volumes at the neighbours, which every pass before it waits
         * for too */
        if (then)
            chain[count++] = (block_visitor_in){then, NULL, then_job, 1, kit_prepare, &prep[3]};
        int ran = 0;
        st = nlist_chain_run(s, chain, count, pairs, &ran);
        if (st == CONSPH_OK && ran) {
            __atomic_fetch_add(&kit_chains, 1, __ATOMIC_RELAXED);
            if (group_first) __atomic_fetch_add(&kit_group_firsts, 1, __ATOMIC_RELAXED);
            if (group_second && with_second)
                __atomic_fetch_add(&kit_group_coupled, 1, __ATOMIC_RELAXED);
            if (visit_pk) __atomic_fetch_add(&kit_coupled_packed, 1, __ATOMIC_RELAXED);
            *passes += kit_count;
            free(job.bonet_ok);
            return CONSPH_OK;
        }
    }
    if (st == CONSPH_OK && with_volumes) {
        consph_sys_next_reads(s, &pre_reads);
        st = kit_run(s, &volume_pass, group_volume, &vj, pairs);
        if (st == CONSPH_OK) ++*passes;
    }
    /* the sources' rows of pass 1's pack, which the volume visits did not write */
    consph_sys_next_reads(s, &first_reads);
    if (st == CONSPH_OK && job.pk1 && with_volumes) st = kit_pack_sources(s, &job, 1);
    int grouped = 0;
    if (st == CONSPH_OK) st = kit_run_grouped(s, &first, group_first, &job, pairs, &grouped);
    if (group_first && grouped) __atomic_fetch_add(&kit_group_firsts, 1, __ATOMIC_RELAXED);
    if (st == CONSPH_OK && visit_first_pk && !grouped) {
        __atomic_fetch_add(&kit_first_packed, 1, __ATOMIC_RELAXED);
        if (kept) __atomic_fetch_add(&kit_first_kept, 1, __ATOMIC_RELAXED);
    }
    if (st == CONSPH_OK) ++*passes;
    if (with_second) consph_sys_next_reads(s, &second_reads);
    if (st == CONSPH_OK && with_second && job.pk2) st = kit_pack_sources(s, &job, 2);
    if (st == CONSPH_OK && with_second) {
        st = kit_run_grouped(s, &second, group_second, &job, pairs, &grouped);
        if (group_second && grouped) __atomic_fetch_add(&kit_group_coupled, 1, __ATOMIC_RELAXED);
        if (st == CONSPH_OK && visit_pk)
            __atomic_fetch_add(&kit_coupled_packed, 1, __ATOMIC_RELAXED);
        if (st == CONSPH_OK) ++*passes;
    }
    free(job.bonet_ok);
    /* then reads the volumes alone at the neighbours (kit_volumes_derivatives_then) */
    if (then) consph_sys_next_reads(s, &then_reads);
    if (st == CONSPH_OK && then) st = consph_pass_run(s, then, then_job);
    return st;
}

int kit_derivatives(consph_sys *s, const kit_req *rq, size_t *pairs, int *passes)
{
    return kit_passes(s, rq, pairs, passes, 0, NULL, NULL);
}

int kit_volumes_derivatives(consph_sys *s, const kit_req *rq, size_t *pairs, int *passes)
{
    return kit_passes(s, rq, pairs, passes, 1, NULL, NULL);
}

int kit_volumes_derivatives_then(consph_sys *s, const kit_req *rq, const consph_pass *then,
                                 void *then_job, size_t *pairs, int *passes)
{
    return kit_passes(s, rq, pairs, passes, 1, then, then_job);
}
