/* Tests of the layout module: lattice positions, the random perturbation of 002, Halton
 * quasi-random points, the packed arrangement of 001, and the layout statistics against brute
 * force. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/consph.h"

static int same_positions(const consph_particles *a, const consph_particles *b)
{
    if (a->n != b->n || a->dim != b->dim) return 0;
    for (int d = 0; d < a->dim; ++d)
        if (memcmp(a->x[d], b->x[d], a->n * sizeof(double)) != 0) return 0;
    return 1;
}

static int inside_box(const consph_particles *p)
{
    for (int d = 0; d < p->dim; ++d)
        for (size_t i = 0; i < p->n; ++i)
            if (!(p->x[d][i] >= p->box.lo[d] && p->x[d][i] < p->box.hi[d])) return 0;
    return 1;
}

/* Minimum-image separation on a fully periodic box. */
static double periodic_dist(const consph_particles *p, size_t i, size_t j)
{
    double r2 = 0.0;
    for (int d = 0; d < p->dim; ++d) {
        double len = p->box.hi[d] - p->box.lo[d];
        double dx = p->x[d][i] - p->x[d][j];
        dx -= len * round(dx / len);
        r2 += dx * dx;
    }
    return sqrt(r2);
}

static void test_names(void)
{
    consph_layout_kind k;
    for (int i = 0; i < CONSPH_LAYOUT_COUNT; ++i) {
        CHECK(consph_layout_lookup(consph_layout_name((consph_layout_kind)i), &k) == CONSPH_OK &&
                  k == (consph_layout_kind)i,
              "name round trip for kind %d", i);
    }
    CHECK(consph_layout_lookup("hexagonal", &k) == CONSPH_EINVAL, "unknown kind is EINVAL");
    CHECK(strstr(consph_last_error(), "hexagonal") && strstr(consph_last_error(), "quasi-random"),
          "message names the value and the allowed kinds: %s", consph_last_error());
}

static void test_lattice(void)
{
    /* A 2x1 box with 8x4 particles: Δs = 0.25 on both axes. */
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 2, 4);
    lp.box.lo[0] = -1.0;
    lp.box.hi[0] = 1.0;
    lp.nx[0] = 8;
    consph_particles p;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "lattice: %s", consph_last_error());
    CHECK(p.n == 32, "count %zu == 8*4", p.n);
    CHECK(p.spacing == 0.25, "spacing %g", p.spacing);
    int exact = 1;
    for (size_t iy = 0; iy < 4; ++iy)
        for (size_t ix = 0; ix < 8; ++ix) {
            size_t i = ix + 8 * iy;
            exact &= p.x[0][i] == -1.0 + ((double)ix + 0.5) * 0.25;
            exact &= p.x[1][i] == ((double)iy + 0.5) * 0.25;
        }
    CHECK(exact, "lattice positions are lo + (i + 1/2) Δs exactly, axis 0 fastest");
    const consph_field *vol = consph_particles_find(&p, "volume");
    CHECK(vol && vol->ncomp == 1, "volume field present");
    if (vol) {
        int ok = 1;
        for (size_t i = 0; i < p.n; ++i) ok &= vol->data[i] == 2.0 / 32.0;
        CHECK(ok, "volume = box volume / N");
    }
    consph_particles_free(&p);

    lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 3, 5);
    lp.nx[2] = 5;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "3D lattice");
    CHECK(p.n == 125, "3D count %zu", p.n);
    CHECK(p.x[2][124] == 0.9 && p.x[0][0] == 0.1, "3D corners %g %g", p.x[2][124], p.x[0][0]);
    consph_particles_free(&p);

    lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 2, 4);
    lp.nx[1] = 5; /* Δs 0.25 vs 0.2 */
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_EINVAL, "unequal spacing rejected");
    CHECK(p.n == 0 && p.x[0] == NULL, "nothing left allocated after an error");
    lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 4, 4);
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_EINVAL, "dim 4 rejected");
}

static void test_random(void)
{
    const size_t nx = 40;
    const double eps = 0.4, ds = 1.0 / 40.0;
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, 2, nx);
    lp.eps = eps;
    lp.seed = 7;
    lp.box.periodic[0] = lp.box.periodic[1] = 0;
    consph_particles p, q, r;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "random: %s", consph_last_error());
    CHECK(consph_layout_generate(&lp, &q, NULL) == CONSPH_OK, "random again");
    lp.seed = 8;
    CHECK(consph_layout_generate(&lp, &r, NULL) == CONSPH_OK, "random, other seed");
    CHECK(same_positions(&p, &q), "same seed gives the same positions bit for bit");
    CHECK(!same_positions(&p, &r), "another seed gives other positions");
    double bound = 0.25 * eps * ds, maxd = 0.0, sum = 0.0;
    for (size_t iy = 0; iy < nx; ++iy)
        for (size_t ix = 0; ix < nx; ++ix) {
            size_t i = ix + nx * iy;
            double dx = p.x[0][i] - ((double)ix + 0.5) * ds;
            double dy = p.x[1][i] - ((double)iy + 0.5) * ds;
            maxd = fmax(maxd, fmax(fabs(dx), fabs(dy)));
            sum += dx + dy;
        }
    CHECK(maxd <= bound * (1.0 + 1e-12), "|displacement| %.6g <= 0.25 eps Δs = %.6g", maxd, bound);
    /* 3200 uniform draws: the largest lies within 0.1% of the bound unless the draws are not
     * uniform over the whole interval. */
    CHECK(maxd > 0.99 * bound, "the perturbation fills its interval: max %.6g", maxd);
    /* Mean of 3200 values uniform in [-b, b]: standard error b/sqrt(3*3200) ≈ 0.0102 b. */
    CHECK(fabs(sum / 3200.0) < 5 * 0.0102 * bound, "perturbation mean %.3g is ~0", sum / 3200.0);
    consph_particles_free(&p);
    consph_particles_free(&q);
    consph_particles_free(&r);

    /* ε = 2 on a periodic box: positions wrap into [0, 1). */
    lp = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, 3, 6);
    lp.eps = 2.0;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "random 3D eps 2");
    CHECK(inside_box(&p), "random positions inside the periodic box");
    consph_particles_free(&p);
    lp.eps = 2.5;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_EINVAL, "eps > 2 rejected");
}

/* Star discrepancy estimated on the grid of anchored boxes [0, a/g) x [0, b/g). */
static double star_discrepancy_2d(const double *x, const double *y, size_t n, int g)
{
    int *cnt = calloc((size_t)(g * g), sizeof(int));
    for (size_t i = 0; i < n; ++i) {
        int cx = (int)(x[i] * g), cy = (int)(y[i] * g);
        cnt[cx + g * cy]++;
    }
    /* Cumulative counts over anchored boxes. */
    double worst = 0.0;
    for (int b = 1; b <= g; ++b)
        for (int a = 1; a <= g; ++a) {
            long c = 0;
            for (int jy = 0; jy < b; ++jy)
                for (int jx = 0; jx < a; ++jx) c += cnt[jx + g * jy];
            double d = fabs((double)c / (double)n - (double)a * b / ((double)g * g));
            if (d > worst) worst = d;
        }
    free(cnt);
    return worst;
}

static void test_quasi_random(void)
{
    const size_t nx = 32, n = nx * nx;
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_QUASI_RANDOM, 2, nx);
    consph_particles p;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "halton: %s", consph_last_error());
    CHECK(p.n == n, "count %zu", p.n);
    CHECK(inside_box(&p), "Halton points inside the box");
    /* Sequence indices 1, 2, 3: base 2 gives 1/2, 1/4, 3/4; base 3 gives 1/3, 2/3, 1/9. */
    CHECK(p.x[0][0] == 0.5 && p.x[0][1] == 0.25 && p.x[0][2] == 0.75, "base-2 radical inverse");
    CHECK_NEAR(p.x[1][0], 1.0 / 3.0, 1e-15, "base 3, index 1");
    CHECK_NEAR(p.x[1][1], 2.0 / 3.0, 1e-15, "base 3, index 2");
    CHECK_NEAR(p.x[1][2], 1.0 / 9.0, 1e-15, "base 3, index 3");
    CHECK_NEAR(p.spacing, 1.0 / 32.0, 1e-15, "spacing (V/N)^(1/d)");
    /* Low discrepancy: N = nx^2 points put at most 3 in any of the nx^2 cells (uniform random
     * points put 6 or more in some cell with probability > 0.5), and the anchored-box
     * discrepancy is below 0.01 (random points: about 0.03). */
    int *cnt = calloc(n, sizeof(int));
    int maxc = 0, empty = 0;
    for (size_t i = 0; i < n; ++i) {
        size_t c = (size_t)(p.x[0][i] * nx) + nx * (size_t)(p.x[1][i] * nx);
        if (++cnt[c] > maxc) maxc = cnt[c];
    }
    for (size_t c = 0; c < n; ++c) empty += cnt[c] == 0;
    CHECK(maxc <= 3, "at most 3 points per cell, got %d", maxc);
    CHECK(empty < (int)n / 4, "few empty cells: %d of %zu (random: ~37%%)", empty, n);
    double disc = star_discrepancy_2d(p.x[0], p.x[1], n, 64);
    CHECK(disc < 0.01, "star discrepancy estimate %.4g < 0.01", disc);
    /* The same statistic for pseudo-random points, so the bound is known to discriminate. */
    consph_rng rng;
    consph_rng_seed(&rng, 3);
    double *rx = malloc(n * sizeof(double)), *ry = malloc(n * sizeof(double));
    for (size_t i = 0; i < n; ++i) {
        rx[i] = consph_rng_uniform(&rng);
        ry[i] = consph_rng_uniform(&rng);
    }
    double rdisc = star_discrepancy_2d(rx, ry, n, 64);
    CHECK(rdisc > 0.01, "pseudo-random discrepancy %.4g exceeds the bound", rdisc);
    free(rx);
    free(ry);
    free(cnt);
    consph_particles_free(&p);

    lp = consph_layout_defaults(CONSPH_LAYOUT_QUASI_RANDOM, 3, 10);
    lp.box.lo[2] = -2.0;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "halton 3D");
    CHECK(p.n == 1000 && inside_box(&p), "3D Halton inside a 1x1x3 box");
    CHECK_NEAR(p.x[2][0], -2.0 + 3.0 / 5.0, 1e-15, "base 5, index 1 scaled to the box");
    consph_particles_free(&p);
}

static void test_stats(void)
{
    /* Lattice with the quintic at h = 1.2Δs: every particle has the infinite-lattice density,
     * whose error is |rho - 1| = 5.62e-5 (docs/reference-values.md; the density is below 1). */
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 2, 20);
    consph_particles p;
    consph_layout_stats st;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "lattice");
    CHECK(consph_layout_stats_compute(&p, "quintic", 1.2, &st) == CONSPH_OK, "stats: %s",
          consph_last_error());
    CHECK(st.n == 400, "n");
    CHECK_NEAR(st.rho_spread, 5.62e-5, 0.01e-5, "UP lattice density error, quintic 1.2");
    CHECK_NEAR(st.rho_mean, 1.0 - 5.62e-5, 0.01e-5, "UP lattice mean density");
    CHECK_NEAR(st.min_spacing, 0.05, 1e-14, "lattice minimum spacing is Δs");
    consph_layout_nn_stats ns;
    CHECK(consph_layout_nn_stats_compute(&p, &ns) == CONSPH_OK, "nn stats");
    CHECK_NEAR(ns.nn_min, 1.0, 1e-12, "lattice NN min");
    CHECK_NEAR(ns.nn_max, 1.0, 1e-12, "lattice NN max");
    CHECK_NEAR(ns.nn_std, 0.0, 1e-12, "lattice NN std");
    CHECK_NEAR(ns.disp_max, 0.0, 1e-12, "lattice nodes are at zero displacement");
    consph_particles_free(&p);

    CHECK(consph_layout_stats_compute(&p, "quintic", 1.2, &st) == CONSPH_EINVAL,
          "empty set rejected");

    /* Random set on a periodic box against brute force with minimum images (the support,
     * 3.6Δs, is below half the box, 6Δs). */
    lp = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, 2, 12);
    lp.eps = 1.6;
    lp.seed = 11;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "random");
    CHECK(consph_layout_stats_compute(&p, "quintic", 1.2, &st) == CONSPH_OK, "stats random");
    consph_kernel k;
    consph_kernel_id id;
    consph_kernel_lookup("quintic", &id);
    consph_kernel_init(&k, id, 2, 1.2 * p.spacing);
    double m = p.spacing * p.spacing, spread = 0.0, dmin = INFINITY, nnsum = 0.0, nnmin = INFINITY;
    for (size_t i = 0; i < p.n; ++i) {
        double rho = 0.0, nn = INFINITY;
        for (size_t j = 0; j < p.n; ++j) {
            double r = periodic_dist(&p, i, j);
            rho += m * consph_kernel_w(&k, r);
            if (j != i) nn = fmin(nn, r);
        }
        spread = fmax(spread, fabs(rho - 1.0));
        dmin = fmin(dmin, nn);
        nnsum += nn / p.spacing;
        nnmin = fmin(nnmin, nn / p.spacing);
    }
    CHECK_NEAR(st.rho_spread, spread, 1e-12, "density spread vs brute force");
    CHECK_NEAR(st.min_spacing, dmin, 1e-15, "minimum spacing vs brute force");
    CHECK(consph_layout_nn_stats_compute(&p, &ns) == CONSPH_OK, "nn stats random");
    CHECK_NEAR(ns.nn_mean, nnsum / (double)p.n, 1e-12, "NN mean vs brute force");
    CHECK_NEAR(ns.nn_min, nnmin, 1e-12, "NN min vs brute force");
    CHECK(ns.disp_max <= sqrt(2.0) * 0.25 * 1.6 + 1e-12, "displacement bound %g", ns.disp_max);
    consph_particles_free(&p);

    /* The tensor-product M4 at h = Δs interpolates: on a lattice it sums to one exactly. */
    lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 2, 16);
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "lattice for M4");
    CHECK(consph_layout_stats_compute(&p, "m4", 1.0, &st) == CONSPH_OK, "stats m4: %s",
          consph_last_error());
    CHECK(st.rho_spread < 1e-13, "M4 partition of unity on the lattice: %g", st.rho_spread);
    consph_particles_free(&p);

    /* A closed box: particles near the walls lose part of their support. */
    lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 2, 20);
    lp.box.periodic[0] = lp.box.periodic[1] = 0;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "closed lattice");
    CHECK(consph_layout_stats_compute(&p, NULL, 1.2, &st) == CONSPH_OK, "stats closed");
    CHECK(st.rho_spread > 0.4, "a corner particle loses about half its support: %g", st.rho_spread);
    consph_particles_free(&p);
}

static void test_polished_2d(void)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED_POLISHED, 2, 20);
    lp.seed = 5;
    lp.packing.max_iter = 4000;
    lp.packing.tol = 1e-4;
    lp.packing.history_every = 100;
    consph_particles p, q, r;
    consph_packing_report rep, rep2, rep3;
    check_set_threads(1);
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_OK, "packed: %s", consph_last_error());
    printf("packed-polished 20^2: %d iterations (polishing from %d), %.2f s, spread %.3e -> %.3e\n",
           rep.iterations, rep.polish_start, rep.seconds, rep.rho_spread_initial,
           rep.rho_spread_final);
    CHECK(rep.rho_spread_initial > 0.1, "perturbed start is far from uniform: %g",
          rep.rho_spread_initial);
    CHECK(rep.rho_spread_final < 1e-4, "reaches the tolerance 1e-4: %g", rep.rho_spread_final);
    CHECK(rep.iterations < lp.packing.max_iter, "converged before max_iter: %d", rep.iterations);
    CHECK(rep.nhistory >= 2 && rep.history_iter[0] == 0 &&
              rep.history_spread[0] == rep.rho_spread_initial &&
              rep.history_iter[rep.nhistory - 1] == rep.iterations &&
              rep.history_spread[rep.nhistory - 1] == rep.rho_spread_final,
          "history runs from the start to the end");
    CHECK(inside_box(&p), "packed particles stay inside the periodic box");
    consph_layout_stats st;
    CHECK(consph_layout_stats_compute(&p, "quintic", 1.2, &st) == CONSPH_OK, "stats packed");
    CHECK_NEAR(st.rho_spread, rep.rho_spread_final, 1e-12,
               "independent density evaluation agrees with the report");
    consph_layout_nn_stats ns;
    CHECK(consph_layout_nn_stats_compute(&p, &ns) == CONSPH_OK, "nn stats packed");
    printf("packed-polished 20^2: NN min %.3f mean %.3f max %.3f std %.3f; lattice displacement "
           "mean %.3f "
           "max %.3f\n",
           ns.nn_min, ns.nn_mean, ns.nn_max, ns.nn_std, ns.disp_mean, ns.disp_max);
    /* Glass-like, as the authors' packed files (docs/reference-values.md: NN min 0.79-0.86, mean
     * 0.96-1.00; displacement mean 0.33-0.37): not a lattice, and no close pairs. */
    CHECK(ns.nn_min > 0.8, "no close pairs: NN min %.3f", ns.nn_min);
    CHECK(ns.nn_mean > 0.93 && ns.nn_mean < 1.0, "NN mean %.3f", ns.nn_mean);
    CHECK(ns.disp_mean > 0.25, "particles left the lattice: mean displacement %.3f", ns.disp_mean);

    consph_particles_free(&p);
    consph_packing_report_free(&rep);

    /* Reproducibility on a short run that still goes through both stages (polishing starts at
     * max_iter/2 at the latest). */
    lp.packing.max_iter = 300;
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_OK, "short packed run");
    CHECK(rep.polish_start > 0 && rep.polish_start <= 150, "polishing started at %d",
          rep.polish_start);
    CHECK(consph_layout_generate(&lp, &q, &rep2) == CONSPH_OK, "packed again");
    CHECK(same_positions(&p, &q) && rep2.iterations == rep.iterations, "reproducible for a seed");
    consph_particles_free(&q);
    consph_packing_report_free(&rep2);
    /* Thread independence on a shorter run still (2 threads are slow on a loaded machine). */
    lp.packing.max_iter = 60;
    consph_particles_free(&p);
    consph_packing_report_free(&rep);
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_OK, "60 steps, 1 thread");
    CHECK(rep.polish_start == 30, "both stages run: polishing from %d", rep.polish_start);
    check_set_threads(2);
    CHECK(consph_layout_generate(&lp, &q, &rep2) == CONSPH_OK, "60 steps, 2 threads");
    CHECK(same_positions(&p, &q), "independent of the number of threads");
    check_set_threads(1);
    lp.seed = 6;
    CHECK(consph_layout_generate(&lp, &r, &rep3) == CONSPH_OK, "packed, other seed");
    CHECK(!same_positions(&p, &r), "another seed gives another arrangement");
    consph_particles_free(&p);
    consph_particles_free(&q);
    consph_particles_free(&r);
    consph_packing_report_free(&rep);
    consph_packing_report_free(&rep2);
    consph_packing_report_free(&rep3);

    /* Packing needs a periodic box; bad parameters are rejected without side effects. */
    lp.box.periodic[1] = 0;
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_EINVAL, "closed box rejected");
    CHECK(strstr(consph_last_error(), "periodic"), "message: %s", consph_last_error());
    lp.box.periodic[1] = 1;
    lp.packing.perturb = 0.7;
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_EINVAL, "perturb > 0.5 rejected");
    lp.packing.perturb = 0.5;
    lp.packing.kernel = "nonsense";
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_EINVAL, "unknown kernel rejected");
    lp.packing.kernel = "m4";
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_EINVAL, "tensor kernel rejected");
    CHECK(rep.history_iter == NULL && p.x[0] == NULL, "nothing allocated after an error");
}

static void test_polished_3d(void)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED_POLISHED, 3, 8);
    lp.seed = 2;
    /* A short cap: polishing starts by iteration 250 at the latest. */
    lp.packing.max_iter = 500;
    lp.packing.tol = 1e-3;
    lp.packing.history_every = 0;
    consph_particles p;
    consph_packing_report rep;
    check_set_threads(1);
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_OK, "packed 3D: %s", consph_last_error());
    printf("packed-polished 8^3: %d iterations (polishing from %d), %.2f s, spread %.3e -> %.3e\n",
           rep.iterations, rep.polish_start, rep.seconds, rep.rho_spread_initial,
           rep.rho_spread_final);
    CHECK(rep.rho_spread_final < 1e-3, "3D reaches the tolerance 1e-3: %g", rep.rho_spread_final);
    CHECK(rep.rho_spread_final < rep.rho_spread_initial / 100, "spread fell a hundredfold");
    CHECK(rep.nhistory == 0 && rep.history_iter == NULL, "no history when history_every = 0");
    CHECK(inside_box(&p), "3D packed particles inside the box");
    consph_layout_nn_stats ns;
    CHECK(consph_layout_nn_stats_compute(&p, &ns) == CONSPH_OK, "nn stats 3D");
    CHECK(ns.nn_min > 0.8, "3D: no close pairs: NN min %.3f", ns.nn_min);
    consph_particles q;
    consph_packing_report rep2;
    CHECK(consph_layout_generate(&lp, &q, &rep2) == CONSPH_OK, "packed 3D again");
    CHECK(same_positions(&p, &q), "3D reproducible for a seed");
    consph_particles_free(&p);
    consph_particles_free(&q);
    consph_packing_report_free(&rep);
    consph_packing_report_free(&rep2);
}

/* packed, [51]'s single stage: its stopping rule is a test every 50 steps (after steps 1, 51,
 * 101, ...: the step count at a stop is 50k + 1) of 100 max|u| Δt / h <= move_tol, honoured from
 * the 11th test on. */
static void test_packed_rule(void)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, 20);
    lp.packing.history_every = 0;
    consph_particles p, q;
    consph_packing_report rep, rep2;
    check_set_threads(1);
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_OK, "packed: %s", consph_last_error());
    printf("packed 20^2: %d steps, 100 max|u|dt/h %.3g, spread %.3e -> %.3e\n", rep.iterations,
           rep.move_final, rep.rho_spread_initial, rep.rho_spread_final);
    CHECK(rep.converged && rep.move_final <= lp.packing.move_tol, "stopped by the rule: %d, %g",
          rep.converged, rep.move_final);
    CHECK(rep.iterations % 50 == 1 && rep.iterations >= 501 && rep.iterations < lp.packing.max_iter,
          "stopped right after a test, the 11th or a later one: %d steps", rep.iterations);
    CHECK(rep.polish_start == -1, "a single stage");
    /* The test 50 steps earlier failed: a cap just before the stop ends there, unconverged, with
     * the motion above the tolerance (same steps: the run is deterministic). */
    lp.packing.max_iter = rep.iterations - 1;
    CHECK(consph_layout_generate(&lp, &q, &rep2) == CONSPH_OK, "capped packed");
    CHECK(!rep2.converged && rep2.iterations == lp.packing.max_iter, "cap before the stop: %d, %d",
          rep2.converged, rep2.iterations);
    CHECK(rep2.move_final > lp.packing.move_tol, "the previous test failed: %g", rep2.move_final);
    consph_particles_free(&q);
    consph_packing_report_free(&rep2);
    /* A tolerance every test meets: the rule still waits for the 11th test (after step 501). */
    lp.packing.max_iter = 40000;
    lp.packing.move_tol = 100.0;
    CHECK(consph_layout_generate(&lp, &q, &rep2) == CONSPH_OK, "loose packed");
    CHECK(rep2.converged && rep2.iterations == 501, "11 tests before stopping: %d steps",
          rep2.iterations);
    consph_particles_free(&p);
    consph_particles_free(&q);
    consph_packing_report_free(&rep);
    consph_packing_report_free(&rep2);

    lp.packing.move_tol = 0.0;
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_EINVAL, "move_tol 0 rejected");
    CHECK(strstr(consph_last_error(), "move_tol"), "message: %s", consph_last_error());
}

/* The geometry the packing is built to give, from a start perturbed by up to Δs/2 per coordinate
 * (mean distance to the lattice node ≈ 0.38Δs): the background pressure evens out the number
 * density from a spread of ~0.4 to the level of the published packed files (~1e-2); the
 * repulsion, which acts only below 0.95Δs, keeps pairs apart (the files: NN min 0.79-0.86Δs);
 * and at perturbation 0.5 the particles settle into a glass, not back on the lattice (node
 * distance well above 0). A sign error in either force clumps particles; a missing background
 * pressure leaves the spread near its start; wrong damping never satisfies the rule. */
static void test_packed_geometry(void)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, 32);
    lp.seed = 3;
    lp.packing.history_every = 0;
    consph_particles p;
    consph_packing_report rep;
    check_set_threads(1);
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_OK, "packed 32: %s", consph_last_error());
    CHECK(rep.converged, "packed 32 converged in %d steps", rep.iterations);
    CHECK(rep.rho_spread_initial > 0.2, "the start is far from uniform: %g",
          rep.rho_spread_initial);
    CHECK(rep.rho_spread_final < 0.03 && rep.rho_spread_final > 1e-4,
          "spread at the level of [51]'s packing, not of a density polish: %g",
          rep.rho_spread_final);
    CHECK(inside_box(&p), "packed particles inside the box");
    consph_layout_stats st;
    CHECK(consph_layout_stats_compute(&p, "quintic", 1.2, &st) == CONSPH_OK, "stats packed 32");
    CHECK_NEAR(st.rho_spread, rep.rho_spread_final, 1e-12, "the report's spread is the layout's");
    CHECK_NEAR(st.rho_mean, 1.0, 1e-3, "mean density rho0: %g", st.rho_mean);
    consph_layout_nn_stats ns;
    CHECK(consph_layout_nn_stats_compute(&p, &ns) == CONSPH_OK, "nn stats packed 32");
    printf("packed 32^2: %d steps; NN min %.3f mean %.3f std %.3f; node distance mean %.3f\n",
           rep.iterations, ns.nn_min, ns.nn_mean, ns.nn_std, ns.disp_mean);
    CHECK(ns.nn_min > 0.8, "no close pairs: NN min %.3f", ns.nn_min);
    CHECK(ns.nn_mean > 0.93 && ns.nn_mean < 1.0, "NN mean %.3f", ns.nn_mean);
    CHECK(ns.disp_mean > 0.25, "a glass, not the lattice: node distance %.3f", ns.disp_mean);
    consph_particles_free(&p);
    consph_packing_report_free(&rep);
}

/* More particles than a pass's parallel_min (2048), so that both the passes and the step run
 * on several threads (3: the neighbour list's build splits its walk into thread ranges that do
 * not fall on 2's boundaries). */
static void test_packed_threads(void)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, 48);
    lp.packing.max_iter = 80;
    lp.packing.history_every = 0;
    consph_particles p, q;
    consph_packing_report rep, rep2;
    check_set_threads(1);
    CHECK(consph_layout_generate(&lp, &p, &rep) == CONSPH_OK, "80 steps, 1 thread");
    for (int threads = 2; threads <= 3; ++threads) {
        check_set_threads(threads);
        CHECK(consph_layout_generate(&lp, &q, &rep2) == CONSPH_OK, "80 steps, %d threads", threads);
        CHECK(same_positions(&p, &q) && rep.rho_spread_final == rep2.rho_spread_final &&
                  rep.move_final == rep2.move_final,
              "packed is independent of the number of threads (1 and %d)", threads);
        consph_particles_free(&q);
        consph_packing_report_free(&rep2);
    }
    check_set_threads(1);
    consph_particles_free(&p);
    consph_packing_report_free(&rep);
}

/* packed with walls: the packing of a walled square, as the authors' packed files were made
 * (docs/reference-values.md): the frozen layers keep every particle at least ~0.37Δs inside the
 * box (the files: 0.37-0.38Δs) and line a row of particles along each wall, while the periodic
 * packing from the same start lets particles straddle the box edges. The walled packing obeys
 * the same stopping rule and gives the same positions for any thread count; walls apply only to
 * packed and are bounded. */
static double min_edge_distance(const consph_particles *p, double ds)
{
    double m = INFINITY;
    for (size_t i = 0; i < p->n; ++i)
        for (int a = 0; a < p->dim; ++a) {
            double d = fmin(p->x[a][i] - p->box.lo[a], p->box.hi[a] - p->x[a][i]) / ds;
            if (d < m) m = d;
        }
    return m;
}

static void test_packed_walls(void)
{
    const size_t n = 24;
    const double ds = 1.0 / (double)n;
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, n);
    lp.packing.history_every = 0;
    consph_particles per, w1, w2;
    consph_packing_report rep;
    check_set_threads(1);
    CHECK(consph_layout_generate(&lp, &per, NULL) == CONSPH_OK, "periodic: %s",
          consph_last_error());
    lp.packing.walls = 3;
    CHECK(consph_layout_generate(&lp, &w1, &rep) == CONSPH_OK, "walled: %s", consph_last_error());
    check_set_threads(2);
    CHECK(consph_layout_generate(&lp, &w2, NULL) == CONSPH_OK, "walled, 2 threads");
    check_set_threads(1);
    const double e_per = min_edge_distance(&per, ds), e_w = min_edge_distance(&w1, ds);
    size_t row = 0;
    for (size_t i = 0; i < w1.n; ++i) {
        double d = INFINITY;
        for (int a = 0; a < 2; ++a) d = fmin(d, fmin(w1.x[a][i], 1.0 - w1.x[a][i]) / ds);
        row += d < 0.75;
    }
    printf("walled 24^2: %d steps, spread %.3e, min edge distance %.3f (periodic %.3f), %zu in "
           "the wall rows\n",
           rep.iterations, rep.rho_spread_final, e_w, e_per, row);
    CHECK(w1.n == n * n && w1.box.periodic[0] && w1.box.periodic[1], "n^2 particles, periodic box");
    CHECK(rep.converged && rep.iterations % 50 == 1, "stopped by [51]'s rule: %d steps",
          rep.iterations);
    CHECK(e_w > 0.3 && e_w < 0.5, "the walls keep particles ~0.4Δs inside: %.3f", e_w);
    CHECK(e_per < 0.3, "the periodic packing crosses the edges: %.3f", e_per);
    CHECK(row >= 3 * n && row <= 4 * n, "one row along each wall: %zu particles", row);
    int same = 1;
    for (size_t i = 0; i < w1.n; ++i)
        for (int a = 0; a < 2; ++a) same &= w1.x[a][i] == w2.x[a][i];
    CHECK(same, "the same positions on 1 and 2 threads");
    consph_particles_free(&per);
    consph_particles_free(&w1);
    consph_particles_free(&w2);
    consph_packing_report_free(&rep);

    lp.packing.walls = 9;
    CHECK(consph_layout_generate(&lp, &per, NULL) == CONSPH_EINVAL &&
              strstr(consph_last_error(), "walls"),
          "walls 9 rejected: %s", consph_last_error());
    /* quintic at h = 1.2Δs: support 3.6Δs, so at least 2 layers (4 across the seam) */
    lp.packing.walls = 1;
    CHECK(consph_layout_generate(&lp, &per, NULL) == CONSPH_EINVAL &&
              strstr(consph_last_error(), "2..8"),
          "walls 1 rejected: %s", consph_last_error());
    lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED_POLISHED, 2, n);
    lp.packing.walls = 3;
    CHECK(consph_layout_generate(&lp, &per, NULL) == CONSPH_EINVAL &&
              strstr(consph_last_error(), "walls"),
          "walls with packed-polished rejected: %s", consph_last_error());
}

/* The ranges an MPI rank makes at a decomposed set-up: consecutive ranges of every kind made by
 * index put together are the whole layout bit for bit (positions and volume), the random kind's
 * numbers skipped for the particles before a range; the packed kinds and a range beyond the set
 * are refused. */
static void test_ranges(void)
{
    static const consph_layout_kind kinds[] = {CONSPH_LAYOUT_LATTICE, CONSPH_LAYOUT_RANDOM,
                                               CONSPH_LAYOUT_QUASI_RANDOM};
    for (int dim = 2; dim <= 3; ++dim)
        for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; ++k) {
            consph_layout_params lp = consph_layout_defaults(kinds[k], dim, 7);
            lp.seed = 11;
            lp.eps = 0.4;
            consph_particles whole;
            CHECK(consph_layout_generate(&lp, &whole, NULL) == CONSPH_OK, "%s: %s",
                  consph_layout_name(kinds[k]), consph_last_error());
            const size_t n = whole.n, cuts[] = {0, 1, n / 3, n / 3, n - 5, n};
            int same = 1;
            for (size_t c = 0; c + 1 < sizeof cuts / sizeof cuts[0]; ++c) {
                consph_particles part;
                const size_t first = cuts[c], count = cuts[c + 1] - cuts[c];
                CHECK(consph_layout_generate_range(&lp, first, count, &part) == CONSPH_OK,
                      "%s range: %s", consph_layout_name(kinds[k]), consph_last_error());
                same = same && part.n == count && part.spacing == whole.spacing;
                for (int a = 0; same && a < dim; ++a)
                    same = !memcmp(part.x[a], whole.x[a] + first, count * sizeof(double));
                const consph_field *v = consph_particles_find(&part, "volume");
                same = same && v &&
                       (!count || v->data[0] == consph_particles_find(&whole, "volume")->data[0]);
                consph_particles_free(&part);
            }
            CHECK(same, "%s %dD: the ranges are the whole layout's particles, bit for bit",
                  consph_layout_name(kinds[k]), dim);
            consph_particles part;
            CHECK(consph_layout_generate_range(&lp, n - 2, 3, &part) == CONSPH_EINVAL,
                  "a range beyond the set is refused");
            consph_particles_free(&whole);
        }
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, 8);
    consph_particles part;
    CHECK(!consph_layout_by_index(CONSPH_LAYOUT_PACKED) &&
              consph_layout_generate_range(&lp, 0, 4, &part) == CONSPH_EINVAL &&
              strstr(consph_last_error(), "whole layout"),
          "packed: no range (%s)", consph_last_error());
}

int main(void)
{
    test_names();
    test_lattice();
    test_random();
    test_quasi_random();
    test_ranges();
    test_stats();
    test_polished_2d();
    test_polished_3d();
    test_packed_rule();
    test_packed_geometry();
    test_packed_threads();
    test_packed_walls();
    return check_summary("test_layout");
}
