/* The order verdict every report states (consph_series_fit): a non-finite row is an error
 * naming its resolution, never a point quietly left out; a row without neighbours or where
 * every particle fell back gives no order; two resolutions give no standard error. */
#include <math.h>
#include <string.h>

#include "check.h"
#include "consph/study.h"

/* Rows with err = c nx^-2 in every norm, nbr 36 and no fallback. */
static void make_rows(consph_approx_row *rows, double *res, int n)
{
    memset(rows, 0, (size_t)n * sizeof *rows);
    for (int k = 0; k < n; ++k) {
        res[k] = 10.0 * (1 << k);
        double e = 3.0 * pow(res[k], -2.0);
        rows[k].nx = (size_t)res[k];
        rows[k].n = rows[k].nx * rows[k].nx;
        rows[k].nbr_mean = 36.0;
        rows[k].err.l1 = rows[k].err.l2 = rows[k].err.linf = rows[k].err.mae = e;
        rows[k].err.count = rows[k].n;
    }
}

static void test_fit_order_rejects_nonfinite(void)
{
    double res[3] = {10, 20, 40}, err[3] = {1e-2, NAN, 6.25e-4};
    consph_order_fit fit;
    CHECK(consph_fit_order(res, err, 3, &fit) == CONSPH_ENUMERIC,
          "a NaN error must fail the fit, not be skipped (order %g)", fit.order);
    err[1] = INFINITY;
    CHECK(consph_fit_order(res, err, 3, &fit) == CONSPH_ENUMERIC, "an infinite error too");
    /* Two points: an order, but no standard error to be had. */
    CHECK(consph_fit_order(res, err, 1, &fit) != CONSPH_OK, "one point");
    double e2[2] = {1e-2, 2.5e-3};
    CHECK(consph_fit_order(res, e2, 2, &fit) == CONSPH_OK, "two points");
    CHECK_NEAR(fit.order, 2.0, 1e-12, "two points");
    CHECK(isnan(fit.order_stderr), "two points: stderr %g, not NaN", fit.order_stderr);
}

static void test_series_nonfinite(void)
{
    consph_approx_row rows[3];
    double res[3];
    make_rows(rows, res, 3);
    rows[1].err.l2 = NAN;
    consph_series_order so;
    /* The fitted norm (l1) is finite everywhere: the NaN l2 still is a wrong result. */
    CHECK(consph_series_fit(rows, res, 3, "l1", 3, "+-", &so) == CONSPH_ENUMERIC, "status");
    CHECK(so.status == CONSPH_SERIES_NONFINITE && so.row == 1, "status %d row %d", so.status,
          so.row);
    CHECK(strstr(so.why, "nx = 20") && strstr(so.why, "l2"), "why: %s", so.why);
    CHECK(strstr(consph_last_error(), "nx = 20") != NULL, "message: %s", consph_last_error());
    CHECK(strncmp(so.text, "n/a", 3) == 0, "text: %s", so.text);
}

static void test_series_degenerate(void)
{
    /* No neighbours: every norm is the same at every resolution, a slope of -0.000. */
    consph_approx_row rows[3];
    double res[3];
    make_rows(rows, res, 3);
    for (int k = 0; k < 3; ++k) {
        rows[k].nbr_mean = 0.0;
        rows[k].fallbacks = rows[k].n;
        rows[k].err.l1 = 1.0;
    }
    consph_series_order so;
    CHECK(consph_series_fit(rows, res, 3, "l1", 3, "+-", &so) == CONSPH_OK, "not an error");
    CHECK(so.status == CONSPH_SERIES_DEGENERATE && so.row == 0, "status %d", so.status);
    CHECK(strstr(so.text, "0.000") == NULL && strncmp(so.text, "n/a", 3) == 0, "text: %s", so.text);
    CHECK(strstr(so.why, "neighbour") != NULL, "why: %s", so.why);
    /* Every particle fell back, neighbours or not. */
    make_rows(rows, res, 3);
    rows[2].fallbacks = rows[2].n;
    CHECK(consph_series_fit(rows, res, 3, "l1", 3, "+-", &so) == CONSPH_OK, "not an error");
    CHECK(so.status == CONSPH_SERIES_DEGENERATE && so.row == 2, "status %d row %d", so.status,
          so.row);
    CHECK(strstr(so.why, "fell back") && strstr(so.why, "nx = 40"), "why: %s", so.why);
    /* No particle compared (none with full support): NaN norms that measure nothing, a warning. */
    make_rows(rows, res, 3);
    rows[0].err.count = 0;
    rows[0].err.l1 = rows[0].err.l2 = rows[0].err.linf = rows[0].err.mae = NAN;
    CHECK(consph_series_fit(rows, res, 3, "l1", 3, "+-", &so) == CONSPH_OK, "not an error");
    CHECK(so.status == CONSPH_SERIES_DEGENERATE && so.row == 0, "status %d", so.status);
}

static void test_series_text(void)
{
    consph_approx_row rows[3];
    double res[3];
    make_rows(rows, res, 3);
    consph_series_order so;
    CHECK(consph_series_fit(rows, res, 3, "mae", 2, "±", &so) == CONSPH_OK, "fit");
    CHECK(so.status == CONSPH_SERIES_ORDER && !strcmp(so.text, "2.00 ± 0.00"), "text: %s", so.text);
    CHECK(consph_series_fit(rows, res, 2, "mae", 3, "+-", &so) == CONSPH_OK, "fit");
    CHECK(!strcmp(so.text, "2.000 +- n/a"), "two rows: %s", so.text);
    /* l1 of a field whose exact values are all 0 is undefined: no order, not an error. */
    for (int k = 0; k < 3; ++k) rows[k].err.l1 = NAN;
    CHECK(consph_series_fit(rows, res, 3, "l1", 3, "+-", &so) == CONSPH_OK, "l1 undefined");
    CHECK(so.status == CONSPH_SERIES_NO_FIT && strstr(so.text, "undefined"), "text: %s", so.text);
    /* An exact row (error 0) is left out of the log fit, and the text says so. */
    make_rows(rows, res, 3);
    rows[0].err.l2 = 0.0;
    CHECK(consph_series_fit(rows, res, 3, "l2", 3, "+-", &so) == CONSPH_OK, "fit");
    CHECK(so.fit.npoints == 2 && strstr(so.text, "2 of 3"), "text: %s", so.text);
}

int main(void)
{
    test_fit_order_rejects_nonfinite();
    test_series_nonfinite();
    test_series_degenerate();
    test_series_text();
    return check_summary("test_fit");
}
