/* Orders of convergence: the least-squares fit, and the one verdict on a series of measured
 * rows that every report (consph approx, the study engine) states. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/study.h"

int consph_fit_order(const double *resolution, const double *err, int n, consph_order_fit *fit)
{
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int m = 0;
    fit->npoints = 0;
    fit->order = fit->order_stderr = fit->intercept = NAN;
    /* A non-finite error is a wrong result, not a point to leave out. */
    for (int k = 0; k < n; ++k)
        if (!isfinite(err[k]) || !isfinite(resolution[k]))
            return consph_fail(CONSPH_ENUMERIC, "order fit: point %d (resolution %g) has error %g",
                               k, resolution[k], err[k]);
    for (int k = 0; k < n; ++k) {
        if (!(err[k] > 0) || !(resolution[k] > 0)) continue;
        double x = log(resolution[k]), y = log(err[k]);
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
        ++m;
    }
    fit->npoints = m;
    if (m < 2)
        return consph_fail(CONSPH_ENUMERIC, "order fit needs two positive errors, got %d", m);
    double den = m * sxx - sx * sx;
    if (!(fabs(den) > 1e-300))
        return consph_fail(CONSPH_ENUMERIC, "order fit: resolutions are all equal");
    double slope = (m * sxy - sx * sy) / den;
    double icpt = (sy - slope * sx) / m;
    fit->order = -slope;
    fit->intercept = icpt;
    if (m > 2) {
        double ssr = 0, mx = sx / m, sxx_c = 0;
        for (int k = 0; k < n; ++k) {
            if (!(err[k] > 0) || !(resolution[k] > 0)) continue;
            double x = log(resolution[k]), y = log(err[k]);
            double r = y - (icpt + slope * x);
            ssr += r * r;
            sxx_c += (x - mx) * (x - mx);
        }
        fit->order_stderr = sqrt(ssr / (m - 2) / sxx_c);
    }
    return CONSPH_OK;
}

const char *consph_order_text(const consph_order_fit *fit, int digits, const char *pm, char *buf,
                              size_t size)
{
    if (!isfinite(fit->order))
        snprintf(buf, size, "n/a");
    else if (!isfinite(fit->order_stderr))
        snprintf(buf, size, "%.*f %s n/a", digits, fit->order, pm);
    else
        snprintf(buf, size, "%.*f %s %.*f", digits, fit->order, pm, digits, fit->order_stderr);
    return buf;
}

double consph_approx_norm(const consph_approx_row *row, const char *norm)
{
    if (!strcmp(norm, "l2")) return row->err.l2;
    if (!strcmp(norm, "linf")) return row->err.linf;
    if (!strcmp(norm, "mae")) return row->err.mae;
    return row->err.l1;
}

int consph_series_fit(const consph_approx_row *rows, const double *res, int nrows, const char *norm,
                      int digits, const char *pm, consph_series_order *out)
{
    memset(out, 0, sizeof *out);
    out->row = -1;
    out->fit.order = out->fit.order_stderr = out->fit.intercept = NAN;
    /* The absolute norms are finite whenever every compared output is: one that is not is an
     * operator result gone wrong, whichever norm is fitted. */
    for (int k = 0; k < nrows; ++k) {
        const consph_error_norms *e = &rows[k].err;
        const char *bad = !isfinite(e->l2)     ? "l2"
                          : !isfinite(e->linf) ? "linf"
                          : !isfinite(e->mae)  ? "mae"
                                               : NULL;
        /* With no particle compared the norms are NaN by definition: nothing was measured. */
        if (!bad || e->count == 0) continue;
        out->status = CONSPH_SERIES_NONFINITE;
        out->row = k;
        snprintf(out->why, sizeof out->why, "nx = %g: the %s error is %g (a non-finite result)",
                 res[k], bad, consph_approx_norm(&rows[k], bad));
        snprintf(out->text, sizeof out->text, "n/a (not finite at nx = %g)", res[k]);
        return consph_fail(CONSPH_ENUMERIC, "%s", out->why);
    }
    /* Where no particle has a neighbour, or every one fell back to the uncorrected form, the
     * error measures the fallback (typically a constant), not the operator's convergence. */
    for (int k = 0; k < nrows; ++k) {
        const consph_approx_row *w = &rows[k];
        const int none = w->err.count == 0, lonely = !(w->nbr_mean > 0),
                  fell = w->n > 0 && w->fallbacks >= w->n;
        if (!none && !lonely && !fell) continue;
        out->status = CONSPH_SERIES_DEGENERATE;
        out->row = k;
        snprintf(out->why, sizeof out->why, "nx = %g: %s, so no order is fitted", res[k],
                 none ? "no particle was compared (none has the kernel's full support)"
                 : lonely
                     ? "no particle has a neighbour within the kernel support (h/dx too small?)"
                     : "every particle fell back (no correction matrix was accepted)");
        snprintf(out->text, sizeof out->text, "n/a (%s at nx = %g)",
                 none     ? "no particle compared"
                 : lonely ? "no neighbours"
                          : "every particle fell back",
                 res[k]);
        return CONSPH_OK;
    }
    for (int k = 0; k < nrows; ++k)
        if (!isfinite(consph_approx_norm(&rows[k], norm))) {
            /* Only l1 gets here: it is relative to Σ|exact|, undefined when that is 0. */
            out->status = CONSPH_SERIES_NO_FIT;
            out->row = k;
            snprintf(out->text, sizeof out->text, "n/a (%s undefined: the exact values are 0)",
                     norm);
            return CONSPH_OK;
        }
    double *err = consph_calloc(nrows > 0 ? (size_t)nrows : 1, sizeof(double));
    if (!err) return CONSPH_ENOMEM;
    for (int k = 0; k < nrows; ++k) err[k] = consph_approx_norm(&rows[k], norm);
    int st = consph_fit_order(res, err, nrows, &out->fit);
    free(err);
    if (st != CONSPH_OK) {
        out->status = CONSPH_SERIES_NO_FIT;
        snprintf(out->text, sizeof out->text, "n/a (%s)",
                 out->fit.npoints < 2 ? "fewer than two non-zero errors" : "one resolution");
        return CONSPH_OK;
    }
    out->status = CONSPH_SERIES_ORDER;
    char fitted[64];
    consph_order_text(&out->fit, digits, pm, fitted, sizeof fitted);
    /* consph_fit_order leaves out errors of exactly 0 (log 0): say so beside the order. */
    if (out->fit.npoints < nrows)
        snprintf(out->text, sizeof out->text, "%s (over %d of %d rows; error 0 elsewhere)", fitted,
                 out->fit.npoints, nrows);
    else
        snprintf(out->text, sizeof out->text, "%s", fitted);
    return CONSPH_OK;
}
