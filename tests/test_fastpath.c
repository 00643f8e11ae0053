/* The fast pair path against the query path it replaces, bit for bit.
 *
 *  - traversal: for every particle, the runs of its cell (and, for points, consph_nnps_point_runs)
 *    tested with the header's consph_nnps_scan_run give exactly the neighbours of
 *    consph_nnps_query_particle (same j, order, x_ij and r); every implementation of
 *    consph_nnps_gather this machine runs (portable C, SSE2, AVX2, AVX-512) gives that again,
 *    with and without the optional outputs, nnps_gather_particles (the neighbours' particles
 *    written in place of their slots) gives it too, and on hand-made runs of every length 0..19 at
 *    every alignment (blocks of 4 and 8 ending anywhere, empty runs, shifted images) the
 *    header's consph_nnps_scan_run's hits, writing nothing past the promised slack. Sets: 1D-3D,
 * periodic, mixed and open boxes with particles outside, radii beyond half the box (several images
 * of one j), an unsorted set, a NaN particle, several cells per radius.
 *  - kernels: consph_kernel_eval_batch equals consph_kernel_w/dw/d2w for every kernel and
 *    dimension, at r = 0 (the W'' limit), on and around every piece boundary and beyond the
 *    support; a kernel with a replaced shape function uses it.
 *  - operators: the function, the F2 gradient and the summation volumes computed by the pass
 *    driver equal sums over consph_nnps_query_particle written out here, and the results are
 *    identical on 1 and 2 threads. */
#include "check.h"
#include "consph/consph.h"
#include "consph/ops.h"
#include "nnps/nnps_internal.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

static int same_bits(double a, double b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

typedef struct set_spec {
    const char *name;
    int dim;
    size_t n;
    int periodic[CONSPH_MAX_DIM];
    double radius;
    int cpr;
    int sort;
    int outside; /* scatter some particles up to 0.3 beyond the box on open axes */
    int nan;     /* give particle 3 a NaN coordinate */
} set_spec;

static void make_set(const set_spec *sp, consph_particles *p, uint64_t seed)
{
    consph_box box = consph_box_unit(sp->dim, 0);
    for (int a = 0; a < sp->dim; ++a) {
        box.lo[a] = -0.5 + 0.25 * a;
        box.hi[a] = box.lo[a] + 1.0 + 0.5 * a;
        box.periodic[a] = sp->periodic[a];
    }
    consph_particles_init(p, sp->dim, sp->n, &box);
    consph_rng rng;
    consph_rng_seed(&rng, seed);
    for (size_t i = 0; i < sp->n; ++i)
        for (int a = 0; a < sp->dim; ++a) {
            double len = box.hi[a] - box.lo[a], u = consph_rng_uniform(&rng);
            if (sp->outside && !box.periodic[a] && i % 7 == 0) u = 1.3 * u - 0.15;
            p->x[a][i] = box.lo[a] + u * len;
        }
    if (sp->nan && sp->n > 3) p->x[0][3] = NAN;
}

typedef struct bufs {
    size_t cap;
    size_t *slot;
    double *dx[CONSPH_MAX_DIM];
    double *r;
} bufs;

static void bufs_reserve(bufs *b, size_t need)
{
    if (need <= b->cap) return;
    b->cap = need;
    b->slot = realloc(b->slot, need * sizeof *b->slot);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) b->dx[a] = realloc(b->dx[a], need * sizeof(double));
    b->r = realloc(b->r, need * sizeof(double));
}

static void bufs_free(bufs *b)
{
    free(b->slot);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(b->dx[a]);
    free(b->r);
}

/* Compares hits (slots mapped to particles, x_ij and r where given) with a query result. */
static int same_as_query(const consph_nnps_slots *v, const consph_nbrs *q, size_t m,
                         const size_t *slot, double *const *dx, const double *r)
{
    if (m != q->n) return 0;
    for (size_t k = 0; k < m; ++k) {
        if (consph_nnps_slot_particle(v, slot[k]) != q->j[k]) return 0;
        if (r && !same_bits(r[k], q->r[k])) return 0;
        for (int a = 0; dx && a < v->dim; ++a)
            if (!same_bits(dx[a][k], q->dx[a][k])) return 0;
    }
    return 1;
}

/* Every gather implementation this machine runs, with all outputs, without x_ij and with the
 * slots only; returns the number of mismatches with the query. */
static int check_gathers(const consph_nnps_slots *v, const consph_nnps_runs *runs, const double *xi,
                         const consph_nbrs *q, bufs *b)
{
    int bad = 0;
    bufs_reserve(b, runs->candidates + CONSPH_NNPS_GATHER_SLACK);
    const int best = nnps_machine_isa();
    for (int isa = NNPS_ISA_C; isa <= best; ++isa) {
        size_t m = nnps_gather_runs(isa, v, runs->run, runs->n, xi, b->slot, b->dx, b->r, 0);
        bad += !same_as_query(v, q, m, b->slot, b->dx, b->r);
        m = nnps_gather_runs(isa, v, runs->run, runs->n, xi, b->slot, b->dx, NULL, 0);
        bad += !same_as_query(v, q, m, b->slot, b->dx, NULL);
        m = nnps_gather_runs(isa, v, runs->run, runs->n, xi, b->slot, NULL, b->r, 0);
        bad += !same_as_query(v, q, m, b->slot, NULL, b->r);
        m = nnps_gather_runs(isa, v, runs->run, runs->n, xi, b->slot, NULL, NULL, 0);
        bad += !same_as_query(v, q, m, b->slot, NULL, NULL);
    }
    size_t m = consph_nnps_gather(v, runs, xi, b->slot, b->dx, b->r);
    bad += !same_as_query(v, q, m, b->slot, b->dx, b->r);
    /* the particles written directly (the slots' buffer its scratch), as identity slots */
    size_t *particle = malloc((runs->candidates + CONSPH_NNPS_GATHER_SLACK) * sizeof *particle);
    if (!particle) return bad + 1;
    m = nnps_gather_particles(v, runs, xi, b->slot, particle, b->dx, b->r);
    const consph_nnps_slots ident = {.dim = v->dim, .particle = NULL};
    bad += !same_as_query(&ident, q, m, particle, b->dx, b->r);
    free(particle);
    return bad;
}

/* nnps_gather4 over each whole group of four slots of a cell (first..last), with and without
 * x_ij: each lane as the query of its particle. Returns the number of mismatches; counts the
 * groups it swept in *swept (none where the chosen gather has no such sweep). */
static int check_gather4(const consph_nnps *g, const consph_nnps_slots *v,
                         const consph_nnps_runs *runs, size_t first, size_t last, consph_nbrs *q,
                         bufs *b4, long *swept)
{
    int bad = 0;
    for (int l = 0; l < 4; ++l) bufs_reserve(&b4[l], runs->candidates + CONSPH_NNPS_GATHER_SLACK);
    for (size_t s = first; s + 4 <= last; s += 4)
        for (int with_dx = 0; with_dx < 2; ++with_dx) {
            size_t *slot[4], n[4];
            double *const *dx[4];
            double *r[4];
            for (int l = 0; l < 4; ++l) {
                slot[l] = b4[l].slot;
                dx[l] = with_dx ? b4[l].dx : NULL;
                r[l] = b4[l].r;
            }
            if (!nnps_gather4(v, runs->run, runs->n, s, slot, dx, r, n)) {
                bad += nnps_best_isa() == NNPS_ISA_AVX512;
                continue;
            }
            ++*swept;
            for (int l = 0; l < 4; ++l) {
                consph_nnps_query_particle(g, consph_nnps_slot_particle(v, s + (size_t)l), q);
                bad += !same_as_query(v, q, n[l], b4[l].slot, dx[l], b4[l].r);
            }
        }
    return bad;
}

static void test_traversal(const set_spec *sp)
{
    consph_particles p;
    make_set(sp, &p, 17 + (uint64_t)sp->n);
    consph_nnps *g = consph_nnps_create(&p.box, sp->radius, sp->cpr);
    CHECK(g != NULL, "%s: create: %s", sp->name, consph_last_error());
    if (!g) return;
    int st = sp->sort ? consph_nnps_sort(g, &p, NULL) : consph_nnps_build(g, &p);
    CHECK(st == CONSPH_OK, "%s: build: %s", sp->name, consph_last_error());
    consph_nnps_slots v;
    CHECK(consph_nnps_slots_get(g, &v) == CONSPH_OK, "%s: slots", sp->name);
    CHECK((v.particle == NULL) == (sp->sort != 0), "%s: identity map iff sorted", sp->name);
    consph_nnps_runs runs;
    memset(&runs, 0, sizeof runs);
    consph_nbrs q;
    memset(&q, 0, sizeof q);
    bufs b, b4[4];
    memset(&b, 0, sizeof b);
    memset(b4, 0, sizeof b4);
    long bad_scan = 0, bad_gather = 0, visited = 0, bad_group = 0, swept = 0, groups = 0;
    size_t pairs = 0, candidates = 0;
    for (size_t c = 0; c < v.ncells; ++c) {
        const size_t first = v.cell_start[c], last = v.cell_start[c + 1];
        if (first == last) continue;
        CHECK(consph_nnps_cell_runs(g, c, &runs) != (size_t)-1, "%s: runs of cell %zu", sp->name,
              c);
        bufs_reserve(&b, runs.candidates + CONSPH_NNPS_GATHER_SLACK);
        for (size_t s = first; s < last; ++s) {
            const size_t i = consph_nnps_slot_particle(&v, s);
            double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
            for (int a = 0; a < v.dim; ++a) xi[a] = v.x[a][s];
            consph_nnps_query_particle(g, i, &q);
            /* The header's inline hit test over the cell's runs. */
            size_t m = 0;
            for (size_t k = 0; k < runs.n; ++k)
                m = consph_nnps_scan_run(&v, &runs.run[k], xi, b.slot, b.dx, b.r, m);
            for (size_t k = 0; k < m; ++k) b.r[k] = sqrt(b.r[k]);
            bad_scan += !same_as_query(&v, &q, m, b.slot, b.dx, b.r);
            bad_gather += check_gathers(&v, &runs, xi, &q, &b);
            pairs += q.n;
            candidates += runs.candidates;
            ++visited;
        }
        bad_group += check_gather4(g, &v, &runs, first, last, &q, b4, &swept);
        groups += (long)((last - first) / 4);
    }
    CHECK(bad_group == 0, "%s: %ld lanes of four-point sweeps differ from the query", sp->name,
          bad_group);
    /* with and without x_ij, every whole group of every cell */
    if (nnps_best_isa() == NNPS_ISA_AVX512)
        CHECK(swept == 2 * groups, "%s: %ld of %ld four-point sweeps ran", sp->name, swept,
              2 * groups);
    CHECK(visited == (long)p.n, "%s: %ld of %zu particles visited", sp->name, visited, p.n);
    CHECK(bad_scan == 0, "%s: %ld particles whose scanned runs differ from the query", sp->name,
          bad_scan);
    CHECK(bad_gather == 0, "%s: %ld gathers differ from the query", sp->name, bad_gather);
    CHECK(pairs > p.n, "%s: only %zu pairs compared", sp->name, pairs);

    /* Arbitrary points, inside and outside the box, through their own runs. */
    consph_rng rng;
    consph_rng_seed(&rng, 99);
    long bad_points = 0;
    for (int t = 0; t < 200; ++t) {
        double x[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        for (int a = 0; a < sp->dim; ++a) {
            double len = p.box.hi[a] - p.box.lo[a];
            x[a] = p.box.lo[a] + (1.6 * consph_rng_uniform(&rng) - 0.3) * len;
        }
        consph_nnps_query(g, x, &q);
        CHECK(consph_nnps_point_runs(g, x, &runs) != (size_t)-1, "%s: point runs", sp->name);
        /* The runs see the point wrapped into the box, as the query does. */
        double xw[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        for (int a = 0; a < sp->dim; ++a) {
            double lo = p.box.lo[a], len = p.box.hi[a] - lo;
            xw[a] = x[a];
            if (p.box.periodic[a] && !(x[a] >= lo && x[a] < lo + len)) {
                xw[a] = x[a] - floor((x[a] - lo) / len) * len;
                if (!(xw[a] >= lo && xw[a] < lo + len)) xw[a] = lo;
            }
        }
        bad_points += check_gathers(&v, &runs, xw, &q, &b) != 0;
    }
    CHECK(bad_points == 0, "%s: %ld points whose runs differ from the query", sp->name, bad_points);
    printf("traversal %-28s %6zu particles, %8zu pairs, %.2f candidates per pair\n", sp->name, p.n,
           pairs, pairs ? (double)candidates / (double)pairs : 0.0);
    bufs_free(&b);
    for (int l = 0; l < 4; ++l) bufs_free(&b4[l]);
    consph_nbrs_free(&q);
    consph_nnps_runs_free(&runs);
    consph_nnps_free(g);
    consph_particles_free(&p);
}

/* Hand-made runs over the slots of one set, against the header's consph_nnps_scan_run followed
 * by sqrt: single runs of every length 0..19 (ending at every offset of an 8-wide and of a
 * 4-wide block, empty ones included) from starts that put them at every alignment, the last
 * ones ending at the last slot (the vector paths must not take the padding for candidates),
 * lists of three runs of lengths 0..9 with different image shifts (a block's hits appended
 * behind another run's), appended from entry 0 and 5; every implementation this machine runs,
 * every combination of the optional outputs. Entries before the start and past count +
 * CONSPH_NNPS_GATHER_SLACK must be left alone. Returns the number of mismatching gathers. */
enum { EDGE_MAX = 32, EDGE_GUARD = 8 };

typedef struct edge_case {
    const consph_nnps_slots *v;
    const double *xi;
    const consph_nnps_run *run;
    size_t nruns;
} edge_case;

static long check_edge_case(const edge_case *e, long *hits, long *candidates)
{
    const consph_nnps_slots *v = e->v;
    const size_t cap = 5 + EDGE_MAX + CONSPH_NNPS_GATHER_SLACK + EDGE_GUARD;
    size_t ref_slot[EDGE_MAX], slot[5 + EDGE_MAX + CONSPH_NNPS_GATHER_SLACK + EDGE_GUARD];
    double ref_dx[CONSPH_MAX_DIM][EDGE_MAX], ref_r[EDGE_MAX];
    double dxs[CONSPH_MAX_DIM][5 + EDGE_MAX + CONSPH_NNPS_GATHER_SLACK + EDGE_GUARD];
    double rs[5 + EDGE_MAX + CONSPH_NNPS_GATHER_SLACK + EDGE_GUARD];
    double *ref_dxp[CONSPH_MAX_DIM] = {ref_dx[0], ref_dx[1], ref_dx[2]};
    size_t cand = 0, ref = 0;
    for (size_t k = 0; k < e->nruns; ++k) {
        cand += e->run[k].s1 - e->run[k].s0;
        ref = consph_nnps_scan_run(v, &e->run[k], e->xi, ref_slot, ref_dxp, ref_r, ref);
    }
    for (size_t k = 0; k < ref; ++k) ref_r[k] = sqrt(ref_r[k]);
    *hits += (long)ref;
    *candidates += (long)cand;
    long bad = 0;
    for (int isa = NNPS_ISA_C; isa <= nnps_machine_isa(); ++isa)
        for (int want = 0; want < 4; ++want)
            for (size_t n0 = 0; n0 <= 5; n0 += 5) {
                const int with_dx = want & 1, with_r = want & 2;
                for (size_t k = 0; k < cap; ++k) {
                    slot[k] = (size_t)0x5eed + k;
                    rs[k] = -1.0 - (double)k;
                    for (int a = 0; a < CONSPH_MAX_DIM; ++a) dxs[a][k] = -2.0 - (double)k;
                }
                double *dx[CONSPH_MAX_DIM] = {dxs[0], dxs[1], dxs[2]};
                const size_t m = nnps_gather_runs(isa, v, e->run, e->nruns, e->xi, slot,
                                                  with_dx ? dx : NULL, with_r ? rs : NULL, n0);
                int ok = m == n0 + ref;
                for (size_t k = 0; ok && k < ref; ++k) {
                    ok = slot[n0 + k] == ref_slot[k];
                    if (with_r) ok = ok && same_bits(rs[n0 + k], ref_r[k]);
                    for (int a = 0; with_dx && a < v->dim; ++a)
                        ok = ok && same_bits(dxs[a][n0 + k], ref_dx[a][k]);
                }
                /* untouched: before the start, past the room the header promises */
                for (size_t k = 0; k < cap; ++k) {
                    if (k >= n0 && k < n0 + cand + CONSPH_NNPS_GATHER_SLACK) continue;
                    ok = ok && slot[k] == (size_t)0x5eed + k && rs[k] == -1.0 - (double)k;
                    for (int a = 0; a < CONSPH_MAX_DIM; ++a)
                        ok = ok && dxs[a][k] == -2.0 - (double)k;
                }
                if (!ok && bad < 3)
                    printf("  run edges: dim %d, isa %d, outputs %d, from %zu: %zu hits, expected "
                           "%zu\n",
                           v->dim, isa, want, n0, m - n0, ref);
                bad += !ok;
            }
    return bad;
}

static void test_run_edges(int dim)
{
    const set_spec sp = {"run edges", dim, 120, {1, 1, 1}, 0.0, 0, 1, 0, 0};
    consph_particles p;
    make_set(&sp, &p, 31 + (uint64_t)dim);
    /* hits and misses mixed in most blocks */
    const double radius = 0.3 + 0.3 * (dim - 1);
    consph_nnps *g = consph_nnps_create(&p.box, radius, 0);
    CHECK(g && consph_nnps_sort(g, &p, NULL) == CONSPH_OK, "run edges %dD: build: %s", dim,
          consph_last_error());
    consph_nnps_slots v;
    CHECK(consph_nnps_slots_get(g, &v) == CONSPH_OK, "run edges %dD: slots", dim);
    const double shifts[3][CONSPH_MAX_DIM] = {{0.0, 0.0, 0.0}, {0.25, -0.5, 0.0}, {-0.3, 0.2, 0.4}};
    long bad = 0, cases = 0, hits = 0, candidates = 0;
    for (size_t q = 0; q < v.n; q += 37) {
        double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        for (int a = 0; a < dim; ++a) xi[a] = v.x[a][q];
        consph_nnps_run run[3];
        for (int t = 0; t < 3; ++t)
            for (int a = 0; a < CONSPH_MAX_DIM; ++a) run[t].shift[a] = a < dim ? shifts[t][a] : 0.0;
        edge_case e = {&v, xi, run, 1};
        const size_t starts[] = {0, 1, 2, 3, 4, 5, 6, 7, 13};
        for (size_t len = 0; len < 20; ++len) {
            for (size_t t = 0; t <= sizeof starts / sizeof starts[0]; ++t) {
                /* the last start: the run ends at the last slot */
                run[0].s0 = t < sizeof starts / sizeof starts[0] ? starts[t] : v.n - len;
                run[0].s1 = run[0].s0 + len;
                bad += check_edge_case(&e, &hits, &candidates);
                ++cases;
            }
        }
        e.nruns = 3;
        for (size_t a = 0; a < 10; ++a)
            for (size_t b = 0; b < 10; ++b)
                for (size_t c = 0; c < 10; c += 3) {
                    run[0].s0 = 3 * q % 50;
                    run[0].s1 = run[0].s0 + a;
                    run[1].s0 = 60 + b;
                    run[1].s1 = run[1].s0 + b;
                    run[2].s0 = v.n - c;
                    run[2].s1 = v.n;
                    bad += check_edge_case(&e, &hits, &candidates);
                    ++cases;
                }
    }
    CHECK(bad == 0, "run edges %dD: %ld of %ld gathers differ from consph_nnps_scan_run", dim, bad,
          cases);
    CHECK(hits > candidates / 5 && hits < candidates - candidates / 5,
          "run edges %dD: %ld hits of %ld candidates, too few hits or too few misses", dim, hits,
          candidates);
    printf("run edges %dD: %ld gathers, %ld hits of %ld candidates\n", dim, cases, hits,
           candidates);
    consph_nnps_free(g);
    consph_particles_free(&p);
}

static void test_traversal_errors(void)
{
    consph_box box = consph_box_unit(2, 1);
    consph_nnps *g = consph_nnps_create(&box, 0.1, 0);
    consph_nnps_slots v;
    consph_nnps_runs runs;
    memset(&runs, 0, sizeof runs);
    CHECK(consph_nnps_slots_get(g, &v) == CONSPH_EINVAL, "slots of an unbuilt search");
    CHECK(consph_nnps_cell_runs(g, 0, &runs) == (size_t)-1, "runs of an unbuilt search");
    consph_particles p;
    consph_particles_init(&p, 2, 4, &box);
    for (size_t i = 0; i < 4; ++i) p.x[0][i] = p.x[1][i] = 0.2 * (double)i;
    consph_nnps_build(g, &p);
    CHECK(consph_nnps_cell_runs(g, consph_nnps_cells(g), &runs) == (size_t)-1 &&
              strstr(consph_last_error(), "not in the search grid") != NULL,
          "cell out of range: %s", consph_last_error());
    consph_nnps_runs_free(&runs);
    consph_nnps_free(g);
    consph_particles_free(&p);
}

static double custom_f(double q)
{
    return q < 1.0 ? 1.0 - q : 0.0;
}

static void test_kernel_batch(void)
{
    enum { M = 4000 };
    static double r[M], w[M], dwr[M], d2w[M], w2[M];
    long bad = 0, compared = 0;
    for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id)
        for (int dim = 1; dim <= 3; ++dim) {
            consph_kernel k;
            consph_kernel_init(&k, (consph_kernel_id)id, dim, 0.37);
            size_t m = 0;
            r[m++] = 0.0;
            for (int t = 1; t < M - 40; ++t) r[m++] = k.radius * 1.2 * t / (M - 40);
            for (int piece = 1; piece <= 3; ++piece) {
                double edge = piece * k.h;
                r[m++] = edge;
                r[m++] = nextafter(edge, 0.0);
                r[m++] = nextafter(edge, 10.0);
            }
            r[m++] = k.radius;
            r[m++] = nextafter(k.radius, 0.0);
            r[m++] = 1e300;
            consph_kernel_eval_batch(&k, m, r, w, dwr, d2w);
            consph_kernel_eval_batch(&k, m, r, w2, NULL, NULL);
            for (size_t t = 0; t < m; ++t) {
                double ew = consph_kernel_w(&k, r[t]), ed2 = consph_kernel_d2w(&k, r[t]);
                double edwr =
                    r[t] > 0.0 ? consph_kernel_dw(&k, r[t]) / r[t] : consph_kernel_d2w(&k, 0.0);
                bad += !same_bits(w[t], ew) || !same_bits(dwr[t], edwr) ||
                       !same_bits(d2w[t], ed2) || !same_bits(w2[t], ew);
                ++compared;
            }
        }
    CHECK(bad == 0, "%ld of %ld batch kernel values differ from the scalar path", bad, compared);
    consph_kernel k;
    consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 2, 1.0);
    k.f = custom_f;
    double rr[3] = {0.25, 0.5, 2.0}, ww[3];
    consph_kernel_eval_batch(&k, 3, rr, ww, NULL, NULL);
    CHECK(ww[0] == k.norm * 0.75 && ww[1] == k.norm * 0.5 && ww[2] == 0.0,
          "a replaced shape function is used: %g %g %g", ww[0], ww[1], ww[2]);
}

/* Reference operators written out over consph_nnps_query_particle, with the expressions of the
 * operator visitors (src/ops): the pass driver must reproduce them bit for bit. */
static void reference_ops(const consph_op_ctx *ctx, const double *f, double *fun, double *grad,
                          double *rho)
{
    const consph_kernel *k = &ctx->kernel;
    const size_t n = ctx->n;
    const int d = ctx->dim;
    consph_nbrs q;
    memset(&q, 0, sizeof q);
    for (size_t i = 0; i < n; ++i) {
        consph_nnps_query_particle(ctx->nnps, i, &q);
        double s = 0.0, m = 0.0, g[3] = {0.0, 0.0, 0.0};
        for (size_t p = 0; p < q.n; ++p) {
            const size_t j = q.j[p];
            const double w = consph_kernel_w(k, q.r[p]);
            const double dwr =
                q.r[p] > 0.0 ? consph_kernel_dw(k, q.r[p]) / q.r[p] : consph_kernel_d2w(k, 0.0);
            const double ww = ctx->volume[j] * w;
            s += ww * f[j];
            m += ctx->mass[j] * w;
            const double t = ctx->volume[j] * (f[j] - f[i]) * dwr;
            for (int a = 0; a < d; ++a) g[a] += t * q.dx[a][p];
        }
        fun[i] = s;
        rho[i] = m;
        for (int a = 0; a < d; ++a) grad[(size_t)a * n + i] = g[a];
    }
    consph_nbrs_free(&q);
}

static void test_operators(const set_spec *sp)
{
    consph_particles p;
    make_set(sp, &p, 5 + (uint64_t)sp->dim);
    consph_kernel k;
    consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, sp->dim, sp->radius / 3.0);
    consph_nnps *g = consph_nnps_create(&p.box, k.radius, sp->cpr);
    int st = sp->sort ? consph_nnps_sort(g, &p, NULL) : consph_nnps_build(g, &p);
    consph_op_ctx ctx;
    st = st ? st : consph_op_ctx_init(&ctx, &p, g, &k, CONSPH_VOLUME_SUMMATION);
    CHECK(st == CONSPH_OK, "%s: context: %s", sp->name, consph_last_error());
    if (st != CONSPH_OK) return;
    ctx.parallel_min = 0;
    const size_t n = p.n;
    double *f = malloc(n * sizeof *f), *fun = malloc(n * sizeof *fun);
    double *grad = malloc(3 * n * sizeof *grad), *rho = malloc(n * sizeof *rho);
    double *out = malloc(3 * n * sizeof *out), *out2 = malloc(3 * n * sizeof *out2);
    for (size_t i = 0; i < n; ++i)
        f[i] = 1.0 + p.x[0][i] * p.x[0][i] - (sp->dim > 1 ? 2.0 * p.x[1][i] : 0.0);
    reference_ops(&ctx, f, fun, grad, rho);
    long bad = 0;
    for (size_t i = 0; i < n; ++i) bad += !same_bits(ctx.volume[i], ctx.mass[i] / rho[i]);
    CHECK(bad == 0, "%s: %ld summation volumes differ from the query reference", sp->name, bad);
    int threads[2] = {1, 2};
    for (int t = 0; t < 2; ++t) {
#ifdef _OPENMP
        omp_set_num_threads(threads[t]);
#endif
        double *o = t == 0 ? out : out2;
        consph_op_report rep;
        st = consph_apply(&ctx, CONSPH_OP_FUNCTION, CONSPH_FORM_STANDARD, CONSPH_CORR_NONE, f, o,
                          &rep);
        CHECK(st == CONSPH_OK, "%s: function: %s", sp->name, consph_last_error());
        bad = 0;
        for (size_t i = 0; i < n; ++i) bad += !same_bits(o[i], fun[i]);
        CHECK(bad == 0, "%s, %d threads: %ld function values differ from the query reference",
              sp->name, threads[t], bad);
        st = consph_apply(&ctx, CONSPH_OP_GRAD, CONSPH_FORM_F2, CONSPH_CORR_NONE, f, o, &rep);
        CHECK(st == CONSPH_OK, "%s: f2: %s", sp->name, consph_last_error());
        bad = 0;
        for (size_t e = 0; e < (size_t)sp->dim * n; ++e) bad += !same_bits(o[e], grad[e]);
        CHECK(bad == 0, "%s, %d threads: %ld F2 gradient values differ from the query reference",
              sp->name, threads[t], bad);
        st = consph_apply(&ctx, CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_CORR_BC, f, o, &rep);
        CHECK(st == CONSPH_OK, "%s: asym_bc: %s", sp->name, consph_last_error());
    }
    CHECK(memcmp(out, out2, (size_t)sp->dim * n * sizeof *out) == 0,
          "%s: asym_bc differs between 1 and 2 threads", sp->name);
#ifdef _OPENMP
    omp_set_num_threads(1);
#endif
    free(f);
    free(fun);
    free(grad);
    free(rho);
    free(out);
    free(out2);
    consph_op_ctx_free(&ctx);
    consph_nnps_free(g);
    consph_particles_free(&p);
}

int main(void)
{
    const set_spec sets[] = {
        {"1D periodic", 1, 300, {1, 0, 0}, 0.05, 0, 1, 0, 0},
        {"1D open, outside, NaN", 1, 300, {0, 0, 0}, 0.05, 0, 0, 1, 1},
        {"2D periodic sorted", 2, 1500, {1, 1, 0}, 0.08, 0, 1, 0, 0},
        {"2D periodic unsorted cpr 3", 2, 1500, {1, 1, 0}, 0.08, 3, 0, 0, 0},
        {"2D mixed, outside", 2, 1200, {1, 0, 0}, 0.1, 2, 0, 1, 0},
        {"2D radius > half box", 2, 60, {1, 1, 0}, 0.9, 0, 0, 0, 0},
        {"2D open, NaN", 2, 800, {0, 0, 0}, 0.09, 1, 1, 0, 1},
        {"3D periodic sorted", 3, 3000, {1, 1, 1}, 0.2, 0, 1, 0, 0},
        {"3D mixed unsorted", 3, 2000, {0, 1, 1}, 0.22, 0, 0, 1, 0},
        {"3D radius > box", 3, 40, {1, 1, 1}, 1.3, 1, 1, 0, 0},
    };
    const size_t nsets = sizeof sets / sizeof sets[0];
    for (size_t k = 0; k < nsets; ++k) test_traversal(&sets[k]);
    for (int dim = 1; dim <= 3; ++dim) test_run_edges(dim);
    test_traversal_errors();
    test_kernel_batch();
    const set_spec op_sets[] = {
        {"ops 2D periodic unsorted", 2, 1600, {1, 1, 0}, 0.12, 0, 0, 0, 0},
        {"ops 2D open sorted", 2, 1600, {0, 0, 0}, 0.12, 0, 1, 0, 0},
        {"ops 3D periodic sorted", 3, 3000, {1, 1, 1}, 0.25, 0, 1, 0, 0},
        {"ops 1D open", 1, 400, {0, 0, 0}, 0.03, 0, 0, 0, 0},
    };
    for (size_t k = 0; k < sizeof op_sets / sizeof op_sets[0]; ++k) test_operators(&op_sets[k]);
    static const char *const isa_names[] = {"portable C", "SSE2", "AVX2", "AVX-512"};
    printf("gather implementations checked: up to %s (consph_nnps_gather uses %s)\n",
           isa_names[nnps_machine_isa()], isa_names[nnps_best_isa()]);
    return check_summary("test_fastpath");
}
