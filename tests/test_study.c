/* Study foundations: order fit, error norms, manufactured-field derivatives, 003's bounds. */
#include <math.h>
#include <stdlib.h>

#include "check.h"
#include "consph/study.h"

static void test_fit(void)
{
    double res[5] = {50, 100, 200, 250, 400}, err[5];
    for (int k = 0; k < 5; ++k) err[k] = 3.0 * pow(res[k], -2.0);
    consph_order_fit fit;
    CHECK(consph_fit_order(res, err, 5, &fit) == CONSPH_OK, "fit failed");
    CHECK_NEAR(fit.order, 2.0, 1e-12, "exact power law");
    CHECK_NEAR(fit.order_stderr, 0.0, 1e-12, "no scatter, no standard error");
    CHECK_NEAR(exp(fit.intercept), 3.0, 1e-10, "intercept");
    /* Scatter of known size: alternate ±10% gives a nonzero standard error. */
    for (int k = 0; k < 5; ++k) err[k] *= (k % 2 ? 1.1 : 0.9);
    CHECK(consph_fit_order(res, err, 5, &fit) == CONSPH_OK, "fit failed");
    CHECK(fit.order_stderr > 0.01 && fit.order_stderr < 0.5, "stderr %g", fit.order_stderr);
    /* Non-positive errors are skipped; fewer than two points is an error. */
    double bad[3] = {0.0, -1.0, 1e-3};
    CHECK(consph_fit_order(res, bad, 3, &fit) != CONSPH_OK, "one point must fail");
}

static void test_norms(void)
{
    /* Two particles, 2 components: e = (5, 0), |g_o| = (1, 1). */
    double approx[4] = {4, 1, 3, 1}, exact[4] = {1, 1, -1, 0};
    /* component-major: comp0 = {4,1} vs {1,1}; comp1 = {3,1} vs {-1,0} */
    consph_error_norms e;
    CHECK(consph_error_norms_compute(approx, exact, 2, 2, NULL, &e) == CONSPH_OK, "norms");
    double e0 = 5.0, e1 = 1.0, g0 = sqrt(2.0), g1 = 1.0;
    CHECK_NEAR(e.l1, (e0 + e1) / (g0 + g1), 1e-15, "l1");
    CHECK_NEAR(e.mae, 3.0, 1e-15, "mae");
    CHECK_NEAR(e.l2, sqrt(13.0), 1e-15, "l2");
    CHECK_NEAR(e.linf, 5.0, 1e-15, "linf");
    unsigned char mask[2] = {0, 1};
    CHECK(consph_error_norms_compute(approx, exact, 2, 2, mask, &e) == CONSPH_OK, "masked");
    CHECK(e.count == 1 && e.linf == 1.0, "masked count %zu linf %g", e.count, e.linf);
    double fx[3] = {1.0, -2.0, 0.5};
    CHECK_NEAR(consph_total_force_ratio(fx, 3, NULL), -0.25, 1e-15, "F_T/F_max");
}

/* Every field's gradient, Hessian, Laplacian and divergence against central differences. */
static void test_fields(void)
{
    const double step = 1e-4;
    for (int dim = 1; dim <= 3; ++dim) {
        consph_mfield_params prm = consph_mfield_defaults(dim);
        prm.sigma = 0.3;
        for (int id = 0; id < CONSPH_MFIELD_COUNT; ++id) {
            if (id == CONSPH_MFIELD_TGV && dim < 2) continue;
            double x[3] = {0.31, 0.17, 0.58};
            consph_mfield_value v, vp, vm;
            consph_mfield_eval(id, dim, &prm, x, &v);
            double lapfd[3] = {0, 0, 0};
            for (int a = 0; a < dim; ++a) {
                double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
                xp[a] += step;
                xm[a] -= step;
                consph_mfield_eval(id, dim, &prm, xp, &vp);
                consph_mfield_eval(id, dim, &prm, xm, &vm);
                for (int c = 0; c < v.ncomp; ++c) {
                    double fd = (vp.f[c] - vm.f[c]) / (2 * step);
                    CHECK_NEAR(v.grad[c][a], fd, 1e-6 * (1 + fabs(fd)), "%s dim %d d%d comp %d",
                               consph_mfield_name(id), dim, a, c);
                    lapfd[c] += (vp.f[c] - 2 * v.f[c] + vm.f[c]) / (step * step);
                }
                if (v.ncomp == 1)
                    for (int b = 0; b < dim; ++b) {
                        double fd = (vp.grad[0][b] - vm.grad[0][b]) / (2 * step);
                        CHECK_NEAR(v.hess[a][b], fd, 1e-6 * (1 + fabs(fd)), "%s hess %d%d",
                                   consph_mfield_name(id), a, b);
                    }
            }
            double div = 0.0;
            for (int c = 0; c < v.ncomp; ++c) {
                CHECK_NEAR(v.lap[c], lapfd[c], 1e-4 * (1 + fabs(lapfd[c])), "%s dim %d lap",
                           consph_mfield_name(id), dim);
                if (v.ncomp > 1) div += v.grad[c][c];
            }
            if (v.ncomp > 1) CHECK_NEAR(v.div, div, 1e-12, "%s div", consph_mfield_name(id));
        }
    }
    consph_mfield_id id;
    CHECK(consph_mfield_lookup("tgv", &id) == CONSPH_OK && id == CONSPH_MFIELD_TGV, "lookup");
    CHECK(consph_mfield_lookup("nope", &id) == CONSPH_EINVAL, "unknown field");
}

/* 003 Table 2 (as computed from 003 eq. 51, which corrects two entries) and the bounds of
 * docs/reference-values.md. */
static void test_bounds(void)
{
    struct {
        const char *k;
        double a2, a3;
    } tab[] = {{"lucy", 20, 70},
               {"super-gaussian", 72, 720 / sqrt(M_PI)},
               {"wendland-c2:h", 28, 112},
               {"wendland-c4:h", 36, 165},
               {"wendland-c6:h", 312.0 / 7, 455.0 / 2}};
    for (size_t k = 0; k < sizeof tab / sizeof tab[0]; ++k) {
        CHECK_NEAR(consph_bound_kernel_factor(tab[k].k, 2), tab[k].a2, 1e-9 * tab[k].a2, "%s 2D",
                   tab[k].k);
        CHECK_NEAR(consph_bound_kernel_factor(tab[k].k, 3), tab[k].a3, 1e-9 * tab[k].a3, "%s 3D",
                   tab[k].k);
    }
    CHECK(isnan(consph_bound_kernel_factor("quintic", 2)), "support-3h kernel has no A_W");
    struct {
        int dim;
        double n, bound;
    } z2[] = {
        {2, 625, 2.537}, {2, 10000, 0.9373}, {2, 1e6, 0.1979}, {3, 15625, 1.828}, {3, 8e6, 0.2224}};
    for (size_t k = 0; k < sizeof z2 / sizeof z2[0]; ++k) {
        int d = z2[k].dim;
        double aw = consph_bound_kernel_factor("wendland-c4:h", d);
        double b = consph_bound_interpolation(aw, d, consph_scaling_nnbr(z2[k].n),
                                              consph_scaling_h(z2[k].n));
        CHECK_NEAR(b, z2[k].bound, 6e-4 * z2[k].bound + 5e-4, "bound %dD N=%g", d, z2[k].n);
    }
    CHECK_NEAR(consph_scaling_nnbr(1e6), 31528.7, 0.1, "scaling law 1000^2");
    CHECK_NEAR(consph_scaling_h(1e6), 0.1, 1e-12, "h = N^-1/6");
}

int main(void)
{
    test_fit();
    test_norms();
    test_fields();
    test_bounds();
    return check_summary("test_study");
}
