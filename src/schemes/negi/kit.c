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
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"
#include "pass/group.h"
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
    double *pack, *pack2;    /* the group visits' rows (kit_pack; else NULL) */
} kit_job;

static void visit_volume(void *vjob, const consph_nbhd *nb)
{
    double *vol = vjob, s = 0.0;
    for (size_t k = 0; k < nb->n; ++k) s += nb->w[k];
    vol[nb->i] = 1.0 / s;
}

/* Pass 1's finish at particle i from its sums, written into the job's fields. */
TERM_INLINE void first_store(const kit_job *job, const size_t i, const int D, const int with_p,
                             const int with_u, const int with_q, const double sm[9],
                             const double sp[3], const double su[9], const double sq[3])
{
    const size_t cap = job->cap;
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

/* ---- the passes over groups of particles (src/pass/group.h) ----
 *
 * The visits above sum one particle's neighbours pair by pair. The group visits run PASS_GROUP
 * particles side by side, one per lane of a vector of four doubles: lane l computes its own
 * particle's k-th pair with the operations of kit_pair.h in their order and adds it to its own
 * sums in its own neighbour order, so every value is the per-particle visit's bit for bit
 * (tests/test_kit_group.c). What a pair reads of its neighbour j is packed per particle on one
 * or more 32-byte rows before the pass (kit_pack), so four lanes' values come as four vector
 * loads and a transpose; the lanes' separations and kernel values are transposed four entries
 * at a time. A lane that has run out of neighbours reads its last one again and keeps its sums
 * (PASS_GROUP_UNPADDED: the neighbour list's pair cache hands its arrays over as they are).
 * GCC's and clang's vector extensions; other compilers run the per-particle visits. */
int kit_group_visits = 1;
unsigned long kit_group_passes = 0;

#if defined(__GNUC__)
#define KIT_GROUPS 1
/* GCC builds a vector from scalars by inserting them into the destination's old value, and then
 * warns that the old value may be uninitialised (it is never read) */
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
typedef double kv4 __attribute__((vector_size(4 * sizeof(double))));
typedef long long kv4i __attribute__((vector_size(4 * sizeof(double))));
typedef double kv4u __attribute__((vector_size(4 * sizeof(double)), aligned(sizeof(double))));
/* m ? a : b per lane (m: all bits set or none) */
#define KV_SEL(m, a, b) ((kv4)(((m) & (kv4i)(a)) | (~(m) & (kv4i)(b))))
/* acc = expr, in the lanes of m only where `tail` (the other lanes have run out) */
#define KV_UPD(tail, m, acc, expr)                                                                 \
    do {                                                                                           \
        const kv4 upd_ = (expr);                                                                   \
        (acc) = (tail) ? KV_SEL((m), upd_, (acc)) : upd_;                                          \
    } while (0)
#if defined(__clang__)
#define KV_SHUF(a, b, i0, i1, i2, i3) __builtin_shufflevector(a, b, i0, i1, i2, i3)
#else
#define KV_SHUF(a, b, i0, i1, i2, i3) __builtin_shuffle(a, b, (kv4i){i0, i1, i2, i3})
#endif
/* An AVX2 copy of the visits in a generic x86-64 build, chosen at load time (the same
 * operations in the same order; no FMA is enabled, so nothing is contracted), as the PySPH
 * family's group visits (src/schemes/pysph/scheme.c). */
#if defined(__x86_64__) && !defined(__clang__) && defined(__GLIBC__) && !defined(__AVX2__)
#define KIT_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define KIT_CLONES
#endif

/* Entries o..o+3 of the four rows q[l], as four vectors f[c] = {q[0][o+c], ..., q[3][o+c]}. */
TERM_INLINE void kv_transpose(const double *const q[PASS_GROUP], size_t o, kv4 f[4])
{
    const kv4 a0 = *(const kv4u *)(q[0] + o), a1 = *(const kv4u *)(q[1] + o);
    const kv4 a2 = *(const kv4u *)(q[2] + o), a3 = *(const kv4u *)(q[3] + o);
    const kv4 t0 = KV_SHUF(a0, a1, 0, 4, 2, 6), t1 = KV_SHUF(a0, a1, 1, 5, 3, 7);
    const kv4 t2 = KV_SHUF(a2, a3, 0, 4, 2, 6), t3 = KV_SHUF(a2, a3, 1, 5, 3, 7);
    f[0] = KV_SHUF(t0, t2, 0, 1, 4, 5);
    f[1] = KV_SHUF(t1, t3, 0, 1, 4, 5);
    f[2] = KV_SHUF(t0, t2, 2, 3, 6, 7);
    f[3] = KV_SHUF(t1, t3, 2, 3, 6, 7);
}

/* The pack rows: pass 1 reads ω, p, u, q of j at KP1_* of a row of KP1 doubles; the Laplacians
 * ω, G and ∇q at 0, 1 + e, 1 + d² + b of a row of kp2(d) doubles. */
enum { KP1 = 8, KP1_VOL = 0, KP1_P = 1, KP1_U0 = 2, KP1_U1 = 3, KP1_Q = 4, KP1_U2 = 5 };
static int kp2(int d)
{
    return d == 2 ? 8 : 16;
}

/* The group's lanes: lane l reads entry e_l = min(k, n_l - 1) of its neighbourhood. */
typedef struct kit_lanes {
    const consph_nbhd *nb[PASS_GROUP];
    size_t i[PASS_GROUP], n[PASS_GROUP], kmin, kmax;
} kit_lanes;

TERM_INLINE void kit_lanes_of(kit_lanes *L, const consph_nbhd *nb)
{
    L->kmin = (size_t)-1;
    L->kmax = 0;
    for (int l = 0; l < PASS_GROUP; ++l) {
        L->nb[l] = &nb[l];
        L->i[l] = nb[l].i;
        L->n[l] = nb[l].n;
        if (nb[l].n < L->kmin) L->kmin = nb[l].n;
        if (nb[l].n > L->kmax) L->kmax = nb[l].n;
    }
}

/* What the lanes read of their own arrays (ω-independent: x_ij, W'/r or W) at entry k, one
 * entry at a time (tail: clamped to each lane's last, with *m the lanes that sum it) or, in
 * kit_block, four entries at once. */
typedef struct kit_pairv {
    kv4 w1, x[3];
    size_t j[PASS_GROUP];
} kit_pairv;

TERM_INLINE void kit_entry(const kit_lanes *L, size_t k, const int tail, const int D,
                           const int with_x, kit_pairv *pv, kv4i *m)
{
    size_t e[PASS_GROUP];
    for (int l = 0; l < PASS_GROUP; ++l) {
        e[l] = tail && k >= L->n[l] ? L->n[l] - 1 : k;
        pv->j[l] = L->nb[l]->j[e[l]];
    }
    pv->w1 =
        (kv4){L->nb[0]->dwr[e[0]], L->nb[1]->dwr[e[1]], L->nb[2]->dwr[e[2]], L->nb[3]->dwr[e[3]]};
    if (with_x)
        for (int a = 0; a < D; ++a)
            pv->x[a] = (kv4){L->nb[0]->dx[a][e[0]], L->nb[1]->dx[a][e[1]], L->nb[2]->dx[a][e[2]],
                             L->nb[3]->dx[a][e[3]]};
    if (tail) {
        const kv4i kv = {(long long)k, (long long)k, (long long)k, (long long)k};
        const kv4i nv = {(long long)L->n[0], (long long)L->n[1], (long long)L->n[2],
                         (long long)L->n[3]};
        *m = (kv4i)(kv < nv);
    }
}

/* Entries k..k+3 of every lane (all below every lane's n). */
TERM_INLINE void kit_block(const kit_lanes *L, size_t k, const int D, const int with_x,
                           kit_pairv pv[4])
{
    kv4 f[4];
    const double *q[PASS_GROUP];
    for (int l = 0; l < PASS_GROUP; ++l) q[l] = L->nb[l]->dwr + k;
    kv_transpose(q, 0, f);
    for (int c = 0; c < 4; ++c) pv[c].w1 = f[c];
    if (with_x)
        for (int a = 0; a < D; ++a) {
            for (int l = 0; l < PASS_GROUP; ++l) q[l] = L->nb[l]->dx[a] + k;
            kv_transpose(q, 0, f);
            for (int c = 0; c < 4; ++c) pv[c].x[a] = f[c];
        }
    for (int c = 0; c < 4; ++c)
        for (int l = 0; l < PASS_GROUP; ++l) pv[c].j[l] = L->nb[l]->j[k + (size_t)c];
}

/* visit_volume over a group */
KIT_CLONES static void group_volume(void *vjob, const consph_nbhd *nb, int count)
{
    double *vol = vjob;
    kit_lanes L;
    kit_lanes_of(&L, nb);
    kv4 s = {0.0, 0.0, 0.0, 0.0};
    size_t k = 0;
    for (; k + 4 <= L.kmin; k += 4) {
        kv4 f[4];
        const double *q[PASS_GROUP];
        for (int l = 0; l < PASS_GROUP; ++l) q[l] = L.nb[l]->w + k;
        kv_transpose(q, 0, f);
        s += f[0];
        s += f[1];
        s += f[2];
        s += f[3];
    }
    for (; k < L.kmax; ++k) {
        size_t e[PASS_GROUP];
        for (int l = 0; l < PASS_GROUP; ++l) e[l] = k >= L.n[l] ? L.n[l] - 1 : k;
        const kv4 w = {L.nb[0]->w[e[0]], L.nb[1]->w[e[1]], L.nb[2]->w[e[2]], L.nb[3]->w[e[3]]};
        const kv4i kv = {(long long)k, (long long)k, (long long)k, (long long)k};
        const kv4i nv = {(long long)L.n[0], (long long)L.n[1], (long long)L.n[2],
                         (long long)L.n[3]};
        const kv4i m = (kv4i)(kv < nv);
        KV_UPD(1, m, s, s + w);
    }
    for (int l = 0; l < count; ++l) vol[L.i[l]] = 1.0 / s[l];
}

typedef struct kit_first_sums {
    kv4 sm[9], sp[3], su[9], sq[3];
} kit_first_sums;

/* kit_first_pair's operations on one entry of every lane. */
TERM_INLINE void first_group_pair(const kit_job *job, const kit_pairv *pv, const int tail,
                                  const kv4i m, const int D, const int with_p, const int with_u,
                                  const int with_q, const kv4 pi, const kv4 ui[3], const kv4 qi,
                                  kit_first_sums *S)
{
    const double *q[PASS_GROUP];
    kv4 f[8];
    for (int l = 0; l < PASS_GROUP; ++l) q[l] = job->pack + pv->j[l] * KP1;
    kv_transpose(q, 0, f);
    if (with_q || (with_u && D > 2)) kv_transpose(q, 4, f + 4);
    const kv4 om = f[KP1_VOL], w1 = pv->w1;
    const kv4 *x = pv->x;
    const kv4 g = om * w1;
    for (int a = 0; a < D; ++a)
        for (int b = 0; b < D; ++b)
            KV_UPD(tail, m, S->sm[a * D + b], S->sm[a * D + b] - g * x[a] * x[b]);
    if (with_p) {
        const kv4 t = om * (f[KP1_P] - pi) * w1;
        for (int b = 0; b < D; ++b) KV_UPD(tail, m, S->sp[b], S->sp[b] + t * x[b]);
    }
    if (with_u)
        for (int a = 0; a < D; ++a) {
            const kv4 uj = f[a == 0 ? KP1_U0 : a == 1 ? KP1_U1 : KP1_U2];
            const kv4 t = om * (uj - ui[a]) * w1;
            for (int b = 0; b < D; ++b)
                KV_UPD(tail, m, S->su[a * D + b], S->su[a * D + b] + t * x[b]);
        }
    if (with_q) {
        const kv4 t = om * (f[KP1_Q] - qi) * w1;
        for (int b = 0; b < D; ++b) KV_UPD(tail, m, S->sq[b], S->sq[b] + t * x[b]);
    }
}

/* first_body over a group */
TERM_INLINE void first_group(const kit_job *job, const consph_nbhd *nb, int count, const int D,
                             const int with_p, const int with_u, const int with_q)
{
    const size_t cap = job->cap;
    kit_lanes L;
    kit_lanes_of(&L, nb);
    const kv4 zero = {0.0, 0.0, 0.0, 0.0};
    const kv4i all = {-1, -1, -1, -1};
    kit_first_sums S;
    kv4 ui[3];
    for (int e = 0; e < 9; ++e) S.sm[e] = S.su[e] = zero;
    for (int a = 0; a < 3; ++a) S.sp[a] = S.sq[a] = ui[a] = zero;
    const double *qi_rows[PASS_GROUP];
    for (int l = 0; l < PASS_GROUP; ++l) qi_rows[l] = job->pack + L.i[l] * KP1;
    kv4 fi[8];
    kv_transpose(qi_rows, 0, fi);
    kv_transpose(qi_rows, 4, fi + 4);
    const kv4 pi = with_p ? fi[KP1_P] : zero, qi = with_q ? fi[KP1_Q] : zero;
    if (with_u)
        for (int a = 0; a < D; ++a) ui[a] = fi[a == 0 ? KP1_U0 : a == 1 ? KP1_U1 : KP1_U2];
    (void)cap;
    size_t k = 0;
    for (; k + 4 <= L.kmin; k += 4) {
        kit_pairv pv[4];
        kit_block(&L, k, D, 1, pv);
        for (int c = 0; c < 4; ++c)
            first_group_pair(job, &pv[c], 0, all, D, with_p, with_u, with_q, pi, ui, qi, &S);
    }
    for (; k < L.kmax; ++k) {
        kit_pairv pv;
        kv4i m = all;
        kit_entry(&L, k, 1, D, 1, &pv, &m);
        first_group_pair(job, &pv, 1, m, D, with_p, with_u, with_q, pi, ui, qi, &S);
    }
    for (int l = 0; l < count; ++l) {
        double m1[9] = {0}, p1[3] = {0}, u1[9] = {0}, q1[3] = {0};
        for (int e = 0; e < D * D; ++e) {
            m1[e] = S.sm[e][l];
            u1[e] = S.su[e][l];
        }
        for (int a = 0; a < D; ++a) {
            p1[a] = S.sp[a][l];
            q1[a] = S.sq[a][l];
        }
        first_store(job, L.i[l], D, with_p, with_u, with_q, m1, p1, u1, q1);
    }
}

#define FIRST_GROUP(D, P, U, Q)                                                                    \
    KIT_CLONES static void first_group_##D##P##U##Q(void *job, const consph_nbhd *nb, int count)   \
    {                                                                                              \
        first_group(job, nb, count, D, P, U, Q);                                                   \
    }
#define FIRST_GROUPS_Q(D, P, U) FIRST_GROUP(D, P, U, 0) FIRST_GROUP(D, P, U, 1)
#define FIRST_GROUPS_U(D, P) FIRST_GROUPS_Q(D, P, 0) FIRST_GROUPS_Q(D, P, 1)
#define FIRST_GROUPS(D) FIRST_GROUPS_U(D, 0) FIRST_GROUPS_U(D, 1)
FIRST_GROUPS(2)
FIRST_GROUPS(3)
#define FIRST_GROUP_NAMES_Q(D, P, U)                                                               \
    {                                                                                              \
        first_group_##D##P##U##0, first_group_##D##P##U##1                                         \
    }
#define FIRST_GROUP_NAMES_U(D, P)                                                                  \
    {                                                                                              \
        FIRST_GROUP_NAMES_Q(D, P, 0), FIRST_GROUP_NAMES_Q(D, P, 1)                                 \
    }
#define FIRST_GROUP_NAMES(D)                                                                       \
    {                                                                                              \
        FIRST_GROUP_NAMES_U(D, 0), FIRST_GROUP_NAMES_U(D, 1)                                       \
    }
/* 2D and 3D (1D runs the per-particle visits) */
static const pass_group_fn first_groups[2][2][2][2] = {FIRST_GROUP_NAMES(2), FIRST_GROUP_NAMES(3)};

/* kit_coupled_pair's operations on one entry of every lane. */
TERM_INLINE void coupled_group_pair(const kit_job *job, const kit_pairv *pv, const int tail,
                                    const kv4i m, const int D, const int with_u, const int with_q,
                                    const kv4 B[9], const kv4 Gi[9], const kv4 gqi[3], kv4 acc[3],
                                    kv4 *accq)
{
    const int R = kp2(D);
    const double *q[PASS_GROUP];
    kv4 f[16];
    for (int l = 0; l < PASS_GROUP; ++l) q[l] = job->pack2 + pv->j[l] * (size_t)R;
    /* ω at 0, G at 1 + e, ∇q at 1 + D² + b: the blocks of four that hold what is read */
    const int last = with_q ? D * D + D : D * D;
    for (int o = 0; o <= last; o += 4) kv_transpose(q, (size_t)o, f + o);
    const kv4 w1 = pv->w1, om = f[0];
    kv4 gr[3], g[3];
    for (int b = 0; b < D; ++b) gr[b] = w1 * pv->x[b];
    for (int a = 0; a < D; ++a) {
        kv4 v = {0.0, 0.0, 0.0, 0.0};
        for (int b = 0; b < D; ++b) v += B[a * D + b] * gr[b];
        g[a] = v;
    }
    if (with_u)
        for (int a = 0; a < D; ++a) {
            kv4 sa = {0.0, 0.0, 0.0, 0.0};
            for (int b = 0; b < D; ++b) sa += (f[1 + a * D + b] - Gi[a * D + b]) * g[b];
            KV_UPD(tail, m, acc[a], acc[a] + om * sa);
        }
    if (with_q) {
        kv4 sq = {0.0, 0.0, 0.0, 0.0};
        for (int b = 0; b < D; ++b) sq += (f[1 + D * D + b] - gqi[b]) * g[b];
        KV_UPD(tail, m, *accq, *accq + om * sq);
    }
}

/* coupled_body over a group */
TERM_INLINE void coupled_group(const kit_job *job, const consph_nbhd *nb, int count, const int D,
                               const int with_u, const int with_q)
{
    const size_t cap = job->cap;
    kit_lanes L;
    kit_lanes_of(&L, nb);
    const kv4 zero = {0.0, 0.0, 0.0, 0.0};
    const kv4i all = {-1, -1, -1, -1};
    kv4 B[9], Gi[9], gqi[3], acc[3] = {zero, zero, zero}, accq = zero;
    for (int e = 0; e < D * D; ++e) {
        B[e] = (kv4){job->bonet[(size_t)e * cap + L.i[0]], job->bonet[(size_t)e * cap + L.i[1]],
                     job->bonet[(size_t)e * cap + L.i[2]], job->bonet[(size_t)e * cap + L.i[3]]};
        Gi[e] = zero;
    }
    for (int b = 0; b < 3; ++b) gqi[b] = zero;
    {
        const int R = kp2(D);
        const double *q[PASS_GROUP];
        kv4 f[16];
        for (int l = 0; l < PASS_GROUP; ++l) q[l] = job->pack2 + L.i[l] * (size_t)R;
        for (int o = 0; o < R; o += 4) kv_transpose(q, (size_t)o, f + o);
        if (with_u)
            for (int e = 0; e < D * D; ++e) Gi[e] = f[1 + e];
        if (with_q)
            for (int b = 0; b < D; ++b) gqi[b] = f[1 + D * D + b];
    }
    size_t k = 0;
    for (; k + 4 <= L.kmin; k += 4) {
        kit_pairv pv[4];
        kit_block(&L, k, D, 1, pv);
        for (int c = 0; c < 4; ++c)
            coupled_group_pair(job, &pv[c], 0, all, D, with_u, with_q, B, Gi, gqi, acc, &accq);
    }
    for (; k < L.kmax; ++k) {
        kit_pairv pv;
        kv4i m = all;
        kit_entry(&L, k, 1, D, 1, &pv, &m);
        coupled_group_pair(job, &pv, 1, m, D, with_u, with_q, B, Gi, gqi, acc, &accq);
    }
    for (int l = 0; l < count; ++l) {
        const size_t i = L.i[l];
        if (with_u)
            for (int a = 0; a < D; ++a) job->lapu[a * cap + i] = acc[a][l];
        if (with_q) job->lapq[i] = accq[l];
    }
}

#define COUPLED_GROUP(D, U, Q)                                                                     \
    KIT_CLONES static void coupled_group_##D##U##Q(void *job, const consph_nbhd *nb, int count)    \
    {                                                                                              \
        coupled_group(job, nb, count, D, U, Q);                                                    \
    }
COUPLED_GROUP(2, 1, 1)
COUPLED_GROUP(2, 1, 0)
COUPLED_GROUP(2, 0, 1)
COUPLED_GROUP(3, 1, 1)
COUPLED_GROUP(3, 1, 0)
COUPLED_GROUP(3, 0, 1)
/* [d - 2][with_u][with_q] */
static const pass_group_fn coupled_groups[2][2][2] = {
    {{NULL, coupled_group_201}, {coupled_group_210, coupled_group_211}},
    {{NULL, coupled_group_301}, {coupled_group_310, coupled_group_311}}};
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif

/* The rows of pass 1 (ω, p, u, q of every particle) into job->pack. */
static void pack_first(const consph_sys *s, const kit_job *job)
{
    const size_t n = s->p->n, cap = job->cap;
    const int d = job->d;
    double *pk = job->pack;
#pragma omp parallel for schedule(static) if (n >= s->parallel_min)
    for (size_t i = 0; i < n; ++i) {
        double *r = pk + i * KP1;
        r[KP1_VOL] = job->vol[i];
        r[KP1_P] = job->p ? job->p[i] : 0.0;
        r[KP1_Q] = job->q ? job->q[i] : 0.0;
        r[KP1_U0] = job->u && d > 0 ? job->u[i] : 0.0;
        r[KP1_U1] = job->u && d > 1 ? job->u[cap + i] : 0.0;
        r[KP1_U2] = job->u && d > 2 ? job->u[2 * cap + i] : 0.0;
        r[6] = r[7] = 0.0;
    }
}

/* The rows of the Laplacians (ω, G, ∇q of every particle) into job->pack2, after pass 1. */
static void pack_second(const consph_sys *s, const kit_job *job)
{
    const size_t n = s->p->n, cap = job->cap;
    const int d = job->d, R = kp2(d);
    double *pk = job->pack2;
#pragma omp parallel for schedule(static) if (n >= s->parallel_min)
    for (size_t i = 0; i < n; ++i) {
        double *r = pk + i * (size_t)R;
        for (int c = 0; c < R; ++c) r[c] = 0.0;
        r[0] = job->vol[i];
        if (job->gradu)
            for (int e = 0; e < d * d; ++e) r[1 + e] = job->gradu[(size_t)e * cap + i];
        if (job->gradq)
            for (int b = 0; b < d; ++b) r[1 + d * d + b] = job->gradq[(size_t)b * cap + i];
    }
}
#endif

/* A pass with its group visit where the system and the compiler allow one, else per particle. */
static int kit_run(consph_sys *s, const consph_pass *pass, pass_group_fn group, void *job,
                   size_t *pairs)
{
#ifdef KIT_GROUPS
    if (kit_group_visits && group) {
        const int st =
            pass_run_groups(s, pass->name, pass->need | PASS_GROUP_UNPADDED, group, job, pairs);
        if (st != PASS_GROUP_UNSERVED) {
            if (st == CONSPH_OK) ++kit_group_passes;
            return st;
        }
    }
#else
    (void)group;
#endif
    return consph_pass_run_counted(s, pass, job, pairs);
}

int kit_volumes(consph_sys *s, size_t *pairs)
{
    double *vol = consph_particles_field(s->p, SF_VOL, 1);
    if (!vol) return CONSPH_ENOMEM;
    const consph_pass pass = {"volumes 1/sum W", CONSPH_PASS_W | CONSPH_PASS_NO_DX, visit_volume};
#ifdef KIT_GROUPS
    return kit_run(s, &pass, group_volume, vol, pairs);
#else
    return kit_run(s, &pass, NULL, vol, pairs);
#endif
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
    const int P = (want & KIT_GRADP) != 0, U = (want & (KIT_GRADU | KIT_DIVU)) != 0;
    const int Q = (want & KIT_GRADQ) != 0;
    const consph_visit_fn visit_first = first_visits[d - 1][P][U][Q];
    pass_group_fn group_first = NULL, group_second = NULL;
#ifdef KIT_GROUPS
    /* a decomposed system's passes run per particle (pass_run_groups declines it), and its
     * scratch is carried to the halo (docs/mpi.md): no pack there */
    if (kit_group_visits && d >= 2 && !s->split) {
        group_first = first_groups[d - 2][P][U][Q];
        /* coupled_bc is the only Laplacian with a group visit */
        const int lu = (want & KIT_LAPU) != 0, lq = (want & KIT_LAPQ) != 0;
        if ((lu || lq) && (!lu || rq->lap == KIT_LAP_COUPLED))
            group_second = coupled_groups[d - 2][lu][lq];
        const size_t nn = p->n ? p->n : 1;
        double *sc = consph_sys_scratch(s, nn * (size_t)(KP1 + kp2(d)) + 8);
        if (!sc) {
            free(job.bonet_ok);
            return CONSPH_ENOMEM;
        }
        while ((uintptr_t)sc % 64) ++sc;
        job.pack = sc;
        job.pack2 = sc + nn * KP1;
        pack_first(s, &job);
    }
#endif
    const consph_pass first = {"kit: bonet, gradients, divergence", CONSPH_PASS_DW, visit_first};
    int st = kit_run(s, &first, group_first, &job, pairs);
    if (st == CONSPH_OK) ++*passes;
    if (st == CONSPH_OK && (want & (KIT_LAPU | KIT_LAPQ))) {
        unsigned need = CONSPH_PASS_DW;
        if ((want & KIT_LAPU) && rq->lap == KIT_LAP_KORZILIUS) need |= CONSPH_PASS_D2W;
        const consph_pass second = {"kit: laplacians", need, visit_second};
#ifdef KIT_GROUPS
        if (group_second) pack_second(s, &job);
#endif
        st = kit_run(s, &second, group_second, &job, pairs);
        if (st == CONSPH_OK) ++*passes;
    }
    free(job.bonet_ok);
    return st;
}
