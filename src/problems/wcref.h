/* A reference solution of the weakly-compressible equations that the SPH schemes discretise, on
 * a 2D box periodic in both axes (src/problems/wcref.c; docs/schemes.md, "The
 * weakly-compressible reference"):
 *
 *     ∂ρ/∂t = -∇·(ρu),   ∂u/∂t = -(u·∇)u - ∇p(ρ)/ρ + ν∇²u,
 *
 * p(ρ) the Tait (001 eq. 18) or linear (001 eq. 28) equation of state. Pseudo-spectral on an
 * n × n grid (n a power of two, 2/3-rule dealiased), Lawson's integrating-factor RK4 with the
 * linear acoustic operator taken exactly, so the step is bounded by the flow speed and ν, not
 * c_o. Internal to the library. */
#ifndef CONSPH_PROBLEMS_WCREF_H
#define CONSPH_PROBLEMS_WCREF_H

#include <stddef.h>

typedef struct wcref wcref;

typedef struct wcref_params {
    int n;                  /* grid points per axis: a power of two, 8 .. 1024 */
    double lo[2], len[2];   /* the box [lo, lo + len) */
    double c0, rho0, gamma; /* the EOS */
    int linear;             /* 1: p = c_o²(ρ - ρ_o); 0: Tait with γ */
    double nu;              /* kinematic viscosity */
    double dt;              /* the step (0: the rule of wcref.c from the initial speed) */
    int unshared;           /* 1: neither uses nor feeds the process-wide share (wcref.c) */
} wcref_params;

/* From grid values at x_ij = lo + (i, j) len/n (index i + n j): density and velocity. */
int wcref_create(wcref **out, const wcref_params *wp, const double *rho, const double *u,
                 const double *v);
void wcref_free(wcref *w);
/* Advances (or restarts from t = 0 and advances) so that the state is that of time t >= 0;
 * the last step is shortened to land on t. */
int wcref_advance(wcref *w, double t);
double wcref_time(const wcref *w);
double wcref_step(const wcref *w);
/* The state at x by its Fourier series (spectral interpolation): velocity u[0..1], density. */
void wcref_eval(const wcref *w, const double x[2], double u[2], double *rho);
/* wcref_eval at the n points (x[i], y[i]) into u[i], v[i] and rho[i], bit for bit, the factors
 * of each distinct coordinate taken once (the particles of a lattice share their rows and
 * columns); parallel: split the points among threads. CONSPH_ENOMEM on failure. */
int wcref_eval_many(const wcref *w, size_t n, const double *x, const double *y, double *u,
                    double *v, double *rho, int parallel);
/* p(ρ) of the reference's equation of state. */
double wcref_pressure(const wcref *w, double rho);

/* The share of wcref.c: references created from identical parameters and grid values (bit for
 * bit) share one trajectory, so the rows of a study that differ in resolution or scheme only
 * step it once. wcref_shared_hits counts the advances served from it (tests);
 * wcref_share_clear frees the trajectories no reference holds. */
unsigned long wcref_shared_hits(void);
void wcref_share_clear(void);

#endif
