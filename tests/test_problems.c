/* The problems and the δ-SPH family: every scheme runs 20 steps of Taylor-Green,
 * Gresho-Chan and the shear layer at nx = 32 with finite values or stops with the divergence
 * message; Gresho-Chan starts from 001 eq. 37; the problems' defaults (inviscid Gresho-Chan);
 * errors of the shear layer are n/a; δ-SPH conserves momentum; thread-count independence. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "check.h"
#include "consph/solver.h"
#include "solver/solver_internal.h"

static consph_run_params params(const char *problem, const char *scheme, int nx, long steps)
{
    consph_run_params p;
    consph_run_params_default(&p);
    CHECK(consph_run_params_problem(&p, problem) == CONSPH_OK, "problem %s: %s", problem,
          consph_last_error());
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = nx;
    p.steps = steps;
    p.tf = 0.0;
    return p;
}

/* Every value of the state is finite. */
static int state_finite(const consph_solver *s)
{
    const consph_particles *p = consph_solver_particles(s);
    static const char *const names[] = {SF_U, SF_P, SF_RHOF};
    for (int d = 0; d < p->dim; ++d)
        for (size_t i = 0; i < p->n; ++i)
            if (!isfinite(p->x[d][i])) return 0;
    for (size_t f = 0; f < sizeof names / sizeof names[0]; ++f) {
        const consph_field *fd = consph_particles_find(p, names[f]);
        if (!fd) return 0;
        for (int c = 0; c < fd->ncomp; ++c)
            for (size_t i = 0; i < p->n; ++i)
                if (!isfinite(fd->data[(size_t)c * p->cap + i])) return 0;
    }
    return 1;
}

/* Every scheme of consph_scheme_names() on every 2D problem of consph_problem_names() (the 3D
 * ones: test_beltrami.c): 20 steps at nx = 32, finite, or stopped by the divergence check with
 * its message. Prints which (the report cites it). */
static void test_every_scheme_every_problem(void)
{
    const char *problems[16];
    size_t nproblems = 0;
    char pnames[512];
    snprintf(pnames, sizeof pnames, "%s", consph_problem_names());
    for (char *t = strtok(pnames, ","); t && nproblems < 16; t = strtok(NULL, ","))
        if (problem_find(t)->dim == 2) problems[nproblems++] = t;
    CHECK(nproblems >= 3, "%zu 2D problems in '%s'", nproblems, consph_problem_names());
    char names[1024];
    snprintf(names, sizeof names, "%s", consph_scheme_names());
    for (char *t = strtok(names, ","); t; t = strtok(NULL, ","))
        for (size_t k = 0; k < nproblems; ++k) {
            consph_run_params p = params(problems[k], t, 32, 20);
            /* A packed default (Taylor-Green leaves the layout to the scheme) costs a packing per
             * scheme: random is disordered enough for a smoke run; the Eulerian and remeshing
             * schemes need the lattice */
            if (problem_find(problems[k])->layout < 0 &&
                scheme_find(t)->layout == CONSPH_LAYOUT_PACKED)
                p.layout = CONSPH_LAYOUT_RANDOM;
            consph_solver *s = NULL;
            int st = consph_solver_create(&s, &p);
            CHECK(st == CONSPH_OK, "%s %s: create: %s", problems[k], t, consph_last_error());
            if (st != CONSPH_OK) continue;
            long step = 0;
            while (st == CONSPH_OK && !consph_solver_done(s)) {
                st = consph_solver_step(s);
                ++step;
            }
            if (st == CONSPH_OK) {
                CHECK(state_finite(s), "%s %s: a non-finite value after 20 steps", problems[k], t);
                printf("%-14s %-18s ran 20 steps\n", problems[k], t);
            } else {
                CHECK(st == CONSPH_ENUMERIC && strstr(consph_last_error(), "diverged at step"),
                      "%s %s: step %ld failed without the divergence message: %s", problems[k], t,
                      step, consph_last_error());
                printf("%-14s %-18s %s\n", problems[k], t, consph_last_error());
            }
            consph_solver_free(s);
        }
}

/* 001 eq. 37 written out here, independently of problems.c. */
static void eq37(double r, double *uphi, double *p)
{
    if (r < 0.2) {
        *uphi = 5.0 * r;
        *p = 12.5 * r * r + 5.0;
    } else if (r < 0.4) {
        *uphi = 2.0 - 5.0 * r;
        *p = 12.5 * r * r - 20.0 * r + 4.0 * log(5.0 * r) + 9.0;
    } else {
        *uphi = 0.0;
        *p = 3.0 + 4.0 * log(2.0);
    }
}

static void test_gresho_initial(void)
{
    /* sample radii, each with its value of eq. 37 computed by hand */
    const problem_def *pb = problem_find("gresho-chan");
    CHECK(pb != NULL, "gresho-chan is not a problem");
    if (!pb) return;
    consph_run_params prm = params("gresho-chan", "l-ipst-c", 32, 1);
    const struct {
        double r, uphi, p;
    } pts[] = {{0.1, 0.5, 5.125},
               {0.2, 1.0, 5.5},
               {0.3, 0.5, 12.5 * 0.09 - 6.0 + 4.0 * log(1.5) + 9.0},
               {0.45, 0.0, 3.0 + 4.0 * log(2.0)},
               {0.6, 0.0, 3.0 + 4.0 * log(2.0)}};
    for (size_t k = 0; k < sizeof pts / sizeof pts[0]; ++k)
        for (int a = 0; a < 8; ++a) {
            const double th = 2.0 * M_PI * a / 8.0 + 0.1;
            const double x[3] = {pts[k].r * cos(th), pts[k].r * sin(th), 0.0};
            double u[3], p;
            for (int ti = 0; ti < 2; ++ti) {
                pb->exact(&prm, ti * 3.0, x, u, &p); /* steady: t = 0 and t = 3 agree */
                const double up = (x[0] * u[1] - x[1] * u[0]) / pts[k].r;
                const double ur = (x[0] * u[0] + x[1] * u[1]) / pts[k].r;
                CHECK(fabs(up - pts[k].uphi) < 1e-12 && fabs(ur) < 1e-12 &&
                          fabs(p - pts[k].p) < 1e-12,
                      "r = %g: u_phi %g (eq. 37: %g), u_r %g, p %g (eq. 37: %g)", pts[k].r, up,
                      pts[k].uphi, ur, p, pts[k].p);
            }
        }
    /* and the particles of a run start on it: u and p at every particle */
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &prm) == CONSPH_OK, "create: %s", consph_last_error());
    if (!s) return;
    const consph_particles *p = consph_solver_particles(s);
    const consph_field *fu = consph_particles_find(p, SF_U), *fp = consph_particles_find(p, SF_P);
    double worst = 0.0;
    for (size_t i = 0; i < p->n; ++i) {
        const double x = p->x[0][i], y = p->x[1][i], r = hypot(x, y);
        double up, pe;
        eq37(r, &up, &pe);
        const double ux = r > 0.0 ? -up * y / r : 0.0, uy = r > 0.0 ? up * x / r : 0.0;
        worst = fmax(worst, fabs(fu->data[i] - ux) + fabs(fu->data[p->cap + i] - uy) +
                                fabs(fp->data[i] - pe));
    }
    CHECK(worst < 1e-12, "initial particles differ from eq. 37 by %g", worst);
    CHECK(p->box.lo[0] == -0.5 && p->box.hi[1] == 0.5, "box [%g, %g)", p->box.lo[0], p->box.hi[1]);
    consph_solver_free(s);
}

/* The problems' defaults, and ν = 0 meaning inviscid. */
static void test_defaults(void)
{
    consph_run_params p;
    consph_run_params_default(&p);
    CHECK(consph_run_params_problem(&p, "gresho-chan") == CONSPH_OK, "%s", consph_last_error());
    CHECK(p.tf == 3.0 && p.nu == 0.0 && p.layout == CONSPH_LAYOUT_LATTICE,
          "gresho-chan: tf %g nu %g layout %d", p.tf, p.nu, p.layout);
    CHECK(consph_run_params_problem(&p, "shear-layer") == CONSPH_OK, "%s", consph_last_error());
    CHECK(p.nu == 1e-4 && p.tf > 0.0, "shear-layer: nu %g tf %g", p.nu, p.tf);
    CHECK(consph_run_params_problem(&p, "vortex") == CONSPH_EINVAL &&
              strstr(consph_last_error(), "gresho-chan"),
          "an unknown problem: %s", consph_last_error());
    /* Taylor-Green's parameters are the defaults of before: ν from Re */
    consph_run_params a, b;
    consph_run_params_default(&a);
    b = a;
    CHECK(consph_run_params_problem(&b, "taylor-green") == CONSPH_OK, "%s", consph_last_error());
    CHECK(!memcmp(&a, &b, sizeof a), "taylor-green changed the defaults");
    /* inviscid: a Gresho-Chan run has ν = 0, so the Laplacian forms cannot differ */
    consph_run_params q = params("gresho-chan", "l-ipst-c", 16, 5);
    consph_solver *s1 = NULL, *s2 = NULL;
    consph_solver_create(&s1, &q);
    snprintf(q.scheme, sizeof q.scheme, "l-ipst-k");
    consph_solver_create(&s2, &q);
    CHECK(s1 && s2, "create: %s", consph_last_error());
    if (s1 && s2) {
        for (int k = 0; k < 5; ++k) {
            consph_solver_step(s1);
            consph_solver_step(s2);
        }
        consph_run_summary m1, m2;
        consph_solver_summary(s1, &m1);
        consph_solver_summary(s2, &m2);
        CHECK(m1.l1_u == m2.l1_u && m1.ke == m2.ke, "nu = 0 but the viscosity acts: %g vs %g",
              m1.l1_u, m2.l1_u);
    }
    consph_solver_free(s1);
    consph_solver_free(s2);
    q.nu = NAN;
    CHECK(consph_run_params_check(&q) == CONSPH_EINVAL &&
              strstr(consph_last_error(), "nu = nan is out of range"),
          "nu NaN accepted");
}

/* No exact solution: the errors are n/a (NaN), not a failure; the state stays finite. */
static void test_shear_layer_no_exact(void)
{
    consph_run_params p = params("shear-layer", "e-c", 16, 3);
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "%s", consph_last_error());
    if (!s) return;
    int st = CONSPH_OK;
    for (int k = 0; k < 3 && st == CONSPH_OK; ++k) st = consph_solver_step(s);
    CHECK(st == CONSPH_OK, "%s", consph_last_error());
    consph_run_summary sum;
    consph_solver_summary(s, &sum);
    CHECK(isnan(sum.l1_u) && isnan(sum.l1_p) && isnan(sum.linf_u) && isnan(sum.linf_p),
          "errors without an exact solution: %g %g %g %g", sum.l1_u, sum.l1_p, sum.linf_u,
          sum.linf_p);
    CHECK(isfinite(sum.ke) && sum.ke > 0.0 && state_finite(s), "state not finite");
    consph_solver_free(s);
}

/* δ-SPH's sym1 pressure gradient and Monaghan-type viscosity are antisymmetric in i, j with
 * V_j = m/ρ_j: total momentum stays at its initial value to round-off on packed particles. */
static void test_delta_momentum(void)
{
    consph_run_params p = params("taylor-green", "delta-sph", 16, 20);
    p.layout = CONSPH_LAYOUT_RANDOM;
    p.alpha = 0.1;
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "%s", consph_last_error());
    if (!s) return;
    consph_step_diag g0, g1;
    consph_solver_diag(s, &g0);
    int st = CONSPH_OK;
    for (int k = 0; k < 20 && st == CONSPH_OK; ++k) st = consph_solver_step(s);
    consph_solver_diag(s, &g1);
    CHECK(st == CONSPH_OK, "%s", consph_last_error());
    CHECK(fabs(g1.mom[0] - g0.mom[0]) < 1e-14 && fabs(g1.mom[1] - g0.mom[1]) < 1e-14,
          "momentum moved by (%g, %g)", g1.mom[0] - g0.mom[0], g1.mom[1] - g0.mom[1]);
    consph_solver_free(s);
}

/* The δ family on 1 and 2 threads, bit for bit (sys.parallel_min = 1 forces the parallel
 * path on this small set). */
static void test_threads(void)
{
#ifdef _OPENMP
    static const char *const sch[] = {"delta-sph", "delta-plus-sph", "delta-plus-sph-d"};
    for (int k = 0; k < 3; ++k) {
        double ke[2], mx[2];
        for (int t = 1; t <= 2; ++t) {
            omp_set_num_threads(t);
            consph_run_params p = params("gresho-chan", sch[k], 16, 5);
            consph_solver *s = NULL;
            CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "%s", consph_last_error());
            if (!s) return;
            s->sys.parallel_min = 1;
            for (int i = 0; i < 5; ++i) consph_solver_step(s);
            consph_step_diag g;
            consph_solver_diag(s, &g);
            ke[t - 1] = g.ke;
            mx[t - 1] = g.mom[0];
            consph_solver_free(s);
        }
        CHECK(ke[0] == ke[1] && mx[0] == mx[1], "%s: 1 and 2 threads differ (%.17g, %.17g)", sch[k],
              ke[0], ke[1]);
    }
    omp_set_num_threads(1);
#endif
}

int main(void)
{
#ifdef _OPENMP
    omp_set_num_threads(1);
#endif
    test_gresho_initial();
    test_defaults();
    test_shear_layer_no_exact();
    test_delta_momentum();
    test_threads();
    test_every_scheme_every_problem();
    return check_summary("test_problems");
}
