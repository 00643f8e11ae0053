/* Every smoothing kernel of the seed papers (catalogue §A1): shape functions f, f', f'' of
 * q = r/h per kernel and per dimension, their normalisations sigma_d and the name table.
 *
 * The shape functions are plain static functions of q so that consph_kernel_init can pick one
 * triple per (kernel, dimension) and the evaluation path carries no branch on the kernel. Each
 * returns 0 for q at or beyond its support, so a caller that forgets the cut still gets the
 * compactly supported kernel. */
#include "consph/kernels.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#define PI 3.14159265358979323846

/* ---- cubic spline, support 2 (001 Table 1 "CS"; formula from Monaghan 1992 / PySPH) ---- */
static double cubic_f(double q)
{
    if (q < 1.0) return 1.0 - q * q * (1.5 - 0.75 * q);
    if (q < 2.0) {
        double t = 2.0 - q;
        return 0.25 * t * t * t;
    }
    return 0.0;
}
static double cubic_df(double q)
{
    if (q < 1.0) return q * (-3.0 + 2.25 * q);
    if (q < 2.0) {
        double t = 2.0 - q;
        return -0.75 * t * t;
    }
    return 0.0;
}
static double cubic_d2f(double q)
{
    if (q < 1.0) return -3.0 + 4.5 * q;
    if (q < 2.0) return 1.5 * (2.0 - q);
    return 0.0;
}

/* ---- quintic spline, support 3 (001 Table 1 "QS") ---- */
static double pow5(double t)
{
    double t2 = t * t;
    return t2 * t2 * t;
}
static double pow4(double t)
{
    double t2 = t * t;
    return t2 * t2;
}
static double quintic_f(double q)
{
    if (q >= 3.0) return 0.0;
    double w = pow5(3.0 - q);
    if (q < 2.0) w -= 6.0 * pow5(2.0 - q);
    if (q < 1.0) w += 15.0 * pow5(1.0 - q);
    return w;
}
static double quintic_df(double q)
{
    if (q >= 3.0) return 0.0;
    double w = -5.0 * pow4(3.0 - q);
    if (q < 2.0) w += 30.0 * pow4(2.0 - q);
    if (q < 1.0) w -= 75.0 * pow4(1.0 - q);
    return w;
}
static double quintic_d2f(double q)
{
    if (q >= 3.0) return 0.0;
    double t3 = 3.0 - q, w = 20.0 * t3 * t3 * t3;
    if (q < 2.0) {
        double t2 = 2.0 - q;
        w -= 120.0 * t2 * t2 * t2;
    }
    if (q < 1.0) {
        double t1 = 1.0 - q;
        w += 300.0 * t1 * t1 * t1;
    }
    return w;
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
static double lucy_f(double q)
{
    if (q >= 1.0) return 0.0;
    double t = 1.0 - q;
    return t * t * t * (1.0 + 3.0 * q);
}
static double lucy_df(double q)
{
    if (q >= 1.0) return 0.0;
    double t = 1.0 - q;
    return -12.0 * q * t * t;
}
static double lucy_d2f(double q)
{
    if (q >= 1.0) return 0.0;
    return 12.0 * (1.0 - q) * (3.0 * q - 1.0);
}

/* ---- Wendland, support 2 (001 "WQ_2/4/6" = PySPH WendlandQuintic, ...C4, ...C6), t = 1 - q/2.
 * 2D and 3D share one polynomial; 1D uses PySPH's own 1D Wendland functions (psi_{1,k}), which
 * is also why their edge order in 1D is 3/5/7 rather than 4/6/8. ---- */
static double wc2_f(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return pow4(t) * (2.0 * q + 1.0);
}
static double wc2_df(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return -5.0 * q * t * t * t;
}
static double wc2_d2f(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return 5.0 * t * t * (2.0 * q - 1.0);
}
static double wc4_f(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q, t2 = t * t;
    return t2 * t2 * t2 * (1.0 + q * (3.0 + q * (35.0 / 12.0)));
}
static double wc4_df(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return -(14.0 / 3.0) * q * pow5(t) * (1.0 + 2.5 * q);
}
static double wc4_d2f(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return -(14.0 / 3.0) * pow4(t) * (1.0 + q * (2.0 - 8.75 * q));
}
static double wc6_f(double q)
{
    if (q >= 2.0) return 0.0;
    double t4 = pow4(1.0 - 0.5 * q);
    return t4 * t4 * (1.0 + q * (4.0 + q * (6.25 + 4.0 * q)));
}
static double wc6_df(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q, t3 = t * t * t;
    return -5.5 * q * t3 * pow4(t) * (1.0 + q * (3.5 + 4.0 * q));
}
static double wc6_d2f(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q, t2 = t * t;
    return -5.5 * t2 * t2 * t2 * (1.0 + q * (3.0 - q * (3.75 + 20.0 * q)));
}
static double wc2_1d_f(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return t * t * t * (1.5 * q + 1.0);
}
static double wc2_1d_df(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return -3.0 * q * t * t;
}
static double wc2_1d_d2f(double q)
{
    if (q >= 2.0) return 0.0;
    return 3.0 * (1.0 - 0.5 * q) * (1.5 * q - 1.0);
}
static double wc4_1d_f(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return pow5(t) * (1.0 + q * (2.5 + 2.0 * q));
}
static double wc4_1d_df(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return -3.5 * q * pow4(t) * (1.0 + 2.0 * q);
}
static double wc4_1d_d2f(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return -3.5 * t * t * t * (1.0 + q * (1.5 - 6.0 * q));
}
static double wc6_1d_f(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q, t3 = t * t * t;
    return t3 * pow4(t) * (1.0 + q * (3.5 + q * (4.75 + 2.625 * q)));
}
static double wc6_1d_df(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q, t2 = t * t;
    return -q * t2 * t2 * t2 * (4.5 + q * (13.5 + 13.125 * q));
}
static double wc6_1d_d2f(double q)
{
    if (q >= 2.0) return 0.0;
    double t = 1.0 - 0.5 * q;
    return -pow5(t) * (4.5 + q * (11.25 - q * (14.625 + 59.0625 * q)));
}

/* ---- Wendland, support 1 (002 eq. 47; 003 eqs. 55, 61, 62), t = 1 - q; same polynomial in
 * every dimension, the 1D constants are the catalogue's [I] values. ---- */
static double wc2h_f(double q)
{
    if (q >= 1.0) return 0.0;
    return pow4(1.0 - q) * (1.0 + 4.0 * q);
}
static double wc2h_df(double q)
{
    if (q >= 1.0) return 0.0;
    double t = 1.0 - q;
    return -20.0 * q * t * t * t;
}
static double wc2h_d2f(double q)
{
    if (q >= 1.0) return 0.0;
    double t = 1.0 - q;
    return 20.0 * t * t * (4.0 * q - 1.0);
}
static double wc4h_f(double q)
{
    if (q >= 1.0) return 0.0;
    double t = 1.0 - q, t2 = t * t;
    return t2 * t2 * t2 * (1.0 + q * (6.0 + q * (35.0 / 3.0)));
}
static double wc4h_df(double q)
{
    if (q >= 1.0) return 0.0;
    return -(56.0 / 3.0) * q * pow5(1.0 - q) * (1.0 + 5.0 * q);
}
static double wc4h_d2f(double q)
{
    if (q >= 1.0) return 0.0;
    return -(56.0 / 3.0) * pow4(1.0 - q) * (1.0 + q * (4.0 - 35.0 * q));
}
static double wc6h_f(double q)
{
    if (q >= 1.0) return 0.0;
    double t4 = pow4(1.0 - q);
    return t4 * t4 * (1.0 + q * (8.0 + q * (25.0 + 32.0 * q)));
}
static double wc6h_df(double q)
{
    if (q >= 1.0) return 0.0;
    double t = 1.0 - q, t3 = t * t * t;
    return -22.0 * q * t3 * pow4(t) * (1.0 + q * (7.0 + 16.0 * q));
}
static double wc6h_d2f(double q)
{
    if (q >= 1.0) return 0.0;
    double t = 1.0 - q, t2 = t * t;
    return -22.0 * t2 * t2 * t2 * (1.0 + q * (6.0 - q * (15.0 + 160.0 * q)));
}

/* ---- M4' remeshing kernel, support 2 (001 eq. 32); a 1D profile used as a tensor product ---- */
static double m4_f(double q)
{
    if (q < 1.0) return 1.0 - q * q * (2.5 - 1.5 * q);
    if (q < 2.0) {
        double t = 2.0 - q;
        return 0.5 * (1.0 - q) * t * t;
    }
    return 0.0;
}
static double m4_df(double q)
{
    if (q < 1.0) return q * (-5.0 + 4.5 * q);
    if (q < 2.0) return -0.5 * (2.0 - q) * (4.0 - 3.0 * q);
    return 0.0;
}
static double m4_d2f(double q)
{
    if (q < 1.0) return -5.0 + 9.0 * q;
    if (q < 2.0) return 5.0 - 3.0 * q;
    return 0.0;
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

/* Normalisations: catalogue §A1 (Z1), each re-derived by quadrature in tests/test_kernels.c.
 * beta_001 is 001's edge smoothness, as catalogue §A1.9 resolves it (001's Table 1 disagrees
 * with its own text). */
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
    /* 001 writes M4 as radial; the catalogue (§A1.7) decides for the usual tensor product. */
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

static const char kernel_names[] = "cubic, quintic, gaussian, super-gaussian, lucy, wendland-c2, "
                                   "wendland-c4, wendland-c6, wendland-c2:h, wendland-c4:h, "
                                   "wendland-c6:h, m4";

const consph_kernel_info *consph_kernel_info_get(consph_kernel_id id)
{
    if ((int)id < 0 || id >= CONSPH_KERNEL_COUNT) {
        consph_fail(CONSPH_EINVAL, "kernel id %d out of range 0..%d", (int)id,
                    CONSPH_KERNEL_COUNT - 1);
        return NULL;
    }
    return &info_table[id];
}

const char *consph_kernel_names(void)
{
    return kernel_names;
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
                       kernel_names);
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
