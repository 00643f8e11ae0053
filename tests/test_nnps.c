/* Neighbour search against the O(N^2) reference: the multiset of (j, x_i - x_j) of every query
 * must agree to round-off, for random and degenerate particle sets in 1D-3D, any periodic
 * axes, radii from a few neighbours to several box lengths. */
#include "check.h"
#include "consph/nnps.h"
#include "nnps/nnps_internal.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

typedef struct entry {
    size_t j;
    double d[CONSPH_MAX_DIM];
    double r;
} entry;

/* Pairs this close to the radius may fall on either side of it in the two searches. */
#define EDGE_REL 1e-12
/* Separations are compared to this relative tolerance (identical formulas give equal bits; the
 * tolerance only guards against the compiler contracting them differently). */
#define DX_REL 1e-12

static int entry_cmp(const void *pa, const void *pb)
{
    const entry *a = pa, *b = pb;
    if (a->j != b->j) return a->j < b->j ? -1 : 1;
    /* Images of one j differ by at least a box length in some component. */
    for (int k = 0; k < CONSPH_MAX_DIM; ++k) {
        if (a->d[k] < b->d[k] - 1e-9) return -1;
        if (a->d[k] > b->d[k] + 1e-9) return 1;
    }
    return 0;
}

/* Copies the entries of nb away from the radius, sorted; returns their count. */
static size_t collect(const consph_nbrs *nb, int dim, double radius, entry *out)
{
    size_t m = 0;
    for (size_t k = 0; k < nb->n; ++k) {
        if (fabs(nb->r[k] - radius) <= EDGE_REL * radius) continue;
        entry e;
        memset(&e, 0, sizeof e);
        e.j = nb->j[k];
        for (int a = 0; a < dim; ++a) e.d[a] = nb->dx[a][k];
        e.r = nb->r[k];
        out[m++] = e;
    }
    qsort(out, m, sizeof *out, entry_cmp);
    return m;
}

typedef struct cmp_state {
    consph_nbrs fast, slow;
    entry *ea, *eb;
    size_t ecap;
    long bad_points;     /* queries whose neighbour multisets differ */
    long bad_entries;    /* entries violating r < radius or r = |dx| or j < n */
    size_t total_nbrs;   /* entries compared, to show the test is not vacuous */
    size_t max_nbrs;     /* largest neighbour count of one query */
    size_t edge_entries; /* entries dropped as lying on the radius */
    char first[512];
} cmp_state;

static void state_free(cmp_state *s)
{
    consph_nbrs_free(&s->fast);
    consph_nbrs_free(&s->slow);
    free(s->ea);
    free(s->eb);
    memset(s, 0, sizeof *s);
}

/* Compares a cell-search result already in s->fast with the brute-force search at x. */
static void compare_with_brute(cmp_state *s, const consph_particles *p, double radius,
                               const double *x, const char *what)
{
    const int dim = p->dim;
    size_t nb = consph_nnps_brute(p, radius, x, &s->slow);
    if (nb == (size_t)-1) {
        ++s->bad_points;
        snprintf(s->first, sizeof s->first, "%s: brute failed: %s", what, consph_last_error());
        return;
    }
    const consph_nbrs *f = &s->fast;
    for (size_t k = 0; k < f->n; ++k) {
        double r2 = 0.0;
        for (int a = 0; a < dim; ++a) r2 += f->dx[a][k] * f->dx[a][k];
        if (!(f->r[k] < radius) || f->j[k] >= p->n ||
            fabs(f->r[k] - sqrt(r2)) > 1e-14 * (1.0 + radius))
            ++s->bad_entries;
    }
    size_t need = (f->n > nb ? f->n : nb) + 1;
    if (need > s->ecap) {
        s->ecap = 2 * need;
        s->ea = realloc(s->ea, s->ecap * sizeof *s->ea);
        s->eb = realloc(s->eb, s->ecap * sizeof *s->eb);
        if (!s->ea || !s->eb) abort();
    }
    size_t ma = collect(f, dim, radius, s->ea);
    size_t mb = collect(&s->slow, dim, radius, s->eb);
    s->edge_entries += (f->n - ma) + (nb - mb);
    s->total_nbrs += ma;
    if (f->n > s->max_nbrs) s->max_nbrs = f->n;
    int ok = ma == mb;
    for (size_t k = 0; ok && k < ma; ++k) {
        const entry *a = &s->ea[k], *b = &s->eb[k];
        if (a->j != b->j) ok = 0;
        for (int c = 0; c < dim; ++c)
            if (fabs(a->d[c] - b->d[c]) > DX_REL * (1.0 + fabs(b->d[c]))) ok = 0;
        if (fabs(a->r - b->r) > DX_REL * (1.0 + b->r)) ok = 0;
    }
    if (!ok) {
        if (!s->bad_points)
            snprintf(s->first, sizeof s->first,
                     "%s: x = (%.17g, %.17g, %.17g): cell search %zu (%zu away from the radius), "
                     "brute %zu (%zu away from the radius)",
                     what, x[0], dim > 1 ? x[1] : 0.0, dim > 2 ? x[2] : 0.0, f->n, ma, nb, mb);
        ++s->bad_points;
    }
}

/* Builds a structure for p and compares every particle's neighbours with brute force. */
static void check_all_particles(consph_particles *p, double radius, int cells_per_radius,
                                const char *what)
{
    cmp_state s;
    memset(&s, 0, sizeof s);
    consph_nnps *g = consph_nnps_create(&p->box, radius, cells_per_radius);
    CHECK(g != NULL, "%s: create: %s", what, consph_last_error());
    if (!g) return;
    CHECK(consph_nnps_build(g, p) == CONSPH_OK, "%s: build: %s", what, consph_last_error());
    CHECK(consph_nnps_cells(g) <= 4 * p->n + 1024, "%s: %zu cells for %zu particles", what,
          consph_nnps_cells(g), p->n);
    long self_missing = 0;
    for (size_t i = 0; i < p->n; ++i) {
        double x[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        for (int a = 0; a < p->dim; ++a) x[a] = p->x[a][i];
        size_t got = consph_nnps_query_particle(g, i, &s.fast);
        if (got == (size_t)-1) {
            ++s.bad_points;
            continue;
        }
        int self = 0;
        for (size_t k = 0; k < s.fast.n; ++k) self |= s.fast.j[k] == i && s.fast.r[k] == 0.0;
        self_missing += !self;
        compare_with_brute(&s, p, radius, x, what);
    }
    CHECK(s.bad_points == 0, "%s: %ld of %zu particles differ; first: %s", what, s.bad_points, p->n,
          s.first);
    CHECK(s.bad_entries == 0, "%s: %ld entries with r >= radius, r != |dx| or bad j", what,
          s.bad_entries);
    CHECK(self_missing == 0, "%s: %ld particles do not see themselves at r = 0", what,
          self_missing);
    CHECK(p->n == 0 || s.total_nbrs >= p->n, "%s: only %zu neighbours compared", what,
          s.total_nbrs);
    consph_nnps_free(g);
    state_free(&s);
}

static consph_box make_box(int dim, const int *periodic)
{
    static const double lo[3] = {-0.7, 0.3, -2.0}, hi[3] = {0.8, 1.3, -0.8};
    consph_box b;
    memset(&b, 0, sizeof b);
    b.dim = dim;
    for (int a = 0; a < dim; ++a) {
        b.lo[a] = lo[a];
        b.hi[a] = hi[a];
        b.periodic[a] = periodic[a];
    }
    return b;
}

static void fill_random(consph_particles *p, consph_rng *rng)
{
    for (size_t i = 0; i < p->n; ++i)
        for (int a = 0; a < p->dim; ++a)
            p->x[a][i] = p->box.lo[a] + consph_rng_uniform(rng) * (p->box.hi[a] - p->box.lo[a]);
}

/* Radius giving about `nbrs` neighbours for n particles in the box. */
static double radius_for(const consph_box *b, size_t n, double nbrs)
{
    const double pi = 3.14159265358979323846;
    double unit_ball[4] = {0.0, 2.0, pi, 4.0 * pi / 3.0};
    double v = consph_box_volume(b) * nbrs / ((double)n * unit_ball[b->dim]);
    return pow(v, 1.0 / b->dim);
}

static void test_random_sets(void)
{
    static const int patterns[][3] = {{1, 1, 1}, {0, 0, 0}, {1, 0, 1}, {0, 1, 0}};
    consph_rng rng;
    consph_rng_seed(&rng, 12345);
    for (int dim = 1; dim <= 3; ++dim) {
        for (int pat = 0; pat < 4; ++pat) {
            if (dim == 1 && pat >= 2) continue;
            consph_box box = make_box(dim, patterns[pat]);
            double lmin = 1e300, lmax = 0.0;
            for (int a = 0; a < dim; ++a) {
                lmin = fmin(lmin, consph_box_length(&box, a));
                lmax = fmax(lmax, consph_box_length(&box, a));
            }
            /* A few and tens of neighbours, then radii comparable to and beyond the box. */
            const size_t n_small = 500, n_big = 80;
            double radii[4] = {radius_for(&box, n_small, 6.0), radius_for(&box, n_small, 40.0),
                               0.6 * lmin, 1.7 * lmax};
            for (int ri = 0; ri < 4; ++ri) {
                size_t n = ri < 2 ? n_small : n_big;
                consph_particles p;
                consph_particles_init(&p, dim, n, &box);
                fill_random(&p, &rng);
                for (int cpr = 0; cpr <= 3; ++cpr) {
                    char what[128];
                    snprintf(what, sizeof what, "random %dD periodic %d%d%d R=%.3g cpr=%d", dim,
                             patterns[pat][0], dim > 1 ? patterns[pat][1] : 0,
                             dim > 2 ? patterns[pat][2] : 0, radii[ri], cpr);
                    check_all_particles(&p, radii[ri], cpr, what);
                }
                consph_particles_free(&p);
            }
        }
    }
}

/* Particles on the box faces and corners, just below hi, on cell boundaries, and (on
 * non-periodic axes) outside the box, for radii equal to a cell edge (distance ties) and
 * spanning several cells. */
static void test_faces_and_boundaries(void)
{
    static const int patterns[][3] = {{1, 1, 1}, {0, 0, 0}, {0, 1, 1}};
    for (int dim = 1; dim <= 3; ++dim) {
        for (int pat = 0; pat < 3; ++pat) {
            if (dim == 1 && pat == 2) continue;
            consph_box box = make_box(dim, patterns[pat]);
            double l0 = consph_box_length(&box, 0);
            /* radius = L/4 with one cell per radius gives 3 cells per axis on axis 0. */
            double radii[3] = {0.25 * l0, 0.25 * l0 * (1.0 + 1e-15), 0.61 * l0};
            for (int ri = 0; ri < 3; ++ri) {
                /* Coordinates per axis: lo, nextafter(hi, lo), every boundary of the grid the
                 * structure will use, and outside points on non-periodic axes. */
                double coords[CONSPH_MAX_DIM][16];
                int ncoord[CONSPH_MAX_DIM] = {0, 0, 0};
                size_t n = 1;
                consph_particles p;
                /* The grid depends on n only through the cell cap, far above these sizes. */
                consph_nnps *probe = consph_nnps_create(&box, radii[ri], 1);
                consph_particles_init(&p, dim, 0, &box);
                consph_nnps_build(probe, &p);
                size_t cells = consph_nnps_cells(probe);
                consph_nnps_free(probe);
                consph_particles_free(&p);
                /* Cell counts per axis follow from L_a * cells_per_radius / radius. */
                size_t check_cells = 1;
                for (int a = 0; a < dim; ++a) {
                    double la = consph_box_length(&box, a);
                    int nc = (int)floor(la / radii[ri] * (1.0 - 1e-9));
                    if (nc < 1) nc = 1;
                    check_cells *= (size_t)nc;
                    double h = la / nc;
                    int m = 0;
                    coords[a][m++] = box.lo[a];
                    coords[a][m++] = nextafter(box.hi[a], box.lo[a]);
                    for (int k = 1; k < nc && m < 12; ++k) {
                        coords[a][m++] = box.lo[a] + k * h;
                        coords[a][m++] = nextafter(box.lo[a] + k * h, box.lo[a]);
                    }
                    coords[a][m++] = box.lo[a] + 0.5 * h;
                    if (!box.periodic[a]) {
                        coords[a][m++] = box.lo[a] - 0.3 * la;
                        coords[a][m++] = box.hi[a] + 0.2 * la;
                        coords[a][m++] = box.hi[a];
                    }
                    ncoord[a] = m;
                    n *= (size_t)m;
                }
                CHECK(cells == check_cells, "boundary test grid: %zu cells, expected %zu", cells,
                      check_cells);
                consph_particles_init(&p, dim, n, &box);
                for (size_t i = 0; i < n; ++i) {
                    size_t rest = i;
                    for (int a = 0; a < dim; ++a) {
                        p.x[a][i] = coords[a][rest % (size_t)ncoord[a]];
                        rest /= (size_t)ncoord[a];
                    }
                }
                char what[128];
                snprintf(what, sizeof what, "boundaries %dD periodic %d%d%d R=%.17g", dim,
                         patterns[pat][0], dim > 1 ? patterns[pat][1] : 0,
                         dim > 2 ? patterns[pat][2] : 0, radii[ri]);
                check_all_particles(&p, radii[ri], 1, what);
                snprintf(what, sizeof what, "boundaries %dD periodic %d%d%d R=%.17g cpr 2", dim,
                         patterns[pat][0], dim > 1 ? patterns[pat][1] : 0,
                         dim > 2 ? patterns[pat][2] : 0, radii[ri]);
                check_all_particles(&p, radii[ri], 2, what);
                consph_particles_free(&p);
            }
        }
    }
}

static int near(double a, double b)
{
    return fabs(a - b) <= 1e-12;
}

static void test_one_particle(void)
{
    /* 1D periodic unit box, radius 2.5: the particle sees itself at shifts -2..2. */
    consph_box box = consph_box_unit(1, 1);
    consph_particles p;
    consph_particles_init(&p, 1, 1, &box);
    p.x[0][0] = 0.3;
    consph_nnps *g = consph_nnps_create(&box, 2.5, 0);
    CHECK(consph_nnps_build(g, &p) == CONSPH_OK, "build one particle");
    consph_nbrs nb;
    memset(&nb, 0, sizeof nb);
    size_t got = consph_nnps_query_particle(g, 0, &nb);
    CHECK(got == 5, "one particle, R = 2.5 L: %zu images, expected 5", got);
    int seen[5] = {0, 0, 0, 0, 0};
    for (size_t k = 0; k < nb.n; ++k) {
        double m = nb.dx[0][k];
        for (int s = -2; s <= 2; ++s)
            if (near(m, s) && near(nb.r[k], fabs((double)s)) && nb.j[k] == 0) seen[s + 2]++;
    }
    for (int s = 0; s < 5; ++s) CHECK(seen[s] == 1, "image shift %d seen %d times", s - 2, seen[s]);
    consph_nnps_free(g);
    consph_particles_free(&p);

    /* 2D periodic unit box, radius 1.2: itself plus the four edge-adjacent images. */
    box = consph_box_unit(2, 1);
    consph_particles_init(&p, 2, 1, &box);
    p.x[0][0] = 0.999;
    p.x[1][0] = 0.0;
    g = consph_nnps_create(&box, 1.2, 0);
    consph_nnps_build(g, &p);
    got = consph_nnps_query_particle(g, 0, &nb);
    CHECK(got == 5, "one particle 2D, R = 1.2: %zu images, expected 5", got);
    consph_nnps_free(g);
    check_all_particles(&p, 1.2, 0, "one particle 2D");
    check_all_particles(&p, 3.3, 1, "one particle 2D R=3.3");
    consph_particles_free(&p);

    /* Non-periodic: only itself, whatever the radius. */
    box = consph_box_unit(3, 0);
    consph_particles_init(&p, 3, 1, &box);
    p.x[0][0] = 1.5; /* outside the box: clamped into a boundary cell */
    g = consph_nnps_create(&box, 5.0, 0);
    consph_nnps_build(g, &p);
    got = consph_nnps_query_particle(g, 0, &nb);
    CHECK(got == 1 && nb.j[0] == 0 && nb.r[0] == 0.0, "one particle 3D non-periodic: %zu", got);
    consph_nnps_free(g);
    consph_particles_free(&p);
    consph_nbrs_free(&nb);
}

static void test_zero_particles(void)
{
    for (int dim = 1; dim <= 3; ++dim) {
        consph_box box = consph_box_unit(dim, dim != 2);
        consph_particles p;
        CHECK(consph_particles_init(&p, dim, 0, &box) == CONSPH_OK, "init empty");
        consph_nnps *g = consph_nnps_create(&box, 0.1, 0);
        CHECK(g != NULL, "create for empty set");
        CHECK(consph_nnps_build(g, &p) == CONSPH_OK, "build empty: %s", consph_last_error());
        CHECK(consph_nnps_cells(g) >= 1, "empty set has %zu cells", consph_nnps_cells(g));
        consph_nbrs nb;
        memset(&nb, 0, sizeof nb);
        double x[3] = {0.5, 0.5, 0.5};
        CHECK(consph_nnps_query(g, x, &nb) == 0 && nb.n == 0, "query on empty set");
        CHECK(consph_nnps_query_particle(g, 0, &nb) == (size_t)-1,
              "query_particle(0) on an empty set must fail");
        size_t perm[1];
        CHECK(consph_nnps_sort(g, &p, perm) == CONSPH_OK, "sort empty set");
        CHECK(consph_nnps_query(g, x, &nb) == 0, "query after sorting an empty set");
        consph_nbrs_free(&nb);
        consph_nnps_free(g);
        consph_particles_free(&p);
    }
}

static void test_arbitrary_points(void)
{
    static const int patterns[][3] = {{1, 1, 1}, {0, 0, 0}, {1, 0, 1}};
    consph_rng rng;
    consph_rng_seed(&rng, 777);
    for (int dim = 1; dim <= 3; ++dim) {
        for (int pat = 0; pat < 3; ++pat) {
            consph_box box = make_box(dim, patterns[pat]);
            consph_particles p;
            consph_particles_init(&p, dim, 600, &box);
            fill_random(&p, &rng);
            double radius = radius_for(&box, p.n, 25.0);
            consph_nnps *g = consph_nnps_create(&box, radius, 0);
            consph_nnps_build(g, &p);
            cmp_state s;
            memset(&s, 0, sizeof s);
            char what[96];
            snprintf(what, sizeof what, "points %dD pattern %d", dim, pat);
            for (int t = 0; t < 300; ++t) {
                double x[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
                /* Up to one box length outside on every side. */
                for (int a = 0; a < dim; ++a) {
                    double l = consph_box_length(&box, a);
                    x[a] = box.lo[a] - l + 3.0 * l * consph_rng_uniform(&rng);
                }
                if (consph_nnps_query(g, x, &s.fast) == (size_t)-1) ++s.bad_points;
                compare_with_brute(&s, &p, radius, x, what);
            }
            CHECK(s.bad_points == 0 && s.bad_entries == 0, "%s: %ld points differ; first: %s", what,
                  s.bad_points, s.first);
            CHECK(s.total_nbrs > 100, "%s: only %zu neighbours compared", what, s.total_nbrs);
            state_free(&s);
            consph_nnps_free(g);
            consph_particles_free(&p);
        }
    }
}

/* Identical (count, order, bits) neighbour lists. */
static int same_lists(const consph_nbrs *a, const consph_nbrs *b, int dim)
{
    if (a->n != b->n) return 0;
    for (size_t k = 0; k < a->n; ++k) {
        if (a->j[k] != b->j[k] || a->r[k] != b->r[k]) return 0;
        for (int c = 0; c < dim; ++c)
            if (a->dx[c][k] != b->dx[c][k]) return 0;
    }
    return 1;
}

static void test_sort(void)
{
    consph_rng rng;
    consph_rng_seed(&rng, 99);
    for (int dim = 2; dim <= 3; ++dim) {
        int periodic[3] = {1, 0, 1};
        consph_box box = make_box(dim, periodic);
        consph_particles p, old;
        const size_t n = 1500;
        consph_particles_init(&p, dim, n, &box);
        consph_particles_init(&old, dim, n, &box);
        fill_random(&p, &rng);
        double *id = consph_particles_field(&p, "id", 1);
        double *vel = consph_particles_field(&p, "vel", 2);
        for (size_t i = 0; i < n; ++i) {
            id[i] = (double)i;
            vel[i] = 2.0 * p.x[0][i];
            vel[p.cap + i] = 10.0 + (double)i;
        }
        for (int a = 0; a < dim; ++a) memcpy(old.x[a], p.x[a], n * sizeof(double));
        double radius = radius_for(&box, n, 30.0);
        consph_nnps *g = consph_nnps_create(&box, radius, 0);
        size_t *perm = malloc(n * sizeof *perm);
        char *hit = calloc(n, 1);
        CHECK(consph_nnps_sort(g, &p, perm) == CONSPH_OK, "sort: %s", consph_last_error());
        long bad_perm = 0, bad_fields = 0;
        for (size_t i = 0; i < n; ++i) {
            if (perm[i] >= n || hit[perm[i]]) {
                ++bad_perm;
                continue;
            }
            hit[perm[i]] = 1;
            for (int a = 0; a < dim; ++a) bad_fields += p.x[a][i] != old.x[a][perm[i]];
            bad_fields += id[i] != (double)perm[i];
            bad_fields += vel[i] != 2.0 * p.x[0][i];
            bad_fields += vel[p.cap + i] != 10.0 + (double)perm[i];
        }
        CHECK(bad_perm == 0, "%dD sort: perm_out is not a permutation (%ld bad)", dim, bad_perm);
        CHECK(bad_fields == 0, "%dD sort: %ld field values did not follow their particles", dim,
              bad_fields);
        /* Sorting must actually reorder a random set. */
        size_t moved = 0;
        for (size_t i = 0; i < n; ++i) moved += perm[i] != i;
        CHECK(moved > n / 2, "%dD sort moved only %zu of %zu particles", dim, moved, n);

        /* The sorted structure answers like a fresh build of the sorted set, entry for entry,
         * and like brute force. */
        consph_nnps *fresh = consph_nnps_create(&box, radius, 0);
        consph_nnps_build(fresh, &p);
        consph_nbrs a, b;
        memset(&a, 0, sizeof a);
        memset(&b, 0, sizeof b);
        long differ = 0;
        size_t sum = 0;
        for (size_t i = 0; i < n; ++i) {
            consph_nnps_query_particle(g, i, &a);
            consph_nnps_query_particle(fresh, i, &b);
            differ += !same_lists(&a, &b, dim);
            sum += a.n;
        }
        CHECK(differ == 0, "%dD: %ld particles differ between sorted and freshly built", dim,
              differ);
        CHECK(sum > 20 * n, "%dD sort test: mean neighbour count %g too small", dim,
              (double)sum / n);
        /* In cell order a particle's neighbours lie in runs of consecutive indices (in a random
         * order nearly every entry starts a run; sorted, 2D gives ~1/3 and 3D ~1/2). */
        size_t runs = 0, entries = 0;
        for (size_t i = 0; i < n; i += 7) {
            consph_nnps_query_particle(fresh, i, &b);
            for (size_t k = 0; k < b.n; ++k) runs += k == 0 || b.j[k] != b.j[k - 1] + 1;
            entries += b.n;
        }
        CHECK(runs * 3 < entries * 2, "%dD: sorted neighbours form %zu runs in %zu entries", dim,
              runs, entries);
        check_all_particles(&p, radius, 0, dim == 2 ? "sorted 2D" : "sorted 3D");
        consph_nbrs_free(&a);
        consph_nbrs_free(&b);
        consph_nnps_free(fresh);
        consph_nnps_free(g);
        free(perm);
        free(hit);
        consph_particles_free(&p);
        consph_particles_free(&old);
    }
}

/* Results are identical whatever the number of threads used to build and to query. */
static void test_thread_independence(void)
{
    consph_box box = consph_box_unit(3, 1);
    consph_particles p;
    const size_t n = 40000; /* above the size where the build runs in parallel */
    consph_particles_init(&p, 3, n, &box);
    consph_rng rng;
    consph_rng_seed(&rng, 4242);
    fill_random(&p, &rng);
    double radius = radius_for(&box, n, 30.0);
    consph_nnps *g1 = consph_nnps_create(&box, radius, 0);
    consph_nnps *g2 = consph_nnps_create(&box, radius, 0);
#ifdef _OPENMP
    int saved = omp_get_max_threads();
    omp_set_num_threads(1);
#endif
    consph_nnps_build(g1, &p);
#ifdef _OPENMP
    omp_set_num_threads(saved > 1 ? saved : 2);
#endif
    consph_nnps_build(g2, &p);
    /* Query every 37th particle serially with g1, and in parallel with g2. */
    const size_t stride = 37, nq = (n + stride - 1) / stride;
    size_t *counts = calloc(nq, sizeof *counts);
    double *first_dx = calloc(nq, sizeof *first_dx);
    long failed = 0;
#pragma omp parallel
    {
        consph_nbrs nb;
        memset(&nb, 0, sizeof nb);
#pragma omp for schedule(dynamic, 16)
        for (size_t q = 0; q < nq; ++q) {
            size_t m = consph_nnps_query_particle(g2, q * stride, &nb);
            counts[q] = m;
            first_dx[q] = m > 1 ? nb.dx[0][1] : -1.0;
        }
        consph_nbrs_free(&nb);
    }
    consph_nbrs a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    long differ = 0;
    for (size_t q = 0; q < nq; ++q) {
        consph_nnps_query_particle(g1, q * stride, &a);
        consph_nnps_query_particle(g2, q * stride, &b);
        differ += !same_lists(&a, &b, 3);
        failed += a.n != counts[q] || (a.n > 1 && a.dx[0][1] != first_dx[q]);
    }
#ifdef _OPENMP
    omp_set_num_threads(saved);
#endif
    CHECK(differ == 0, "%ld lists differ between 1-thread and multi-thread builds", differ);
    CHECK(failed == 0, "%ld parallel queries differ from serial ones", failed);
    consph_nbrs_free(&a);
    consph_nbrs_free(&b);
    free(counts);
    free(first_dx);
    consph_nnps_free(g1);
    consph_nnps_free(g2);
    consph_particles_free(&p);
}

/* A radius tiny compared with the box: the cell count is capped, results stay exact. */
static void test_cell_cap(void)
{
    consph_rng rng;
    consph_rng_seed(&rng, 5);
    for (int dim = 1; dim <= 3; ++dim) {
        for (int periodic = 0; periodic <= 1; ++periodic) {
            consph_box box = consph_box_unit(dim, periodic);
            for (int a = 0; a < dim; ++a) box.hi[a] = 1000.0;
            consph_particles p;
            const size_t n = 300;
            consph_particles_init(&p, dim, n, &box);
            fill_random(&p, &rng);
            /* Pairs at distance ~1e-3 so that some neighbours exist; the last pair straddles
             * the periodic boundary. */
            for (size_t i = 0; i + 1 < n; i += 2)
                for (int a = 0; a < dim; ++a)
                    p.x[a][i + 1] = p.x[a][i] + (consph_rng_uniform(&rng) - 0.5) * 1e-3;
            for (int a = 0; a < dim; ++a) {
                p.x[a][n - 2] = box.lo[a];
                p.x[a][n - 1] = nextafter(box.hi[a], 0.0) - 2e-4;
            }
            for (size_t i = 0; i < n; ++i)
                for (int a = 0; a < dim; ++a)
                    if (periodic)
                        p.x[a][i] = p.x[a][i] >= box.hi[a]  ? p.x[a][i] - 1000.0
                                    : p.x[a][i] < box.lo[a] ? p.x[a][i] + 1000.0
                                                            : p.x[a][i];
            consph_nnps *g = consph_nnps_create(&box, 1e-3, 1);
            consph_nnps_build(g, &p);
            size_t cells = consph_nnps_cells(g);
            CHECK(cells <= 4 * n + 1024, "%dD: %zu cells for %zu particles", dim, cells, n);
            consph_nnps_free(g);
            char what[64];
            snprintf(what, sizeof what, "tiny radius %dD periodic %d", dim, periodic);
            check_all_particles(&p, 1e-3, 1, what);
            consph_particles_free(&p);
        }
    }
}

static void test_errors(void)
{
    consph_box box = consph_box_unit(2, 1);
    CHECK(consph_nnps_create(&box, 0.0, 0) == NULL, "radius 0 accepted");
    CHECK(consph_nnps_create(&box, NAN, 0) == NULL, "radius NaN accepted");
    CHECK(consph_nnps_create(&box, 0.1, -1) == NULL, "cells_per_radius -1 accepted");
    CHECK(consph_nnps_create(&box, 1e9, 0) == NULL, "radius 1e9 box lengths accepted");
    consph_box bad = box;
    bad.hi[1] = bad.lo[1];
    CHECK(consph_nnps_create(&bad, 0.1, 0) == NULL, "empty box accepted");
    consph_nnps *g = consph_nnps_create(&box, 0.1, 0);
    CHECK(fabs(consph_nnps_radius(g) - 0.1) == 0.0, "radius reported");
    consph_particles p;
    consph_particles_init(&p, 3, 10, NULL);
    CHECK(consph_nnps_build(g, &p) == CONSPH_EINVAL, "dimension mismatch not rejected");
    consph_nbrs nb;
    memset(&nb, 0, sizeof nb);
    CHECK(consph_nnps_query_particle(g, 0, &nb) == (size_t)-1, "query on a failed build");
    consph_particles_free(&p);
    consph_particles_init(&p, 2, 10, &box);
    CHECK(consph_nnps_build(g, &p) == CONSPH_OK, "build");
    CHECK(consph_nnps_query_particle(g, 10, &nb) == (size_t)-1, "index past the end accepted");
    CHECK(consph_nnps_bytes(g) > 0, "bytes");
    consph_nbrs_free(&nb);
    consph_nnps_free(g);
    consph_particles_free(&p);
}

/* A lattice of spacing 1/8 (exact in binary) with radius 2/8: distances equal to the radius
 * must be excluded, so every particle has exactly 9 neighbours in 2D (itself, 4 edge and 4
 * diagonal neighbours) and 3 in 1D; in 3D 1 + 6 + 12 + 8 = 27. */
static void test_exact_lattice(void)
{
    static const size_t expected[4] = {0, 3, 9, 27};
    for (int dim = 1; dim <= 3; ++dim) {
        for (int cpr = 1; cpr <= 3; ++cpr) {
            consph_box box = consph_box_unit(dim, 1);
            size_t n = 1;
            for (int a = 0; a < dim; ++a) n *= 8;
            consph_particles p;
            consph_particles_init(&p, dim, n, &box);
            for (size_t i = 0; i < n; ++i) {
                size_t rest = i;
                for (int a = 0; a < dim; ++a) {
                    p.x[a][i] = (double)(rest % 8) * 0.125;
                    rest /= 8;
                }
            }
            consph_nnps *g = consph_nnps_create(&box, 0.25, cpr);
            consph_nnps_build(g, &p);
            consph_nbrs nb;
            memset(&nb, 0, sizeof nb);
            long wrong = 0;
            for (size_t i = 0; i < n; ++i)
                wrong += consph_nnps_query_particle(g, i, &nb) != expected[dim];
            CHECK(wrong == 0, "lattice %dD cpr %d: %ld particles without exactly %zu neighbours",
                  dim, cpr, wrong, expected[dim]);
            consph_nbrs_free(&nb);
            consph_nnps_free(g);
            consph_particles_free(&p);
        }
    }
}

/* The re-sort after a small step, as a solver makes it: few particles change cell, so the
 * permutation moves a minority of the slots (in runs, the first and the last slot among them),
 * and a sort that takes the build after the move as current (nnps_build_is_current) must leave
 * the particles, their fields and the permutation exactly as a sort that bins them afresh. */
static void test_resort_small_moves(void)
{
    consph_rng rng;
    consph_rng_seed(&rng, 7);
    for (int dim = 2; dim <= 3; ++dim) {
        const int periodic[3] = {1, 1, 0};
        const consph_box box = make_box(dim, periodic);
        const size_t n = 2000;
        consph_particles p, q;
        consph_particles_init(&p, dim, n, &box);
        fill_random(&p, &rng);
        double *id = consph_particles_field(&p, "id", 1);
        for (size_t i = 0; i < n; ++i) id[i] = (double)i;
        const double radius = radius_for(&box, n, 30.0);
        consph_nnps *g = consph_nnps_create(&box, radius, 0), *fresh = NULL;
        size_t *perm = malloc(n * sizeof *perm), *perm2 = malloc(n * sizeof *perm2);
        CHECK(consph_nnps_sort(g, &p, perm) == CONSPH_OK, "first sort: %s", consph_last_error());
        /* one particle in 50, and the first and last slots, moved by up to a fifth of a radius,
         * wrapped on the periodic axes; one coordinate exactly on a periodic upper bound */
        for (size_t i = 0; i < n; ++i) {
            if (i % 50 && i != 0 && i != n - 1) continue;
            for (int a = 0; a < dim; ++a) {
                const double L = box.hi[a] - box.lo[a];
                double x = p.x[a][i] + 0.2 * radius * (2.0 * consph_rng_uniform(&rng) - 1.0);
                if (box.periodic[a]) x = x < box.lo[a] ? x + L : x >= box.hi[a] ? x - L : x;
                p.x[a][i] = x;
            }
        }
        p.x[0][n / 2] = box.hi[0];
        consph_particles_copy(&q, &p);
        CHECK(consph_nnps_build(g, &p) == CONSPH_OK, "build after the move");
        nnps_build_is_current(g);
        CHECK(consph_nnps_sort(g, &p, perm) == CONSPH_OK, "re-sort on the current build: %s",
              consph_last_error());
        fresh = consph_nnps_create(&box, radius, 0);
        CHECK(consph_nnps_sort(fresh, &q, perm2) == CONSPH_OK, "fresh sort: %s",
              consph_last_error());
        size_t moved = 0;
        long differ = 0;
        const double *qid = consph_particles_find(&q, "id")->data;
        for (size_t i = 0; i < n; ++i) {
            moved += perm[i] != i;
            differ += perm[i] != perm2[i] || id[i] != qid[i];
            for (int a = 0; a < dim; ++a) differ += memcmp(&p.x[a][i], &q.x[a][i], sizeof(double));
        }
        CHECK(differ == 0, "%dD re-sort: %ld values differ from a sort binned afresh", dim, differ);
        CHECK(moved > 0 && moved < n / 2, "%dD re-sort after a small move moved %zu of %zu", dim,
              moved, n);
        check_all_particles(&p, radius, 0, dim == 2 ? "re-sorted 2D" : "re-sorted 3D");
        consph_nnps_free(fresh);
        consph_nnps_free(g);
        free(perm);
        free(perm2);
        consph_particles_free(&p);
        consph_particles_free(&q);
    }
}

int main(void)
{
    double t0 = consph_wtime();
    test_errors();
    test_zero_particles();
    test_one_particle();
    test_exact_lattice();
    test_random_sets();
    test_faces_and_boundaries();
    test_arbitrary_points();
    test_sort();
    test_resort_small_moves();
    test_thread_independence();
    test_cell_cap();
    printf("test_nnps: %.2f s\n", consph_wtime() - t0);
    return check_summary("test_nnps");
}
