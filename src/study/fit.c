#include <math.h>

#include "consph/study.h"

int consph_fit_order(const double *resolution, const double *err, int n, consph_order_fit *fit)
{
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int m = 0;
    for (int k = 0; k < n; ++k) {
        if (!(err[k] > 0) || !isfinite(err[k]) || !(resolution[k] > 0)) continue;
        double x = log(resolution[k]), y = log(err[k]);
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
        ++m;
    }
    fit->npoints = m;
    fit->order = fit->order_stderr = fit->intercept = NAN;
    if (m < 2)
        return consph_fail(CONSPH_ENUMERIC, "order fit needs two positive errors, got %d", m);
    double den = m * sxx - sx * sx;
    if (!(fabs(den) > 1e-300))
        return consph_fail(CONSPH_ENUMERIC, "order fit: resolutions are all equal");
    double slope = (m * sxy - sx * sy) / den;
    double icpt = (sy - slope * sx) / m;
    fit->order = -slope;
    fit->intercept = icpt;
    fit->order_stderr = 0.0;
    if (m > 2) {
        double ssr = 0, mx = sx / m, sxx_c = 0;
        for (int k = 0; k < n; ++k) {
            if (!(err[k] > 0) || !isfinite(err[k]) || !(resolution[k] > 0)) continue;
            double x = log(resolution[k]), y = log(err[k]);
            double r = y - (icpt + slope * x);
            ssr += r * r;
            sxx_c += (x - mx) * (x - mx);
        }
        fit->order_stderr = sqrt(ssr / (m - 2) / sxx_c);
    }
    return CONSPH_OK;
}
