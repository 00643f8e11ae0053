/* The pair interactions of the δ-SPH family (delta-sph, delta-plus-sph, delta-plus-sph-d;
 * scheme.c), pure functions of the two particles' values and the pair geometry: plain C over
 * scalars and small arrays, no library type, so that the same file compiles for any target.
 * With x_ij = x_i - x_j, ∇W_ij = dwr x_ij and u_ji = u_j - u_i (the equations are in scheme.c's
 * header and docs/schemes.md). The order of every sum is part of the results (every run is
 * reproduced bit for bit): keep it.
 *
 * The sums live in a delta_sums that the caller keeps on its stack and passes by a restrict
 * pointer, so that after inlining every accumulator is a register: with d a compile-time 2 (the
 * caller's clone) the indices of G are constants too and nothing of the sums goes to memory. */
#ifndef CONSPH_SCHEMES_DELTA_IACT_H
#define CONSPH_SCHEMES_DELTA_IACT_H

#include "gpu/hd.h" /* CONSPH_HD: these terms compile for the GPU too (src/gpu/dev_delta.h) */

#if defined(__GNUC__)
#define DELTA_IACT CONSPH_HD static inline __attribute__((always_inline))
#else
#define DELTA_IACT CONSPH_HD static inline
#endif

/* C++ (nvcc) spells C's restrict __restrict__. */
#if defined(__cplusplus)
#define DELTA_RESTRICT __restrict__
#else
#define DELTA_RESTRICT restrict
#endif

/* The shifting terms of the rates (scheme.c): none (δ-SPH), Sun et al. 2019's sum and
 * difference forms (δ+-SPH), 001 eq. D.5 (δ+-SPH-D). */
enum { DELTA_SHIFT_NONE, DELTA_SHIFT_SUN, DELTA_SHIFT_APP_D };

/* The neighbour sums of particle i's rates. */
typedef struct delta_sums {
    double divu;    /* Σ V_j u_ji·∇W_ij */
    double diff;    /* Σ V_j ψ_ij·∇W_ij (Marrone et al. eq. 5a's δ-term) */
    double shq;     /* the shifting term of dρ/dt */
    double gp[3];   /* Σ V_j (p_i + p_j) ∇W_ij (sym1) */
    double visc[3]; /* Σ V_j π_ij ∇W_ij */
    double shu[3];  /* the shifting terms of du/dt */
    double G[9];    /* Σ V_j u_ji ⊗ ∇W_ij, row-major d × d */
} delta_sums;

/* Adds neighbour j (r > 0) to the sums of i. gri, grj: ⟨∇ρ⟩^L of i and j; dui, duj: the
 * shifting velocities δu (read only when shift is not DELTA_SHIFT_NONE). */
DELTA_IACT void delta_pair(const int d, const int shift, const double rhoi, const double pi,
                           const double ui[3], const double dui[3], const double gri[3],
                           const double rhoj, const double pj, const double uj[3],
                           const double duj[3], const double grj[3], const double Vj,
                           const double dwr, const double x[3], const double r,
                           delta_sums *DELTA_RESTRICT s)
{
    const double r2 = r * r;
    double gw[3], uji[3];
    double ux = 0.0, psig = 0.0;
    for (int a = 0; a < d; ++a) {
        gw[a] = dwr * x[a];
        uji[a] = uj[a] - ui[a];
        ux += uji[a] * x[a];
    }
    const double drho = rhoj - rhoi;
    for (int a = 0; a < d; ++a) {
        /* ψ_ij with x_ji = -x_ij */
        const double psi = -2.0 * drho * x[a] / r2 - (gri[a] + grj[a]);
        psig += psi * gw[a];
        s->divu += Vj * uji[a] * gw[a];
        s->gp[a] += Vj * (pi + pj) * gw[a];
        /* π_ij = u_ji·x_ji/r² = -u_ji·x_ij/r² */
        s->visc[a] -= Vj * ux / r2 * gw[a];
        for (int b = 0; b < d; ++b) s->G[a * d + b] += Vj * uji[a] * gw[b];
    }
    s->diff += Vj * psig;
    if (shift == DELTA_SHIFT_SUN) {
        /* Σ V_j [(f_j δu_j + f_i δu_i) - f_i (δu_j - δu_i)]·∇W_ij
         *   = Σ V_j [(f_j - f_i) δu_j·∇W_ij + 2 f_i δu_i·∇W_ij] */
        double sj = 0.0, si = 0.0;
        for (int a = 0; a < d; ++a) {
            sj += duj[a] * gw[a];
            si += dui[a] * gw[a];
        }
        s->shq += Vj * (drho * sj + 2.0 * rhoi * si);
        for (int a = 0; a < d; ++a) s->shu[a] += Vj * (uji[a] * sj + 2.0 * ui[a] * si);
    } else if (shift == DELTA_SHIFT_APP_D) {
        /* 001 eq. D.5: Σ V_j (f_j - f_i) δu_i·∇W_ij */
        double si = 0.0;
        for (int a = 0; a < d; ++a) si += dui[a] * gw[a];
        s->shq += Vj * drho * si;
        for (int a = 0; a < d; ++a) s->shu[a] += Vj * uji[a] * si;
    }
}

/* Particle i's rates from its sums (scheme.c's rate pass, the GPU's dev_delta.h): du/dt
 * (sym1's pressure, the viscosity, the shifting terms), ∇p's sum, dx/dt = u + δu, ∇u = G L_i^T
 * (the renormalised gradient, for the vorticity of the output), ∇·u and dρ/dt (the δ-term and the
 * shifting term). L: L_i, d × d row-major; visc = (α h c_o + 2(d + 2) ν) ρ_o, h_c0_delta = δ h
 * c_o. */
DELTA_IACT void delta_rates_i(const int d, const delta_sums *DELTA_RESTRICT s, const double rhoi,
                              const double ui[3], const double dui[3], const double L[9],
                              const double visc, const double h_c0_delta, double au[3],
                              double gradp[3], double ax[3], double gradu[9], double *divu,
                              double *aq)
{
    for (int a = 0; a < d; ++a) {
        au[a] = -s->gp[a] / rhoi + visc / rhoi * s->visc[a] + s->shu[a];
        gradp[a] = s->gp[a];
        ax[a] = ui[a] + dui[a];
        /* ∂_b u_a renormalised with L_i, for the vorticity of the output */
        for (int b = 0; b < d; ++b) {
            double v = 0.0;
            for (int c = 0; c < d; ++c) v += L[b * d + c] * s->G[a * d + c];
            gradu[a * d + b] = v;
        }
    }
    *divu = s->divu;
    *aq = -rhoi * s->divu + h_c0_delta * s->diff + s->shq;
}

#endif
