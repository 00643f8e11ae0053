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
#include <string.h>

#include "solver/solver_internal.h"

#define SF_NUMD "numden" /* V_i = Σ_j W_ij (tvf, edac) */
#define SF_RHOS "rhos"   /* ϱ_i = m V_i, the summation density of the last right-hand side */
#define SF_PAVG "pavg"   /* p̄_i: the average p over the neighbours of i (edac) */
#define SF_TVDU "tvdu"   /* ũ - u of the last drift (tv_transport), which the A-term uses, d */
#define SF_UHAT "auhat"  /* the background-pressure acceleration, d */

enum { RV_WCSPH, RV_TVF, RV_EDAC };

typedef struct rival_job {
    int kind, d;
    size_t cap;
    double m, h, h2, rho0, c0, cexp, nu, alpha, pb, p0, nu_edac;
    const double *u, *rho, *p, *tvdu;
    const double *cs; /* wcsph with α > 0: Tait's sound speed of each particle */
    double *numd, *pavg, *rhos, *pw, *au, *aq, *ax, *auhat;
    double *gradp, *divu, *gradu; /* for the diagnostics and the vorticity output */
} rival_job;

/* The solver's diagnostics read ∇p (as -ϱ times the pressure acceleration), ∇·u and ∇u: the
 * scheme's own estimates, Σ_j m_j/ϱ_j (u_j - u_i) ⊗ ∇W_ij for ∇u. */
static void put_diag(const rival_job *job, size_t i, const double fp[3], double div,
                     const double G[9])
{
    const int d = job->d;
    const size_t cap = job->cap;
    for (int a = 0; a < d; ++a) job->gradp[a * cap + i] = -job->rho[i] * fp[a];
    for (int e = 0; e < d * d; ++e) job->gradu[(size_t)e * cap + i] = G[e];
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
    job->rhos[i] = job->m * s;
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
RV_INLINE void visit_tv_d(const rival_job *job, const consph_nbhd *nb, const int d, const int edac)
{
    const size_t i = nb->i, cap = job->cap;
    const double *u = job->u, *du = job->tvdu;
    const double rhoi = job->rho[i], pi = job->p[i], Vi = 1.0 / job->numd[i];
    const double pav = edac ? job->pavg[i] : 0.0;
    const double m = job->m, h2 = job->h2, nu = job->nu, pb = job->pb;
    const double nu_edac = job->nu_edac, c0 = job->c0;
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
        double rhoj[RV_BLOCK], pj[RV_BLOCK], nd[RV_BLOCK], uj[3][RV_BLOCK], duj[3][RV_BLOCK];
        double tf[3][RV_BLOCK], tp[3][RV_BLOCK], tb[3][RV_BLOCK], tg[9][RV_BLOCK];
        double tdiv[RV_BLOCK], ta1[RV_BLOCK], ta2[RV_BLOCK];
        rv_gather(1, 0, job->rho, jb, nk, &rhoj);
        rv_gather(1, 0, job->p, jb, nk, &pj);
        rv_gather(1, 0, job->numd, jb, nk, &nd);
        rv_gather(d, cap, u, jb, nk, uj);
        rv_gather(d, cap, du, jb, nk, duj);
        for (size_t k = 0; k < nk; ++k) {
            /* the particle itself gets terms too (∇W_ii = 0); they are not summed */
            const double Vj = 1.0 / nd[k];
            const double w2 = Vi * Vi + Vj * Vj, dwr = nb->dwr[k0 + k];
            double xij[3] = {0.0, 0.0, 0.0}, uij[3] = {0.0, 0.0, 0.0}, gw[3] = {0.0, 0.0, 0.0};
            double xdw = 0.0, udw = 0.0;
            for (int a = 0; a < d; ++a) {
                xij[a] = nb->dx[a][k0 + k];
                gw[a] = dwr * xij[a];
                uij[a] = ui[a] - uj[a][k];
                xdw += xij[a] * gw[a];
                udw += uij[a] * gw[a];
            }
            const double r2 = nb->r[k0 + k] * nb->r[k0 + k];
            /* Adami et al. eq. 7 (p̃_ij), with p - p̄_i in edac (Ramachandran & Puri eq. 25) */
            const double pij = (rhoj[k] * (pi - pav) + rhoi * (pj[k] - pav)) / (rhoi + rhoj[k]);
            const double eta = 2.0 * nu * rhoi * rhoj[k] / (rhoi + rhoj[k]);
            const double visc = w2 * eta * xdw / (r2 + h2);
            for (int a = 0; a < d; ++a) {
                double A = 0.0; /* ½(A_i + A_j)·∇W, A = ϱ u (ũ - u) */
                for (int b = 0; b < d; ++b)
                    A += 0.5 * (rhoi * ui[a] * dui[b] + rhoj[k] * uj[a][k] * duj[b][k]) * gw[b];
                tf[a][k] = -pij * w2 * gw[a] + visc * uij[a] + w2 * A;
                tp[a][k] = -pij * w2 * gw[a] / m;
                tb[a][k] = -pb * w2 * gw[a];
            }
            const double vj = m / rhoj[k];
            for (int a = 0; a < d; ++a)
                for (int b = 0; b < d; ++b) tg[a * d + b][k] = vj * uij[a] * gw[b];
            tdiv[k] = vj * udw;
            if (edac) {
                /* Ramachandran & Puri eq. 22: the continuity-like term and EDAC diffusion */
                const double etae = 2.0 * nu_edac * rhoi * rhoj[k] / (rhoi + rhoj[k]);
                ta1[k] = rhoi / rhoj[k] * c0 * c0 * m * udw;
                ta2[k] = w2 * etae * xdw / (r2 + h2) * (pi - pj[k]) / m;
            }
        }
        for (size_t k = 0; k < nk; ++k) {
            if (jb[k] == i) continue; /* ∇W_ii = 0: no force on itself */
            for (int a = 0; a < d; ++a) {
                f[a] += tf[a][k];
                fp[a] += tp[a][k];
                fb[a] += tb[a][k];
            }
            for (int e = 0; e < d * d; ++e) G[e] -= tg[e][k];
            div -= tdiv[k];
            if (edac) {
                ap += ta1[k];
                ap += ta2[k];
            }
        }
    }
    for (int a = 0; a < d; ++a) {
        job->au[a * cap + i] = f[a] / m;
        job->auhat[a * cap + i] = fb[a] / m;
    }
    job->aq[i] = ap;
    put_diag(job, i, fp, div, G);
}

RV_CLONES static void visit_tv(void *vjob, const consph_nbhd *nb)
{
    const rival_job *job = vjob;
    const int edac = job->kind == RV_EDAC;
    if (job->d == 2 && edac)
        visit_tv_d(job, nb, 2, 1);
    else if (job->d == 2)
        visit_tv_d(job, nb, 2, 0);
    else
        visit_tv_d(job, nb, job->d, edac);
}

/* ---- wcsph ---- */
RV_INLINE void visit_wcsph_d(const rival_job *job, const consph_nbhd *nb, const int d)
{
    const size_t i = nb->i, cap = job->cap;
    const double *u = job->u, m = job->m, h = job->h, h2 = job->h2, nu = job->nu;
    const double rhoi = job->rho[i], pi = job->p[i], ti = pi / (rhoi * rhoi);
    const double alpha = job->alpha;
    const int av = alpha > 0.0;
    const double ci = av ? job->cs[i] : 0.0;
    double ui[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) ui[a] = u[a * cap + i];
    double f[3] = {0.0, 0.0, 0.0}, xs[3] = {0.0, 0.0, 0.0}, fp[3] = {0.0, 0.0, 0.0}, drho = 0.0;
    double G[9] = {0.0};
    for (size_t k0 = 0; k0 < nb->n; k0 += RV_BLOCK) {
        const size_t nk = nb->n - k0 < RV_BLOCK ? nb->n - k0 : RV_BLOCK;
        const size_t *jb = nb->j + k0;
        double rhoj[RV_BLOCK], pj[RV_BLOCK], uj[3][RV_BLOCK], ux[RV_BLOCK], r2[RV_BLOCK];
        double tij[RV_BLOCK], pij[RV_BLOCK], gw[3][RV_BLOCK], uij[3][RV_BLOCK];
        double tf[3][RV_BLOCK], tp[3][RV_BLOCK], tx[3][RV_BLOCK], tg[9][RV_BLOCK];
        double td[RV_BLOCK];
        rv_gather(1, 0, job->rho, jb, nk, &rhoj);
        rv_gather(1, 0, job->p, jb, nk, &pj);
        rv_gather(d, cap, u, jb, nk, uj);
        for (size_t k = 0; k < nk; ++k) {
            /* the particle itself gets terms too (∇W_ii = 0); they are not summed */
            const double dwr = nb->dwr[k0 + k];
            double uxk = 0.0;
            tij[k] = pj[k] / (rhoj[k] * rhoj[k]);
            r2[k] = nb->r[k0 + k] * nb->r[k0 + k];
            for (int a = 0; a < d; ++a) {
                const double xa = nb->dx[a][k0 + k];
                uij[a][k] = ui[a] - uj[a][k];
                gw[a][k] = dwr * xa;
                uxk += uij[a][k] * xa;
            }
            ux[k] = uxk;
            pij[k] = 0.0;
        }
        if (av) {
            double cj[RV_BLOCK];
            rv_gather(1, 0, job->cs, jb, nk, &cj);
            for (size_t k = 0; k < nk; ++k) {
                /* Monaghan 1992 eq. 4.2 (β = 0), on approach only; computed for every pair
                 * and selected, since the sign of u_ij·x_ij is a coin toss to the branch
                 * predictor */
                const double mu = h * ux[k] / (r2[k] + h2), rhob = 0.5 * (rhoi + rhoj[k]);
                const double v = -alpha * 0.5 * (ci + cj[k]) * mu / rhob;
                pij[k] = ux[k] < 0.0 ? v : 0.0;
            }
        }
        for (size_t k = 0; k < nk; ++k) {
            const double rhob = 0.5 * (rhoi + rhoj[k]);
            double udw = 0.0, xdw = 0.0;
            for (int a = 0; a < d; ++a) {
                const double xa = nb->dx[a][k0 + k];
                udw += uij[a][k] * gw[a][k];
                xdw += xa * gw[a][k];
            }
            /* Morris et al. 1997 / Cleary's laminar viscosity */
            const double visc = m * 4.0 * nu * xdw / ((rhoi + rhoj[k]) * (r2[k] + h2));
            const double wk = nb->w[k0 + k];
            for (int a = 0; a < d; ++a) {
                tf[a][k] = -m * (ti + tij[k] + pij[k]) * gw[a][k] + visc * uij[a][k];
                tp[a][k] = -m * (ti + tij[k]) * gw[a][k];
                tx[a][k] = 0.5 * m * wk / rhob * uij[a][k]; /* XSPH, ε = 0.5 */
            }
            td[k] = m * udw;
            const double vj = m / rhoj[k];
            for (int a = 0; a < d; ++a)
                for (int b = 0; b < d; ++b) tg[a * d + b][k] = vj * uij[a][k] * gw[b][k];
        }
        for (size_t k = 0; k < nk; ++k) {
            if (jb[k] == i) continue;
            for (int a = 0; a < d; ++a) {
                f[a] += tf[a][k];
                fp[a] += tp[a][k];
                xs[a] -= tx[a][k];
            }
            drho += td[k];
            for (int e = 0; e < d * d; ++e) G[e] -= tg[e][k];
        }
    }
    for (int a = 0; a < d; ++a) {
        job->au[a * cap + i] = f[a];
        job->ax[a * cap + i] = ui[a] + xs[a];
    }
    job->aq[i] = drho;
    put_diag(job, i, fp, -drho / rhoi, G);
}

RV_CLONES static void visit_wcsph(void *vjob, const consph_nbhd *nb)
{
    const rival_job *job = vjob;
    if (job->d == 2)
        visit_wcsph_d(job, nb, 2);
    else
        visit_wcsph_d(job, nb, job->d);
}

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC pop_options
#endif

static int job_fields(consph_solver *s, rival_job *job, int kind)
{
    const int d = s->dim;
    memset(job, 0, sizeof *job);
    job->kind = kind;
    job->d = d;
    job->cap = s->sys.p->cap;
    job->m = s->mass;
    job->h = s->h;
    job->h2 = 0.01 * s->h * s->h; /* PySPH's EPS = 0.01 h_ij² in every 1/(r² + EPS) */
    job->rho0 = s->prm.rho0;
    job->c0 = s->c0;
    job->cexp = 0.5 * (s->prm.gamma - 1.0); /* Tait's sound speed c_o (ϱ/ϱ_o)^((γ-1)/2) */
    job->nu = s->nu;
    job->alpha = s->prm.alpha >= 0.0 ? s->prm.alpha : 0.1; /* PySPH WCSPHScheme */
    job->p0 = s->c0 * s->c0 * s->prm.rho0;                 /* tvf's p_o = c_o² ϱ_o */
    job->pb = job->p0; /* Adami et al. §2.3; PySPH's taylor_green: p_b = p_o */
    job->nu_edac = 0.5 * s->h * s->c0 / 8.0; /* Ramachandran & Puri: α_edac h c_o / 8, α = 0.5 */
    job->u = sv_field(s, SF_U, d);
    job->p = sv_field(s, SF_P, 1);
    job->au = sv_field(s, SF_AU, d);
    job->aq = sv_field(s, SF_AQ, 1);
    job->ax = sv_field(s, SF_AX, d);
    job->gradp = sv_field(s, SF_GRADP, d);
    job->divu = sv_field(s, SF_DIVU, 1);
    job->gradu = sv_field(s, SF_GRADU, d * d);
    if (!job->u || !job->p || !job->au || !job->aq || !job->ax || !job->gradp || !job->divu ||
        !job->gradu)
        return CONSPH_ENOMEM;
    if (kind == RV_WCSPH) {
        job->rho = sv_field(s, SF_RHOF, 1);
        if (!job->rho) return CONSPH_ENOMEM;
        if (job->alpha > 0.0) {
            /* Tait's c_o (ϱ/ϱ_o)^((γ-1)/2) once per particle for Monaghan's Π_ij: a pow() per
             * approaching pair cost more than the rest of the pair. */
            const size_t n = s->sys.p->n;
            double *cs = consph_sys_scratch(&s->sys, n ? n : 1);
            if (!cs) return CONSPH_ENOMEM;
            const double *rho = job->rho, c0 = job->c0, rho0 = job->rho0, cexp = job->cexp;
#pragma omp parallel for schedule(static) if (n >= s->sys.parallel_min)
            for (size_t i = 0; i < n; ++i) cs[i] = c0 * pow(rho[i] / rho0, cexp);
            job->cs = cs;
        }
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
    return CONSPH_OK;
}

static int rhs_wcsph(consph_solver *s)
{
    rival_job job;
    int st = job_fields(s, &job, RV_WCSPH);
    if (st != CONSPH_OK) return st;
    const consph_pass pass = {"wcsph rates", CONSPH_PASS_W | CONSPH_PASS_DW, visit_wcsph};
    s->passes = 1;
    return consph_pass_run_counted(&s->sys, &pass, &job, &s->pairs);
}

/* Density pass, then the rates; the transport velocity follows from them in tv_transport. */
static int rhs_tv(consph_solver *s, int kind)
{
    rival_job job;
    int st = job_fields(s, &job, kind);
    if (st != CONSPH_OK) return st;
    const consph_pass dens = {"tv density", CONSPH_PASS_W | CONSPH_PASS_NO_DX, visit_density};
    const consph_pass rates = {"tv rates", CONSPH_PASS_DW, visit_tv};
    st = consph_pass_run_counted(&s->sys, &dens, &job, &s->pairs);
    if (st == CONSPH_OK) st = consph_pass_run_counted(&s->sys, &rates, &job, &s->pairs);
    if (st != CONSPH_OK) return st;
    s->passes = 2;
    double *rhof = sv_field(s, SF_RHOF, 1);
    if (!rhof) return CONSPH_ENOMEM;
    memcpy(rhof, job.rhos, s->sys.p->n * sizeof(double));
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
    for (int a = 0; a < d; ++a)
        for (size_t i = 0; i < n; ++i) {
            du[a * cap + i] = c * ab[a * cap + i];
            ax[a * cap + i] = u[a * cap + i] + du[a * cap + i];
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
    if (rs && rhof) memcpy(rhof, rs, s->sys.p->n * sizeof(double));
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
    .regularise = NULL};
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
    .regularise = NULL,
    .closure = closure_summation,
    .transport = tv_transport};
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
    .transport = tv_transport};
