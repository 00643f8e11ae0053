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

#include "schemes/solver_internal.h"

#define SF_NUMD "numden" /* V_i = Σ_j W_ij (tvf, edac) */
#define SF_RHOS "rhos"   /* ϱ_i = m V_i, the summation density of the last right-hand side */
#define SF_PAVG "pavg"   /* p̄_i: the average p over the neighbours of i (edac) */
#define SF_TVDU "tvdu"   /* ũ - u of the last right-hand side, which the A-term uses, d */
#define SF_UHAT "auhat"  /* the background-pressure acceleration, d */

enum { RV_WCSPH, RV_TVF, RV_EDAC };

typedef struct rival_job {
    int kind, d;
    size_t cap;
    double m, h, h2, rho0, c0, cexp, nu, alpha, pb, p0, nu_edac;
    const double *u, *rho, *p, *tvdu;
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

static void add_gradu(int d, double G[9], double vj, const double uij[3], const double gw[3])
{
    for (int a = 0; a < d; ++a)
        for (int b = 0; b < d; ++b) G[a * d + b] -= vj * uij[a] * gw[b];
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

/* ---- the tvf / edac rates ---- */
static void visit_tv(void *vjob, const consph_nbhd *nb)
{
    const rival_job *job = vjob;
    const int d = job->d;
    const size_t i = nb->i, cap = job->cap;
    const double *u = job->u, *du = job->tvdu;
    const double rhoi = job->rho[i], pi = job->p[i], Vi = 1.0 / job->numd[i];
    const double pav = job->kind == RV_EDAC ? job->pavg[i] : 0.0;
    double ui[3] = {0.0, 0.0, 0.0}, dui[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) {
        ui[a] = u[a * cap + i];
        dui[a] = du[a * cap + i];
    }
    double f[3] = {0.0, 0.0, 0.0}, fb[3] = {0.0, 0.0, 0.0}, fp[3] = {0.0, 0.0, 0.0}, ap = 0.0;
    double G[9] = {0.0}, div = 0.0;
    for (size_t k = 0; k < nb->n; ++k) {
        const size_t j = nb->j[k];
        if (j == i) continue; /* ∇W_ii = 0: no force on itself */
        const double rhoj = job->rho[j], pj = job->p[j], Vj = 1.0 / job->numd[j];
        const double w2 = Vi * Vi + Vj * Vj, dwr = nb->dwr[k];
        double xij[3] = {0.0, 0.0, 0.0}, uij[3] = {0.0, 0.0, 0.0}, gw[3] = {0.0, 0.0, 0.0};
        double xdw = 0.0, udw = 0.0;
        for (int a = 0; a < d; ++a) {
            xij[a] = nb->dx[a][k];
            gw[a] = dwr * xij[a];
            uij[a] = ui[a] - u[a * cap + j];
            xdw += xij[a] * gw[a];
            udw += uij[a] * gw[a];
        }
        const double r2 = nb->r[k] * nb->r[k];
        /* Adami et al. eq. 7 (p̃_ij), with p - p̄_i in edac (Ramachandran & Puri eq. 25) */
        const double pij = (rhoj * (pi - pav) + rhoi * (pj - pav)) / (rhoi + rhoj);
        const double eta = 2.0 * job->nu * rhoi * rhoj / (rhoi + rhoj);
        const double visc = w2 * eta * xdw / (r2 + job->h2);
        for (int a = 0; a < d; ++a) {
            double A = 0.0; /* ½(A_i + A_j)·∇W, A = ϱ u (ũ - u) */
            for (int b = 0; b < d; ++b)
                A +=
                    0.5 * (rhoi * ui[a] * dui[b] + rhoj * u[a * cap + j] * du[b * cap + j]) * gw[b];
            f[a] += -pij * w2 * gw[a] + visc * uij[a] + w2 * A;
            fp[a] += -pij * w2 * gw[a] / job->m;
            fb[a] += -job->pb * w2 * gw[a];
        }
        add_gradu(d, G, job->m / rhoj, uij, gw);
        div -= job->m / rhoj * udw;
        if (job->kind == RV_EDAC) {
            /* Ramachandran & Puri eq. 22: the continuity-like term and EDAC diffusion */
            const double etae = 2.0 * job->nu_edac * rhoi * rhoj / (rhoi + rhoj);
            ap += rhoi / rhoj * job->c0 * job->c0 * job->m * udw;
            ap += w2 * etae * xdw / (r2 + job->h2) * (pi - pj) / job->m;
        }
    }
    for (int a = 0; a < d; ++a) {
        job->au[a * cap + i] = f[a] / job->m;
        job->auhat[a * cap + i] = fb[a] / job->m;
    }
    job->aq[i] = ap;
    put_diag(job, i, fp, div, G);
}

/* ---- wcsph ---- */
static void visit_wcsph(void *vjob, const consph_nbhd *nb)
{
    const rival_job *job = vjob;
    const int d = job->d;
    const size_t i = nb->i, cap = job->cap;
    const double *u = job->u, m = job->m;
    const double rhoi = job->rho[i], pi = job->p[i], ti = pi / (rhoi * rhoi);
    double ui[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) ui[a] = u[a * cap + i];
    double f[3] = {0.0, 0.0, 0.0}, xs[3] = {0.0, 0.0, 0.0}, fp[3] = {0.0, 0.0, 0.0}, drho = 0.0;
    double G[9] = {0.0};
    for (size_t k = 0; k < nb->n; ++k) {
        const size_t j = nb->j[k];
        if (j == i) continue;
        const double rhoj = job->rho[j], tj = job->p[j] / (rhoj * rhoj), dwr = nb->dwr[k];
        const double r2 = nb->r[k] * nb->r[k], rhob = 0.5 * (rhoi + rhoj);
        double uij[3] = {0.0, 0.0, 0.0}, gw[3] = {0.0, 0.0, 0.0}, ux = 0.0, udw = 0.0, xdw = 0.0;
        for (int a = 0; a < d; ++a) {
            const double xa = nb->dx[a][k];
            uij[a] = ui[a] - u[a * cap + j];
            gw[a] = dwr * xa;
            ux += uij[a] * xa;
            udw += uij[a] * gw[a];
            xdw += xa * gw[a];
        }
        double pi_ij = 0.0; /* Monaghan 1992 eq. 4.2 (β = 0), on approach only */
        if (ux < 0.0 && job->alpha > 0.0) {
            const double ci = job->c0 * pow(rhoi / job->rho0, job->cexp);
            const double cj = job->c0 * pow(rhoj / job->rho0, job->cexp);
            const double mu = job->h * ux / (r2 + job->h2);
            pi_ij = -job->alpha * 0.5 * (ci + cj) * mu / rhob;
        }
        /* Morris et al. 1997 / Cleary's laminar viscosity */
        const double visc = m * 4.0 * job->nu * xdw / ((rhoi + rhoj) * (r2 + job->h2));
        for (int a = 0; a < d; ++a) {
            f[a] += -m * (ti + tj + pi_ij) * gw[a] + visc * uij[a];
            fp[a] += -m * (ti + tj) * gw[a];
            xs[a] -= 0.5 * m * nb->w[k] / rhob * uij[a]; /* XSPH, ε = 0.5 */
        }
        drho += m * udw;
        add_gradu(d, G, m / rhoj, uij, gw);
    }
    for (int a = 0; a < d; ++a) {
        job->au[a * cap + i] = f[a];
        job->ax[a * cap + i] = ui[a] + xs[a];
    }
    job->aq[i] = drho;
    put_diag(job, i, fp, -drho / rhoi, G);
}

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
        return job->rho ? CONSPH_OK : CONSPH_ENOMEM;
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
