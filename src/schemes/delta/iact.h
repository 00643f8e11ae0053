/* The pair interactions of the δ-SPH family (scheme.c), a pure function of the two particles'
 * values and the pair geometry, and the per-particle rates from their sums: plain C over
 * scalars and small arrays, no library type. With x_ij = x_i - x_j, ∇W_ij = dwr x_ij,
 * u_ji = u_j - u_i, V_j = m_j/ρ_j. The order of every sum is part of the results (every run is
 * reproduced bit for bit): keep it. */
#ifndef CONSPH_SCHEMES_DELTA_IACT_H
#define CONSPH_SCHEMES_DELTA_IACT_H

/* How δ+-SPH adds the shifting terms ∇f·δu (001 eq. D.1) to the rates of f = ρ and f = u. */
enum {
    DELTA_SHIFT_NONE, /* δ-SPH: no shifting */
    DELTA_SHIFT_SUN,  /* Sun et al. 2019: ∇·(f δu) - f ∇·δu as a sum and a difference */
    DELTA_SHIFT_APP_D /* 001 eq. D.5: δu_i·Σ (f_j - f_i) ∇W_ij V_j */
};

/* What neighbour j adds to particle i's sums; per component where the sum runs over
 * components (its terms are added one component at a time). */
typedef struct delta_pair {
    double div[3];  /* V_j u_ji,a ∂_a W_ij: ∇·u */
    double gp[3];   /* V_j (p_i + p_j) ∇W_ij (sym1) */
    double visc[3]; /* V_j (u_ji·x_ij/r²) ∇W_ij, subtracted: Σ π_ij ∇W_ij V_j */
    double G[9];    /* V_j u_ji ⊗ ∇W_ij */
    double diff;    /* V_j ψ_ij·∇W_ij (Marrone eq. 5a) */
    double shq;     /* the shifting term of dρ/dt */
    double shu[3];  /* the shifting terms of du/dt */
} delta_pair;

/* One pair (r > 0). gri, grj: ⟨∇ρ⟩^L at i and j; dui, duj: δu (read for the shifting forms
 * only). */
static inline void delta_pair_terms(int d, int shift, double Vj, double dwr, const double x[3],
                                    double r, double rhoi, double rhoj, double pi, double pj,
                                    const double ui[3], const double uj[3], const double gri[3],
                                    const double grj[3], const double dui[3], const double duj[3],
                                    delta_pair *o)
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
        o->div[a] = Vj * uji[a] * gw[a];
        o->gp[a] = Vj * (pi + pj) * gw[a];
        /* π_ij = u_ji·x_ji/r² = -u_ji·x_ij/r² */
        o->visc[a] = Vj * ux / r2 * gw[a];
        for (int b = 0; b < d; ++b) o->G[a * d + b] = Vj * uji[a] * gw[b];
    }
    o->diff = Vj * psig;
    o->shq = 0.0;
    for (int a = 0; a < d; ++a) o->shu[a] = 0.0;
    if (shift == DELTA_SHIFT_SUN) {
        /* Σ V_j [(f_j δu_j + f_i δu_i) - f_i (δu_j - δu_i)]·∇W_ij
         *   = Σ V_j [(f_j - f_i) δu_j·∇W_ij + 2 f_i δu_i·∇W_ij] */
        double sj = 0.0, si = 0.0;
        for (int a = 0; a < d; ++a) {
            sj += duj[a] * gw[a];
            si += dui[a] * gw[a];
        }
        o->shq = Vj * (drho * sj + 2.0 * rhoi * si);
        for (int a = 0; a < d; ++a) o->shu[a] = Vj * (uji[a] * sj + 2.0 * ui[a] * si);
    } else if (shift == DELTA_SHIFT_APP_D) {
        /* 001 eq. D.5: Σ V_j (f_j - f_i) δu_i·∇W_ij */
        double si = 0.0;
        for (int a = 0; a < d; ++a) si += dui[a] * gw[a];
        o->shq = Vj * drho * si;
        for (int a = 0; a < d; ++a) o->shu[a] = Vj * uji[a] * si;
    }
}

#endif
