/* The packing's private neighbour list (a Verlet list): every particle's neighbours within the
 * kernel radius plus a skin, with the periodic image of each pair, kept over many steps while
 * the particles move by less than half the skin. The packing's motions per step are small
 * (at most a few percent of h once the first steps are past), so the search runs once in many
 * steps instead of every step; the pair sums then walk the list. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "layout/layout_internal.h"

/* A thread's entries of the build, for its contiguous range of particles from `first`, and those
 * of them with a periodic image (their index among the part's entries and the image's key).
 * Kept in the list from build to build: fresh buffers at every build cost a page fault per 4 KiB
 * (at 2D nx 500, 15 % of the time of the first 300 steps went to the kernel). */
struct pack_list_part {
    uint32_t *j;
    size_t len, cap, first;
    size_t *img_e;
    int32_t *img_key;
    size_t nimg, img_cap;
};

static void list_part_free(pack_list_part *t)
{
    free(t->j);
    free(t->img_e);
    free(t->img_key);
    memset(t, 0, sizeof *t);
}

void pack_list_free(pack_list *L)
{
    free(L->start);
    free(L->j_lo);
    free(L->j_hi);
    free(L->j);
    free(L->dwr);
    free(L->ghost_src);
    free(L->ghost_key);
    free(L->ghost_head);
    free(L->ghost_next);
    free(L->xv);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(L->x_ref[a]);
    for (int t = 0; t < L->nparts; ++t) list_part_free(&L->parts[t]);
    free(L->parts);
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
    ok &= (L->ghost_head = consph_calloc(p->n, sizeof(int32_t))) != NULL;
    ok &= (L->j_lo = consph_calloc(p->n, sizeof(uint32_t))) != NULL;
    ok &= (L->j_hi = consph_calloc(p->n, sizeof(uint32_t))) != NULL;
    for (int a = 0; a < p->dim; ++a)
        ok &= (L->x_ref[a] = consph_calloc(p->n, sizeof(double))) != NULL;
    if (!ok) {
        pack_list_free(L);
        return CONSPH_ENOMEM;
    }
    return CONSPH_OK;
}

/* Periodic image of the pair (i, j) that the search returned with separation dx: x_i - x_j - dx
 * is an integer number of box lengths up to round-off, so rounding t to the nearest integer
 * (half away from zero, by truncation) gives it whatever the rounding rule. */
static inline int8_t image_of(double xi, double xj, double dx, double inv_len)
{
    const double t = (xi - xj - dx) * inv_len;
    return (int8_t)(t < 0.0 ? t - 0.5 : t + 0.5);
}

/* Room for `need` entries and `need_img` of them with an image; 0 when out of memory. */
static int list_part_reserve(pack_list_part *t, size_t need, size_t need_img)
{
    if (need > t->cap) {
        size_t cap = need + need / 2 + 256;
        uint32_t *j = realloc(t->j, cap * sizeof *j);
        if (!j) return 0;
        t->j = j;
        t->cap = cap;
    }
    if (need_img > t->img_cap) {
        size_t cap = need_img + need_img / 2 + 256;
        size_t *e = realloc(t->img_e, cap * sizeof *e);
        if (e) t->img_e = e;
        int32_t *key = realloc(t->img_key, cap * sizeof *key);
        if (key) t->img_key = key;
        if (!e || !key) return 0;
        t->img_cap = cap;
    }
    return 1;
}

static inline int image_of_key(int32_t key, int a)
{
    return (int8_t)(uint8_t)((uint32_t)key >> (8 * a));
}

/* Room for `rows` rows of xv (and the ghosts' arrays for rows - n of them). */
static int reserve_rows(pack_list *L, size_t ghosts)
{
    if (ghosts > L->ghost_cap) {
        size_t cap = ghosts + ghosts / 4 + 16;
        uint32_t *src = realloc(L->ghost_src, cap * sizeof *src);
        if (src) L->ghost_src = src;
        int32_t *key = realloc(L->ghost_key, cap * sizeof *key);
        if (key) L->ghost_key = key;
        int32_t *next = realloc(L->ghost_next, cap * sizeof *next);
        if (next) L->ghost_next = next;
        if (!src || !key || !next) return CONSPH_ENOMEM;
        L->ghost_cap = cap;
    }
    const size_t rows = L->n + L->ghost_cap + PACK_SLACK;
    if (rows > L->xv_rows) {
        free(L->xv);
        const size_t bytes = rows * PACK_XV_STRIDE * sizeof(double); /* a multiple of 32 */
        L->xv = aligned_alloc(32, bytes);
        if (!L->xv) {
            L->xv_rows = 0;
            return CONSPH_ENOMEM;
        }
        memset(L->xv, 0, bytes); /* the slack rows hold finite values for vector reads */
        L->xv_rows = rows;
    }
    return CONSPH_OK;
}

/* Points entry e, whose image has the key `key`, at the ghost of its (j, image), created if new. */
static int assign_ghost(pack_list *L, size_t e, int32_t key)
{
    const size_t n = L->n;
    const uint32_t j = L->j[e];
    int32_t g = L->ghost_head[j];
    while (g >= 0 && L->ghost_key[g] != key) g = L->ghost_next[g];
    if (g < 0) {
        if (n + L->n_ghost >= (size_t)INT32_MAX)
            return consph_fail(CONSPH_EINVAL, "layout packing: too many periodic images");
        int rc = reserve_rows(L, L->n_ghost + 1);
        if (rc) return rc;
        g = (int32_t)L->n_ghost++;
        L->ghost_src[g] = j;
        L->ghost_key[g] = key;
        L->ghost_next[g] = L->ghost_head[j];
        L->ghost_head[j] = g;
    }
    L->j[e] = (uint32_t)(n + (size_t)g);
    return CONSPH_OK;
}

/* Points every entry with a non-zero image at the ghost of its (j, image), creating the ghosts
 * in the order the entries first name them (the parts in particle order). */
static int assign_ghosts(pack_list *L, int nparts)
{
    const size_t n = L->n;
    for (size_t i = 0; i < n; ++i) L->ghost_head[i] = -1;
    L->n_ghost = 0;
    for (int t = 0; t < nparts; ++t) {
        const pack_list_part *pt = &L->parts[t];
        if (pt->len == 0) continue;
        for (size_t k = 0; k < pt->nimg; ++k) {
            const size_t e = L->start[pt->first] + pt->img_e[k];
            const int rc = assign_ghost(L, e, pt->img_key[k]);
            if (rc) return rc;
        }
    }
    return reserve_rows(L, L->n_ghost);
}

int pack_list_build(pack_list *L, const consph_nnps *grid, const consph_particles *p)
{
    const size_t n = L->n;
    const int dim = L->dim;
    double inv_len[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
    for (int a = 0; a < dim; ++a) inv_len[a] = 1.0 / L->len[a];
    const double margin = 1.01 * L->radius;
#ifdef _OPENMP
    const int max_threads = omp_get_max_threads();
#else
    const int max_threads = 1;
#endif
    if (max_threads > L->nparts) {
        pack_list_part *parts = realloc(L->parts, (size_t)max_threads * sizeof *parts);
        if (!parts) return CONSPH_ENOMEM;
        memset(parts + L->nparts, 0, (size_t)(max_threads - L->nparts) * sizeof *parts);
        L->parts = parts;
        L->nparts = max_threads;
    }
    int failed = 0, nparts = 1;
    /* One walk of the search: each thread lists its contiguous range of particles into its own
     * buffer, then copies it to its place in the list once the counts give the offsets. */
#pragma omp parallel if (n >= 2048)
    {
        consph_nbrs nb;
        memset(&nb, 0, sizeof nb);
#ifdef _OPENMP
        pack_list_part *t = &L->parts[omp_get_thread_num()];
#pragma omp single
        nparts = omp_get_num_threads();
#else
        pack_list_part *t = &L->parts[0];
#endif
        t->len = 0;
        t->nimg = 0;
        t->first = n;
#pragma omp for schedule(static)
        for (size_t i = 0; i < n; ++i) {
            if (t->first == n) t->first = i;
            size_t m = consph_nnps_query_particle(grid, i, &nb);
            if (m == (size_t)-1 || !list_part_reserve(t, t->len + m, t->nimg + m)) {
#pragma omp atomic write
                failed = 1;
                m = 0;
            }
            /* A particle farther than the search radius from every face of the box (the
             * positions are wrapped into it at the builds) has no neighbour across a face: every
             * image is 0, as image_of would find. */
            int interior = 1;
            for (int a = 0; a < dim; ++a) {
                const double x = p->x[a][i];
                interior &= x - p->box.lo[a] > margin && p->box.lo[a] + L->len[a] - x > margin;
            }
            size_t lo = i, hi = i;
            for (size_t q = 0; q < m; ++q) {
                const size_t j = nb.j[q];
                lo = j < lo ? j : lo;
                hi = j > hi ? j : hi;
                t->j[t->len + q] = (uint32_t)j;
                if (interior) continue;
                /* the image as one key, a byte per axis (0: the box itself) */
                uint32_t key = 0;
                for (int a = 0; a < dim; ++a)
                    key |=
                        (uint32_t)(uint8_t)image_of(p->x[a][i], p->x[a][j], nb.dx[a][q], inv_len[a])
                        << (8 * a);
                if (key) {
                    t->img_e[t->nimg] = t->len + q;
                    t->img_key[t->nimg++] = (int32_t)key;
                }
            }
            t->len += m;
            L->start[i + 1] = m;
            L->j_lo[i] = (uint32_t)lo;
            L->j_hi[i] = (uint32_t)hi;
        }
#pragma omp single
        {
            if (!failed) {
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
                    /* calloc: the slack past the entries holds valid indices (0) for vector
                     * reads */
                    L->j = consph_calloc(cap + PACK_SLACK, sizeof *L->j);
                    free(L->dwr);
                    L->dwr = consph_calloc(cap + PACK_SLACK, sizeof *L->dwr);
                    const int ok = L->j != NULL && L->dwr != NULL;
                    L->cap = ok ? cap : 0;
                    if (!ok) failed = 1;
                }
            }
        }
        if (!failed && t->len > 0) memcpy(L->j + L->start[t->first], t->j, t->len * sizeof *t->j);
        consph_nbrs_free(&nb);
    }
    if (failed) return CONSPH_ENOMEM;
    int rc = assign_ghosts(L, nparts);
    if (rc) return rc;
    for (int a = 0; a < L->dim; ++a) memcpy(L->x_ref[a], p->x[a], n * sizeof(double));
    L->rows_current = 0;
    L->builds++;
    return CONSPH_OK;
}

void pack_list_fill_range(pack_list *L, const consph_particles *p, size_t r0, size_t r1)
{
    const size_t n = L->n;
    const int dim = L->dim;
    double *restrict xv = L->xv;
    for (size_t r = r0; r < r1; ++r) {
        if (r < n) {
            for (int a = 0; a < dim; ++a) xv[PACK_XV_STRIDE * r + (size_t)a] = p->x[a][r];
        } else {
            const size_t g = r - n, src = L->ghost_src[g];
            for (int a = 0; a < dim; ++a)
                xv[PACK_XV_STRIDE * r + (size_t)a] =
                    p->x[a][src] + (double)image_of_key(L->ghost_key[g], a) * L->len[a];
        }
    }
}

void pack_list_fill_positions(pack_list *L, const consph_particles *p)
{
    const size_t rows = L->n + L->n_ghost, first = L->rows_current ? L->n : 0;
    const size_t blocks = (rows - first + 1023) / 1024;
#pragma omp parallel for schedule(static) if (rows - first >= 2048)
    for (size_t k = 0; k < blocks; ++k) {
        const size_t r0 = first + 1024 * k;
        pack_list_fill_range(L, p, r0, r0 + 1024 < rows ? r0 + 1024 : rows);
    }
}

void pack_list_fill_ghost_weights(pack_list *L)
{
    const size_t n = L->n;
    double *restrict xv = L->xv;
    for (size_t g = 0; g < L->n_ghost; ++g)
        xv[PACK_XV_STRIDE * (n + g) + PACK_XV_WEIGHT] =
            xv[PACK_XV_STRIDE * (size_t)L->ghost_src[g] + PACK_XV_WEIGHT];
}
