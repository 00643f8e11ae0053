/* consph heat: the transient heat-conduction test of Fatehi & Manzari (002 §6, Figs. 1-3),
 * a scalar solver on the pass layer.
 *
 * ∂T/∂t = α∇²T on the unit square, α = 1 by default. Particles sit on the vertices of an
 * nx × nx grid including the boundary, Δ = 1/(nx - 1) (002 does not say whether its n × n
 * particles include the walls, docs/deviations.md; the paper's "vertices of a square grid in
 * [0,1]×[0,1]", whose boundary nodes are where the Dirichlet values live; docs/heat.md). The
 * boundary particles carry the wall temperature and are sources only (the system's destination
 * mask): they appear among the neighbours of the interior particles and are never updated. There
 * are no ghost particles.
 *
 * Interior particles may be perturbed as 002 §6.2: x += ε κ Δ per coordinate, κ uniform in
 * [-0.25, 0.25] (the walls are not). Volumes ω = Δ² for every particle (002 §6 states
 * "constant and equal" volumes for the regular grid only).
 * Kernel Wendland C2 with support h = η Δ (`wendland-c2:h`, 002 eq. 47).
 *
 * The Laplacian is S3 (Brookshaw/Cleary, 002 eq. 13) or S4 (002 eqs. 40-41: the F4 gradient
 * and Fatehi-Manzari's B̂), the same terms consph_apply runs (src/ops/terms.h). Forward Euler
 * with Δt = c d_min²/α (c = 0.2, d_min the smallest particle distance), the last step shortened
 * to land on tf exactly.
 *
 * Walls: `sin` is 002's problem (T = sin πx on y = 1, 0 on the other walls, T = 0 at t = 0;
 * exact solution the series of 002 eq. 43); `linear` puts T = y on every wall and starts from
 * T = y, the steady state, which is then the exact solution at every time (S4 is exact on
 * quadratics, 002 eq. 40, so it must keep it to round-off).
 *
 * Errors (002 eqs. 44-46) over all N particles, walls included: L2 = sqrt(Σ e²/N),
 * L∞ = max |e|, EC = |Σ e|/N, e = T_exact - T. Sums use consph_sum, so results do not depend
 * on the thread count. */
#ifndef CONSPH_HEAT_H
#define CONSPH_HEAT_H

#include <stddef.h>
#include <stdio.h>

#include "consph/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum consph_heat_lap {
    CONSPH_HEAT_S3 = 0, /* "s3": Brookshaw/Cleary, 002 eq. 13 */
    CONSPH_HEAT_S4 = 1  /* "s4": Fatehi-Manzari, 002 eqs. 40-41 */
} consph_heat_lap;

typedef enum consph_heat_walls {
    CONSPH_HEAT_WALLS_SIN = 0,   /* "sin": 002's T = sin πx on y = 1, 0 elsewhere */
    CONSPH_HEAT_WALLS_LINEAR = 1 /* "linear": T = y on every wall, steady state T = y */
} consph_heat_walls;

typedef struct consph_heat_params {
    consph_heat_lap laplacian;
    consph_heat_walls walls;
    int nx;     /* particles per side, walls included (>= 4) */
    double eta; /* h/Δ (002: 1.5 ... 3.5) */
    double eps; /* perturbation ε of the interior particles (002: 0, 0.2, 0.4), in [0, 1] */
    unsigned long seed; /* of κ */
    double tf;          /* final time (002: 0.1) */
    long steps;         /* > 0: exactly this many steps of Δt instead of running to tf */
    double alpha;       /* diffusivity (1) */
    double courant;     /* Δt = courant · d_min²/α (002: 0.2) */
} consph_heat_params;

/* 002's values: S4, sin walls, nx 40, η 2, ε 0, seed 1, tf 0.1, α 1, courant 0.2. */
void consph_heat_params_default(consph_heat_params *prm);
/* CONSPH_EINVAL naming the CLI option and the allowed values when a parameter is out of range. */
int consph_heat_params_check(const consph_heat_params *prm);
/* Name lookups for "s3"/"s4" and "sin"/"linear" (CONSPH_EINVAL listing the names). */
int consph_heat_lap_lookup(const char *name, consph_heat_lap *lap);
int consph_heat_walls_lookup(const char *name, consph_heat_walls *walls);
const char *consph_heat_lap_name(consph_heat_lap lap);
const char *consph_heat_walls_name(consph_heat_walls walls);

/* The exact temperature at (x, y), time t. sin walls: 002 eq. 43, the sum over m stopped at the
 * first m whose term bound |2m/(π(m²+1))| e^{-β_m t} is below 1e-14 (at t <= 0: the initial
 * state, 0 inside and the wall values on the boundary). linear walls: y. *terms (may be NULL)
 * receives the number of series terms summed. */
double consph_heat_exact(consph_heat_walls walls, double alpha, double x, double y, double t,
                         int *terms);

/* What a run measured. */
typedef struct consph_heat_summary {
    char laplacian[4], walls[8];
    size_t n, n_interior;
    int nx;
    long steps;
    double t, dt, dt_last; /* the regular step and the last one */
    double delta, h, eta, eps, d_min;
    double l2, linf, ec;  /* 002 eqs. 44-46 at t */
    size_t fallbacks;     /* interior particles whose B or B̂ was rejected (S4) */
    double seconds;       /* wall time of the time steps (set-up excluded) */
    double setup_seconds; /* particles, search and (S4) the correction matrices */
    size_t pairs;         /* pair evaluations of the time steps */
} consph_heat_summary;

typedef struct consph_heat consph_heat;

/* Builds the particles, the search and (S4) the correction matrices; checks the parameters
 * first. */
int consph_heat_create(consph_heat **out, const consph_heat_params *prm);
void consph_heat_free(consph_heat *h);
/* One forward Euler step of the interior particles. A non-finite temperature stops with
 * CONSPH_ENUMERIC naming the step, the particle and its position. */
int consph_heat_step(consph_heat *h);
int consph_heat_done(const consph_heat *h);
long consph_heat_step_count(const consph_heat *h);
double consph_heat_time(const consph_heat *h);
/* The particles in the system's order, with the fields "T", "T_exact" (refreshed by
 * consph_heat_output_fields), "wall" (1 on the boundary) and "volume". */
const consph_particles *consph_heat_particles(const consph_heat *h);
int consph_heat_output_fields(consph_heat *h);
/* L2, L∞ and EC at the current time (any may be NULL). */
int consph_heat_errors(const consph_heat *h, double *l2, double *linf, double *ec);
int consph_heat_summary_get(const consph_heat *h, consph_heat_summary *sum);
void consph_heat_summary_json(FILE *fp, const consph_heat_summary *sum);

/* Runs to the end with the files of every run (include/consph/solver.h, consph_run_output):
 * snapshots snap_NNNNNN.vtu indexed by run.pvd (the first, every snapshot_every steps and the
 * last), log.csv (one row per step: step, t, dt, the mean temperature, and l2, linf, ec where a
 * snapshot was written, nan elsewhere) and summary.json. dir NULL: no files. *sum is filled
 * in every case. */
int consph_heat_run(consph_heat *h, const char *dir, long snapshot_every, consph_heat_summary *sum);

#ifdef __cplusplus
}
#endif
#endif
