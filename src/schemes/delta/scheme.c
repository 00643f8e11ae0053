/* The δ-SPH family: δ-SPH (Antuono et al. 2010, Marrone et al. 2011), δ+-SPH (Sun et al. 2017,
 * 2019) and δ+-SPH with the conservative correction of 001 App. D. docs/schemes.md records
 * every choice with its source (PySPH 1.0b1's wc/basic.py, wc/viscosity.py and
 * wc/kernel_correction.py are the readable reference for the constants).
 *
 * One density: ρ is evolved and gives both the pressure (EOS) and the volumes V_j = m/ρ_j of
 * every sum (001 §5.2: these schemes make no distinction between ϱ and ρ), so "volume" holds
 * m/ρ, set before each right-hand side; the masses m_i = ρ_i(0) Δs^d (field "mass"). With x_ij =
 * x_i - x_j, ∇W_ij = dwr x_ij, u_ji = u_j - u_i: dρ_i/dt = -ρ_i Σ u_ji·∇W_ij V_j + δ h c_o Σ
 * ψ_ij·∇W_ij V_j             (Marrone eq. 5a) ψ_ij = 2 (ρ_j - ρ_i) x_ji/r² - (⟨∇ρ⟩^L_i + ⟨∇ρ⟩^L_j)
 *   du_i/dt = -(1/ρ_i) Σ (p_i + p_j) ∇W_ij V_j                                  (sym1)
 *             + (α h c_o + 2(d + 2) ν) (ρ_o/ρ_i) Σ π_ij ∇W_ij V_j,  π_ij = u_ji·x_ji/r²
 * ⟨∇ρ⟩^L the renormalised gradient L_i Σ (ρ_j - ρ_i) ∇W_ij V_j, L_i = (Σ x_ji ⊗ ∇W_ij V_j)^-1.
 * δ+-SPH moves the particles with u + δu, δu = δr/Δt from Sun's shifting (reg_pst_shift), and
 * adds the shifting terms ∇f·δu (001 eq. D.1) to the rates of f = ρ and f = u in Sun et al.
 * 2019's form ∇·(f δu) - f ∇·δu, the first as the sum Σ (f_j δu_j + f_i δu_i)·∇W_ij V_j, the
 * second as the difference f_i Σ (δu_j - δu_i)·∇W_ij V_j; δ+-SPH-D uses 001's eq. D.5 instead,
 * δu_i·Σ (f_j - f_i) ∇W_ij V_j, which is ∇f·δu_i to first order. */
#include <math.h>
#include <string.h>

#include "ops/terms.h"
#include "regularise/regularise.h"
#include "schemes/delta/iact.h"
#include "solver/solver_internal.h"

#define SF_GRADRHO_L "gradrho_l" /* ⟨∇ρ⟩^L, d */

#if defined(__GNUC__)
#define DELTA_INLINE static inline __attribute__((always_inline))
#else
#define DELTA_INLINE static inline
#endif

typedef struct delta_job {
    int d, shift;
    size_t cap;
    const double *vol, *rho, *p, *u, *du;
    double *L, *gradrho;
    double *au, *aq, *ax, *gradp, *divu, *gradu;
    double h_c0_delta, visc; /* δ h c_o and (α h c_o + 2(d+2)ν) ρ_o */
} delta_job;

/* Pass 1: L_i and the renormalised density gradient. */
static void visit_renorm(void *vjob, const consph_nbhd *nb)
{
    const delta_job *job = vjob;
    const int d = job->d;
    const size_t i = nb->i, cap = job->cap;
    double moment[9], L[9], sg[3], sw, g[3];
    const double zero[3] = {0.0, 0.0, 0.0};
    term_bonet_moment_any(d, nb, job->vol, moment);
    consph_bonet_finalise(d, moment, 1e8, L, NULL);
    term_grad_sums_any(d, TERM_GRAD_DIFF, 0, nb, job->vol, NULL, NULL, job->rho, job->rho[i], sg,
                       &sw);
    term_apply_rule(d, zero, L, sg, sw, g);
    for (int e = 0; e < d * d; ++e) job->L[(size_t)e * cap + i] = L[e];
    for (int a = 0; a < d; ++a) job->gradrho[a * cap + i] = g[a];
}

/* Pass 2: every rate, the pair terms of iact.h summed in neighbour order. */
DELTA_INLINE void visit_rates_d(const delta_job *job, const consph_nbhd *nb, const int d,
                                const int shift)
{
    const size_t i = nb->i, cap = job->cap;
    const double *restrict u = job->u, *restrict rho = job->rho, *restrict vol = job->vol;
    const double *restrict p = job->p, *restrict gr = job->gradrho, *restrict du = job->du;
    const double rhoi = rho[i], pi = p[i];
    double ui[3] = {0.0, 0.0, 0.0}, dui[3] = {0.0, 0.0, 0.0}, gri[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) {
        ui[a] = u[a * cap + i];
        gri[a] = gr[a * cap + i];
    }
    if (shift != DELTA_SHIFT_NONE)
        for (int a = 0; a < d; ++a) dui[a] = du[a * cap + i];
    delta_sums s = {0};
    for (size_t q = 0; q < nb->n; ++q) {
        const double r = nb->r[q];
        if (!(r > 0.0)) continue;
        const size_t j = nb->j[q];
        double x[3] = {0.0, 0.0, 0.0}, uj[3] = {0.0, 0.0, 0.0}, duj[3] = {0.0, 0.0, 0.0};
        double grj[3] = {0.0, 0.0, 0.0};
        for (int a = 0; a < d; ++a) {
            x[a] = nb->dx[a][q];
            uj[a] = u[a * cap + j];
            grj[a] = gr[a * cap + j];
        }
        if (shift == DELTA_SHIFT_SUN)
            for (int a = 0; a < d; ++a) duj[a] = du[a * cap + j];
        delta_pair(d, shift, rhoi, pi, ui, dui, gri, rho[j], p[j], uj, duj, grj, vol[j], nb->dwr[q],
                   x, r, &s);
    }
    double L[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    for (int e = 0; e < d * d; ++e) L[e] = job->L[(size_t)e * cap + i];
    double au[3] = {0.0, 0.0, 0.0}, gradp[3] = {0.0, 0.0, 0.0}, ax[3] = {0.0, 0.0, 0.0};
    double gradu[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, divu = 0.0, aq = 0.0;
    delta_rates_i(d, &s, rhoi, ui, dui, L, job->visc, job->h_c0_delta, au, gradp, ax, gradu, &divu,
                  &aq);
    for (int a = 0; a < d; ++a) {
        job->au[a * cap + i] = au[a];
        job->gradp[a * cap + i] = gradp[a];
        if (job->ax) job->ax[a * cap + i] = ax[a];
        for (int b = 0; b < d; ++b) job->gradu[(size_t)(a * d + b) * cap + i] = gradu[a * d + b];
    }
    job->divu[i] = divu;
    job->aq[i] = aq;
}

/* Clones with d and the shifting form compile-time constants (2D and 3D), so that the pair
 * term's loops unroll and its sums, G's included, stay in registers: a run-time d leaves G in
 * memory and costs 7 % (3D) to 25 % (2D) more instructions. */
DELTA_INLINE void visit_rates_shift(const delta_job *job, const consph_nbhd *nb, const int shift)
{
    if (job->d == 2)
        visit_rates_d(job, nb, 2, shift);
    else if (job->d == 3)
        visit_rates_d(job, nb, 3, shift);
    else
        visit_rates_d(job, nb, job->d, shift);
}

static void visit_rates(void *vjob, const consph_nbhd *nb)
{
    const delta_job *job = vjob;
    if (job->shift == DELTA_SHIFT_SUN)
        visit_rates_shift(job, nb, DELTA_SHIFT_SUN);
    else if (job->shift == DELTA_SHIFT_APP_D)
        visit_rates_shift(job, nb, DELTA_SHIFT_APP_D);
    else
        visit_rates_shift(job, nb, DELTA_SHIFT_NONE);
}

/* What the passes read at the neighbours (consph_sys_next_reads): Sun's shift V_j
 * (reg_pst_shift), the renormalisation V_j and ρ_j, the rates V_j, ρ_j, p_j, u_j, ⟨∇ρ⟩^L_j and,
 * with Sun's shifting terms, δu_j. */
static const consph_sys_reads shift_reads = {0, 0, {SF_VOL}, {0}};
static const consph_sys_reads renorm_reads = {0, 0, {SF_VOL, SF_RHOF}, {0}};
static const consph_sys_reads rates_reads = {
    0, 0, {SF_VOL, SF_RHOF, SF_P, SF_U, SF_GRADRHO_L}, {0}};
static const consph_sys_reads rates_sun_reads = {
    0, 0, {SF_VOL, SF_RHOF, SF_P, SF_U, SF_GRADRHO_L, SF_SHIFT}, {0}};

static int delta_rates(consph_solver *s, int shift)
{
    consph_sys *sys = &s->sys;
    consph_particles *p = sys->p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    double *vol = sv_field(s, SF_VOL, 1), *m = sv_field(s, SF_MASS, 1);
    const double *rho = sv_field(s, SF_RHOF, 1);
    if (!vol || !rho || !m) return CONSPH_ENOMEM;
    /* set-up created the masses zero; tested at a particle of the solver's own (a decomposed
     * system's halo holds what the migration brought) */
    const size_t i0 = solver_first_own(s);
    const int first = i0 < n && !(m[i0] > 0.0);
    /* m_i = ρ_i(0) Δs^d, so that V_i = m_i/ρ_i starts at the particle's volume Δs^d whatever
     * the initial pressure (Gresho-Chan's ρ is 5 % above ρ_o); a checkpoint carries the field */
    if (first)
        for (size_t i = 0; i < n; ++i) m[i] = rho[i] * s->mass / s->prm.rho0;
    for (size_t i = 0; i < n; ++i) vol[i] = m[i] / rho[i];
    s->passes = 0;
    double *du = NULL;
    int st = CONSPH_OK;
    if (shift != DELTA_SHIFT_NONE) {
        consph_sys_next_reads(sys, &shift_reads);
        st = solver_shift_velocity(s, &du);
        if (st != CONSPH_OK) return st;
    }
    delta_job job = {.d = d,
                     .shift = shift,
                     .cap = cap,
                     .vol = vol,
                     .rho = rho,
                     .p = sv_field(s, SF_P, 1),
                     .u = sv_field(s, SF_U, d),
                     .du = du,
                     .L = sv_field(s, SF_BONET, d * d),
                     .gradrho = sv_field(s, SF_GRADRHO_L, d),
                     .au = sv_field(s, SF_AU, d),
                     .aq = sv_field(s, SF_AQ, 1),
                     .ax = sv_field(s, SF_AX, d),
                     .gradp = sv_field(s, SF_GRADP, d),
                     .divu = sv_field(s, SF_DIVU, 1),
                     .gradu = sv_field(s, SF_GRADU, d * d),
                     .h_c0_delta = s->D,
                     .visc = ((s->prm.alpha >= 0.0 ? s->prm.alpha : 0.0) * s->h * s->c0 +
                              2.0 * (d + 2) * s->nu) *
                             s->prm.rho0};
    if (!job.p || !job.u || !job.L || !job.gradrho || !job.au || !job.aq || !job.ax || !job.gradp ||
        !job.divu || !job.gradu)
        return CONSPH_ENOMEM;
    const consph_pass renorm = {"delta-SPH: renormalised density gradient", CONSPH_PASS_DW,
                                visit_renorm};
    const consph_pass rates = {"delta-SPH: rates", CONSPH_PASS_DW, visit_rates};
    consph_sys_next_reads(sys, &renorm_reads);
    st = consph_pass_run_counted(sys, &renorm, &job, &s->pairs);
    if (st != CONSPH_OK) return st;
    consph_sys_next_reads(sys, shift == DELTA_SHIFT_SUN ? &rates_sun_reads : &rates_reads);
    st = consph_pass_run_counted(sys, &rates, &job, &s->pairs);
    if (st != CONSPH_OK) return st;
    s->passes += 2;
    return CONSPH_OK;
}

static int rhs_delta(consph_solver *s)
{
    return delta_rates(s, DELTA_SHIFT_NONE);
}
static int rhs_delta_plus(consph_solver *s)
{
    return delta_rates(s, DELTA_SHIFT_SUN);
}
static int rhs_delta_plus_d(consph_solver *s)
{
    return delta_rates(s, DELTA_SHIFT_APP_D);
}

const scheme_def scheme_delta_sph = {
    .name = "delta-sph",
    .summary = "Antuono et al. 2010 / Marrone et al. 2011: δ-diffusion with the renormalised "
               "density gradient, sym1 pressure, artificial viscosity α, linear EOS",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_LINEAR,
    .integrator = "rk2",
    .passes_min = 2,
    .reads = CONSPH_PARAM_ALPHA | CONSPH_PARAM_DELTA,
    .rhs = rhs_delta,
    .regularise = NULL,
    .fields = delta_fields};
const scheme_def scheme_delta_plus_sph = {
    .name = "delta-plus-sph",
    .summary = "Sun et al. 2017/2019: δ-SPH moved with u + δu (Sun's shifting), shifting terms "
               "∇·(f δu) - f ∇·δu in Sun's sum and difference forms",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_LINEAR,
    .integrator = "rk2",
    .passes_min = 3,
    .reads = CONSPH_PARAM_ALPHA | CONSPH_PARAM_DELTA,
    .rhs = rhs_delta_plus,
    .regularise = NULL,
    .fields = delta_fields};
const scheme_def scheme_delta_plus_sph_d = {
    .name = "delta-plus-sph-d",
    .summary = "δ+-SPH with the correction of 001 App. D: shifting terms δu_i·Σ (f_j - f_i) "
               "∇W_ij V_j (eq. D.5)",
    .moves = 1,
    .evolve_p = 0,
    .layout = CONSPH_LAYOUT_PACKED,
    .eos = CONSPH_EOS_LINEAR,
    .integrator = "rk2",
    .passes_min = 3,
    .reads = CONSPH_PARAM_ALPHA | CONSPH_PARAM_DELTA,
    .rhs = rhs_delta_plus_d,
    .regularise = NULL,
    .fields = delta_fields};

/* ---- fields: what these schemes declare beyond the solver's and the integrator's
 * (solver_internal.h, field_decl; the snapshot names are in docs/solver-files.md) ---- */
const field_decl delta_fields[] = {{SF_RHOF, FIELD_SCALAR, FIELD_STATE, "density"},
                                   {SF_VOL, FIELD_SCALAR, FIELD_DERIVED, "volume"}, /* m/ρ */
                                   {SF_MASS, FIELD_SCALAR, FIELD_STATE, "mass"},
                                   {SF_BONET, FIELD_TENSOR, FIELD_DERIVED, NULL}, /* L_i */
                                   {SF_GRADRHO_L, FIELD_VECTOR, FIELD_DERIVED, NULL},
                                   {SF_GRADP, FIELD_VECTOR, FIELD_DERIVED, NULL},
                                   {SF_SHIFT, FIELD_VECTOR, FIELD_DERIVED, NULL}, /* δu of δ+-SPH */
                                   FIELD_END};
/* ---- end of fields ---- */
