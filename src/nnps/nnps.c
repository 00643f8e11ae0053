/* Cell-linked lists over cell-sorted particles.
 *
 * The box is cut into nc[a] cells per axis of edge h[a] >= radius / cells_per_radius. A build
 * bins the particles with a stable counting sort (cell start offsets + a permutation) and keeps
 * a copy of the positions in cell order, so a query reads each cell as one contiguous run and a
 * row of adjacent cells as one run too. Memory is O(N + cells) whatever the neighbour count.
 *
 * Unused axes (a >= dim) are padded as one non-periodic cell, so one loop nest serves 1D-3D.
 *
 * A query visits the unwrapped cell indices u = c + o, |o| <= reach, in a fixed order (axis 2
 * outermost, axis 0 innermost, ascending); on a periodic axis u maps to cell u mod nc with the
 * image shift floor(u / nc) * L, so distinct u are distinct images and none is counted twice.
 * Rows and cells that cannot reach within the radius are skipped (the walk covers a sphere,
 * not a cube); this changes which cells are read, never the order of what is returned.
 *
 * The same walk from a whole cell gives the runs of candidate slots shared by its particles
 * (the inline traversal of nnps.h); the hit test over runs, shared with the query, is in
 * gather.c. */
#include "nnps_internal.h"
#include "core/particles_internal.h"

#include <float.h>
#include <stdint.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <stdlib.h>
#include <string.h>

#define NNPS_MAX_IMAGES_PER_AXIS 1.0e6
/* The default cells per radius grows with the mean neighbour count: finer cells waste fewer
 * distance evaluations on the corners of the walked region but cost more runs of cells per
 * query. Thresholds from timing every query with 1, 2 and 3 cells per radius (random
 * particles in the unit periodic box, 10^5 single-threaded at 20-3000 neighbours and 10^6 in
 * bench_nnps --sweep): in 2D 1 was fastest up to ~50 neighbours (tied with 2 at 50), 2 at
 * ~100, 3 from ~200 on (10% ahead of 2 at 1000); in 3D 1 up to ~100 (30% ahead of 2 at 50),
 * 2 at 200-400, 3 from 1000 on (5-8% ahead of 2). In 1D a query is one run of cells whatever
 * the count; 1, 2, 4 and 8 were within 20%, finer slightly faster. The solver's group visits
 * (four particles of a cell at a time) tip it further towards 1: at 2D Taylor-Green's ~41
 * neighbours, 2 made wcsph, tvf and E-C 14-46% slower (docs/pass.md, "Finer search cells"). */
static int default_cells_per_radius(int dim, double mean_neighbours)
{
    if (dim == 1) return 4;
    if (dim == 2) return mean_neighbours < 75.0 ? 1 : mean_neighbours < 150.0 ? 2 : 3;
    return mean_neighbours < 150.0 ? 1 : mean_neighbours < 700.0 ? 2 : 3;
}
/* The cell count is capped near this many cells per particle (plus a constant) so that a tiny
 * radius cannot make the structure huge; cells then grow and hold more particles. */
#define NNPS_CELLS_PER_PARTICLE 4.0
#define NNPS_CELLS_EXTRA 1024.0
/* Cells are made this much wider than radius / cells_per_radius, so that cells_per_radius
 * cells still span the radius plus the rounding slack below. */
#define NNPS_CELL_WIDEN 1.0e-9
/* Builds parallelise the per-particle loops above this size. */
#define NNPS_PARALLEL_MIN 20000
/* A build on the threads (build_threads) from this size on: one parallel region, its fork and
 * three barriers, costs less than a thread's share of the sweeps from a few thousand particles. */
#define NNPS_BUILD_THREADS_MIN 4096

struct consph_nnps {
    consph_box box;
    int dim;
    int cells_per_radius_asked; /* 0: choose at each build from the mean neighbour count */
    int cells_per_radius;       /* in use since the last build */
    double radius, radius2;
    /* Grid, padded to three axes. slack[a] bounds how far rounding can put a particle outside
     * the cell it was binned into; geometric pruning widens cells by it. */
    int64_t nc[CONSPH_MAX_DIM];
    int64_t reach[CONSPH_MAX_DIM];
    int periodic[CONSPH_MAX_DIM];
    double lo[CONSPH_MAX_DIM], hi[CONSPH_MAX_DIM], len[CONSPH_MAX_DIM];
    double h[CONSPH_MAX_DIM], inv_h[CONSPH_MAX_DIM], slack[CONSPH_MAX_DIM];
    double slack_max;
    size_t ncells;
    /* cell_start[c] .. cell_start[c+1] are the sorted slots of cell c. */
    size_t *cell_start;
    size_t cell_start_cap;
    /* order[s] = particle in sorted slot s; xs[a][s] its (wrapped) coordinate. */
    size_t *order;
    size_t *cell_of; /* build work: cell of each particle, in particle order */
    double *xs[CONSPH_MAX_DIM];
    size_t particle_cap;
    size_t n;
    int identity; /* order[s] == s for every slot: the set is in cell order */
    const consph_particles *p;
    size_t grid_n; /* nnps_fix_grid: the grid is chosen for this many particles, not n */
    int current;   /* nnps_build_is_current: the next sort may use this build as it is */
    int inside;    /* nnps_positions_inside: the next build's coordinates on the periodic axes
                    * are known to lie in [lo, hi) */
    /* build_threads' scratch: each thread's count, then slot, per cell (threads x ncells), and
     * two words per thread */
    size_t *tcount;
    size_t tcount_cap;
    particles_permute_buf permute; /* consph_nnps_sort's, kept between re-sorts */
};

consph_nnps *consph_nnps_create(const consph_box *box, double radius, int cells_per_radius)
{
    if (!box) {
        consph_fail(CONSPH_EINVAL, "neighbour search needs a box");
        return NULL;
    }
    if (consph_box_check(box)) return NULL;
    if (!(radius > 0.0) || !isfinite(radius)) {
        consph_fail(CONSPH_EINVAL, "search radius must be finite and > 0, got %g", radius);
        return NULL;
    }
    if (cells_per_radius < 0 || cells_per_radius > 16) {
        consph_fail(CONSPH_EINVAL, "cells per radius must be 0 (default) or 1..16, got %d",
                    cells_per_radius);
        return NULL;
    }
    for (int a = 0; a < box->dim; ++a) {
        if (box->periodic[a] && radius > NNPS_MAX_IMAGES_PER_AXIS * consph_box_length(box, a)) {
            consph_fail(CONSPH_EINVAL,
                        "search radius %g exceeds %g lengths of periodic axis %d of the box",
                        radius, NNPS_MAX_IMAGES_PER_AXIS, a);
            return NULL;
        }
    }
    consph_nnps *g = consph_calloc(1, sizeof *g);
    if (!g) return NULL;
    g->box = *box;
    g->dim = box->dim;
    g->cells_per_radius_asked = cells_per_radius;
    g->cells_per_radius = cells_per_radius ? cells_per_radius : 1;
    g->radius = radius;
    g->radius2 = radius * radius;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        g->nc[a] = 1;
        g->len[a] = g->h[a] = g->inv_h[a] = 1.0;
    }
    for (int a = 0; a < g->dim; ++a) {
        g->periodic[a] = box->periodic[a] != 0;
        g->lo[a] = box->lo[a];
        g->hi[a] = box->hi[a];
        g->len[a] = box->hi[a] - box->lo[a];
        /* Rounding in binning and in lo + u*h is a few ulps of the largest coordinate met,
         * which is at most max(|lo|, |hi|) + L + R for unwrapped image coordinates. */
        g->slack[a] =
            64.0 * DBL_EPSILON * (fmax(fabs(box->lo[a]), fabs(box->hi[a])) + g->len[a] + radius);
        if (g->slack[a] > g->slack_max) g->slack_max = g->slack[a];
    }
    return g;
}

void consph_nnps_free(consph_nnps *g)
{
    if (!g) return;
    free(g->cell_start);
    free(g->order);
    free(g->cell_of);
    free(g->tcount);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(g->xs[a]);
    particles_permute_buf_free(&g->permute);
    free(g);
}

double consph_nnps_radius(const consph_nnps *g)
{
    return g->radius;
}

int consph_nnps_cells_per_radius(const consph_nnps *g)
{
    return g->cells_per_radius;
}

size_t consph_nnps_cells(const consph_nnps *g)
{
    return g->ncells;
}

size_t consph_nnps_bytes(const consph_nnps *g)
{
    size_t per_particle = 2 * sizeof(size_t) + (size_t)g->dim * sizeof(double);
    size_t padding =
        g->particle_cap ? (size_t)g->dim * CONSPH_NNPS_GATHER_SLACK * sizeof(double) : 0;
    return sizeof *g + (g->cell_start_cap + g->tcount_cap) * sizeof(size_t) +
           g->particle_cap * per_particle + padding;
}

/* Picks the cell counts for n particles: edge >= radius / cells_per_radius, total capped. */
static void setup_grid(consph_nnps *g, size_t n)
{
    if (g->grid_n) n = g->grid_n;
    double v[CONSPH_MAX_DIM] = {1.0, 1.0, 1.0};
    if (g->cells_per_radius_asked == 0) {
        const double pi = 3.14159265358979323846;
        const double unit_ball[CONSPH_MAX_DIM + 1] = {0.0, 2.0, pi, 4.0 * pi / 3.0};
        double volume = 1.0;
        for (int a = 0; a < g->dim; ++a) volume *= g->len[a];
        double mean = (double)n * unit_ball[g->dim] * pow(g->radius, g->dim) / volume;
        g->cells_per_radius = default_cells_per_radius(g->dim, mean);
    }
    for (int a = 0; a < g->dim; ++a) {
        double want = floor(g->len[a] * g->cells_per_radius / g->radius * (1.0 - NNPS_CELL_WIDEN));
        v[a] = fmin(fmax(want, 1.0), 1073741824.0); /* 2^30: exact and far from overflow */
    }
    const double max_cells = NNPS_CELLS_PER_PARTICLE * (double)n + NNPS_CELLS_EXTRA;
    double total = v[0] * v[1] * v[2];
    if (total > max_cells) {
        double f = pow(max_cells / total, 1.0 / g->dim);
        for (int a = 0; a < g->dim; ++a) v[a] = fmax(1.0, floor(v[a] * f));
    }
    /* Flooring at 1 can leave the product above the cap; halve the longest axis until not. */
    while (v[0] * v[1] * v[2] > max_cells) {
        int big = 0;
        for (int a = 1; a < g->dim; ++a)
            if (v[a] > v[big]) big = a;
        v[big] = ceil(v[big] / 2.0);
    }
    g->ncells = 1;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        g->nc[a] = (int64_t)v[a];
        g->ncells *= (size_t)g->nc[a];
        if (a >= g->dim) {
            g->reach[a] = 0;
            continue;
        }
        g->h[a] = g->len[a] / v[a];
        g->inv_h[a] = v[a] / g->len[a];
        /* Cells to walk so that every point within radius (plus the slack on both particles)
         * is covered; at most the box on a non-periodic axis, any number of periods on a
         * periodic one (bounded at create). */
        double k = ceil((g->radius + 2.0 * g->slack[a]) / g->h[a]);
        if (!g->periodic[a]) k = fmin(k, v[a] - 1.0);
        g->reach[a] = (int64_t)k;
    }
}

/* The cell of v = (x - lo)/h along an axis of nc cells, clamped into the grid. */
static inline int64_t cell_clamp(double v, int64_t nc)
{
    if (!(v >= 0.0)) return 0;
    if (v >= (double)nc) return nc - 1;
    return (int64_t)v;
}

/* Cell of a (wrapped, on periodic axes) coordinate along axis a, clamped into the grid. */
static inline int64_t cell_index(const consph_nnps *g, int a, double x)
{
    return cell_clamp((x - g->lo[a]) * g->inv_h[a], g->nc[a]);
}

static inline double stored_coord(const consph_nnps *g, int a, double x)
{
    return g->periodic[a] ? nnps_wrap(x, g->lo[a], g->hi[a], g->len[a]) : x;
}

static int grow(void **ptr, size_t count, size_t size)
{
    if (count > SIZE_MAX / size)
        return consph_fail(CONSPH_ENOMEM, "neighbour search arrays of %zu entries are too large",
                           count);
    void *q = realloc(*ptr, count * size);
    if (!q)
        return consph_fail(CONSPH_ENOMEM, "out of memory for the neighbour search (%zu entries)",
                           count);
    *ptr = q;
    return CONSPH_OK;
}

static int reserve_arrays(consph_nnps *g, size_t n)
{
    if (g->ncells + 1 > g->cell_start_cap) {
        if (grow((void **)&g->cell_start, g->ncells + 1, sizeof(size_t))) return CONSPH_ENOMEM;
        g->cell_start_cap = g->ncells + 1;
    }
    if (n > g->particle_cap) {
        if (grow((void **)&g->order, n, sizeof(size_t))) return CONSPH_ENOMEM;
        if (grow((void **)&g->cell_of, n, sizeof(size_t))) return CONSPH_ENOMEM;
        for (int a = 0; a < g->dim; ++a)
            if (grow((void **)&g->xs[a], n + CONSPH_NNPS_GATHER_SLACK, sizeof(double)))
                return CONSPH_ENOMEM;
        g->particle_cap = n;
    }
    return CONSPH_OK;
}

/* The counting sort's two sweeps over particles [i0, i1) with cells cell_of: count[c] += the
 * particles of cell c; then each takes the next slot of its cell, slot[c]++ (order[slot] = i),
 * and the return is 1 when every particle kept its own slot. Particles nearly in cell order come
 * in runs of one cell, each counted and given its slots in a register: the counts, slots and
 * order of one particle at a time, without each increment waiting on the last one's store. */
static void count_cells(const size_t *restrict cell_of, size_t i0, size_t i1, size_t *count)
{
    for (size_t i = i0; i < i1;) {
        const size_t c = cell_of[i];
        size_t j = i + 1;
        while (j < i1 && cell_of[j] == c) ++j;
        count[c] += j - i;
        i = j;
    }
}

static int scatter_cells(const size_t *restrict cell_of, size_t i0, size_t i1, size_t *slot,
                         size_t *restrict order)
{
    int identity = 1;
    for (size_t i = i0; i < i1;) {
        const size_t c = cell_of[i];
        size_t sl = slot[c];
        identity = identity && sl == i;
        do order[sl++] = i++;
        while (i < i1 && cell_of[i] == c);
        slot[c] = sl;
    }
    return identity;
}

/* scatter_cells in 2D with the coordinates as they are (none to wrap): xs[slot] = x[i] as each
 * particle takes its slot, instead of a sweep of the order after it. */
static int scatter_cells_xs(const size_t *restrict cell_of, size_t n, size_t *slot,
                            size_t *restrict order, const double *restrict x0,
                            const double *restrict x1, double *restrict xs0, double *restrict xs1)
{
    int identity = 1;
    for (size_t i = 0; i < n;) {
        const size_t c = cell_of[i];
        size_t sl = slot[c];
        identity = identity && sl == i;
        do {
            xs0[sl] = x0[i];
            xs1[sl] = x1[i];
            order[sl++] = i++;
        } while (i < n && cell_of[i] == c);
        slot[c] = sl;
    }
    return identity;
}

/* The cell of every particle, c = (c2 nc1 + c1) nc0 + c0. */
static void bin_cells(const consph_nnps *g, const consph_particles *p, size_t *cell_of, size_t n)
{
    const int dim = g->dim;
#pragma omp parallel for schedule(static) if (n > NNPS_PARALLEL_MIN)
    for (size_t i = 0; i < n; ++i) {
        size_t c = 0;
        for (int a = dim - 1; a >= 0; --a)
            c = c * (size_t)g->nc[a] + (size_t)cell_index(g, a, stored_coord(g, a, p->x[a][i]));
        cell_of[i] = c;
    }
}

/* The binning loop's copies chosen at load time in a generic x86-64 build, as LANE4_CLONES
 * (src/pass/lanes4.h): with AVX-512 the conversion to a 64-bit cell index vectorises, which
 * SSE2 and AVX2 have no instruction for. A conversion and a product of two values give the same
 * bits at any width, and there is no sum for FMA to contract. */
#if defined(__x86_64__) && !defined(__clang__) && defined(__GLIBC__) && !defined(__AVX2__) &&      \
    defined(__STRICT_ANSI__) && __GNUC__ >= 11
#define NNPS_BIN_CLONES __attribute__((target_clones("arch=x86-64-v4", "default")))
#else
#define NNPS_BIN_CLONES
#endif

/* The cells of particles [i0, i1) whose coordinates are known to be in the box (bin_cells_2d's
 * loop without the wrap). */
NNPS_BIN_CLONES static void bin_inside_2d(const double *restrict x0, const double *restrict x1,
                                          size_t *restrict cell_of, size_t i0, size_t i1,
                                          const double lo[2], const double ih[2],
                                          const int64_t nc[2])
{
    const double lo0 = lo[0], lo1 = lo[1], ih0 = ih[0], ih1 = ih[1];
    const int64_t nc0 = nc[0], nc1 = nc[1];
    const double top0 = (double)nc0, top1 = (double)nc1;
    for (size_t i = i0; i < i1; ++i) {
        const double v0 = (x0[i] - lo0) * ih0, v1 = (x1[i] - lo1) * ih1;
        const int64_t c0 = !(v0 >= 0.0) ? 0 : v0 >= top0 ? nc0 - 1 : (int64_t)v0;
        const int64_t c1 = !(v1 >= 0.0) ? 0 : v1 >= top1 ? nc1 - 1 : (int64_t)v1;
        cell_of[i] = (size_t)c1 * (size_t)nc0 + (size_t)c0;
    }
}

/* Particles per call of bin_inside_2d, shared out among the threads. */
#define NNPS_BIN_BLOCK 4096

/* bin_cells in 2D, the grid's constants held in locals (1: every coordinate was inside the
 * box on its periodic axes): the stores to cell_of (size_t) may alias
 * the grid's int64_t members, which the general loop would otherwise read again per particle.
 * The same operations as cell_index and stored_coord, hence the same cells. */
static int bin_cells_2d(const consph_nnps *g, const double *x0, const double *x1,
                        size_t *restrict cell_of, size_t n, int par)
{
    (void)par; /* read by the OpenMP if alone */
    const double lo0 = g->lo[0], hi0 = g->hi[0], len0 = g->len[0], ih0 = g->inv_h[0];
    const double lo1 = g->lo[1], hi1 = g->hi[1], len1 = g->len[1], ih1 = g->inv_h[1];
    const int per0 = g->periodic[0], per1 = g->periodic[1];
    const int64_t nc0 = g->nc[0], nc1 = g->nc[1];
    const double top0 = (double)nc0, top1 = (double)nc1;
    /* nnps_wrap returns a coordinate inside [lo, hi) as it is: when every one is (the solver
     * wraps its positions), the loop needs neither its test nor its call */
    int outside = 0;
    if ((per0 || per1) && !g->inside) {
        /* in bitwise form (a NaN is outside), so that it vectorises */
#pragma omp simd reduction(| : outside)
        for (size_t i = 0; i < n; ++i)
            outside |= (per0 & ((int)!(x0[i] >= lo0) | (int)!(x0[i] < hi0))) |
                       (per1 & ((int)!(x1[i] >= lo1) | (int)!(x1[i] < hi1)));
    }
    if (!outside) {
        const double lo[2] = {lo0, lo1}, ih[2] = {ih0, ih1};
        const int64_t nc[2] = {nc0, nc1};
        const size_t nb = (n + NNPS_BIN_BLOCK - 1) / NNPS_BIN_BLOCK;
#pragma omp parallel for schedule(static) if (par && n > NNPS_PARALLEL_MIN)
        for (size_t b = 0; b < nb; ++b)
            bin_inside_2d(x0, x1, cell_of, b * NNPS_BIN_BLOCK,
                          b + 1 < nb ? (b + 1) * NNPS_BIN_BLOCK : n, lo, ih, nc);
        return 1;
    }
#pragma omp parallel for schedule(static) if (par && n > NNPS_PARALLEL_MIN)
    for (size_t i = 0; i < n; ++i) {
        const double y0 = per0 ? nnps_wrap(x0[i], lo0, hi0, len0) : x0[i];
        const double y1 = per1 ? nnps_wrap(x1[i], lo1, hi1, len1) : x1[i];
        const double v0 = (y0 - lo0) * ih0, v1 = (y1 - lo1) * ih1;
        const int64_t c0 = !(v0 >= 0.0) ? 0 : v0 >= top0 ? nc0 - 1 : (int64_t)v0;
        const int64_t c1 = !(v1 >= 0.0) ? 0 : v1 >= top1 ? nc1 - 1 : (int64_t)v1;
        cell_of[i] = (size_t)c1 * (size_t)nc0 + (size_t)c0;
    }
    return 0;
}

/* xs[s] = the stored coordinate along axis a of particle order[s]; inside: every coordinate is
 * known to be inside the box, where nnps_wrap keeps it as it is. */
static void gather_coords(const consph_nnps *g, int a, const double *x, const size_t *order,
                          double *restrict xs, size_t n, int inside)
{
    const double lo = g->lo[a], hi = g->hi[a], len = g->len[a];
    if (g->periodic[a] && !inside) {
#pragma omp parallel for schedule(static) if (n > NNPS_PARALLEL_MIN)
        for (size_t s = 0; s < n; ++s) xs[s] = nnps_wrap(x[order[s]], lo, hi, len);
    } else {
#pragma omp parallel for schedule(static) if (n > NNPS_PARALLEL_MIN)
        for (size_t s = 0; s < n; ++s) xs[s] = x[order[s]];
    }
}

#ifdef _OPENMP
/* The cells of particles [i0, i1), as bin_cells and bin_cells_2d give them; 1 when every
 * coordinate on a periodic axis was inside the box (nnps_wrap would keep each as it is). */
static int bin_range(const consph_nnps *g, const consph_particles *p, size_t *restrict cell_of,
                     size_t i0, size_t i1)
{
    const int dim = g->dim;
    int outside = 0;
    for (size_t i = i0; i < i1; ++i) {
        size_t c = 0;
        for (int a = dim - 1; a >= 0; --a) {
            const double x = p->x[a][i];
            outside |= g->periodic[a] & ((int)!(x >= g->lo[a]) | (int)!(x < g->hi[a]));
            c = c * (size_t)g->nc[a] + (size_t)cell_index(g, a, stored_coord(g, a, x));
        }
        cell_of[i] = c;
    }
    return !outside;
}
#endif

/* The build on the threads, in one parallel region: the same cells, slot order, cell starts and
 * coordinates as the serial build, for any thread count. The stable counting sort is split as
 * particles [i0, i1) per thread: each thread counts its particles per cell; cell c's slots go to
 * the threads' particles in thread order (so in particle order, as the serial sort), from
 * start[c], each thread's first slot in c being start[c] plus the counts of the threads before
 * it; then each thread scatters its own particles. Returns 0 when the per-thread counts would
 * not fit (the caller builds serially). */
static int build_threads(consph_nnps *g, const consph_particles *p, size_t n)
{
#ifdef _OPENMP
    const int want = omp_get_max_threads();
    const size_t ncells = g->ncells;
    /* the counts stay smaller than the particles' own arrays, else the serial sort */
    if (want < 2 || n < NNPS_BUILD_THREADS_MIN || (size_t)want * ncells > n) return 0;
    const size_t need = (size_t)want * (ncells + 2);
    if (need > g->tcount_cap) {
        if (grow((void **)&g->tcount, need, sizeof(size_t))) return 0;
        g->tcount_cap = need;
    }
    size_t *tcount = g->tcount, *total = tcount + (size_t)want * ncells, *inside = total + want;
    size_t *start = g->cell_start, *cell_of = g->cell_of, *order = g->order;
    const int dim = g->dim;
    int identity = 1;
#pragma omp parallel num_threads(want) reduction(&& : identity)
    {
        const int nt = omp_get_num_threads(), t = omp_get_thread_num();
        const size_t i0 = n * (size_t)t / (size_t)nt, i1 = n * (size_t)(t + 1) / (size_t)nt;
        const size_t c0 = ncells * (size_t)t / (size_t)nt;
        const size_t c1 = ncells * (size_t)(t + 1) / (size_t)nt;
        inside[t] = (size_t)(dim == 2 ? bin_cells_2d(g, p->x[0] + i0, p->x[1] + i0, cell_of + i0,
                                                     i1 - i0, 0)
                                      : bin_range(g, p, cell_of, i0, i1));
        size_t *mine = tcount + (size_t)t * ncells;
        memset(mine, 0, ncells * sizeof *mine);
        count_cells(cell_of, i0, i1, mine);
#pragma omp barrier
        size_t sum = 0;
        for (size_t c = c0; c < c1; ++c)
            for (int u = 0; u < nt; ++u) sum += tcount[(size_t)u * ncells + c];
        total[t] = sum;
#pragma omp barrier
        size_t next = 0;
        for (int u = 0; u < t; ++u) next += total[u];
        for (size_t c = c0; c < c1; ++c) {
            start[c] = next;
            for (int u = 0; u < nt; ++u) {
                const size_t k = tcount[(size_t)u * ncells + c];
                tcount[(size_t)u * ncells + c] = next;
                next += k;
            }
        }
        if (t == nt - 1) start[ncells] = next;
#pragma omp barrier
        identity = scatter_cells(cell_of, i0, i1, mine, order);
        int in = 1;
        for (int u = 0; u < nt; ++u) in = in && inside[u];
#pragma omp barrier
        /* slots [i0, i1): the coordinates in cell order */
        for (int a = 0; a < dim; ++a) {
            const double lo = g->lo[a], hi = g->hi[a], len = g->len[a], *x = p->x[a];
            double *xs = g->xs[a];
            if (g->periodic[a] && !in)
                for (size_t sl = i0; sl < i1; ++sl) xs[sl] = nnps_wrap(x[order[sl]], lo, hi, len);
            else
                for (size_t sl = i0; sl < i1; ++sl) xs[sl] = x[order[sl]];
        }
    }
    g->identity = identity;
    return 1;
#else
    (void)g;
    (void)p;
    (void)n;
    return 0;
#endif
}

static int build(consph_nnps *g, const consph_particles *p)
{
    g->current = 0;
    g->p = NULL;
    g->n = 0;
    if (!p || p->dim != g->dim)
        return consph_fail(CONSPH_EINVAL,
                           "particle dimension %d does not match the search box (%d)",
                           p ? p->dim : 0, g->dim);
    const size_t n = p->n;
    setup_grid(g, n);
    if (reserve_arrays(g, n)) {
        g->ncells = 0;
        return CONSPH_ENOMEM;
    }
    const int dim = g->dim;
    if (!build_threads(g, p, n)) {
        size_t *cell_of = g->cell_of;
        const int inside = dim == 2 ? bin_cells_2d(g, p->x[0], p->x[1], cell_of, n, 1) : g->inside;
        if (dim != 2) bin_cells(g, p, cell_of, n);

        /* Stable counting sort, serial: few particles, or more cells than the per-thread
         * counts of build_threads may take. */
        size_t *start = g->cell_start;
        const size_t ncells = g->ncells;
        memset(start, 0, (ncells + 1) * sizeof *start);
        count_cells(cell_of, 0, n, start + 1);
        for (size_t c = 0; c < ncells; ++c) start[c + 1] += start[c];
        /* in 2D with both axes copied as they are, the coordinates go with the scatter */
        const int as_is = dim == 2 && (inside || (!g->periodic[0] && !g->periodic[1]));
        g->identity = as_is ? scatter_cells_xs(cell_of, n, start, g->order, p->x[0], p->x[1],
                                               g->xs[0], g->xs[1])
                            : scatter_cells(cell_of, 0, n, start, g->order);
        /* The scatter advanced each start to the next cell's start; shift back. */
        for (size_t c = ncells; c > 0; --c) start[c] = start[c - 1];
        start[0] = 0;
        if (!as_is)
            for (int a = 0; a < dim; ++a)
                gather_coords(g, a, p->x[a], g->order, g->xs[a], n, inside);
    }
    /* The gather's vector paths read whole blocks past a run's end; NaN is never a hit. */
    if (n)
        for (int a = 0; a < dim; ++a)
            for (size_t s = n; s < n + CONSPH_NNPS_GATHER_SLACK; ++s) g->xs[a][s] = NAN;
    g->p = p;
    g->n = n;
    return CONSPH_OK;
}

int consph_nnps_build(consph_nnps *g, const consph_particles *p)
{
    const int st = build(g, p);
    g->inside = 0; /* the word holds for one build */
    return st;
}

void nnps_positions_inside(consph_nnps *g, const double *lo, const double *hi)
{
    int same = lo && hi;
    for (int a = 0; same && a < g->dim; ++a)
        same = same && (!g->periodic[a] || (lo[a] == g->lo[a] && hi[a] == g->hi[a]));
    g->inside = same;
}

int consph_nnps_sort(consph_nnps *g, consph_particles *p, size_t *perm_out)
{
    /* A build its caller vouched for (nnps_build_is_current) is the build of these positions:
     * making it again would give the same cells, order and coordinates. */
    const int reuse = g->current && g->p == p && g->n == p->n;
    int status = reuse ? CONSPH_OK : consph_nnps_build(g, p);
    g->current = 0;
    if (status) return status;
    if (p->n == 0) return CONSPH_OK;
    /* already in cell order: the permutation is the identity and moves nothing */
    status = g->identity ? CONSPH_OK : particles_permute_buf_run(p, g->order, &g->permute);
    if (status) return status;
    /* A rebuild of the permuted set would bin particle s into the cell of old particle
     * order[s]: cells ascend with s, the stable sort keeps them in place, and the sorted
     * coordinates and cell starts are unchanged. So the rebuild reduces to this. */
    const size_t n = p->n;
    size_t *order = g->order;
#pragma omp parallel for schedule(static) if (n >= NNPS_BUILD_THREADS_MIN)
    for (size_t s = 0; s < n; ++s) {
        if (perm_out) perm_out[s] = order[s];
        order[s] = s;
    }
    g->identity = 1;
    return CONSPH_OK;
}

void nnps_build_is_current(consph_nnps *g)
{
    g->current = g->p != NULL;
}

void nnps_fix_grid(consph_nnps *g, size_t n)
{
    g->grid_n = n;
}

void nnps_grid(const consph_nnps *g, int64_t nc[CONSPH_MAX_DIM], int64_t reach[CONSPH_MAX_DIM],
               double edge[CONSPH_MAX_DIM])
{
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        nc[a] = g->nc[a];
        reach[a] = g->reach[a];
        edge[a] = g->h[a];
    }
}

int64_t nnps_axis_cell(const consph_nnps *g, int a, double x)
{
    return cell_index(g, a, stored_coord(g, a, x));
}

void nnps_axis_cells(const consph_nnps *g, int a, const double *x, const size_t *idx, size_t n,
                     int64_t *out, size_t stride)
{
    /* the grid's constants in locals: the int64_t stores may alias its members */
    const double lo = g->lo[a], hi = g->hi[a], len = g->len[a], ih = g->inv_h[a];
    const int64_t nc = g->nc[a];
    const int per = g->periodic[a];
    for (size_t k = 0; k < n; ++k) {
        const double xs = per ? nnps_wrap(x[idx[k]], lo, hi, len) : x[idx[k]];
        out[k * stride] = cell_clamp((xs - lo) * ih, nc);
    }
}

/* Integer floor division for a positive divisor; u is nearly always inside [0, d) or one
 * period off, and a hardware division per row would cost more than the row's distances. */
static inline int64_t floor_div(int64_t u, int64_t d)
{
    if (u >= 0 && u < d) return 0;
    if (u < 0 && u >= -d) return -1;
    if (u >= d && u < 2 * d) return 1;
    int64_t q = u / d;
    return (u % d != 0 && u < 0) ? q - 1 : q;
}

/* Unwrapped cell indices [*ua, *ub] along axis a whose slack-widened extent comes within rr of
 * x, limited to c +- reach (and to the grid on a non-periodic axis). Empty when *ua > *ub. */
static inline void axis_range(const consph_nnps *g, int a, double x, int64_t c, double rr,
                              int64_t *ua, int64_t *ub)
{
    double fa = floor((x - rr - g->slack[a] - g->lo[a]) * g->inv_h[a]);
    double fb = floor((x + rr + g->slack[a] - g->lo[a]) * g->inv_h[a]);
    if (!g->periodic[a]) {
        /* Boundary cells also hold everything beyond the box: clamping the range keeps them. */
        double last = (double)(g->nc[a] - 1);
        fa = fa > 0.0 ? (fa < last ? fa : last) : 0.0;
        fb = fb > 0.0 ? (fb < last ? fb : last) : 0.0;
    }
    /* Written so that a NaN (from a NaN query point) gives way to the reach bound; fmin and
     * fmax would do the same but are library calls on baseline x86-64. */
    double lo_bound = (double)(c - g->reach[a]), hi_bound = (double)(c + g->reach[a]);
    fa = fa > lo_bound ? fa : lo_bound;
    fb = fb < hi_bound ? fb : hi_bound;
    *ua = (int64_t)fa;
    *ub = (int64_t)fb;
}

/* Distance along axis a from x to unwrapped cell u, widened by the slack; boundary cells of a
 * non-periodic axis extend to infinity. */
static inline double axis_gap(const consph_nnps *g, int a, double x, int64_t u)
{
    double lo = g->lo[a] + (double)u * g->h[a] - g->slack[a];
    double hi = g->lo[a] + (double)(u + 1) * g->h[a] + g->slack[a];
    if (!g->periodic[a]) {
        if (u == 0) lo = -INFINITY;
        if (u == g->nc[a] - 1) hi = INFINITY;
    }
    if (x < lo) return lo - x;
    if (x > hi) return x - hi;
    return 0.0;
}

/* Where a walk starts: a point (a query, pruned by the distance from the point to each cell) or
 * a whole cell (the runs shared by every particle binned there, pruned by the distance between
 * cells). A cell walk visits every cell that a walk from any of its points visits, in the same
 * order: both enumerate unwrapped cells in ascending (u2, u1, u0), and the cell-to-cell gap
 * never exceeds the point-to-cell gap (it is widened by twice the slack of both cells). */
typedef struct walk_origin {
    int from_cell;
    double x[CONSPH_MAX_DIM];
    int64_t c[CONSPH_MAX_DIM];
} walk_origin;

/* Gap along axis a between cells c and u: (|u - c| - 1) h less the slack of both cells, less
 * twice the slack again, so that it stays below the point-to-cell gap of axis_gap of any point
 * binned into c despite rounding. */
static inline double cell_gap(const consph_nnps *g, int a, int64_t c, int64_t u)
{
    int64_t k = u > c ? u - c : c - u;
    double gap = (double)(k - 1) * g->h[a] - 4.0 * g->slack[a];
    return k > 1 && gap > 0.0 ? gap : 0.0;
}

/* Cells along axis a to walk within rr of the origin (see axis_range for a point). */
static inline void walk_range(const consph_nnps *g, int a, const walk_origin *o, double rr,
                              int64_t *ua, int64_t *ub)
{
    if (!o->from_cell) {
        axis_range(g, a, o->x[a], o->c[a], rr, ua, ub);
        return;
    }
    int64_t c = o->c[a], lo = c - g->reach[a], hi = c + g->reach[a];
    if (!g->periodic[a]) {
        lo = lo > 0 ? lo : 0;
        hi = hi < g->nc[a] - 1 ? hi : g->nc[a] - 1;
    }
    while (lo < c && !(cell_gap(g, a, c, lo) < rr)) ++lo;
    while (hi > c && !(cell_gap(g, a, c, hi) < rr)) --hi;
    *ua = lo;
    *ub = hi;
}

static inline double walk_gap(const consph_nnps *g, int a, const walk_origin *o, int64_t u)
{
    return o->from_cell ? cell_gap(g, a, o->c[a], u) : axis_gap(g, a, o->x[a], u);
}

/* Where a walk's runs go: appended to a run list, or, for a query, gathered into a neighbour
 * buffer in batches of runs (a query keeps no run list). */
#define NNPS_QUERY_BATCH 64
typedef struct walk_sink {
    consph_nnps_runs *runs;
    /* query: */
    const consph_nnps_slots *slots;
    const double *xi;
    consph_nbrs *nbrs;
    size_t n;
    consph_nnps_run *batch; /* NNPS_QUERY_BATCH entries */
    size_t nbatch, batch_candidates;
} walk_sink;

static int runs_reserve(consph_nnps_runs *r, size_t need)
{
    if (need <= r->cap) return CONSPH_OK;
    size_t cap = r->cap ? r->cap : 32;
    while (cap < need) cap *= 2;
    consph_nnps_run *run = realloc(r->run, cap * sizeof *run);
    if (!run) return consph_fail(CONSPH_ENOMEM, "out of memory for %zu runs of cells", cap);
    r->run = run;
    r->cap = cap;
    return CONSPH_OK;
}

/* Gathers the batched runs of a query into its neighbour buffer. */
static int sink_flush(walk_sink *k)
{
    if (k->nbatch == 0) return CONSPH_OK;
    consph_nbrs *out = k->nbrs;
    size_t need = k->n + k->batch_candidates + CONSPH_NNPS_GATHER_SLACK;
    if (need > out->cap && nnps_nbrs_reserve(out, need)) return CONSPH_ENOMEM;
    const size_t n0 = k->n;
    k->n = nnps_gather_runs(nnps_best_isa(), k->slots, k->batch, k->nbatch, k->xi, out->j, out->dx,
                            out->r, n0);
    if (k->slots->particle)
        for (size_t p = n0; p < k->n; ++p) out->j[p] = k->slots->particle[out->j[p]];
    k->nbatch = 0;
    k->batch_candidates = 0;
    return CONSPH_OK;
}

static inline int sink_run(walk_sink *k, size_t s0, size_t s1, const double *shift)
{
    consph_nnps_run *run;
    if (k->runs) {
        consph_nnps_runs *r = k->runs;
        if (r->n == r->cap && runs_reserve(r, r->n + 1)) return CONSPH_ENOMEM;
        run = &r->run[r->n++];
        r->candidates += s1 - s0;
    } else {
        if (k->nbatch == NNPS_QUERY_BATCH && sink_flush(k)) return CONSPH_ENOMEM;
        run = &k->batch[k->nbatch++];
        k->batch_candidates += s1 - s0;
    }
    run->s0 = s0;
    run->s1 = s1;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) run->shift[a] = shift[a];
    return CONSPH_OK;
}

/* Visits the unwrapped cells u = c + o, |o| <= reach, in a fixed order (axis 2 outermost, axis
 * 0 innermost, ascending), skipping rows and cells that cannot come within the radius, and
 * hands each row to the sink as runs of adjacent cells with one image shift. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline int
walk(const consph_nnps *g, const walk_origin *o, walk_sink *sink)
{
    const size_t *start = g->cell_start;
    const double rp = g->radius + g->slack_max;
    const double rp2 = rp * rp;
    double shift[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
    int64_t u2a, u2b;
    walk_range(g, 2, o, rp, &u2a, &u2b);
    for (int64_t u2 = u2a; u2 <= u2b; ++u2) {
        double g2 = walk_gap(g, 2, o, u2);
        double rem2 = rp2 - g2 * g2;
        if (!(rem2 > 0.0)) continue;
        int64_t m2 = g->periodic[2] ? floor_div(u2, g->nc[2]) : 0;
        int64_t cell2 = u2 - m2 * g->nc[2];
        shift[2] = (double)m2 * g->len[2];
        int64_t u1a, u1b;
        walk_range(g, 1, o, sqrt(rem2), &u1a, &u1b);
        for (int64_t u1 = u1a; u1 <= u1b; ++u1) {
            double g1 = walk_gap(g, 1, o, u1);
            double rem1 = rem2 - g1 * g1;
            if (!(rem1 > 0.0)) continue;
            int64_t m1 = g->periodic[1] ? floor_div(u1, g->nc[1]) : 0;
            int64_t cell1 = u1 - m1 * g->nc[1];
            shift[1] = (double)m1 * g->len[1];
            const size_t row =
                (size_t)g->nc[0] * ((size_t)cell1 + (size_t)g->nc[1] * (size_t)cell2);
            int64_t u0a, u0b;
            walk_range(g, 0, o, sqrt(rem1), &u0a, &u0b);
            /* Split the row where it wraps: each piece is a run of adjacent cells with one
             * image shift, hence one contiguous range of sorted slots. */
            for (int64_t u0 = u0a; u0 <= u0b;) {
                int64_t m0 = g->periodic[0] ? floor_div(u0, g->nc[0]) : 0;
                int64_t cell0 = u0 - m0 * g->nc[0];
                int64_t last = m0 * g->nc[0] + g->nc[0] - 1;
                int64_t end = u0b < last ? u0b : last;
                size_t s0 = start[row + (size_t)cell0];
                size_t s1 = start[row + (size_t)(cell0 + (end - u0)) + 1];
                if (s1 > s0) {
                    shift[0] = (double)m0 * g->len[0];
                    if (sink_run(sink, s0, s1, shift)) return CONSPH_ENOMEM;
                }
                u0 = end + 1;
            }
        }
    }
    return CONSPH_OK;
}

static void slots_view(const consph_nnps *g, consph_nnps_slots *v)
{
    v->dim = g->dim;
    v->n = g->n;
    v->ncells = g->ncells;
    v->cell_start = g->cell_start;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) v->x[a] = a < g->dim ? g->xs[a] : NULL;
    v->particle = g->identity ? NULL : g->order;
    v->radius2 = g->radius2;
}

int consph_nnps_slots_get(const consph_nnps *g, consph_nnps_slots *v)
{
    memset(v, 0, sizeof *v);
    if (!g->p) return consph_fail(CONSPH_EINVAL, "neighbour search has not been built");
    slots_view(g, v);
    return CONSPH_OK;
}

void consph_nnps_runs_free(consph_nnps_runs *runs)
{
    free(runs->run);
    memset(runs, 0, sizeof *runs);
}

size_t consph_nnps_cell_runs(const consph_nnps *g, size_t c, consph_nnps_runs *out)
{
    out->n = 0;
    out->candidates = 0;
    if (!g->p || c >= g->ncells) {
        consph_fail(CONSPH_EINVAL, "cell %zu is not in the search grid (%zu cells)", c,
                    g->p ? g->ncells : 0);
        return (size_t)-1;
    }
    walk_origin o = {1, {0.0, 0.0, 0.0}, {0, 0, 0}};
    size_t rest = c;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        o.c[a] = (int64_t)(rest % (size_t)g->nc[a]);
        rest /= (size_t)g->nc[a];
    }
    walk_sink sink = {out, NULL, NULL, NULL, 0, NULL, 0, 0};
    if (walk(g, &o, &sink)) {
        out->n = 0;
        out->candidates = 0;
        return (size_t)-1;
    }
    return out->n;
}

size_t consph_nnps_point_runs(const consph_nnps *g, const double *x, consph_nnps_runs *out)
{
    out->n = 0;
    out->candidates = 0;
    if (!g->p) {
        consph_fail(CONSPH_EINVAL, "neighbour search has not been built");
        return (size_t)-1;
    }
    walk_origin o = {0, {0.0, 0.0, 0.0}, {0, 0, 0}};
    for (int a = 0; a < g->dim; ++a) {
        o.x[a] = stored_coord(g, a, x[a]);
        o.c[a] = cell_index(g, a, o.x[a]);
    }
    walk_sink sink = {out, NULL, NULL, NULL, 0, NULL, 0, 0};
    if (g->n && walk(g, &o, &sink)) {
        out->n = 0;
        out->candidates = 0;
        return (size_t)-1;
    }
    return out->n;
}

static size_t query_at(const consph_nnps *g, const double *xin, consph_nbrs *out)
{
    out->n = 0;
    if (!g->p || g->n == 0) return 0;
    walk_origin o = {0, {0.0, 0.0, 0.0}, {0, 0, 0}};
    for (int a = 0; a < g->dim; ++a) {
        o.x[a] = stored_coord(g, a, xin[a]);
        o.c[a] = cell_index(g, a, o.x[a]);
    }
    consph_nnps_slots v;
    slots_view(g, &v);
    consph_nnps_run batch[NNPS_QUERY_BATCH];
    walk_sink sink = {NULL, &v, o.x, out, 0, batch, 0, 0};
    if (walk(g, &o, &sink) || sink_flush(&sink)) {
        out->n = 0;
        return (size_t)-1;
    }
    out->n = sink.n;
    return sink.n;
}

size_t consph_nnps_query(const consph_nnps *g, const double *x, consph_nbrs *out)
{
    return query_at(g, x, out);
}

size_t consph_nnps_query_particle(const consph_nnps *g, size_t i, consph_nbrs *out)
{
    out->n = 0;
    if (!g->p || i >= g->n) {
        consph_fail(CONSPH_EINVAL, "particle %zu is not in the searched set (%zu particles)", i,
                    g->p ? g->n : 0);
        return (size_t)-1;
    }
    double x[CONSPH_MAX_DIM];
    for (int a = 0; a < g->dim; ++a) x[a] = g->p->x[a][i];
    return query_at(g, x, out);
}
