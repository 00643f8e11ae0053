/* The shifting velocity of Sun et al. (δ+-SPH; 001's TV-C): reg_pst_shift's δr at the
 * solver's constants, divided by Δt. */
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
