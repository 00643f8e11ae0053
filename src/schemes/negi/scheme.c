/* The schemes of 001 §5 as table entries: the rates of each from the kit's fused passes, and
 * its regularisation (docs/schemes.md records every choice with its source).
 *
 * Every rate is a per-particle combination of the kit's derivatives:
 *   du/dt = -∇p/ϱ + ν∇²u  [- (u·∇)u Eulerian]  [+ (δu·∇)u TV-C]
 *   dϱ/dt = -ϱ∇·u  [+ D∇²ϱ]  [- u·∇ϱ E-C]  [+ δu·∇ϱ TV-C]
 *   dp/dt = -ϱ c_o² ∇·u + D∇²p   (PE-IPST-C, eq. 30; ϱ from eq. 31)
 *   dx/dt = u  [+ δu TV-C]  (0 Eulerian)
 * with ∇p asym_bc, ∇u f4 (asym_bc per component), ∇·u div_bc and the Laplacians of Table 6. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "regularise/regularise.h"
#include "solver/solver_internal.h"

enum {
    T_EULER = 1u << 0,    /* -(u·∇)u, and -u·∇ϱ unless T_NO_ADV_Q */
    T_NO_ADV_Q = 1u << 1, /* EWCSPH: the continuity equation drops -u·∇ϱ (Nasar et al.) */
    T_DIFFUSE = 1u << 2,  /* D∇²q (δ-SPH term, eq. 27) */
    T_TV = 1u << 3        /* the shifting velocity δu of TV-C (eqs. 34-35) */
};

int solver_shift_velocity(consph_solver *s, double **du)
{
    const int d = s->dim;
    const size_t n = s->sys.p->n, cap = s->sys.p->cap;
    *du = sv_field(s, SF_SHIFT, d);
    if (!*du) return CONSPH_ENOMEM;
    reg_pst_params pp = {s->h, s->ds, s->dt * s->c0 / s->h, s->prm.U / s->c0, 0.2, 4.0, 0.0};
    int st = reg_pst_shift(&s->sys, &pp, *du);
    if (st != CONSPH_OK) return st;
    ++s->passes;
    const double inv_dt = 1.0 / s->dt;
    for (int a = 0; a < d; ++a)
        for (size_t i = 0; i < n; ++i) (*du)[a * cap + i] *= inv_dt;
    return CONSPH_OK;
}

static int rates(consph_solver *s, kit_lap lap, unsigned terms)
{
    consph_sys *sys = &s->sys;
    consph_particles *p = sys->p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    int st = CONSPH_OK;
    s->passes = 0;
    if (!s->volumes_fixed) {
        st = kit_volumes(sys, &s->pairs);
        if (st != CONSPH_OK) return st;
        s->passes = 1;
    }
    const char *q = s->scheme->evolve_p ? SF_P : SF_RHOF;
    kit_req rq = {KIT_GRADP | KIT_LAPU | KIT_DIVU, lap, q, 1e8};
    if (terms & T_DIFFUSE) rq.want |= KIT_LAPQ;
    if ((terms & T_TV) || ((terms & T_EULER) && !(terms & T_NO_ADV_Q))) rq.want |= KIT_GRADQ;
    st = kit_derivatives(sys, &rq, &s->pairs, &s->passes);
    if (st != CONSPH_OK) return st;
    double *du = NULL;
    if (terms & T_TV) {
        /* 001 §5.4 item 4: the PST of [33] as a transport velocity */
        st = solver_shift_velocity(s, &du);
        if (st != CONSPH_OK) return st;
    }
    const double *u = sv_field(s, SF_U, d), *rhof = sv_field(s, SF_RHOF, 1);
    const double *gradp = sv_field(s, SF_GRADP, d), *G = sv_field(s, SF_GRADU, d * d);
    const double *lapu = sv_field(s, SF_LAPU, d), *divu = sv_field(s, SF_DIVU, 1);
    const double *gradq = (rq.want & KIT_GRADQ) ? sv_field(s, SF_GRADQ, d) : NULL;
    const double *lapq = (rq.want & KIT_LAPQ) ? sv_field(s, SF_LAPQ, 1) : NULL;
    double *ax = s->scheme->moves ? sv_field(s, SF_AX, d) : NULL;
    double *au = sv_field(s, SF_AU, d), *aq = sv_field(s, SF_AQ, 1);
    if (!u || !rhof || !gradp || !G || !lapu || !divu || !au || !aq || (s->scheme->moves && !ax))
        return CONSPH_ENOMEM;
    const double nu = s->nu, D = s->D, c2 = s->c0 * s->c0;
    const int evolve_p = s->scheme->evolve_p;
#pragma omp parallel for schedule(static) if (n > sys->parallel_min)
    for (size_t i = 0; i < n; ++i) {
        double ui[3], dui[3] = {0.0, 0.0, 0.0};
        for (int a = 0; a < d; ++a) ui[a] = u[a * cap + i];
        if (du)
            for (int a = 0; a < d; ++a) dui[a] = du[a * cap + i];
        for (int a = 0; a < d; ++a) {
            double v = -gradp[a * cap + i] / rhof[i] + nu * lapu[a * cap + i];
            for (int b = 0; b < d; ++b) {
                double g = G[(size_t)(a * d + b) * cap + i];
                if (terms & T_EULER) v -= ui[b] * g;
                if (terms & T_TV) v += dui[b] * g;
            }
            au[a * cap + i] = v;
            if (ax) ax[a * cap + i] = ui[a] + dui[a];
        }
        double r = evolve_p ? -rhof[i] * c2 * divu[i] : -rhof[i] * divu[i];
        if (lapq) r += D * lapq[i];
        if (gradq)
            for (int a = 0; a < d; ++a) {
                double gq = gradq[a * cap + i];
                if ((terms & T_EULER) && !(terms & T_NO_ADV_Q)) r -= ui[a] * gq;
                if (terms & T_TV) r += dui[a] * gq;
            }
        aq[i] = r;
    }
    return CONSPH_OK;
}

static int rhs_l_c(consph_solver *s)
{
    return rates(s, KIT_LAP_COUPLED, 0);
}
static int rhs_l_f(consph_solver *s)
{
    return rates(s, KIT_LAP_FATEHI_C, 0);
}
static int rhs_l_k(consph_solver *s)
{
    return rates(s, KIT_LAP_KORZILIUS, 0);
}
static int rhs_pe_c(consph_solver *s)
{
    return rates(s, KIT_LAP_COUPLED, T_DIFFUSE);
}
static int rhs_tv_c(consph_solver *s)
{
    return rates(s, KIT_LAP_COUPLED, T_DIFFUSE | T_TV);
}
static int rhs_e_c(consph_solver *s)
{
    return rates(s, KIT_LAP_COUPLED, T_DIFFUSE | T_EULER);
}
static int rhs_ewcsph(consph_solver *s)
{
    return rates(s, KIT_LAP_COUPLED, T_EULER | T_NO_ADV_Q);
}

/* The gradients of u and of the evolved scalar at the positions before a shift (the Taylor
 * update of eq. 22 uses them), with fresh volumes. */
static int gradients_for_shift(consph_solver *s)
{
    int passes = 0;
    int st = kit_volumes(&s->sys, &s->pairs);
    kit_req rq = {KIT_GRADU | KIT_GRADQ, KIT_LAP_COUPLED, s->scheme->evolve_p ? SF_P : SF_RHOF,
                  1e8};
    return st == CONSPH_OK ? kit_derivatives(&s->sys, &rq, &s->pairs, &passes) : st;
}

static int zeroed_shift(consph_solver *s, double **dr)
{
    *dr = sv_field(s, SF_SHIFT, s->dim);
    if (!*dr) return CONSPH_ENOMEM;
    for (int a = 0; a < s->dim; ++a)
        memset(*dr + (size_t)a * s->sys.p->cap, 0, s->sys.p->n * sizeof(double));
    return CONSPH_OK;
}

/* IPST every ipst_every steps (001 §5.1.1). */
static int regularise_ipst(consph_solver *s)
{
    if (s->prm.ipst_every <= 0 || s->step % s->prm.ipst_every != 0) return CONSPH_OK;
    double *dr;
    int st = gradients_for_shift(s);
    if (st == CONSPH_OK) st = zeroed_shift(s, &dr);
    if (st != CONSPH_OK) return st;
    reg_ipst_params ip = {s->h, s->chi0, s->prm.ipst_tol, s->prm.ipst_max_iter};
    reg_ipst_report rep;
    st = reg_ipst(&s->sys, &ip, dr, &rep);
    if (st != CONSPH_OK) return st;
    solver_taylor_update(s, dr);
    ++s->regs;
    return CONSPH_OK;
}

/* The non-iterative shifting of Sun et al. every step (L-PST-C). */
static int regularise_pst(consph_solver *s)
{
    double *dr;
    int st = gradients_for_shift(s);
    if (st == CONSPH_OK) st = zeroed_shift(s, &dr);
    if (st != CONSPH_OK) return st;
    reg_pst_params pp = {s->h, s->ds, s->dt * s->c0 / s->h, s->prm.U / s->c0, 0.2, 4.0, 0.0};
    st = reg_pst_shift(&s->sys, &pp, dr);
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

const scheme_def scheme_l_ipst_c = {
    .name = "l-ipst-c",
    .summary = "001 §5.1.1: Lagrangian, asym_bc ∇p, div_bc, coupled_bc viscosity, IPST",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "rk2",
    .passes_min = 3,
    .rhs = rhs_l_c,
    .regularise = regularise_ipst};
const scheme_def scheme_l_ipst_f = {.name = "l-ipst-f",
                                    .summary =
                                        "001 §5.1.1: L-IPST-C with the Fatehi_c viscosity (eq. 13)",
                                    .moves = 1,
                                    .evolve_p = 0,
                                    .layout = CONSPH_LAYOUT_PACKED,
                                    .eos = CONSPH_EOS_TAIT,
                                    .integrator = "rk2",
                                    .passes_min = 3,
                                    .rhs = rhs_l_f,
                                    .regularise = regularise_ipst};
const scheme_def scheme_l_ipst_k = {
    .name = "l-ipst-k",
    .summary = "001 §5.1.1: L-IPST-C with the Korzilius viscosity (eqs. 14-15)",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "rk2",
    .passes_min = 3,
    .rhs = rhs_l_k,
    .regularise = regularise_ipst};
const scheme_def scheme_l_pst_c = {
    .name = "l-pst-c",
    .summary = "001 §5.4: L-IPST-C with Sun et al.'s non-iterative PST every step (eq. 29)",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "rk2",
    .passes_min = 3,
    .rhs = rhs_l_c,
    .regularise = regularise_pst};
const scheme_def scheme_pe_ipst_c = {
    .name = "pe-ipst-c",
    .summary = "001 §5.4: pressure evolution (eqs. 30-31), linear EOS, IPST",
    .moves = 1,
    .evolve_p = 1,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_LINEAR,
    .integrator = "rk2",
    .passes_min = 3,
    .reads = CONSPH_PARAM_DELTA,
    .rhs = rhs_pe_c,
    .regularise = regularise_ipst};
const scheme_def scheme_l_rr_c = {
    .name = "l-rr-c",
    .summary = "001 §5.4: Lagrangian with M4 remeshing to the lattice every step (eqs. 32-33)",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_LATTICE,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "rk2",
    .passes_min = 3,
    .rhs = rhs_l_c,
    .regularise = regularise_remesh};
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
    .rhs = rhs_tv_c,
    .regularise = NULL};
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
                               .rhs = rhs_e_c,
                               .regularise = NULL};
const scheme_def scheme_ewcsph = {
    .name = "ewcsph",
    .summary = "Nasar et al. 2019 as 001 runs it: Eulerian, drops -u·∇ϱ, ϱ from p (Tait)",
    .moves = 0,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_LATTICE,
    .eos = CONSPH_EOS_TAIT,
    .integrator = "rk2",
    .passes_min = 2,
    .rhs = rhs_ewcsph,
    .regularise = NULL};

/* The table, in the order consph_scheme_names lists; a scheme family in its own file adds its
 * rows here (their definitions are declared in solver_internal.h). */
static const scheme_def *const schemes[] = {
    &scheme_l_ipst_c,
    &scheme_l_ipst_f,
    &scheme_l_ipst_k,
    &scheme_l_pst_c,
    &scheme_pe_ipst_c,
    &scheme_l_rr_c,
    &scheme_tv_c,
    &scheme_e_c,
    &scheme_ewcsph,
    &scheme_wcsph,
    &scheme_tvf,
    &scheme_edac,
    &scheme_delta_sph,
    &scheme_delta_plus_sph,
    &scheme_delta_plus_sph_d,
};

const scheme_def *scheme_find(const char *name)
{
    for (size_t k = 0; k < sizeof schemes / sizeof schemes[0]; ++k)
        if (strcmp(schemes[k]->name, name) == 0) return schemes[k];
    return NULL;
}

/* Kept in table order; test_solver checks that every name resolves and the table has no other. */
const char *consph_scheme_names(void)
{
    return "l-ipst-c,l-ipst-f,l-ipst-k,l-pst-c,pe-ipst-c,l-rr-c,tv-c,e-c,ewcsph,wcsph,tvf,edac,"
           "delta-sph,delta-plus-sph,delta-plus-sph-d";
}

int consph_scheme_uses_ipst(const char *name)
{
    return consph_scheme_reads(name, CONSPH_PARAM_IPST);
}

int consph_scheme_reads(const char *name, unsigned param)
{
    const scheme_def *sd = scheme_find(name);
    if (!sd) return 0;
    switch (param) {
    case CONSPH_PARAM_EOS:
        /* solver_eos and the initial density are the only readers; a closure or an evolved p
         * replaces both */
        return !sd->evolve_p && !sd->closure;
    case CONSPH_PARAM_IPST:
        return sd->regularise == regularise_ipst;
    default:
        return (sd->reads & param) != 0;
    }
}

const char *consph_scheme_readers(unsigned param, char *buf, size_t size)
{
    size_t len = 0;
    if (size) buf[0] = '\0';
    for (size_t k = 0; k < scheme_count() && len < size; ++k)
        if (consph_scheme_reads(schemes[k]->name, param)) {
            int w = snprintf(buf + len, size - len, "%s%s", len ? ", " : "", schemes[k]->name);
            if (w < 0) break;
            len += (size_t)w;
        }
    return buf;
}

size_t scheme_count(void)
{
    return sizeof schemes / sizeof schemes[0];
}
