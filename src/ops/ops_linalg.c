/* Small dense inverses for the per-particle correction matrices (at most 10×10). */
#include <math.h>
#include <string.h>

#include "ops/ops_internal.h"

#define MAXN OPS_MAX_MSPH

static inline double norm1(const int n, const double *a)
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
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline int
invert_n(const int n, const double *a, double *ainv, double cond_max, double *cond)
{
    double rs[MAXN], cs[MAXN], m[MAXN * MAXN], inv[MAXN * MAXN];
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
    double anorm = norm1(n, m);
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
    double kappa = anorm * norm1(n, inv);
    if (!isfinite(kappa) || kappa > cond_max) return 0;
    /* (R A C)^{-1} = C^{-1} A^{-1} R^{-1}, so A^{-1} = C (RAC)^{-1} R. */
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) ainv[r * n + c] = cs[r] * inv[r * n + c] * rs[c];
    if (cond) *cond = kappa;
    return 1;
}

int ops_invert(int n, const double *a, double *ainv, double cond_max, double *cond)
{
    if (n < 1 || n > MAXN) return 0;
    if (n == 2) return invert_n(2, a, ainv, cond_max, cond);
    if (n == 3) return invert_n(3, a, ainv, cond_max, cond);
    return invert_n(n, a, ainv, cond_max, cond);
}

void ops_pair_index(int dim, int p, int *l, int *k)
{
    int idx = 0;
    for (int a = 0; a < dim; ++a)
        for (int b = a; b < dim; ++b) {
            if (idx == p) {
                *l = a;
                *k = b;
                return;
            }
            ++idx;
        }
    *l = *k = 0;
}
