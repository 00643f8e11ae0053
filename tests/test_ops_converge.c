/* Every operator converges to the exact derivative of a smooth periodic field on an unperturbed
 * periodic lattice when h -> 0 with Δs/h -> 0 (000 §2.3, 001 eq. 3: kernel error O(h²) plus a
 * discretisation error that vanishes with Δs/h).
 *
 * This catches sign, factor and index slips that exactness tests cannot see in the forms that
 * are not exact on polynomials (F1-F3, S1, S2, Cleary, tvf, coupled, the uncorrected Fatehi),
 * and checks the consistent ones on a non-polynomial field. The refinement is Δs = 1/16, 1/32,
 * 1/64 with h = 0.5 √Δs (quintic, support 3h < half the box), so h shrinks by √2 per step: an
 * O(h²) error halves. Each step must cut the error by at least 1.6. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/consph.h"
#include "consph/ops.h"

static const double PI = 3.14159265358979323846;

/* u = sin(2πx) sin(2πy) + 0.5 cos(2πx): periodic on the unit square. */
static double u_val(double x, double y)
{
    return sin(2 * PI * x) * sin(2 * PI * y) + 0.5 * cos(2 * PI * x);
}
static void u_grad(double x, double y, double *g)
{
    g[0] = 2 * PI * cos(2 * PI * x) * sin(2 * PI * y) - PI * sin(2 * PI * x);
    g[1] = 2 * PI * sin(2 * PI * x) * cos(2 * PI * y);
}
static void u_hess(double x, double y, double *h)
{
    double k2 = 4 * PI * PI;
    h[0] = -k2 * sin(2 * PI * x) * sin(2 * PI * y) - 0.5 * k2 * cos(2 * PI * x);
    h[1] = k2 * cos(2 * PI * x) * cos(2 * PI * y);
    h[2] = -k2 * sin(2 * PI * x) * sin(2 * PI * y);
}

typedef struct triple {
    consph_op op;
    consph_op_form form;
    consph_op_corr corr;
} triple;

static const triple triples[] = {
    {CONSPH_OP_FUNCTION, CONSPH_FORM_STANDARD, CONSPH_CORR_NONE},
    {CONSPH_OP_FUNCTION, CONSPH_FORM_SHEPARD, CONSPH_CORR_NONE},
    {CONSPH_OP_FUNCTION, CONSPH_FORM_FPM, CONSPH_CORR_NONE},
    {CONSPH_OP_FUNCTION, CONSPH_FORM_MSPH, CONSPH_CORR_NONE},
    {CONSPH_OP_FUNCTION, CONSPH_FORM_CSHEPARD, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_F1, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_CSHEPARD, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_F2, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_F3, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_CORR_BC},
    {CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_CORR_LC},
    {CONSPH_OP_GRAD, CONSPH_FORM_SYM1, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_SYM1, CONSPH_CORR_BC},
    {CONSPH_OP_GRAD, CONSPH_FORM_SYM1, CONSPH_CORR_LC},
    {CONSPH_OP_GRAD, CONSPH_FORM_SYM2, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_SYM2, CONSPH_CORR_BC},
    {CONSPH_OP_GRAD, CONSPH_FORM_SYM2, CONSPH_CORR_LC},
    {CONSPH_OP_GRAD, CONSPH_FORM_SYM_S1, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_CSPM, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_IAD, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_FPM, CONSPH_CORR_NONE},
    {CONSPH_OP_GRAD, CONSPH_FORM_MSPH, CONSPH_CORR_NONE},
    {CONSPH_OP_DIV, CONSPH_FORM_DIV, CONSPH_CORR_NONE},
    {CONSPH_OP_DIV, CONSPH_FORM_DIV, CONSPH_CORR_BC},
    {CONSPH_OP_DIV, CONSPH_FORM_DIV, CONSPH_CORR_LC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S1, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S1_DIFF, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S1_SUM, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S2, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S2_DIFF, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S2_SUM, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_CLEARY, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_CLEARY, CONSPH_CORR_BC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_CLEARY, CONSPH_CORR_LC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_TVF, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_TVF, CONSPH_CORR_BC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_TVF, CONSPH_CORR_LC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_COUPLED, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_COUPLED, CONSPH_CORR_BC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_COUPLED, CONSPH_CORR_LC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI, CONSPH_CORR_FATEHI},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI_C, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_KORZILIUS, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_CSPM, CONSPH_CORR_NONE},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_MSPH, CONSPH_CORR_NONE},
    {CONSPH_OP_HESSIAN, CONSPH_FORM_KORZILIUS, CONSPH_CORR_NONE},
    {CONSPH_OP_HESSIAN, CONSPH_FORM_CSPM, CONSPH_CORR_NONE},
    {CONSPH_OP_HESSIAN, CONSPH_FORM_MSPH, CONSPH_CORR_NONE},
};
#define NTRIPLES (sizeof triples / sizeof triples[0])

/* Max-norm errors of every triple at resolution nx. */
static int run(size_t nx, double *err)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 2, nx);
    consph_particles src;
    if (consph_layout_generate(&lp, &src, NULL) != CONSPH_OK) return 0;
    consph_kernel k;
    consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 2, 0.5 * sqrt(1.0 / (double)nx));
    consph_sys sys;
    consph_op_ctx ctx;
    int have_sys = consph_sys_init(&sys, &src, &k, 0.0) == CONSPH_OK;
    consph_particles_free(&src);
    int ok = have_sys && consph_op_ctx_init_sys(&ctx, &sys, CONSPH_VOLUME_SUMMATION) == CONSPH_OK;
    if (ok) {
        const consph_particles *p = sys.p;
        const size_t n = p->n;
        double *in = malloc(2 * n * sizeof(double)), *out = malloc(3 * n * sizeof(double));
        for (size_t t = 0; t < NTRIPLES && ok; ++t) {
            const triple *tr = &triples[t];
            for (size_t i = 0; i < n; ++i) {
                double x = p->x[0][i], y = p->x[1][i];
                in[i] = u_val(x, y);
                /* divergence input: (u, u(y, x)) */
                if (tr->op == CONSPH_OP_DIV) in[n + i] = u_val(y, x);
            }
            ok = consph_apply(&ctx, tr->op, tr->form, tr->corr, in, out, NULL) == CONSPH_OK;
            double worst = 0.0;
            for (size_t i = 0; ok && i < n; ++i) {
                double x = p->x[0][i], y = p->x[1][i], gr[2], gs[2], h[3], ex[3];
                int ne = 1;
                u_grad(x, y, gr);
                u_hess(x, y, h);
                switch (tr->op) {
                case CONSPH_OP_FUNCTION:
                    ex[0] = u_val(x, y);
                    break;
                case CONSPH_OP_GRAD:
                    ne = 2;
                    ex[0] = gr[0], ex[1] = gr[1];
                    /* asym, sym1, sym2 approximate ∇p/ρ */
                    if (tr->form == CONSPH_FORM_ASYM || tr->form == CONSPH_FORM_SYM1 ||
                        tr->form == CONSPH_FORM_SYM2 || tr->form == CONSPH_FORM_SYM_S1)
                        ex[0] /= ctx.rho[i], ex[1] /= ctx.rho[i];
                    break;
                case CONSPH_OP_DIV:
                    u_grad(y, x, gs);
                    ex[0] = gr[0] + gs[0]; /* ∂_y of u(y, x) is ∂_1 u at (y, x) */
                    break;
                case CONSPH_OP_LAPLACIAN:
                    ex[0] = h[0] + h[2];
                    break;
                default:
                    ne = 3;
                    ex[0] = h[0], ex[1] = h[1], ex[2] = h[2];
                }
                for (int c = 0; c < ne; ++c) {
                    double e = fabs(out[(size_t)c * n + i] - ex[c]);
                    if (!(e <= worst)) worst = e;
                }
            }
            err[t] = worst;
        }
        free(in);
        free(out);
        consph_op_ctx_free(&ctx);
    }
    if (have_sys) consph_sys_free(&sys);
    return ok;
}

int main(void)
{
    const size_t nx[3] = {16, 32, 64};
    double err[3][NTRIPLES];
    for (int r = 0; r < 3; ++r) CHECK(run(nx[r], err[r]), "nx %zu: %s", nx[r], consph_last_error());
    for (size_t t = 0; t < NTRIPLES; ++t) {
        const triple *tr = &triples[t];
        double r1 = err[0][t] / err[1][t], r2 = err[1][t] / err[2][t];
        printf("%-9s %-9s %-6s  %.3e %.3e %.3e  ratios %.2f %.2f\n", consph_op_name(tr->op),
               consph_form_name(tr->form), consph_corr_name(tr->corr), err[0][t], err[1][t],
               err[2][t], r1, r2);
        CHECK(r1 > 1.6 && r2 > 1.6, "%s %s[%s] does not converge: errors %.3e %.3e %.3e",
              consph_op_name(tr->op), consph_form_name(tr->form), consph_corr_name(tr->corr),
              err[0][t], err[1][t], err[2][t]);
    }
    return check_summary("test_ops_converge");
}
