/* Small dense inverses for the per-particle correction matrices (at most 10×10). */
#include <math.h>
#include <string.h>

#include "ops/ops_internal.h"
#include "ops/small.h"

#define MAXN OPS_MAX_MSPH
_Static_assert(OPS_SMALL_MAXN == OPS_MAX_MSPH, "ops/small.h inverts up to OPS_MAX_MSPH");

int ops_invert(int n, const double *a, double *ainv, double cond_max, double *cond)
{
    if (n < 1 || n > MAXN) return 0;
    if (n == 2) return ops_invert_n(2, a, ainv, cond_max, cond);
    if (n == 3) return ops_invert_n(3, a, ainv, cond_max, cond);
    return ops_invert_n(n, a, ainv, cond_max, cond);
}

void ops_pair_index(int dim, int p, int *l, int *k)
{
    int idx = 0;
    for (int a = 0; a < dim; ++a)
        for (int b = a; b < dim; ++b) {
            if (idx == p) {
                *l = a;
                *k = b;
                return;
            }
            ++idx;
        }
    *l = *k = 0;
}
