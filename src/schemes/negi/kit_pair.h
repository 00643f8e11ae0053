/* The arithmetic of the kit's fused derivative passes (kit.c) per pair and per particle, written
 * once for the CPU's passes and the GPU's (CONSPH_HD, src/gpu/hd.h; src/gpu/dev.h walks the
 * neighbours in the CPU's order and calls these): pass 1's sums (the Bonet moment and the raw
 * gradient sums Σ ω_j (f_j - f_i) ∇W_ij of p, u and q, with term_moments' and term_grad_sums'
 * arithmetic, src/ops/terms.h) and their finish (B_i = the moment's inverse or the identity, as
 * consph_bonet_finalise; B_i applied by term_apply_rule; ∇·u the trace of G), coupled_bc's
 * pair (Σ ω_j (G_j - G_i)·B_i∇W_ij, term_corrected_div's arithmetic) and Cleary's. D and the with_*
 * flags are constants at every call, so the sums stay in registers. The order of every operation is
 * part of the results: keep it. */
#ifndef CONSPH_SCHEMES_NEGI_KIT_PAIR_H
#define CONSPH_SCHEMES_NEGI_KIT_PAIR_H

#include "ops/small.h"

#define KIT_PAIR OPS_SMALL

/* One neighbour j of pass 1: om = ω_j, w1 = W'(r)/r, x = x_ij, the values at j and at i. */
KIT_PAIR void kit_first_pair(const int D, const int with_p, const int with_u, const int with_q,
                             double om, double w1, const double x[3], double pj, double pi,
                             const double uj[3], const double ui[3], double qj, double qi,
                             double sm[9], double sp[3], double su[9], double sq[3])
{
    const double g = om * w1;
    for (int a = 0; a < D; ++a)
        for (int b = 0; b < D; ++b) sm[a * D + b] -= g * x[a] * x[b];
    if (with_p) {
        const double t = om * (pj - pi) * w1;
        for (int b = 0; b < D; ++b) sp[b] += t * x[b];
    }
    if (with_u)
        for (int a = 0; a < D; ++a) {
            const double t = om * (uj[a] - ui[a]) * w1;
            for (int b = 0; b < D; ++b) su[a * D + b] += t * x[b];
        }
    if (with_q) {
        const double t = om * (qj - qi) * w1;
        for (int b = 0; b < D; ++b) sq[b] += t * x[b];
    }
}

/* kit_first_finish's derivatives from B_i given: ∇p = B sp, G = B su per row, ∇·u = tr G, ∇q =
 * B sq (a fixed geometry's pass 1 keeps B_i from its first evaluation: kit_req.bonet_kept). */
KIT_PAIR void kit_first_apply(const int D, const int with_p, const int with_u, const int with_q,
                              const double B[9], const double sp[3], const double su[9],
                              const double sq[3], double gradp[3], double G[9], double *divu,
                              double gradq[3])
{
    const double zero[3] = {0.0, 0.0, 0.0};
    if (with_p) term_apply_rule(D, zero, B, sp, 0.0, gradp);
    if (with_u) {
        double div = 0.0;
        for (int a = 0; a < D; ++a) {
            term_apply_rule(D, zero, B, su + a * D, 0.0, G + a * D);
            div += G[a * D + a];
        }
        *divu = div;
    }
    if (with_q) term_apply_rule(D, zero, B, sq, 0.0, gradq);
}

/* Pass 1's finish at a particle: B (the inverted moment, or the identity when singular or worse
 * conditioned than cond_max: the return value 0), then the derivatives asked
 * for (kit_first_apply). */
KIT_PAIR int kit_first_finish(const int D, const int with_p, const int with_u, const int with_q,
                              const double mom[9], double cond_max, const double sp[3],
                              const double su[9], const double sq[3], double B[9], double gradp[3],
                              double G[9], double *divu, double gradq[3])
{
    double cond = 0.0;
    const int ok = ops_invert_n(D, mom, B, cond_max, &cond);
    if (!ok)
        for (int r = 0; r < D; ++r)
            for (int c = 0; c < D; ++c) B[r * D + c] = r == c ? 1.0 : 0.0;
    kit_first_apply(D, with_p, with_u, with_q, B, sp, su, sq, gradp, G, divu, gradq);
    return ok;
}

/* One neighbour j of coupled_bc: B = B_i, w1 = W'(r)/r, x = x_ij, om = ω_j, G and ∇q at j and
 * at i; adds ω_j (G_j - G_i)·B_i∇W_ij per component of u into acc and that of q into *accq. */
KIT_PAIR void kit_coupled_pair(const int D, const int with_u, const int with_q, const double B[9],
                               double w1, const double x[3], double om, const double Gj[9],
                               const double Gi[9], const double gqj[3], const double gqi[3],
                               double acc[3], double *accq)
{
    double gr[3], g[3];
    for (int b = 0; b < D; ++b) gr[b] = w1 * x[b];
    for (int a = 0; a < D; ++a) {
        double v = 0.0;
        for (int b = 0; b < D; ++b) v += B[a * D + b] * gr[b];
        g[a] = v;
    }
    if (with_u)
        for (int a = 0; a < D; ++a) {
            double sa = 0.0;
            for (int b = 0; b < D; ++b) sa += (Gj[a * D + b] - Gi[a * D + b]) * g[b];
            acc[a] += om * sa;
        }
    if (with_q) {
        double s = 0.0;
        for (int b = 0; b < D; ++b) s += (gqj[b] - gqi[b]) * g[b];
        *accq += om * s;
    }
}

/* One neighbour j of Cleary's Laplacian (kit.c's cleary_body) at r_ij > 1e-14 (the caller skips
 * the others): B = B_i, w1 = W'(r)/r, x = x_ij, om = ω_j, ϱ and u at i and j; adds
 * 4 ω_j/(ϱ_i + ϱ_j) W'/r (x·B x)/r² (u_i - u_j) into acc. */
KIT_PAIR void kit_cleary_pair(const int D, const double B[9], double r, double w1,
                              const double x[3], double om, double rhoi, double rhoj,
                              const double ui[3], const double uj[3], double acc[3])
{
    double xBx = 0.0;
    for (int a = 0; a < D; ++a)
        for (int b = 0; b < D; ++b) xBx += x[a] * B[a * D + b] * x[b];
    const double c = 4.0 * om / (rhoi + rhoj) * w1 * xBx / (r * r);
    for (int a = 0; a < D; ++a) acc[a] += c * (ui[a] - uj[a]);
}

/* One neighbour j of Fatehi_c's Laplacian (kit.c's fatehi_body) at r_ij > 0 (the caller skips
 * the others): Bh = B̂_i, w1 = W'(r)/r, x = x_ij, om = ω_j, G = ∇u_i, u at i and j; adds
 * 2 ω_j W'/r ((u_i - u_j) - x·G) (x·B̂ x)/r² per component into acc. */
KIT_PAIR void kit_fatehi_pair(const int D, const double Bh[9], double r, double w1,
                              const double x[3], double om, const double G[9], const double ui[3],
                              const double uj[3], double acc[3])
{
    double xBx = 0.0;
    for (int a = 0; a < D; ++a)
        for (int b = 0; b < D; ++b) xBx += x[a] * Bh[a * D + b] * x[b];
    const double c = 2.0 * om * w1;
    for (int a = 0; a < D; ++a) {
        double xG = 0.0;
        for (int b = 0; b < D; ++b) xG += x[b] * G[a * D + b];
        acc[a] += c * ((ui[a] - uj[a]) - xG) * xBx / (r * r);
    }
}

/* One neighbour j of Korzilius' Laplacian (kit.c's korzilius_body; P = d(d+1)/2 pairs (pl, pk)
 * with Taylor coefficients cq): om = ω_j, dwr = W'/r, aee the Hessian's radial part, x = x_ij,
 * G = ∇u_i, u at i and j; adds to the sums of term_second_moment (A, Hx, Gz) and
 * term_hessian_rhs (rhs, per component of u). */
KIT_PAIR void kit_korzilius_pair(const int D, const int P, const int pl[6], const int pk[6],
                                 const double cq[6], double om, double dwr, double aee,
                                 const double x[3], const double G[9], const double ui[3],
                                 const double uj[3], double A[36], double Hx[18], double Gz[18],
                                 double rhs[18])
{
    double zeta[6], H[6];
    for (int q = 0; q < P; ++q) {
        zeta[q] = cq[q] * x[pl[q]] * x[pk[q]];
        H[q] = aee * x[pl[q]] * x[pk[q]] + (pl[q] == pk[q] ? dwr : 0.0);
    }
    for (int a = 0; a < P; ++a)
        for (int b = 0; b < P; ++b) A[a * P + b] += om * H[a] * zeta[b];
    for (int a = 0; a < P; ++a)
        for (int b = 0; b < D; ++b) Hx[a * D + b] -= om * H[a] * x[b];
    for (int a = 0; a < D; ++a)
        for (int b = 0; b < P; ++b) Gz[a * P + b] += om * dwr * x[a] * zeta[b];
    for (int a = 0; a < D; ++a) {
        double xG = 0.0;
        for (int b = 0; b < D; ++b) xG += x[b] * G[a * D + b];
        /* x_ji·G = -x_ij·G */
        const double sa = om * ((uj[a] - ui[a]) + xG);
        for (int q = 0; q < P; ++q) rhs[a * P + q] += sa * H[q];
    }
}

/* Korzilius' finish: Γ̃ = A - Hx B Gz inverted (001 eq. 15), the identity where B_i fell back (ok
 * 0) or Γ̃ is singular or worse conditioned than cond_max; ∇²u's components the diagonal rows of
 * Γ̃^{-1} applied to rhs. A is overwritten. */
KIT_PAIR void kit_korzilius_finish(const int D, const int P, const int pl[6], const int pk[6],
                                   int ok, const double Hx[18], const double Gz[18],
                                   const double B[9], double A[36], const double rhs[18],
                                   double cond_max, double lapu[3])
{
    double Ainv[36], cond = 0.0;
    if (ok) {
        term_korzilius_correct(D, P, Hx, Gz, B, A);
        ok = ops_invert_n(P, A, Ainv, cond_max, &cond);
    }
    if (!ok)
        for (int r = 0; r < P; ++r)
            for (int c = 0; c < P; ++c) Ainv[r * P + c] = r == c ? 1.0 : 0.0;
    for (int a = 0; a < D; ++a) {
        double lap = 0.0;
        for (int r = 0; r < P; ++r)
            if (pl[r] == pk[r])
                for (int c = 0; c < P; ++c) lap += Ainv[r * P + c] * rhs[a * P + c];
        lapu[a] = lap;
    }
}

#endif
