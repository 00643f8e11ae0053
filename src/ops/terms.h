/* The pair sums of every operator, each written once as a static inline function of one
 * neighbourhood (include/consph/pass.h), so that consph_apply and a scheme's fused pass run the
 * same arithmetic: a fused pass calls several of these in one visit, over the pair geometry and
 * kernel values the traversal evaluated once, and gets the numbers consph_apply gets.
 *
 * A term only sums: it reads the neighbourhood and per-particle arrays (ω, m, ρ, the input) and
 * returns its sums; the caller applies the per-particle correction and stores the result. The
 * order of every floating-point operation is part of a term's contract: the studies' numbers are
 * compared bit for bit across changes, so a term must not be "simplified" (reassociated) without
 * checking them.
 *
 * Conventions (001 App. C, 002 eq. 15): x_ij = x_i - x_j = nb->dx, x_ji = -x_ij, ∇W_ij = dwr x_ij.
 * Arrays of d-vectors are component-major with stride N (component a of j is u[a * N + j]). */
#ifndef CONSPH_OPS_TERMS_H
#define CONSPH_OPS_TERMS_H

#include <stddef.h>
#include <string.h>

#include "consph/ops.h"
#include "consph/pass.h"
#include "ops/small.h" /* term_apply_rule, fatehi_c's pair and finish */

/* For terms instantiated with a compile-time dimension, so their sums stay in registers. */
#if defined(__GNUC__)
#define TERM_INLINE static inline __attribute__((always_inline))
#else
#define TERM_INLINE static inline
#endif

/* ---- the corrected kernel gradient ---- */

/* The corrected-gradient rule shared by every corrected form: g̃_ij = c W_ij + M ∇W_ij, with
 * (c, M) = (0, I) uncorrected, (0, B_i) for Bonet-Lok and the gradient rows of L_i^{-1} for
 * Liu. `mat` holds the per-particle matrices, mat_size doubles apart. */
static inline void term_grad_rule(int d, consph_op_corr corr, const double *mat, size_t mat_size,
                                  size_t i, double c[3], double M[9])
{
    for (int a = 0; a < d; ++a) {
        c[a] = 0.0;
        for (int b = 0; b < d; ++b) M[a * d + b] = a == b ? 1.0 : 0.0;
    }
    if (corr == CONSPH_CORR_BC) {
        memcpy(M, mat + i * mat_size, (size_t)(d * d) * sizeof(double));
    } else if (corr == CONSPH_CORR_LC) {
        const double *L = mat + i * mat_size;
        const int n = d + 1;
        for (int a = 0; a < d; ++a) {
            c[a] = L[(1 + a) * n];
            for (int b = 0; b < d; ++b) M[a * d + b] = L[(1 + a) * n + 1 + b];
        }
    }
}

/* g = c W + M (dwr x) for pair p of nb, x = x_ij. Only the Liu rule has a W term (c != 0), and
 * a pass evaluates W only for visitors that ask for it (CONSPH_PASS_W), so W is read for Liu
 * alone: reading it otherwise would multiply 0 by whatever the scratch held, NaN included. */
static inline void term_corrected_grad(int d, consph_op_corr corr, const double c[3],
                                       const double M[9], const consph_nbhd *nb, size_t p,
                                       const double x[3], double g[3])
{
    const double dwr = nb->dwr[p];
    const double w = corr == CONSPH_CORR_LC ? nb->w[p] : 0.0;
    double gr[3];
    for (int b = 0; b < d; ++b) gr[b] = dwr * x[b];
    for (int a = 0; a < d; ++a) {
        double v = c[a] * w;
        for (int b = 0; b < d; ++b) v += M[a * d + b] * gr[b];
        g[a] = v;
    }
}

/* Loads x = x_ij of pair q and returns (W'' - W'/r)/r² (0 at r = 0), the radial part of the
 * kernel Hessian ∂_l∂_k W = aee x^l x^k + dwr δ_lk. */
static inline double term_pair_hess(int d, const consph_nbhd *nb, size_t q, double x[3])
{
    for (int a = 0; a < d; ++a) x[a] = nb->dx[a][q];
    return term_hess_radial(nb->r[q], nb->dwr[q], nb->d2w[q]);
}

/* ---- function sums ---- */

/* Σ_j a_j b_j W_ij f_j into *sf and Σ_j a_j b_j W_ij into *s0 (either may be NULL; a NULL a or
 * b is 1, a NULL f skips *sf). Standard and Shepard functions (a = ω), consistent Shepard and
 * its power iteration (b = c̃), summation density (a = m) and the number density (a = NULL). */
static inline void term_wsum(const consph_nbhd *nb, const double *a, const double *b,
                             const double *f, double *sf, double *s0)
{
    double s = 0.0, z = 0.0;
    for (size_t p = 0; p < nb->n; ++p) {
        const size_t j = nb->j[p];
        double ww = nb->w[p];
        if (a) ww = b ? a[j] * b[j] * ww : a[j] * ww;
        if (f) s += ww * f[j];
        z += ww;
    }
    if (sf) *sf = s;
    if (s0) *s0 = z;
}

/* FPM (001 eq. A.5) and MSPH (000 §3.3) right-hand sides Σ ω f_j T_ij over the test functions
 * T = [W, ∇W] (+ ∂∂W with msph; pl, pk the pair index of each second-derivative component).
 * rhs must hold zeros on entry. */
static inline void term_taylor_rhs(int d, int msph, int P, const int *pl, const int *pk,
                                   const consph_nbhd *nb, const double *vol, const double *f,
                                   double *rhs)
{
    for (size_t q = 0; q < nb->n; ++q) {
        double x[3];
        for (int a = 0; a < d; ++a) x[a] = nb->dx[a][q];
        double of = vol[nb->j[q]] * f[nb->j[q]], dwr = nb->dwr[q];
        rhs[0] += of * nb->w[q];
        for (int a = 0; a < d; ++a) rhs[1 + a] += of * dwr * x[a];
        if (msph) {
            double r = nb->r[q];
            double aee = r > 0.0 ? (nb->d2w[q] - dwr) / (r * r) : 0.0;
            for (int p = 0; p < P; ++p)
                rhs[1 + d + p] += of * (aee * x[pl[p]] * x[pk[p]] + (pl[p] == pk[p] ? dwr : 0.0));
        }
    }
}

/* ---- gradient sums ---- */

/* The pair weight s_j of term_grad_sums. */
enum {
    TERM_GRAD_DIFF, /* ω_j (f_j - shift): F1-F4, CSPM, asym, sym1, IAD's fallback, inner G */
    TERM_GRAD_SYM2, /* m_j (f_j/ρ_j² + shift) */
    TERM_GRAD_PROD  /* ω_j f_j: the consistent-Shepard sums (f = c̃) */
};

/* Σ_j s_j ∇W_ij into sg[0..2] and Σ_j s_j W_ij into *sw (with_w only: Liu, consistent Shepard),
 * for a dimension known at compile time. Every gradient correction is linear in (W, ∇W), so it is
 * applied to these sums once per particle instead of once per pair. */
TERM_INLINE void term_grad_sums(const int d, const int mode, const int with_w,
                                const consph_nbhd *nb, const double *vol, const double *mass,
                                const double *rho, const double *f, double shift, double *sg,
                                double *sw)
{
    double g0 = 0.0, g1 = 0.0, g2 = 0.0, aw = 0.0;
    const double *dx0 = nb->dx[0], *dx1 = nb->dx[1], *dx2 = nb->dx[2];
    for (size_t p = 0; p < nb->n; ++p) {
        const size_t j = nb->j[p];
        double s = mode == TERM_GRAD_SYM2   ? mass[j] * (f[j] / (rho[j] * rho[j]) + shift)
                   : mode == TERM_GRAD_PROD ? vol[j] * f[j]
                                            : vol[j] * (f[j] - shift);
        double t = s * nb->dwr[p];
        g0 += t * dx0[p];
        if (d > 1) g1 += t * dx1[p];
        if (d > 2) g2 += t * dx2[p];
        if (with_w) aw += s * nb->w[p];
    }
    sg[0] = g0;
    sg[1] = g1;
    sg[2] = g2;
    *sw = aw;
}

/* term_grad_sums for a dimension, mode and with_w known only at run time. */
static inline void term_grad_sums_any(int d, int mode, int with_w, const consph_nbhd *nb,
                                      const double *vol, const double *mass, const double *rho,
                                      const double *f, double shift, double *sg, double *sw)
{
#define TERM_GS(D, M)                                                                              \
    (with_w ? term_grad_sums(D, M, 1, nb, vol, mass, rho, f, shift, sg, sw)                        \
            : term_grad_sums(D, M, 0, nb, vol, mass, rho, f, shift, sg, sw))
#define TERM_GS_D(D)                                                                               \
    do {                                                                                           \
        if (mode == TERM_GRAD_SYM2)                                                                \
            TERM_GS(D, TERM_GRAD_SYM2);                                                            \
        else if (mode == TERM_GRAD_PROD)                                                           \
            TERM_GS(D, TERM_GRAD_PROD);                                                            \
        else                                                                                       \
            TERM_GS(D, TERM_GRAD_DIFF);                                                            \
    } while (0)
    if (d == 1)
        TERM_GS_D(1);
    else if (d == 2)
        TERM_GS_D(2);
    else
        TERM_GS_D(3);
#undef TERM_GS_D
#undef TERM_GS
}

/* F4 (002 eq. 5): G_i = B_i Σ_j ω_j (u_j - u_i) ∇W_ij, B the particle's Bonet matrix (d×d; F2
 * where B fell back to the identity). The inner gradient of S4, Korzilius and CSPM. */
static inline void term_f4_grad(int d, const consph_nbhd *nb, const double *vol, const double *u,
                                const double B[9], double G[3])
{
    const double zero[3] = {0.0, 0.0, 0.0};
    double s[3], sw;
    term_grad_sums_any(d, TERM_GRAD_DIFF, 0, nb, vol, NULL, NULL, u, u[nb->i], s, &sw);
    term_apply_rule(d, zero, B, s, 0.0, G);
}

/* Dilts-symmetrised sym1 (001 eq. 10 with the ½ it lacks as printed): Σ m_j (f_j + f_i)/(ρ_j ρ_i)
 * ½(g̃_ij - L_j∇W_ji), g̃_ij from (c, M), L_j∇W_ji j's Liu rows applied to (W, ∇W_ji = -∇W_ij);
 * added to acc. */
static inline void term_sym_s1(int d, consph_op_corr corr, const double c[3], const double M[9],
                               const consph_nbhd *nb, const double *mass, const double *rho,
                               const double *f, const double *liu, size_t liu_size, double acc[3])
{
    const size_t i = nb->i;
    const double fi = f[i];
    const int n = d + 1;
    for (size_t p = 0; p < nb->n; ++p) {
        size_t j = nb->j[p];
        double x[3], g[3];
        for (int a = 0; a < d; ++a) x[a] = nb->dx[a][p];
        term_corrected_grad(d, corr, c, M, nb, p, x, g);
        const double *Lj = liu + j * liu_size;
        double s = 0.5 * mass[j] * (f[j] + fi) / (rho[j] * rho[i]);
        for (int a = 0; a < d; ++a) {
            double gji = Lj[(1 + a) * n] * nb->w[p];
            for (int b = 0; b < d; ++b) gji -= Lj[(1 + a) * n + 1 + b] * nb->dwr[p] * x[b];
            acc[a] += s * (g[a] - gji);
        }
    }
}

/* IAD (000 eqs. 50-52): Σ -ω (f_j - f_i) x_ij W = Σ ω (f_j - f_i) x_ji W, added to I. */
static inline void term_iad_rhs(int d, const consph_nbhd *nb, const double *vol, const double *f,
                                double fi, double I[3])
{
    for (size_t p = 0; p < nb->n; ++p) {
        double s = -vol[nb->j[p]] * (f[nb->j[p]] - fi) * nb->w[p];
        for (int a = 0; a < d; ++a) I[a] += s * nb->dx[a][p];
    }
}

/* ---- divergence and second derivatives ---- */

/* The corrected divergence Σ_j ω_j (u_j - shift)·g̃_ij of the d-vector u (stride N), g̃ from
 * (c, M), for a dimension known at compile time: the div form (shift = u_i) and the s1 family's
 * outer sum over G (shift 0, G_i, -G_i). */
TERM_INLINE double term_corrected_div(const int d, consph_op_corr corr, const double c[3],
                                      const double M[9], const consph_nbhd *nb, const double *vol,
                                      const double *u, size_t N, const double shift[3])
{
    double acc = 0.0;
    for (size_t p = 0; p < nb->n; ++p) {
        size_t j = nb->j[p];
        double x[3], g[3];
        for (int a = 0; a < d; ++a) x[a] = nb->dx[a][p];
        term_corrected_grad(d, corr, c, M, nb, p, x, g);
        double s = 0.0;
        for (int a = 0; a < d; ++a) s += (u[a * N + j] - shift[a]) * g[a];
        acc += vol[j] * s;
    }
    return acc;
}

/* term_corrected_div for a dimension known only at run time. */
static inline double term_corrected_div_any(int d, consph_op_corr corr, const double c[3],
                                            const double M[9], const consph_nbhd *nb,
                                            const double *vol, const double *u, size_t N,
                                            const double shift[3])
{
    if (d == 1) return term_corrected_div(1, corr, c, M, nb, vol, u, N, shift);
    if (d == 2) return term_corrected_div(2, corr, c, M, nb, vol, u, N, shift);
    return term_corrected_div(3, corr, c, M, nb, vol, u, N, shift);
}

/* Σ_j ω_j (u_j - shift) ∇²W_ij (002 eqs. 10-12). ∇²W = W'' + (d - 1) W'/r; at r = 0 dwr holds
 * W''(0), giving d W''(0). */
static inline double term_s2(int d, const consph_nbhd *nb, const double *vol, const double *u,
                             double shift)
{
    double acc = 0.0;
    for (size_t p = 0; p < nb->n; ++p) {
        size_t j = nb->j[p];
        double lap = nb->d2w[p] + (double)(d - 1) * nb->dwr[p];
        acc += vol[j] * (u[j] - shift) * lap;
    }
    return acc;
}

/* Cleary/Brookshaw (002 eq. 13: weight 2ω_j) and tvf (001 Table 4: weight ω_i² + ω_j², before
 * the division by m_i): Σ_j wgt (u_i - u_j) g̃_ij·x_ij / r², the self pair skipped. */
static inline double term_cleary(int d, int tvf, consph_op_corr corr, const double c[3],
                                 const double M[9], const consph_nbhd *nb, const double *vol,
                                 const double *u)
{
    const size_t i = nb->i;
    const double ui = u[i], oi2 = vol[i] * vol[i];
    double acc = 0.0;
    for (size_t p = 0; p < nb->n; ++p) {
        double r = nb->r[p];
        if (!(r > 0.0)) continue;
        size_t j = nb->j[p];
        double x[3], g[3];
        for (int a = 0; a < d; ++a) x[a] = nb->dx[a][p];
        term_corrected_grad(d, corr, c, M, nb, p, x, g);
        double gx = 0.0;
        for (int a = 0; a < d; ++a) gx += g[a] * x[a];
        double wgt = tvf ? oi2 + vol[j] * vol[j] : 2.0 * vol[j];
        acc += wgt * (ui - u[j]) * gx / (r * r);
    }
    return acc;
}

/* Fatehi (001 eq. C.8), S4 (002 eq. 41) and fatehi_c (001 eq. C.10):
 * Σ_j 2ω_j W'/r ((u_i - u_j) - x_ij·G_i) (x_ij^T B̂ x_ij)/r², the self pair skipped. */
static inline double term_fatehi_lap(int d, const consph_nbhd *nb, const double *vol,
                                     const double *u, const double G[3], const double Bh[9])
{
    const double ui = u[nb->i];
    double acc = 0.0;
    for (size_t p = 0; p < nb->n; ++p) {
        double r = nb->r[p];
        if (!(r > 0.0)) continue;
        double x[3], xG = 0.0, xBx = 0.0;
        for (int a = 0; a < d; ++a) {
            x[a] = nb->dx[a][p];
            xG += x[a] * G[a];
        }
        for (int a = 0; a < d; ++a)
            for (int b = 0; b < d; ++b) xBx += x[a] * Bh[a * d + b] * x[b];
        acc += 2.0 * vol[nb->j[p]] * nb->dwr[p] * ((ui - u[nb->j[p]]) - xG) * xBx / (r * r);
    }
    return acc;
}

/* Korzilius (001 eq. 14) and CSPM (000 eqs. 31-32) second-derivative right-hand side
 * Σ ω ((u_j - u_i) - x_ji·G_i) ∂_l∂_k W_ij for the P pairs (pl, pk); rhs zero on entry. */
static inline void term_hessian_rhs(int d, int P, const int *pl, const int *pk,
                                    const consph_nbhd *nb, const double *vol, const double *u,
                                    const double G[3], double *rhs)
{
    const double ui = u[nb->i];
    for (size_t q = 0; q < nb->n; ++q) {
        double r = nb->r[q], x[3], xG = 0.0;
        for (int a = 0; a < d; ++a) {
            x[a] = nb->dx[a][q];
            xG += x[a] * G[a];
        }
        double dwr = nb->dwr[q];
        double aee = r > 0.0 ? (nb->d2w[q] - dwr) / (r * r) : 0.0;
        /* x_ji·G = -x_ij·G */
        double s = vol[nb->j[q]] * ((u[nb->j[q]] - ui) + xG);
        for (int p = 0; p < P; ++p)
            rhs[p] += s * (aee * x[pl[p]] * x[pk[p]] + (pl[p] == pk[p] ? dwr : 0.0));
    }
}

/* ---- moments and correction matrices ---- */

/* The discrete moments (000 eqs. 15-16, 22) for a dimension known at compile time: with_w gives
 * m0 = Σ ω W and m1 = Σ ω x_ji W, with_g0 g0 = Σ ω ∇W; always g1 = Σ ω x_ji ⊗ ∇W
 * (g1[a d + b] = Σ -ω dwr x^a x^b). g1 is the Bonet moment whose inverse is B_i, and
 * [m0, m1; g0, g1] is Liu's L_i. Outputs are written, not added to. */
TERM_INLINE void term_moments(const int d, const int with_w, const int with_g0,
                              const consph_nbhd *nb, const double *vol, double *m0_out,
                              double *m1_out, double *g0_out, double *g1_out)
{
    double m0 = 0.0, m1[3] = {0}, g0[3] = {0}, g1[9] = {0};
    for (size_t p = 0; p < nb->n; ++p) {
        double om = vol[nb->j[p]], g = om * nb->dwr[p];
        double x[3];
        for (int a = 0; a < d; ++a) x[a] = nb->dx[a][p];
        if (with_w) {
            double w = om * nb->w[p];
            m0 += w;
            /* x_j - x_i = -x_ij */
            for (int a = 0; a < d; ++a) m1[a] -= w * x[a];
        }
        for (int a = 0; a < d; ++a) {
            if (with_g0) g0[a] += g * x[a];
            for (int b = 0; b < d; ++b) g1[a * d + b] -= g * x[a] * x[b];
        }
    }
    if (with_w) {
        *m0_out = m0;
        for (int a = 0; a < d; ++a) m1_out[a] = m1[a];
    }
    if (with_g0)
        for (int a = 0; a < d; ++a) g0_out[a] = g0[a];
    for (int e = 0; e < d * d; ++e) g1_out[e] = g1[e];
}

/* The Bonet moment Σ -ω ∇W ⊗ x_ij (= g1 of term_moments), d×d row-major, whose inverse is B_i
 * (consph_bonet_finalise). */
TERM_INLINE void term_bonet_moment(const int d, const consph_nbhd *nb, const double *vol,
                                   double *moment)
{
    term_moments(d, 0, 0, nb, vol, NULL, NULL, NULL, moment);
}

/* term_bonet_moment for a dimension known only at run time. */
static inline void term_bonet_moment_any(int d, const consph_nbhd *nb, const double *vol,
                                         double *moment)
{
    if (d == 1)
        term_bonet_moment(1, nb, vol, moment);
    else if (d == 2)
        term_bonet_moment(2, nb, vol, moment);
    else
        term_bonet_moment(3, nb, vol, moment);
}

/* IAD (000 eq. 51): A = Σ ω x_ij ⊗ x_ij W; A zero on entry. */
static inline void term_iad_moment(int d, const consph_nbhd *nb, const double *vol, double A[9])
{
    for (size_t p = 0; p < nb->n; ++p) {
        double s = vol[nb->j[p]] * nb->w[p];
        for (int a = 0; a < d; ++a)
            for (int b = 0; b < d; ++b) A[a * d + b] += s * nb->dx[a][p] * nb->dx[b][p];
    }
}

/* Fatehi-Manzari (002 eq. 40) moments, the self pair skipped: T4 over the P×P pairs
 * (Σ ω r e e e ∂W), S3 = Σ ω e e ∂W and R3 = Σ ω x x ∂W (d³ each); all zero on entry. */
static inline void term_fatehi_moments(int d, int P, const int *pl, const int *pk,
                                       const consph_nbhd *nb, const double *vol, double *T4,
                                       double S3[27], double R3[27])
{
    for (size_t q = 0; q < nb->n; ++q) {
        double r = nb->r[q];
        if (!(r > 0.0)) continue;
        double x[3];
        for (int a = 0; a < d; ++a) x[a] = nb->dx[a][q];
        double om = vol[nb->j[q]], dwr = nb->dwr[q];
        /* r e e e ∂W = dwr x x x x / r², e e ∂W = dwr x x x / r², x x ∂W = dwr x x x */
        double s4 = om * dwr / (r * r), s3 = s4, r3 = om * dwr;
        for (int a = 0; a < P; ++a) {
            double xab = x[pl[a]] * x[pk[a]];
            for (int b = 0; b < P; ++b) T4[a * P + b] += s4 * xab * x[pl[b]] * x[pk[b]];
        }
        for (int a = 0; a < d; ++a)
            for (int b = 0; b < d; ++b) {
                double xab = x[a] * x[b];
                for (int c = 0; c < d; ++c) {
                    S3[(a * d + b) * d + c] += s3 * xab * x[c];
                    R3[(a * d + b) * d + c] += r3 * xab * x[c];
                }
            }
    }
}

/* fatehi_c (001 eq. 13) moments, the self pair skipped: L1 = Σ ω r² ∂W, L2 = Σ ω x ∂W,
 * L3 = Σ ω e ∂W e; all zero on entry. */
static inline void term_fatehi_c_moments(int d, const consph_nbhd *nb, const double *vol,
                                         double L1[3], double L2[9], double L3[27])
{
    for (size_t q = 0; q < nb->n; ++q) {
        double r = nb->r[q];
        if (!(r > 0.0)) continue;
        double x[3];
        for (int a = 0; a < d; ++a) x[a] = nb->dx[a][q];
        term_fatehi_c_pair(d, r, x, vol[nb->j[q]] * nb->dwr[q], L1, L2, L3);
    }
}

/* fatehi_c's matrix before inversion (001 eq. 13 = C.13): M = -(L2 + L3·(B L1)), the moments of
 * term_fatehi_c_moments and the Bonet matrix B; B̂ = M^{-1}. */
static inline void term_fatehi_c_matrix(int d, const consph_nbhd *nb, const double *vol,
                                        const double B[9], double M[9])
{
    double L1[3] = {0}, L2[9] = {0}, L3[27] = {0};
    term_fatehi_c_moments(d, nb, vol, L1, L2, L3);
    term_fatehi_c_finish(d, B, L1, L2, L3, M);
}

/* The CSPM second-derivative matrix (000 eq. 32) A = Σ ω ∂∂W ζ^T, ζ_q = cq_q x^l x^k, and with
 * korz Korzilius' Hx = Σ ω ∂∂W x_ji^T and Gz = Σ ω ∇W ζ^T (001 eq. 15); all zero on entry. */
static inline void term_second_moment(int d, int P, const int *pl, const int *pk, const double *cq,
                                      int korz, const consph_nbhd *nb, const double *vol, double *A,
                                      double *Hx, double *Gz)
{
    for (size_t q = 0; q < nb->n; ++q) {
        const double om = vol[nb->j[q]], dwr = nb->dwr[q];
        double x[3];
        const double aee = term_pair_hess(d, nb, q, x);
        double zeta[6], H[6];
        for (int p = 0; p < P; ++p) {
            zeta[p] = cq[p] * x[pl[p]] * x[pk[p]];
            H[p] = aee * x[pl[p]] * x[pk[p]] + (pl[p] == pk[p] ? dwr : 0.0);
        }
        for (int a = 0; a < P; ++a)
            for (int b = 0; b < P; ++b) A[a * P + b] += om * H[a] * zeta[b];
        if (korz) {
            for (int a = 0; a < P; ++a)
                for (int b = 0; b < d; ++b) Hx[a * d + b] -= om * H[a] * x[b];
            for (int a = 0; a < d; ++a)
                for (int b = 0; b < P; ++b) Gz[a * P + b] += om * dwr * x[a] * zeta[b];
        }
    }
}

/* MSPH (000 §3.3): A = Σ T C^T with test functions T = ω [W, ∂W, ∂∂W] and columns
 * C = [1, x_ji, cq x_ji^l x_ji^k]; n = 1 + d + P, A zero on entry. */
static inline void term_msph_moment(int d, int P, const int *pl, const int *pk, const double *cq,
                                    const consph_nbhd *nb, const double *vol, double *A)
{
    const int n = 1 + d + P;
    for (size_t q = 0; q < nb->n; ++q) {
        const double om = vol[nb->j[q]], dwr = nb->dwr[q];
        double x[3];
        const double aee = term_pair_hess(d, nb, q, x);
        double T[10], C[10];
        T[0] = om * nb->w[q];
        C[0] = 1.0;
        for (int a = 0; a < d; ++a) {
            T[1 + a] = om * dwr * x[a];
            C[1 + a] = -x[a];
        }
        for (int p = 0; p < P; ++p) {
            double xx = x[pl[p]] * x[pk[p]];
            T[1 + d + p] = om * (aee * xx + (pl[p] == pk[p] ? dwr : 0.0));
            C[1 + d + p] = cq[p] * xx;
        }
        for (int a = 0; a < n; ++a)
            for (int b = 0; b < n; ++b) A[a * n + b] += T[a] * C[b];
    }
}

/* ---- consistent Shepard and the 1D boundary integrals ---- */

/* The consistent-Shepard gradient sum (000 eq. 67 as ops_cshepard.c reads it):
 * Σ_j ω_j c̃_j (A_j - A_i)(∇W_ij - W_ij q), q = ∇S_i / S_i; added to g. */
static inline void term_cshepard_grad(int d, const consph_nbhd *nb, const double *vol,
                                      const double *c, const double *A, const double q[3],
                                      double g[3])
{
    const double Ai = A[nb->i];
    for (size_t p = 0; p < nb->n; ++p) {
        const size_t j = nb->j[p];
        const double vcA = vol[j] * c[j] * (A[j] - Ai);
        for (int a = 0; a < d; ++a) g[a] += vcA * (nb->dwr[p] * nb->dx[a][p] - nb->w[p] * q[a]);
    }
}

/* 000 eqs. 45-46 (1D): Γ = Σ ω W, s1 = Σ ω f_j dW/dx_a and s2 = Σ ω (f_j - f_i)/(x_j - x_i)
 * dW/dx_a (self pair skipped). */
static inline void term_boundary_1d(const consph_nbhd *nb, const double *vol, const double *f,
                                    double *gamma_out, double *s1_out, double *s2_out)
{
    const double fa = f[nb->i];
    double gamma = 0.0, s1 = 0.0, s2 = 0.0;
    for (size_t p = 0; p < nb->n; ++p) {
        size_t j = nb->j[p];
        double om = vol[j];
        gamma += om * nb->w[p];
        /* dW_ab/dx_a = W'(r) (x_a - x_b)/r */
        double dw = nb->dwr[p] * nb->dx[0][p];
        /* eq. 45 as eq. 43 implies (the printed sum lacks dW_ab/dx_a) */
        s1 += om * f[j] * dw;
        /* eq. 46: ((f_b - f_a)/(x_b - x_a)) dW_ab/dx_a, x_b - x_a = -dx; skipped at r = 0 */
        if (nb->r[p] > 0.0) s2 += om * (f[j] - fa) / (-nb->dx[0][p]) * dw;
    }
    *gamma_out = gamma;
    *s1_out = s1;
    *s2_out = s2;
}

#endif
