/* Wasserstein distances (include/consph/transport.h) against answers known in closed form:
 * quantile-sampled Gaussians, translations, a lattice against the uniform density, a point
 * against a smoothing kernel; metric properties on random measures; sliced = exact in 1D;
 * Sinkhorn against exact 1D transport and brute-force assignment as ε → 0; the same numbers on
 * any number of threads. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/kernels.h"
#include "consph/transport.h"

#ifdef _OPENMP
#include <omp.h>
#endif

/* Φ^-1 by Newton's method on Φ(x) = erfc(-x/√2)/2; exact to round-off for u in (1e-12, 1). */
static double normal_quantile(double u)
{
    double x = 0.0;
    for (int it = 0; it < 100; ++it) {
        double f = 0.5 * erfc(-x / M_SQRT2) - u;
        double step = f / (exp(-0.5 * x * x) / sqrt(2.0 * M_PI));
        x -= step;
        if (fabs(step) < 1e-15 * (1.0 + fabs(x))) break;
    }
    return x;
}

static double wdist(const consph_measure *a, const consph_measure *b, consph_ot_options o,
                    consph_ot_result *res)
{
    consph_ot_result local;
    if (!res) res = &local;
    int rc = consph_wasserstein(a, b, &o, res);
    CHECK(rc == CONSPH_OK, "consph_wasserstein: %s", consph_last_error());
    return res->distance;
}

static consph_ot_options method(consph_ot_method m, int p)
{
    consph_ot_options o = consph_ot_defaults();
    o.method = m;
    o.p = p;
    return o;
}

/* Two Gaussians sampled at the quantiles (k + 1/2)/N: W2 → sqrt(Δμ² + Δσ²) and W1 → the
 * L1 distance of the quantile functions, E|Δμ + Δσ Z|. */
static void test_gaussians(void)
{
    size_t n1 = 4000, n2 = 2999;
    double mu1 = 0.3, s1 = 1.0, mu2 = -0.5, s2 = 1.7;
    double *x1 = malloc(n1 * sizeof *x1), *x2 = malloc(n2 * sizeof *x2);
    for (size_t k = 0; k < n1; ++k) x1[k] = mu1 + s1 * normal_quantile((k + 0.5) / n1);
    for (size_t k = 0; k < n2; ++k) x2[k] = mu2 + s2 * normal_quantile((k + 0.5) / n2);
    consph_measure a = {1, n1, {x1}, NULL}, b = {1, n2, {x2}, NULL};
    double w2 = wdist(&a, &b, method(CONSPH_OT_EXACT, 2), NULL);
    double want2 = sqrt((mu1 - mu2) * (mu1 - mu2) + (s1 - s2) * (s1 - s2));
    /* The quantile samples miss the tails beyond Φ^-1(1/(2N)): their variance falls short of
     * σ² by O(log N / N), ~2e-3 here. */
    CHECK_NEAR(w2, want2, 2e-3 * want2, "W2 of two Gaussians");
    /* E|m + s Z| = m (1 - 2Φ(-m/s)) + 2 s φ(m/s) with m = Δμ, s = Δσ. */
    double m = mu1 - mu2, s = fabs(s1 - s2);
    double want1 = m * (1.0 - erfc(m / s / M_SQRT2)) +
                   2.0 * s * exp(-0.5 * m * m / (s * s)) / sqrt(2.0 * M_PI);
    double w1 = wdist(&a, &b, method(CONSPH_OT_EXACT, 1), NULL);
    CHECK_NEAR(w1, want1, 2e-3 * want1, "W1 of two Gaussians");
    /* Sliced in 1D is the exact walk: every direction is ±1. */
    consph_ot_result r;
    double sw2 = wdist(&a, &b, method(CONSPH_OT_SLICED, 2), &r);
    CHECK_NEAR(sw2, w2, 1e-14 * w2, "sliced = exact in 1D");
    CHECK(r.error == 0.0, "sliced error in 1D is %g, not 0", r.error);
    free(x1);
    free(x2);
}

static double *random_points(consph_rng *rng, size_t n, int dim, double lo, double hi)
{
    double *x = malloc(n * (size_t)dim * sizeof *x);
    for (size_t i = 0; i < n * (size_t)dim; ++i) x[i] = lo + (hi - lo) * consph_rng_uniform(rng);
    return x;
}

static consph_measure soa(double *x, size_t n, int dim, const double *w)
{
    consph_measure m = {dim, n, {NULL, NULL, NULL}, w};
    for (int a = 0; a < dim; ++a) m.x[a] = x + (size_t)a * n;
    return m;
}

/* A measure and its translate by s: W_p = |s| in any dimension, exactly; sliced SW_2 = |s|/√d
 * and SW_1 = |s| E|θ_1| (2/π in 2D, 1/2 in 3D). */
static void test_translation(void)
{
    consph_rng rng;
    consph_rng_seed(&rng, 7);
    for (int dim = 1; dim <= 3; ++dim) {
        size_t n = 40;
        double shift[3] = {0.3, -0.4, 0.25}, len2 = 0.0;
        for (int a = 0; a < dim; ++a) len2 += shift[a] * shift[a];
        double len = sqrt(len2);
        double *x = random_points(&rng, n, dim, 0.0, 1.0);
        double *y = malloc(n * (size_t)dim * sizeof *y);
        double *w = random_points(&rng, n, 1, 0.5, 2.0);
        for (int a = 0; a < dim; ++a)
            for (size_t i = 0; i < n; ++i) y[(size_t)a * n + i] = x[(size_t)a * n + i] + shift[a];
        consph_measure mx = soa(x, n, dim, w), my = soa(y, n, dim, w);
        for (int p = 1; p <= 2; ++p) {
            consph_ot_result r;
            if (dim == 1)
                CHECK_NEAR(wdist(&mx, &my, method(CONSPH_OT_EXACT, p), NULL), len, 1e-14,
                           "exact translation p=%d", p);
            consph_ot_options o = method(CONSPH_OT_SINKHORN, p);
            o.eps = 1e-4;
            double ws = wdist(&mx, &my, o, &r);
            CHECK(r.converged, "sinkhorn %dD p=%d did not converge (delta %g)", dim, p,
                  r.marginal_error);
            CHECK(fabs(ws - len) <= r.error,
                  "sinkhorn %dD p=%d: %.10g vs %.10g outside its bound %g", dim, p, ws, len,
                  r.error);
            CHECK(r.error < 0.05 * len, "sinkhorn %dD p=%d: bound %g is not informative", dim, p,
                  r.error);
            if (dim == 1) continue;
            o = method(CONSPH_OT_SLICED, p);
            o.directions = 2000;
            double sw = wdist(&mx, &my, o, &r);
            double e1 = dim == 2 ? 2.0 / M_PI : 0.5;
            double want = p == 2 ? len / sqrt((double)dim) : len * e1;
            CHECK(fabs(sw - want) <= 4.0 * r.error, "sliced %dD p=%d: %.8g vs %.8g, 4 SE = %.3g",
                  dim, p, sw, want, 4.0 * r.error);
            CHECK(r.error > 0.0 && r.error < 0.05 * want, "sliced %dD p=%d: SE %g", dim, p,
                  r.error);
        }
        free(x);
        free(y);
        free(w);
    }
}

/* Lattice points at the cell centres of [0,1) against the uniform density: each cell's mass
 * goes to its centre, W1 = Δ/4, W2 = Δ/√12. The uniform density is a grid measure of M cells,
 * within half a grid cell of it in W_p (triangle inequality). */
static void test_lattice_uniform(void)
{
    consph_box box = consph_box_unit(1, 0);
    size_t n = 50, cells = 50 * 1000 + 7;
    double *x = malloc(n * sizeof *x);
    for (size_t i = 0; i < n; ++i) x[i] = (i + 0.5) / n;
    consph_measure lat = {1, n, {x}, NULL};
    consph_grid_measure g;
    CHECK(consph_grid_measure_density(&box, cells, NULL, NULL, &g) == CONSPH_OK, "grid: %s",
          consph_last_error());
    double d = 1.0 / n;
    CHECK_NEAR(wdist(&lat, &g.mu, method(CONSPH_OT_EXACT, 1), NULL), d / 4.0, g.half_diagonal,
               "W1 lattice vs uniform");
    CHECK_NEAR(wdist(&lat, &g.mu, method(CONSPH_OT_EXACT, 2), NULL), d / sqrt(12.0),
               g.half_diagonal, "W2 lattice vs uniform");
    CHECK(g.half_diagonal < 0.01 * d / 4.0, "the grid is too coarse for the test: %g",
          g.half_diagonal);
    consph_grid_measure_free(&g);
    free(x);
}

/* One particle of unit mass at 0.5 smoothed by the cubic spline (support 2h) is the cubic
 * B-spline with knot spacing h: W2(δ, smoothed) = its standard deviation h/√3, W1 = its mean
 * absolute deviation 7h/15 (∫|x| W dx for the cubic B-spline). */
static void test_point_smoothed(void)
{
    consph_box box = consph_box_unit(1, 0);
    double x0 = 0.5, h = 0.1;
    consph_measure pt = {1, 1, {&x0}, NULL};
    consph_kernel k;
    consph_kernel_id id;
    CHECK(consph_kernel_lookup("cubic", &id) == CONSPH_OK, "cubic kernel");
    CHECK(consph_kernel_init(&k, id, 1, h) == CONSPH_OK, "kernel init");
    consph_grid_measure g;
    CHECK(consph_grid_measure_sph(&box, 20001, &pt, &k, &g) == CONSPH_OK, "sph grid: %s",
          consph_last_error());
    CHECK_NEAR(wdist(&pt, &g.mu, method(CONSPH_OT_EXACT, 2), NULL), h / sqrt(3.0), g.half_diagonal,
               "W2 point vs cubic spline");
    CHECK_NEAR(wdist(&pt, &g.mu, method(CONSPH_OT_EXACT, 1), NULL), 7.0 * h / 15.0, g.half_diagonal,
               "W1 point vs cubic spline");
    consph_grid_measure_free(&g);
}

/* Symmetry and the triangle inequality on random weighted measures of unequal sizes: exact in
 * 1D, sliced in 2D and 3D (for a fixed set of directions SW_p is an L^p mean of 1D metrics, so
 * it is a metric itself). */
static void test_metric(void)
{
    consph_rng rng;
    consph_rng_seed(&rng, 11);
    for (int dim = 1; dim <= 3; ++dim)
        for (int trial = 0; trial < 5; ++trial) {
            size_t n[3] = {17, 30, 9};
            double *x[3], *w[3];
            consph_measure m[3];
            for (int s = 0; s < 3; ++s) {
                x[s] = random_points(&rng, n[s], dim, -1.0 + s, 1.0 + 0.5 * s);
                w[s] = random_points(&rng, n[s], 1, 0.1, 3.0);
                m[s] = soa(x[s], n[s], dim, w[s]);
            }
            for (int p = 1; p <= 2; ++p) {
                consph_ot_options o = method(dim == 1 ? CONSPH_OT_EXACT : CONSPH_OT_SLICED, p);
                o.seed = 3 + (uint64_t)trial;
                double ab = wdist(&m[0], &m[1], o, NULL), ba = wdist(&m[1], &m[0], o, NULL);
                double bc = wdist(&m[1], &m[2], o, NULL), ac = wdist(&m[0], &m[2], o, NULL);
                double aa = wdist(&m[0], &m[0], o, NULL);
                CHECK_NEAR(ab, ba, 1e-13 * ab, "symmetry %dD p=%d", dim, p);
                CHECK(ac <= ab + bc + 1e-13 * ac, "triangle %dD p=%d: %g > %g + %g", dim, p, ac, ab,
                      bc);
                CHECK(aa == 0.0 && ab > 0.0, "identity %dD p=%d: W(a,a) = %g", dim, p, aa);
            }
            for (int s = 0; s < 3; ++s) {
                free(x[s]);
                free(w[s]);
            }
        }
}

/* min over permutations σ of (1/n) Σ_i |x_i − y_σ(i)|^p, by Heap's algorithm. */
static double brute_assignment(const double *x, const double *y, int n, int dim, int p)
{
    int perm[8], c[8] = {0};
    for (int i = 0; i < n; ++i) perm[i] = i;
    double best = INFINITY;
    for (int i = 0;;) {
        double s = 0.0;
        for (int k = 0; k < n; ++k) {
            double d2 = 0.0;
            for (int a = 0; a < dim; ++a) {
                double d = x[a * n + k] - y[a * n + perm[k]];
                d2 += d * d;
            }
            s += p == 2 ? d2 : sqrt(d2);
        }
        if (s < best) best = s;
        while (i < n && c[i] >= i) c[i++] = 0;
        if (i >= n) break;
        int j = i % 2 ? c[i] : 0, t = perm[j];
        perm[j] = perm[i];
        perm[i] = t;
        ++c[i];
        i = 0;
    }
    return best / n;
}

/* Sinkhorn's cost tends to the exact one as ε → 0, always within its own bound: against exact
 * 1D transport (unequal sizes and weights) and against brute-force assignment (equal masses,
 * N = 8, 2D and 3D). */
static void test_sinkhorn_limit(void)
{
    consph_rng rng;
    consph_rng_seed(&rng, 5);
    double *x = random_points(&rng, 6, 1, 0.0, 1.0), *wx = random_points(&rng, 6, 1, 0.2, 1.0);
    double *y = random_points(&rng, 9, 1, 0.2, 1.5), *wy = random_points(&rng, 9, 1, 0.2, 1.0);
    consph_measure a = {1, 6, {x}, wx}, b = {1, 9, {y}, wy};
    for (int p = 1; p <= 2; ++p) {
        double exact = wdist(&a, &b, method(CONSPH_OT_EXACT, p), NULL), prev = INFINITY, last = 0;
        double eps[] = {1e-1, 1e-2, 1e-3, 1e-4};
        for (int e = 0; e < 4; ++e) {
            consph_ot_options o = method(CONSPH_OT_SINKHORN, p);
            o.eps = eps[e];
            o.tol = 1e-10;
            consph_ot_result r;
            double s = wdist(&a, &b, o, &r);
            CHECK(r.converged,
                  "1D p=%d eps=%g not converged (%ld iterations, delta %g, eps_abs %g)", p, eps[e],
                  r.iterations, r.marginal_error, r.eps_abs);
            CHECK(fabs(s - exact) <= r.error, "1D p=%d eps=%g: %.12g vs exact %.12g, bound %g", p,
                  eps[e], s, exact, r.error);
            /* The error itself need not fall monotonically; the bound, ~ε·H, must. */
            CHECK(r.error < 0.5 * prev, "1D p=%d: bound %g at eps=%g, %g before", p, r.error,
                  eps[e], prev);
            prev = r.error;
            last = fabs(s - exact);
        }
        CHECK(last < 1e-3 * exact, "1D p=%d: sinkhorn at eps=1e-4 is %g from exact", p, last);
    }
    free(x);
    free(wx);
    free(y);
    free(wy);
    for (int dim = 2; dim <= 3; ++dim) {
        int n = 8;
        double *u = random_points(&rng, (size_t)n, dim, 0.0, 1.0);
        double *v = random_points(&rng, (size_t)n, dim, 0.1, 1.2);
        consph_measure mu = soa(u, (size_t)n, dim, NULL), mv = soa(v, (size_t)n, dim, NULL);
        for (int p = 1; p <= 2; ++p) {
            double pw = brute_assignment(u, v, n, dim, p), want = p == 2 ? sqrt(pw) : pw;
            consph_ot_options o = method(CONSPH_OT_SINKHORN, p);
            o.eps = 1e-5;
            o.tol = 1e-10;
            consph_ot_result r;
            double s = wdist(&mu, &mv, o, &r);
            CHECK(fabs(s - want) <= r.error, "%dD p=%d: %.12g vs assignment %.12g, bound %g", dim,
                  p, s, want, r.error);
            CHECK(fabs(s - want) < 1e-4 * want, "%dD p=%d: %.12g vs assignment %.12g", dim, p, s,
                  want);
        }
        free(u);
        free(v);
    }
}

/* Sliced and Sinkhorn results are bitwise the same on 1, 2 and 3 threads. */
static void test_threads(void)
{
#ifdef _OPENMP
    consph_rng rng;
    consph_rng_seed(&rng, 9);
    size_t n = 300, m = 257;
    double *x = random_points(&rng, n, 2, 0.0, 1.0), *y = random_points(&rng, m, 2, 0.0, 1.0);
    double *w = random_points(&rng, n, 1, 0.5, 1.0);
    consph_measure a = soa(x, n, 2, w), b = soa(y, m, 2, NULL);
    consph_ot_options os = method(CONSPH_OT_SLICED, 2), ok = method(CONSPH_OT_SINKHORN, 1);
    ok.eps = 1e-2;
    double ref_s = 0, ref_k = 0;
    int max = omp_get_max_threads();
    for (int t = 1; t <= 3; ++t) {
        omp_set_num_threads(t);
        double s = wdist(&a, &b, os, NULL), k = wdist(&a, &b, ok, NULL);
        if (t == 1) {
            ref_s = s;
            ref_k = k;
        }
        CHECK(s == ref_s && k == ref_k,
              "%d threads: sliced %.17g vs %.17g, sinkhorn %.17g vs %.17g", t, s, ref_s, k, ref_k);
    }
    omp_set_num_threads(max);
    free(x);
    free(y);
    free(w);
#endif
}

static void test_rejections(void)
{
    double x[2] = {0, 1}, w[2] = {1, -1};
    consph_measure a = {1, 2, {x}, NULL}, bad = {1, 2, {x}, w}, empty = {1, 0, {x}, NULL};
    double y[4] = {0, 1, 0, 1};
    consph_measure two = {2, 2, {y, y + 2}, NULL};
    consph_ot_options o = consph_ot_defaults();
    consph_ot_result r;
    CHECK(consph_wasserstein(&a, &bad, &o, &r) == CONSPH_EINVAL, "negative weight accepted");
    CHECK(consph_wasserstein(&a, &empty, &o, &r) == CONSPH_EINVAL, "empty measure accepted");
    CHECK(consph_wasserstein(&a, &two, &o, &r) == CONSPH_EINVAL, "1D vs 2D accepted");
    CHECK(consph_wasserstein(&two, &two, &o, &r) == CONSPH_EINVAL, "exact in 2D accepted");
    o.p = 3;
    CHECK(consph_wasserstein(&a, &a, &o, &r) == CONSPH_EINVAL, "p = 3 accepted");
}

typedef struct seen {
    long calls, last_iteration;
    double last_done, last_total;
} seen;

static void count_iterations(void *ctx, long iteration, double eps_abs, double marginal_error)
{
    seen *s = ctx;
    CHECK(iteration == s->last_iteration + 1 && eps_abs > 0 && marginal_error >= 0,
          "sinkhorn progress: iteration %ld after %ld", iteration, s->last_iteration);
    s->last_iteration = iteration;
    s->calls++;
}

static void count_cells(void *ctx, double done, double total)
{
    seen *s = ctx;
    CHECK(done > s->last_done && done <= total, "grid progress: %g of %g after %g", done, total,
          s->last_done);
    s->last_done = done;
    s->last_total = total;
    s->calls++;
}

/* The estimates behind `consph wasserstein`'s memory refusal and time note,
 * and progress callbacks that report every iteration and block of cells without changing a
 * bit of the result. */
static void test_estimates_and_progress(void)
{
    consph_ot_options sl = method(CONSPH_OT_SLICED, 2), sk = method(CONSPH_OT_SINKHORN, 2);
    /* 2D, 1600 particles against the uniform grid of 10000² cells: the 10.9 GB that prompted the
     * refusal, with 2 threads (grid copy and one projection buffer per thread). */
    consph_ot_estimate e = consph_wasserstein_estimate(&sl, 2, 1600, 1e8, 2);
    CHECK(e.bytes > 8e9 && e.bytes < 1.2e10, "sliced estimate %g bytes", e.bytes);
    consph_ot_estimate e1 = consph_wasserstein_estimate(&sl, 2, 1600, 1e8, 1);
    CHECK(e1.bytes < e.bytes && e1.seconds > e.seconds, "threads: %g %g", e1.bytes, e1.seconds);
    consph_ot_estimate g = consph_grid_measure_estimate(2, 10000, 0, 1);
    CHECK(fabs(g.bytes - 2.4e9) < 1e6, "grid bytes %g", g.bytes);
    consph_ot_estimate gs = consph_grid_measure_estimate(3, 500, 1728, 2);
    CHECK(gs.seconds > 120, "3D smoothing on a 500³ grid estimated at %g s", gs.seconds);
    /* Sinkhorn: O(N + M) memory, O(N M) per iteration (README's 1600 vs 6400). */
    consph_ot_estimate s1 = consph_wasserstein_estimate(&sk, 2, 1600, 6400, 1);
    CHECK(s1.bytes < 1e6 && s1.seconds > 0.1 && s1.seconds < 10, "sinkhorn %g B %g s", s1.bytes,
          s1.seconds);

    consph_rng rng;
    consph_rng_seed(&rng, 5);
    enum { NA = 40, NB = 50 };
    double xa[2][NA], xb[2][NB];
    for (int a = 0; a < 2; ++a) {
        for (int i = 0; i < NA; ++i) xa[a][i] = consph_rng_uniform(&rng);
        for (int i = 0; i < NB; ++i) xb[a][i] = consph_rng_uniform(&rng);
    }
    consph_measure ma = {2, NA, {xa[0], xa[1]}, NULL}, mb = {2, NB, {xb[0], xb[1]}, NULL};
    consph_ot_result plain, watched;
    wdist(&ma, &mb, sk, &plain);
    seen s = {0, 0, 0, 0};
    sk.progress = count_iterations;
    sk.progress_ctx = &s;
    wdist(&ma, &mb, sk, &watched);
    CHECK(s.calls == watched.iterations && s.calls > 0, "%ld progress calls, %ld iterations",
          s.calls, watched.iterations);
    CHECK(memcmp(&plain, &watched, sizeof plain) == 0, "progress changed the Sinkhorn result");

    consph_box box = consph_box_unit(2, 1);
    consph_kernel k;
    consph_kernel_id id;
    CHECK(consph_kernel_lookup("quintic", &id) == CONSPH_OK, "quintic");
    CHECK(consph_kernel_init(&k, id, 2, 0.15) == CONSPH_OK, "kernel init");
    consph_grid_measure g0, g1;
    CHECK(consph_grid_measure_sph(&box, 300, &ma, &k, &g0) == CONSPH_OK, "%s", consph_last_error());
    seen c = {0, 0, 0, 0};
    CHECK(consph_grid_measure_sph_progress(&box, 300, &ma, &k, &g1, count_cells, &c) == CONSPH_OK,
          "%s", consph_last_error());
    CHECK(c.calls > 1 && c.last_done == 90000 && c.last_total == 90000, "%ld grid reports",
          c.calls);
    CHECK(memcmp(g0.mu.w, g1.mu.w, g0.mu.n * sizeof *g0.mu.w) == 0,
          "progress changed the smoothed density");
    consph_grid_measure_free(&g0);
    consph_grid_measure_free(&g1);
}

int main(void)
{
    test_gaussians();
    test_translation();
    test_lattice_uniform();
    test_point_smoothed();
    test_metric();
    test_sinkhorn_limit();
    test_threads();
    test_rejections();
    test_estimates_and_progress();
    return check_summary("test_transport");
}
