/* The packing's private neighbour list (a Verlet list): every particle's neighbours within the
 * kernel radius plus a skin, with the periodic image of each pair, kept over many steps while
 * the particles move by less than half the skin. The packing's motions per step are small
 * (at most a few percent of h once the first steps are past), so the search runs once in many
 * steps instead of every step; the pair sums then walk the list. Each row lists the entries
 * with j >= i first (search order within each part), and every pair j > i knows its mirror
 * entry in j's row, so that the packing evaluates the kernel once per pair
 * (layout_internal.h). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "layout/layout_internal.h"

void pack_list_free(pack_list *L)
{
    free(L->start);
    free(L->upper);
    free(L->j);
    free(L->mirror);
    free(L->w[0]);
    free(L->w[1]);
    free(L->dwr);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        free(L->image[a]);
        free(L->x_ref[a]);
    }
    memset(L, 0, sizeof *L);
}

int pack_list_init(pack_list *L, const consph_particles *p, double radius, int glass_w)
{
    memset(L, 0, sizeof *L);
    if (p->n > INT32_MAX) /* the indices are 32-bit (signed for the vector gathers) */
        return consph_fail(CONSPH_EINVAL, "layout packing: %zu particles; at most %d", p->n,
                           INT32_MAX);
    L->dim = p->dim;
    L->n = p->n;
    L->radius = radius;
    L->glass_w = glass_w;
    for (int a = 0; a < p->dim; ++a) L->len[a] = consph_box_length(&p->box, a);
    int ok = (L->start = consph_calloc(p->n + 1, sizeof(size_t))) != NULL;
    ok &= (L->upper = consph_calloc(p->n + 1, sizeof(uint32_t))) != NULL;
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

/* Fills list entries [L->start[i], L->start[i + 1]) of particle i, those with j >= i first, or
 * counts them (fill = 0). */
static size_t list_particle(pack_list *L, const consph_nnps *grid, const consph_particles *p,
                            size_t i, consph_nbrs *nb, int fill)
{
    size_t m = consph_nnps_query_particle(grid, i, nb);
    if (m == (size_t)-1 || !fill) return m;
    const size_t b = L->start[i];
    size_t up = 0;
    for (size_t q = 0; q < m; ++q) up += nb->j[q] >= i;
    size_t at_up = b, at_low = b + up;
    for (size_t q = 0; q < m; ++q) {
        const size_t j = nb->j[q];
        const size_t e = j >= i ? at_up++ : at_low++;
        L->j[e] = (uint32_t)j;
        for (int a = 0; a < L->dim; ++a)
            L->image[a][e] = image_of(p->x[a][i], p->x[a][j], nb->dx[a][q], L->len[a]);
    }
    L->upper[i] = (uint32_t)up;
    return m;
}

/* The mirrors of particle i's pairs j > i (the entry of j's row for i with the opposite image,
 * among the entries j lists with smaller indices; for the others the spare slot just past the
 * list's entries, within its slack), and zero kernel values in i's lower part,
 * for the entries that no pair's mirror writes. */
static void link_particle(pack_list *L, size_t i)
{
    const size_t b = L->start[i], up = b + L->upper[i];
    for (size_t e = b; e < up; ++e) {
        const size_t j = L->j[e];
        L->mirror[e] = (uint32_t)L->start[L->n];
        if (j == i) continue;
        for (size_t f = L->start[j] + L->upper[j]; f < L->start[j + 1]; ++f) {
            if (L->j[f] != i) continue;
            int opposite = 1;
            for (int a = 0; a < L->dim; ++a) opposite &= L->image[a][f] == -L->image[a][e];
            if (opposite) {
                L->mirror[e] = (uint32_t)f;
                break;
            }
        }
    }
    for (size_t e = up; e < L->start[i + 1]; ++e) {
        L->mirror[e] = (uint32_t)L->start[L->n];
        L->w[0][e] = 0.0;
        if (L->glass_w) L->w[1][e] = 0.0;
        L->dwr[e] = 0.0;
    }
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
        if (entries > PACK_MAX_ENTRIES)
            return consph_fail(CONSPH_EINVAL,
                               "layout packing: %zu neighbour-list entries; at most %zu", entries,
                               (size_t)PACK_MAX_ENTRIES);
        if (entries > L->cap) {
            size_t cap = entries + entries / 8;
            if (cap > PACK_MAX_ENTRIES) cap = entries;
            free(L->j);
            free(L->mirror);
            free(L->w[0]);
            free(L->w[1]);
            free(L->dwr);
            L->w[1] = NULL;
            /* calloc: the slack past the entries holds valid indices (0) for vector reads */
            L->j = consph_calloc(cap + PACK_SLACK, sizeof *L->j);
            L->mirror = consph_calloc(cap + PACK_SLACK, sizeof *L->mirror);
            L->w[0] = consph_calloc(cap + PACK_SLACK, sizeof *L->w[0]);
            if (L->glass_w) L->w[1] = consph_calloc(cap + PACK_SLACK, sizeof *L->w[1]);
            L->dwr = consph_calloc(cap + PACK_SLACK, sizeof *L->dwr);
            int ok = L->j != NULL && L->mirror != NULL && L->w[0] != NULL && L->dwr != NULL &&
                     (!L->glass_w || L->w[1] != NULL);
            for (int a = 0; a < L->dim; ++a) {
                free(L->image[a]);
                ok &= (L->image[a] = consph_calloc(cap + PACK_SLACK, sizeof *L->image[a])) != NULL;
            }
            if (!ok) return CONSPH_ENOMEM;
            L->cap = cap;
        }
    }
#pragma omp parallel for schedule(static) if (n >= 2048)
    for (size_t i = 0; i < n; ++i) link_particle(L, i);
    for (int a = 0; a < L->dim; ++a) memcpy(L->x_ref[a], p->x[a], n * sizeof(double));
    L->builds++;
    return CONSPH_OK;
}
