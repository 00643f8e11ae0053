/* consph transport: Wasserstein distances between weighted particle measures
 * μ = Σ_a m_a δ(x − x_a), for the convergence test of 004 (Rendón et al. 2022) in the
 * Wasserstein metric. Masses are normalised to sum 1 (probability measures) before anything is
 * computed, so two resolutions of one body compare whatever their total masses.
 *
 * Three methods, each with its own error estimate:
 *  - exact W_p in 1D from the sorted cumulative distributions (any N, M and weights);
 *  - sliced W_p in any dimension: the mean of exact 1D W_p^p over K random directions (Monte Carlo
 *    standard error reported); it is a different metric from W_p (SW_p <= W_p), not an estimate
 *    of it;
 *  - entropically regularised transport (Sinkhorn in the log domain with ε-continuation), whose
 *    transport cost is reported with a bound on its distance from W_p^p. */
#ifndef CONSPH_TRANSPORT_H
#define CONSPH_TRANSPORT_H

#include <stddef.h>
#include <stdint.h>

#include "consph/core.h"
#include "consph/kernels.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A weighted point set. w may be NULL (equal weights); otherwise positive and finite. Weights
 * need not sum to 1: every function normalises them. Positions are structure of arrays as in
 * consph_particles: x[a][i] is coordinate a of point i. */
typedef struct consph_measure {
    int dim;
    size_t n;
    const double *x[CONSPH_MAX_DIM];
    const double *w;
} consph_measure;

/* Where the weights of consph_measure_from_particles came from. */
typedef enum consph_mass_origin {
    CONSPH_MASS_FIELD,      /* the particles' "mass" field (an `m` column) */
    CONSPH_MASS_VOLUME_RHO, /* volume × rho (fields "volume" and "rho") */
    CONSPH_MASS_EQUAL       /* neither: every particle weighs the same */
} consph_mass_origin;

/* A view of `p` as a measure (no copy: it points into p). Masses are the "mass" field, else
 * "volume" × "rho" (written into *scratch, which the caller frees; NULL when not needed), else
 * equal. */
int consph_measure_from_particles(const consph_particles *p, consph_measure *mu, double **scratch,
                                  consph_mass_origin *origin);
const char *consph_mass_origin_name(consph_mass_origin origin);

typedef enum consph_ot_method {
    CONSPH_OT_EXACT,   /* exact, 1D only */
    CONSPH_OT_SLICED,  /* sliced Wasserstein, any dimension */
    CONSPH_OT_SINKHORN /* entropic transport cost, any dimension, O(N·M) work per iteration */
} consph_ot_method;

typedef struct consph_ot_options {
    consph_ot_method method;
    int p;          /* 1 or 2: the ground cost |x − y|^p */
    int directions; /* sliced: K >= 1 random directions */
    uint64_t seed;  /* sliced: seed of the directions (consph_rng) */
    double eps;     /* sinkhorn: final ε relative to the largest cost C_max, in (0, 1] */
    double tol;     /* sinkhorn: stop when the L1 marginal violation is below tol */
    long max_iter;  /* sinkhorn: iteration cap over all ε stages */
    /* sinkhorn: called after every iteration (NULL: never), for a progress display, with the
     * iteration, the current absolute ε and the L1 marginal violation; it changes nothing. */
    void (*progress)(void *ctx, long iteration, double eps_abs, double marginal_error);
    void *progress_ctx;
} consph_ot_options;

/* The defaults: exact, p = 1, 64 directions, seed 1, eps 1e-3, tol 1e-6, 20000 iterations. */
consph_ot_options consph_ot_defaults(void);

/* The tuning parameters, each read by one method only. One given to a method that does not read
 * it would do nothing, so the CLI's options and the study files' keys are refused there. */
typedef enum consph_ot_param {
    CONSPH_OT_PARAM_DIRECTIONS,
    CONSPH_OT_PARAM_SEED,
    CONSPH_OT_PARAM_EPS,
    CONSPH_OT_PARAM_TOL,
    CONSPH_OT_PARAM_MAX_ITER
} consph_ot_param;
/* The method that reads `param`. */
consph_ot_method consph_ot_param_method(consph_ot_param param);
/* 1 when `method` in `dim` dimensions reads `param`: sliced draws no direction in 1D, where
 * every direction is +-1 and the sliced distance is the exact one. */
int consph_ot_param_read(consph_ot_method method, int dim, consph_ot_param param);

/* The bytes a computation may allocate: the cap (CONSPH_MEMORY_LIMIT=BYTES[K|M|G], else 4 GiB,
 * a figure that fits ordinary workstations) or the memory the machine has available now,
 * whichever is less, in *limit; *cap and *available (either may be NULL) get the two figures.
 * CONSPH_EINVAL, with the message, when CONSPH_MEMORY_LIMIT is set but not a size. */
int consph_memory_limit(double *limit, double *cap, double *available);

typedef struct consph_ot_result {
    double distance; /* W_p (exact), SW_p (sliced), or (⟨π_ε, C⟩)^(1/p) (sinkhorn) */
    /* The method's own error estimate on `distance`: 0 for exact (round-off only); for sliced
     * the Monte Carlo standard error of SW_p (delta method for p = 2); for sinkhorn a bound on
     * |distance − W_p| from the entropic bias ε·min(H(a), H(b)) and the marginal violation δ
     * (the rounding bound 2·δ·C_max), propagated through the p-th root. */
    double error;
    /* sinkhorn: the final L1 marginal violation δ, the final absolute ε, C_max, iterations, and
     * whether δ <= tol was reached within max_iter. */
    double marginal_error;
    double eps_abs;
    double cost_max;
    long iterations;
    int converged;
} consph_ot_result;

/* W between a and b (same dim). CONSPH_EINVAL for an empty measure, a dimension mismatch, a
 * non-positive or non-finite weight, a non-finite position, exact in 2D/3D, or an option out of
 * range; CONSPH_ENOMEM. Results do not depend on the number of threads. */
int consph_wasserstein(const consph_measure *a, const consph_measure *b,
                       const consph_ot_options *opt, consph_ot_result *res);

/* What a call will cost, estimated before it is made from the sizes alone: the bytes it
 * allocates at its peak, and rough seconds on `threads` threads from rates measured on 2 shared
 * cores (docs/wasserstein.md). For sinkhorn `seconds` is one iteration: how many it takes
 * depends on the data (up to max_iter). The point counts na, nb are doubles: a grid asked for
 * may hold more points than a size_t. */
typedef struct consph_ot_estimate {
    double bytes;
    double seconds;
} consph_ot_estimate;
consph_ot_estimate consph_wasserstein_estimate(const consph_ot_options *opt, int dim, double na,
                                               double nb, int threads);

/* Exact W_p^p between two 1D weighted point sets (weights normalised here). */
int consph_wasserstein_1d_pow(const double *xa, const double *wa, size_t na, const double *xb,
                              const double *wb, size_t nb, int p, double *wpp);

/* ---- Continuous densities on a grid --------------------------------------------------------- */

/* A measure on the cell centres of a regular grid of cells^dim cells over `box` (periodicity
 * ignored): positions and weights are allocated here (free with consph_grid_measure_free). Each
 * cell carries density(centre) × cell volume: the midpoint rule. Replacing each cell's uniform
 * mass by its centre moves no mass further than half the cell diagonal, so W_p between the
 * density and this measure is at most half the cell diagonal (plus the midpoint-rule error of the
 * weights). */
typedef struct consph_grid_measure {
    consph_measure mu;
    double *storage;
    double half_diagonal; /* the W_p bound of the discretisation, for reports */
} consph_grid_measure;

typedef double (*consph_density_fn)(const double *x, void *ctx);

/* density NULL: the uniform density. */
int consph_grid_measure_density(const consph_box *box, size_t cells, consph_density_fn density,
                                void *ctx, consph_grid_measure *g);
/* The SPH density Σ_b m_b W(x − x_b, h) of the measure mu (weights normalised to sum 1) at the
 * grid's cell centres, with the kernel k (k->dim == mu->dim); periodic axes of box are wrapped
 * with the minimum image. This is the kernel-smoothed measure of 004. */
int consph_grid_measure_sph(const consph_box *box, size_t cells, const consph_measure *mu,
                            const consph_kernel *k, consph_grid_measure *g);
/* As consph_grid_measure_sph, calling progress(ctx, cells done, cells) now and then (NULL:
 * never); the result is the same. */
int consph_grid_measure_sph_progress(const consph_box *box, size_t cells, const consph_measure *mu,
                                     const consph_kernel *k, consph_grid_measure *g,
                                     void (*progress)(void *ctx, double done, double total),
                                     void *ctx);
/* The cost of a grid of cells^dim cells: its bytes, and the seconds of filling it with the SPH
 * density of `particles` points (0: a density function, O(grid)). */
consph_ot_estimate consph_grid_measure_estimate(int dim, size_t cells, size_t particles,
                                                int threads);
void consph_grid_measure_free(consph_grid_measure *g);

#ifdef __cplusplus
}
#endif
#endif
