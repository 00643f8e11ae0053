/* Shared by the transport sources: a measure copied into contiguous, validated form. */
#ifndef CONSPH_TRANSPORT_INTERNAL_H
#define CONSPH_TRANSPORT_INTERNAL_H

#include <math.h>

#include "consph/transport.h"

/* Points of positive weight only (a zero-weight point carries no mass and would put log 0 into
 * Sinkhorn), positions interleaved x[i*dim + a], weights normalised to sum 1. */
typedef struct ot_points {
    int dim;
    size_t n;
    double *x;
    double *w;
} ot_points;

/* `which` names the measure in messages ("first", "second"). */
int ot_points_make(const consph_measure *mu, const char *which, ot_points *pts);
void ot_points_free(ot_points *pts);

/* Exact W_p^p in 1D between sorted (x ascending) point sets with normalised weights. */
double ot_w1d_sorted_pow(const double *xa, const double *wa, size_t na, const double *xb,
                         const double *wb, size_t nb, int p);

/* |x - y|^p in dim dimensions, p = 1 or 2. */
static inline double ot_cost(const double *x, const double *y, int dim, int p)
{
    double s = 0.0;
    for (int a = 0; a < dim; ++a) {
        double d = x[a] - y[a];
        s += d * d;
    }
    return p == 2 ? s : sqrt(s);
}

/* Rough costs behind the estimates, in seconds per unit of work on one thread, measured on
 * 2 shared cores (1 and 2 threads) with margin: a Sinkhorn half step per point pair (log-sum-exp
 * with exp), a sliced projection per point and sort level, an SPH grid gather per cell and
 * particle (distance test, kernel inside the support). */
#define OT_RATE_SINKHORN_PAIR 35e-9
#define OT_RATE_SORT 30e-9
#define OT_RATE_GRID_PAIR 80e-9

int ot_sinkhorn(const ot_points *a, const ot_points *b, const consph_ot_options *opt,
                consph_ot_result *res);

#endif
