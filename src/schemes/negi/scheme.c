/* The schemes of 001 §5 (and EWCSPH as 001 runs it): each one a const negi_terms naming the
 * terms of its rates (iact.h gives them as equations and the per-particle combination), beside
 * its table row: layout, EOS, integrator, regularisation. The derivatives the rates combine come
 * from the kit's fused passes (kit.c) with ∇p asym_bc, ∇u f4 (asym_bc per component), ∇·u
 * div_bc and the Laplacians of 001 Table 6; docs/schemes.md records every choice with its
 * source. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "regularise/regularise.h"
#include "schemes/negi/iact.h"
#include "solver/solver_internal.h"

/* EWCSPH's ϱ_c (negi_terms.frozen_rho), a state field so that a checkpoint carries it */
#define SF_RHOC "rhoc"

/* The rates of one scheme's terms t at the current state: the kit's derivatives, then
 * negi_rates_i per particle. */
/* negi_rates_i over every particle in 2D, its terms' switches held in locals so that the loop
 * is unswitched on them and vectorises: its operations in its order, hence its values. NULL
 * arrays (du, rhoc, gradq, lapq, ax) read as negi_rates_i's zeros (rhoc: ϱ). */
static void rates_2d(const negi_terms *t, size_t n, size_t cap, double nu, double D, double c2,
                     double rho0, int evolve_p, const double *restrict u, const double *restrict du,
                     const double *restrict rhof, const double *restrict rhoc,
                     const double *restrict gradp, const double *restrict G,
                     const double *restrict lapu, const double *restrict divu,
                     const double *restrict gradq, const double *restrict lapq, double *restrict au,
                     double *restrict ax, double *restrict aq, int par)
{
    (void)par; /* read by the OpenMP if alone */
    const int adv_u = t->advect_u, tr = t->transport && du, adv_q = t->advect_q && gradq;
    const int dif_q = t->diffuse_q && lapq, trq = t->transport && du && gradq;
    const double *rhom = rhoc ? rhoc : rhof;
#pragma omp parallel for schedule(static) if (par)
    for (size_t i = 0; i < n; ++i) {
        const double u0 = u[i], u1 = u[cap + i];
        const double d0 = tr ? du[i] : 0.0, d1 = tr ? du[cap + i] : 0.0;
        const double g00 = G[i], g01 = G[cap + i], g10 = G[2 * cap + i], g11 = G[3 * cap + i];
        double r0 = -gradp[i] / rhom[i] + nu * lapu[i];
        if (adv_u) r0 -= u0 * g00;
        if (tr) r0 += d0 * g00;
        if (adv_u) r0 -= u1 * g01;
        if (tr) r0 += d1 * g01;
        double r1 = -gradp[cap + i] / rhom[i] + nu * lapu[cap + i];
        if (adv_u) r1 -= u0 * g10;
        if (tr) r1 += d0 * g10;
        if (adv_u) r1 -= u1 * g11;
        if (tr) r1 += d1 * g11;
        au[i] = r0;
        au[cap + i] = r1;
        if (ax) {
            ax[i] = u0 + d0;
            ax[cap + i] = u1 + d1;
        }
        double r = evolve_p ? -rho0 * c2 * divu[i] : -rhof[i] * divu[i];
        if (dif_q) r += D * lapq[i];
        if (adv_q || trq) {
            const double q0 = gradq[i], q1 = gradq[cap + i];
            if (adv_q) r -= u0 * q0;
            if (trq) r += d0 * q0;
            if (adv_q) r -= u1 * q1;
            if (trq) r += d1 * q1;
        }
        aq[i] = r;
    }
}

static int rates(consph_solver *s, const negi_terms *t)
{
    consph_sys *sys = &s->sys;
    consph_particles *p = sys->p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    int st = CONSPH_OK;
    s->passes = 0;
    /* The volumes, the kit's two passes and TV-C's shifting read this position state: one
     * gather and one kernel batch for all of them (the neighbour list's pair cache). */
    consph_sys_expect_passes(sys, 2 + !s->volumes_fixed + (t->transport != 0),
                             CONSPH_PASS_W | CONSPH_PASS_DW |
                                 (t->lap == KIT_LAP_KORZILIUS ? CONSPH_PASS_D2W : 0u));
    const char *q = s->scheme->evolve_p ? SF_P : SF_RHOF;
    kit_req rq = {KIT_GRADP | KIT_LAPU | KIT_DIVU, (kit_lap)t->lap, q, 1e8, 0};
    if (t->diffuse_q) rq.want |= KIT_LAPQ;
    if (t->transport || t->advect_q) rq.want |= KIT_GRADQ;
    double *du = NULL;
    reg_pst_job shift_job;
    consph_pass shift;
    if (t->transport) {
        /* 001 §5.4 item 4: the PST of [33] as a transport velocity, at 001's authors'
         * constants (tsph_dsph.py, ComputeShiftVelocity; docs/schemes.md); its pass chained
         * after the kit's, which make the volumes it reads */
        st = solver_shift_velocity_tvc_pass(s, &du, &shift_job, &shift);
        if (st != CONSPH_OK) return st;
    }
    const consph_pass *then = t->transport ? &shift : NULL;
    /* a fixed geometry's B_i from the last evaluation on the same build of the list (the kit's
     * moment and its inversion: about a sixth of E-C's step); only while the list is on, whose
     * builds count every change of the positions or of the particles' order */
    consph_nlist_info nl;
    consph_sys_nlist_info(sys, &nl);
    rq.bonet_kept = s->volumes_fixed && s->bonet_kept && nl.on && nl.builds == s->bonet_builds;
    st = s->volumes_fixed
             ? kit_derivatives(sys, &rq, &s->pairs, &s->passes)
             : kit_volumes_derivatives_then(sys, &rq, then, &shift_job, &s->pairs, &s->passes);
    if (s->volumes_fixed) {
        consph_sys_nlist_info(sys, &nl);
        s->bonet_kept = st == CONSPH_OK && nl.on;
        s->bonet_builds = nl.builds;
    }
    if (st == CONSPH_OK && then && s->volumes_fixed) st = consph_pass_run(sys, then, &shift_job);
    if (st != CONSPH_OK) return st;
    if (t->transport) solver_shift_velocity_tvc_finish(s, du);
    const double *u = sv_field(s, SF_U, d), *rhof = sv_field(s, SF_RHOF, 1);
    double *rhoc = NULL;
    if (t->frozen_rho) {
        /* 001's authors' EWCSPH divides ∇p by rhoc, which taylor_green.py sets to
         * ρ_o + p_0/c_o² and their no_soc steppers never update (ewcsph.py, RK2Stepper and
         * MomentumEquationSymm). The field is zero until the first evaluation, which is at the
         * initial state (p there is the EOS of the ϱ inverted from the exact p_0). */
        rhoc = sv_field(s, SF_RHOC, 1);
        if (!rhoc || !sv_field(s, SF_P, 1)) return CONSPH_ENOMEM;
        const double *p0 = sv_field(s, SF_P, 1);
        /* tested at a particle of the solver's own: a decomposed system's halo holds what its
         * last refresh or this loop left there, which a pass that does not read ϱ_c at the
         * neighbours does not bring (consph_sys_next_reads) */
        const size_t i0 = solver_first_own(s);
        if (i0 < n && rhoc[i0] == 0.0)
            for (size_t i = 0; i < n; ++i) rhoc[i] = s->prm.rho0 + p0[i] / (s->c0 * s->c0);
    }
    const double *gradp = sv_field(s, SF_GRADP, d), *G = sv_field(s, SF_GRADU, d * d);
    const double *lapu = sv_field(s, SF_LAPU, d), *divu = sv_field(s, SF_DIVU, 1);
    const double *gradq = (rq.want & KIT_GRADQ) ? sv_field(s, SF_GRADQ, d) : NULL;
    const double *lapq = (rq.want & KIT_LAPQ) ? sv_field(s, SF_LAPQ, 1) : NULL;
    double *ax = s->scheme->moves ? sv_field(s, SF_AX, d) : NULL;
    double *au = sv_field(s, SF_AU, d), *aq = sv_field(s, SF_AQ, 1);
    if (!u || !rhof || !gradp || !G || !lapu || !divu || !au || !aq || (s->scheme->moves && !ax) ||
        ((rq.want & KIT_GRADQ) && !gradq) || ((rq.want & KIT_LAPQ) && !lapq))
        return CONSPH_ENOMEM;
    const double rho0 = s->prm.rho0, c2 = s->c0 * s->c0, D = s->D;
    /* Cleary's Laplacian comes per unit mass density (kit.c: m_j = ρ_o ω_j) */
    const double nu = t->lap == KIT_LAP_CLEARY ? s->nu * rho0 : s->nu;
    const int evolve_p = s->scheme->evolve_p;
    if (d == 2) {
        rates_2d(t, n, cap, nu, D, c2, rho0, evolve_p, u, du, rhof, rhoc, gradp, G, lapu, divu,
                 gradq, lapq, au, ax, aq, n > sys->parallel_min);
        return CONSPH_OK;
    }
#pragma omp parallel for schedule(static) if (n > sys->parallel_min)
    for (size_t i = 0; i < n; ++i) {
        negi_derivs v = {.rhof = rhof[i],
                         .rhom = rhoc ? rhoc[i] : rhof[i],
                         .divu = divu[i],
                         .lapq = lapq ? lapq[i] : 0.0};
        for (int a = 0; a < d; ++a) {
            v.u[a] = u[a * cap + i];
            v.du[a] = du ? du[a * cap + i] : 0.0;
            v.gradp[a] = gradp[a * cap + i];
            v.lapu[a] = lapu[a * cap + i];
            v.gradq[a] = gradq ? gradq[a * cap + i] : 0.0;
        }
        for (int e = 0; e < d * d; ++e) v.G[e] = G[(size_t)e * cap + i];
        double rau[3], rax[3];
        negi_rates_i(t, d, nu, D, c2, rho0, evolve_p, &v, rau, rax, &aq[i]);
        for (int a = 0; a < d; ++a) {
            au[a * cap + i] = rau[a];
            if (ax) ax[a * cap + i] = rax[a];
        }
    }
    return CONSPH_OK;
}

/* The gradients of u and of the evolved scalar at the positions before a shift (the Taylor
 * update of eq. 22 uses them), with fresh volumes; then the pass `then` (the PST's, chained
 * after them; NULL: none). */
static int gradients_for_shift(consph_solver *s, const consph_pass *then, void *then_job)
{
    int passes = 0;
    /* These two passes and the shifting's first (IPST's volumes, or the PST) read this state */
    consph_sys_expect_passes(&s->sys, 3, CONSPH_PASS_W | CONSPH_PASS_DW);
    kit_req rq = {KIT_GRADU | KIT_GRADQ, KIT_LAP_COUPLED, s->scheme->evolve_p ? SF_P : SF_RHOF, 1e8,
                  0};
    return kit_volumes_derivatives_then(&s->sys, &rq, then, then_job, &s->pairs, &passes);
}

static int zeroed_shift(consph_solver *s, double **dr)
{
    *dr = sv_field(s, SF_SHIFT, s->dim);
    if (!*dr) return CONSPH_ENOMEM;
    for (int a = 0; a < s->dim; ++a)
        memset(*dr + (size_t)a * s->sys.p->cap, 0, s->sys.p->n * sizeof(double));
    return CONSPH_OK;
}

/* IPST every ipst_every steps (001 §5.1.1), the first after step 1 as 001's authors run it
 * (reg_ipst_due); with ipst_h_dt, steps of the time-step rule's Δt at that h (001 §5.2: the
 * finest resolution's Δt for every resolution), so the shifts fall at the same times whatever
 * the run's Δt (docs/schemes.md, "IPST schedule"). */
static int regularise_ipst(consph_solver *s)
{
    const double period_dt =
        s->prm.ipst_h_dt > 0.0 ? s->prm.cfl * s->prm.ipst_h_dt / (s->prm.U + s->c0) : 0.0;
    if (!reg_ipst_due(s->step, s->t - s->dt, s->t, s->prm.ipst_every, period_dt)) return CONSPH_OK;
    double *dr;
    int st = gradients_for_shift(s, NULL, NULL);
    if (st == CONSPH_OK) st = zeroed_shift(s, &dr);
    if (st != CONSPH_OK) return st;
    /* χ_o (docs/schemes.md, "IPST"): ipst_chi0 = lattice: 001's text, the unperturbed
     * lattice's (reg_chi0); 0: as 001's authors, one shift at the first call, then max χ after
     * it, kept in prm so that a checkpoint carries it (pst.py, NumberDensityMoment: χ_o is set
     * while t < Δt, in the same iteration, which then converges at once); > 0: that value. At
     * least one shift per call, as the authors' iterated group (min_iterations=1). */
    reg_ipst_params ip = {s->h, s->chi0, s->prm.ipst_tol, s->prm.ipst_max_iter, 1};
    reg_ipst_report rep;
    const int first = s->prm.ipst_chi0 == 0.0;
    if (s->prm.ipst_chi0 > 0.0) ip.chi0 = s->prm.ipst_chi0;
    if (first) ip.max_iter = 1;
    st = reg_ipst(&s->sys, &ip, dr, &rep);
    if (st != CONSPH_OK) return st;
    if (first) s->prm.ipst_chi0 = rep.chi_max;
    solver_taylor_update(s, dr);
    ++s->regs;
    return CONSPH_OK;
}

/* The non-iterative shifting of Sun et al. every step (L-PST-C), at 001's authors' constants:
 * CFL 0.5 and R = 0.24, n = 4, Ma = U/c_o (pst.py, DeltaPlusSPHPST: δr = -2h² Ma Σ (1 + R
 * (W_ij/W(Δs))^n) ∇W_ij V_j). 001 does not write the shift out (docs/schemes.md). */
static int regularise_pst(consph_solver *s)
{
    double *dr = sv_field(s, SF_SHIFT, s->dim);
    if (!dr) return CONSPH_ENOMEM;
    reg_pst_params pp = {s->h, s->ds, 0.5, s->prm.U / s->c0, 0.24, 4.0, 0.0};
    reg_pst_job job;
    consph_pass pass;
    int st = reg_pst_pass(&s->sys, &pp, dr, &job, &pass);
    if (st == CONSPH_OK) st = gradients_for_shift(s, &pass, &job);
    if (st == CONSPH_OK) st = reg_move(&s->sys, dr);
    if (st != CONSPH_OK) return st;
    solver_taylor_update(s, dr);
    ++s->regs;
    return CONSPH_OK;
}

/* M4 remeshing to the lattice after every step (L-RR-C, eqs. 32-33). */
static int regularise_remesh(consph_solver *s)
{
    const char *fields[2] = {SF_U, s->scheme->evolve_p ? SF_P : SF_RHOF};
    const double *lat = sv_field(s, SF_LATTICE, s->dim);
    if (!lat) return CONSPH_ENOMEM;
    size_t orphans = 0;
    int st = reg_remesh_m4(&s->sys, lat, s->ds, fields, 2, &orphans);
    if (st != CONSPH_OK) return st;
    solver_eos(s);
    ++s->regs;
    return CONSPH_OK;
}

/* EWCSPH also carries its frozen ϱ_c (negi_terms.frozen_rho) */
extern const field_decl negi_ewcsph_fields[];

/* ---- the schemes: the terms of each one's rates, then its row ---- */

/* 001 §5.1.1: Lagrangian, -∇p/ϱ + ν∇²u (coupled_bc), dϱ/dt = -ϱ∇·u; IPST every ipst_every
 * steps. L-IPST-F and L-IPST-K change the viscous Laplacian only; L-PST-C the shifting and
 * L-RR-C the regularisation (remeshing), with L-IPST-C's rates. */
static const negi_terms l_ipst_c = {.lap = KIT_LAP_COUPLED};
static const negi_terms l_ipst_f = {.lap = KIT_LAP_FATEHI_C};
static const negi_terms l_ipst_k = {.lap = KIT_LAP_KORZILIUS};
static const negi_terms l_pst_c = {.lap = KIT_LAP_COUPLED};
static const negi_terms l_rr_c = {.lap = KIT_LAP_COUPLED};
/* 001 §5.4: dp/dt = -ρ_o c_o² ∇·u + D∇²p (eq. 30 with 001's authors' ρ_o c_o²; ϱ of eq. 31
 * in -∇p/ϱ, as 001's text: docs/schemes.md, "PE-IPST-C") */
static const negi_terms pe_ipst_c = {.lap = KIT_LAP_COUPLED, .diffuse_q = 1};
/* 001 §5.4 (eqs. 34-35): moved with u + δu, the δu terms in both rates, δ-term */
static const negi_terms tv_c = {.lap = KIT_LAP_COUPLED, .diffuse_q = 1, .transport = 1};
/* 001 eq. 36: Eulerian, both advection terms, δ-term */
static const negi_terms e_c = {
    .lap = KIT_LAP_COUPLED, .advect_u = 1, .advect_q = 1, .diffuse_q = 1};
/* Nasar et al. 2019 as 001 runs it: Eulerian without -u·∇ϱ, no δ-term, Cleary's viscosity
 * with the Bonet-corrected kernel gradient (001's authors' ewcsph.py, get_equations_ewcsph:
 * ViscosityCleary after GradientCorrection; docs/schemes.md, "EWCSPH") */
static const negi_terms ewcsph = {.lap = KIT_LAP_CLEARY, .advect_u = 1, .frozen_rho = 1};

/* Every scheme of the family: the rates its row's terms name. */
static int rhs_negi(consph_solver *s)
{
    return rates(s, s->scheme->terms);
}

const scheme_def scheme_l_ipst_c = {
    .name = "l-ipst-c",
    .summary = "001 §5.1.1: Lagrangian, asym_bc ∇p, div_bc, coupled_bc viscosity, IPST",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "rk2",
    .passes_min = 3,
    .reads = CONSPH_PARAM_IPST,
    .rhs = rhs_negi,
    .terms = &l_ipst_c,
    .regularise = regularise_ipst,
    .fields = negi_fields};
const scheme_def scheme_l_ipst_f = {.name = "l-ipst-f",
                                    .summary =
                                        "001 §5.1.1: L-IPST-C with the Fatehi_c viscosity (eq. 13)",
                                    .moves = 1,
                                    .evolve_p = 0,
                                    .layout = CONSPH_LAYOUT_PACKED,
                                    .eos = CONSPH_EOS_TAIT,
                                    .integrator = "rk2",
                                    .passes_min = 3,
                                    .reads = CONSPH_PARAM_IPST,
                                    .rhs = rhs_negi,
                                    .terms = &l_ipst_f,
                                    .regularise = regularise_ipst,
                                    .fields = negi_fields};
const scheme_def scheme_l_ipst_k = {
    .name = "l-ipst-k",
    .summary = "001 §5.1.1: L-IPST-C with the Korzilius viscosity (eqs. 14-15)",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "rk2",
    .passes_min = 3,
    .reads = CONSPH_PARAM_IPST,
    .rhs = rhs_negi,
    .terms = &l_ipst_k,
    .regularise = regularise_ipst,
    .fields = negi_fields};
const scheme_def scheme_l_pst_c = {
    .name = "l-pst-c",
    .summary = "001 §5.4: L-IPST-C with Sun et al.'s non-iterative PST every step (eq. 29)",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "rk2",
    .passes_min = 3,
    .rhs = rhs_negi,
    .terms = &l_pst_c,
    .regularise = regularise_pst,
    .fields = negi_fields};
const scheme_def scheme_pe_ipst_c = {
    .name = "pe-ipst-c",
    .summary = "001 §5.4: pressure evolution (eqs. 30-31), linear EOS, IPST",
    .moves = 1,
    .evolve_p = 1,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_LINEAR,
    .integrator = "rk2",
    .passes_min = 3,
    .reads = CONSPH_PARAM_DELTA | CONSPH_PARAM_IPST,
    .rhs = rhs_negi,
    .terms = &pe_ipst_c,
    .regularise = regularise_ipst,
    .fields = negi_fields};
const scheme_def scheme_l_rr_c = {
    .name = "l-rr-c",
    .summary = "001 §5.4: Lagrangian with M4 remeshing to the lattice every step (eqs. 32-33)",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_LATTICE,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "rk2",
    .needs_lattice = 1,
    .passes_min = 3,
    .rhs = rhs_negi,
    .terms = &l_rr_c,
    .regularise = regularise_remesh,
    .fields = negi_remesh_fields};
const scheme_def scheme_tv_c = {
    .name = "tv-c",
    .summary =
        "001 §5.4: transport velocity δu from Sun et al.'s PST (eqs. 34-35), δ-term, linear EOS",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_LINEAR,
    .integrator = "rk2",
    .passes_min = 4,
    .reads = CONSPH_PARAM_DELTA,
    .rhs = rhs_negi,
    .terms = &tv_c,
    .regularise = NULL,
    .fields = negi_fields};
const scheme_def scheme_e_c = {.name = "e-c",
                               .summary =
                                   "001 §5.4: Eulerian (eq. 36, keeps -u·∇ϱ), δ-term, linear EOS",
                               .moves = 0,
                               .evolve_p = 0,
                               .layout = CONSPH_LAYOUT_LATTICE,
                               .eos = CONSPH_EOS_LINEAR,
                               .integrator = "rk2",
                               .passes_min = 2,
                               .reads = CONSPH_PARAM_DELTA,
                               .rhs = rhs_negi,
                               .terms = &e_c,
                               .regularise = NULL,
                               .fields = negi_fields};
const scheme_def scheme_ewcsph = {
    .name = "ewcsph",
    .summary = "Nasar et al. 2019 as 001 runs it: Eulerian, drops -u·∇ϱ, ϱ from p (Tait)",
    .moves = 0,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_LATTICE,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "rk2",
    .passes_min = 2,
    .rhs = rhs_negi,
    .terms = &ewcsph,
    .regularise = NULL,
    .fields = negi_ewcsph_fields};

/* ---- fields: what these schemes declare beyond the solver's and the integrator's
 * (solver_internal.h, field_decl; the snapshot names are in docs/solver-files.md) ---- */
/* clang-format off */
#define NEGI_FIELDS                                                                                \
    {SF_RHOF, FIELD_SCALAR, FIELD_STATE, "density"},                                               \
    {SF_VOL, FIELD_SCALAR, FIELD_DERIVED, "volume"}, /* ω = 1/Σ W (kit_volumes) */                \
    {SF_BONET, FIELD_TENSOR, FIELD_DERIVED, NULL},                                                 \
    {SF_GRADP, FIELD_VECTOR, FIELD_DERIVED, NULL},                                                 \
    {SF_GRADQ, FIELD_VECTOR, FIELD_DERIVED, NULL},                                                 \
    {SF_LAPU, FIELD_VECTOR, FIELD_DERIVED, NULL},                                                  \
    {SF_LAPQ, FIELD_SCALAR, FIELD_DERIVED, NULL},                                                  \
    {SF_SHIFT, FIELD_VECTOR, FIELD_DERIVED, NULL} /* δr of a shift, δu of TV-C */
/* clang-format on */
const field_decl negi_fields[] = {NEGI_FIELDS, FIELD_END};
/* L-RR-C also keeps the lattice point each particle is remeshed to */
const field_decl negi_remesh_fields[] = {
    NEGI_FIELDS, {SF_LATTICE, FIELD_VECTOR, FIELD_STATE, NULL}, FIELD_END};
const field_decl negi_ewcsph_fields[] = {
    NEGI_FIELDS, {SF_RHOC, FIELD_SCALAR, FIELD_STATE, NULL}, FIELD_END};
/* ---- end of fields ---- */
