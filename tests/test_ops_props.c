/* Structural properties of the operators: conservation of the symmetric forms, independence of
 * the thread count, the ill-conditioned fallback, name lookups, and the moment diagnostics on a
 * lattice against the lattice sums of docs/reference-values.md. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "check.h"
#include "layout_fixture.h"
#include "consph/consph.h"
#include "consph/ops.h"

static const double TWO_PI = 6.283185307179586;

/* A smooth non-polynomial field (values need not be periodic for these checks). */
static double field(const double *x, int d)
{
    double v = sin(TWO_PI * x[0]) + 0.3 * x[0];
    if (d > 1) v *= cos(TWO_PI * x[1]) + 1.5;
    if (d > 2) v += x[2] * x[2];
    return v;
}

static void fill_field(const consph_particles *p, double *f, int ncomp)
{
    for (size_t i = 0; i < p->n; ++i) {
        double x[3] = {0, 0, 0};
        for (int a = 0; a < p->dim; ++a) x[a] = p->x[a][i];
        for (int c = 0; c < ncomp; ++c) {
            double xs[3] = {x[0] + 0.1 * c, x[1] - 0.2 * c, x[2]};
            f[(size_t)c * p->n + i] = field(xs, p->dim);
        }
    }
}

static int world_layout(world *w, consph_layout_kind kind, int dim, size_t nx, double hdx,
                        consph_volume_kind vk)
{
    return world_setup(w, kind, dim, nx, hdx, vk, 3);
}

/* |Σ_i m_i F_i| relative to Σ_i |m_i F_i|, per component, with consph_sum. */
static double total_force_ratio(const world *w, const double *F)
{
    const size_t n = w->p.n;
    double *t = malloc(n * sizeof(double)), *ta = malloc(n * sizeof(double)), worst = 0.0;
    for (int a = 0; a < w->p.dim; ++a) {
        for (size_t i = 0; i < n; ++i) {
            t[i] = w->ctx.mass[i] * F[(size_t)a * n + i];
            ta[i] = fabs(t[i]);
        }
        double r = fabs(consph_sum(t, n)) / consph_sum(ta, n);
        if (!(r <= worst)) worst = r;
    }
    free(t);
    free(ta);
    return worst;
}

static void test_conservation(void)
{
    /* sym1, sym2, sym_s1 conserve for any volumes; Cleary and tvf need m_i ω_j = m_j ω_i,
     * i.e. the constant volumes of the layout (given) with ρ = 1. */
    for (int pass = 0; pass < 2; ++pass) {
        world w;
        consph_volume_kind vk = pass ? CONSPH_VOLUME_GIVEN : CONSPH_VOLUME_SUMMATION;
        int ok = world_layout(&w, CONSPH_LAYOUT_RANDOM, 2, 24, 1.2, vk);
        CHECK(ok, "setup: %s", consph_last_error());
        if (!ok) {
            world_free(&w);
            continue;
        }
        const size_t n = w.p.n;
        double *f = malloc(n * sizeof(double)), *out = malloc(2 * n * sizeof(double));
        fill_field(&w.p, f, 1);
        struct {
            consph_op op;
            consph_op_form form;
            int conserves;
        } cases[] = {
            {CONSPH_OP_GRAD, CONSPH_FORM_SYM1, 1},
            {CONSPH_OP_GRAD, CONSPH_FORM_SYM2, 1},
            {CONSPH_OP_GRAD, CONSPH_FORM_SYM_S1, 1},
            {CONSPH_OP_LAPLACIAN, CONSPH_FORM_CLEARY, 1},
            {CONSPH_OP_LAPLACIAN, CONSPH_FORM_TVF, 1},
            {CONSPH_OP_GRAD, CONSPH_FORM_ASYM, 0},
            {CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI, 0},
        };
        for (size_t c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
            if (!pass && cases[c].op == CONSPH_OP_LAPLACIAN && cases[c].conserves) continue;
            int st =
                consph_apply(&w.ctx, cases[c].op, cases[c].form, CONSPH_CORR_NONE, f, out, NULL);
            CHECK(st == CONSPH_OK, "%s: %s", consph_form_name(cases[c].form), consph_last_error());
            double r = total_force_ratio(&w, out);
            printf("total force ratio %-8s (%s volumes): %.3e\n", consph_form_name(cases[c].form),
                   consph_volume_name(vk), r);
            if (cases[c].conserves)
                CHECK(r < 1e-13, "%s does not conserve: |Σ m F| / Σ |m F| = %.3e",
                      consph_form_name(cases[c].form), r);
            else
                CHECK(r > 1e-8, "%s conserves unexpectedly (%.3e): the test cannot tell",
                      consph_form_name(cases[c].form), r);
        }
        free(f);
        free(out);
        world_free(&w);
    }
}

/* Every operator once, with 1 and with 2 threads: the outputs must match bit for bit. */
static void test_threads(void)
{
#ifdef _OPENMP
    world w;
    int ok = world_layout(&w, CONSPH_LAYOUT_RANDOM, 2, 24, 1.2, CONSPH_VOLUME_SUMMATION);
    CHECK(ok, "setup: %s", consph_last_error());
    if (ok) {
        const size_t n = w.p.n;
        double *in = malloc(2 * n * sizeof(double));
        double *o1 = malloc(3 * n * sizeof(double)), *o2 = malloc(3 * n * sizeof(double));
        fill_field(&w.p, in, 2);
        int saved = omp_get_max_threads(), tested = 0;
        w.ctx.parallel_min = 0; /* this set is small: force the parallel path */
        for (int op = 0; op < CONSPH_OP_COUNT; ++op)
            for (int form = 0; form < CONSPH_FORM_COUNT; ++form)
                for (int corr = 0; corr < CONSPH_CORR_COUNT; ++corr) {
                    if (consph_op_check(op, form, corr, 2) != CONSPH_OK) continue;
                    size_t bytes = n * (size_t)consph_op_ncomp_out(op, 2) * sizeof(double);
                    int st1, st2;
                    omp_set_num_threads(1);
                    consph_op_ctx_refresh(&w.ctx);
                    st1 = consph_apply(&w.ctx, op, form, corr, in, o1, NULL);
                    omp_set_num_threads(2);
                    consph_op_ctx_refresh(&w.ctx);
                    st2 = consph_apply(&w.ctx, op, form, corr, in, o2, NULL);
                    CHECK(st1 == CONSPH_OK && st2 == CONSPH_OK, "%s %s: %s", consph_op_name(op),
                          consph_form_name(form), consph_last_error());
                    CHECK(memcmp(o1, o2, bytes) == 0, "%s %s[%s] differs between 1 and 2 threads",
                          consph_op_name(op), consph_form_name(form), consph_corr_name(corr));
                    ++tested;
                }
        omp_set_num_threads(saved);
        printf("thread independence: %d operator triples identical on 1 and 2 threads\n", tested);
        free(in);
        free(o1);
        free(o2);
    }
    world_free(&w);
#else
    printf("thread independence: built without OpenMP, skipped\n");
#endif
}

/* A lattice block in [0,1]² of a box [0,2]×[0,1] (not periodic) plus `extra` particles far from
 * it: one isolated particle, or a close pair whose two-point neighbourhoods make every
 * correction matrix singular. */
static int world_starved(world *w, int pair)
{
    memset(w, 0, sizeof *w);
    const size_t nx = 16, nblock = nx * nx, n = nblock + (pair ? 2 : 1);
    consph_box box = consph_box_unit(2, 0);
    box.hi[0] = 2.0;
    if (consph_particles_init(&w->p, 2, n, &box) != CONSPH_OK) return 0;
    const double ds = 1.0 / (double)nx;
    for (size_t a = 0; a < nx; ++a)
        for (size_t b = 0; b < nx; ++b) {
            w->p.x[0][a * nx + b] = (a + 0.5) * ds;
            w->p.x[1][a * nx + b] = (b + 0.5) * ds;
        }
    w->p.x[0][nblock] = 1.6;
    w->p.x[1][nblock] = 0.5;
    if (pair) {
        w->p.x[0][nblock + 1] = 1.6 + 0.9 * ds;
        w->p.x[1][nblock + 1] = 0.5 + 0.4 * ds;
    }
    w->p.spacing = ds;
    if (consph_kernel_init(&w->k, CONSPH_KERNEL_QUINTIC, 2, 1.2 * ds) != CONSPH_OK) return 0;
    w->g = consph_nnps_create(&w->p.box, w->k.radius, 0);
    if (!w->g || consph_nnps_build(w->g, &w->p) != CONSPH_OK) return 0;
    return consph_op_ctx_init(&w->ctx, &w->p, w->g, &w->k, CONSPH_VOLUME_SUMMATION) == CONSPH_OK;
}

static void test_fallback(void)
{
    for (int pair = 0; pair < 2; ++pair) {
        world w;
        int ok = world_starved(&w, pair);
        CHECK(ok, "starved setup: %s", consph_last_error());
        if (!ok) {
            world_free(&w);
            continue;
        }
        const size_t n = w.p.n, first = n - (pair ? 2 : 1);
        const size_t expect = pair ? 2 : 1;
        double *in = malloc(2 * n * sizeof(double));
        double *o = malloc(3 * n * sizeof(double)), *u = malloc(3 * n * sizeof(double));
        fill_field(&w.p, in, 2);
        /* corrected triple, and the uncorrected triple it must reduce to (op, form, corr) */
        struct {
            consph_op op;
            consph_op_form form, uform;
            consph_op_corr corr, ucorr;
        } cases[] = {
            {CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_FORM_ASYM, CONSPH_CORR_BC, CONSPH_CORR_NONE},
            {CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_FORM_ASYM, CONSPH_CORR_LC, CONSPH_CORR_NONE},
            {CONSPH_OP_GRAD, CONSPH_FORM_SYM1, CONSPH_FORM_SYM1, CONSPH_CORR_LC, CONSPH_CORR_NONE},
            {CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_FORM_F2, CONSPH_CORR_NONE, CONSPH_CORR_NONE},
            {CONSPH_OP_GRAD, CONSPH_FORM_IAD, CONSPH_FORM_F2, CONSPH_CORR_NONE, CONSPH_CORR_NONE},
            {CONSPH_OP_GRAD, CONSPH_FORM_FPM, CONSPH_FORM_F1, CONSPH_CORR_NONE, CONSPH_CORR_NONE},
            {CONSPH_OP_FUNCTION, CONSPH_FORM_FPM, CONSPH_FORM_STANDARD, CONSPH_CORR_NONE,
             CONSPH_CORR_NONE},
            {CONSPH_OP_DIV, CONSPH_FORM_DIV, CONSPH_FORM_DIV, CONSPH_CORR_BC, CONSPH_CORR_NONE},
            {CONSPH_OP_LAPLACIAN, CONSPH_FORM_CLEARY, CONSPH_FORM_CLEARY, CONSPH_CORR_BC,
             CONSPH_CORR_NONE},
            {CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI, CONSPH_FORM_FATEHI, CONSPH_CORR_FATEHI,
             CONSPH_CORR_NONE},
            {CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI_C, CONSPH_FORM_FATEHI, CONSPH_CORR_NONE,
             CONSPH_CORR_NONE},
            {CONSPH_OP_LAPLACIAN, CONSPH_FORM_COUPLED, CONSPH_FORM_COUPLED, CONSPH_CORR_BC,
             CONSPH_CORR_NONE},
            /* no uncorrected counterpart: finiteness and the count only */
            {CONSPH_OP_HESSIAN, CONSPH_FORM_KORZILIUS, CONSPH_FORM_COUNT, CONSPH_CORR_NONE,
             CONSPH_CORR_NONE},
            {CONSPH_OP_HESSIAN, CONSPH_FORM_CSPM, CONSPH_FORM_COUNT, CONSPH_CORR_NONE,
             CONSPH_CORR_NONE},
            {CONSPH_OP_HESSIAN, CONSPH_FORM_MSPH, CONSPH_FORM_COUNT, CONSPH_CORR_NONE,
             CONSPH_CORR_NONE},
        };
        for (size_t c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
            const char *name = consph_form_name(cases[c].form);
            consph_op_report rep;
            int nout = consph_op_ncomp_out(cases[c].op, 2);
            int st = consph_apply(&w.ctx, cases[c].op, cases[c].form, cases[c].corr, in, o, &rep);
            CHECK(st == CONSPH_OK, "%s: %s", name, consph_last_error());
            CHECK(rep.fallbacks == expect, "%s[%s]: %zu fallbacks, expected %zu", name,
                  consph_corr_name(cases[c].corr), rep.fallbacks, expect);
            int finite = 1;
            for (size_t k = 0; k < n * (size_t)nout; ++k) finite &= isfinite(o[k]) != 0;
            CHECK(finite, "%s[%s]: non-finite output", name, consph_corr_name(cases[c].corr));
            if (cases[c].uform == CONSPH_FORM_COUNT) continue;
            st = consph_apply(&w.ctx, cases[c].op, cases[c].uform, cases[c].ucorr, in, u, NULL);
            CHECK(st == CONSPH_OK, "%s: %s", consph_form_name(cases[c].uform), consph_last_error());
            for (size_t i = first; i < n; ++i)
                for (int a = 0; a < nout; ++a) {
                    double vo = o[(size_t)a * n + i], vu = u[(size_t)a * n + i];
                    CHECK_NEAR(vo, vu, 1e-13 * (1.0 + fabs(vu)), "%s[%s] particle %zu comp %d",
                               name, consph_corr_name(cases[c].corr), i, a);
                }
        }
        /* The pair's uncorrected gradient is not trivially zero: the comparison has teeth. */
        if (pair) {
            consph_apply(&w.ctx, CONSPH_OP_GRAD, CONSPH_FORM_F2, CONSPH_CORR_NONE, in, u, NULL);
            CHECK(fabs(u[first]) > 1e-3, "pair F2 gradient is %.3e", u[first]);
        }
        free(in);
        free(o);
        free(u);
        world_free(&w);
    }
}

static void test_names(void)
{
    consph_op_spec s;
    CHECK(consph_op_parse("laplacian", "fatehi", "fatehi", 2, &s) == CONSPH_OK, "%s",
          consph_last_error());
    CHECK(s.op == CONSPH_OP_LAPLACIAN && s.form == CONSPH_FORM_FATEHI &&
              s.corr == CONSPH_CORR_FATEHI,
          "parse result");
    CHECK(consph_op_parse("grad", "asym", "bc", 3, &s) == CONSPH_OK, "%s", consph_last_error());
    CHECK(consph_op_parse("grad", "sym1", NULL, 2, &s) == CONSPH_OK && s.corr == CONSPH_CORR_NONE,
          "default corr");
    CHECK(consph_op_parse("grad", "cleary", "none", 2, &s) == CONSPH_EINVAL, "grad cleary");
    CHECK(strstr(consph_last_error(), "asym[none|bc|lc]") != NULL, "message lists forms: %s",
          consph_last_error());
    CHECK(consph_op_parse("laplacian", "cleary", "fatehi", 2, &s) == CONSPH_EINVAL, "corr");
    CHECK(strstr(consph_last_error(), "none|bc|lc") != NULL, "message lists corrections: %s",
          consph_last_error());
    CHECK(consph_op_parse("gradient", "f1", NULL, 2, &s) == CONSPH_EINVAL, "bad op");
    CHECK(strstr(consph_last_error(), "function, grad, div, laplacian, hessian") != NULL, "%s",
          consph_last_error());
    CHECK(consph_op_parse("grad", "f5", NULL, 2, &s) == CONSPH_EINVAL, "bad form");
    CHECK(consph_op_parse("grad", "f4", "xx", 2, &s) == CONSPH_EINVAL, "bad corr");
    /* every name round-trips */
    for (int f = 0; f < CONSPH_FORM_COUNT; ++f) {
        consph_op_form g;
        CHECK(consph_form_lookup(consph_form_name((consph_op_form)f), &g) == CONSPH_OK &&
                  (int)g == f,
              "form %d", f);
    }
    CHECK(consph_op_ncomp_out(CONSPH_OP_HESSIAN, 3) == 6 &&
              consph_op_ncomp_in(CONSPH_OP_DIV, 3) == 3,
          "component counts");
}

/* On the unperturbed periodic lattice with ω = Δs², M0 - 1 is the lattice summation error of
 * docs/reference-values.md (QS, h/Δs = 1.2: 5.62e-5), the odd moments vanish and
 * Σ ω x_ji ⊗ ∇W = (1 + ε) I. */
static void test_moments(void)
{
    world w;
    int ok = world_layout(&w, CONSPH_LAYOUT_LATTICE, 2, 20, 1.2, CONSPH_VOLUME_GIVEN);
    CHECK(ok, "setup: %s", consph_last_error());
    if (ok) {
        const size_t n = w.p.n;
        double *m0 = malloc(n * sizeof(double)), *m1 = malloc(2 * n * sizeof(double));
        double *g0 = malloc(2 * n * sizeof(double)), *g1 = malloc(4 * n * sizeof(double));
        consph_op_report rep;
        CHECK(consph_op_moments(&w.ctx, m0, m1, g0, g1, &rep) == CONSPH_OK, "%s",
              consph_last_error());
        CHECK(rep.pairs == n * 37, "pairs %zu, expected 37 per particle", rep.pairs);
        double e0 = 0.0, e1 = 0.0, eg0 = 0.0, eoff = 0.0, ediag = 0.0;
        for (size_t i = 0; i < n; ++i) {
            e0 = fmax(e0, fabs(fabs(m0[i] - 1.0) - 5.62e-5));
            e1 = fmax(e1, fmax(fabs(m1[i]), fabs(m1[n + i])));
            eg0 = fmax(eg0, fmax(fabs(g0[i]), fabs(g0[n + i])));
            eoff = fmax(eoff, fmax(fabs(g1[n + i]), fabs(g1[2 * n + i])));
            ediag = fmax(ediag, fabs(g1[i] - g1[3 * n + i]));
        }
        CHECK(e0 < 5e-8, "|M0 - 1| differs from the lattice sum 5.62e-5 by %.3e", e0);
        CHECK(e1 < 1e-15 && eg0 < 1e-12 && eoff < 1e-14 && ediag < 1e-14,
              "lattice moments: m1 %.3e g0 %.3e offdiag %.3e diag spread %.3e", e1, eg0, eoff,
              ediag);
        CHECK(fabs(g1[0] - 1.0) < 1e-3, "Σ ω x_ji ∂_x W = %.6f", g1[0]);
        printf("lattice: M0 - 1 = %.4e, g1_xx - 1 = %.4e\n", m0[0] - 1.0, g1[0] - 1.0);
        /* every lattice particle has the same M0 */
        size_t counts[4], below, above;
        double mean, sd;
        CHECK(consph_histogram(m0, n, 0.99, 1.01, 4, counts, &below, &above, &mean, &sd) ==
                  CONSPH_OK,
              "histogram");
        CHECK((counts[1] == n || counts[2] == n) && below == 0 && above == 0,
              "lattice M0 all in one bin");
        CHECK(fabs(mean - m0[0]) < 1e-13 && sd < 1e-13, "mean %.17g sd %.3e", mean, sd);
        free(m0);
        free(m1);
        free(g0);
        free(g1);
    }
    world_free(&w);
    double v[6] = {0.0, 0.1, 0.25, 0.5, 0.99, 2.0};
    size_t c[2], b, a;
    double mean, sd;
    CHECK(consph_histogram(v, 6, 0.0, 1.0, 2, c, &b, &a, &mean, &sd) == CONSPH_OK, "hist");
    CHECK(c[0] == 3 && c[1] == 2 && b == 0 && a == 1, "bins %zu %zu above %zu", c[0], c[1], a);
    CHECK_NEAR(mean, 3.84 / 6.0, 1e-15, "mean");
}

/* The consistent-Shepard factors satisfy the eigen relation Σ_b ω_b c̃_b W_ab = λ c̃_a (000 eq.
 * 62) once the power iteration stops; with summation volumes every column of A sums to 1
 * (ρ_b = m Σ_a W_ab), so λ = 1 up to round-off, while c̃ itself is far from 1. And summation and
 * number-density volumes agree when the mass is uniform (001 eq. 5). */
static void test_volumes_cshepard(void)
{
    world w, wn;
    memset(&wn, 0, sizeof wn);
    int ok = world_layout(&w, CONSPH_LAYOUT_RANDOM, 2, 24, 1.2, CONSPH_VOLUME_SUMMATION);
    ok = ok && world_layout(&wn, CONSPH_LAYOUT_RANDOM, 2, 24, 1.2, CONSPH_VOLUME_NUMBER);
    CHECK(ok, "setup: %s", consph_last_error());
    if (ok) {
        const size_t n = w.p.n;
        double vdiff = 0.0;
        for (size_t i = 0; i < n; ++i)
            vdiff = fmax(vdiff, fabs(w.ctx.volume[i] - wn.ctx.volume[i]) / w.ctx.volume[i]);
        CHECK(vdiff < 1e-14, "summation vs number volumes differ by %.3e", vdiff);
        double *c = malloc(n * sizeof(double)), *ac = malloc(n * sizeof(double)), lambda;
        int iters;
        CHECK(consph_op_cshepard_factors(&w.ctx, 1e-12, 5000, c, &iters, &lambda) == CONSPH_OK,
              "%s", consph_last_error());
        CHECK(consph_apply(&w.ctx, CONSPH_OP_FUNCTION, CONSPH_FORM_STANDARD, CONSPH_CORR_NONE, c,
                           ac, NULL) == CONSPH_OK,
              "A c");
        double res = 0.0, spread = 0.0;
        for (size_t i = 0; i < n; ++i) {
            res = fmax(res, fabs(ac[i] - lambda * c[i]));
            spread = fmax(spread, fabs(c[i] - 1.0));
        }
        printf("consistent Shepard: %d sweeps, lambda - 1 = %.3e, max |c - 1| = %.3e, "
               "residual %.3e\n",
               iters, lambda - 1.0, spread, res);
        CHECK(iters < 5000 && res < 1e-9, "not converged: %d sweeps, residual %.3e", iters, res);
        CHECK(fabs(lambda - 1.0) < 1e-12 && spread > 1e-3, "lambda %.17g, spread %.3e", lambda,
              spread);
        free(c);
        free(ac);
    }
    world_free(&w);
    world_free(&wn);
}

int main(void)
{
    test_volumes_cshepard();
    test_names();
    test_moments();
    test_conservation();
    test_fallback();
    test_threads();
    return check_summary("test_ops_props");
}
