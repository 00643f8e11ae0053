/* The shifting velocities: Sun et al.'s for the δ+-SPH schemes (src/schemes/delta) and 001's
 * authors' for TV-C. */
#include "regularise/regularise.h"
#include "solver/solver_internal.h"

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

/* 001's TV-C as its authors compute it (tsph_dsph.py, ComputeShiftVelocity): δu = -2 h U Σ_j
 * (1 + 0.24 (W_ij/W(Δs))^4) ∇W_ij V_j, U the velocity scale. That is reg_pst_shift's δr at
 * CFL 0.5 and Ma = U/c_o (-2h² (U/c_o) Σ ...) times c_o/h; Sun's δr/Δt above, with R = 0.2
 * and CFL = Δt c_o/h, is -4hU Σ (1 + 0.2 (...)^4) ..., twice it (docs/schemes.md). */
int solver_shift_velocity_tvc_pass(consph_solver *s, double **du, reg_pst_job *job,
                                   consph_pass *pass)
{
    *du = sv_field(s, SF_SHIFT, s->dim);
    if (!*du) return CONSPH_ENOMEM;
    reg_pst_params pp = {s->h, s->ds, 0.5, s->prm.U / s->c0, 0.24, 4.0, 0.0};
    return reg_pst_pass(&s->sys, &pp, *du, job, pass);
}

void solver_shift_velocity_tvc_finish(consph_solver *s, double *du)
{
    const int d = s->dim;
    const size_t n = s->sys.p->n, cap = s->sys.p->cap;
    ++s->passes;
    const double to_velocity = s->c0 / s->h;
    for (int a = 0; a < d; ++a)
        for (size_t i = 0; i < n; ++i) du[a * cap + i] *= to_velocity;
}

int solver_shift_velocity_tvc(consph_solver *s, double **du)
{
    reg_pst_job job;
    consph_pass pass;
    int st = solver_shift_velocity_tvc_pass(s, du, &job, &pass);
    if (st == CONSPH_OK) st = consph_pass_run(&s->sys, &pass, &job);
    if (st == CONSPH_OK) solver_shift_velocity_tvc_finish(s, *du);
    return st;
}
