/* The weakly-compressible schemes 001 measures itself against, as the established codes run
 * them (docs/schemes.md, sections wcsph, tvf and edac, records every constant with its source):
 *
 *   wcsph  Monaghan's WCSPH: dϱ/dt = Σ m_j u_ij·∇W_ij, Tait EOS, the symmetric pressure force
 *          -Σ m_j (p_i/ϱ_i² + p_j/ϱ_j² + Π_ij)∇W_ij with Monaghan's Π_ij, the laminar
 *          viscosity of Morris/Cleary, XSPH advection (ε = 0.5); PySPH's predict-evaluate-
 *          correct (pec: one evaluation per step).
 *   tvf    Adami, Hu & Adams 2013: ϱ = m Σ W, p = p_o(ϱ/ϱ_o - 1), forces weighted by
 *          (V_i² + V_j²) with the density-weighted p̃_ij, the A = ϱ u(ũ - u) stress, and the
 *          background pressure p_b driving the transport velocity ũ; kick-drift-kick with
 *          one evaluation per step.
 *   edac   Ramachandran & Puri 2019: tvf's momentum with p - p̄_i (the neighbour average) and
 *          the evolved pressure dp/dt = Σ ϱ_i/ϱ_j c² m_j u_ij·∇W_ij + EDAC diffusion ν_edac;
 *          predict-evaluate-correct.
 *
 * Every pair force of tvf and edac is antisymmetric in i and j (the weights V_i² + V_j², p̃_ij,
 * η_ij and A_i + A_j are symmetric and ∇W_ij is odd), so they conserve linear momentum to
 * round-off on any particle distribution. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "pass/group.h"
#include "pass/lanes4.h"
#include "schemes/pysph/iact.h"
#include "solver/solver_internal.h"

#define SF_NUMD "numden" /* V_i = Σ_j W_ij (tvf, edac) */
#define SF_RHOS "rhos"   /* ϱ_i = m V_i, the summation density of the last right-hand side */
#define SF_PAVG "pavg"   /* p̄_i: the average p over the neighbours of i (edac) */
#define SF_TVDU "tvdu"   /* ũ - u of the last drift (tv_transport), which the A-term uses, d */
#define SF_UHAT "auhat"  /* the background-pressure acceleration, d */

enum { RV_WCSPH, RV_TVF, RV_EDAC };

/* Whether wcsph, tvf and edac run their passes over groups (0: the per-particle visits, which give
 * the same values; tests/test_pysph_group.c compares the two). */
int pysph_group_visits = 1;

typedef struct rival_job {
    int kind, d;
    size_t cap;
    pysph_consts c; /* the pair terms' constants (iact.h) */
    double rho0, cexp, p0;
    const double *u, *rho, *p, *tvdu;
    const double *cs; /* wcsph with α > 0: Tait's sound speed of each particle */
    /* per particle, computed once instead of once per pair (the same operations, hence the
     * same values): wcsph p/ϱ², tvf and edac 1/V = 1/Σ W; m/ϱ for ∇u */
    double *pr2, *vol, *mrho;
    /* the group visits: what a pair reads of its neighbour j, together at pack[j * pk] (one
     * cache line instead of one per field); NULL: read from the fields */
    double *pack;
    size_t pk; /* doubles per particle in the pack */
    /* the group visits: the pack in slot order (PASS_GROUP_SLOTS), and each particle's slot */
    const size_t *slot_of;
    const double *pslot; /* edac's group density visit: p in slot order */
    double *numd, *pavg, *rhos, *pw, *au, *aq, *ax, *auhat;
    double *gradp, *divu, *gradu; /* for the diagnostics and the vorticity output */
    int grads;                    /* ∇u and ∇p wanted (consph_solver.grads_skip unset) */
} rival_job;

/* The solver's diagnostics read ∇p (as -ϱ times the pressure acceleration), ∇·u and ∇u: the
 * scheme's own estimates, Σ_j m_j/ϱ_j (u_j - u_i) ⊗ ∇W_ij for ∇u. */
static inline void put_diag(const rival_job *job, size_t i, const double fp[3], double div,
                            const double G[9], const int d, const int grads)
{
    const size_t cap = job->cap;
    if (grads) {
        for (int a = 0; a < d; ++a) job->gradp[a * cap + i] = -job->rho[i] * fp[a];
        for (int e = 0; e < d * d; ++e) job->gradu[(size_t)e * cap + i] = G[e];
    }
    job->divu[i] = div;
}

/* ---- summation density, EOS, neighbour-average pressure (tvf, edac) ---- */
static void visit_density(void *vjob, const consph_nbhd *nb)
{
    const rival_job *job = vjob;
    const size_t i = nb->i;
    double s = 0.0, ps = 0.0;
    for (size_t k = 0; k < nb->n; ++k) s += nb->w[k];
    job->numd[i] = s;
    job->rhos[i] = job->c.m * s;
    job->vol[i] = 1.0 / s;
    job->mrho[i] = job->c.m / job->rhos[i];
    if (job->kind == RV_TVF) {
        job->pw[i] = job->p0 * (job->rhos[i] / job->rho0 - 1.0);
    } else {
        for (size_t k = 0; k < nb->n; ++k) ps += job->p[nb->j[k]];
        job->pavg[i] = ps / (double)nb->n;
    }
}

/* GCC does not if-convert a select of computed values while floating-point operations may
 * trap (it sinks them into the selected arm), so the loops below would not vectorise. Nothing
 * here reads the exception flags, and the option changes no value (it permits no
 * reassociation). */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC push_options
#pragma GCC optimize("no-trapping-math")
#endif

/* Neighbours per block of the rate visits: the per-pair terms of a block are computed in
 * loops over the block that vectorise (their divisions above all), then summed in neighbour
 * order, so every sum adds the same terms in the same order as a pair-by-pair loop. */
#define RV_BLOCK 64

/* The term loops are straight vector code, divisions above all, so wider vectors pay in
 * proportion: a generic x86-64 build also carries an AVX2 copy of the visits chosen at load time
 * (the same operations in the same order, hence the same values; no FMA is enabled, so nothing
 * is contracted), as consph_kernel_eval_batch does. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__GLIBC__) &&       \
    !defined(__AVX2__)
#define RV_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define RV_CLONES
#endif

/* The group visits' AVX-512 and AVX2 copies (src/pass/lanes4.h): their four lanes' sums, own
 * values and constants exceed AVX2's 16 vector registers. */
#define RV_GROUP_CLONES LANE4_CLONES

#if defined(__GNUC__)
#define RV_INLINE static inline __attribute__((always_inline))
#else
#define RV_INLINE static inline
#endif

/* The block's j-indexed values, copied contiguous so that the term loops are plain vector
 * code. */
RV_INLINE void rv_gather(int d, size_t cap, const double *f, const size_t *j, size_t n,
                         double (*out)[RV_BLOCK])
{
    for (int a = 0; a < d; ++a)
        for (size_t k = 0; k < n; ++k) out[a][k] = f[a * cap + j[k]];
}

/* ---- the tvf / edac rates ---- */
RV_INLINE void visit_tv_d(const rival_job *job, const consph_nbhd *nb, const int d, const int edac,
                          const int grads)
{
    const size_t i = nb->i, cap = job->cap;
    const double *u = job->u, *du = job->tvdu;
    const double rhoi = job->rho[i], pi = job->p[i], Vi = job->vol[i];
    const double pav = edac ? job->pavg[i] : 0.0;
    const pysph_consts *c = &job->c;
    double ui[3] = {0.0, 0.0, 0.0}, dui[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) {
        ui[a] = u[a * cap + i];
        dui[a] = du[a * cap + i];
    }
    double f[3] = {0.0, 0.0, 0.0}, fb[3] = {0.0, 0.0, 0.0}, fp[3] = {0.0, 0.0, 0.0}, ap = 0.0;
    double G[9] = {0.0}, div = 0.0;
    for (size_t k0 = 0; k0 < nb->n; k0 += RV_BLOCK) {
        const size_t nk = nb->n - k0 < RV_BLOCK ? nb->n - k0 : RV_BLOCK;
        const size_t *jb = nb->j + k0;
        double rhoj[RV_BLOCK], pj[RV_BLOCK], vol[RV_BLOCK], mr[RV_BLOCK], uj[3][RV_BLOCK],
            duj[3][RV_BLOCK];
        double tf[3][RV_BLOCK], tp[3][RV_BLOCK], tb[3][RV_BLOCK], tg[9][RV_BLOCK];
        double tdiv[RV_BLOCK], ta1[RV_BLOCK], ta2[RV_BLOCK];
        rv_gather(1, 0, job->rho, jb, nk, &rhoj);
        rv_gather(1, 0, job->p, jb, nk, &pj);
        rv_gather(1, 0, job->vol, jb, nk, &vol);
        rv_gather(1, 0, job->mrho, jb, nk, &mr);
        rv_gather(d, cap, u, jb, nk, uj);
        rv_gather(d, cap, du, jb, nk, duj);
        for (size_t k = 0; k < nk; ++k) {
            /* the particle itself gets terms too (∇W_ii = 0); they are not summed */
            double xij[3] = {0.0, 0.0, 0.0}, ujk[3] = {0.0, 0.0, 0.0}, dujk[3] = {0.0, 0.0, 0.0};
            for (int a = 0; a < d; ++a) {
                xij[a] = nb->dx[a][k0 + k];
                ujk[a] = uj[a][k];
                dujk[a] = duj[a][k];
            }
            pysph_pair o;
            pysph_tv_pair(d, edac, c, rhoi, pi, pav, Vi, ui, dui, rhoj[k], pj[k], vol[k], mr[k],
                          ujk, dujk, nb->dwr[k0 + k], xij, nb->r[k0 + k], &o);
            for (int a = 0; a < d; ++a) {
                tf[a][k] = o.f[a];
                tb[a][k] = o.fb[a];
                if (grads) tp[a][k] = o.fp[a];
            }
            if (grads)
                for (int e = 0; e < d * d; ++e) tg[e][k] = o.g[e];
            tdiv[k] = o.div;
            if (edac) {
                ta1[k] = o.q1;
                ta2[k] = o.q2;
            }
        }
        for (size_t k = 0; k < nk; ++k) {
            if (jb[k] == i) continue; /* ∇W_ii = 0: no force on itself */
            for (int a = 0; a < d; ++a) {
                f[a] += tf[a][k];
                fb[a] += tb[a][k];
                if (grads) fp[a] += tp[a][k];
            }
            if (grads)
                for (int e = 0; e < d * d; ++e) G[e] -= tg[e][k];
            div -= tdiv[k];
            if (edac) {
                ap += ta1[k];
                ap += ta2[k];
            }
        }
    }
    for (int a = 0; a < d; ++a) {
        job->au[a * cap + i] = f[a] / c->m;
        job->auhat[a * cap + i] = fb[a] / c->m;
    }
    job->aq[i] = ap;
    put_diag(job, i, fp, div, G, d, grads);
}

/* Compile-time clones for 2D and 3D, with and without ∇u, as the δ family has
 * (src/schemes/delta/scheme.c). */
RV_CLONES static void visit_tv(void *vjob, const consph_nbhd *nb)
{
    const rival_job *job = vjob;
    const int edac = job->kind == RV_EDAC, g = job->grads;
    if (job->d == 2) {
        if (edac)
            g ? visit_tv_d(job, nb, 2, 1, 1) : visit_tv_d(job, nb, 2, 1, 0);
        else
            g ? visit_tv_d(job, nb, 2, 0, 1) : visit_tv_d(job, nb, 2, 0, 0);
    } else { /* the problems are 2D or 3D (the problem table) */
        if (edac)
            g ? visit_tv_d(job, nb, 3, 1, 1) : visit_tv_d(job, nb, 3, 1, 0);
        else
            g ? visit_tv_d(job, nb, 3, 0, 1) : visit_tv_d(job, nb, 3, 0, 0);
    }
}

/* ---- wcsph ---- */
RV_INLINE void visit_wcsph_d(const rival_job *job, const consph_nbhd *nb, const int d,
                             const int grads)
{
    const size_t i = nb->i, cap = job->cap;
    const double *u = job->u;
    const double rhoi = job->rho[i], ti = job->pr2[i];
    const pysph_consts *c = &job->c;
    const int av = c->alpha > 0.0;
    const double ci = av ? job->cs[i] : 0.0;
    double ui[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) ui[a] = u[a * cap + i];
    double f[3] = {0.0, 0.0, 0.0}, xs[3] = {0.0, 0.0, 0.0}, fp[3] = {0.0, 0.0, 0.0}, drho = 0.0;
    double G[9] = {0.0};
    for (size_t k0 = 0; k0 < nb->n; k0 += RV_BLOCK) {
        const size_t nk = nb->n - k0 < RV_BLOCK ? nb->n - k0 : RV_BLOCK;
        const size_t *jb = nb->j + k0;
        double rhoj[RV_BLOCK], tj[RV_BLOCK], mr[RV_BLOCK], cj[RV_BLOCK], uj[3][RV_BLOCK];
        double tf[3][RV_BLOCK], tp[3][RV_BLOCK], tx[3][RV_BLOCK], tg[9][RV_BLOCK];
        double td[RV_BLOCK];
        rv_gather(1, 0, job->rho, jb, nk, &rhoj);
        rv_gather(1, 0, job->pr2, jb, nk, &tj);
        if (grads) rv_gather(1, 0, job->mrho, jb, nk, &mr);
        rv_gather(d, cap, u, jb, nk, uj);
        double pij[RV_BLOCK], inv_s[RV_BLOCK], inv_r[RV_BLOCK];
        for (size_t k = 0; k < nk; ++k) {
            pij[k] = 0.0;
            inv_s[k] = 1.0 / (rhoi + rhoj[k]);
            inv_r[k] = 1.0 / (nb->r[k0 + k] * nb->r[k0 + k] + c->h2);
        }
        if (av) {
            rv_gather(1, 0, job->cs, jb, nk, &cj);
            for (size_t k = 0; k < nk; ++k) {
                double ux = 0.0;
                for (int a = 0; a < d; ++a) ux += (ui[a] - uj[a][k]) * nb->dx[a][k0 + k];
                pij[k] = pysph_monaghan_pi(c, ci, cj[k], ux, inv_r[k], inv_s[k]);
            }
        }
        for (size_t k = 0; k < nk; ++k) {
            /* the particle itself gets terms too (∇W_ii = 0); they are not summed */
            double xij[3] = {0.0, 0.0, 0.0}, ujk[3] = {0.0, 0.0, 0.0};
            for (int a = 0; a < d; ++a) {
                xij[a] = nb->dx[a][k0 + k];
                ujk[a] = uj[a][k];
            }
            pysph_pair o;
            pysph_wcsph_pair(d, c, ti, ui, tj[k], grads ? mr[k] : 0.0, ujk, pij[k], nb->w[k0 + k],
                             nb->dwr[k0 + k], xij, inv_s[k], inv_r[k], &o);
            for (int a = 0; a < d; ++a) {
                tf[a][k] = o.f[a];
                tx[a][k] = o.fb[a];
                if (grads) tp[a][k] = o.fp[a];
            }
            td[k] = o.div;
            if (grads)
                for (int e = 0; e < d * d; ++e) tg[e][k] = o.g[e];
        }
        for (size_t k = 0; k < nk; ++k) {
            if (jb[k] == i) continue;
            for (int a = 0; a < d; ++a) {
                f[a] += tf[a][k];
                xs[a] -= tx[a][k];
                if (grads) fp[a] += tp[a][k];
            }
            drho += td[k];
            if (grads)
                for (int e = 0; e < d * d; ++e) G[e] -= tg[e][k];
        }
    }
    for (int a = 0; a < d; ++a) {
        job->au[a * cap + i] = f[a];
        job->ax[a * cap + i] = ui[a] + xs[a];
    }
    job->aq[i] = drho;
    put_diag(job, i, fp, -drho / rhoi, G, d, grads);
}

RV_CLONES static void visit_wcsph(void *vjob, const consph_nbhd *nb)
{
    const rival_job *job = vjob;
    const int g = job->grads;
    if (job->d == 2)
        g ? visit_wcsph_d(job, nb, 2, 1) : visit_wcsph_d(job, nb, 2, 0);
    else /* 3D */
        g ? visit_wcsph_d(job, nb, 3, 1) : visit_wcsph_d(job, nb, 3, 0);
}

/* ---- the same visits over groups of particles (src/pass/group.h) ----
 *
 * Each sum above is a chain of dependent additions in neighbour order, whose latency bounds the
 * visit. The group visits run the chains of PASS_GROUP particles of one cell side by side, one
 * particle per lane of a vector: lane l computes the terms of its own particle's k-th neighbour
 * with the operations of the pair functions (iact.h) in their order and adds them to its own
 * sums in its own neighbour order, so every value is the per-particle visit's bit for bit
 * (tests/test_pysph_group.c). GCC's and clang's vector extensions; other compilers run the
 * per-particle visits. */
#ifdef CONSPH_LANES4
#define RV_GROUPS 1
/* GCC builds a vector from scalars by inserting them into the destination's old value, and then
 * warns that the old value may be uninitialised (it is never read) */
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
/* acc + t in the lanes of m; the others keep acc */
#define RV_ADD(acc, m, t) ((acc) = LANE4_SEL((m), (acc) + (t), (acc)))
#define RV_SUB(acc, m, t) ((acc) = LANE4_SEL((m), (acc) - (t), (acc)))
/* The same with the lanes that keep acc given (k), as acc ± t with t made +0 in them: the sum's
 * chain is the addition alone, not an addition and a select after it. It gives
 * RV_ADD's and RV_SUB's values bit for bit: x - (+0) is x for every x, and x + (+0) for every x
 * but -0; a sum that starts at +0 and adds never is -0 (a sum is -0 only if both addends are). */
#define RV_ADD_UNLESS(acc, k, t) ((acc) += (lane4)(~(k) & (lane4i)(t)))
#define RV_SUB_UNLESS(acc, k, t) ((acc) -= (lane4)(~(k) & (lane4i)(t)))

/* The group's lanes (src/pass/group.h: every lane's arrays reach kmax, and the lanes past
 * count repeat the first, whose sums are never written). */
typedef struct rv_lanes {
    const consph_nbhd *nb[PASS_GROUP];
    size_t i[PASS_GROUP], kmax;
    lane4i n;
    int count;
} rv_lanes;

RV_INLINE void rv_lanes_of(rv_lanes *L, const consph_nbhd *nb, int count)
{
    L->count = count;
    L->kmax = 0;
    for (int l = 0; l < PASS_GROUP; ++l) {
        L->nb[l] = &nb[l];
        L->i[l] = nb[l].i;
        L->n[l] = (long long)nb[l].n;
        if (nb[l].n > L->kmax) L->kmax = nb[l].n;
    }
}

/* The neighbours j of entry k of each lane, and the lanes that sum it: all but the padding
 * (skip_self: all but the particle itself, ∇W_ii = 0, which the padding is too). */
RV_INLINE void rv_entry(const rv_lanes *L, size_t k, size_t j[PASS_GROUP], int skip_self, lane4i *m)
{
    for (int l = 0; l < PASS_GROUP; ++l) j[l] = L->nb[l]->j[k];
    if (skip_self) {
        const lane4i jv = {(long long)j[0], (long long)j[1], (long long)j[2], (long long)j[3]};
        const lane4i iv = {(long long)L->i[0], (long long)L->i[1], (long long)L->i[2],
                           (long long)L->i[3]};
        *m = (lane4i)(jv != iv);
    } else {
        *m = (lane4i)((long long)k < L->n);
    }
}

#define RV_AT(arr, idx)                                                                            \
    ((lane4){(arr)[(idx)[0]], (arr)[(idx)[1]], (arr)[(idx)[2]], (arr)[(idx)[3]]})
#define RV_NB(L, field, k)                                                                         \
    ((lane4){(L)->nb[0]->field[k], (L)->nb[1]->field[k], (L)->nb[2]->field[k],                     \
             (L)->nb[3]->field[k]})
/* Entries o..o+3 of the four lanes' rows q[l], as four vectors (a 4×4 transpose). */
typedef double rv4u __attribute__((vector_size(4 * sizeof(double)), aligned(sizeof(double))));
#if defined(__clang__)
#define RV_SHUF(a, b, i0, i1, i2, i3) __builtin_shufflevector(a, b, i0, i1, i2, i3)
#else
#define RV_SHUF(a, b, i0, i1, i2, i3) __builtin_shuffle(a, b, (lane4i){i0, i1, i2, i3})
#endif
RV_INLINE void rv_transpose(const double *const q[PASS_GROUP], size_t o, lane4 *f0, lane4 *f1,
                            lane4 *f2, lane4 *f3)
{
    const lane4 a0 = *(const rv4u *)(q[0] + o), a1 = *(const rv4u *)(q[1] + o);
    const lane4 a2 = *(const rv4u *)(q[2] + o), a3 = *(const rv4u *)(q[3] + o);
    const lane4 t0 = RV_SHUF(a0, a1, 0, 4, 2, 6), t1 = RV_SHUF(a0, a1, 1, 5, 3, 7);
    const lane4 t2 = RV_SHUF(a2, a3, 0, 4, 2, 6), t3 = RV_SHUF(a2, a3, 1, 5, 3, 7);
    *f0 = RV_SHUF(t0, t2, 0, 1, 4, 5);
    *f1 = RV_SHUF(t1, t3, 0, 1, 4, 5);
    *f2 = RV_SHUF(t0, t2, 2, 3, 6, 7);
    *f3 = RV_SHUF(t1, t3, 2, 3, 6, 7);
}
#define RV_PK(q, o) ((lane4){(q)[0][o], (q)[1][o], (q)[2][o], (q)[3][o]})
#define RV_I(L, arr)                                                                               \
    ((lane4){(arr)[(L)->i[0]], (arr)[(L)->i[1]], (arr)[(L)->i[2]], (arr)[(L)->i[3]]})

/* A chunk of a group's entries, interleaved: entry k's four lanes side by side, so that the
 * entry loops read each value of an entry with one vector load. Gathering an entry's vector from
 * four lanes' arrays took a scalar load, and with more arrays than registers a reload of the
 * array's address, per lane and value; staged, four entries of a lane are read at once and
 * transposed. */
#define RV_CHUNK 32
typedef struct rv_stage {
    lane4 w[RV_CHUNK], dwr[RV_CHUNK], r[RV_CHUNK], dx[3][RV_CHUNK];
    lane4i j[RV_CHUNK];
} rv_stage;

/* size_t viewed as a vector of four (the neighbour indices of four entries of a lane) */
typedef unsigned long rv4j __attribute__((vector_size(4 * sizeof(unsigned long)),
                                          aligned(sizeof(unsigned long)), may_alias));

/* Entries k0..k0+nk (nk ≤ RV_CHUNK, within every lane's kmax) into st: j << sh always (sh = 6:
 * the byte offset of j's line in a pack of 64-byte lines, which the entry loop then adds to the
 * pack's address without a shift of its own), and w, dwr, r and the d separations where
 * wanted. */
RV_INLINE void rv_stage_of(const rv_lanes *L, size_t k0, size_t nk, const int d, const int ww,
                           const int wdwr, const int wr, const int sh, rv_stage *st)
{
    size_t k = 0;
    for (; k + 4 <= nk; k += 4) {
        const size_t o = k0 + k;
#define RV_T(field, out)                                                                           \
    do {                                                                                           \
        const double *const q_[PASS_GROUP] = {L->nb[0]->field + o, L->nb[1]->field + o,            \
                                              L->nb[2]->field + o, L->nb[3]->field + o};           \
        lane4_transpose(q_, 0, out);                                                               \
    } while (0)
        if (ww) RV_T(w, &st->w[k]);
        if (wdwr) RV_T(dwr, &st->dwr[k]);
        if (wr) RV_T(r, &st->r[k]);
        for (int a = 0; a < d; ++a) RV_T(dx[a], &st->dx[a][k]);
#undef RV_T
        const lane4i a0 = (lane4i)(*(const rv4j *)(L->nb[0]->j + o));
        const lane4i a1 = (lane4i)(*(const rv4j *)(L->nb[1]->j + o));
        const lane4i a2 = (lane4i)(*(const rv4j *)(L->nb[2]->j + o));
        const lane4i a3 = (lane4i)(*(const rv4j *)(L->nb[3]->j + o));
        const lane4i t0 = LANE4_SHUF(a0, a1, 0, 4, 2, 6), t1 = LANE4_SHUF(a0, a1, 1, 5, 3, 7);
        const lane4i t2 = LANE4_SHUF(a2, a3, 0, 4, 2, 6), t3 = LANE4_SHUF(a2, a3, 1, 5, 3, 7);
        st->j[k] = LANE4_SHUF(t0, t2, 0, 1, 4, 5) << sh;
        st->j[k + 1] = LANE4_SHUF(t1, t3, 0, 1, 4, 5) << sh;
        st->j[k + 2] = LANE4_SHUF(t0, t2, 2, 3, 6, 7) << sh;
        st->j[k + 3] = LANE4_SHUF(t1, t3, 2, 3, 6, 7) << sh;
    }
    for (; k < nk; ++k) {
        const size_t o = k0 + k;
        if (ww) st->w[k] = RV_NB(L, w, o);
        if (wdwr) st->dwr[k] = RV_NB(L, dwr, o);
        if (wr) st->r[k] = RV_NB(L, r, o);
        for (int a = 0; a < d; ++a) st->dx[a][k] = RV_NB(L, dx[a], o);
        st->j[k] = (lane4i){(long long)L->nb[0]->j[o], (long long)L->nb[1]->j[o],
                            (long long)L->nb[2]->j[o], (long long)L->nb[3]->j[o]}
                   << sh;
    }
}

/* slots: the entries' j are slots (PASS_GROUP_SLOTS), and edac reads p in slot order */
RV_INLINE void group_density(const rival_job *job, const consph_nbhd *nb, int count,
                             const int slots)
{
    rv_lanes L;
    rv_lanes_of(&L, nb, count);
    const int edac = job->kind != RV_TVF;
    const double *p = slots ? job->pslot : job->p;
    lane4 s = {0.0, 0.0, 0.0, 0.0}, ps = s;
    size_t j[PASS_GROUP] = {0};
    for (size_t k = 0; k < L.kmax; ++k) {
        /* the padding's W is +0, which leaves a sum from +0 as it is: no mask, and the chain is
         * the addition alone */
        s += RV_NB(&L, w, k);
        if (edac) {
            lane4i m;
            rv_entry(&L, k, j, 0, &m);
            RV_ADD_UNLESS(ps, ~m, RV_AT(p, j));
        }
    }
    for (int l = 0; l < count; ++l) {
        const size_t i = L.i[l];
        job->numd[i] = s[l];
        job->rhos[i] = job->c.m * s[l];
        job->vol[i] = 1.0 / s[l];
        job->mrho[i] = job->c.m / job->rhos[i];
        if (job->kind == RV_TVF)
            job->pw[i] = job->p0 * (job->rhos[i] / job->rho0 - 1.0);
        else
            job->pavg[i] = ps[l] / (double)L.nb[l]->n;
    }
}

RV_GROUP_CLONES static void group_visit_density(void *vjob, const consph_nbhd *nb, int count)
{
    group_density(vjob, nb, count, 0);
}

/* tvf and edac: ϱ, p, V, m/ϱ, u and ũ - u of particle i into the pack at its slot (after its
 * density visit, which sets ϱ, V, m/ϱ and tvf's p). */
RV_INLINE void tv_pack_one(const rival_job *job, size_t i)
{
    const size_t cap = job->cap;
    const int d = job->d;
    double *q = job->pack + job->slot_of[i] * job->pk;
    q[0] = job->rho[i];
    q[1] = job->p[i];
    q[2] = job->vol[i];
    q[3] = job->mrho[i];
    for (int a = 0; a < d; ++a) {
        q[4 + a] = job->u[a * cap + i];
        q[4 + d + a] = job->tvdu[a * cap + i];
    }
}

/* The density visit that also packs its particles for the rates visit (pass_run_groups2: the
 * rates of a particle may run before the density pass has reached every particle). */
RV_GROUP_CLONES static void group_visit_density_pack(void *vjob, const consph_nbhd *nb, int count)
{
    const rival_job *job = vjob;
    group_density(job, nb, count, 1);
    for (int l = 0; l < count; ++l) tv_pack_one(job, nb[l].i);
}

/* visit_tv_d over a group: pysph_tv_pair's operations in its order, per lane, the entries staged
 * as group_wcsph_d's, or read as they come where pass_run_groups2 hands them interleaved (il:
 * PASS_GROUP_INTERLEAVED, entry k's four lanes at 4k of nb[0]'s arrays; lanes past count repeat
 * lane 0, as the staging of nb[count..) = nb[0] does). */
RV_INLINE void group_tv_d(const rival_job *job, const consph_nbhd *nb, int count, const int d,
                          const int edac, const int grads, const int il)
{
    rv_lanes L;
    rv_lanes_of(&L, nb, count);
    const size_t cap = job->cap;
    const pysph_consts *c = &job->c;
    const lane4 rhoi = RV_I(&L, job->rho), pi = RV_I(&L, job->p), Vi = RV_I(&L, job->vol);
    const lane4 zero = {0.0, 0.0, 0.0, 0.0};
    const lane4 pav = edac ? RV_I(&L, job->pavg) : zero;
    lane4 ui[3] = {zero, zero, zero}, dui[3] = {zero, zero, zero};
    for (int a = 0; a < d; ++a) {
        ui[a] = RV_I(&L, job->u + a * cap);
        dui[a] = RV_I(&L, job->tvdu + a * cap);
    }
    /* the entries' j are slots (PASS_GROUP_SLOTS), the pack in slot order; 2D packs a particle on
     * a 64-byte line: j staged as its byte offset */
    const int sh = d == 2 ? 6 : 0;
    const size_t *so = job->slot_of;
    const lane4i iv = (lane4i){(long long)so[L.i[0]], (long long)so[L.i[1]], (long long)so[L.i[2]],
                               (long long)so[L.i[3]]}
                      << sh;
    lane4 f[3] = {zero, zero, zero}, fb[3] = {zero, zero, zero}, fp[3] = {zero, zero, zero};
    lane4 G[9] = {zero, zero, zero, zero, zero, zero, zero, zero, zero}, div = zero, ap = zero;
    rv_stage st;
    for (size_t k0 = 0; k0 < L.kmax; k0 += RV_CHUNK) {
        const size_t nk = L.kmax - k0 < RV_CHUNK ? L.kmax - k0 : RV_CHUNK;
        if (!il) rv_stage_of(&L, k0, nk, d, 0, 1, 1, sh, &st);
        for (size_t k = 0; k < nk; ++k) {
            const size_t e = PASS_GROUP * (k0 + k);
            lane4i jk;
            lane4 dwr, r;
            lane4 xij[3] = {zero, zero, zero}, uj[3] = {zero, zero, zero},
                  duj[3] = {zero, zero, zero};
            if (il) {
                jk = (lane4i)(*(const rv4j *)(nb[0].j + e)) << sh;
                dwr = *(const rv4u *)(nb[0].dwr + e);
                r = *(const rv4u *)(nb[0].r + e);
                for (int a = 0; a < d; ++a) xij[a] = *(const rv4u *)(nb[0].dx[a] + e);
            } else {
                jk = st.j[k];
                dwr = st.dwr[k];
                r = st.r[k];
                for (int a = 0; a < d; ++a) xij[a] = st.dx[a][k];
            }
            /* the particle itself and the padding: ∇W_ii = 0, not summed */
            const lane4i self = (lane4i)(jk == iv);
            const long long *js = (const long long *)&jk;
            const double *q[PASS_GROUP];
            for (int l = 0; l < PASS_GROUP; ++l)
                q[l] = d == 2 ? (const double *)((const char *)job->pack + js[l])
                              : job->pack + (size_t)js[l] * job->pk;
            lane4 rhoj, pj, Vj, vj;
            rv_transpose(q, 0, &rhoj, &pj, &Vj, &vj);
            if (d == 2) {
                rv_transpose(q, 4, &uj[0], &uj[1], &duj[0], &duj[1]);
            } else {
                for (int a = 0; a < d; ++a) {
                    uj[a] = RV_PK(q, 4 + a);
                    duj[a] = RV_PK(q, 4 + d + a);
                }
            }
            /* pysph_tv_pair */
            const lane4 w2 = Vi * Vi + Vj * Vj;
            lane4 uij[3] = {zero, zero, zero}, gw[3] = {zero, zero, zero};
            for (int a = 0; a < d; ++a) {
                gw[a] = dwr * xij[a];
                uij[a] = ui[a] - uj[a];
            }
            /* The dot products and A below start from their first product, not from 0 + it as
             * pysph_tv_pair's do: that differs only where the product is -0, and then only in
             * the sign of a zero (x + y is -0 only if both are), which reaches no sum: a term
             * is ±0 where it differs, and each sum, starting at +0, is never -0, so s ± 0 = s.
             * No term divides by these values or tests their sign. */
            lane4 xdw = xij[0] * gw[0], udw = uij[0] * gw[0];
            for (int a = 1; a < d; ++a) {
                xdw += xij[a] * gw[a];
                udw += uij[a] * gw[a];
            }
            const lane4 r2 = r * r;
            const lane4 inv_s = 1.0 / (rhoi + rhoj), inv_r = 1.0 / (r2 + c->h2);
            const lane4 pij = (rhoj * (pi - pav) + rhoi * (pj - pav)) * inv_s;
            const lane4 rr = rhoi * rhoj * inv_s, wx = w2 * xdw * inv_r;
            const lane4 visc = 2.0 * c->nu * rr * wx;
            for (int a = 0; a < d; ++a) {
                lane4 A = 0.5 * (rhoi * ui[a] * dui[0] + rhoj * uj[a] * duj[0]) * gw[0];
                for (int b = 1; b < d; ++b)
                    A += 0.5 * (rhoi * ui[a] * dui[b] + rhoj * uj[a] * duj[b]) * gw[b];
                RV_ADD_UNLESS(f[a], self, -pij * w2 * gw[a] + visc * uij[a] + w2 * A);
                RV_ADD_UNLESS(fb[a], self, -c->pb * w2 * gw[a]);
                if (grads) RV_ADD_UNLESS(fp[a], self, -pij * w2 * gw[a] * c->minv);
            }
            if (grads)
                for (int a = 0; a < d; ++a)
                    for (int b = 0; b < d; ++b)
                        RV_SUB_UNLESS(G[a * d + b], self, vj * uij[a] * gw[b]);
            RV_SUB_UNLESS(div, self, vj * udw);
            if (edac) {
                RV_ADD_UNLESS(ap, self, rhoi * vj * c->c0 * c->c0 * udw);
                RV_ADD_UNLESS(ap, self, 2.0 * c->nu_edac * rr * wx * (pi - pj) * c->minv);
            }
        }
    }
    for (int l = 0; l < count; ++l) {
        const size_t i = L.i[l];
        double fpl[3] = {0.0, 0.0, 0.0}, Gl[9] = {0.0};
        for (int a = 0; a < d; ++a) {
            job->au[a * cap + i] = f[a][l] / c->m;
            job->auhat[a * cap + i] = fb[a][l] / c->m;
            fpl[a] = fp[a][l];
        }
        for (int e = 0; e < d * d; ++e) Gl[e] = G[e][l];
        job->aq[i] = ap[l];
        put_diag(job, i, fpl, div[l], Gl, d, grads);
    }
}

#define RV_TV_VISIT(name, il)                                                                      \
    RV_GROUP_CLONES static void name(void *vjob, const consph_nbhd *nb, int count)                 \
    {                                                                                              \
        const rival_job *job = vjob;                                                               \
        const int edac = job->kind == RV_EDAC, g = job->grads;                                     \
        if (job->d == 2) {                                                                         \
            if (edac)                                                                              \
                g ? group_tv_d(job, nb, count, 2, 1, 1, il)                                        \
                  : group_tv_d(job, nb, count, 2, 1, 0, il);                                       \
            else                                                                                   \
                g ? group_tv_d(job, nb, count, 2, 0, 1, il)                                        \
                  : group_tv_d(job, nb, count, 2, 0, 0, il);                                       \
        } else {                                                                                   \
            if (edac)                                                                              \
                g ? group_tv_d(job, nb, count, 3, 1, 1, il)                                        \
                  : group_tv_d(job, nb, count, 3, 1, 0, il);                                       \
            else                                                                                   \
                g ? group_tv_d(job, nb, count, 3, 0, 1, il)                                        \
                  : group_tv_d(job, nb, count, 3, 0, 0, il);                                       \
        }                                                                                          \
    }
RV_TV_VISIT(group_visit_tv, 0)
/* the rates visit of pass_run_groups2, which hands the entries interleaved */
RV_TV_VISIT(group_visit_tv_il, 1)
#undef RV_TV_VISIT

/* visit_wcsph_d over a group: pysph_monaghan_pi's and pysph_wcsph_pair's operations. The pack
 * holds ϱ, p/ϱ², u_x, u_y of a particle in its first four doubles (what 2D without the artificial
 * viscosity and ∇u reads: one transpose), m/ϱ, c, u_z in the next. */
RV_INLINE void group_wcsph_d(const rival_job *job, const consph_nbhd *nb, int count, const int d,
                             const int grads, const int av)
{
    rv_lanes L;
    rv_lanes_of(&L, nb, count);
    const size_t cap = job->cap;
    const pysph_consts *c = &job->c;
    const lane4 zero = {0.0, 0.0, 0.0, 0.0};
    const lane4 rhoi = RV_I(&L, job->rho), ti = RV_I(&L, job->pr2);
    const lane4 ci = av ? RV_I(&L, job->cs) : zero;
    /* the lanes' own slots (PASS_GROUP_SLOTS: the entries' j are slots, the pack in slot order) */
    const size_t *so = job->slot_of;
    const lane4i iv = (lane4i){(long long)so[L.i[0]], (long long)so[L.i[1]], (long long)so[L.i[2]],
                               (long long)so[L.i[3]]}
                      << 6;
    lane4 ui[3] = {zero, zero, zero};
    for (int a = 0; a < d; ++a) ui[a] = RV_I(&L, job->u + a * cap);
    lane4 f[3] = {zero, zero, zero}, xs[3] = {zero, zero, zero}, fp[3] = {zero, zero, zero};
    lane4 G[9] = {zero, zero, zero, zero, zero, zero, zero, zero, zero}, drho = zero;
    const double m = c->m;
    rv_stage st;
    for (size_t k0 = 0; k0 < L.kmax; k0 += RV_CHUNK) {
        const size_t nk = L.kmax - k0 < RV_CHUNK ? L.kmax - k0 : RV_CHUNK;
        rv_stage_of(&L, k0, nk, d, 1, 1, 1, 6, &st);
        for (size_t k = 0; k < nk; ++k) {
            /* the lanes whose entry is the particle itself or the padding keep their sums */
            const lane4i self = (lane4i)(st.j[k] == iv);
            const long long *js = (const long long *)&st.j[k];
            const double *q[PASS_GROUP];
            for (int l = 0; l < PASS_GROUP; ++l)
                q[l] = (const double *)((const char *)job->pack + js[l]);
            lane4 rhoj, tj, vj = zero, cj = zero, uj[3] = {zero, zero, zero}, pad;
            rv_transpose(q, 0, &rhoj, &tj, &uj[0], &uj[1]);
            if (av || grads || d == 3) rv_transpose(q, 4, &vj, &cj, &uj[2], &pad);
            (void)pad;
            const lane4 w = st.w[k], dwr = st.dwr[k], r = st.r[k];
            lane4 xij[3] = {zero, zero, zero};
            for (int a = 0; a < d; ++a) xij[a] = st.dx[a][k];
            const lane4 inv_s = 1.0 / (rhoi + rhoj), inv_r = 1.0 / (r * r + c->h2);
            lane4 pij = zero;
            if (av) {
                lane4 ux = zero;
                for (int a = 0; a < d; ++a) ux += (ui[a] - uj[a]) * xij[a];
                /* pysph_monaghan_pi */
                const lane4 mu = c->h * ux * inv_r;
                const lane4 v = -c->alpha * (ci + cj) * mu * inv_s;
                pij = LANE4_SEL((lane4i)(ux < 0.0), v, zero);
            }
            /* pysph_wcsph_pair */
            lane4 uij[3] = {zero, zero, zero}, gw[3] = {zero, zero, zero};
            for (int a = 0; a < d; ++a) {
                uij[a] = ui[a] - uj[a];
                gw[a] = dwr * xij[a];
            }
            lane4 udw = zero, xdw = zero;
            for (int a = 0; a < d; ++a) {
                udw += uij[a] * gw[a];
                xdw += xij[a] * gw[a];
            }
            const lane4 visc = m * 4.0 * c->nu * xdw * inv_s * inv_r;
            for (int a = 0; a < d; ++a) {
                RV_ADD_UNLESS(f[a], self, -m * (ti + tj + pij) * gw[a] + visc * uij[a]);
                RV_SUB_UNLESS(xs[a], self, m * w * inv_s * uij[a]);
                if (grads) RV_ADD_UNLESS(fp[a], self, -m * (ti + tj) * gw[a]);
            }
            RV_ADD_UNLESS(drho, self, m * udw);
            if (grads)
                for (int a = 0; a < d; ++a)
                    for (int b = 0; b < d; ++b)
                        RV_SUB_UNLESS(G[a * d + b], self, vj * uij[a] * gw[b]);
        }
    }
    for (int l = 0; l < count; ++l) {
        const size_t i = L.i[l];
        double fpl[3] = {0.0, 0.0, 0.0}, Gl[9] = {0.0};
        for (int a = 0; a < d; ++a) {
            job->au[a * cap + i] = f[a][l];
            job->ax[a * cap + i] = ui[a][l] + xs[a][l];
            fpl[a] = fp[a][l];
        }
        for (int e = 0; e < d * d; ++e) Gl[e] = G[e][l];
        job->aq[i] = drho[l];
        put_diag(job, i, fpl, -drho[l] / rhoi[l], Gl, d, grads);
    }
}

RV_GROUP_CLONES static void group_visit_wcsph(void *vjob, const consph_nbhd *nb, int count)
{
    const rival_job *job = vjob;
    const int g = job->grads;
    /* Monaghan's Π_ij a compile-time choice too: the common runs have α = 0 */
    if (job->c.alpha > 0.0) {
        if (job->d == 2)
            g ? group_wcsph_d(job, nb, count, 2, 1, 1) : group_wcsph_d(job, nb, count, 2, 0, 1);
        else
            g ? group_wcsph_d(job, nb, count, 3, 1, 1) : group_wcsph_d(job, nb, count, 3, 0, 1);
    } else if (job->d == 2) {
        g ? group_wcsph_d(job, nb, count, 2, 1, 0) : group_wcsph_d(job, nb, count, 2, 0, 0);
    } else {
        g ? group_wcsph_d(job, nb, count, 3, 1, 0) : group_wcsph_d(job, nb, count, 3, 0, 0);
    }
}
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif /* __GNUC__ */

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC pop_options
#endif

#ifdef RV_GROUPS
/* Whether the group visits get their pack, in the search's slot order (PASS_GROUP_SLOTS): the
 * search holds every particle (a decomposed system's halo too); its slots into *v. */
static int rv_packed(const consph_solver *s, consph_nnps_slots *v)
{
    return pysph_group_visits && consph_nnps_slots_get(s->sys.nnps, v) == CONSPH_OK &&
           v->n == s->sys.p->n;
}

/* The pack of nn particles at stride pk on the first 64-byte line from `at` (the scratch holds
 * pk·nn + 8 doubles there), and the slot of each particle (nn) behind it. */
static double *rv_pack_at(double *at, size_t pk, size_t nn, size_t **slot_of)
{
    while ((uintptr_t)at % 64) ++at;
    *slot_of = (size_t *)(at + pk * nn);
    return at;
}
#endif

/* wcsph's p/ϱ² (and m/ϱ) of particles [i0, i1), in particle order: loops the compiler
 * vectorises (divisions give the same bits at any width), where the pack's sweep by slot (an
 * indirect index) waited on one division at a time. */
LANE4_CLONES static void rv_ratios(const double *restrict p, const double *restrict rho,
                                   double *restrict pr2, double *restrict mrho, double m, size_t i0,
                                   size_t i1)
{
    for (size_t i = i0; i < i1; ++i) pr2[i] = p[i] / (rho[i] * rho[i]);
    if (mrho)
        for (size_t i = i0; i < i1; ++i) mrho[i] = m / rho[i];
}

/* Particles per block of rv_ratios, shared out among the threads. */
#define RV_RATIO_BLOCK 4096

static int job_fields(consph_solver *s, rival_job *job, int kind)
{
    const int d = s->dim;
    memset(job, 0, sizeof *job);
    job->kind = kind;
    job->d = d;
    job->cap = s->sys.p->cap;
    job->c.m = s->mass;
    job->c.minv = 1.0 / s->mass;
    job->c.h = s->h;
    job->c.h2 = 0.01 * s->h * s->h; /* PySPH's EPS = 0.01 h_ij² in every 1/(r² + EPS) */
    job->rho0 = s->prm.rho0;
    job->c.c0 = s->c0;
    job->cexp = 0.5 * (s->prm.gamma - 1.0); /* Tait's sound speed c_o (ϱ/ϱ_o)^((γ-1)/2) */
    job->c.nu = s->nu;
    job->c.alpha = s->prm.alpha >= 0.0 ? s->prm.alpha : 0.1; /* PySPH WCSPHScheme */
    job->p0 = s->c0 * s->c0 * s->prm.rho0;                   /* tvf's p_o = c_o² ϱ_o */
    job->c.pb = job->p0; /* Adami et al. §2.3; PySPH's taylor_green: p_b = p_o */
    job->c.nu_edac = 0.5 * s->h * s->c0 / 8.0; /* Ramachandran & Puri: α_edac h c_o / 8, α = 0.5 */
    job->u = sv_field(s, SF_U, d);
    job->p = sv_field(s, SF_P, 1);
    job->au = sv_field(s, SF_AU, d);
    job->aq = sv_field(s, SF_AQ, 1);
    job->ax = sv_field(s, SF_AX, d);
    job->gradp = sv_field(s, SF_GRADP, d);
    job->divu = sv_field(s, SF_DIVU, 1);
    job->gradu = sv_field(s, SF_GRADU, d * d);
    job->grads = !s->grads_skip;
    if (!job->u || !job->p || !job->au || !job->aq || !job->ax || !job->gradp || !job->divu ||
        !job->gradu)
        return CONSPH_ENOMEM;
    if (kind == RV_WCSPH) {
        job->rho = sv_field(s, SF_RHOF, 1);
        if (!job->rho) return CONSPH_ENOMEM;
        /* Tait's c_o (ϱ/ϱ_o)^((γ-1)/2) once per particle for Monaghan's Π_ij (a pow() per
         * approaching pair cost more than the rest of the pair), p/ϱ² and m/ϱ */
        const size_t n = s->sys.p->n, nn = n ? n : 1;
        size_t want = 3 * nn;
#ifdef RV_GROUPS
        /* the pack of the group visit: ϱ, p/ϱ², u_x, u_y, m/ϱ, c, u_z per particle on a 64-byte
         * line, in the search's slot order (PASS_GROUP_SLOTS), and the slot of each particle */
        job->pk = 8;
        consph_nnps_slots v;
        const int packed = rv_packed(s, &v);
        want += packed ? job->pk * nn + 8 + nn : 0;
        /* A decomposed system: the halo refreshed first, then p/ϱ², m/ϱ and c computed for it
         * too (the same operations on its owners' ϱ and p: their values bit for bit) and its
         * rows packed, all in a buffer of the system's own (the refresh carries the scratch as
         * columns, which would write over the pack's rows): no scratch travels. */
        const int own = packed && s->sys.split;
#else
        const int own = 0;
#endif
        double *sc = own ? sys_pack_buffer(&s->sys, want) : consph_sys_scratch(&s->sys, want);
        if (!sc) return CONSPH_ENOMEM;
        if (own) {
            (void)consph_sys_scratch(&s->sys, 0); /* none asked: the refresh carries none */
            const int st = pass_halo_refresh(&s->sys);
            if (st != CONSPH_OK) return st;
        }
        double *pr2 = sc, *mrho = sc + nn, *cs = sc + 2 * nn, *pack = NULL;
        size_t *slot_of = NULL;
        const size_t *particle = NULL;
#ifdef RV_GROUPS
        if (packed) {
            pack = rv_pack_at(sc + 3 * nn, job->pk, nn, &slot_of);
            particle = v.particle;
        }
#endif
        const size_t cap = job->cap;
        const double *u = job->u;
        const double *rho = job->rho, *p = job->p, c0 = job->c.c0, rho0 = job->rho0;
        const double cexp = job->cexp, m = job->c.m;
        const int ie = eos_int_exponent(cexp); /* γ = 7: the cube, by multiplication */
        const int av = job->c.alpha > 0.0, grads = job->grads;
        const size_t nb = (n + RV_RATIO_BLOCK - 1) / RV_RATIO_BLOCK;
#pragma omp parallel for schedule(static) if (n >= s->sys.parallel_min)
        for (size_t b = 0; b < nb; ++b) {
            const size_t i0 = b * RV_RATIO_BLOCK, i1 = b + 1 < nb ? i0 + RV_RATIO_BLOCK : n;
            rv_ratios(p, rho, pr2, grads ? mrho : NULL, m, i0, i1);
            if (av)
                for (size_t i = i0; i < i1; ++i)
                    cs[i] = c0 * (ie >= 0 ? eos_ipow(rho[i] / rho0, ie) : pow(rho[i] / rho0, cexp));
        }
        if (pack) {
#pragma omp parallel for schedule(static) if (n >= s->sys.parallel_min)
            for (size_t sl = 0; sl < n; ++sl) {
                /* by slot: the particle in slot sl (each particle once) */
                const size_t i = particle ? particle[sl] : sl;
                slot_of[i] = sl;
                double *q = pack + sl * 8;
                q[0] = rho[i];
                q[1] = pr2[i];
                q[2] = u[i];
                q[3] = d > 1 ? u[cap + i] : 0.0;
                q[4] = grads ? mrho[i] : 0.0;
                q[5] = av ? cs[i] : 0.0;
                q[6] = d > 2 ? u[2 * cap + i] : 0.0;
                q[7] = 0.0;
            }
        }
        job->pack = pack;
        job->slot_of = slot_of;
        job->pr2 = pr2;
        job->mrho = mrho;
        if (av) job->cs = cs;
        return CONSPH_OK;
    }
    job->rhos = sv_field(s, SF_RHOS, 1);
    job->rho = job->rhos;
    job->pw = sv_field(s, SF_P, 1);
    job->numd = sv_field(s, SF_NUMD, 1);
    job->pavg = sv_field(s, SF_PAVG, 1);
    job->tvdu = sv_field(s, SF_TVDU, d);
    job->auhat = sv_field(s, SF_UHAT, d);
    if (!job->rhos || !job->numd || !job->pavg || !job->tvdu || !job->auhat) return CONSPH_ENOMEM;
    /* 1/V and m/ϱ of each particle, set by the density pass */
    const size_t n = s->sys.p->n, nn = n ? n : 1;
    size_t want = 2 * nn;
#ifdef RV_GROUPS
    /* the pack of the group visits, its particles on 64-byte lines in 2D, in the search's slot
     * order (PASS_GROUP_SLOTS); the slot of each particle; edac's p in slot order */
    job->pk = d == 2 ? 8 : 10;
    consph_nnps_slots v;
    const int packed = rv_packed(s, &v);
    want += packed ? job->pk * nn + 8 + 2 * nn : 0;
    /* A decomposed system: 1/V and m/ϱ beside the pack in a buffer of the system's own (the
     * refresh carries the scratch as columns, which would write over the pack's rows), the
     * halo's computed from its refreshed fields before the rates (tv_pack): no scratch
     * travels. */
    const int own = packed && s->sys.split;
#else
    const int own = 0;
#endif
    double *sc = own ? sys_pack_buffer(&s->sys, want) : consph_sys_scratch(&s->sys, want);
    if (!sc) return CONSPH_ENOMEM;
    if (own) (void)consph_sys_scratch(&s->sys, 0); /* none asked: the refresh carries none */
    job->vol = sc;
    job->mrho = sc + nn;
#ifdef RV_GROUPS
    if (packed) {
        size_t *slot_of;
        double *pk = rv_pack_at(sc + 2 * nn, job->pk, nn, &slot_of);
        double *pslot = (double *)(slot_of + nn);
        const size_t *particle = v.particle;
        const double *p = job->p;
        const int edac = kind == RV_EDAC;
#pragma omp parallel for schedule(static) if (n >= s->sys.parallel_min)
        for (size_t sl = 0; sl < n; ++sl) {
            const size_t i = particle ? particle[sl] : sl;
            slot_of[i] = sl;
            if (edac) pslot[sl] = p[i];
        }
        job->pack = pk;
        job->slot_of = slot_of;
        job->pslot = pslot;
    }
#endif
    return CONSPH_OK;
}

#ifdef RV_GROUPS
/* Every particle into the pack, after a density pass that did not pack. On a decomposed system,
 * after the rates pass's refresh, the halo's 1/V and m/ϱ first (which no scratch brings): the
 * density visits' operations on its owners' Σ W and ϱ, so their values bit for bit. */
static void tv_pack(const consph_solver *s, const rival_job *job)
{
    const size_t n = s->sys.p->n;
    const unsigned char *dest = s->sys.split ? s->sys.dest : NULL;
    const double m = job->c.m;
#pragma omp parallel for schedule(static) if (n >= s->sys.parallel_min)
    for (size_t i = 0; i < n; ++i) {
        if (dest && !dest[i]) {
            job->vol[i] = 1.0 / job->numd[i];
            job->mrho[i] = m / job->rhos[i];
        }
        tv_pack_one(job, i);
    }
}
#endif

/* A pass with its group visit where the system and the compiler allow one (group_need: what the
 * group visit needs beyond pass->need, PASS_GROUP_SLOTS), else per particle. */
static int run_pass(consph_solver *s, const consph_pass *pass, pass_group_fn group,
                    unsigned group_need, rival_job *job)
{
#ifdef RV_GROUPS
    if (pysph_group_visits && group) {
        const int st =
            pass_run_groups(&s->sys, pass->name, pass->need | group_need, group, job, &s->pairs);
        if (st != PASS_GROUP_UNSERVED) return st;
    }
#else
    (void)group;
    (void)group_need;
#endif
    return consph_pass_run_counted(&s->sys, pass, job, &s->pairs);
}

#ifndef RV_GROUPS
#define group_visit_wcsph NULL
#define group_visit_density NULL
#define group_visit_tv NULL
#endif

/* What the passes read at the neighbours (consph_sys_next_reads), their packs' halo rows
 * included: wcsph's rates ϱ_j, p_j, u_j and the scratch's p/ϱ², m/ϱ and c (none on a decomposed
 * system that packs: the halo's computed from its ϱ and p); tvf's density W alone, edac's p_j
 * too; the tv rates ϱ_j, p_j, u_j, ũ_j - u_j, and 1/V_j and m/ϱ_j from the scratch or, where
 * they pack, from the halo's Σ W and ϱ. */
static const consph_sys_reads wcsph_reads = {0, 1, {SF_RHOF, SF_P, SF_U}, {0}};
static const consph_sys_reads tvf_density_reads = {0, 0, {NULL}, {0}};
static const consph_sys_reads edac_density_reads = {0, 0, {SF_P}, {0}};
static const consph_sys_reads tv_rates_reads = {0, 1, {SF_RHOS, SF_P, SF_U, SF_TVDU, SF_NUMD}, {0}};

static int rhs_wcsph(consph_solver *s)
{
    rival_job job;
    /* before job_fields, whose refresh serves the pass on a decomposed system that packs */
    consph_sys_next_reads(&s->sys, &wcsph_reads);
    int st = job_fields(s, &job, RV_WCSPH);
    if (st != CONSPH_OK) return st;
    const consph_pass pass = {"wcsph rates", CONSPH_PASS_W | CONSPH_PASS_DW, visit_wcsph};
    s->passes = 1;
    return run_pass(s, &pass, job.pack ? group_visit_wcsph : NULL, PASS_GROUP_SLOTS, &job);
}

/* dst = src over n values, on the threads from the system's parallel_min on */
static void copy_values(const consph_solver *s, double *restrict dst, const double *restrict src)
{
    const size_t n = s->sys.p->n;
#pragma omp parallel for schedule(static) if (n >= s->sys.parallel_min)
    for (size_t i = 0; i < n; ++i) dst[i] = src[i];
}

#ifdef RV_GROUPS
typedef struct tv_prep {
    const consph_solver *s;
    const rival_job *job;
} tv_prep;

/* What the passes one by one do between the density and the rates on a decomposed system: the
 * rates' refresh, which brings the halo's densities (Σ W, ϱ, tvf's p), then the halo's rows of
 * the pack (pass_run_groups2's prepare2). */
static int tv_rates_prepare(consph_sys *sys, void *ctx)
{
    const tv_prep *t = ctx;
    consph_sys_next_reads(sys, &tv_rates_reads);
    const int st = pass_halo_refresh(sys);
    if (st == CONSPH_OK) tv_pack(t->s, t->job);
    return st;
}
#endif

/* Density pass, then the rates; the transport velocity follows from them in tv_transport. */
static int rhs_tv(consph_solver *s, int kind)
{
    rival_job job;
    int st = job_fields(s, &job, kind);
    if (st != CONSPH_OK) return st;
    const consph_pass dens = {"tv density", CONSPH_PASS_W | CONSPH_PASS_NO_DX, visit_density};
    const consph_pass rates = {"tv rates", CONSPH_PASS_DW, visit_tv};
    const consph_sys_reads *dens_reads = kind == RV_EDAC ? &edac_density_reads : &tvf_density_reads;
    st = PASS_GROUP_UNSERVED;
#ifdef RV_GROUPS
    /* both passes in one sweep, each neighbourhood gathered once where it can be; on a
     * decomposed system after the density's refresh, which the passes one by one below then do
     * not repeat */
    if (pysph_group_visits && job.pack) {
        const tv_prep prep = {s, &job};
        if (s->sys.split) consph_sys_next_reads(&s->sys, dens_reads);
        const int rc = s->sys.split ? pass_halo_refresh(&s->sys) : CONSPH_OK;
        st = rc != CONSPH_OK
                 ? rc
                 : pass_run_groups2(
                       &s->sys, dens.name, dens.need | PASS_GROUP_SLOTS, group_visit_density_pack,
                       rates.name, rates.need | PASS_GROUP_SLOTS | PASS_GROUP_INTERLEAVED,
                       group_visit_tv_il, &job, &s->pairs, tv_rates_prepare, (void *)&prep);
    }
#endif
    if (st == PASS_GROUP_UNSERVED) {
        consph_sys_next_reads(&s->sys, dens_reads);
        st = run_pass(s, &dens, group_visit_density, 0, &job);
        consph_sys_next_reads(&s->sys, &tv_rates_reads);
#ifdef RV_GROUPS
        /* a decomposed system (pass_run_groups2 declines it): the rates pass's refresh first,
         * which brings the halo's densities (Σ W, ϱ, tvf's p) for its rows of the pack */
        if (st == CONSPH_OK && job.pack) st = pass_halo_refresh(&s->sys);
        if (st == CONSPH_OK && job.pack) tv_pack(s, &job);
#endif
        if (st == CONSPH_OK)
            st = run_pass(s, &rates, job.pack ? group_visit_tv : NULL, PASS_GROUP_SLOTS, &job);
    }
    if (st != CONSPH_OK) return st;
    s->passes = 2;
    double *rhof = sv_field(s, SF_RHOF, 1);
    if (!rhof) return CONSPH_ENOMEM;
    copy_values(s, rhof, job.rhos);
    return CONSPH_OK;
}

/* ũ = u + c ã with the background-pressure acceleration ã of the last right-hand side, after
 * the velocity update: tvf's kick-drift-kick drifts with c = Δt/2 (Adami et al.; PySPH's
 * TransportVelocityStep), edac's predictor and corrector with c = Δt/2 and Δt (PySPH's
 * EDACTVFStep). The next right-hand side's A-term reads this ũ - u. */
static void tv_transport(consph_solver *s, double c)
{
    const int d = s->dim;
    const size_t n = s->sys.p->n, cap = s->sys.p->cap;
    const double *u = sv_field(s, SF_U, d), *ab = sv_field(s, SF_UHAT, d);
    double *du = sv_field(s, SF_TVDU, d), *ax = sv_field(s, SF_AX, d);
    if (!u || !ab || !du || !ax) return; /* created by the first right-hand side */
        /* on the threads: a serial loop here is a part of the step that no thread count shortens;
         * one parallel region for every component */
#pragma omp parallel if (n >= s->sys.parallel_min)
    for (int a = 0; a < d; ++a) {
        /* one component at a time: loops the compiler vectorises */
        const double *ua = u + a * cap, *aba = ab + a * cap;
        double *dua = du + a * cap, *axa = ax + a * cap;
#pragma omp for schedule(static) nowait
        for (size_t i = 0; i < n; ++i) {
            const double v = c * aba[i];
            dua[i] = v;
            axa[i] = ua[i] + v;
        }
    }
}

static int rhs_tvf(consph_solver *s)
{
    return rhs_tv(s, RV_TVF);
}
static int rhs_edac(consph_solver *s)
{
    return rhs_tv(s, RV_EDAC);
}

/* The density is the summation of the last right-hand side (the integrator advanced rhof as an
 * evolved field with zero rate, or not at all): restore it; p is tvf's EOS of that density, or
 * edac's evolved pressure, and stays as it is. */
static void closure_summation(consph_solver *s)
{
    const double *rs = sv_field(s, SF_RHOS, 1);
    double *rhof = sv_field(s, SF_RHOF, 1);
    if (rs && rhof) copy_values(s, rhof, rs);
}

const scheme_def scheme_wcsph = {
    .name = "wcsph",
    .summary = "Monaghan's WCSPH: continuity, Tait, sym. pressure force + AV, XSPH (PySPH "
               "WCSPHScheme)",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_LATTICE,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "pec",
    .passes_min = 1,
    .reads = CONSPH_PARAM_ALPHA,
    .rhs = rhs_wcsph,
    .regularise = NULL,
    .fields = wcsph_fields};
const scheme_def scheme_tvf = {
    .name = "tvf",
    .summary = "Adami, Hu & Adams 2013: transport velocity with background pressure, summation "
               "density, kick-drift-kick",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_LATTICE,
    .eos = CONSPH_EOS_LINEAR,
    .integrator = "kdk",
    .passes_min = 2,
    .rhs = rhs_tvf,
    .rhs_writes_q = 1,
    .regularise = NULL,
    .closure = closure_summation,
    .transport = tv_transport,
    .fields = tvf_fields};
const scheme_def scheme_edac = {
    .name = "edac",
    .summary = "Ramachandran & Puri 2019: EDAC pressure evolution with TVF and p - p_avg",
    .moves = 1,
    .evolve_p = 1,
    .layout = CONSPH_LAYOUT_LATTICE,
    .eos = CONSPH_EOS_LINEAR,
    .integrator = "pec",
    .passes_min = 2,
    .rhs = rhs_edac,
    .regularise = NULL,
    .closure = closure_summation,
    .transport = tv_transport,
    .fields = tv_fields};

/* ---- fields: what these schemes declare beyond the solver's and the integrator's
 * (solver_internal.h, field_decl; the snapshot names are in docs/solver-files.md). wcsph
 * evolves its density; tvf's and edac's is the summation m Σ W of the last right-hand side.
 * Every right-hand side writes ∇·u of every particle, and ∇u, ∇p unless grads_skip (put_diag),
 * and no step reads them before its right-hand side: FIELD_STEP and FIELD_GRADS, which the
 * re-sort need not carry. tvf's p is its density pass's (visit_density), written before the
 * rates read it; edac evolves its p. ---- */
#define PYSPH_STEP_FIELDS                                                                          \
    {SF_GRADP, FIELD_VECTOR, FIELD_GRADS, NULL}, {SF_GRADU, FIELD_TENSOR, FIELD_GRADS, NULL},      \
    {                                                                                              \
        SF_DIVU, FIELD_SCALAR, FIELD_STEP, NULL                                                    \
    }
#define TV_FIELDS                                                                                  \
    {SF_RHOF, FIELD_SCALAR, FIELD_STATE, "summation_density"}, PYSPH_STEP_FIELDS,                  \
        {SF_RHOS, FIELD_SCALAR, FIELD_DERIVED, NULL},                                              \
        {SF_NUMD, FIELD_SCALAR, FIELD_SCRATCH, NULL},                                              \
        {SF_PAVG, FIELD_SCALAR, FIELD_SCRATCH, NULL}, {SF_TVDU, FIELD_VECTOR, FIELD_STATE, NULL},  \
    {                                                                                              \
        SF_UHAT, FIELD_VECTOR, FIELD_DERIVED, NULL                                                 \
    }
const field_decl wcsph_fields[] = {
    {SF_RHOF, FIELD_SCALAR, FIELD_STATE, "density"}, PYSPH_STEP_FIELDS, FIELD_END};
const field_decl tv_fields[] = {TV_FIELDS, FIELD_END};
const field_decl tvf_fields[] = {TV_FIELDS, {SF_P, FIELD_SCALAR, FIELD_STEP, NULL}, FIELD_END};
/* ---- end of fields ---- */
