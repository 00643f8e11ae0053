/* 1D boundary-integral derivatives (000 §3.4, eqs. 45-46) converge on an interval, boundary
 * particles included.
 *
 * Near an end the estimates are Shepard-like, with a kernel error O(h) (000 eq. 40), and the
 * particle sums add a quadrature error of the cut-off integrand that grows like Δ²/h³ (midpoint
 * rule on cell-centred particles). Both vanish when h -> 0 with Δ/h -> 0, so the refinement
 * takes h = 0.5 √Δ: the maximum error over all particles should fall like √Δ, i.e. halve with
 * every 4× refinement. A constant h/Δ would not converge at the ends. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/consph.h"
#include "consph/ops.h"

static double f(double x)
{
    return sin(2.0 * x) + x * x;
}
static double df(double x)
{
    return 2.0 * cos(2.0 * x) + 2.0 * x;
}
static double d2f(double x)
{
    return -4.0 * sin(2.0 * x) + 2.0;
}

typedef struct errs {
    double d1_max, d2_max, d1_mid, d2_mid;
} errs;

/* A system over the layout's particles. */
static int make_sys(const consph_layout_params *lp, const consph_kernel *k, consph_sys *sys)
{
    consph_particles p;
    if (consph_layout_generate(lp, &p, NULL) != CONSPH_OK) return 0;
    int ok = consph_sys_init(sys, &p, k, 0.0) == CONSPH_OK;
    consph_particles_free(&p);
    return ok;
}

static int run(size_t n, errs *e)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 1, n);
    lp.box = consph_box_unit(1, 0);
    const double ds = 1.0 / (double)n;
    consph_kernel k;
    consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 1, 0.5 * sqrt(ds));
    consph_sys sys;
    consph_op_ctx ctx;
    int have_sys = make_sys(&lp, &k, &sys);
    int ok = have_sys && consph_op_ctx_init_sys(&ctx, &sys, CONSPH_VOLUME_GIVEN) == CONSPH_OK;
    if (ok) {
        const consph_particles *p = sys.p;
        double *u = malloc(n * sizeof(double)), *d1 = malloc(n * sizeof(double)),
               *d2 = malloc(n * sizeof(double));
        for (size_t i = 0; i < n; ++i) u[i] = f(p->x[0][i]);
        consph_op_report rep;
        ok = consph_op_boundary_1d(&ctx, u, f(0.0), f(1.0), d1, d2, &rep) == CONSPH_OK;
        memset(e, 0, sizeof *e);
        for (size_t i = 0; ok && i < n; ++i) {
            double x = p->x[0][i];
            double e1 = fabs(d1[i] - df(x)), e2 = fabs(d2[i] - d2f(x));
            e->d1_max = fmax(e->d1_max, e1);
            e->d2_max = fmax(e->d2_max, e2);
            if (x > 0.4 && x < 0.6) {
                e->d1_mid = fmax(e->d1_mid, e1);
                e->d2_mid = fmax(e->d2_mid, e2);
            }
        }
        free(u);
        free(d1);
        free(d2);
        consph_op_ctx_free(&ctx);
    }
    if (have_sys) consph_sys_free(&sys);
    return ok;
}

int main(void)
{
    const size_t ns[4] = {100, 400, 1600, 6400};
    errs e[4];
    for (int r = 0; r < 4; ++r) {
        CHECK(run(ns[r], &e[r]), "n = %zu: %s", ns[r], consph_last_error());
        printf("n %5zu  h %.4f  max|d1 err| %.3e  max|d2 err| %.3e  (interior %.3e %.3e)\n", ns[r],
               0.5 / sqrt((double)ns[r]), e[r].d1_max, e[r].d2_max, e[r].d1_mid, e[r].d2_mid);
    }
    for (int r = 1; r < 4; ++r) {
        /* error ∝ h ∝ √Δ: a factor 2 per refinement; demand 1.6 */
        CHECK(e[r - 1].d1_max / e[r].d1_max > 1.6, "d1 error ratio %.3f at n = %zu",
              e[r - 1].d1_max / e[r].d1_max, ns[r]);
        CHECK(e[r - 1].d2_max / e[r].d2_max > 1.6, "d2 error ratio %.3f at n = %zu",
              e[r - 1].d2_max / e[r].d2_max, ns[r]);
    }
    CHECK(e[3].d1_max < 0.05 && e[3].d2_max < 0.5, "finest errors %.3e %.3e", e[3].d1_max,
          e[3].d2_max);
    /* Rejected inputs: periodic interval, wrong dimension. */
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 1, 20);
    consph_kernel k;
    consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 1, 0.06);
    consph_sys sys;
    consph_op_ctx ctx;
    CHECK(make_sys(&lp, &k, &sys) /* periodic by default */ &&
              consph_op_ctx_init_sys(&ctx, &sys, CONSPH_VOLUME_GIVEN) == CONSPH_OK,
          "ctx: %s", consph_last_error());
    double u[20], d1[20];
    for (int i = 0; i < 20; ++i) u[i] = 1.0;
    CHECK(consph_op_boundary_1d(&ctx, u, 1.0, 1.0, d1, NULL, NULL) == CONSPH_EINVAL,
          "periodic interval must be rejected");
    consph_op_ctx_free(&ctx);
    consph_sys_free(&sys);
    return check_summary("test_ops_boundary");
}
