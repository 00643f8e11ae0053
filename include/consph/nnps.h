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

/* ---- inline traversal ----
 *
 * The same search without a neighbour buffer, for loops that want the pair body inlined into
 * the candidate loop. The structure exposes its sorted slots (a cell-ordered copy of the
 * positions and the slot -> particle map) and, per cell, the runs of candidate slots with their
 * periodic image shift. For particle i in slot s of cell c, the separation from the candidate in
 * slot t of a run of c is x_ij[a] = (x[a][s] - run.shift[a]) - x[a][t]; the candidates with
 * Σ_a x_ij[a]² < radius2 (summed from axis 0 up) are exactly the neighbours that
 * consph_nnps_query_particle returns for i, in the same order and with the same x_ij bit for bit
 * (r = sqrt of that sum). consph_nnps_scan_run below is that test. */

/* A run of consecutive sorted slots [s0, s1) that share one periodic image shift. */
typedef struct consph_nnps_run {
    size_t s0, s1;
    double shift[CONSPH_MAX_DIM]; /* 0 on unused axes */
} consph_nnps_run;

/* A cell's runs, in search order. Grows as needed; free with consph_nnps_runs_free. */
typedef struct consph_nnps_runs {
    size_t n, cap;
    consph_nnps_run *run;
    size_t candidates; /* Σ (s1 - s0) over the runs */
} consph_nnps_runs;

void consph_nnps_runs_free(consph_nnps_runs *runs);

/* A read-only view of the sorted slots, valid until the structure is rebuilt or freed. */
typedef struct consph_nnps_slots {
    int dim;
    size_t n;      /* slots, one per particle */
    size_t ncells; /* cells; cell c holds slots [cell_start[c], cell_start[c + 1]) */
    const size_t *cell_start;
    const double *x[CONSPH_MAX_DIM]; /* coordinate of each slot, wrapped on periodic axes;
                                        NULL past dim */
    const size_t *particle;          /* particle in each slot; NULL when slot s holds particle s
                                        (after consph_nnps_sort, or a build of a sorted set) */
    double radius2;                  /* a candidate is a neighbour when r² < radius2 */
} consph_nnps_slots;

/* Fills *v; CONSPH_EINVAL when the structure has not been built. */
int consph_nnps_slots_get(const consph_nnps *g, consph_nnps_slots *v);

/* The runs of candidate slots shared by every particle binned into cell c (a superset of what a
 * query of any of them walks, in the same order). Returns the number of runs, or (size_t)-1
 * with an error on allocation failure or a cell out of range. */
size_t consph_nnps_cell_runs(const consph_nnps *g, size_t c, consph_nnps_runs *out);

/* The runs that a query at the point x walks (pruned by the distance from x to each cell): fewer
 * candidates than the runs of x's cell, at the cost of a walk per point. x is wrapped into the
 * box on periodic axes like a query's; the candidates are seen from that wrapped point. Returns
 * the number of runs, or (size_t)-1 with an error. */
size_t consph_nnps_point_runs(const consph_nnps *g, const double *x, consph_nnps_runs *out);

/* Entries past the count that consph_nnps_gather may write (its vector paths store whole
 * blocks). */
#define CONSPH_NNPS_GATHER_SLACK 4

/* The neighbours of the point xi (slot coordinates, or a wrapped query point) among the
 * candidates of `runs`: writes their slots to slot[], and, where the arrays are non-NULL, their
 * x_ij to dx[a][] (a < dim) and their distance to r[]. Returns the count. The hits, their order
 * and their values are those of consph_nnps_scan_run over the runs followed by r = sqrt(r²), bit
 * for bit; the test runs on vectors (SSE2, or AVX2 or AVX-512 where the processor has it) and
 * only hits are kept, which makes it several times faster. Each array needs room for
 * runs->candidates + CONSPH_NNPS_GATHER_SLACK entries. */
size_t consph_nnps_gather(const consph_nnps_slots *v, const consph_nnps_runs *runs,
                          const double *xi, size_t *slot, double *const *dx, double *r);

static inline size_t consph_nnps_slot_particle(const consph_nnps_slots *v, size_t s)
{
    return v->particle ? v->particle[s] : s;
}

/* The hit test of one run, seen from the point xi (the gathering particle's slot coordinates):
 * appends the slot, x_ij (when dx is non-NULL) and r² of every candidate within the radius to
 * slot[n..], dx[a][n..] and r2[n..], and returns the new count. The arrays need room for
 * n + (s1 - s0) entries: every candidate is written, and the count advances only for hits, so the
 * loop has no branch on the hit. */
static inline size_t consph_nnps_scan_run(const consph_nnps_slots *v, const consph_nnps_run *run,
                                          const double *xi, size_t *slot, double *const *dx,
                                          double *r2, size_t n)
{
    const size_t s0 = run->s0, s1 = run->s1;
    const double r2max = v->radius2;
    const double *x0 = v->x[0], *x1 = v->x[1], *x2 = v->x[2];
    const double q0 = xi[0] - run->shift[0];
    if (v->dim == 1) {
        for (size_t s = s0; s < s1; ++s) {
            double d0 = q0 - x0[s];
            double rr = d0 * d0;
            slot[n] = s;
            if (dx) dx[0][n] = d0;
            r2[n] = rr;
            n += rr < r2max;
        }
        return n;
    }
    const double q1 = xi[1] - run->shift[1];
    if (v->dim == 2) {
        for (size_t s = s0; s < s1; ++s) {
            double d0 = q0 - x0[s], d1 = q1 - x1[s];
            double rr = d0 * d0 + d1 * d1;
            slot[n] = s;
            if (dx) {
                dx[0][n] = d0;
                dx[1][n] = d1;
            }
            r2[n] = rr;
            n += rr < r2max;
        }
        return n;
    }
    const double q2 = xi[2] - run->shift[2];
    for (size_t s = s0; s < s1; ++s) {
        double d0 = q0 - x0[s], d1 = q1 - x1[s], d2 = q2 - x2[s];
        double rr = d0 * d0 + d1 * d1 + d2 * d2;
        slot[n] = s;
        if (dx) {
            dx[0][n] = d0;
            dx[1][n] = d1;
            dx[2][n] = d2;
        }
        r2[n] = rr;
        n += rr < r2max;
    }
    return n;
}

/* Reference O(N^2) search with the same contract as consph_nnps_query, for tests. */
size_t consph_nnps_brute(const consph_particles *p, double radius, const double *x,
                         consph_nbrs *out);

#ifdef __cplusplus
}
#endif
#endif
