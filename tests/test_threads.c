/* The step's per-particle sweeps on the threads give the serial bits: the neighbour search's
 * build (its stable counting sort split over the threads), the re-sort's permutation, consph_sum,
 * and whole solver steps of the schemes and integrators whose O(N) parts run on the threads,
 * at sizes above every threshold from which those parts go parallel. The thread counts 1, 2 and
 * 3 (3: slices that do not halve evenly). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/nnps.h"
#include "consph/solver.h"
#include "nnps/nnps_internal.h"

static const int thread_counts[] = {1, 2, 3};
#define NCOUNTS 3

static void fill_random(consph_particles *p, consph_rng *rng, double spill)
{
    for (size_t i = 0; i < p->n; ++i)
        for (int a = 0; a < p->dim; ++a) {
            const double lo = p->box.lo[a], len = p->box.hi[a] - lo;
            /* spill: a fraction of the coordinates up to half a period outside the box (wrapped
             * by the build on a periodic axis, kept in the boundary cells on the others) */
            const double u = consph_rng_uniform(rng);
            const double out = u < spill ? (consph_rng_uniform(rng) - 0.5) : 0.0;
            p->x[a][i] = lo + (consph_rng_uniform(rng) + out) * len;
        }
}

/* A build's slots as the properties of a stable counting sort by cell, independently of how
 * the build made them: cells ascend with the slot, each particle is in its own cell, particles
 * ascend within a cell, and every slot holds the particle's stored coordinate. */
static int stable_by_cell(const consph_nnps *g, const consph_particles *p)
{
    consph_nnps_slots v;
    if (consph_nnps_slots_get(g, &v) != CONSPH_OK || v.n != p->n) return 0;
    int64_t nc[CONSPH_MAX_DIM], reach[CONSPH_MAX_DIM];
    double edge[CONSPH_MAX_DIM];
    nnps_grid(g, nc, reach, edge);
    unsigned char *seen = calloc(p->n ? p->n : 1, 1);
    int ok = seen != NULL && v.cell_start[0] == 0 && v.cell_start[v.ncells] == v.n;
    for (size_t c = 0; ok && c < v.ncells; ++c) {
        for (size_t s = v.cell_start[c]; ok && s < v.cell_start[c + 1]; ++s) {
            const size_t i = v.particle ? v.particle[s] : s;
            ok = i < p->n && !seen[i];
            if (!ok) break;
            seen[i] = 1;
            if (s > v.cell_start[c]) {
                const size_t prev = v.particle ? v.particle[s - 1] : s - 1;
                ok = prev < i;
            }
            size_t cell = 0;
            for (int a = p->dim - 1; a >= 0; --a)
                cell = cell * (size_t)nc[a] + (size_t)nnps_axis_cell(g, a, p->x[a][i]);
            ok = ok && cell == c;
            for (int a = 0; a < p->dim && ok; ++a) {
                const double lo = p->box.lo[a], hi = p->box.hi[a];
                const double want =
                    p->box.periodic[a] ? nnps_wrap(p->x[a][i], lo, hi, hi - lo) : p->x[a][i];
                ok = memcmp(&want, &v.x[a][s], sizeof want) == 0;
            }
        }
    }
    free(seen);
    return ok;
}

static int same_slots(const consph_nnps *g1, const consph_nnps *g2)
{
    consph_nnps_slots a, b;
    if (consph_nnps_slots_get(g1, &a) != CONSPH_OK || consph_nnps_slots_get(g2, &b) != CONSPH_OK)
        return 0;
    if (a.n != b.n || a.ncells != b.ncells || !a.particle != !b.particle) return 0;
    if (memcmp(a.cell_start, b.cell_start, (a.ncells + 1) * sizeof(size_t))) return 0;
    if (a.particle && memcmp(a.particle, b.particle, a.n * sizeof(size_t))) return 0;
    for (int d = 0; d < a.dim; ++d)
        if (memcmp(a.x[d], b.x[d], a.n * sizeof(double))) return 0;
    return 1;
}

/* Builds of random particles in 1D-3D, every axis periodic or none or some, some coordinates
 * outside the box: the same slots at every thread count, a stable sort by cell each. */
static void test_build(void)
{
    static const int patterns[][3] = {{1, 1, 1}, {0, 0, 0}, {1, 0, 1}};
    consph_rng rng;
    consph_rng_seed(&rng, 2611);
    for (int dim = 1; dim <= 3; ++dim)
        for (int pat = 0; pat < 3; ++pat)
            for (int spill = 0; spill < 2; ++spill) {
                consph_box box = consph_box_unit(dim, 0);
                for (int a = 0; a < dim; ++a) {
                    box.lo[a] = -0.3 * (a + 1);
                    box.hi[a] = 0.9 + 0.2 * a;
                    box.periodic[a] = patterns[pat][a];
                }
                consph_particles p;
                const size_t n = 9001; /* above the build's threshold for the threads */
                CHECK(consph_particles_init(&p, dim, n, &box) == CONSPH_OK, "init");
                fill_random(&p, &rng, spill ? 0.05 : 0.0);
                const double radius = dim == 1 ? 0.004 : dim == 2 ? 0.05 : 0.15;
                consph_nnps *g[NCOUNTS];
                for (int t = 0; t < NCOUNTS; ++t) {
                    check_set_threads(thread_counts[t]);
                    g[t] = consph_nnps_create(&box, radius, 0);
                    CHECK(g[t] && consph_nnps_build(g[t], &p) == CONSPH_OK, "build: %s",
                          consph_last_error());
                }
                check_set_threads(1);
                CHECK(stable_by_cell(g[0], &p),
                      "%dD pattern %d spill %d: not a stable sort by cell", dim, pat, spill);
                for (int t = 1; t < NCOUNTS; ++t)
                    CHECK(same_slots(g[0], g[t]) && stable_by_cell(g[t], &p),
                          "%dD pattern %d spill %d: %d threads build other slots than 1", dim, pat,
                          spill, thread_counts[t]);
                for (int t = 0; t < NCOUNTS; ++t) consph_nnps_free(g[t]);
                consph_particles_free(&p);
            }
}

/* The re-sort of particles carrying fields: at every thread count the same permutation, and
 * every array new[s] = old[perm[s]]. */
static void test_sort(void)
{
    consph_box box = consph_box_unit(2, 1);
    consph_rng rng;
    consph_rng_seed(&rng, 77);
    const size_t n = 12000;
    consph_particles base;
    CHECK(consph_particles_init(&base, 2, n, &box) == CONSPH_OK, "init");
    fill_random(&base, &rng, 0.0);
    double *f1 = consph_particles_field(&base, "s", 1), *f3 = consph_particles_field(&base, "v", 3);
    CHECK(f1 && f3, "fields");
    if (!f1 || !f3) return;
    for (size_t i = 0; i < n; ++i) {
        f1[i] = (double)i;
        for (int c = 0; c < 3; ++c) f3[c * base.cap + i] = (double)i + 0.25 * c;
    }
    consph_particles p[NCOUNTS];
    size_t *perm[NCOUNTS];
    for (int t = 0; t < NCOUNTS; ++t) {
        check_set_threads(thread_counts[t]);
        CHECK(consph_particles_copy(&p[t], &base) == CONSPH_OK, "copy");
        consph_nnps *g = consph_nnps_create(&box, 0.02, 0);
        perm[t] = malloc(n * sizeof(size_t));
        CHECK(g && perm[t] && consph_nnps_sort(g, &p[t], perm[t]) == CONSPH_OK, "sort: %s",
              consph_last_error());
        consph_nnps_free(g);
    }
    check_set_threads(1);
    size_t wrong = 0;
    for (size_t s = 0; s < n; ++s) {
        const size_t o = perm[0][s];
        wrong += o >= n || p[0].x[0][s] != base.x[0][o] || p[0].x[1][s] != base.x[1][o];
        const double *g1 = consph_particles_field(&p[0], "s", 1);
        const double *g3 = consph_particles_field(&p[0], "v", 3);
        wrong += g1[s] != (double)o;
        for (int c = 0; c < 3; ++c) wrong += g3[c * p[0].cap + s] != (double)o + 0.25 * c;
    }
    CHECK(wrong == 0, "%zu values are not new[s] = old[perm[s]]", wrong);
    for (int t = 1; t < NCOUNTS; ++t) {
        int same = !memcmp(perm[0], perm[t], n * sizeof(size_t));
        for (int a = 0; a < 2 && same; ++a)
            same = !memcmp(p[0].x[a], p[t].x[a], n * sizeof(double));
        for (int f = 0; f < 2 && same; ++f)
            for (int c = 0; c < p[0].fields[f].ncomp && same; ++c)
                same = !memcmp(p[0].fields[f].data + c * p[0].cap,
                               p[t].fields[f].data + c * p[t].cap, n * sizeof(double));
        CHECK(same, "the re-sort on %d threads differs from 1", thread_counts[t]);
    }
    for (int t = 0; t < NCOUNTS; ++t) {
        consph_particles_free(&p[t]);
        free(perm[t]);
    }
    consph_particles_free(&base);
}

/* consph_sum at every thread count, sizes on both sides of the threads' threshold and not
 * multiples of a block: the same bits, and within round-off of a compensated sum. */
static void test_sum(void)
{
    static const size_t sizes[] = {1000, 8191, 8192, 16384, 70001, 250000};
    consph_rng rng;
    consph_rng_seed(&rng, 5);
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; ++k) {
        const size_t n = sizes[k];
        double *a = malloc(n * sizeof *a);
        if (!a) return;
        for (size_t i = 0; i < n; ++i)
            a[i] = (consph_rng_uniform(&rng) - 0.3) * pow(10.0, 6.0 * consph_rng_uniform(&rng));
        double sum[NCOUNTS], strided[NCOUNTS];
        for (int t = 0; t < NCOUNTS; ++t) {
            check_set_threads(thread_counts[t]);
            sum[t] = consph_sum(a, n);
            strided[t] = consph_sum_strided(a, n / 2, 2);
        }
        check_set_threads(1);
        double kahan = 0.0, comp = 0.0, mag = 0.0;
        for (size_t i = 0; i < n; ++i) {
            const double y = a[i] - comp, t = kahan + y;
            comp = (t - kahan) - y;
            kahan = t;
            mag += fabs(a[i]);
        }
        CHECK(fabs(sum[0] - kahan) <= 1e-13 * mag, "n %zu: sum %.17g, compensated %.17g", n, sum[0],
              kahan);
        for (int t = 1; t < NCOUNTS; ++t)
            CHECK(!memcmp(&sum[0], &sum[t], sizeof sum[0]) &&
                      !memcmp(&strided[0], &strided[t], sizeof strided[0]),
                  "n %zu: %d threads sum %.17g (strided %.17g), 1 thread %.17g (%.17g)", n,
                  thread_counts[t], sum[t], strided[t], sum[0], strided[0]);
        free(a);
    }
}

/* Solver steps above every threshold of the step's parallel sweeps (nx 72: 5184 particles; 3D
 * nx 18: 5832): the integrators' updates and drift, the wrap, the build, the re-sort, the
 * closure and transport hooks, the checks. */
static void test_steps(const char *problem, const char *scheme, const char *integrator, int nx)
{
    consph_run_params prm;
    consph_run_params_default(&prm);
    CHECK(consph_run_params_problem(&prm, problem) == CONSPH_OK, "%s", consph_last_error());
    snprintf(prm.scheme, sizeof prm.scheme, "%s", scheme);
    snprintf(prm.integrator, sizeof prm.integrator, "%s", integrator);
    prm.nx = nx;
    prm.steps = 4;
    prm.tf = 0.0;
    prm.layout = CONSPH_LAYOUT_LATTICE;
    prm.log_every = 2;
    consph_solver *s[NCOUNTS] = {NULL};
    for (int t = 0; t < NCOUNTS; ++t) {
        check_set_threads(thread_counts[t]);
        int st = consph_solver_create(&s[t], &prm);
        CHECK(st == CONSPH_OK, "%s %s %s: %s", problem, scheme, integrator, consph_last_error());
        while (st == CONSPH_OK && !consph_solver_done(s[t])) st = consph_solver_step(s[t]);
        CHECK(st == CONSPH_OK, "%s %s %s: %s", problem, scheme, integrator, consph_last_error());
    }
    check_set_threads(1);
    for (int t = 1; t < NCOUNTS; ++t)
        CHECK(
            s[0] && s[t] &&
                check_particles_equal(consph_solver_particles(s[0]), consph_solver_particles(s[t])),
            "%s %s %s: %d threads differ from 1", problem, scheme, integrator, thread_counts[t]);
    for (int t = 0; t < NCOUNTS; ++t) consph_solver_free(s[t]);
}

int main(void)
{
    double t0 = consph_wtime();
    test_build();
    test_sort();
    test_sum();
    test_steps("taylor-green", "wcsph", "", 72);
    test_steps("taylor-green", "tvf", "", 72);
    test_steps("taylor-green", "edac", "", 72);
    test_steps("taylor-green", "wcsph", "kdk", 72);
    test_steps("taylor-green", "edac", "ssprk3", 72);
    test_steps("taylor-green", "l-ipst-c", "", 72);
    test_steps("beltrami", "wcsph", "", 18);
    printf("test_threads: %.2f s\n", consph_wtime() - t0);
    return check_summary("test_threads");
}
