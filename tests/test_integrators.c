/* The integrators' table (src/integrators/): the names the CLI lists come from it, an unknown
 * one is refused naming the allowed ones, and each row's step keeps its order in time and its
 * evaluations per step. Measured on wcsph's Taylor-Green on a 16² lattice at fixed Δt: the
 * velocity at t = 0.04 with Δt, Δt/2 and Δt/4 departs from a run with Δt/32 on the same
 * particles by errors whose ratios give the order. α = 0: the artificial viscosity's switch on
 * u_ij·x_ij is not smooth in time and would cap the order it lets us see. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/solver.h"

#define NX 16
#define NP (NX * NX)

static consph_run_params params(const char *integ, double dt)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "wcsph");
    snprintf(p.integrator, sizeof p.integrator, "%s", integ);
    p.nx = NX;
    p.alpha = 0.0;
    p.dt = dt;
    p.tf = 0.04;
    return p;
}

/* The final velocity by initial particle index; the steps taken and the pairs visited. */
static int run_dt(const char *integ, double dt, double *u_out, double *steps, double *pairs)
{
    consph_run_params p = params(integ, dt);
    consph_solver *s = NULL;
    int st = consph_solver_create(&s, &p);
    CHECK(st == CONSPH_OK, "%s create: %s", integ, consph_last_error());
    if (st != CONSPH_OK) return st;
    while (st == CONSPH_OK && !consph_solver_done(s)) st = consph_solver_step(s);
    CHECK(st == CONSPH_OK, "%s run: %s", integ, consph_last_error());
    const consph_particles *q = consph_solver_particles(s);
    const consph_field *fu = consph_particles_find(q, "u"), *fid = consph_particles_find(q, "id");
    CHECK(q->n == NP && fu && fid, "%s: %zu particles", integ, q->n);
    for (size_t i = 0; fu && fid && i < q->n && i < NP; ++i) {
        const size_t k = (size_t)fid->data[i]; /* runs sort differently */
        u_out[k] = fu->data[i];
        u_out[NP + k] = fu->data[q->cap + i];
    }
    consph_run_summary sum;
    consph_solver_summary(s, &sum);
    *steps = (double)sum.steps;
    *pairs = (double)sum.pairs;
    consph_solver_free(s);
    return st;
}

static void time_order(const char *integ, int evals, double lo, double hi)
{
    static double ref[2 * NP], u[2 * NP];
    const double dt = 2e-3;
    double steps, pairs, err[3];
    run_dt(integ, dt / 32, ref, &steps, &pairs);
    for (int r = 0; r < 3; ++r) {
        run_dt(integ, dt / (1 << r), u, &steps, &pairs);
        double e = 0.0;
        for (size_t i = 0; i < 2 * NP; ++i) e = fmax(e, fabs(u[i] - ref[i]));
        err[r] = e;
        /* wcsph's rates are one pass; on the lattice every particle starts with ~45 neighbours
         * (pairs counted with i itself), so the pairs per step count the evaluations */
        const double per_eval = pairs / steps / evals;
        CHECK(steps == 20 << r, "%s: %g steps", integ, steps);
        CHECK(per_eval > 40.0 * NP && per_eval < 50.0 * NP,
              "%s: %.0f pairs per step / %d, expected %d evaluations per step (~45 n each)", integ,
              pairs / steps, evals, evals);
    }
    const double o1 = log2(err[0] / err[1]), o2 = log2(err[1] / err[2]);
    printf("%s time order: max |u - u_ref| %.3e %.3e %.3e, orders %.2f %.2f\n", integ, err[0],
           err[1], err[2], o1, o2);
    CHECK(o1 > lo && o1 < hi && o2 > lo && o2 < hi, "%s: time orders %.2f %.2f outside [%g, %g]",
          integ, o1, o2, lo, hi);
}

static void test_names(void)
{
    const char *names = consph_integrator_names();
    const char *want[] = {"rk2", "euler", "kdk", "pec", "ssprk3"};
    for (int k = 0; k < 5; ++k) {
        CHECK(strstr(names, want[k]) != NULL, "'%s' not in the names '%s'", want[k], names);
        consph_run_params p = params(want[k], 1e-3);
        CHECK(consph_run_params_check(&p) == CONSPH_OK, "%s refused: %s", want[k],
              consph_last_error());
    }
    consph_run_params p = params("rk4", 1e-3);
    CHECK(consph_run_params_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), names) &&
              strstr(consph_last_error(), "integrator 'rk4'"),
          "rk4 not refused with the allowed names: %s", consph_last_error());
}

int main(void)
{
    test_names();
    time_order("rk2", 2, 1.7, 2.4);
    time_order("ssprk3", 3, 2.7, 3.4);
    return check_summary("test_integrators");
}
