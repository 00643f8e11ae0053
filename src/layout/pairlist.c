/* The packing's private neighbour list (a Verlet list): every particle's neighbours within the
 * kernel radius plus a skin, with the periodic image of each pair, kept over many steps while
 * the particles move by less than half the skin. The packing's motions per step are small
 * (at most a few percent of h once the first steps are past), so the search runs once in many
 * steps instead of every step; the pair sums then walk the list. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "layout/layout_internal.h"

void pack_list_free(pack_list *L)
{
    free(L->start);
    free(L->j);
    free(L->dwr);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        free(L->image[a]);
        free(L->x_ref[a]);
    }
    memset(L, 0, sizeof *L);
}

int pack_list_init(pack_list *L, const consph_particles *p, double radius)
{
    memset(L, 0, sizeof *L);
    if (p->n > INT32_MAX) /* the indices are 32-bit (signed for the vector gathers) */
        return consph_fail(CONSPH_EINVAL, "layout packing: %zu particles; at most %d", p->n,
                           INT32_MAX);
    L->dim = p->dim;
    L->n = p->n;
    L->radius = radius;
    for (int a = 0; a < p->dim; ++a) L->len[a] = consph_box_length(&p->box, a);
    int ok = (L->start = consph_calloc(p->n + 1, sizeof(size_t))) != NULL;
    for (int a = 0; a < p->dim; ++a)
        ok &= (L->x_ref[a] = consph_calloc(p->n, sizeof(double))) != NULL;
    if (!ok) {
        pack_list_free(L);
        return CONSPH_ENOMEM;
    }
    return CONSPH_OK;
}

/* Periodic image of the pair (i, j) that the search returned with separation dx: x_i - x_j - dx
 * is an integer number of box lengths. */
static int8_t image_of(double xi, double xj, double dx, double len)
{
    return (int8_t)lrint((xi - xj - dx) / len);
}

/* Fills list entries [L->start[i], L->start[i + 1]) of particle i, or counts them (fill = 0). */
static size_t list_particle(pack_list *L, const consph_nnps *grid, const consph_particles *p,
                            size_t i, consph_nbrs *nb, int fill)
{
    size_t m = consph_nnps_query_particle(grid, i, nb);
    if (m == (size_t)-1 || !fill) return m;
    const size_t b = L->start[i];
    for (size_t q = 0; q < m; ++q) {
        const size_t j = nb->j[q];
        L->j[b + q] = (uint32_t)j;
        for (int a = 0; a < L->dim; ++a)
            L->image[a][b + q] = image_of(p->x[a][i], p->x[a][j], nb->dx[a][q], L->len[a]);
    }
    return m;
}

int pack_list_build(pack_list *L, const consph_nnps *grid, const consph_particles *p)
{
    const size_t n = L->n;
    int failed = 0;
    /* Two walks of the search, counting then filling, so that each thread writes its own rows
     * of one array. */
    for (int fill = 0; fill < 2; ++fill) {
#pragma omp parallel if (n >= 2048)
        {
            consph_nbrs nb;
            memset(&nb, 0, sizeof nb);
#pragma omp for schedule(static)
            for (size_t i = 0; i < n; ++i) {
                size_t m = list_particle(L, grid, p, i, &nb, fill);
                if (m == (size_t)-1) {
#pragma omp atomic write
                    failed = 1;
                    m = 0;
                }
                if (!fill) L->start[i + 1] = m;
            }
            consph_nbrs_free(&nb);
        }
        if (failed) return CONSPH_ENOMEM;
        if (fill) break;
        L->start[0] = 0;
        L->max_len = 0;
        for (size_t i = 0; i < n; ++i) {
            if (L->start[i + 1] > L->max_len) L->max_len = L->start[i + 1];
            L->start[i + 1] += L->start[i];
        }
        const size_t entries = L->start[n];
        if (entries > L->cap) {
            size_t cap = entries + entries / 8;
            free(L->j);
            /* calloc: the slack past the entries holds valid indices (0) for vector reads */
            L->j = consph_calloc(cap + PACK_SLACK, sizeof *L->j);
            free(L->dwr);
            L->dwr = consph_calloc(cap + PACK_SLACK, sizeof *L->dwr);
            int ok = L->j != NULL && L->dwr != NULL;
            for (int a = 0; a < L->dim; ++a) {
                free(L->image[a]);
                ok &= (L->image[a] = consph_calloc(cap + PACK_SLACK, sizeof *L->image[a])) != NULL;
            }
            if (!ok) return CONSPH_ENOMEM;
            L->cap = cap;
        }
    }
    for (int a = 0; a < L->dim; ++a) memcpy(L->x_ref[a], p->x[a], n * sizeof(double));
    L->builds++;
    return CONSPH_OK;
}
