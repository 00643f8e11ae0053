/* The established schemes wcsph, tvf and edac: tvf's momentum conservation on disordered particles,
 * 20 finite steps of Taylor-Green for wcsph, tvf and edac, and edac against PySPH 1.0b1. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/solver.h"
#include "solver/solver_internal.h"

static consph_run_params params(const char *scheme, int nx)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = nx;
    p.cfl = 0.25; /* PySPH's taylor_green: Δt = 0.25 h/(c_o + U) */
    p.alpha = 0.0;
    return p;
}

static int run_all(consph_solver *s)
{
    while (!consph_solver_done(s)) {
        int st = consph_solver_step(s);
        if (st != CONSPH_OK) return st;
    }
    return CONSPH_OK;
}

/* Every tvf pair force (pressure with p̃_ij, background pressure, viscosity, A-term) is
 * antisymmetric in i, j and the particles share one mass, so Σ m u stays at its initial value
 * (zero for Taylor-Green) to round-off, however disordered the particles. */
static void test_tvf_momentum(void)
{
    consph_run_params p = params("tvf", 16);
    p.layout = CONSPH_LAYOUT_RANDOM;
    p.steps = 100;
    p.tf = 0.0;
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
    if (!s) return;
    consph_run_summary s0, sum;
    consph_solver_summary(s, &s0);
    CHECK(run_all(s) == CONSPH_OK, "tvf: %s", consph_last_error());
    consph_solver_summary(s, &sum);
    /* Σ|m u| is about 0.6 m N = 2.3e-3 (N = 256); its round-off is near 1e-18 */
    const double dx = sum.momentum[0] - s0.momentum[0], dy = sum.momentum[1] - s0.momentum[1];
    CHECK(fabs(dx) < 1e-15 && fabs(dy) < 1e-15, "tvf momentum moved by (%g, %g) in 100 steps", dx,
          dy);
    consph_solver_free(s);
}

static void test_finite(void)
{
    const char *names[] = {"wcsph", "tvf", "edac"};
    for (int k = 0; k < 3; ++k) {
        consph_run_params p = params(names[k], 32);
        p.alpha = 0.1;
        p.steps = 20;
        p.tf = 0.0;
        consph_solver *s = NULL;
        CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
        if (!s) continue;
        CHECK(run_all(s) == CONSPH_OK, "%s: %s", names[k], consph_last_error());
        const consph_particles *q = consph_solver_particles(s);
        int finite = 1;
        for (int f = 0; f < q->nfields; ++f)
            for (int c = 0; c < q->fields[f].ncomp; ++c)
                for (size_t i = 0; i < q->n; ++i)
                    finite &= isfinite(q->fields[f].data[(size_t)c * q->cap + i]) != 0;
        for (size_t i = 0; i < q->n; ++i) finite &= isfinite(q->x[0][i]) && isfinite(q->x[1][i]);
        CHECK(finite, "%s: a non-finite value after 20 steps", names[k]);
        consph_solver_free(s);
    }
}

/* 1 and 2 threads give the same particles bit for bit (the passes are gathers; every other
 * loop is per particle). */
static void test_threads(void)
{
    const char *names[] = {"wcsph", "tvf", "edac"};
    for (int k = 0; k < 3; ++k) {
        consph_solver *s[2] = {NULL, NULL};
        for (int t = 0; t < 2; ++t) {
            consph_run_params p = params(names[k], 20);
            p.layout = CONSPH_LAYOUT_RANDOM;
            p.alpha = 0.1;
            p.steps = 10;
            p.tf = 0.0;
            consph_set_num_threads(t + 1);
            CHECK(consph_solver_create(&s[t], &p) == CONSPH_OK, "create: %s", consph_last_error());
            if (!s[t]) break;
            s[t]->sys.parallel_min = 1; /* the pass layer is serial below parallel_min */
            CHECK(run_all(s[t]) == CONSPH_OK, "%s: %s", names[k], consph_last_error());
        }
        consph_set_num_threads(1);
        if (s[0] && s[1]) {
            const consph_particles *a = consph_solver_particles(s[0]);
            const consph_particles *b = consph_solver_particles(s[1]);
            /* the state: positions, u, p, ϱ (every other field derives from it) */
            int same = a->n == b->n && !memcmp(a->x[0], b->x[0], a->n * sizeof(double)) &&
                       !memcmp(a->x[1], b->x[1], a->n * sizeof(double));
            const char *state[] = {"u", "p", "rhof"};
            for (int f = 0; same && f < 3; ++f) {
                const consph_field *fa = consph_particles_find(a, state[f]);
                const consph_field *fb = consph_particles_find(b, state[f]);
                for (int c = 0; same && c < fa->ncomp; ++c)
                    same = !memcmp(fa->data + (size_t)c * a->cap, fb->data + (size_t)c * b->cap,
                                   a->n * sizeof(double));
            }
            CHECK(same, "%s: 1 and 2 threads differ", names[k]);
        }
        consph_solver_free(s[0]);
        consph_solver_free(s[1]);
    }
}

/* PySPH's velocity measure (taylor_green.py post_process): Σ| |u| - |u_e| | / Σ |u_e|. */
static double l1_vmag(const consph_solver *s, double t)
{
    const consph_particles *q = consph_solver_particles(s);
    const consph_field *fu = consph_particles_find(q, "u");
    const double e = exp(-8.0 * M_PI * M_PI / 100.0 * t);
    double num = 0.0, den = 0.0;
    for (size_t i = 0; i < q->n; ++i) {
        const double x = q->x[0][i], y = q->x[1][i];
        const double ue = -e * cos(2 * M_PI * x) * sin(2 * M_PI * y);
        const double ve = e * sin(2 * M_PI * x) * cos(2 * M_PI * y);
        num += fabs(hypot(fu->data[i], fu->data[q->cap + i]) - hypot(ue, ve));
        den += hypot(ue, ve);
    }
    return num / den;
}

/* PYSPH_EDAC32 was computed once by PySPH 1.0b1 (Debian python3-pysph 1.0~b1-5) with
 *   python3 /usr/lib/python3/dist-packages/pysph/examples/taylor_green.py --scheme edac \
 *       --nx 32 --hdx 1.2 --tf 0.5 --pfreq 100000 -d OUT
 * and bench/pysph_errors.py OUT/taylor_green_00587.hdf5 0.5 100 0.0375 (its first number).
 * With PySPH's own integrator (pec, and the drift of EDACTVFStep) consph gives 2.1413e-02,
 * 0.35 % above; at nx 50 the two codes agree to 1e-5 (bench/pysph.md). The tolerance, 2 %, is
 * a few times the gap measured here; the explicit midpoint rule used before gave 5 %. */
#define PYSPH_EDAC32 2.133827e-02
#define PYSPH_TOL 0.02
static void test_edac_pysph(void)
{
    consph_run_params p = params("edac", 32);
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
    if (!s) return;
    CHECK(run_all(s) == CONSPH_OK, "edac: %s", consph_last_error());
    const double l1 = l1_vmag(s, consph_solver_time(s));
    CHECK(fabs(l1 / PYSPH_EDAC32 - 1.0) < PYSPH_TOL, "edac nx 32: L1 |u| %.6e, PySPH %.6e", l1,
          PYSPH_EDAC32);
    consph_solver_free(s);
}

/* The one-evaluation integrators (wcsph and edac: pec; tvf: kdk reusing the last rates) evaluate
 * the rates once per step (pairs = steps × one evaluation's pairs; a tvf or edac evaluation is
 * two passes), and converge in time: on the same particles, the velocity at t = 0.04 with Δt,
 * Δt/2 and Δt/4 departs from a Δt/16 run by errors whose ratios give the order. wcsph is
 * second order (asserted in [1.7, 2.4]) with pec as with rk2. tvf and edac are first order
 * whatever the integrator (asserted in [0.8, 1.7]; edac under rk2 measured 0.89 and 1.07): their
 * particles drift with ũ = u + cΔt ã, a shift proportional to Δt, so the particle paths and with
 * them the solution at a fixed time depend on Δt at first order. */
static double run_dt(const char *scheme, const char *integ, double dt, double *u_out, size_t n,
                     size_t *pairs)
{
    *pairs = 0;
    consph_run_params p = params(scheme, 16);
    p.dt = dt;
    p.tf = 0.04;
    snprintf(p.integrator, sizeof p.integrator, "%s", integ);
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
    if (!s) return NAN;
    CHECK(run_all(s) == CONSPH_OK, "%s: %s", scheme, consph_last_error());
    const consph_particles *q = consph_solver_particles(s);
    const consph_field *fu = consph_particles_find(q, "u"), *fid = consph_particles_find(q, "id");
    CHECK(q->n == n, "%s: %zu particles", scheme, q->n);
    for (size_t i = 0; i < q->n && i < n; ++i) {
        const size_t k = (size_t)fid->data[i]; /* by initial index: runs sort differently */
        u_out[k] = fu->data[i];
        u_out[n + k] = fu->data[q->cap + i];
    }
    consph_run_summary sum;
    consph_solver_summary(s, &sum);
    *pairs = sum.pairs;
    const double steps = (double)sum.steps;
    consph_solver_free(s);
    return steps;
}

static void test_time_order(void)
{
    const char *names[] = {"wcsph", "wcsph", "tvf", "edac"};
    const char *integ[] = {"", "rk2", "", ""};
    const int passes[] = {1, 2, 2, 2};
    const double lo[] = {1.7, 1.7, 0.8, 0.8}, hi[] = {2.4, 2.4, 1.7, 1.7};
    const size_t n = 256;
    double ref[2 * 256], u[2 * 256];
    for (int k = 0; k < 4; ++k) {
        size_t pairs = 0;
        const double dt = 2e-3;
        run_dt(names[k], integ[k], dt / 16, ref, n, &pairs);
        double err[3];
        for (int r = 0; r < 3; ++r) {
            const double steps = run_dt(names[k], integ[k], dt / (1 << r), u, n, &pairs);
            double e = 0.0;
            for (size_t i = 0; i < 2 * n; ++i) e = fmax(e, fabs(u[i] - ref[i]));
            err[r] = e;
            /* on the lattice every particle has the same neighbour count at t = 0 */
            const double per_eval = (double)pairs / steps / passes[k];
            CHECK(per_eval > 40.0 * n && per_eval < 50.0 * n,
                  "%s: %.0f pairs per evaluation per step, expected one evaluation (~45 n)",
                  names[k], per_eval);
        }
        const double o1 = log2(err[0] / err[1]), o2 = log2(err[1] / err[2]);
        printf("%s %s time order: errors %.3e %.3e %.3e, orders %.2f %.2f\n", names[k],
               integ[k][0] ? integ[k] : "default", err[0], err[1], err[2], o1, o2);
        CHECK(o1 > lo[k] && o1 < hi[k] && o2 > lo[k] && o2 < hi[k],
              "%s: time orders %.2f %.2f outside [%g, %g]", names[k], o1, o2, lo[k], hi[k]);
    }
}

/* --rho-init rho0 (001's and PySPH's Taylor-Green scripts for their one-density schemes, 001's
 * δ+-SPH in Table 7): ϱ starts at ρ_o and p at EOS(ρ_o) = 0, not at the exact pressure; the
 * masses are ρ_o Δs², and a checkpoint carries the choice. One step of 001 Table 7 (Δt =
 * 6.54e-5) moves ρ by O(Δt) only, so the pressure error stays the mean |p_exact| (0.2026 on the
 * continuum), which is the 2.03e-1 of 001 Table 7. Schemes that evolve p or take ρ from a
 * closure refuse the option. */
static void test_rho_init(void)
{
    consph_run_params p = params("delta-plus-sph", 20);
    p.rho_init = CONSPH_RHO_INIT_RHO0;
    p.steps = 1;
    p.tf = 0.0;
    p.dt = 6.54e-5;
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
    if (!s) return;
    const consph_particles *q = consph_solver_particles(s);
    const consph_field *fr = consph_particles_find(q, "rhof"), *fp = consph_particles_find(q, "p");
    const consph_field *fm = consph_particles_find(q, "mass");
    const double m0 = p.rho0 * pow(1.0 / p.nx, 2);
    size_t bad = 0;
    for (size_t i = 0; i < q->n; ++i)
        bad += fr->data[i] != p.rho0 || fp->data[i] != 0.0 || fabs(fm->data[i] / m0 - 1) > 1e-14;
    CHECK(bad == 0, "rho0: %zu particles start with ϱ != ρ_o, p != 0 or m != ρ_o Δs²", bad);
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    CHECK(consph_solver_checkpoint_meta(s, &meta, &hist, &nh) == CONSPH_OK, "meta: %s",
          consph_last_error());
    consph_solver *r = NULL;
    if (meta)
        CHECK(consph_solver_restore(&r, meta, q, hist, nh) == CONSPH_OK, "restore: %s",
              consph_last_error());
    if (r)
        CHECK(consph_solver_params(r)->rho_init == CONSPH_RHO_INIT_RHO0,
              "a checkpoint lost --rho-init");
    consph_solver_free(r);
    free(meta);
    free(hist);
    CHECK(run_all(s) == CONSPH_OK, "delta-plus-sph: %s", consph_last_error());
    consph_run_summary sum;
    consph_solver_summary(s, &sum);
    q = consph_solver_particles(s);
    fp = consph_particles_find(q, "p");
    const double e2 = exp(-2.0 * 8.0 * M_PI * M_PI / 100.0 * sum.t);
    double pmax = 0.0, pe = 0.0;
    for (size_t i = 0; i < q->n; ++i) {
        const double x = q->x[0][i], y = q->x[1][i];
        pmax = fmax(pmax, fabs(fp->data[i]));
        pe += fabs(0.25 * e2 * (cos(4 * M_PI * x) + cos(4 * M_PI * y)));
    }
    pe /= (double)q->n;
    CHECK(pmax < 5e-3, "rho0: max |p| %g after one step, expected near 0", pmax);
    CHECK(fabs(sum.l1_p / sum.t / pe - 1.0) < 0.02, "rho0: mean |p - p_e| %g, mean |p_e| %g",
          sum.l1_p / sum.t, pe);
    consph_solver_free(s);

    /* the default starts from the exact pressure */
    p.rho_init = CONSPH_RHO_INIT_EOS;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
    if (s) {
        q = consph_solver_particles(s);
        fr = consph_particles_find(q, "rhof");
        fp = consph_particles_find(q, "p");
        bad = 0;
        for (size_t i = 0; i < q->n; ++i) {
            const double x = q->x[0][i], y = q->x[1][i];
            const double pex = -0.25 * (cos(4 * M_PI * x) + cos(4 * M_PI * y));
            /* linear EOS of the δ family: ϱ = ρ_o + p/c_o² */
            bad += fp->data[i] != pex || fabs(fr->data[i] - (1.0 + pex / 100.0)) > 1e-15;
        }
        CHECK(bad == 0, "eos: %zu particles do not start from the exact pressure", bad);
        consph_solver_free(s);
    }

    const char *refuse[] = {"edac", "tvf"};
    for (int k = 0; k < 2; ++k) {
        consph_run_params e = params(refuse[k], 20);
        e.rho_init = CONSPH_RHO_INIT_RHO0;
        CHECK(consph_run_params_check(&e) == CONSPH_EINVAL &&
                  strstr(consph_last_error(), "rho_init rho0 needs"),
              "%s accepted --rho-init rho0", refuse[k]);
    }
    p.rho_init = 2;
    CHECK(consph_run_params_check(&p) == CONSPH_EINVAL, "--rho-init 2 accepted");
}

int main(void)
{
    test_rho_init();
    test_tvf_momentum();
    test_finite();
    test_threads();
    test_edac_pysph();
    test_time_order();
    return check_summary("test_solver_rival");
}
