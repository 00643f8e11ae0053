/* The error measure of 001's authors (--error authors): on small Taylor-Green
 * runs the reported mean over the output times equals the normalised errors computed here by
 * hand from the particles at those times (the exact solution written out again, not consph's);
 * --tf runs land on the output times, t = 0 included; --steps runs sample each output step
 * once; a restart continues the measure bit for bit; an eq26 run is not touched by it.
 * F_T/F_max is the authors' Σ m a_x / max |a_x| of the whole acceleration du/dt with
 * m = ρ_o Δs², by hand from the particles; at round-off on the lattice for E-C. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/solver.h"

/* 001 eq. 25 with U = 1 on the unit square. */
static void tg(double re, double t, double x, double y, double *umag, double *p)
{
    const double e = exp(-8.0 * M_PI * M_PI / re * t);
    const double u = -e * cos(2 * M_PI * x) * sin(2 * M_PI * y);
    const double v = e * sin(2 * M_PI * x) * cos(2 * M_PI * y);
    *umag = sqrt(u * u + v * v);
    *p = -0.25 * e * e * (cos(4 * M_PI * x) + cos(4 * M_PI * y));
}

/* mean||u| - |u_e|| / mean|u_e| and mean|p - p_e| / max|p_e| of the solver's state now. */
static void by_hand(const consph_solver *s, double *eu, double *ep)
{
    const consph_particles *p = consph_solver_particles(s);
    const consph_field *fu = consph_particles_find(p, "u"), *fp = consph_particles_find(p, "p");
    const double re = consph_solver_params(s)->re, t = consph_solver_time(s);
    double su = 0, sm = 0, sp = 0, pm = 0;
    for (size_t i = 0; i < p->n; ++i) {
        double me, pe;
        tg(re, t, p->x[0][i], p->x[1][i], &me, &pe);
        su += fabs(hypot(fu->data[i], fu->data[p->cap + i]) - me);
        sm += me;
        sp += fabs(fp->data[i] - pe);
        if (fabs(pe) > pm) pm = fabs(pe);
    }
    *eu = su / sm;
    *ep = sp / (double)p->n / pm;
}

static consph_run_params params(void)
{
    consph_run_params p;
    consph_run_params_default(&p);
    p.nx = 12;
    p.c0 = 20;
    p.error = CONSPH_ERROR_AUTHORS;
    return p;
}

static int close_to(double a, double b)
{
    return fabs(a - b) <= 1e-12 * fabs(b);
}

/* --tf: every output time k tf/(N - 1) is reached exactly, and the mean matches. */
static void test_tf(void)
{
    consph_run_params p = params();
    p.tf = 0.01;
    p.error_times = 5; /* output every 0.0025, Δt = 1.53e-3: most steps are cut */
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
    if (!s) return;
    double su = 0, sp = 0, eu, ep;
    int k = 0;
    by_hand(s, &eu, &ep);
    CHECK(eu < 1e-14 && ep < 1e-12, "t = 0 is sampled from the exact initial state: %g %g", eu, ep);
    su += eu, sp += ep, ++k;
    while (!consph_solver_done(s)) {
        CHECK(consph_solver_step(s) == CONSPH_OK, "step: %s", consph_last_error());
        const double t = consph_solver_time(s);
        /* an output time is reached exactly (the last is tf itself) */
        if (k < 5 && t == (k == 4 ? p.tf : p.tf * k / 4.0)) {
            by_hand(s, &eu, &ep);
            su += eu, sp += ep, ++k;
        }
        CHECK(consph_solver_step_count(s) < 100, "runaway");
        if (consph_solver_step_count(s) >= 100) break;
    }
    CHECK(k == 5, "reached %d of the 5 output times exactly", k);
    consph_run_summary sum;
    consph_solver_summary(s, &sum);
    CHECK(sum.error == CONSPH_ERROR_AUTHORS && sum.error_samples == 5, "samples %d",
          sum.error_samples);
    CHECK(close_to(sum.l1n_u, su / 5) && close_to(sum.l1n_p, sp / 5),
          "authors' L1: consph %.17g %.17g, by hand %.17g %.17g", sum.l1n_u, sum.l1n_p, su / 5,
          sp / 5);
    /* eq. 26 beside it, of the same run */
    CHECK(isfinite(sum.l1_u) && sum.l1_u > 0 && sum.l1_u != sum.l1n_u, "eq. 26 %g", sum.l1_u);
    consph_solver_free(s);
}

/* --steps: output steps round(k S/(N - 1)), each sampled once; no step is cut. */
static void test_steps(void)
{
    consph_run_params p = params();
    p.tf = 0.0;
    p.steps = 3;
    p.error_times = 50;
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
    if (!s) return;
    const double dt = consph_solver_dt(s);
    double su = 0, sp = 0, eu, ep;
    by_hand(s, &eu, &ep);
    su += eu, sp += ep;
    for (int k = 0; k < 3; ++k) {
        CHECK(consph_solver_step(s) == CONSPH_OK, "step: %s", consph_last_error());
        by_hand(s, &eu, &ep);
        su += eu, sp += ep;
    }
    consph_run_summary sum;
    consph_solver_summary(s, &sum);
    CHECK(sum.error_samples == 4 && sum.dt == dt, "samples %d (4: steps 0..3)", sum.error_samples);
    CHECK(close_to(sum.l1n_u, su / 4) && close_to(sum.l1n_p, sp / 4),
          "authors' L1: consph %.17g, by hand %.17g", sum.l1n_u, su / 4);
    consph_solver_free(s);
}

/* A checkpoint in the middle carries the sums and the next output time. */
static void test_restart(void)
{
    consph_run_params p = params();
    p.tf = 0.01;
    p.error_times = 7;
    consph_solver *a = NULL, *b = NULL;
    CHECK(consph_solver_create(&a, &p) == CONSPH_OK, "create: %s", consph_last_error());
    if (!a) return;
    for (int k = 0; k < 4; ++k) consph_solver_step(a);
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    int st = consph_solver_checkpoint_meta(a, &meta, &hist, &nh);
    if (st == CONSPH_OK) st = consph_solver_restore(&b, meta, consph_solver_particles(a), hist, nh);
    CHECK(st == CONSPH_OK, "restore: %s", consph_last_error());
    free(meta);
    free(hist);
    if (b) {
        while (!consph_solver_done(a)) consph_solver_step(a);
        while (!consph_solver_done(b)) consph_solver_step(b);
        consph_run_summary sa, sb;
        consph_solver_summary(a, &sa);
        consph_solver_summary(b, &sb);
        CHECK(sa.steps == sb.steps && sa.error_samples == 7 && sb.error_samples == 7 &&
                  memcmp(&sa.l1n_u, &sb.l1n_u, sizeof(double)) == 0 &&
                  memcmp(&sa.l1n_p, &sb.l1n_p, sizeof(double)) == 0,
              "restored: %ld/%ld steps, %d/%d samples, %.17g vs %.17g", sa.steps, sb.steps,
              sa.error_samples, sb.error_samples, sa.l1n_u, sb.l1n_u);
    }
    consph_solver_free(a);
    consph_solver_free(b);
}

/* eq26 (the default): the steps are the rule's, nothing sampled. */
static void test_eq26(void)
{
    consph_run_params p = params();
    p.error = CONSPH_ERROR_EQ26;
    p.tf = 0.01;
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
    if (!s) return;
    const double dt = consph_solver_dt(s);
    while (!consph_solver_done(s)) consph_solver_step(s);
    consph_run_summary sum;
    consph_solver_summary(s, &sum);
    CHECK(sum.steps == (long)ceil(p.tf / dt) && sum.error_samples == 0 && isnan(sum.l1n_u),
          "eq26: %ld steps, %d samples", sum.steps, sum.error_samples);
    p.error = 2;
    CHECK(consph_run_params_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "eq26"),
          "a bad error measure accepted");
    p.error = CONSPH_ERROR_AUTHORS;
    p.error_times = 1;
    CHECK(consph_run_params_check(&p) == CONSPH_EINVAL, "one output time accepted");
    consph_solver_free(s);
}

/* Σ_i m a_x,i / max_i |a_x,i| from the particles' "au", m = ρ_o Δs². */
static double ft_by_hand(const consph_solver *s)
{
    const consph_particles *p = consph_solver_particles(s);
    const consph_field *fa = consph_particles_find(p, "au");
    const consph_run_params *prm = consph_solver_params(s);
    const double m = prm->rho0 / ((double)prm->nx * prm->nx); /* unit box */
    double sum = 0, amax = 0;
    for (size_t i = 0; fa && i < p->n; ++i) {
        sum += m * fa->data[i];
        if (fabs(fa->data[i]) > amax) amax = fabs(fa->data[i]);
    }
    return sum / amax;
}

static void test_ft_fmax(void)
{
    static const char *const schemes[] = {"l-ipst-c", "e-c"};
    for (int k = 0; k < 2; ++k) {
        consph_run_params p = params();
        snprintf(p.scheme, sizeof p.scheme, "%s", schemes[k]);
        p.nx = 20;
        p.error = CONSPH_ERROR_EQ26;
        p.steps = 5;
        p.tf = 0.0;
        consph_solver *s = NULL;
        CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
        if (!s) continue;
        while (!consph_solver_done(s)) consph_solver_step(s);
        consph_step_diag d;
        CHECK(consph_solver_diag(s, &d) == CONSPH_OK, "diag");
        const double ft = ft_by_hand(s);
        /* the plain sum by hand of N terms of at most m max|a| is good to about N m ε = 2e-16 of
         * max|a| (consph_sum's is not plain): e-c's F_T, itself round-off, agrees to that only */
        CHECK(fabs(d.ft_fmax - ft) <= 1e-8 * fabs(ft) + 1e-14, "%s: F_T/F_max %.17g, by hand %.17g",
              schemes[k], d.ft_fmax, ft);
        if (k == 1)
            CHECK(fabs(d.ft_fmax) < 1e-14, "e-c on the lattice: F_T/F_max %g, not round-off",
                  d.ft_fmax);
        else
            CHECK(fabs(d.ft_fmax) > 1e-9 && fabs(d.ft_fmax) < 1e-1,
                  "l-ipst-c packed: F_T/F_max %g (1/N of an O(1) unweighted ratio)", d.ft_fmax);
        consph_solver_free(s);
    }
}

int main(void)
{
    test_ft_fmax();
    test_tf();
    test_steps();
    test_restart();
    test_eq26();
    return check_summary("test_error_measure");
}
