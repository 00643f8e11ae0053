/* The pair interactions of the PySPH family (wcsph, tvf, edac; scheme.c), each a pure function
 * of the two particles' values and the pair geometry: plain C over scalars and small arrays,
 * no library type, so that the same file compiles for any target. With x_ij = x_i - x_j,
 * ∇W_ij = dwr x_ij and u_ij = u_i - u_j. The order of every sum is part of the results (every
 * run is reproduced bit for bit): keep it. */
#ifndef CONSPH_SCHEMES_PYSPH_IACT_H
#define CONSPH_SCHEMES_PYSPH_IACT_H

#include "gpu/hd.h" /* CONSPH_HD: these terms compile for the GPU too (src/gpu/) */

#if defined(__GNUC__)
#define PYSPH_IACT CONSPH_HD static inline __attribute__((always_inline))
#else
#define PYSPH_IACT CONSPH_HD static inline
#endif

/* The constants of a right-hand side. */
typedef struct pysph_consts {
    double m, minv; /* particle mass and its inverse */
    double h, h2;   /* smoothing length; PySPH's ε = 0.01 h² in every 1/(r² + ε) */
    double nu;      /* kinematic viscosity */
    double alpha;   /* wcsph: Monaghan's α (0: no artificial viscosity) */
    double pb;      /* tvf, edac: background pressure */
    double c0;      /* edac: speed of sound */
    double nu_edac; /* edac: the pressure diffusion ν_edac */
} pysph_consts;

/* What one neighbour j adds to particle i (not summed for j = i, where ∇W_ii = 0). */
typedef struct pysph_pair {
    double f[3];   /* force per unit mass times m (tvf, edac) or acceleration (wcsph) */
    double fp[3];  /* its pressure part (the solver's ∇p diagnostics) */
    double fb[3];  /* tvf, edac: the background-pressure force; wcsph: XSPH's ε ū_ij W term */
    double g[9];   /* m/ϱ_j u_ij ⊗ ∇W_ij, subtracted into ∇u */
    double div;    /* m/ϱ_j u_ij·∇W_ij (tvf, edac), m u_ij·∇W_ij (wcsph: dϱ/dt) */
    double q1, q2; /* edac: dp/dt's continuity-like and diffusion terms */
} pysph_pair;

/* Adami, Hu & Adams 2013 (tvf) and Ramachandran & Puri 2019 (edac): one pair. V = 1/Σ W,
 * du = ũ - u the transport velocity's offset, pav p̄_i (edac; 0 for tvf), vj = m/ϱ_j. */
PYSPH_IACT void pysph_tv_pair(int d, int edac, const pysph_consts *c, double rhoi, double pi,
                              double pav, double Vi, const double ui[3], const double dui[3],
                              double rhoj, double pj, double Vj, double vj, const double uj[3],
                              const double duj[3], double dwr, const double xij[3], double r,
                              pysph_pair *o)
{
    const double w2 = Vi * Vi + Vj * Vj;
    double uij[3] = {0.0, 0.0, 0.0}, gw[3] = {0.0, 0.0, 0.0};
    double xdw = 0.0, udw = 0.0;
    for (int a = 0; a < d; ++a) {
        gw[a] = dwr * xij[a];
        uij[a] = ui[a] - uj[a];
        xdw += xij[a] * gw[a];
        udw += uij[a] * gw[a];
    }
    const double r2 = r * r;
    /* two divisions per pair, shared by every term that divides by ϱ_i + ϱ_j or r² + ε (the
     * pair's values move at round-off against dividing in each term) */
    const double inv_s = 1.0 / (rhoi + rhoj), inv_r = 1.0 / (r2 + c->h2);
    /* Adami et al. eq. 7 (p̃_ij), with p - p̄_i in edac (Ramachandran & Puri eq. 25) */
    const double pij = (rhoj * (pi - pav) + rhoi * (pj - pav)) * inv_s;
    const double rr = rhoi * rhoj * inv_s, wx = w2 * xdw * inv_r;
    const double visc = 2.0 * c->nu * rr * wx; /* η_ij = 2 ν ϱ_i ϱ_j/(ϱ_i + ϱ_j) */
    for (int a = 0; a < d; ++a) {
        double A = 0.0; /* ½(A_i + A_j)·∇W, A = ϱ u (ũ - u) */
        for (int b = 0; b < d; ++b)
            A += 0.5 * (rhoi * ui[a] * dui[b] + rhoj * uj[a] * duj[b]) * gw[b];
        o->f[a] = -pij * w2 * gw[a] + visc * uij[a] + w2 * A;
        o->fp[a] = -pij * w2 * gw[a] * c->minv;
        o->fb[a] = -c->pb * w2 * gw[a];
    }
    for (int a = 0; a < d; ++a)
        for (int b = 0; b < d; ++b) o->g[a * d + b] = vj * uij[a] * gw[b];
    o->div = vj * udw;
    o->q1 = 0.0;
    o->q2 = 0.0;
    if (edac) {
        /* Ramachandran & Puri eq. 22: the continuity-like term and EDAC diffusion */
        o->q1 = rhoi * vj * c->c0 * c->c0 * udw; /* ϱ_i/ϱ_j c² m u_ij·∇W */
        o->q2 = 2.0 * c->nu_edac * rr * wx * (pi - pj) * c->minv;
    }
}

/* Monaghan 1992 eq. 4.2 (β = 0): the artificial viscosity Π_ij, on approach only (ux = u_ij·x_ij
 * < 0); ci, cj the Tait sound speeds. Computed for every pair and selected, since the sign of
 * u_ij·x_ij is a coin toss to the branch predictor. */
PYSPH_IACT double pysph_monaghan_pi(const pysph_consts *c, double ci, double cj, double ux,
                                    double inv_r, double inv_s)
{
    /* inv_r = 1/(r² + ε), inv_s = 1/(ϱ_i + ϱ_j) = 1/(2 ϱ̄_ij) */
    const double mu = c->h * ux * inv_r;
    const double v = -c->alpha * (ci + cj) * mu * inv_s;
    return ux < 0.0 ? v : 0.0;
}

/* Monaghan's WCSPH: one pair of the symmetric pressure force with Monaghan's Π_ij (pij, 0 when
 * α = 0), Morris/Cleary's laminar viscosity, XSPH (ε = 0.5) and the continuity equation.
 * w = W_ij; ti = p_i/ϱ_i², tij = p_j/ϱ_j², vj = m/ϱ_j; inv_s = 1/(ϱ_i + ϱ_j) and
 * inv_r = 1/(r² + ε), shared with Π_ij (two divisions per pair). */
PYSPH_IACT void pysph_wcsph_pair(int d, const pysph_consts *c, double ti, const double ui[3],
                                 double tij, double vj, const double uj[3], double pij, double w,
                                 double dwr, const double xij[3], double inv_s, double inv_r,
                                 pysph_pair *o)
{
    const double m = c->m;
    double uij[3] = {0.0, 0.0, 0.0}, gw[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) {
        uij[a] = ui[a] - uj[a];
        gw[a] = dwr * xij[a];
    }
    double udw = 0.0, xdw = 0.0;
    for (int a = 0; a < d; ++a) {
        udw += uij[a] * gw[a];
        xdw += xij[a] * gw[a];
    }
    /* Morris et al. 1997 / Cleary's laminar viscosity */
    const double visc = m * 4.0 * c->nu * xdw * inv_s * inv_r;
    for (int a = 0; a < d; ++a) {
        o->f[a] = -m * (ti + tij + pij) * gw[a] + visc * uij[a];
        o->fp[a] = -m * (ti + tij) * gw[a];
        o->fb[a] = m * w * inv_s * uij[a]; /* XSPH, ε = 0.5: ε m W/ϱ̄_ij */
    }
    o->div = m * udw;
    for (int a = 0; a < d; ++a)
        for (int b = 0; b < d; ++b) o->g[a * d + b] = vj * uij[a] * gw[b];
}

#endif
