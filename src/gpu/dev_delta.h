/* The GPU's per-particle functions of the δ-SPH family (src/schemes/delta/scheme.c: delta-sph,
 * delta-plus-sph, delta-plus-sph-d): delta_rates' volumes V = m/ρ, its pass 1 (L_i and the
 * renormalised density gradient ⟨∇ρ⟩^L, visit_renorm) and pass 2 (the rates, visit_rates_d);
 * δ+-SPH's shifting velocity δu = δr/Δt of Sun et al. (solver_shift_velocity) is dev_negi.h's
 * dev_pst_shift_d at the constants gpu.c sets. Part of dev.h (its walk, kernel and view); each
 * sum gathers over the neighbours in the CPU's order, and the arithmetic is the CPU's own code:
 * pass 1's sums and finish are the kit's (kit_pair.h: term_moments' Bonet moment and
 * term_grad_sums' Σ V_j (ρ_j - ρ_i) ∇W_ij, the inverse of consph_bonet_finalise, term_apply_rule),
 * pass 2 the family's pair term and per-particle rates (src/schemes/delta/iact.h). */
#ifndef CONSPH_GPU_DEV_DELTA_H
#define CONSPH_GPU_DEV_DELTA_H

#include "schemes/delta/iact.h"

/* delta_rates: V_i = m_i/ρ_i (the field "volume", which Sun's shift reads too). */
GPU_FN void dev_delta_volumes(const gpu_view *v, size_t i)
{
    gv(v, GA_VOL, 0)[i] = gv(v, GA_MASS, 0)[i] / gv(v, GA_RHOF, 0)[i];
}

/* The rate pass's neighbour records (the view's pack, in slot order): ρ, p, V, ⟨∇ρ⟩^L, u and, for
 * δ+-SPH, δu, padded to an even width so that every record is read in 16-byte pairs. */
GPU_FN int gpu_delta_pack_width(int d, int shift)
{
    return (3 + 2 * d + (shift == DELTA_SHIFT_SUN ? d : 0) + 1) & ~1;
}

/* Pass 1 at particle i (visit_renorm): L_i, the inverted Bonet moment Σ -V_j ∇W_ij ⊗ x_ij (the
 * identity where singular or conditioned worse than 1e8), into the bonet field, and ⟨∇ρ⟩^L_i =
 * L_i Σ V_j (ρ_j - ρ_i) ∇W_ij into gradrho_l (GA_GRADQ). Both sums over every neighbour, i
 * itself included (its ∇W_ii x_ii is 0), in the walk's order: one walk for the CPU's two loops. */
GPU_FN_INLINE void dev_delta_renorm_d(const gpu_view *v, size_t i, const int D)
{
    const double *vol = gv(v, GA_VOL, 0), *rho = gv(v, GA_RHOF, 0);
    const double rhoi = rho[i], none[3] = {0.0, 0.0, 0.0};
    double sm[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    double su[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    double sp[3] = {0.0, 0.0, 0.0}, sq[3] = {0.0, 0.0, 0.0};
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, D);
    double x[3], r;
    uint32_t sl;
    size_t cnt = 0;
    while (gpu_walkr_next(v, &w, D, &sl, x, &r)) {
        const uint32_t j = GPU_LDG(&v->order[sl]);
        kit_first_pair(D, 0, 0, 1, vol[j], gpu_dwr(&v->k, r), x, 0.0, 0.0, none, none, rho[j], rhoi,
                       sm, sp, su, sq);
        ++cnt;
    }
    /* this pass's neighbours and the rate pass's, which walks the same ones (the CPU counts
     * both): a counter there would cost the rate kernels registers */
    gpu_pairs_add(v, i, 2 * cnt);
    double L[9], gp[3], G[9], div = 0.0, gr[3];
    kit_first_finish(D, 0, 0, 1, sm, v->cond_max, sp, su, sq, L, gp, G, &div, gr);
    for (int e = 0; e < D * D; ++e) gv(v, GA_BONET, e)[i] = L[e];
    for (int a = 0; a < D; ++a) gv(v, GA_GRADQ, a)[i] = gr[a];
    /* i's record for pass 2 (δu written by the shift's launch before this one) */
    const int sun = v->dshift == DELTA_SHIFT_SUN, K = gpu_delta_pack_width(D, v->dshift);
    double *rec = v->pack + (size_t)v->slot_of[i] * (size_t)K;
    rec[0] = rhoi;
    rec[1] = gv(v, GA_P, 0)[i];
    rec[2] = vol[i];
    for (int a = 0; a < D; ++a) {
        rec[3 + a] = gr[a];
        rec[3 + D + a] = gv(v, GA_U, a)[i];
        if (sun) rec[3 + 2 * D + a] = gv(v, GA_SHIFT, a)[i];
    }
    if ((3 + 2 * D + (sun ? D : 0)) & 1) rec[K - 1] = 0.0;
}

GPU_BY_DIM(dev_delta_renorm, dev_delta_renorm_d)

/* Pass 2 at particle i (visit_rates_d): delta_pair over the neighbours at r > 0 in the walk's
 * order, each neighbour's values from its slot's record (pass 1 wrote them), then delta_rates_i;
 * SHIFT the scheme's shifting form (iact.h's DELTA_SHIFT_*), δu from the shift field. D and SHIFT
 * constants once inlined: the sums stay in registers. */
GPU_FN_INLINE void dev_delta_rates_d(const gpu_view *v, size_t i, const int D, const int SHIFT)
{
    const double rhoi = gv(v, GA_RHOF, 0)[i], pi = gv(v, GA_P, 0)[i];
    double ui[3] = {0.0, 0.0, 0.0}, dui[3] = {0.0, 0.0, 0.0}, gri[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < D; ++a) {
        ui[a] = gv(v, GA_U, a)[i];
        gri[a] = gv(v, GA_GRADQ, a)[i];
        if (SHIFT != DELTA_SHIFT_NONE) dui[a] = gv(v, GA_SHIFT, a)[i];
    }
    delta_sums s;
    s.divu = s.diff = s.shq = 0.0;
    for (int a = 0; a < 3; ++a) s.gp[a] = s.visc[a] = s.shu[a] = 0.0;
    for (int e = 0; e < 9; ++e) s.G[e] = 0.0;
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, D);
    double x[3], r;
    uint32_t sl;
    const int K = (3 + 2 * D + (SHIFT == DELTA_SHIFT_SUN ? D : 0) + 1) & ~1; /* pack width */
    while (gpu_walkr_next(v, &w, D, &sl, x, &r)) {
        if (!(r > 0.0)) continue;
        double q[12], uj[3] = {0.0, 0.0, 0.0}, duj[3] = {0.0, 0.0, 0.0}, grj[3] = {0.0, 0.0, 0.0};
        gpu_pack_read(v->pack + (size_t)sl * (size_t)K, q, K);
        for (int a = 0; a < D; ++a) {
            grj[a] = q[3 + a];
            uj[a] = q[3 + D + a];
            if (SHIFT == DELTA_SHIFT_SUN) duj[a] = q[3 + 2 * D + a];
        }
        delta_pair(D, SHIFT, rhoi, pi, ui, dui, gri, q[0], q[1], uj, duj, grj, q[2],
                   gpu_dwr(&v->k, r), x, r, &s);
    }
    double L[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    for (int e = 0; e < D * D; ++e) L[e] = gv(v, GA_BONET, e)[i];
    double au[3], gradp[3], ax[3], gradu[9], divu, aq;
    delta_rates_i(D, &s, rhoi, ui, dui, L, v->dvisc, v->Dq, au, gradp, ax, gradu, &divu, &aq);
    for (int a = 0; a < D; ++a) {
        gv(v, GA_AU, a)[i] = au[a];
        gv(v, GA_GRADP, a)[i] = gradp[a];
        gv(v, GA_AX, a)[i] = ax[a];
    }
    for (int e = 0; e < D * D; ++e) gv(v, GA_GRADU, e)[i] = gradu[e];
    gv(v, GA_DIVU, 0)[i] = divu;
    gv(v, GA_AQ, 0)[i] = aq;
}

GPU_FN void dev_delta_rates(const gpu_view *v, size_t i)
{
#define DELTA_RATES_D(D)                                                                           \
    do {                                                                                           \
        if (v->dshift == DELTA_SHIFT_SUN)                                                          \
            dev_delta_rates_d(v, i, D, DELTA_SHIFT_SUN);                                           \
        else if (v->dshift == DELTA_SHIFT_APP_D)                                                   \
            dev_delta_rates_d(v, i, D, DELTA_SHIFT_APP_D);                                         \
        else                                                                                       \
            dev_delta_rates_d(v, i, D, DELTA_SHIFT_NONE);                                          \
    } while (0)
    if (v->d == 2)
        DELTA_RATES_D(2);
    else
        DELTA_RATES_D(3);
#undef DELTA_RATES_D
}

#endif
