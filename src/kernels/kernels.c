/* Every smoothing kernel of the seed papers (001 Table 1, 002 eq. 47,
 * 003 eqs. 55, 59-62, 000 eq. 58, 001 eq. 32): shape functions f, f', f'' of
 * q = r/h per kernel and per dimension, their normalisations sigma_d and the name table.
 *
 * The shape functions are plain static functions of q so that consph_kernel_init can pick one
 * triple per (kernel, dimension) and the evaluation path carries no branch on the kernel. Each
 * returns 0 for q at or beyond its support, so a caller that forgets the cut still gets the
 * compactly supported kernel.
 *
 * The polynomial ones compute every piece and then select, instead of branching: selects
 * vectorise when consph_kernel_eval_batch inlines them into its loops, and a branch on q
 * mispredicts on neighbour lists. A piece that does not apply is either not selected or adds
 * an exact zero (x - 6·0 = x), so the values are those of the branching form bit for bit. */
#include "consph/kernels.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#define PI 3.14159265358979323846

/* GCC does not if-convert the selects below while floating-point operations may trap (it sinks
 * each piece into its arm first), so the batch loops would not vectorise. No code here reads the
 * floating-point exception flags, and the option changes no value (it permits no
 * reassociation). */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("no-trapping-math")
#endif

#if defined(__GNUC__)
#define SHAPE static inline __attribute__((always_inline))
#else
#define SHAPE static inline
#endif

/* t where t > 0, else 0 (also for NaN). */
SHAPE double positive(double t)
{
    return t > 0.0 ? t : 0.0;
}

/* ---- cubic spline, support 2 (001 Table 1 "CS"; formula from Monaghan 1992 / PySPH) ---- */
SHAPE double cubic_f(double q)
{
    double inner = 1.0 - q * q * (1.5 - 0.75 * q);
    double t = 2.0 - q, outer = 0.25 * t * t * t;
    return q < 1.0 ? inner : q < 2.0 ? outer : 0.0;
}
SHAPE double cubic_df(double q)
{
    double inner = q * (-3.0 + 2.25 * q);
    double t = 2.0 - q, outer = -0.75 * t * t;
    return q < 1.0 ? inner : q < 2.0 ? outer : 0.0;
}
SHAPE double cubic_d2f(double q)
{
    double inner = -3.0 + 4.5 * q, outer = 1.5 * (2.0 - q);
    return q < 1.0 ? inner : q < 2.0 ? outer : 0.0;
}

/* ---- quintic spline, support 3 (001 Table 1 "QS") ---- */
SHAPE double pow5(double t)
{
    double t2 = t * t;
    return t2 * t2 * t;
}
SHAPE double pow4(double t)
{
    double t2 = t * t;
    return t2 * t2;
}
/* (3-q)^5 - 6 (2-q)_+^5 + 15 (1-q)_+^5: the terms of the outer pieces vanish exactly. */
SHAPE double quintic_f(double q)
{
    double w = pow5(3.0 - q) - 6.0 * pow5(positive(2.0 - q)) + 15.0 * pow5(positive(1.0 - q));
    return q >= 3.0 ? 0.0 : w;
}
SHAPE double quintic_df(double q)
{
    double w =
        -5.0 * pow4(3.0 - q) + 30.0 * pow4(positive(2.0 - q)) - 75.0 * pow4(positive(1.0 - q));
    return q >= 3.0 ? 0.0 : w;
}
SHAPE double quintic_d2f(double q)
{
    double t3 = 3.0 - q, t2 = positive(2.0 - q), t1 = positive(1.0 - q);
    double w = 20.0 * t3 * t3 * t3 - 120.0 * t2 * t2 * t2 + 300.0 * t1 * t1 * t1;
    return q >= 3.0 ? 0.0 : w;
}

/* ---- Gaussian exp(-q^2), truncated at q = 3 (001 Table 1 "G") ---- */
static double gaussian_f(double q)
{
    return q < 3.0 ? exp(-q * q) : 0.0;
}
static double gaussian_df(double q)
{
    return q < 3.0 ? -2.0 * q * exp(-q * q) : 0.0;
}
static double gaussian_d2f(double q)
{
    return q < 3.0 ? (4.0 * q * q - 2.0) * exp(-q * q) : 0.0;
}

/* ---- Monaghan super-Gaussian exp(-9q^2)(1 + d/2 - 9q^2), truncated at q = 1 (003 eq. 60).
 * The bracket holds the dimension d, hence one triple per dimension; c = 1 + d/2. 003 keeps
 * q = 1 inside the support; like every kernel here it is cut at q < support, which differs only
 * on the sphere q = 1 itself. ---- */
static double supergauss_f(double q, double c)
{
    return q < 1.0 ? exp(-9.0 * q * q) * (c - 9.0 * q * q) : 0.0;
}
static double supergauss_df(double q, double c)
{
    return q < 1.0 ? -18.0 * q * exp(-9.0 * q * q) * (c + 1.0 - 9.0 * q * q) : 0.0;
}
static double supergauss_d2f(double q, double c)
{
    if (q >= 1.0) return 0.0;
    double q2 = q * q;
    return -18.0 * exp(-9.0 * q2) * ((c + 1.0) * (1.0 - 18.0 * q2) - 27.0 * q2 + 162.0 * q2 * q2);
}
static double supergauss1_f(double q)
{
    return supergauss_f(q, 1.5);
}
static double supergauss1_df(double q)
{
    return supergauss_df(q, 1.5);
}
static double supergauss1_d2f(double q)
{
    return supergauss_d2f(q, 1.5);
}
static double supergauss2_f(double q)
{
    return supergauss_f(q, 2.0);
}
static double supergauss2_df(double q)
{
    return supergauss_df(q, 2.0);
}
static double supergauss2_d2f(double q)
{
    return supergauss_d2f(q, 2.0);
}
static double supergauss3_f(double q)
{
    return supergauss_f(q, 2.5);
}
static double supergauss3_df(double q)
{
    return supergauss_df(q, 2.5);
}
static double supergauss3_d2f(double q)
{
    return supergauss_d2f(q, 2.5);
}

/* ---- Lucy quartic (1-q)^3 (1+3q), support 1 (003 eq. 59) ---- */
SHAPE double lucy_f(double q)
{
    double t = 1.0 - q, v = t * t * t * (1.0 + 3.0 * q);
    return q >= 1.0 ? 0.0 : v;
}
SHAPE double lucy_df(double q)
{
    double t = 1.0 - q, v = -12.0 * q * t * t;
    return q >= 1.0 ? 0.0 : v;
}
SHAPE double lucy_d2f(double q)
{
    double v = 12.0 * (1.0 - q) * (3.0 * q - 1.0);
    return q >= 1.0 ? 0.0 : v;
}

/* ---- Wendland, support 2 (001 "WQ_2/4/6" = PySPH WendlandQuintic, ...C4, ...C6), t = 1 - q/2.
 * 2D and 3D share one polynomial; 1D uses PySPH's own 1D Wendland functions (psi_{1,k}), which
 * is also why their edge order in 1D is 3/5/7 rather than 4/6/8. ---- */
SHAPE double wc2_f(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = pow4(t) * (2.0 * q + 1.0);
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc2_df(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = -5.0 * q * t * t * t;
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc2_d2f(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = 5.0 * t * t * (2.0 * q - 1.0);
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc4_f(double q)
{
    double t = 1.0 - 0.5 * q, t2 = t * t;
    double v = t2 * t2 * t2 * (1.0 + q * (3.0 + q * (35.0 / 12.0)));
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc4_df(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = -(14.0 / 3.0) * q * pow5(t) * (1.0 + 2.5 * q);
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc4_d2f(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = -(14.0 / 3.0) * pow4(t) * (1.0 + q * (2.0 - 8.75 * q));
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc6_f(double q)
{
    double t4 = pow4(1.0 - 0.5 * q);
    double v = t4 * t4 * (1.0 + q * (4.0 + q * (6.25 + 4.0 * q)));
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc6_df(double q)
{
    double t = 1.0 - 0.5 * q, t3 = t * t * t;
    double v = -5.5 * q * t3 * pow4(t) * (1.0 + q * (3.5 + 4.0 * q));
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc6_d2f(double q)
{
    double t = 1.0 - 0.5 * q, t2 = t * t;
    double v = -5.5 * t2 * t2 * t2 * (1.0 + q * (3.0 - q * (3.75 + 20.0 * q)));
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc2_1d_f(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = t * t * t * (1.5 * q + 1.0);
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc2_1d_df(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = -3.0 * q * t * t;
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc2_1d_d2f(double q)
{
    double v = 3.0 * (1.0 - 0.5 * q) * (1.5 * q - 1.0);
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc4_1d_f(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = pow5(t) * (1.0 + q * (2.5 + 2.0 * q));
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc4_1d_df(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = -3.5 * q * pow4(t) * (1.0 + 2.0 * q);
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc4_1d_d2f(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = -3.5 * t * t * t * (1.0 + q * (1.5 - 6.0 * q));
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc6_1d_f(double q)
{
    double t = 1.0 - 0.5 * q, t3 = t * t * t;
    double v = t3 * pow4(t) * (1.0 + q * (3.5 + q * (4.75 + 2.625 * q)));
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc6_1d_df(double q)
{
    double t = 1.0 - 0.5 * q, t2 = t * t;
    double v = -q * t2 * t2 * t2 * (4.5 + q * (13.5 + 13.125 * q));
    return q >= 2.0 ? 0.0 : v;
}
SHAPE double wc6_1d_d2f(double q)
{
    double t = 1.0 - 0.5 * q;
    double v = -pow5(t) * (4.5 + q * (11.25 - q * (14.625 + 59.0625 * q)));
    return q >= 2.0 ? 0.0 : v;
}

/* ---- Wendland, support 1 (002 eq. 47; 003 eqs. 55, 61, 62), t = 1 - q; same polynomial in
 * every dimension; the papers give no 1D constants, these normalise f in 1D. ---- */
SHAPE double wc2h_f(double q)
{
    double v = pow4(1.0 - q) * (1.0 + 4.0 * q);
    return q >= 1.0 ? 0.0 : v;
}
SHAPE double wc2h_df(double q)
{
    double t = 1.0 - q;
    double v = -20.0 * q * t * t * t;
    return q >= 1.0 ? 0.0 : v;
}
SHAPE double wc2h_d2f(double q)
{
    double t = 1.0 - q;
    double v = 20.0 * t * t * (4.0 * q - 1.0);
    return q >= 1.0 ? 0.0 : v;
}
SHAPE double wc4h_f(double q)
{
    double t = 1.0 - q, t2 = t * t;
    double v = t2 * t2 * t2 * (1.0 + q * (6.0 + q * (35.0 / 3.0)));
    return q >= 1.0 ? 0.0 : v;
}
SHAPE double wc4h_df(double q)
{
    double v = -(56.0 / 3.0) * q * pow5(1.0 - q) * (1.0 + 5.0 * q);
    return q >= 1.0 ? 0.0 : v;
}
SHAPE double wc4h_d2f(double q)
{
    double v = -(56.0 / 3.0) * pow4(1.0 - q) * (1.0 + q * (4.0 - 35.0 * q));
    return q >= 1.0 ? 0.0 : v;
}
SHAPE double wc6h_f(double q)
{
    double t4 = pow4(1.0 - q);
    double v = t4 * t4 * (1.0 + q * (8.0 + q * (25.0 + 32.0 * q)));
    return q >= 1.0 ? 0.0 : v;
}
SHAPE double wc6h_df(double q)
{
    double t = 1.0 - q, t3 = t * t * t;
    double v = -22.0 * q * t3 * pow4(t) * (1.0 + q * (7.0 + 16.0 * q));
    return q >= 1.0 ? 0.0 : v;
}
SHAPE double wc6h_d2f(double q)
{
    double t = 1.0 - q, t2 = t * t;
    double v = -22.0 * t2 * t2 * t2 * (1.0 + q * (6.0 - q * (15.0 + 160.0 * q)));
    return q >= 1.0 ? 0.0 : v;
}
/* ---- M4' remeshing kernel, support 2 (001 eq. 32); a 1D profile used as a tensor product ---- */
SHAPE double m4_f(double q)
{
    double inner = 1.0 - q * q * (2.5 - 1.5 * q);
    double t = 2.0 - q, outer = 0.5 * (1.0 - q) * t * t;
    return q < 1.0 ? inner : q < 2.0 ? outer : 0.0;
}
SHAPE double m4_df(double q)
{
    double inner = q * (-5.0 + 4.5 * q), outer = -0.5 * (2.0 - q) * (4.0 - 3.0 * q);
    return q < 1.0 ? inner : q < 2.0 ? outer : 0.0;
}
SHAPE double m4_d2f(double q)
{
    double inner = -5.0 + 9.0 * q, outer = 5.0 - 3.0 * q;
    return q < 1.0 ? inner : q < 2.0 ? outer : 0.0;
}

typedef struct shape_set {
    consph_shape_fn f, df, d2f;
} shape_set;

#define SHAPES(p)                                                                                  \
    {                                                                                              \
        p##_f, p##_df, p##_d2f                                                                     \
    }
#define SAME3(p)                                                                                   \
    {                                                                                              \
        SHAPES(p), SHAPES(p), SHAPES(p)                                                            \
    }

/* Indexed by [kernel][dim - 1]. */
static const shape_set shape_table[CONSPH_KERNEL_COUNT][CONSPH_MAX_DIM] = {
    [CONSPH_KERNEL_CUBIC] = SAME3(cubic),
    [CONSPH_KERNEL_QUINTIC] = SAME3(quintic),
    [CONSPH_KERNEL_GAUSSIAN] = SAME3(gaussian),
    [CONSPH_KERNEL_SUPER_GAUSSIAN] = {SHAPES(supergauss1), SHAPES(supergauss2),
                                      SHAPES(supergauss3)},
    [CONSPH_KERNEL_LUCY] = SAME3(lucy),
    [CONSPH_KERNEL_WENDLAND_C2] = {SHAPES(wc2_1d), SHAPES(wc2), SHAPES(wc2)},
    [CONSPH_KERNEL_WENDLAND_C4] = {SHAPES(wc4_1d), SHAPES(wc4), SHAPES(wc4)},
    [CONSPH_KERNEL_WENDLAND_C6] = {SHAPES(wc6_1d), SHAPES(wc6), SHAPES(wc6)},
    [CONSPH_KERNEL_WENDLAND_C2_H] = SAME3(wc2h),
    [CONSPH_KERNEL_WENDLAND_C4_H] = SAME3(wc4h),
    [CONSPH_KERNEL_WENDLAND_C6_H] = SAME3(wc6h),
    [CONSPH_KERNEL_M4] = SAME3(m4),
};

/* Normalisations: the papers' (the 1D ones derived), each re-derived by quadrature in
 * tests/test_kernels.c. beta_001 is 001's edge smoothness, as the text after its eq. 3 defines it
 * (001's Table 1 disagrees with that text; docs/deviations.md). */
#define INV_SQRT_PI 0.56418958354775628 /* pi^(-1/2) */
#define INV_PI_3_2 0.17958712212516656  /* pi^(-3/2) */
static const consph_kernel_info info_table[CONSPH_KERNEL_COUNT] = {
    [CONSPH_KERNEL_CUBIC] = {.id = CONSPH_KERNEL_CUBIC,
                             .name = "cubic",
                             .description = "cubic B-spline; pairing and tensile instability (001)",
                             .source = "001 Table 1 (CS); Monaghan 1992",
                             .support = 2.0,
                             .beta_001 = 3,
                             .sigma = {2.0 / 3.0, 10.0 / (7.0 * PI), 1.0 / PI}},
    [CONSPH_KERNEL_QUINTIC] = {.id = CONSPH_KERNEL_QUINTIC,
                               .name = "quintic",
                               .description = "quintic spline; 001's kernel after its section 3 "
                                              "(h/ds = 1.2)",
                               .source = "001 Table 1 (QS)",
                               .support = 3.0,
                               .beta_001 = 5,
                               .sigma = {1.0 / 120.0, 7.0 / (478.0 * PI), 1.0 / (120.0 * PI)}},
    [CONSPH_KERNEL_GAUSSIAN] = {.id = CONSPH_KERNEL_GAUSSIAN,
                                .name = "gaussian",
                                .description = "Gaussian exp(-q^2) cut at q = 3 (integral short "
                                               "of 1 by 2e-5 to 4e-4)",
                                .source = "001 Table 1 (G)",
                                .support = 3.0,
                                .beta_001 = 0,
                                .sigma = {INV_SQRT_PI, 1.0 / PI, INV_PI_3_2}},
    [CONSPH_KERNEL_SUPER_GAUSSIAN] = {.id = CONSPH_KERNEL_SUPER_GAUSSIAN,
                                      .name = "super-gaussian",
                                      .description = "Monaghan super-Gaussian exp(-9q^2)(1 + d/2 "
                                                     "- 9q^2) cut at q = 1; negative near the "
                                                     "edge",
                                      .source = "003 eq. (60)",
                                      .support = 1.0,
                                      .beta_001 = 0,
                                      .sigma = {3.0 * INV_SQRT_PI, 9.0 / PI, 27.0 * INV_PI_3_2}},
    [CONSPH_KERNEL_LUCY] = {.id = CONSPH_KERNEL_LUCY,
                            .name = "lucy",
                            .description = "Lucy quartic (1-q)^3 (1+3q)",
                            .source = "003 eq. (59)",
                            .support = 1.0,
                            .beta_001 = 3,
                            .sigma = {1.25, 5.0 / PI, 105.0 / (16.0 * PI)}},
    [CONSPH_KERNEL_WENDLAND_C2] = {.id = CONSPH_KERNEL_WENDLAND_C2,
                                   .name = "wendland-c2",
                                   .description = "Wendland C2 (1-q/2)^4 (2q+1), support 2h; 1D: "
                                                  "PySPH (1-q/2)^3 (1.5q+1) with beta_001 = 3",
                                   .source = "001 Table 1 (WQ_2); PySPH WendlandQuintic",
                                   .support = 2.0,
                                   .beta_001 = 4,
                                   .sigma = {5.0 / 8.0, 7.0 / (4.0 * PI), 21.0 / (16.0 * PI)}},
    [CONSPH_KERNEL_WENDLAND_C4] = {.id = CONSPH_KERNEL_WENDLAND_C4,
                                   .name = "wendland-c4",
                                   .description = "Wendland C4 (1-q/2)^6 (35/12 q^2+3q+1), "
                                                  "support 2h; 1D: PySPH (1-q/2)^5 "
                                                  "(2q^2+2.5q+1) with beta_001 = 5",
                                   .source = "001 Table 1 (WQ_4); PySPH WendlandQuinticC4",
                                   .support = 2.0,
                                   .beta_001 = 6,
                                   .sigma = {0.75, 9.0 / (4.0 * PI), 495.0 / (256.0 * PI)}},
    [CONSPH_KERNEL_WENDLAND_C6] = {.id = CONSPH_KERNEL_WENDLAND_C6,
                                   .name = "wendland-c6",
                                   .description = "Wendland C6 (1-q/2)^8 (4q^3+25/4 q^2+4q+1), "
                                                  "support 2h; 1D: PySPH (1-q/2)^7 (21/8 q^3+19/4 "
                                                  "q^2+7/2 q+1) with beta_001 = 7",
                                   .source = "001 Table 1 (WQ_6); PySPH WendlandQuinticC6",
                                   .support = 2.0,
                                   .beta_001 = 8,
                                   .sigma = {55.0 / 64.0, 78.0 / (28.0 * PI),
                                             1365.0 / (512.0 * PI)}},
    [CONSPH_KERNEL_WENDLAND_C2_H] = {.id = CONSPH_KERNEL_WENDLAND_C2_H,
                                     .name = "wendland-c2:h",
                                     .description = "Wendland C2 (1-q)^4 (1+4q), support h",
                                     .source = "002 eq. (47); 003 eq. (61)",
                                     .support = 1.0,
                                     .beta_001 = 4,
                                     .sigma = {1.5, 7.0 / PI, 21.0 / (2.0 * PI)}},
    [CONSPH_KERNEL_WENDLAND_C4_H] = {.id = CONSPH_KERNEL_WENDLAND_C4_H,
                                     .name = "wendland-c4:h",
                                     .description = "Wendland C4 (1-q)^6 (1+6q+35/3 q^2), "
                                                    "support h",
                                     .source = "003 eq. (55); 000 eq. (58)",
                                     .support = 1.0,
                                     .beta_001 = 6,
                                     .sigma = {27.0 / 16.0, 9.0 / PI, 495.0 / (32.0 * PI)}},
    [CONSPH_KERNEL_WENDLAND_C6_H] = {.id = CONSPH_KERNEL_WENDLAND_C6_H,
                                     .name = "wendland-c6:h",
                                     .description = "Wendland C6 (1-q)^8 (1+8q+25q^2+32q^3), "
                                                    "support h",
                                     .source = "003 eq. (62)",
                                     .support = 1.0,
                                     .beta_001 = 8,
                                     .sigma = {15.0 / 8.0, 78.0 / (7.0 * PI),
                                               1365.0 / (64.0 * PI)}},
    /* 001 eq. 32 writes M4 as radial; we use the usual tensor product (docs/deviations.md). */
    [CONSPH_KERNEL_M4] = {.id = CONSPH_KERNEL_M4,
                          .name = "m4",
                          .description = "M4' interpolating remeshing kernel, tensor product "
                                         "prod_a M4(|dx_a|/h)/h^d with h = particle spacing",
                          .source = "001 eq. (32)",
                          .support = 2.0,
                          .beta_001 = 2,
                          .sigma = {1.0, 1.0, 1.0},
                          .tensor = 1},
};

const consph_kernel_info *consph_kernel_info_get(consph_kernel_id id)
{
    if ((int)id < 0 || id >= CONSPH_KERNEL_COUNT) {
        consph_fail(CONSPH_EINVAL, "kernel id %d out of range 0..%d", (int)id,
                    CONSPH_KERNEL_COUNT - 1);
        return NULL;
    }
    return &info_table[id];
}

/* Built from info_table on the first call; the critical section orders that write before any
 * caller's read. */
const char *consph_kernel_names(void)
{
    static char names[512];
#pragma omp critical(consph_kernel_names)
    if (!names[0]) {
        size_t len = 0;
        for (int k = 0; k < CONSPH_KERNEL_COUNT && len < sizeof names; ++k) {
            int w = snprintf(names + len, sizeof names - len, "%s%s", k ? ", " : "",
                             info_table[k].name);
            if (w < 0) break;
            len += (size_t)w;
        }
    }
    return names;
}

int consph_kernel_lookup(const char *name, consph_kernel_id *id)
{
    if (name)
        for (int k = 0; k < CONSPH_KERNEL_COUNT; ++k)
            if (strcmp(name, info_table[k].name) == 0) {
                if (id) *id = (consph_kernel_id)k;
                return CONSPH_OK;
            }
    return consph_fail(CONSPH_EINVAL, "unknown kernel '%s'; allowed: %s", name ? name : "(null)",
                       consph_kernel_names());
}

int consph_kernel_beta_001(consph_kernel_id id, int dim)
{
    const consph_kernel_info *info = consph_kernel_info_get(id);
    if (!info) return -1;
    if (dim == 1 && (id == CONSPH_KERNEL_WENDLAND_C2 || id == CONSPH_KERNEL_WENDLAND_C4 ||
                     id == CONSPH_KERNEL_WENDLAND_C6))
        return info->beta_001 - 1;
    return info->beta_001;
}

int consph_kernel_init(consph_kernel *k, consph_kernel_id id, int dim, double h)
{
    if (!k) return consph_fail(CONSPH_EINVAL, "kernel: NULL output");
    const consph_kernel_info *info = consph_kernel_info_get(id);
    if (!info) return CONSPH_EINVAL;
    if (dim < 1 || dim > CONSPH_MAX_DIM)
        return consph_fail(CONSPH_EINVAL, "kernel %s: dimension %d; allowed: 1, 2, 3", info->name,
                           dim);
    if (!(h > 0.0) || !isfinite(h))
        return consph_fail(CONSPH_EINVAL,
                           "kernel %s: smoothing length h = %g; must be finite "
                           "and > 0",
                           info->name, h);
    double inv_h = 1.0 / h;
    double norm = info->sigma[dim - 1];
    for (int a = 0; a < dim; ++a) norm *= inv_h;
    if (!isfinite(inv_h) || !isfinite(norm) || norm == 0.0 || !isfinite(info->support * h))
        return consph_fail(CONSPH_EINVAL,
                           "kernel %s: smoothing length h = %g makes sigma/h^%d unrepresentable",
                           info->name, h, dim);
    const shape_set *s = &shape_table[id][dim - 1];
    *k = (consph_kernel){.id = id,
                         .name = info->name,
                         .dim = dim,
                         .h = h,
                         .support = info->support,
                         .radius = info->support * h,
                         .norm = norm,
                         .inv_h = inv_h,
                         .f = s->f,
                         .df = s->df,
                         .d2f = s->d2f,
                         .tensor = info->tensor};
    return CONSPH_OK;
}

double consph_kernel_w_vec(const consph_kernel *k, const double *dx)
{
    if (k->tensor) {
        double w = k->norm;
        for (int a = 0; a < k->dim; ++a) {
            double q = fabs(dx[a]) * k->inv_h;
            if (!(q < k->support)) return 0.0;
            w *= k->f(q);
        }
        return w;
    }
    double r2 = 0.0;
    for (int a = 0; a < k->dim; ++a) r2 += dx[a] * dx[a];
    return consph_kernel_w(k, sqrt(r2));
}

/* The loops of consph_kernel_eval_batch for one shape triple; inlined with constant shape
 * functions, each loop is straight-line code that vectorises. Every value is computed and then
 * selected, so no lane branches on q. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
eval_batch(const consph_kernel *k, size_t m, const double *restrict r, double *restrict w,
           double *restrict dwr, double *restrict d2w, consph_shape_fn f, consph_shape_fn df,
           consph_shape_fn d2f)
{
    const double inv_h = k->inv_h, support = k->support, norm = k->norm;
    const double norm1 = norm * inv_h, norm2 = norm * inv_h * inv_h;
    if (w && dwr) {
        /* W and W'/r in one loop: the shape functions share their pieces ((3 - q)^4 of W' is
         * the start of (3 - q)^5 of W), computed once; each value is the loops' below */
        const double at_zero = norm2 * d2f(0.0);
        for (size_t p = 0; p < m; ++p) {
            double rp = r[p], q = rp * inv_h, v = norm * f(q);
            w[p] = q < support ? v : 0.0;
            double v1 = norm1 * df(q) / (rp > 0.0 ? rp : 1.0);
            dwr[p] = !(q < support) ? 0.0 : rp > 0.0 ? v1 : at_zero;
        }
        w = dwr = NULL;
    }
    if (w)
        for (size_t p = 0; p < m; ++p) {
            double q = r[p] * inv_h, v = norm * f(q);
            w[p] = q < support ? v : 0.0;
        }
    if (dwr) {
        const double at_zero = norm2 * d2f(0.0);
        for (size_t p = 0; p < m; ++p) {
            double rp = r[p], q = rp * inv_h;
            /* The division is done in every lane (by 1 at r = 0) and the result selected. */
            double v = norm1 * df(q) / (rp > 0.0 ? rp : 1.0);
            dwr[p] = !(q < support) ? 0.0 : rp > 0.0 ? v : at_zero;
        }
    }
    if (d2w)
        for (size_t p = 0; p < m; ++p) {
            double q = r[p] * inv_h, v = norm2 * d2f(q);
            d2w[p] = q < support ? v : 0.0;
        }
}

/* The batch loops are straight vector code, so wider vectors pay in proportion; a generic
 * x86-64 build also carries AVX2 and AVX-512F copies chosen at load time (the same operations in
 * the same order, hence the same values). AVX2 enables no FMA, so nothing can be contracted;
 * AVX-512F does, so its copy is made only in ISO C mode (__STRICT_ANSI__: the build's -std=c11),
 * where GCC contracts nothing (-ffp-contract=off; in GNU mode it fuses hundreds of products).
 * tests/test_fastpath.c compares the batch with the scalar functions bit for bit. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__GLIBC__) &&       \
    !defined(__AVX2__)
#if defined(__STRICT_ANSI__)
#define KERNEL_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define KERNEL_CLONES __attribute__((target_clones("avx2", "default")))
#endif
#else
#define KERNEL_CLONES
#endif

KERNEL_CLONES
void consph_kernel_eval_batch(const consph_kernel *k, size_t m, const double *r, double *w,
                              double *dwr, double *d2w)
{
    /* The shape triple is matched by address, so a kernel whose pointers were replaced by the
     * caller still gets its own functions (through the generic loop below). */
#define BATCH_CASE(P)                                                                              \
    if (k->f == P##_f && k->df == P##_df && k->d2f == P##_d2f) {                                   \
        eval_batch(k, m, r, w, dwr, d2w, P##_f, P##_df, P##_d2f);                                  \
        return;                                                                                    \
    }
    switch (k->id) {
    case CONSPH_KERNEL_CUBIC:
        BATCH_CASE(cubic);
        break;
    case CONSPH_KERNEL_QUINTIC:
        BATCH_CASE(quintic);
        break;
    case CONSPH_KERNEL_LUCY:
        BATCH_CASE(lucy);
        break;
    case CONSPH_KERNEL_WENDLAND_C2:
        BATCH_CASE(wc2);
        BATCH_CASE(wc2_1d);
        break;
    case CONSPH_KERNEL_WENDLAND_C4:
        BATCH_CASE(wc4);
        BATCH_CASE(wc4_1d);
        break;
    case CONSPH_KERNEL_WENDLAND_C6:
        BATCH_CASE(wc6);
        BATCH_CASE(wc6_1d);
        break;
    case CONSPH_KERNEL_WENDLAND_C2_H:
        BATCH_CASE(wc2h);
        break;
    case CONSPH_KERNEL_WENDLAND_C4_H:
        BATCH_CASE(wc4h);
        break;
    case CONSPH_KERNEL_WENDLAND_C6_H:
        BATCH_CASE(wc6h);
        break;
    case CONSPH_KERNEL_M4:
        BATCH_CASE(m4);
        break;
    default:
        /* Gaussians: exp() does not vectorise without -ffast-math; the calls dominate anyway. */
        break;
    }
#undef BATCH_CASE
    eval_batch(k, m, r, w, dwr, d2w, k->f, k->df, k->d2f);
}
