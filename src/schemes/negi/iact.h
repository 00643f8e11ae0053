/* 001's schemes (§5.1, §5.4) as terms: which terms a scheme's rates are made of, and the
 * per-particle combination of the derivatives the kit (kit.c) leaves at a particle into its
 * rates. The pair sums behind those derivatives are the shared operator terms of
 * src/ops/terms.h (∇p asym_bc, ∇u f4, ∇·u div_bc: 001 Table 2, eq. 11; the Laplacians of
 * 001 Table 6), fused by kit.c. Plain C over scalars and small arrays, no library type. */
#ifndef CONSPH_SCHEMES_NEGI_IACT_H
#define CONSPH_SCHEMES_NEGI_IACT_H

#include "gpu/hd.h" /* CONSPH_HD: the rates compile for the GPU too (src/gpu/dev.h) */

/* The terms of one scheme's rates (a const one per scheme in scheme.c):
 *   du/dt = -∇p/ϱ (ϱ_c: frozen_rho) + ν∇²u  [- (u·∇)u  advect_u]  [+ (δu·∇)u  transport]
 *   dq/dt = -ϱ∇·u (q = ϱ) or -ρ_o c_o² ∇·u (q = p: eq. 30 as 001's authors run it)
 *           [+ D∇²q  diffuse_q]  [- u·∇q  advect_q]  [+ δu·∇q  transport]
 *   dx/dt = u + δu  (δu = 0 without transport; no drift when the scheme does not move) */
typedef struct negi_terms {
    int lap;       /* the viscous Laplacian ∇²u, a kit_lap: coupled_bc, Fatehi_c (eq. 13),
                      Korzilius (eqs. 14-15) or Cleary's (EWCSPH) */
    int advect_u;  /* Eulerian: -(u·∇)u (eq. 36) */
    int advect_q;  /* Eulerian: -u·∇ϱ (E-C keeps it; EWCSPH drops it, Nasar et al.) */
    int diffuse_q; /* the δ-term D∇²q, D = δ h c_o (eq. 27) */
    int transport; /* TV-C's shifting velocity δu (eqs. 34-35) */
    int frozen_rho; /* -∇p/ϱ_c with ϱ_c = ρ_o + p(t=0)/c_o² kept from the start (EWCSPH as 001's
                       authors run it: docs/schemes.md, "EWCSPH"); else -∇p/ϱ */
} negi_terms;

/* The derivatives at particle i (d components each, G[a d + b] = ∂_b u_a). gradq is read only
 * when advect_q or transport, lapq only when diffuse_q. */
typedef struct negi_derivs {
    double u[3], du[3]; /* velocity and shifting velocity (0 without transport) */
    double rhof, gradp[3], G[9], lapu[3], divu, gradq[3], lapq;
    double rhom; /* the density dividing ∇p: ϱ, or ϱ_c with frozen_rho */
} negi_derivs;

/* The rates at particle i: du/dt into au, dx/dt into ax, dq/dt into *aq. nu the viscosity, D
 * the δ-term's coefficient, c2 = c_o², rho0 = ρ_o, evolve_p: q is p. With q = p the factor of
 * ∇·u is ρ_o c_o², as 001's authors' EDACEquation (tsph_with_pst.py) where eq. 30 prints
 * ϱ c_o² (docs/schemes.md, "PE-IPST-C"). The order of the sums is part of the
 * results (every run is reproduced bit for bit): keep it. */
CONSPH_HD static inline void negi_rates_i(const negi_terms *t, int d, double nu, double D,
                                          double c2, double rho0, int evolve_p,
                                          const negi_derivs *v, double au[3], double ax[3],
                                          double *aq)
{
    for (int a = 0; a < d; ++a) {
        double r = -v->gradp[a] / v->rhom + nu * v->lapu[a];
        for (int b = 0; b < d; ++b) {
            const double g = v->G[a * d + b];
            if (t->advect_u) r -= v->u[b] * g;
            if (t->transport) r += v->du[b] * g;
        }
        au[a] = r;
        ax[a] = v->u[a] + v->du[a];
    }
    double r = evolve_p ? -rho0 * c2 * v->divu : -v->rhof * v->divu;
    if (t->diffuse_q) r += D * v->lapq;
    if (t->advect_q || t->transport)
        for (int a = 0; a < d; ++a) {
            const double gq = v->gradq[a];
            if (t->advect_q) r -= v->u[a] * gq;
            if (t->transport) r += v->du[a] * gq;
        }
    *aq = r;
}

#endif
