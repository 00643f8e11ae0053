/* The IPST schedule and the shifting constants of the 001 schemes as 001's authors run them
 * (docs/schemes.md, "IPST schedule" and "Shifting constants"):
 * - reg_ipst_due: after steps 1, K + 1, 2K + 1, ... of the run's Δt; on a reference Δt, the
 *   same shift times for two run Δt's (and accumulated times), at most once per step;
 * - a run counts those shifts (ipst_every alone, and ipst_h_dt at half the run's Δt);
 * - χ_o is max χ after the first shift (001's authors), or the lattice's on request;
 * - L-PST-C moves a particle by -2h² (U/c_o) Σ_j (1 + 0.24 (W_ij/W(Δs))⁴) ∇W_ij V_j and TV-C's
 *   shifting velocity is -2hU Σ_j (...) ∇W_ij V_j, both against a brute-force sum here. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/solver.h"
#include "regularise/regularise.h"
#include "solver/solver_internal.h"

/* Steps 1..nsteps of a run of step dt (times accumulated by additions, as the solver does):
 * due[k] is the step of the k-th shift; returns the number of shifts. */
static int schedule(double dt, int nsteps, int every, double period_dt, long *due, int cap)
{
    int m = 0;
    double t = 0.0;
    for (long n = 1; n <= nsteps; ++n) {
        double prev = t;
        t += dt;
        if (reg_ipst_due(n, prev, t, every, period_dt) && m < cap) due[m++] = n;
    }
    return m;
}

static void test_due(void)
{
    long due[64];
    /* the run's own steps: after 1, 11, 21 (PySPH's counter is 0, 10, 20 in the post-step) */
    int m = schedule(1e-3, 30, 10, 0.0, due, 64);
    CHECK(m == 3 && due[0] == 1 && due[1] == 11 && due[2] == 21, "steps: %d shifts, %ld %ld %ld", m,
          due[0], due[1], due[2]);
    CHECK(schedule(1e-3, 30, 0, 0.0, due, 64) == 0, "every 0: never");
    CHECK(schedule(1e-3, 30, 0, 1e-3, due, 64) == 0, "every 0 with a reference step: never");
    /* the reference step equal to the run's: the same steps */
    const double DT = 3.4285714285714284e-05; /* 0.3 (1.2/500)/21 */
    m = schedule(DT, 30, 10, DT, due, 64);
    CHECK(m == 3 && due[0] == 1 && due[1] == 11 && due[2] == 21, "DT: %d shifts, %ld %ld %ld", m,
          due[0], due[1], due[2]);
    /* a run of 2.5 DT: shift times DT, 11 DT, 21 DT, ... fall in steps 1, 5, 9, 13, ... */
    m = schedule(2.5 * DT, 160, 10, DT, due, 64);
    int ok = m == 40;
    for (int k = 0; k < m && ok; ++k) {
        const double ts = DT * (1 + 10.0 * k);
        ok = (due[k] - 1) * 2.5 * DT < ts * (1 + 1e-12) && ts <= due[k] * 2.5 * DT * (1 + 1e-12);
    }
    CHECK(ok, "2.5 DT: each of the 40 shift times in 400 DT once, in its step (%d shifts)", m);
    /* a run of 4 DT: same count over the same time span */
    m = schedule(4.0 * DT, 100, 10, DT, due, 64);
    CHECK(m == 40 && due[0] == 1 && due[1] == 3 && due[2] == 6, "4 DT: %d shifts, %ld %ld %ld", m,
          due[0], due[1], due[2]);
    /* a step longer than the period: every step, never twice */
    m = schedule(12.5 * DT, 20, 10, DT, due, 64);
    CHECK(m == 20, "12.5 DT: every step (%d of 20)", m);
}

static consph_run_params params(const char *scheme)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = 16;
    p.tf = 0.0;
    p.layout = CONSPH_LAYOUT_RANDOM;
    return p;
}

static long shifts_of_run(const consph_run_params *p)
{
    consph_solver *s = NULL;
    if (consph_solver_create(&s, p) != CONSPH_OK) {
        CHECK(0, "solver: %s", consph_last_error());
        return -1;
    }
    while (!consph_solver_done(s))
        if (consph_solver_step(s) != CONSPH_OK) {
            CHECK(0, "step: %s", consph_last_error());
            break;
        }
    consph_run_summary sum;
    CHECK(consph_solver_summary(s, &sum) == CONSPH_OK, "summary");
    consph_solver_free(s);
    return sum.regularisations;
}

static void test_run_counts(void)
{
    consph_run_params p = params("l-ipst-c");
    p.steps = 9;
    p.ipst_every = 4;
    long n = shifts_of_run(&p);
    CHECK(n == 3, "ipst_every 4, 9 steps: %ld shifts, want 3 (steps 1, 5, 9)", n);
    /* the run's h is 1.2/16; a reference h of half that halves the reference Δt: shift times
     * 0.5, 2.5, 4.5, 6.5, 8.5 run steps */
    p.ipst_h_dt = 0.5 * p.hdx / p.nx;
    n = shifts_of_run(&p);
    CHECK(n == 5, "ipst_h_dt at half the run's dt, 9 steps: %ld shifts, want 5", n);
}

/* Σ_j (1 + 0.24 (W_ij/W(Δs))⁴) ∇W_ij V_j at particle i, over every particle with the minimum
 * image of the periodic unit box, V_j from "volume". */
static void by_hand(consph_solver *s, size_t i, double *sum)
{
    consph_particles *p = s->sys.p;
    const consph_kernel *k = &s->sys.kernel;
    const double *vol = consph_particles_field(p, "volume", 1);
    const double L = s->prob->hi[0] - s->prob->lo[0], wds = consph_kernel_w(k, s->ds);
    sum[0] = sum[1] = 0.0;
    for (size_t j = 0; j < p->n; ++j) {
        double xij[2], r2 = 0.0;
        for (int a = 0; a < 2; ++a) {
            xij[a] = p->x[a][i] - p->x[a][j];
            xij[a] -= L * nearbyint(xij[a] / L);
            r2 += xij[a] * xij[a];
        }
        const double r = sqrt(r2), w = consph_kernel_w(k, r);
        if (r == 0.0 || w == 0.0) continue;
        double g[2];
        consph_kernel_grad(k, xij, r, g);
        const double f = 1.0 + 0.24 * pow(w / wds, 4.0);
        for (int a = 0; a < 2; ++a) sum[a] += f * g[a] * vol[j];
    }
}

static void test_constants(void)
{
    /* L-PST-C: the shift of particle 0 by the regularisation alone, from the initial state */
    consph_run_params p = params("l-pst-c");
    p.steps = 1;
    p.c0 = 20.0;
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "l-pst-c: %s", consph_last_error());
    if (s) {
        const size_t i = 0;
        double sum[2], x0[2] = {s->sys.p->x[0][i], s->sys.p->x[1][i]};
        by_hand(s, i, sum);
        CHECK(s->scheme->regularise(s) == CONSPH_OK, "l-pst-c shift: %s", consph_last_error());
        const double fac = -2.0 * s->h * s->h * p.U / s->c0;
        for (int a = 0; a < 2; ++a) {
            const double L = s->prob->hi[a] - s->prob->lo[a];
            double dx = s->sys.p->x[a][i] - x0[a];
            dx -= L * nearbyint(dx / L);
            CHECK(fabs(dx - fac * sum[a]) <= 1e-9 * fabs(fac * sum[a]) && dx != 0.0,
                  "l-pst-c: δx_%d = %.10g, by hand -2h²Ma Σ = %.10g", a, dx, fac * sum[a]);
        }
        consph_solver_free(s);
    }
    /* TV-C: the shifting velocity of particle 0 */
    p = params("tv-c");
    p.steps = 1;
    p.c0 = 20.0;
    s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "tv-c: %s", consph_last_error());
    if (s) {
        const size_t i = 0;
        double sum[2], *du = NULL;
        by_hand(s, i, sum);
        CHECK(solver_shift_velocity_tvc(s, &du) == CONSPH_OK && du, "tv-c δu: %s",
              consph_last_error());
        const double fac = -2.0 * s->h * p.U;
        for (int a = 0; du && a < 2; ++a) {
            const double v = du[(size_t)a * s->sys.p->cap + i];
            CHECK(fabs(v - fac * sum[a]) <= 1e-9 * fabs(fac * sum[a]) && v != 0.0,
                  "tv-c: δu_%d = %.10g, by hand -2hU Σ = %.10g", a, v, fac * sum[a]);
        }
        consph_solver_free(s);
    }
}

/* χ_o as 001's authors fix it: max_i h^d Σ_j W_ij after the first shift (step 1), recorded in
 * the run's parameters; `lattice` keeps -1 (reg_chi0 is used). */
static void test_chi0_first_shift(void)
{
    consph_run_params p = params("l-ipst-c");
    p.steps = 1;
    p.ipst_every = 10;
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "l-ipst-c: %s", consph_last_error());
    if (!s) return;
    CHECK(consph_solver_step(s) == CONSPH_OK, "step: %s", consph_last_error());
    const consph_particles *q = consph_solver_particles(s);
    const consph_kernel *k = &s->sys.kernel;
    const double L = s->prob->hi[0] - s->prob->lo[0];
    double mx = 0.0;
    for (size_t i = 0; i < q->n; ++i) {
        double sum = 0.0;
        for (size_t j = 0; j < q->n; ++j) {
            double r2 = 0.0;
            for (int a = 0; a < 2; ++a) {
                double x = q->x[a][i] - q->x[a][j];
                x -= L * nearbyint(x / L);
                r2 += x * x;
            }
            sum += consph_kernel_w(k, sqrt(r2));
        }
        mx = fmax(mx, s->h * s->h * sum);
    }
    const double chi0 = consph_solver_params(s)->ipst_chi0;
    CHECK(fabs(chi0 - mx) <= 1e-12 * mx, "χ_o %.15g, max χ after step 1 by hand %.15g", chi0, mx);
    CHECK(fabs(chi0 - s->chi0) > 1e-6, "χ_o %.10g is not the lattice's %.10g", chi0, s->chi0);
    consph_solver_free(s);
    p.ipst_chi0 = -1.0;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "lattice: %s", consph_last_error());
    if (!s) return;
    CHECK(consph_solver_step(s) == CONSPH_OK, "step: %s", consph_last_error());
    CHECK(consph_solver_params(s)->ipst_chi0 == -1.0, "lattice χ_o kept");
    consph_solver_free(s);
}

int main(void)
{
    test_chi0_first_shift();
    test_due();
    test_run_counts();
    test_constants();
    return check_summary("test_ipst_schedule");
}
