/* Measured orders of convergence at small resolutions, against 001: asym_bc (Table 3: 1.99),
 * div_bc (Fig. 9: second order) and coupled_bc (Table 5: 1.95), on the unperturbed lattice (UP)
 * and on packed particles (PP), each within ±0.3. The field is sin(2π(x+y)) (docs/deviations.md).
 */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "consph/study.h"

static double measured_order(const char *op, const char *form, const char *corr,
                             consph_layout_kind layout, consph_mfield_id field, const size_t *nx,
                             int n)
{
    consph_approx_spec s = consph_approx_defaults(2);
    if (consph_op_parse(op, form, corr, 2, &s.op) != CONSPH_OK) {
        fprintf(stderr, "%s\n", consph_last_error());
        return NAN;
    }
    s.layout = consph_layout_defaults(layout, 2, 10);
    s.field = field;
    double res[8], err[8];
    for (int k = 0; k < n; ++k) {
        consph_approx_row row;
        if (consph_approx_run(&s, nx[k], &row) != CONSPH_OK) {
            fprintf(stderr, "%s\n", consph_last_error());
            return NAN;
        }
        res[k] = (double)nx[k];
        err[k] = row.err.l1;
        CHECK(row.fallbacks == 0, "%s %s %s: %zu fallbacks", op, form, corr, row.fallbacks);
    }
    consph_order_fit fit;
    if (consph_fit_order(res, err, n, &fit) != CONSPH_OK) return NAN;
    printf("%-10s %-8s %-4s %-8s order %.3f +- %.3f\n", op, form, corr, consph_layout_name(layout),
           fit.order, fit.order_stderr);
    return fit.order;
}

int main(void)
{
    const size_t up[4] = {20, 30, 40, 60};
    const size_t pp[3] = {16, 24, 32};
    struct {
        const char *op, *form, *corr;
        consph_mfield_id field;
        double paper;
    } cases[] = {
        {"grad", "asym", "bc", CONSPH_MFIELD_SIN2PI, 1.99},
        {"div", "div", "bc", CONSPH_MFIELD_SIN2PI_VEC, 2.0},
        {"laplacian", "coupled", "bc", CONSPH_MFIELD_SIN2PI, 1.95},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
        double o = measured_order(cases[c].op, cases[c].form, cases[c].corr, CONSPH_LAYOUT_LATTICE,
                                  cases[c].field, up, 4);
        CHECK(fabs(o - cases[c].paper) <= 0.3, "%s %s on UP: order %.3f, 001: %.2f", cases[c].op,
              cases[c].form, o, cases[c].paper);
        o = measured_order(cases[c].op, cases[c].form, cases[c].corr, CONSPH_LAYOUT_PACKED,
                           cases[c].field, pp, 3);
        CHECK(fabs(o - cases[c].paper) <= 0.3, "%s %s on PP: order %.3f, 001: %.2f", cases[c].op,
              cases[c].form, o, cases[c].paper);
    }
    return check_summary("test_orders");
}
