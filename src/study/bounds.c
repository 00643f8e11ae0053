#include <math.h>

#include "consph/kernels.h"
#include "consph/study.h"

/* Surface measure of the unit sphere, B_n = 2π^(n/2)/Γ(n/2) (003 eq. 39). */
static double unit_sphere_area(int n)
{
    return 2.0 * pow(M_PI, 0.5 * n) / tgamma(0.5 * n);
}

double consph_bound_kernel_factor(const char *kernel, int dim)
{
    consph_kernel_id id;
    consph_kernel k;
    if (dim < 1 || dim > 3 || consph_kernel_lookup(kernel, &id) != CONSPH_OK) return NAN;
    const consph_kernel_info *info = consph_kernel_info_get(id);
    /* 003's bounds assume support radius h (k = 1). */
    if (info->support != 1.0 || info->tensor) return NAN;
    if (consph_kernel_init(&k, id, dim, 1.0) != CONSPH_OK) return NAN;
    double a0 = consph_kernel_w(&k, 0.0); /* W_max h^n with h = 1 */
    /* (2/π)^n a0 B_n / n = A_W^(n) / π^n, so A_W^(n) = 2^n a0 B_n / n: 4πa0 (2D), 32πa0/3 (3D). */
    return pow(2.0, dim) * a0 * unit_sphere_area(dim) / dim;
}

double consph_bound_interpolation(double a_w, int dim, double nnbr, double h)
{
    /* 003 eq. 51 for f = Π sin(πx_a): ẽ^(l,n) = (nπ)^l/l!, e_r^(2,n) = n²π²/2, k = 1. */
    double n = dim, npi = n * M_PI;
    double poly = 1.0 + h * npi + h * h * npi * npi / 2.0;
    double particle = a_w * pow(1.0 + CONSPH_EULER_GAMMA, n) / (pow(M_PI, n) * nnbr) * poly;
    return particle + h * h * npi * npi / 2.0;
}

double consph_bound_delta(int dim, double nnbr, double h, double sigma)
{
    double g = 1.0 + CONSPH_EULER_GAMMA, r = h / sigma;
    if (dim == 2)
        return 36.0 * g * g / (M_PI * M_PI * nnbr) *
                   (1.0 + 2.0 * sqrt(2.0) * r / sqrt(M_E) + 4 * r * r) +
               4 * r * r;
    if (dim == 3)
        return 165.0 * g * g * g / (M_PI * M_PI * M_PI * nnbr) *
                   (1.0 + 3.0 * sqrt(2.0) * r + 9 * r * r) +
               9 * r * r;
    return NAN;
}

double consph_scaling_h(double n)
{
    return pow(n, -1.0 / 6.0);
}
double consph_scaling_nnbr(double n)
{
    return 2.81 * pow(n, 0.675);
}
