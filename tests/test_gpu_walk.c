/* The GPU pair passes' walk by rows of cells (src/gpu/dev.h's gpu_walkr_*) against a walk cell
 * by cell (the reference below, the walk the CPU search's order was first matched with on the
 * GPU): for every particle of random points, the same neighbours in the same order with
 * bit-identical x_ij and r, in 2D and 3D, on periodic, walled and mixed boxes, and on grids so
 * coarse that a periodic row wraps more than once (the search reaching farther than the box,
 * several images of one particle). The cells and slots are built by dev.h's own binning and
 * counting sort. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "gpu/dev.h"

#define HITS_MAX 4096 /* neighbours of one particle, images included */

/* ---- the reference: the cells of reach around i's one at a time, axis 0 innermost, each
 * pruned when farther than the radius (widened by the binning's rounding) ---- */
typedef struct cell_walk {
    int64_t c[3], u[3], ua[3], ub[3];
    double xi[3], q[3];
    uint32_t s, s1;
    uint32_t hits; /* neighbours yielded so far, i itself among them (gpu_pairs_add) */
} cell_walk;

static int64_t floor_div(int64_t u, int64_t d)
{
    if (u >= 0 && u < d) return 0;
    if (u < 0 && u >= -d) return -1;
    const int64_t q = u / d;
    return (u % d != 0 && u < 0) ? q - 1 : q;
}

/* Points the walk at its current unwrapped cell u: the cell's slots and the image shift; no slots
 * when the cell lies farther than the radius (widened by the rounding of binning, as the CPU's
 * walk widens it by its slack) from the point: such a cell holds no neighbour, so skipping it
 * changes which cells are read, never the neighbours or their order. */
static void cell_walk_cell(const gpu_view *v, cell_walk *w)
{
    const gpu_grid *g = &v->g;
    double gap2 = 0.0;
    for (int a = 0; a < 3; ++a) {
        if (a >= g->dim) break;
        const double lo = g->lo[a] + (double)w->u[a] * g->h[a];
        const double hi = g->lo[a] + (double)(w->u[a] + 1) * g->h[a];
        const int open_lo = !g->periodic[a] && w->u[a] == 0;
        const int open_hi = !g->periodic[a] && w->u[a] == g->nc[a] - 1;
        const double x = w->xi[a];
        const double gap = (!open_lo && x < lo) ? lo - x : (!open_hi && x > hi) ? x - hi : 0.0;
        gap2 += gap * gap;
    }
    if (gap2 > g->prune2) {
        w->s = w->s1 = 0;
        return;
    }
    size_t cell = 0;
    double shift[3] = {0.0, 0.0, 0.0};
    for (int a = 2; a >= 0; --a) {
        int64_t ca = w->u[a];
        if (g->periodic[a]) {
            const int64_t m = floor_div(w->u[a], g->nc[a]);
            ca = w->u[a] - m * g->nc[a];
            shift[a] = (double)m * g->len[a];
        }
        cell = cell * (size_t)g->nc[a] + (size_t)ca;
    }
    for (int a = 0; a < 3; ++a) w->q[a] = a < g->dim ? w->xi[a] - shift[a] : 0.0;
    w->s = v->start[cell];
    w->s1 = v->start[cell + 1];
}

static void cell_walk_start(const gpu_view *v, size_t i, cell_walk *w)
{
    const gpu_grid *g = &v->g;
    for (int a = 0; a < 3; ++a) {
        w->xi[a] = w->q[a] = 0.0;
        w->c[a] = 0;
        w->ua[a] = w->ub[a] = 0;
        if (a >= g->dim) continue;
        w->xi[a] = gpu_stored(g, a, gv(v, GA_X, a)[i]);
        w->c[a] = gpu_cell_axis(g, a, w->xi[a]);
        w->ua[a] = w->c[a] - g->reach[a];
        w->ub[a] = w->c[a] + g->reach[a];
        if (!g->periodic[a]) {
            if (w->ua[a] < 0) w->ua[a] = 0;
            if (w->ub[a] > g->nc[a] - 1) w->ub[a] = g->nc[a] - 1;
        }
    }
    for (int a = 0; a < 3; ++a) w->u[a] = w->ua[a];
    w->hits = 0;
    cell_walk_cell(v, w);
}

/* The next neighbour j of the walk (i itself among them, at r = 0), with x_ij and r; 0 at the
 * end. */
static int cell_walk_next(const gpu_view *v, cell_walk *w, uint32_t *j, double dx[3], double *r)
{
    const int d = v->d;
    for (;;) {
        while (w->s < w->s1) {
            const uint32_t s = w->s++;
            const double d0 = w->q[0] - v->xp[4 * (size_t)s];
            double rr = d0 * d0;
            dx[0] = d0;
            dx[1] = dx[2] = 0.0;
            if (d > 1) {
                const double d1 = w->q[1] - v->xp[4 * (size_t)s + 1];
                rr += d1 * d1;
                dx[1] = d1;
            }
            if (d > 2) {
                const double d2 = w->q[2] - v->xp[4 * (size_t)s + 2];
                rr += d2 * d2;
                dx[2] = d2;
            }
            if (rr < v->g.radius2) {
                *j = v->order[s];
                *r = sqrt(rr);
                ++w->hits;
                return 1;
            }
        }
        /* the next cell: axis 0 innermost, ascending */
        int a = 0;
        while (a < 3 && ++w->u[a] > w->ub[a]) {
            w->u[a] = w->ua[a];
            ++a;
        }
        if (a == 3) return 0;
        cell_walk_cell(v, w);
    }
}

typedef struct walk_case {
    const char *name;
    int dim;
    int periodic[3];
    int nc[3];
    double len[3], radius;
    size_t n;
} walk_case;

static double rnd(unsigned *state)
{
    *state = *state * 1103515245u + 12345u;
    return (double)((*state >> 8) & 0xffffff) / 16777216.0;
}

/* The grid as gpu.c's grid_setup makes it, for given cell counts. */
static void grid(gpu_grid *g, const walk_case *c)
{
    memset(g, 0, sizeof *g);
    g->dim = c->dim;
    double slack_max = 0.0;
    g->ncells = 1;
    for (int a = 0; a < 3; ++a) {
        g->nc[a] = 1;
        g->len[a] = g->inv_h[a] = 1.0;
        if (a >= c->dim) continue;
        g->periodic[a] = c->periodic[a];
        g->lo[a] = -0.5 * c->len[a];
        g->hi[a] = 0.5 * c->len[a];
        g->len[a] = g->hi[a] - g->lo[a];
        g->nc[a] = c->nc[a];
        g->h[a] = g->len[a] / (double)c->nc[a];
        g->inv_h[a] = (double)c->nc[a] / g->len[a];
        const double slack =
            64.0 * DBL_EPSILON * (fmax(fabs(g->lo[a]), fabs(g->hi[a])) + g->len[a] + c->radius);
        slack_max = fmax(slack_max, slack);
        double k = ceil((c->radius + 2.0 * slack) / g->h[a]);
        if (!g->periodic[a]) k = fmin(k, (double)c->nc[a] - 1.0);
        g->reach[a] = (int64_t)k;
        g->ncells *= (size_t)c->nc[a];
    }
    g->radius2 = c->radius * c->radius;
    g->prune2 = (c->radius + 4.0 * slack_max) * (c->radius + 4.0 * slack_max);
}

static void run_case(const walk_case *c, unsigned seed)
{
    const size_t n = c->n;
    const int d = c->dim;
    gpu_view v;
    memset(&v, 0, sizeof v);
    v.n = n;
    v.d = d;
    v.narr = d;
    for (int q = 0; q < GA_COUNT; ++q) v.at[q] = -1;
    v.at[GA_X] = 0;
    v.scheme = GS_WCSPH; /* no p beside the coordinates */
    grid(&v.g, c);
    v.a = calloc((size_t)d * n, sizeof(double));
    v.xp = calloc(4 * n, sizeof(double));
    v.cell = calloc(n, sizeof(uint32_t));
    v.count = calloc(v.g.ncells + 1, sizeof(uint32_t));
    v.start = calloc(v.g.ncells + 1, sizeof(uint32_t));
    v.order = calloc(n, sizeof(uint32_t));
    v.slot_of = calloc(n, sizeof(uint32_t));
    uint32_t *hits_j = malloc(HITS_MAX * sizeof(uint32_t));
    double *hits_x = malloc(4 * HITS_MAX * sizeof(double));
    if (!v.a || !v.xp || !v.cell || !v.count || !v.start || !v.order || !v.slot_of || !hits_j ||
        !hits_x) {
        CHECK(0, "out of memory");
        return;
    }
    /* random points, a few of them on cell faces and the box's faces */
    for (size_t i = 0; i < n; ++i)
        for (int a = 0; a < d; ++a) {
            double x = v.g.lo[a] + rnd(&seed) * v.g.len[a];
            if (i % 7 == 3) x = v.g.lo[a] + (double)(i % (size_t)(v.g.nc[a] + 1)) * v.g.h[a];
            if (x >= v.g.hi[a] && !v.g.periodic[a]) x = v.g.lo[a];
            v.a[(size_t)a * n + i] = x;
        }
    for (size_t i = 0; i < n; ++i) dev_bin(&v, i);
    for (size_t i = 0; i < n; ++i) dev_count(&v, i);
    uint32_t run = 0;
    for (size_t k = 0; k <= v.g.ncells; ++k) {
        v.start[k] = run;
        run += v.count[k];
    }
    memset(v.count, 0, (v.g.ncells + 1) * sizeof(uint32_t));
    for (size_t i = n; i-- > 0;) dev_scatter(&v, i);
    for (size_t k = 0; k < v.g.ncells; ++k) dev_cell_sort(&v, k);
    for (size_t s = 0; s < n; ++s) dev_slots(&v, s);
    size_t total = 0, differ = 0, images = 0;
    for (size_t i = 0; i < n; ++i) {
        /* the cell walk's neighbours of i */
        cell_walk w;
        cell_walk_start(&v, i, &w);
        size_t k = 0;
        uint32_t j;
        double dx[3], r;
        while (k < HITS_MAX && cell_walk_next(&v, &w, &j, dx, &r)) {
            hits_j[k] = j;
            for (int a = 0; a < 3; ++a) hits_x[4 * k + (size_t)a] = a < d ? dx[a] : 0.0;
            hits_x[4 * k + 3] = r;
            ++k;
        }
        /* the row walk's */
        gpu_walkr wr;
        size_t m = 0;
        int same = 1;
        uint32_t s;
        if (d == 2)
            gpu_walkr_start(&v, i, &wr, 2);
        else
            gpu_walkr_start(&v, i, &wr, 3);
        for (;;) {
            const int more = d == 2 ? gpu_walkr_next(&v, &wr, 2, &s, dx, &r)
                                    : gpu_walkr_next(&v, &wr, 3, &s, dx, &r);
            if (!more) break;
            if (m < k) {
                double x[4] = {0.0, 0.0, 0.0, r};
                for (int a = 0; a < d; ++a) x[a] = dx[a];
                if (v.order[s] != hits_j[m] || memcmp(x, hits_x + 4 * m, sizeof x) != 0) same = 0;
                if (v.order[s] == i && r > 0.0) ++images;
            }
            ++m;
        }
        if (m != k || !same) ++differ;
        total += k;
    }
    CHECK(differ == 0, "%s: %zu of %zu particles' neighbours differ", c->name, differ, n);
    CHECK(total > n && total < HITS_MAX * n,
          "%s: %zu neighbours of %zu particles (a test of nothing)", c->name, total, n);
    if (c->radius > c->len[0] && c->periodic[0])
        CHECK(images > 0, "%s: no particle meets its own image (the wrap is not tested)", c->name);
    free(v.a);
    free(v.xp);
    free(v.cell);
    free(v.count);
    free(v.start);
    free(v.order);
    free(v.slot_of);
    free(hits_j);
    free(hits_x);
}

int main(void)
{
    const walk_case cases[] = {
        {"2D periodic", 2, {1, 1, 0}, {9, 7, 1}, {1.0, 0.8, 0.0}, 0.23, 400},
        {"2D walled", 2, {0, 0, 0}, {9, 7, 1}, {1.0, 0.8, 0.0}, 0.23, 400},
        {"2D periodic in x", 2, {1, 0, 0}, {8, 6, 1}, {1.0, 1.0, 0.0}, 0.3, 300},
        {"2D periodic in y", 2, {0, 1, 0}, {8, 6, 1}, {1.0, 1.0, 0.0}, 0.3, 300},
        {"2D cells of half the radius", 2, {1, 1, 0}, {16, 12, 1}, {1.0, 0.75, 0.0}, 0.13, 400},
        {"2D periodic, the reach beyond the box",
         2,
         {1, 1, 0},
         {3, 2, 1},
         {1.0, 1.0, 0.0},
         0.6,
         12},
        {"3D periodic", 3, {1, 1, 1}, {6, 5, 7}, {1.0, 0.9, 1.1}, 0.36, 500},
        {"3D walled", 3, {0, 0, 0}, {6, 5, 7}, {1.0, 0.9, 1.1}, 0.36, 500},
        {"3D mixed", 3, {1, 0, 1}, {5, 4, 6}, {1.0, 1.0, 1.0}, 0.4, 400},
        {"3D periodic, one cell along z", 3, {1, 1, 1}, {6, 6, 1}, {1.0, 1.0, 0.3}, 0.3, 300},
        {"3D periodic, the reach beyond the box",
         3,
         {1, 1, 1},
         {2, 3, 2},
         {1.0, 1.0, 1.0},
         0.55,
         10},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k)
        run_case(&cases[k], 12345u + 77u * (unsigned)k);
    return check_summary("test_gpu_walk");
}
