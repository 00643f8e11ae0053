/* consph layout: particle arrangements in a box.
 *
 * lattice       the unperturbed periodic (UP) Cartesian arrangement, cell-centred:
 *               x = lo + (i + 1/2) Δs (001 §3's UP, cell-centred as in its first author's
 *               later tool).
 * random        lattice plus eps·Δs·κ per coordinate, κ uniform in [-0.25, 0.25] (002 §6.2).
 * quasi-random  a low-discrepancy Halton fill of the box (003 §6.2).
 * packed        the perturbed-periodic (PP) arrangement of 001: a perturbed lattice relaxed
 *               by the particle packing of [51] (Negi & Ramachandran 2021) as its authors'
 *               implementation runs it, with its stopping rule (the particles have stopped
 *               moving). With packing.walls = L > 0 it packs inside L frozen lattice layers
 *               around the box and returns the particles in the periodic box: the authors'
 *               packed files were made so (src/layout/packing.c).
 * packed-polished  the same start relaxed by that packing until it stalls, then by a damped
 *               descent of the density error until max|rho/rho0 - 1| < tol (consph's own).
 *
 * Every layout sets p->spacing = Δs (for quasi-random: (V/N)^(1/dim)) and adds the field
 * "volume" = box volume / N. */
#ifndef CONSPH_LAYOUT_H
#define CONSPH_LAYOUT_H

#include "consph/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum consph_layout_kind {
    CONSPH_LAYOUT_LATTICE,
    CONSPH_LAYOUT_RANDOM,
    CONSPH_LAYOUT_QUASI_RANDOM,
    CONSPH_LAYOUT_PACKED,
    CONSPH_LAYOUT_PACKED_POLISHED,
    CONSPH_LAYOUT_COUNT
} consph_layout_kind;

/* Parameters of the packing iteration. */
typedef struct consph_packing_params {
    const char *kernel; /* packed: the packing's kernel; packed-polished: the kernel of the
                           density target (default "quintic") */
    double hdx;         /* h / Δs (default 1.2) */
    double perturb;     /* initial perturbation amplitude in units of Δs (default 0.5) */
    int max_iter;       /* iteration cap (default 5000) */
    double tol;         /* packed-polished: stop once max |rho/rho0 - 1| < tol (default 1e-4) */
    double move_tol;    /* packed: stop once 100 max_i |u_i| Δt / h <= move_tol at a test
                           (every 50 steps, from the 11th test on; default 1e-2, [51]'s code) */
    int history_every;  /* record the density spread every this many iterations (0: never) */
    int walls;          /* packed: 0 (default) packs in the periodic box; L > 0 packs inside a
                           frozen container of L lattice layers around the box, as PySPH's
                           packing tool does for a bounded domain, and returns the particles in
                           the (periodic) box: the authors' packed files were made this way */
} consph_packing_params;

typedef struct consph_layout_params {
    consph_layout_kind kind;
    int dim;
    size_t nx[CONSPH_MAX_DIM]; /* particles per axis (lattice-based kinds); total N = prod nx */
    consph_box box;            /* box; periodic flags as the caller wants them */
    uint64_t seed;
    double eps; /* random: perturbation factor ε (002 uses 0.2 and 0.4) */
    consph_packing_params packing;
} consph_layout_params;

/* How the packing went: iterations run, final density spread, and a history. */
typedef struct consph_packing_report {
    int iterations;
    double rho_spread_initial; /* max_i |rho_i/rho0 - 1| before packing */
    double rho_spread_final;
    int nhistory;
    int *history_iter;
    double *history_spread;
    double seconds;
    int polish_start;  /* iteration at which the density-polishing stage began, -1 if never */
    int converged;     /* the stopping rule was met before max_iter */
    double move_final; /* packed: 100 max|u| Δt / h at the last test (NaN before the first) */
    int from_cache;    /* 1: read from the layout cache (seconds is then the original packing's) */
} consph_packing_report;

void consph_packing_report_free(consph_packing_report *r);

const char *consph_layout_name(consph_layout_kind kind);
int consph_layout_lookup(const char *name, consph_layout_kind *kind);
const char *consph_layout_names(void);
/* 1 when the kind draws random numbers (its seed acts: random, packed, packed-polished). */
int consph_layout_uses_seed(consph_layout_kind kind);
/* Those kinds' names, ", "-separated, into buf (truncated to size), for messages; returns buf. */
const char *consph_layout_seeded_names(char *buf, size_t size);

/* Default parameters: unit periodic box, seed 1, eps 0.2, packing defaults. */
consph_layout_params consph_layout_defaults(consph_layout_kind kind, int dim, size_t nx);

/* Generates the layout into `p` (initialised here). `report` may be NULL; it is filled only for
 * the packed kinds. */
int consph_layout_generate(const consph_layout_params *lp, consph_particles *p,
                           consph_packing_report *report);

/* 1 when the kind makes each particle from its index alone (lattice, random, quasi-random), so
 * that a part of the layout can be made without the rest. */
int consph_layout_by_index(consph_layout_kind kind);
/* The particles first, ..., first + count - 1 of the layout consph_layout_generate makes (the
 * same bits, "volume" that of the whole set), into `p` (initialised here): an MPI rank's share
 * of the set-up (src/par/par_solver.c). The random kind draws and drops the random numbers of
 * the particles before `first`. The packed kinds are read from a valid file of the layout cache
 * (consph_layout_cache_set; the whole file checked, the range kept), never packed: CONSPH_EINVAL
 * without one, and for a range beyond the set. */
int consph_layout_generate_range(const consph_layout_params *lp, size_t first, size_t count,
                                 consph_particles *p);

/* ---- the cache of packed layouts ----
 *
 * When a cache directory is set, consph_layout_generate keeps every packed and packed-polished
 * result there and reads it back for the same parameters instead of packing again (the other
 * kinds are cheaper to make than to read and are never cached). A file is named by a hash of its
 * key, holds the key in full and a CRC-32 of its content, and is used only when both match: a
 * corrupt, truncated or foreign file is ignored with one line on stderr, recomputed and
 * rewritten. The key is everything that decides the positions: kind, dim, nx, box and
 * periodicity, seed, kernel, hdx, perturb, max_iter, tol (packed-polished) or move_tol (packed),
 * CONSPH_LAYOUT_PACKING_VERSION, and the build's arithmetic (fused multiply-adds or not, byte
 * order). Writes go to a temporary file in the directory, renamed into place: concurrent
 * processes are safe. A directory that cannot be written warns once on stderr and the run goes
 * on without the cache. Off by default in the library; the CLI turns it on. Not thread-safe to
 * change while layouts are being generated. */

/* Bump whenever a change to the packing moves its positions: old cache files then miss. */
#define CONSPH_LAYOUT_PACKING_VERSION 2

/* Sets the cache directory (created when first written; copied), or turns the cache off with
 * NULL or "". */
int consph_layout_cache_set(const char *dir);
/* The directory in use, or NULL when the cache is off. */
const char *consph_layout_cache_get(void);
/* The key of lp as written in its file (text), and the file that holds it under the current
 * directory (CONSPH_EINVAL when the cache is off). */
int consph_layout_cache_key(const consph_layout_params *lp, char *key, size_t size);
int consph_layout_cache_path(const consph_layout_params *lp, char *path, size_t size);

/* Summary statistics of any particle set: minimum pair distance (periodic aware) and the spread
 * of the summation density max |rho_i/rho0 - 1| with the given kernel and h/Δs. */
typedef struct consph_layout_stats {
    size_t n;
    double min_spacing;
    double rho_spread;
    double rho_mean;
} consph_layout_stats;
int consph_layout_stats_compute(const consph_particles *p, const char *kernel, double hdx,
                                consph_layout_stats *st);

/* The geometry of a particle set in units of its spacing Δs (p->spacing, or (V/N)^(1/dim) when
 * 0), the quantities docs/reference-values.md lists for the authors' packed files: the
 * nearest-neighbour distance of every particle (periodic aware) and the distance of every particle
 * from the nearest node of the cell-centred lattice lo + (i + 1/2) Δs. */
typedef struct consph_layout_nn_stats {
    double nn_min, nn_mean, nn_max, nn_std; /* nearest-neighbour distance / Δs */
    double disp_mean, disp_max;             /* distance to the nearest lattice node / Δs */
} consph_layout_nn_stats;
int consph_layout_nn_stats_compute(const consph_particles *p, consph_layout_nn_stats *st);

#ifdef __cplusplus
}
#endif
#endif
