/* The heat-conduction solver of 002 §6 (include/consph/heat.h): the exact series against the
 * reference values of docs/reference-values.md ("Heat exact solution"), S4's exactness on the
 * steady state T = y (002 eq. 40: exact for quadratics), S4 against S3 at η = 1.5, Dirichlet walls
 * that never change, the time steps landing on t = 0.1, and results independent of the thread
 * count. */
#include <math.h>
#include <string.h>

#include "check.h"
#include "consph/heat.h"

static const double *field(const consph_particles *p, const char *name)
{
    const consph_field *f = consph_particles_find(p, name);
    return f ? f->data : NULL;
}

/* docs/reference-values.md, "Heat exact solution": 002 eq. 43 at t = 0.1 (2000 terms there; ours
 * stop at a 1e-14 term bound). */
static void test_series(void)
{
    static const double z8[][3] = {{0.5, 0.5, 0.1550614991},
                                   {0.5, 0.25, 0.0457762399},
                                   {0.5, 0.75, 0.4195832981},
                                   {0.25, 0.5, 0.1096450375},
                                   {0.5, 0.9, 0.7144595078}};
    for (size_t k = 0; k < sizeof z8 / sizeof z8[0]; ++k) {
        int terms = 0;
        double T = consph_heat_exact(CONSPH_HEAT_WALLS_SIN, 1.0, z8[k][0], z8[k][1], 0.1, &terms);
        CHECK_NEAR(T, z8[k][2], 1e-9, "T(%g, %g, 0.1)", z8[k][0], z8[k][1]);
        CHECK(terms > 0 && terms < 20, "%d terms", terms);
    }
    /* the steady state sinh(πy)/sinh(π) sin(πx) at late times (0.1992684077 at the centre) */
    CHECK_NEAR(consph_heat_exact(CONSPH_HEAT_WALLS_SIN, 1.0, 0.5, 0.5, 50.0, NULL), 0.1992684077,
               1e-9, "steady state");
    /* walls and the initial state */
    CHECK(consph_heat_exact(CONSPH_HEAT_WALLS_SIN, 1.0, 0.3, 1.0, 0.0, NULL) == sin(M_PI * 0.3),
          "top wall");
    CHECK(consph_heat_exact(CONSPH_HEAT_WALLS_SIN, 1.0, 0.3, 0.4, 0.0, NULL) == 0.0, "t = 0");
}

/* Every wall particle holds its Dirichlet value exactly. */
static int walls_exact(const consph_heat *h, consph_heat_walls walls)
{
    const consph_particles *p = consph_heat_particles(h);
    const double *T = field(p, "T"), *wall = field(p, "wall");
    int bad = 0;
    for (size_t i = 0; i < p->n; ++i) {
        if (wall[i] == 0.0) continue;
        double x = p->x[0][i], y = p->x[1][i];
        double want = walls == CONSPH_HEAT_WALLS_LINEAR ? y : y >= 1.0 ? sin(M_PI * x) : 0.0;
        if (T[i] != want) ++bad;
    }
    return bad;
}

/* 002 eq. 40: S4 is exact for quadratics, so T = y stays put to round-off, on the lattice and on
 * the ε = 0.4 particles. */
static void test_linear_steady(double eps)
{
    consph_heat_params prm;
    consph_heat_params_default(&prm);
    prm.laplacian = CONSPH_HEAT_S4;
    prm.walls = CONSPH_HEAT_WALLS_LINEAR;
    prm.nx = 20;
    prm.eta = 2.5;
    prm.eps = eps;
    prm.steps = 100;
    consph_heat *h = NULL;
    CHECK(consph_heat_create(&h, &prm) == CONSPH_OK, "create: %s", consph_last_error());
    if (!h) return;
    while (!consph_heat_done(h))
        if (consph_heat_step(h) != CONSPH_OK) break;
    CHECK(consph_heat_step_count(h) == 100, "%ld steps", consph_heat_step_count(h));
    const consph_particles *p = consph_heat_particles(h);
    const double *T = field(p, "T");
    double worst = 0.0;
    for (size_t i = 0; i < p->n; ++i) worst = fmax(worst, fabs(T[i] - p->x[1][i]));
    CHECK(worst <= 1e-10, "eps %g: max |T - y| = %.3e after 100 steps", eps, worst);
    CHECK(walls_exact(h, prm.walls) == 0, "eps %g: wall values changed", eps);
    consph_heat_summary sum;
    consph_heat_summary_get(h, &sum);
    CHECK(sum.fallbacks == 0, "eps %g: %zu fallbacks", eps, sum.fallbacks);
    CHECK(sum.linf <= 1e-10, "eps %g: linf %.3e", eps, sum.linf);
    consph_heat_free(h);

    /* S3 is not exact on the perturbed particles: the test above can fail */
    if (eps > 0.0) {
        prm.laplacian = CONSPH_HEAT_S3;
        CHECK(consph_heat_create(&h, &prm) == CONSPH_OK, "create: %s", consph_last_error());
        if (!h) return;
        consph_heat_run(h, NULL, 0, &sum);
        CHECK(sum.linf > 1e-6, "S3 keeps T = y on eps %g particles (linf %.3e)?", eps, sum.linf);
        consph_heat_free(h);
    }
}

static int run_to_end(consph_heat_lap lap, int nx, double eta, double eps, consph_heat_summary *sum,
                      int *walls_bad)
{
    consph_heat_params prm;
    consph_heat_params_default(&prm);
    prm.laplacian = lap;
    prm.nx = nx;
    prm.eta = eta;
    prm.eps = eps;
    consph_heat *h = NULL;
    int st = consph_heat_create(&h, &prm);
    CHECK(st == CONSPH_OK, "create: %s", consph_last_error());
    if (st != CONSPH_OK) return st;
    st = consph_heat_run(h, NULL, 0, sum);
    CHECK(st == CONSPH_OK, "run: %s", consph_last_error());
    if (walls_bad) *walls_bad = walls_exact(h, prm.walls);
    consph_heat_free(h);
    return st;
}

/* 002 §6.1: at η = 1.5 (8 neighbours) S4 is far more accurate than S3 on the lattice. */
static void test_s4_beats_s3(void)
{
    consph_heat_summary s3, s4;
    int wb3 = -1, wb4 = -1;
    if (run_to_end(CONSPH_HEAT_S3, 20, 1.5, 0.0, &s3, &wb3) != CONSPH_OK) return;
    if (run_to_end(CONSPH_HEAT_S4, 20, 1.5, 0.0, &s4, &wb4) != CONSPH_OK) return;
    CHECK(s4.l2 < 0.1 * s3.l2, "l2 S4 %.3e vs S3 %.3e", s4.l2, s3.l2);
    CHECK(s4.linf < s3.linf, "linf S4 %.3e vs S3 %.3e", s4.linf, s3.linf);
    CHECK(wb3 == 0 && wb4 == 0, "wall values changed (%d, %d)", wb3, wb4);
    /* the run lands on t = 0.1: Δ = 1/19, Δt = 0.2Δ², 180 full steps and a shorter one */
    CHECK(s4.t == 0.1, "t = %.17g", s4.t);
    CHECK(s4.steps == 181, "%ld steps", s4.steps);
    CHECK_NEAR(s4.dt, 0.2 / (19.0 * 19.0), 1e-15, "dt");
    CHECK(s4.dt_last > 0.0 && s4.dt_last < s4.dt, "last step %.3e", s4.dt_last);
    CHECK(s4.n == 400 && s4.n_interior == 324, "n %zu interior %zu", s4.n, s4.n_interior);
}

/* Wall values on perturbed particles: the walls stay unperturbed and unchanged. */
static void test_walls_perturbed(void)
{
    consph_heat_summary sum;
    int wb = -1;
    if (run_to_end(CONSPH_HEAT_S4, 12, 2.0, 0.4, &sum, &wb) != CONSPH_OK) return;
    CHECK(wb == 0, "%d wall values changed", wb);
    CHECK(sum.d_min < sum.delta, "d_min %.3e vs Δ %.3e on perturbed particles", sum.d_min,
          sum.delta);
    CHECK_NEAR(sum.dt, 0.2 * sum.d_min * sum.d_min, 1e-18, "Δt from d_min");
    CHECK(isfinite(sum.l2) && sum.l2 < 1e-2, "l2 %.3e", sum.l2);
}

/* Bit-identical results on 1 and 2 threads (nx = 50: 2500 particles, above the serial
 * threshold of a pass). */
static void test_threads(void)
{
    double l2[2], linf[2], ec[2];
    for (int k = 0; k < 2; ++k) {
        consph_set_num_threads(k + 1);
        consph_heat_params prm;
        consph_heat_params_default(&prm);
        prm.nx = 50;
        prm.eps = 0.2;
        prm.steps = 20;
        consph_heat *h = NULL;
        consph_heat_summary sum;
        CHECK(consph_heat_create(&h, &prm) == CONSPH_OK, "create: %s", consph_last_error());
        if (!h) return;
        consph_heat_run(h, NULL, 0, &sum);
        consph_heat_free(h);
        l2[k] = sum.l2;
        linf[k] = sum.linf;
        ec[k] = sum.ec;
    }
    consph_set_num_threads(1);
    CHECK(memcmp(&l2[0], &l2[1], sizeof(double)) == 0, "l2 %.17g vs %.17g", l2[0], l2[1]);
    CHECK(memcmp(&linf[0], &linf[1], sizeof(double)) == 0, "linf");
    CHECK(memcmp(&ec[0], &ec[1], sizeof(double)) == 0, "ec");
}

static void test_params(void)
{
    consph_heat_params prm;
    consph_heat_params_default(&prm);
    prm.eta = 0.5;
    consph_heat *h = NULL;
    CHECK(consph_heat_create(&h, &prm) == CONSPH_EINVAL && !h, "eta 0.5 accepted");
    CHECK(strstr(consph_last_error(), "--eta") != NULL, "message: %s", consph_last_error());
    consph_heat_lap lap;
    CHECK(consph_heat_lap_lookup("s5", &lap) == CONSPH_EINVAL, "s5 accepted");
    CHECK(strstr(consph_last_error(), "s3, s4") != NULL, "message: %s", consph_last_error());
}

int main(void)
{
    test_series();
    test_linear_steady(0.0);
    test_linear_steady(0.4);
    test_s4_beats_s3();
    test_walls_perturbed();
    test_threads();
    test_params();
    return check_summary("test_heat");
}
