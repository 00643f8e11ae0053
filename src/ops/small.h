/* The per-particle dense algebra of the correction matrices, written once for the host and the
 * GPU (CONSPH_HD, src/gpu/hd.h): the small inverse of ops_invert (src/ops/ops_linalg.c) and the
 * corrected-gradient rule applied to a particle's sums and fatehi_c's moments (src/ops/terms.h), so
 * that the GPU's fused derivative passes (src/gpu/dev.h) round as the CPU's. Plain C over small
 * arrays. The order of every operation is part of the results: keep it. */
#ifndef CONSPH_OPS_SMALL_H
#define CONSPH_OPS_SMALL_H

#include <math.h>

#include "gpu/hd.h"

/* The largest matrix inverted (OPS_MAX_MSPH of ops_internal.h: MSPH's 10×10 in 3D). */
#define OPS_SMALL_MAXN 10

/* The scratch of one inverse: the GPU inverts the Bonet and Fatehi_c matrices (2×2, 3×3) and
 * Korzilius' (3×3, 6×6), and its pivoting indexes the scratch at run time, which puts it in the
 * thread's local memory. */
#if defined(__CUDA_ARCH__)
#define OPS_SMALL_SCRATCH 6
#else
#define OPS_SMALL_SCRATCH OPS_SMALL_MAXN
#endif

#if defined(__CUDACC__)
#define OPS_SMALL __host__ __device__ static __forceinline__
#elif defined(__GNUC__)
#define OPS_SMALL static inline __attribute__((always_inline))
#else
#define OPS_SMALL static inline
#endif

OPS_SMALL double ops_norm1(const int n, const double *a)
{
    double best = 0.0;
    for (int c = 0; c < n; ++c) {
        double s = 0.0;
        for (int r = 0; r < n; ++r) s += fabs(a[r * n + c]);
        if (s > best) best = s;
    }
    return best;
}

/* The inverse for n known at compile time where the caller passes a constant (the 2×2 and 3×3
 * Bonet matrices of every step), the same operations in the same order for any n. */
OPS_SMALL int ops_invert_n(const int n, const double *a, double *ainv, double cond_max,
                           double *cond)
{
    double rs[OPS_SMALL_SCRATCH], cs[OPS_SMALL_SCRATCH];
    double m[OPS_SMALL_SCRATCH * OPS_SMALL_SCRATCH], inv[OPS_SMALL_SCRATCH * OPS_SMALL_SCRATCH];
    if (n > OPS_SMALL_SCRATCH) return 0;
    /* Correction matrices mix entries of different units (W, x W, ∇W, x ∇W, ...). Scaling rows
     * and columns to unit max-norm removes the units, so one threshold serves every matrix and
     * every h; it also improves the pivoting. */
    for (int r = 0; r < n; ++r) {
        double mx = 0.0;
        for (int c = 0; c < n; ++c) {
            double v = a[r * n + c];
            if (!isfinite(v)) return 0;
            if (fabs(v) > mx) mx = fabs(v);
        }
        if (mx == 0.0) return 0;
        rs[r] = 1.0 / mx;
    }
    for (int c = 0; c < n; ++c) {
        double mx = 0.0;
        for (int r = 0; r < n; ++r)
            if (fabs(rs[r] * a[r * n + c]) > mx) mx = fabs(rs[r] * a[r * n + c]);
        if (mx == 0.0) return 0;
        cs[c] = 1.0 / mx;
    }
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) {
            m[r * n + c] = rs[r] * a[r * n + c] * cs[c];
            inv[r * n + c] = r == c ? 1.0 : 0.0;
        }
    double anorm = ops_norm1(n, m);
    /* Gauss-Jordan with partial pivoting on the equilibrated matrix. */
    for (int k = 0; k < n; ++k) {
        int piv = k;
        for (int r = k + 1; r < n; ++r)
            if (fabs(m[r * n + k]) > fabs(m[piv * n + k])) piv = r;
        if (!(fabs(m[piv * n + k]) > 0.0)) return 0;
        if (piv != k) {
            for (int c = 0; c < n; ++c) {
                double t = m[k * n + c];
                m[k * n + c] = m[piv * n + c];
                m[piv * n + c] = t;
                t = inv[k * n + c];
                inv[k * n + c] = inv[piv * n + c];
                inv[piv * n + c] = t;
            }
        }
        double d = 1.0 / m[k * n + k];
        for (int c = 0; c < n; ++c) {
            m[k * n + c] *= d;
            inv[k * n + c] *= d;
        }
        for (int r = 0; r < n; ++r) {
            if (r == k) continue;
            double f = m[r * n + k];
            if (f == 0.0) continue;
            for (int c = 0; c < n; ++c) {
                m[r * n + c] -= f * m[k * n + c];
                inv[r * n + c] -= f * inv[k * n + c];
            }
        }
    }
    double kappa = anorm * ops_norm1(n, inv);
    if (!isfinite(kappa) || kappa > cond_max) return 0;
    /* (R A C)^{-1} = C^{-1} A^{-1} R^{-1}, so A^{-1} = C (RAC)^{-1} R. */
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) ainv[r * n + c] = cs[r] * inv[r * n + c] * rs[c];
    if (cond) *cond = kappa;
    return 1;
}

/* The rule applied to a particle's sums (term_grad_sums): out = c sw + M sg. */
CONSPH_HD static inline void term_apply_rule(int d, const double c[3], const double M[9],
                                             const double sg[3], double sw, double out[3])
{
    for (int a = 0; a < d; ++a) {
        double v = c[a] * sw;
        for (int b = 0; b < d; ++b) v += M[a * d + b] * sg[b];
        out[a] = v;
    }
}

/* One pair of fatehi_c's moments (term_fatehi_c_moments, r > 0): g = ω_j W'/r, so that
 * L1 += g r² x, L2 += g x x, L3 += g/r² x x x. */
CONSPH_HD static inline void term_fatehi_c_pair(int d, double r, const double x[3], double g,
                                                double L1[3], double L2[9], double L3[27])
{
    const double g3 = g / (r * r);
    for (int a = 0; a < d; ++a) {
        L1[a] += g * r * r * x[a];
        for (int b = 0; b < d; ++b) {
            L2[a * d + b] += g * x[a] * x[b];
            for (int c = 0; c < d; ++c) L3[(a * d + b) * d + c] += g3 * x[a] * x[b] * x[c];
        }
    }
}

/* fatehi_c's matrix from its moments (term_fatehi_c_matrix): M = -(L2 + L3·(B L1)). */
CONSPH_HD static inline void term_fatehi_c_finish(int d, const double B[9], const double L1[3],
                                                  const double L2[9], const double L3[27],
                                                  double M[9])
{
    double BL1[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a)
        for (int t = 0; t < d; ++t) BL1[a] += B[a * d + t] * L1[t];
    for (int a = 0; a < d; ++a)
        for (int b = 0; b < d; ++b) {
            double v = L2[a * d + b];
            for (int c = 0; c < d; ++c) v += L3[(a * d + b) * d + c] * BL1[c];
            M[a * d + b] = -v;
        }
}

/* Coefficient of x^l x^k H_lk in the second-order Taylor term: 1/2 on the diagonal, 1 off it
 * (the symmetric pair is counted once); 000 eq. 32's (1 - δ_lk/2). */
CONSPH_HD static inline double term_taylor_c(int l, int k)
{
    return l == k ? 0.5 : 1.0;
}

/* The radial part of the kernel Hessian ∂_l∂_k W = aee x^l x^k + dwr δ_lk of a pair at r:
 * (W'' - W'/r)/r², 0 at r = 0 (term_pair_hess). */
CONSPH_HD static inline double term_hess_radial(double r, double dwr, double d2w)
{
    return r > 0.0 ? (d2w - dwr) / (r * r) : 0.0;
}

/* Korzilius' Γ̃ (001 eq. 15 with the fixes of docs/deviations.md): subtracts Hx B Gz, from the sums
 * of term_second_moment with korz, from its CSPM matrix A. */
CONSPH_HD static inline void term_korzilius_correct(int d, int P, const double *Hx,
                                                    const double *Gz, const double B[9], double *A)
{
    double BG[3 * 6];
    for (int e = 0; e < 3 * 6; ++e) BG[e] = 0.0;
    for (int a = 0; a < d; ++a)
        for (int b = 0; b < P; ++b)
            for (int c = 0; c < d; ++c) BG[a * P + b] += B[a * d + c] * Gz[c * P + b];
    for (int a = 0; a < P; ++a)
        for (int b = 0; b < P; ++b)
            for (int c = 0; c < d; ++c) A[a * P + b] -= Hx[a * d + c] * BG[c * P + b];
}

#endif
