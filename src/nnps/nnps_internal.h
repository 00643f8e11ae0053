/* Helpers shared by the cell search and the brute-force reference, so that both compute the
 * same wrapped coordinates and the same separations bit for bit. */
#ifndef CONSPH_NNPS_INTERNAL_H
#define CONSPH_NNPS_INTERNAL_H

#include "consph/nnps.h"

#include <math.h>
#include <stdint.h>

/* Maps a coordinate on a periodic axis into [lo, hi). Points already inside are returned
 * unchanged; the few that rounding pushes onto hi or below lo go to lo, which is the same
 * point modulo the period up to round-off. NaN stays NaN (it never becomes a neighbour). */
static inline double nnps_wrap(double x, double lo, double hi, double len)
{
    if (x >= lo && x < hi) return x;
    if (isnan(x)) return x;
    double w = x - floor((x - lo) / len) * len;
    if (!(w >= lo && w < hi)) w = lo;
    return w;
}

/* nnps_hit_permute[m]: the 32-bit lane indices that move the 64-bit lanes of the set bits of the
 * 4-bit mask m to the front (a permutevar8x32 compress), for the AVX2 hit tests of gather.c and
 * src/pass/nlist.c. */
extern const int32_t nnps_hit_permute[16][8];

/* Implementations of the hit test (gather.c); each gives the same result bit for bit. */
enum { NNPS_ISA_C, NNPS_ISA_SSE2, NNPS_ISA_AVX2, NNPS_ISA_AVX512 };
/* The fastest implementation this machine runs (each runs those below it too). */
int nnps_machine_isa(void);
/* The implementation consph_nnps_gather uses: nnps_machine_isa(), or the lower one that the
 * environment's CONSPH_GATHER_ISA (c, sse2, avx2, avx512) names. */
int nnps_best_isa(void);
/* consph_nnps_gather with a given implementation (one this machine runs; NNPS_ISA_C always
 * is) over nruns runs, appending from entry n; returns the new count. Exposed for tests. */
size_t nnps_gather_runs(int isa, const consph_nnps_slots *v, const consph_nnps_run *run,
                        size_t nruns, const double *xi, size_t *slot, double *const *dx, double *r,
                        size_t n);

/* consph_nnps_gather writing each neighbour's particle (consph_nnps_slot_particle of its slot)
 * into particle[] instead of its slot, with the same x_ij, r, order and room; slot[] (room for
 * the candidates and CONSPH_NNPS_GATHER_SLACK) is scratch where the implementation maps the
 * slots afterwards. The AVX-512 gather permutes the slots' particles with the hits' other
 * outputs: a load per block of eight candidates instead of a pass over the hits. */
size_t nnps_gather_particles(const consph_nnps_slots *v, const consph_nnps_runs *runs,
                             const double *xi, size_t *slot, size_t *particle, double *const *dx,
                             double *r);

/* The neighbourhoods of the four particles in slots sl..sl+3, which lie in one cell whose
 * candidate runs are run[0..nruns), in one sweep over the candidates: each block of candidates is
 * loaded once and tested against the four points. Lane l's slots, x_ij (where dx[l] is not NULL)
 * and r go to slot[l], dx[l] and r[l] from entry 0 and number n[l]; each lane's outputs are those
 * of consph_nnps_gather for its particle bit for bit, in its order, with the same room. Returns 0
 * (and writes nothing) where the chosen implementation (nnps_best_isa) has no such sweep: the
 * caller then gathers each particle. */
int nnps_gather4(const consph_nnps_slots *v, const consph_nnps_run *run, size_t nruns, size_t sl,
                 size_t *const slot[4], double *const *const dx[4], double *const r[4],
                 size_t n[4]);

/* Makes room for `need` neighbours; all CONSPH_MAX_DIM separation arrays are kept so that a
 * buffer can be reused across structures of different dimension. */
int nnps_nbrs_reserve(consph_nbrs *nb, size_t need);

/* The caller's word that the particles have not moved since the last build (nor been
 * reordered): the next consph_nnps_sort permutes by that build's order instead of binning them
 * again. Any build in between takes the word back. */
void nnps_build_is_current(consph_nnps *g);

/* The caller's word that every coordinate of the particles on a periodic axis lies in
 * [lo[a], hi[a]) (the solver wraps its positions after each move and checks them on the way):
 * the next build, and only that one, skips its own sweep looking for one outside, which would
 * be wrapped there. Taken only where lo and hi are the search box's; NULL takes it back. */
void nnps_positions_inside(consph_nnps *g, const double *lo, const double *hi);

/* For a search over part of a particle set (an MPI rank's particles and its halo, src/par): the
 * grid (cells per radius and cell counts) is chosen at every build as for n particles, the
 * whole set, so that it is the whole set's grid and cells are walked as in the serial run. */
void nnps_fix_grid(consph_nnps *g, size_t n);
/* The grid of the last build: cells per axis, cells a query walks each way, cell edges. */
void nnps_grid(const consph_nnps *g, int64_t nc[CONSPH_MAX_DIM], int64_t reach[CONSPH_MAX_DIM],
               double edge[CONSPH_MAX_DIM]);
/* The cell along axis a of coordinate x, as a build bins it (wrapped on a periodic axis). */
int64_t nnps_axis_cell(const consph_nnps *g, int a, double x);
/* out[k·stride] = nnps_axis_cell(g, a, x[idx[k]]) for k < n. */
void nnps_axis_cells(const consph_nnps *g, int a, const double *x, const size_t *idx, size_t n,
                     int64_t *out, size_t stride);

#endif
