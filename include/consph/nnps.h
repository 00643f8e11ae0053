/* consph nnps: cell-linked-list neighbour search over cell-sorted particles, 1D/2D/3D, periodic
 * in any subset of axes.
 *
 * Memory is O(N + cells) whatever the neighbour count: neighbours are found by walking cells on
 * the fly. A query fills a caller-owned buffer with one particle's neighbours (index, separation
 * x_ij = x_i - x_j including the periodic image shift, and distance) in a fixed order, so sums
 * over it are reproducible and independent of the number of threads. On periodic axes every
 * image within the radius is returned, also when the radius exceeds half the box (then the same
 * j can appear with several shifts, and i can see its own images). */
#ifndef CONSPH_NNPS_H
#define CONSPH_NNPS_H

#include "consph/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct consph_nnps consph_nnps;

/* One particle's neighbours. Grows as needed; free with consph_nbrs_free. */
typedef struct consph_nbrs {
    size_t n, cap;
    size_t *j;
    double *dx[CONSPH_MAX_DIM]; /* x_i - x_j, periodic shift applied */
    double *r;
} consph_nbrs;

void consph_nbrs_free(consph_nbrs *nb);

/* Creates a search structure for the box of `p` and a search radius > 0. `cells_per_radius`
 * (>= 1) sets the cell edge to radius/cells_per_radius; 0 picks a default. */
consph_nnps *consph_nnps_create(const consph_box *box, double radius, int cells_per_radius);
void consph_nnps_free(consph_nnps *g);

/* Bins the particles of `p`, keeping a pointer to it: `p` must outlive the structure and be
 * rebuilt after it moves. Positions on a periodic axis are expected in [lo, hi); positions on
 * a non-periodic axis may lie anywhere (they are clamped to the boundary cells). */
int consph_nnps_build(consph_nnps *g, const consph_particles *p);

/* Reorders `p` (positions and all fields) into cell order and rebuilds, so that neighbours are
 * close in memory. If `perm_out` is non-NULL it receives new[i] = old[perm_out[i]]. */
int consph_nnps_sort(consph_nnps *g, consph_particles *p, size_t *perm_out);

/* The neighbours j with |x - x_j| < radius of the point x (length dim), in a fixed order.
 * Returns the count, or (size_t)-1 with an error on allocation failure. */
size_t consph_nnps_query(const consph_nnps *g, const double *x, consph_nbrs *out);
/* The same for particle i of the particle set the structure was built from (includes i itself
 * at r = 0). */
size_t consph_nnps_query_particle(const consph_nnps *g, size_t i, consph_nbrs *out);

double consph_nnps_radius(const consph_nnps *g);
/* The cells per radius used by the last build. When 0 was asked for, each build picks it from
 * the mean neighbour count (coarser cells for few neighbours, finer for many). */
int consph_nnps_cells_per_radius(const consph_nnps *g);
/* Total cells and bytes held by the structure (for memory reports). */
size_t consph_nnps_cells(const consph_nnps *g);
size_t consph_nnps_bytes(const consph_nnps *g);

/* Reference O(N^2) search with the same contract as consph_nnps_query, for tests. */
size_t consph_nnps_brute(const consph_particles *p, double radius, const double *x,
                         consph_nbrs *out);

#ifdef __cplusplus
}
#endif
#endif
