/* Kernel tests, every kernel in 1D, 2D and 3D: normalisation by independent quadrature (the
 * constants are not trusted), derivatives against finite differences, the edge smoothness beta
 * measured from the shape near the support edge, continuity at the spline breakpoints, the M4
 * tensor product and its polynomial reproduction, name lookup and argument validation.
 * Prints the table of |∫W dV - 1|. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "consph/kernels.h"

#define PI 3.14159265358979323846
#define GL_N 20

static double gl_x[GL_N], gl_w[GL_N];

/* Gauss-Legendre nodes and weights on [-1, 1] by Newton iteration on P_n. */
static void gauss_legendre_init(void)
{
    for (int i = 0; i < (GL_N + 1) / 2; ++i) {
        double z = cos(PI * (i + 0.75) / (GL_N + 0.5)), dp = 1.0;
        for (int it = 0; it < 100; ++it) {
            double p0 = 1.0, p1 = 0.0;
            for (int j = 1; j <= GL_N; ++j) {
                double p2 = p1;
                p1 = p0;
                p0 = ((2.0 * j - 1.0) * z * p1 - (j - 1.0) * p2) / j;
            }
            dp = GL_N * (z * p0 - p1) / (z * z - 1.0);
            double dz = p0 / dp;
            z -= dz;
            if (fabs(dz) < 1e-16) break;
        }
        gl_x[i] = -z;
        gl_x[GL_N - 1 - i] = z;
        gl_w[i] = gl_w[GL_N - 1 - i] = 2.0 / ((1.0 - z * z) * dp * dp);
    }
}

static const double sphere_area[4] = {0.0, 2.0, 2.0 * PI, 4.0 * PI};

/* Every kernel's pieces join at integer q (the support is 1, 2 or 3), so unit intervals cut 16
 * times make each piece smooth on every subinterval: 20-point Gauss-Legendre is then exact on
 * the polynomials and accurate to round-off on the Gaussians. */
#define SUBDIV 16

/* ∫ W dV over R^d of a radial kernel, ∫_0^radius W(r) S_d r^(d-1) dr, through the public API. */
static double radial_integral(const consph_kernel *k)
{
    double sum = 0.0;
    int nunits = (int)k->support;
    for (int u = 0; u < nunits; ++u)
        for (int s = 0; s < SUBDIV; ++s) {
            double a = k->h * (u + (double)s / SUBDIV), b = k->h * (u + (s + 1.0) / SUBDIV);
            double mid = 0.5 * (a + b), half = 0.5 * (b - a), part = 0.0;
            for (int g = 0; g < GL_N; ++g) {
                double r = mid + half * gl_x[g];
                part += gl_w[g] * consph_kernel_w(k, r) * sphere_area[k->dim] * pow(r, k->dim - 1);
            }
            sum += half * part;
        }
    return sum;
}

/* ∫ W dV of the tensor-product kernel over [-radius, radius]^d through consph_kernel_w_vec,
 * the 20-point rule on each unit piece per axis (exact on the cubic pieces of M4). */
static double tensor_integral(const consph_kernel *k)
{
    enum { NAX = 4 * GL_N };
    double ax[NAX], aw[NAX];
    int m = 0;
    for (int u = -2; u < 2; ++u)
        for (int g = 0; g < GL_N; ++g, ++m) {
            ax[m] = k->h * (u + 0.5 + 0.5 * gl_x[g]);
            aw[m] = k->h * 0.5 * gl_w[g];
        }
    int n2 = k->dim > 1 ? NAX : 1, n3 = k->dim > 2 ? NAX : 1;
    double sum = 0.0;
    for (int i3 = 0; i3 < n3; ++i3)
        for (int i2 = 0; i2 < n2; ++i2)
            for (int i1 = 0; i1 < NAX; ++i1) {
                double dx[3] = {ax[i1], ax[i2], ax[i3]};
                double wt = aw[i1] * (k->dim > 1 ? aw[i2] : 1.0) * (k->dim > 2 ? aw[i3] : 1.0);
                sum += wt * consph_kernel_w_vec(k, dx);
            }
    return sum;
}

static double kernel_integral(const consph_kernel *k)
{
    return k->tensor ? tensor_integral(k) : radial_integral(k);
}

/* J_m = ∫_3^∞ u^m exp(-u^2) du, by J_m = 3^(m-1) e^-9 / 2 + (m-1)/2 J_(m-2). */
static double gauss_tail_moment(int m)
{
    if (m == 0) return 0.5 * sqrt(PI) * erfc(3.0);
    if (m == 1) return 0.5 * exp(-9.0);
    return 0.5 * pow(3.0, m - 1) * exp(-9.0) + 0.5 * (m - 1) * gauss_tail_moment(m - 2);
}

/* What the cut at the support removes from ∫W dV, analytically (h = 1). Gaussian: sigma_d S_d
 * J_(d-1) with sigma_d = pi^(-d/2). Super-Gaussian, u = 3q: pi^(-d/2) S_d ((1 + d/2) J_(d-1) -
 * J_(d+1)). */
static double truncated_tail(consph_kernel_id id, int d)
{
    double c = pow(PI, -0.5 * d) * sphere_area[d];
    if (id == CONSPH_KERNEL_GAUSSIAN) return c * gauss_tail_moment(d - 1);
    return c * ((1.0 + 0.5 * d) * gauss_tail_moment(d - 1) - gauss_tail_moment(d + 1));
}

/* docs/reference-values.md, "Kernel integrals": integrals of the truncated kernels, and the
 * precision they are given to. */
static const double z1_gaussian[3] = {0.9999779, 0.9998766, 0.9995602};
static const double z1_supergauss[3] = {1.000187, 1.000987, 1.003320};

static void test_normalisation(double err_table[CONSPH_KERNEL_COUNT][3])
{
    for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id)
        for (int d = 1; d <= 3; ++d) {
            consph_kernel k, ks;
            CHECK(consph_kernel_init(&k, id, d, 1.0) == CONSPH_OK, "%s", consph_last_error());
            double integral = kernel_integral(&k);
            err_table[id][d - 1] = fabs(integral - 1.0);
            const char *name = k.name;
            if (id == CONSPH_KERNEL_GAUSSIAN || id == CONSPH_KERNEL_SUPER_GAUSSIAN) {
                const double *z1 = id == CONSPH_KERNEL_GAUSSIAN ? z1_gaussian : z1_supergauss;
                /* They are rounded to 7 (Gaussian) and 6 (super-Gaussian) decimals. */
                double tol = id == CONSPH_KERNEL_GAUSSIAN ? 5e-8 : 5e-7;
                CHECK_NEAR(integral, z1[d - 1], tol, "%s %dD truncated integral vs reference", name,
                           d);
                CHECK_NEAR(integral + truncated_tail(id, d), 1.0, 1e-10,
                           "%s %dD untruncated integral", name, d);
            } else {
                CHECK_NEAR(integral, 1.0, 1e-10, "%s %dD", name, d);
            }
            /* The h-scaling of sigma/h^d: the integral does not depend on h. */
            CHECK(consph_kernel_init(&ks, id, d, 0.37) == CONSPH_OK, "%s", consph_last_error());
            CHECK_NEAR(kernel_integral(&ks), integral, 1e-12, "%s %dD at h = 0.37", name, d);
            const consph_kernel_info *info = consph_kernel_info_get(id);
            CHECK(info && info->support == k.support && info->sigma[d - 1] == k.norm &&
                      info->tensor == k.tensor && k.radius == k.support,
                  "%s %dD: kernel and info disagree", name, d);
        }
}

/* 4th-order central difference of g at x with step e. */
static double fd4(double (*g)(const consph_kernel *, double), const consph_kernel *k, double x,
                  double e)
{
    return (8.0 * (g(k, x + e) - g(k, x - e)) - (g(k, x + 2.0 * e) - g(k, x - 2.0 * e))) /
           (12.0 * e);
}

/* dW/dr and d2W/dr2 of the public API against 4th-order central differences of W and dW/dr in
 * r, at h = 0.37 so that the 1/h factors are exercised. Step 1e-3 h: truncation ~1e-12 f^(5),
 * round-off ~1e-13 |f|. Samples keep 3 steps away from q = 0 and every integer q (breakpoints,
 * support edge), where f'' may jump. Tolerance: 1e-8 of the largest |derivative| sampled. */
static void test_derivatives(void)
{
    const double h = 0.37;
    const int nsamples = 400;
    for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id)
        for (int d = 1; d <= 3; ++d) {
            consph_kernel k;
            CHECK(consph_kernel_init(&k, id, d, h) == CONSPH_OK, "%s", consph_last_error());
            double e = 1e-3 * h, max_dw = 0.0, max_d2w = 0.0, worst_dw = 0.0, worst_d2w = 0.0;
            int nused = 0;
            for (int i = 0; i < nsamples; ++i) {
                double q = k.support * (i + 0.5) / nsamples;
                if (fabs(q - nearbyint(q)) < 3e-3) continue;
                double r = q * h;
                double dw = consph_kernel_dw(&k, r), d2w = consph_kernel_d2w(&k, r);
                max_dw = fmax(max_dw, fabs(dw));
                max_d2w = fmax(max_d2w, fabs(d2w));
                worst_dw = fmax(worst_dw, fabs(dw - fd4(consph_kernel_w, &k, r, e)));
                worst_d2w = fmax(worst_d2w, fabs(d2w - fd4(consph_kernel_dw, &k, r, e)));
                ++nused;
            }
            CHECK(nused > nsamples / 2, "%s %dD: too few samples", k.name, d);
            CHECK(worst_dw <= 1e-8 * max_dw, "%s %dD: dW/dr off FD by %.3g (max |dW/dr| %.3g)",
                  k.name, d, worst_dw, max_dw);
            CHECK(worst_d2w <= 1e-8 * max_d2w,
                  "%s %dD: d2W/dr2 off FD by %.3g (max |d2W/dr2| %.3g)", k.name, d, worst_d2w,
                  max_d2w);
            /* At the centre: f'(0) = 0 (even kernel), and f''(0) against the one-sided
             * difference (4 f'(e) - f'(2e)) / 2e, O(e^2) — a central one would straddle the
             * |q|^3 term several kernels have at the origin. */
            double e0 = 1e-4;
            CHECK(fabs(k.df(0.0)) <= 1e-14 * fmax(1.0, fabs(k.f(0.0))), "%s %dD: f'(0) = %g",
                  k.name, d, k.df(0.0));
            double d2f0 = (4.0 * k.df(e0) - k.df(2.0 * e0)) / (2.0 * e0);
            CHECK(fabs(k.d2f(0.0) - d2f0) <= 1e-6 * fmax(1.0, fabs(d2f0)),
                  "%s %dD: f''(0) = %.17g, FD %.17g", k.name, d, k.d2f(0.0), d2f0);
            /* Interior breakpoints: f and f' are continuous. */
            for (int b = 1; b < (int)k.support; ++b) {
                double lo = b - 1e-12, hi = b + 1e-12;
                CHECK(fabs(k.f(lo) - k.f(hi)) <= 1e-9 * fmax(1.0, fabs(k.f(0.0))),
                      "%s %dD: f jumps at q = %d", k.name, d, b);
                CHECK(fabs(k.df(lo) - k.df(hi)) <= 1e-9 * fmax(1.0, max_dw * h),
                      "%s %dD: f' jumps at q = %d", k.name, d, b);
            }
            /* Compact support: zero at and beyond the edge, through every entry point. (Just past
             * the radius: r * inv_h can round to below the support at r = radius itself.) */
            double edge = k.radius * (1.0 + 1e-15), dx[3] = {edge, 0.0, 0.0};
            CHECK(consph_kernel_w(&k, edge) == 0.0 && consph_kernel_dw(&k, edge) == 0.0 &&
                      consph_kernel_d2w(&k, 1.5 * k.radius) == 0.0 &&
                      consph_kernel_w_vec(&k, dx) == 0.0 && k.f(k.support) == 0.0 &&
                      k.df(k.support + 0.5) == 0.0 && k.d2f(k.support) == 0.0,
                  "%s %dD: nonzero at the support edge", k.name, d);
        }
}

/* Log-log slope of |g(s - e)| between e1 and e2. */
static double edge_slope(consph_shape_fn g, double s, double e1, double e2)
{
    return log(fabs(g(s - e1)) / fabs(g(s - e2))) / log(e1 / e2);
}

/* beta_001 measured: near the edge s, f(s - e) ~ e^beta, f' ~ e^(beta-1), f'' ~ e^(beta-2)
 * (for a truncated kernel, beta = 0 and f tends to a nonzero constant). Slopes between
 * e = 1e-3 and 1e-4 must match within 0.1. */
static void test_beta(void)
{
    const double e1 = 1e-3, e2 = 1e-4;
    for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id)
        for (int d = 1; d <= 3; ++d) {
            consph_kernel k;
            CHECK(consph_kernel_init(&k, id, d, 1.0) == CONSPH_OK, "%s", consph_last_error());
            int beta = consph_kernel_beta_001(id, d);
            double s = k.support;
            double slope = edge_slope(k.f, s, e1, e2);
            CHECK(fabs(slope - beta) <= 0.1, "%s %dD: f slope %.4f, beta_001 %d", k.name, d, slope,
                  beta);
            CHECK(fabs(k.f(s - e2)) > 0.0, "%s %dD: f vanishes inside the support", k.name, d);
            if (beta >= 1) {
                double sd = edge_slope(k.df, s, e1, e2);
                CHECK(fabs(sd - (beta - 1)) <= 0.1, "%s %dD: f' slope %.4f, want %d", k.name, d, sd,
                      beta - 1);
            }
            if (beta >= 2) {
                double sd2 = edge_slope(k.d2f, s, e1, e2);
                CHECK(fabs(sd2 - (beta - 2)) <= 0.1, "%s %dD: f'' slope %.4f, want %d", k.name, d,
                      sd2, beta - 2);
            }
            if (d > 1) {
                const consph_kernel_info *info = consph_kernel_info_get(id);
                CHECK(info && beta == info->beta_001, "%s %dD: beta differs from info", k.name, d);
            }
        }
    /* The values under 001's definition (after its eq. 3; docs/deviations.md). */
    const int expected[CONSPH_KERNEL_COUNT] = {3, 5, 0, 0, 3, 4, 6, 8, 4, 6, 8, 2};
    for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id) {
        const consph_kernel_info *info = consph_kernel_info_get(id);
        CHECK(info && info->beta_001 == expected[id], "kernel %d: beta_001", id);
    }
    CHECK(consph_kernel_beta_001(CONSPH_KERNEL_WENDLAND_C4, 1) == 5, "PySPH 1D C4 edge order");
}

/* M4 of 001 eq. (32), written out independently of the library. */
static double m4_reference(double q)
{
    q = fabs(q);
    if (q < 1.0) return 1.0 - 2.5 * q * q + 1.5 * q * q * q;
    if (q < 2.0) return 0.5 * (1.0 - q) * (2.0 - q) * (2.0 - q);
    return 0.0;
}

static void test_m4(void)
{
    /* On a lattice of spacing h: sum_j h W(x - x_j) x_j^k = x^k for k = 0, 1, 2. */
    const double spacings[2] = {1.0, 0.3};
    for (int t = 0; t < 2; ++t) {
        double h = spacings[t];
        consph_kernel k;
        CHECK(consph_kernel_init(&k, CONSPH_KERNEL_M4, 1, h) == CONSPH_OK, "%s",
              consph_last_error());
        for (int ix = 0; ix < 23; ++ix) {
            double x = h * (-1.0 + 0.137 * ix);
            double moments[3] = {0.0, 0.0, 0.0};
            for (int j = -6; j <= 6; ++j) {
                double xj = j * h, dx = x - xj, w = h * consph_kernel_w_vec(&k, &dx);
                moments[0] += w;
                moments[1] += w * xj;
                moments[2] += w * xj * xj;
            }
            CHECK_NEAR(moments[0], 1.0, 1e-14, "M4 partition of unity at x = %g, h = %g", x, h);
            CHECK_NEAR(moments[1], x, 1e-14, "M4 reproduces x at x = %g, h = %g", x, h);
            CHECK_NEAR(moments[2], x * x, 1e-14, "M4 reproduces x^2 at x = %g, h = %g", x, h);
        }
        /* Interpolating: 1 at its own node, 0 at the others. */
        double zero = 0.0, one = h, two = 2.0 * h;
        CHECK(h * consph_kernel_w_vec(&k, &zero) == 1.0 && consph_kernel_w_vec(&k, &one) == 0.0 &&
                  consph_kernel_w_vec(&k, &two) == 0.0,
              "M4 is not interpolating at h = %g", h);
    }
    /* 2D/3D: the tensor product of the independent profile, and a 2D partition of unity. */
    for (int d = 2; d <= 3; ++d) {
        const double h = 0.7;
        consph_kernel k;
        CHECK(consph_kernel_init(&k, CONSPH_KERNEL_M4, d, h) == CONSPH_OK, "%s",
              consph_last_error());
        CHECK(k.tensor == 1, "m4 is a tensor product");
        consph_rng rng;
        consph_rng_seed(&rng, 42u + (unsigned)d);
        double worst = 0.0;
        for (int s = 0; s < 1000; ++s) {
            double dx[3], ref = 1.0;
            for (int a = 0; a < 3; ++a) dx[a] = (consph_rng_uniform(&rng) * 5.0 - 2.5) * h;
            for (int a = 0; a < d; ++a) ref *= m4_reference(dx[a] / h) / h;
            worst = fmax(worst, fabs(consph_kernel_w_vec(&k, dx) - ref));
        }
        CHECK(worst <= 1e-13, "m4 %dD tensor product off by %g", d, worst);
    }
    consph_kernel k2;
    CHECK(consph_kernel_init(&k2, CONSPH_KERNEL_M4, 2, 0.5) == CONSPH_OK, "%s",
          consph_last_error());
    double pos[2] = {0.113, -0.271}, sum = 0.0;
    for (int i = -6; i <= 6; ++i)
        for (int j = -6; j <= 6; ++j) {
            double dx[2] = {pos[0] - 0.5 * i, pos[1] - 0.5 * j};
            sum += 0.25 * consph_kernel_w_vec(&k2, dx);
        }
    CHECK_NEAR(sum, 1.0, 1e-14, "m4 2D lattice partition of unity");
}

/* consph_kernel_w_vec of a radial kernel is W(|dx|). */
static void test_w_vec_radial(void)
{
    consph_rng rng;
    consph_rng_seed(&rng, 7u);
    for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id)
        for (int d = 1; d <= 3; ++d) {
            consph_kernel k;
            if (id == CONSPH_KERNEL_M4) continue;
            CHECK(consph_kernel_init(&k, id, d, 0.8) == CONSPH_OK, "%s", consph_last_error());
            double worst = 0.0;
            for (int s = 0; s < 200; ++s) {
                double dx[3] = {0.0, 0.0, 0.0}, r2 = 0.0;
                for (int a = 0; a < d; ++a) {
                    dx[a] = (2.0 * consph_rng_uniform(&rng) - 1.0) * k.radius;
                    r2 += dx[a] * dx[a];
                }
                double ref = consph_kernel_w(&k, sqrt(r2));
                worst = fmax(worst, fabs(consph_kernel_w_vec(&k, dx) - ref) / k.norm);
            }
            CHECK(worst <= 1e-14, "%s %dD: w_vec differs from w(|dx|) by %g", k.name, d, worst);
        }
}

/* Does the comma-separated `list` hold `name` as a whole item? */
static int list_has(const char *list, const char *name)
{
    size_t n = strlen(name);
    for (const char *p = strstr(list, name); p; p = strstr(p + 1, name)) {
        int starts = p == list || p[-1] == ' ' || p[-1] == ',';
        int ends = p[n] == '\0' || p[n] == ',';
        if (starts && ends) return 1;
    }
    return 0;
}

static void test_lookup_and_validation(void)
{
    const char *names = consph_kernel_names();
    for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id) {
        const consph_kernel_info *info = consph_kernel_info_get(id);
        CHECK(info && info->id == (consph_kernel_id)id, "info of kernel %d", id);
        if (!info) continue;
        consph_kernel_id found = CONSPH_KERNEL_COUNT;
        CHECK(consph_kernel_lookup(info->name, &found) == CONSPH_OK && found == info->id,
              "lookup of '%s'", info->name);
        CHECK(list_has(names, info->name), "'%s' missing from the name list", info->name);
        CHECK(info->description && *info->description && info->source && *info->source,
              "%s: empty description or source", info->name);
    }
    CHECK(consph_kernel_info_get(CONSPH_KERNEL_COUNT) == NULL, "info past the end");
    const char *bad[] = {"foo", "", "Cubic", "wendland-c2:H", "wendland", "m4 ", "cubic,"};
    for (size_t b = 0; b < sizeof bad / sizeof bad[0]; ++b) {
        consph_kernel_id found = CONSPH_KERNEL_CUBIC;
        consph_clear_error();
        CHECK(consph_kernel_lookup(bad[b], &found) == CONSPH_EINVAL, "'%s' accepted", bad[b]);
        const char *msg = consph_last_error();
        for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id)
            CHECK(list_has(strstr(msg, "allowed: ") ? strstr(msg, "allowed: ") + 9 : "",
                           consph_kernel_info_get(id)->name),
                  "message '%s' does not name '%s'", msg, consph_kernel_info_get(id)->name);
    }
    CHECK(consph_kernel_lookup(NULL, NULL) == CONSPH_EINVAL, "NULL name accepted");

    consph_kernel k;
    const int bad_dims[] = {0, 4, -1};
    for (size_t b = 0; b < 3; ++b)
        CHECK(consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, bad_dims[b], 1.0) == CONSPH_EINVAL,
              "dim %d accepted", bad_dims[b]);
    const double bad_h[] = {0.0, -1.0, NAN, INFINITY, -INFINITY, 1e-200};
    for (size_t b = 0; b < sizeof bad_h / sizeof bad_h[0]; ++b)
        CHECK(consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 3, bad_h[b]) == CONSPH_EINVAL,
              "h = %g accepted", bad_h[b]);
    CHECK(consph_kernel_init(&k, CONSPH_KERNEL_COUNT, 2, 1.0) == CONSPH_EINVAL, "bad id accepted");
    CHECK(consph_kernel_init(&k, CONSPH_KERNEL_LUCY, 2, 2.0) == CONSPH_OK && k.radius == 2.0 &&
              k.inv_h == 0.5 && fabs(k.norm - 5.0 / PI / 4.0) < 1e-16,
          "lucy 2D at h = 2");
}

int main(void)
{
    gauss_legendre_init();
    double sum_w = 0.0;
    for (int g = 0; g < GL_N; ++g) sum_w += gl_w[g];
    CHECK_NEAR(sum_w, 2.0, 1e-14, "Gauss-Legendre weights");

    double err[CONSPH_KERNEL_COUNT][3];
    test_normalisation(err);
    test_derivatives();
    test_beta();
    test_m4();
    test_w_vec_radial();
    test_lookup_and_validation();

    printf("measured normalisation error |integral of W dV - 1| (20-point Gauss-Legendre, 16 "
           "cells per unit of q; m4: tensor product)\n");
    printf("%-16s %12s %12s %12s\n", "kernel", "1D", "2D", "3D");
    for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id)
        printf("%-16s %12.3e %12.3e %12.3e\n", consph_kernel_info_get(id)->name, err[id][0],
               err[id][1], err[id][2]);
    return check_summary("test_kernels");
}
