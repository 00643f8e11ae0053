/* The neighbour buffer and the O(N^2) reference search. */
#include "nnps_internal.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Beyond this many box lengths per axis the image count is absurd and index arithmetic would
 * need care; the cell search rejects such radii too. */
#define NNPS_MAX_IMAGES_PER_AXIS 1.0e6

void consph_nbrs_free(consph_nbrs *nb)
{
    if (!nb) return;
    free(nb->j);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(nb->dx[a]);
    free(nb->r);
    memset(nb, 0, sizeof *nb);
}

static int grow_array(void **ptr, size_t count, size_t size)
{
    void *q = realloc(*ptr, count * size);
    if (!q)
        return consph_fail(CONSPH_ENOMEM, "out of memory growing a neighbour list to %zu entries",
                           count);
    *ptr = q;
    return CONSPH_OK;
}

int nnps_nbrs_reserve(consph_nbrs *nb, size_t need)
{
    if (need <= nb->cap && nb->j && nb->r && nb->dx[0] && nb->dx[1] && nb->dx[2]) return CONSPH_OK;
    size_t cap = nb->cap < 64 ? 64 : nb->cap;
    while (cap < need) {
        if (cap > SIZE_MAX / 2 / sizeof(double))
            return consph_fail(CONSPH_ENOMEM, "neighbour list of %zu entries is too large", need);
        cap *= 2;
    }
    /* Each array is grown in turn; cap is raised only when all succeeded, so a failure leaves
     * a consistent (if partly larger) buffer. */
    if (grow_array((void **)&nb->j, cap, sizeof *nb->j)) return CONSPH_ENOMEM;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a)
        if (grow_array((void **)&nb->dx[a], cap, sizeof(double))) return CONSPH_ENOMEM;
    if (grow_array((void **)&nb->r, cap, sizeof *nb->r)) return CONSPH_ENOMEM;
    nb->cap = cap;
    return CONSPH_OK;
}

size_t consph_nnps_brute(const consph_particles *p, double radius, const double *x,
                         consph_nbrs *out)
{
    out->n = 0;
    if (!(radius > 0.0) || !isfinite(radius)) {
        consph_fail(CONSPH_EINVAL, "search radius must be finite and > 0, got %g", radius);
        return (size_t)-1;
    }
    const consph_box *box = &p->box;
    const int dim = p->dim;
    if (dim < 1 || dim > CONSPH_MAX_DIM || box->dim != dim) {
        consph_fail(CONSPH_EINVAL, "particle dimension %d does not match its box (%d)", dim,
                    box->dim);
        return (size_t)-1;
    }
    double len[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
    double xq[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
    int64_t mmax[CONSPH_MAX_DIM] = {0, 0, 0};
    for (int a = 0; a < dim; ++a) {
        len[a] = box->hi[a] - box->lo[a];
        xq[a] = x[a];
        if (!box->periodic[a]) continue;
        if (radius > NNPS_MAX_IMAGES_PER_AXIS * len[a]) {
            consph_fail(CONSPH_EINVAL, "search radius %g exceeds %g periodic box lengths", radius,
                        NNPS_MAX_IMAGES_PER_AXIS);
            return (size_t)-1;
        }
        /* Both points lie in [lo, hi), so |x - x_j| < L and shifts beyond ceil(R/L) + 1 periods
         * cannot come within the radius. */
        mmax[a] = (int64_t)ceil(radius / len[a]) + 1;
        xq[a] = nnps_wrap(x[a], box->lo[a], box->hi[a], len[a]);
    }
    const double r2max = radius * radius;
    size_t n = 0;
    for (size_t j = 0; j < p->n; ++j) {
        double xj[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        for (int a = 0; a < dim; ++a)
            xj[a] = box->periodic[a] ? nnps_wrap(p->x[a][j], box->lo[a], box->hi[a], len[a])
                                     : p->x[a][j];
        for (int64_t m2 = -mmax[2]; m2 <= mmax[2]; ++m2) {
            for (int64_t m1 = -mmax[1]; m1 <= mmax[1]; ++m1) {
                for (int64_t m0 = -mmax[0]; m0 <= mmax[0]; ++m0) {
                    /* Same expression order as the cell search: (x - shift) - x_j. */
                    double d0 = (xq[0] - (double)m0 * len[0]) - xj[0];
                    double d1 = (xq[1] - (double)m1 * len[1]) - xj[1];
                    double d2 = (xq[2] - (double)m2 * len[2]) - xj[2];
                    double r2 = dim == 1   ? d0 * d0
                                : dim == 2 ? d0 * d0 + d1 * d1
                                           : d0 * d0 + d1 * d1 + d2 * d2;
                    if (!(r2 < r2max)) continue;
                    if (nnps_nbrs_reserve(out, n + 1)) {
                        out->n = 0;
                        return (size_t)-1;
                    }
                    out->j[n] = j;
                    out->dx[0][n] = d0;
                    if (dim > 1) out->dx[1][n] = d1;
                    if (dim > 2) out->dx[2][n] = d2;
                    out->r[n] = sqrt(r2);
                    ++n;
                }
            }
        }
    }
    out->n = n;
    return n;
}
