/* consph kernels: every smoothing kernel of the seed papers in 1D, 2D and 3D.
 *
 * Convention: q = r/h and W(r, h) = sigma_d / h^d * f(q), with support radius `support`·h.
 * dW/dr = sigma_d / h^(d+1) * f'(q), d2W/dr2 = sigma_d / h^(d+2) * f''(q).
 * The meaning of h differs between papers (docs/deviations.md): the Wendland kernels exist in both
 * conventions, support 2h (001/PySPH, names "wendland-cN") and support h (002/003, names
 * "wendland-cN:h"). */
#ifndef CONSPH_KERNELS_H
#define CONSPH_KERNELS_H

#include "consph/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum consph_kernel_id {
    CONSPH_KERNEL_CUBIC,
    CONSPH_KERNEL_QUINTIC,
    CONSPH_KERNEL_GAUSSIAN,
    CONSPH_KERNEL_SUPER_GAUSSIAN,
    CONSPH_KERNEL_LUCY,
    CONSPH_KERNEL_WENDLAND_C2,
    CONSPH_KERNEL_WENDLAND_C4,
    CONSPH_KERNEL_WENDLAND_C6,
    CONSPH_KERNEL_WENDLAND_C2_H,
    CONSPH_KERNEL_WENDLAND_C4_H,
    CONSPH_KERNEL_WENDLAND_C6_H,
    CONSPH_KERNEL_M4,
    CONSPH_KERNEL_COUNT
} consph_kernel_id;

/* Shape functions of q for one kernel in one dimension. */
typedef double (*consph_shape_fn)(double q);

/* A kernel bound to a dimension and a smoothing length: everything an operator needs. */
typedef struct consph_kernel {
    consph_kernel_id id;
    const char *name;
    int dim;
    double h;
    double support; /* support radius in units of h */
    double radius;  /* support * h */
    double norm;    /* sigma_d / h^d */
    double inv_h;
    consph_shape_fn f, df, d2f;
    int tensor; /* 1 for the tensor-product remeshing kernel M4: W = prod_a f(|x_a|/h)/h^d */
} consph_kernel;

/* Static description of a kernel, as `consph kernels` lists it. */
typedef struct consph_kernel_info {
    consph_kernel_id id;
    const char *name;
    const char *description;
    const char *source; /* paper and equation */
    double support;     /* in units of h */
    /* Edge smoothness: beta_001 is the order of the first non-vanishing derivative at the edge
     * of the support (001's definition); 002's definition is beta_001 - 1. */
    int beta_001;
    double sigma[CONSPH_MAX_DIM]; /* sigma_1, sigma_2, sigma_3; 0 where unsupported */
    int tensor;
} consph_kernel_info;

const consph_kernel_info *consph_kernel_info_get(consph_kernel_id id);
/* Looks a kernel up by its CLI name; CONSPH_EINVAL naming the allowed names when unknown. */
int consph_kernel_lookup(const char *name, consph_kernel_id *id);
/* A comma-separated list of every kernel name, for help and error messages. */
const char *consph_kernel_names(void);
/* beta_001 of kernel `id` in dimension `dim`. It equals info->beta_001 except for the support-2h
 * Wendland kernels in 1D, whose PySPH 1D polynomials end as (1-q/2)^3, ^5, ^7 (3, 5, 7 instead
 * of 4, 6, 8); -1 for an unknown id. */
int consph_kernel_beta_001(consph_kernel_id id, int dim);

/* Binds kernel `id` to dimension `dim` and smoothing length h > 0. */
int consph_kernel_init(consph_kernel *k, consph_kernel_id id, int dim, double h);

/* W, dW/dr and d2W/dr2 at distance r >= 0 (radial kernels). */
static inline double consph_kernel_w(const consph_kernel *k, double r)
{
    double q = r * k->inv_h;
    return q < k->support ? k->norm * k->f(q) : 0.0;
}
static inline double consph_kernel_dw(const consph_kernel *k, double r)
{
    double q = r * k->inv_h;
    return q < k->support ? k->norm * k->inv_h * k->df(q) : 0.0;
}
static inline double consph_kernel_d2w(const consph_kernel *k, double r)
{
    double q = r * k->inv_h;
    return q < k->support ? k->norm * k->inv_h * k->inv_h * k->d2f(q) : 0.0;
}
/* W, W'(r)/r and W''(r) at m distances r[p] >= 0 by the radial formula: the values of
 * consph_kernel_w, consph_kernel_dw(k, r)/r and consph_kernel_d2w bit for bit, except that at
 * r = 0 the middle one is its limit W''(0) (so that ∇W = (W'/r) x_ij is 0 there and the Hessian
 * (W'' - W'/r) e e + (W'/r) I stays continuous). Any output may be NULL; outputs must not overlap
 * r or each other. The library's shape functions are inlined into one loop per kernel, which
 * vectorises for the polynomial kernels: much cheaper per value than the function pointers. */
void consph_kernel_eval_batch(const consph_kernel *k, size_t m, const double *r, double *w,
                              double *dwr, double *d2w);
/* W of a separation vector, valid for radial and tensor-product kernels alike. */
double consph_kernel_w_vec(const consph_kernel *k, const double *dx);

/* Gradient ∇_i W(x_i - x_j) given x_ij = x_i - x_j and r = |x_ij| (zero at r = 0). */
static inline void consph_kernel_grad(const consph_kernel *k, const double *xij, double r,
                                      double *grad)
{
    double dw = r > 0.0 ? consph_kernel_dw(k, r) / r : 0.0;
    for (int a = 0; a < k->dim; ++a) grad[a] = dw * xij[a];
}

#ifdef __cplusplus
}
#endif
#endif
