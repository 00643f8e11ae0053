#include <math.h>
#include <stdlib.h>

#include "consph/study.h"

int consph_error_norms_compute(const double *approx, const double *exact, size_t n, int ncomp,
                               const unsigned char *mask, consph_error_norms *out)
{
    /* Per-particle terms first, then order-fixed sums: the norms do not depend on threads. */
    double *e = consph_calloc(n, sizeof(double));
    double *e2 = consph_calloc(n, sizeof(double));
    double *g = consph_calloc(n, sizeof(double));
    if (!e || !e2 || !g) {
        free(e);
        free(e2);
        free(g);
        return CONSPH_ENOMEM;
    }
    size_t count = 0;
    double linf = 0.0;
    for (size_t i = 0; i < n; ++i) {
        if (mask && !mask[i]) continue;
        double s = 0.0, go = 0.0;
        for (int c = 0; c < ncomp; ++c) {
            double d = approx[(size_t)c * n + i] - exact[(size_t)c * n + i];
            s += d * d;
            go += exact[(size_t)c * n + i] * exact[(size_t)c * n + i];
        }
        e[count] = sqrt(s);
        e2[count] = s;
        g[count] = sqrt(go);
        if (!(e[count] <= linf)) linf = e[count]; /* propagates NaN */
        ++count;
    }
    out->count = count;
    if (count == 0) {
        out->l1 = out->l2 = out->linf = out->mae = NAN;
    } else {
        double se = consph_sum(e, count), sg = consph_sum(g, count);
        out->l1 = sg > 0 ? se / sg : NAN;
        out->mae = se / (double)count;
        out->l2 = sqrt(consph_sum(e2, count) / (double)count);
        out->linf = linf;
    }
    free(e);
    free(e2);
    free(g);
    return CONSPH_OK;
}

double consph_total_force_ratio(const double *fx, size_t n, const unsigned char *mask)
{
    double *v = consph_calloc(n, sizeof(double));
    if (!v) return NAN;
    size_t m = 0;
    double fmax = 0.0;
    for (size_t i = 0; i < n; ++i) {
        if (mask && !mask[i]) continue;
        v[m++] = fx[i];
        if (fabs(fx[i]) > fmax) fmax = fabs(fx[i]);
    }
    double total = consph_sum(v, m);
    free(v);
    return fmax > 0 ? total / fmax : NAN;
}
