/* Passes over groups of particles (group.h): the traversal of consph_pass_run_counted (pass.c),
 * handing the neighbourhoods of up to PASS_GROUP consecutive particles of a cell to one visit.
 *
 * A visit that sums one particle's neighbours in their order has one chain of dependent
 * additions per sum; a group visit runs the chains of several particles side by side in the
 * lanes of a vector, each lane adding its own particle's terms in that particle's neighbour
 * order, so the sums are those of the per-particle visit bit for bit. Each neighbourhood is
 * gathered and its kernel values evaluated exactly as pass.c does, into one scratch per lane. */
#include "pass/group.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef CONSPH_HAVE_OPENMP
#include <omp.h>
#endif

#include "nnps/nnps_internal.h"
#include "pass/lanes4.h"
#include "pass/nbhd.h"
#include "pass/nlist.h"

/* The neighbourhoods of the group's count particles in slots g.. of one cell: a whole group in
 * one sweep over the cell's candidates where the gather has one (nbhd_gather4), else particle by
 * particle; the same values in the same order either way. */
static void gather_group(const consph_sys *s, const consph_nnps_slots *v,
                         const consph_nnps_runs *runs, size_t g, int count, unsigned need,
                         int with_dx, nbhd_scratch *sc, consph_nbhd *nb)
{
    if (count == PASS_GROUP && nbhd_gather4(s, v, runs, g, need, with_dx, sc, nb)) return;
    for (int l = 0; l < count; ++l)
        nbhd_gather(s, v, runs, g + (size_t)l, need, with_dx, &sc[l], &nb[l]);
}

/* Entries n..kmax of a lane: the particle itself (self: its index, or its slot under
 * PASS_GROUP_SLOTS) with zero separation and kernel values. */
static void lane_pad(nbhd_scratch *sc, const consph_nbhd *nb, size_t kmax, size_t self)
{
    size_t *j = (size_t *)nb->j;
    for (size_t p = nb->n; p < kmax; ++p) {
        j[p] = self;
        for (int a = 0; a < CONSPH_MAX_DIM; ++a)
            if (nb->dx[a]) sc->dx[a][p] = 0.0;
        sc->r[p] = sc->w[p] = sc->dwr[p] = sc->d2w[p] = 0.0;
    }
}

unsigned long pass_group_runs = 0;

/* The next group of a cell's slots [*g, last): the cell in fours; under a mask (dest non-NULL)
 * up to four consecutive destinations, *g moved past the sources before them. 0: none left. */
static int group_next(const unsigned char *dest, const consph_nnps_slots *v, size_t *g, size_t last)
{
    if (dest)
        while (*g < last && !dest[consph_nnps_slot_particle(v, *g)]) ++*g;
    if (*g >= last) return 0;
    int count = last - *g < PASS_GROUP ? (int)(last - *g) : PASS_GROUP;
    if (dest) {
        int run = 1;
        while (run < count && dest[consph_nnps_slot_particle(v, *g + (size_t)run)]) ++run;
        count = run;
    }
    return count;
}

int pass_run_groups(const consph_sys *s, const char *name, unsigned need, pass_group_fn visit,
                    void *job, size_t *pairs)
{
    if (!s || !s->p || !s->nnps || !visit || s->kernel.tensor) return PASS_GROUP_UNSERVED;
    /* A decomposed system refreshes its halo first, on every rank whatever it decides below
     * (the refresh is collective); where it declines, the per-particle pass finds the system
     * refreshed and does not refresh again. */
    consph_sys *const sw = (consph_sys *)s;
    if (s->split) {
        const int rc = pass_halo_refresh(sw);
        if (rc != CONSPH_OK) return rc;
    }
    const size_t n = s->p->n;
    if (n == 0) {
        sw->halo_fresh = 0;
        return CONSPH_OK;
    }
    consph_nnps_slots v;
    if (consph_nnps_slots_get(s->nnps, &v) != CONSPH_OK || v.n != n) return PASS_GROUP_UNSERVED;
    if (s->nlist && nlist_serves(s->nlist, n)) {
        if (need & PASS_GROUP_UNPADDED) {
            if (need & PASS_GROUP_SLOTS) return PASS_GROUP_UNSERVED;
            int ran;
            const int st = nlist_group_run(s, name, need, visit, job, pairs, &ran);
            if (st != CONSPH_OK || ran > 0) {
                sw->halo_fresh = 0;
                if (st == CONSPH_OK) __atomic_fetch_add(&pass_group_runs, 1, __ATOMIC_RELAXED);
                return st;
            }
            if (ran < 0) return PASS_GROUP_UNSERVED;
        } else if (!nlist_gathers(s->nlist)) {
            /* a list that serves this pass from its cache or its own filter: the per-particle
             * pass */
            return PASS_GROUP_UNSERVED;
        }
    }
    sw->halo_fresh = 0; /* this pass reads the halo as refreshed; its visits write fields */
    const unsigned char *dest = s->dest;
    need &= ~PASS_GROUP_UNPADDED;
    const int with_dx = !(need & CONSPH_PASS_NO_DX), slots = (need & PASS_GROUP_SLOTS) != 0;
    __atomic_fetch_add(&pass_group_runs, 1, __ATOMIC_RELAXED);
    int status = CONSPH_OK;
    char why[256] = "";
    size_t total = 0;
    const size_t chunk = pass_cells_per_chunk(v.ncells);
    (void)chunk; /* read by the OpenMP schedule alone */
#pragma omp parallel if (n >= s->parallel_min)
    {
        consph_nnps_runs runs;
        memset(&runs, 0, sizeof runs);
        nbhd_scratch sc[PASS_GROUP];
        memset(sc, 0, sizeof sc);
        int my_status = CONSPH_OK;
        char my_why[256] = "";
        size_t my_pairs = 0;
#pragma omp for schedule(dynamic, chunk)
        for (size_t c = 0; c < v.ncells; ++c) {
            const size_t first = v.cell_start[c], last = v.cell_start[c + 1];
            if (first == last || my_status != CONSPH_OK) continue;
            if (dest) {
                /* a cell of sources only (the halo's) needs no runs */
                size_t s_dest = first;
                while (s_dest < last && !dest[consph_nnps_slot_particle(&v, s_dest)]) ++s_dest;
                if (s_dest == last) continue;
            }
            if (consph_nnps_cell_runs(s->nnps, c, &runs) == (size_t)-1) {
                my_status = CONSPH_ENOMEM;
                snprintf(my_why, sizeof my_why, "runs of cell %zu: %s", c, consph_last_error());
                continue;
            }
            for (int l = 0; l < PASS_GROUP && my_status == CONSPH_OK; ++l)
                if (nbhd_scratch_reserve(&sc[l], runs.candidates + CONSPH_NNPS_GATHER_SLACK) !=
                    CONSPH_OK) {
                    my_status = CONSPH_ENOMEM;
                    snprintf(my_why, sizeof my_why, "out of memory for %zu candidate neighbours",
                             runs.candidates);
                }
            if (my_status != CONSPH_OK) continue;
            size_t g = first;
            for (int count; (count = group_next(dest, &v, &g, last)) > 0;) {
                consph_nbhd nb[PASS_GROUP];
                size_t kmax = 0;
                gather_group(s, &v, &runs, g, count, need, with_dx, sc, nb);
                for (int l = 0; l < count; ++l) {
                    my_pairs += nb[l].n;
                    if (nb[l].n > kmax) kmax = nb[l].n;
                }
                for (int l = 0; l < count; ++l)
                    lane_pad(&sc[l], &nb[l], kmax, slots ? g + (size_t)l : nb[l].i);
                for (int l = count; l < PASS_GROUP; ++l) nb[l] = nb[0];
                visit(job, nb, count);
                g += (size_t)count;
            }
        }
#pragma omp critical(consph_pass_run_groups)
        {
            total += my_pairs;
            if (my_status != CONSPH_OK && (status == CONSPH_OK || my_status < status)) {
                status = my_status;
                memcpy(why, my_why, sizeof why);
            }
        }
        consph_nnps_runs_free(&runs);
        for (int l = 0; l < PASS_GROUP; ++l) nbhd_scratch_free(&sc[l]);
    }
    if (pairs) *pairs += total;
    if (status != CONSPH_OK)
        return consph_fail(status, "pass '%s': %s", name ? name : "unnamed", why);
    return CONSPH_OK;
}

/* ---- two passes in one sweep (pass_run_groups2) ----
 *
 * The cells are cut into slabs: the cells of one index along the outermost axis of the grid
 * (nnps.c numbers cells with that axis slowest, so a slab is a contiguous range of cells and of
 * slots). A particle's neighbours lie in the slabs within `lag` (the search's reach along that
 * axis) of its own, modulo the period. Each thread takes a band of consecutive slabs:
 *   1. the first pass on the band's lag edge slabs at each end (other bands' second pass reads
 *      them), gathered as pass_run_groups does it; then a barrier;
 *   2. one sweep over the band: the first pass on interior slab t, its neighbourhoods gathered
 *      with the kernel values of both passes and kept, and the second pass on slab t - lag,
 *      whose neighbours' first pass is then done (interior slabs from the kept neighbourhoods,
 *      edge slabs gathered again).
 * A neighbourhood is the same whichever pass gathers it (the gather's hits and r do not depend
 * on which outputs it writes; the kernel batch's W and W'/r loop gives the separate loops'
 * values), and each visit writes its own particles only, so the results are those of two
 * pass_run_groups calls bit for bit for any thread count. Only lag + 1 slabs of
 * neighbourhoods are kept per thread. */

/* Above this lag (slabs thinner than the radius / 8) every slab is an edge slab: no ring. */
#define GROUP2_MAX_LAG 8

typedef struct group_rec {
    int count;
    size_t i[PASS_GROUP], n[PASS_GROUP], off[PASS_GROUP];
} group_rec;

/* The kept neighbourhoods of one slab's groups, as the second pass reads them. The gather writes
 * straight into it: lane l of a group at used + l·stride (stride: the cell's candidates and the
 * gather's slack), each lane's entries running to the group's kmax (the padding included); the
 * next group starts after the last lane's kmax entries. The gaps are never touched. */
typedef struct slab_store {
    group_rec *rec;
    size_t nrec, rec_cap;
    size_t *slot, *j;
    double *dx[CONSPH_MAX_DIM], *r, *w, *dwr, *d2w;
    size_t used, cap;
} slab_store;

static void store_free(slab_store *st)
{
    free(st->rec);
    free(st->slot);
    free(st->j);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(st->dx[a]);
    free(st->r);
    free(st->w);
    free(st->dwr);
    free(st->d2w);
    memset(st, 0, sizeof *st);
}

/* Each thread's ring of slabs, kept from one call to the next so that its pages stay mapped
 * (allocating megabytes per pass cost more in page faults than the gathers it saves), and freed
 * when the thread ends. */
static void ring_free(void *p)
{
    slab_store *ring = p;
    for (int k = 0; k <= GROUP2_MAX_LAG; ++k) store_free(&ring[k]);
    free(ring);
}

#if !defined(__STDC_NO_THREADS__)
#include <threads.h>
static tss_t ring_key;
static once_flag ring_once = ONCE_FLAG_INIT;
static int ring_key_made;
static void ring_key_make(void)
{
    ring_key_made = tss_create(&ring_key, ring_free) == thrd_success;
}
static slab_store *thread_ring(void)
{
    call_once(&ring_once, ring_key_make);
    if (!ring_key_made) return NULL;
    slab_store *ring = tss_get(ring_key);
    if (!ring) {
        ring = calloc(GROUP2_MAX_LAG + 1, sizeof *ring);
        if (ring && tss_set(ring_key, ring) != thrd_success) {
            free(ring);
            ring = NULL;
        }
    }
    return ring;
}
#else
/* without C11 threads: kept for the thread's life (the library starts no threads itself) */
static _Thread_local slab_store ring_of_thread[GROUP2_MAX_LAG + 1];
static slab_store *thread_ring(void)
{
    (void)ring_free;
    return ring_of_thread;
}
#endif

unsigned long pass_group_kept_slabs = 0;

static int grow_array(void **p, size_t count, size_t size)
{
    void *q = realloc(*p, count * size);
    if (!q) return CONSPH_ENOMEM;
    *p = q;
    return CONSPH_OK;
}

typedef struct sweep {
    const consph_sys *s;
    const consph_nnps_slots *v;
    void *job;
    unsigned need1, need2, need12;
    int dx1, dx2, dx12; /* the passes' separations wanted */
    int il;             /* PASS_GROUP_INTERLEAVED in need2 */
    pass_group_fn visit1, visit2;
    /* a decomposed system: each cell's CELL_* (NULL: every cell CELL_DEEP); late: the second
     * pass on the CELL_NEAR and CELL_MIXED cells, after the sweep */
    const unsigned char *cls;
    int late;
} sweep;

/* A cell of a decomposed system: the halo's (sources only: no pass), one whose candidates are
 * all the rank's own (both passes in the sweep), one of the rank's whose candidates reach the
 * halo (the second pass after the refresh that brings the first's values there), or one that
 * holds both (particles drift across cells between re-sorts, their owners fixed): as a near one,
 * its own particles alone visited. */
enum { CELL_DEEP = 0, CELL_HALO = 1, CELL_NEAR = 2, CELL_MIXED = 3 };

typedef struct sweep_thread {
    consph_nnps_runs runs;
    nbhd_scratch sc[PASS_GROUP];
    slab_store one; /* under il: a group gathered for the second pass alone, interleaved */
    size_t pairs, kept;
    int status;
    char why[256];
} sweep_thread;

/* Room for `need` more entries and one more group in st (the arrays the second pass reads). */
static int store_reserve(slab_store *st, size_t need)
{
    if (st->nrec == st->rec_cap) {
        const size_t cap = st->rec_cap ? 2 * st->rec_cap : 256;
        if (grow_array((void **)&st->rec, cap, sizeof *st->rec)) return CONSPH_ENOMEM;
        st->rec_cap = cap;
    }
    need += st->used;
    if (need <= st->cap) return CONSPH_OK;
    size_t cap = st->cap ? st->cap : 4096;
    while (cap < need) cap *= 2;
    /* every array, whatever this pass reads: the ring serves the thread's later calls too */
    int e = grow_array((void **)&st->slot, cap, sizeof(size_t));
    e = e ? e : grow_array((void **)&st->j, cap, sizeof(size_t));
    for (int a = 0; a < CONSPH_MAX_DIM; ++a)
        e = e ? e : grow_array((void **)&st->dx[a], cap, sizeof(double));
    e = e ? e : grow_array((void **)&st->r, cap, sizeof(double));
    e = e ? e : grow_array((void **)&st->w, cap, sizeof(double));
    e = e ? e : grow_array((void **)&st->dwr, cap, sizeof(double));
    e = e ? e : grow_array((void **)&st->d2w, cap, sizeof(double));
    if (e == CONSPH_OK) st->cap = cap;
    return e;
}

/* n 8-byte words (doubles or size_t), in blocks of four: a lane's few hundred bytes cost a
 * library memcpy more in its call and dispatch than in the copy. Reads and writes up to three
 * words past n: the lane scratch has that slack, and the store's room is reserved with it (the
 * words are overwritten by the next lane, or never read). */
static inline void copy_words(void *dst, const void *src, size_t n)
{
    char *d = dst;
    const char *s = src;
    for (size_t k = 0; k < n; k += 4) __builtin_memcpy(d + 8 * k, s + 8 * k, 32);
}

/* Keeps the group's neighbourhoods nb[0..count) (entries to kmax) in st, compactly: copying
 * from the lane's scratch, hot in the cache, costs less than gathering into the store's spread
 * lanes, which the second pass then reads from further away. */
static void store_group(const sweep *w, slab_store *st, const consph_nbhd *nb, int count,
                        size_t kmax)
{
    group_rec *rec = &st->rec[st->nrec++];
    rec->count = count;
    for (int l = 0; l < count; ++l) {
        const size_t off = st->used;
        rec->i[l] = nb[l].i;
        rec->n[l] = nb[l].n;
        rec->off[l] = off;
        copy_words(st->slot + off, nb[l].j, kmax);
        for (int a = 0; a < w->v->dim && w->dx2; ++a)
            copy_words(st->dx[a] + off, nb[l].dx[a], kmax);
        copy_words(st->r + off, nb[l].r, kmax);
        if (w->need2 & CONSPH_PASS_W) copy_words(st->w + off, nb[l].w, kmax);
        if (w->need2 & (CONSPH_PASS_DW | CONSPH_PASS_D2W))
            copy_words(st->dwr + off, nb[l].dwr, kmax);
        if (w->need2 & CONSPH_PASS_D2W) copy_words(st->d2w + off, nb[l].d2w, kmax);
        st->used += kmax;
    }
}

/* n entries of the four lanes' 8-byte words src[l] (doubles or size_t) into dst interleaved:
 * entry k of lane l at dst[4k + l]. Four entries at a time, a 4×4 transpose: reads up to three
 * words past n (the lane scratch has the slack) and writes those entries' words (reserved, and
 * never read). */
#if defined(CONSPH_LANES4)
typedef long long lane4w __attribute__((vector_size(4 * sizeof(long long)), aligned(8), may_alias));
static inline __attribute__((always_inline)) void
interleave_words(void *dst, const void *const src[PASS_GROUP], size_t n)
{
    lane4w *d = dst;
    const char *s0 = src[0], *s1 = src[1], *s2 = src[2], *s3 = src[3];
    for (size_t k = 0; k < n; k += 4) {
        const lane4i a0 = *(const lane4w *)(s0 + 8 * k), a1 = *(const lane4w *)(s1 + 8 * k);
        const lane4i a2 = *(const lane4w *)(s2 + 8 * k), a3 = *(const lane4w *)(s3 + 8 * k);
        LANE4_TRANSPOSE(lane4i, a0, a1, a2, a3, d + k);
    }
}
#define STORE_CLONES LANE4_CLONES
#else
static inline void interleave_words(void *dst, const void *const src[PASS_GROUP], size_t n)
{
    for (size_t k = 0; k < n; ++k)
        for (int l = 0; l < PASS_GROUP; ++l)
            memcpy((char *)dst + 8 * (PASS_GROUP * k + (size_t)l), (const char *)src[l] + 8 * k, 8);
}
#define STORE_CLONES
#endif

/* store_group for a second visit that reads the entries interleaved (PASS_GROUP_INTERLEAVED):
 * the transposition the visit would do is done here instead, in the one copy. All four lanes
 * (nb[count..) repeat nb[0]), to kmax rounded up to whole vectors. Copies for AVX2 and AVX-512
 * as the visits' (a copy: the same bits in any). */
STORE_CLONES static void store_group_il(const sweep *w, slab_store *st, const consph_nbhd *nb,
                                        int count, size_t kmax)
{
    group_rec *rec = &st->rec[st->nrec++];
    const size_t off = st->used;
    rec->count = count;
    for (int l = 0; l < PASS_GROUP; ++l) {
        rec->i[l] = nb[l].i;
        rec->n[l] = nb[l].n;
        rec->off[l] = off + (size_t)l;
    }
#define IL(dst, field)                                                                             \
    do {                                                                                           \
        const void *const q_[PASS_GROUP] = {nb[0].field, nb[1].field, nb[2].field, nb[3].field};   \
        interleave_words((dst) + off, q_, kmax);                                                   \
    } while (0)
    IL(st->slot, j);
    for (int a = 0; a < w->v->dim && w->dx2; ++a) IL(st->dx[a], dx[a]);
    IL(st->r, r);
    if (w->need2 & CONSPH_PASS_W) IL(st->w, w);
    if (w->need2 & (CONSPH_PASS_DW | CONSPH_PASS_D2W)) IL(st->dwr, dwr);
    if (w->need2 & CONSPH_PASS_D2W) IL(st->d2w, d2w);
#undef IL
    st->used += PASS_GROUP * ((kmax + 3) & ~(size_t)3);
}

/* Room store_group or store_group_il takes for a group of count lanes to kmax. */
static size_t store_need(const sweep *w, int count, size_t kmax)
{
    return w->il ? PASS_GROUP * ((kmax + 3) & ~(size_t)3) + 4 : (size_t)count * kmax + 4;
}

/* The second pass over the groups kept in st. */
static void store_replay(const sweep *w, const slab_store *st)
{
    const size_t *j = st->slot;
    for (size_t g = 0; g < st->nrec; ++g) {
        const group_rec *rec = &st->rec[g];
        consph_nbhd nb[PASS_GROUP];
        /* lanes past count repeat lane 0 (interleaved, the store holds all four) */
        const int lanes = w->il ? PASS_GROUP : rec->count;
        for (int l = 0; l < PASS_GROUP; ++l) {
            const int q = l < lanes ? l : 0;
            const size_t off = rec->off[q];
            nb[l].i = rec->i[q];
            nb[l].n = rec->n[q];
            nb[l].j = j + off;
            for (int a = 0; a < CONSPH_MAX_DIM; ++a)
                nb[l].dx[a] = w->dx2 && a < w->v->dim ? st->dx[a] + off : NULL;
            nb[l].r = st->r + off;
            nb[l].w = w->need2 & CONSPH_PASS_W ? st->w + off : NULL;
            nb[l].dwr = w->need2 & (CONSPH_PASS_DW | CONSPH_PASS_D2W) ? st->dwr + off : NULL;
            nb[l].d2w = w->need2 & CONSPH_PASS_D2W ? st->d2w + off : NULL;
        }
        w->visit2(w->job, nb, rec->count);
    }
}

enum { SLAB_FIRST = 1, SLAB_SECOND = 2, SLAB_BOTH = 3 };

/* One cell's groups: the first pass, the second, or the first keeping the neighbourhoods (with
 * both passes' kernel values) in st for the second. */
static void run_cell(const sweep *w, sweep_thread *t, size_t c, int mode, slab_store *st)
{
    if (t->status != CONSPH_OK) return;
    if (w->cls) {
        const int cls = w->cls[c];
        if (cls == CELL_HALO || (cls != CELL_DEEP && mode == SLAB_SECOND && !w->late)) return;
        /* kept for no second pass in the sweep */
        if (cls != CELL_DEEP && mode == SLAB_BOTH) mode = SLAB_FIRST;
    }
    const unsigned char *dest = w->cls && w->cls[c] == CELL_MIXED ? w->s->dest : NULL;
    const consph_nnps_slots *v = w->v;
    const unsigned need = mode == SLAB_FIRST    ? w->need1
                          : mode == SLAB_SECOND ? w->need2
                                                : w->need12;
    const int with_dx = mode == SLAB_FIRST ? w->dx1 : mode == SLAB_SECOND ? w->dx2 : w->dx12;
    const size_t per_pair = mode == SLAB_BOTH ? 2 : 1;
    const int slots = (need & PASS_GROUP_SLOTS) != 0;
    {
        const size_t first = v->cell_start[c], last = v->cell_start[c + 1];
        if (first == last) return;
        if (consph_nnps_cell_runs(w->s->nnps, c, &t->runs) == (size_t)-1) {
            t->status = CONSPH_ENOMEM;
            snprintf(t->why, sizeof t->why, "runs of cell %zu: %s", c, consph_last_error());
            return;
        }
        /* the gather's slack, and the kernel batch's rounding up to whole vectors */
        const size_t stride = t->runs.candidates + CONSPH_NNPS_GATHER_SLACK + 4;
        for (int l = 0; l < PASS_GROUP; ++l)
            if (nbhd_scratch_reserve(&t->sc[l], stride) != CONSPH_OK) {
                t->status = CONSPH_ENOMEM;
                snprintf(t->why, sizeof t->why, "out of memory for %zu candidate neighbours",
                         t->runs.candidates);
                return;
            }
        size_t g = first;
        for (int count; (count = group_next(dest, v, &g, last)) > 0; g += (size_t)count) {
            consph_nbhd nb[PASS_GROUP];
            size_t kmax = 0;
            gather_group(w->s, v, &t->runs, g, count, need, with_dx, t->sc, nb);
            for (int l = 0; l < count; ++l) {
                t->pairs += per_pair * nb[l].n;
                if (nb[l].n > kmax) kmax = nb[l].n;
            }
            for (int l = 0; l < count; ++l)
                lane_pad(&t->sc[l], &nb[l], kmax, slots ? g + (size_t)l : nb[l].i);
            for (int l = count; l < PASS_GROUP; ++l) nb[l] = nb[0];
            if (mode == SLAB_SECOND && !w->il) {
                w->visit2(w->job, nb, count);
                continue;
            }
            if (mode == SLAB_SECOND) {
                st = &t->one;
                st->nrec = st->used = 0;
            } else {
                w->visit1(w->job, nb, count);
            }
            if (mode != SLAB_FIRST) {
                if (store_reserve(st, store_need(w, count, kmax)) != CONSPH_OK) {
                    t->status = CONSPH_ENOMEM;
                    snprintf(t->why, sizeof t->why, "out of memory keeping %zu neighbours",
                             (size_t)count * kmax);
                    return;
                }
                if (w->il)
                    store_group_il(w, st, nb, count, kmax);
                else
                    store_group(w, st, nb, count, kmax);
            }
            if (mode == SLAB_SECOND) store_replay(w, st);
        }
    }
}

/* Cells of a tile-slab (the cells of slab y with axis-0 index in [x0, x1), every index on the
 * axes between) that a call runs: all, the edge columns (within lag0 of the strip's ends, where
 * a neighbour may lie in another strip) or the others. */
enum { CELLS_ALL, CELLS_EDGE, CELLS_INNER };

typedef struct tiling {
    size_t nc0, middle, nslabs; /* cells along axis 0, between, along the outermost axis */
    size_t lag0, lag;           /* the search's reach along axis 0 and the outermost axis */
    size_t nstrips;
} tiling;

static void strip_range(const tiling *tl, size_t strip, size_t *x0, size_t *x1)
{
    *x0 = tl->nc0 * strip / tl->nstrips;
    *x1 = tl->nc0 * (strip + 1) / tl->nstrips;
}

static void run_tile(const sweep *w, const tiling *tl, sweep_thread *t, size_t strip, size_t y,
                     int which, int mode, slab_store *st)
{
    size_t x0, x1;
    strip_range(tl, strip, &x0, &x1);
    const int whole = tl->nstrips == 1; /* axis-0 neighbours wrap into the same strip */
    for (size_t m = 0; m < tl->middle; ++m) {
        const size_t base = tl->nc0 * (m + tl->middle * y);
        for (size_t x = x0; x < x1; ++x) {
            const int edge = !whole && (x < x0 + tl->lag0 || x + tl->lag0 >= x1);
            if ((which == CELLS_EDGE && !edge) || (which == CELLS_INNER && edge)) continue;
            run_cell(w, t, base + x, mode, st);
        }
    }
}

/* A tile-slab's ring entries stay below this many neighbour entries (about 40 bytes each), so
 * that the ring stays in a core's cache; above it the passes run as two plain sweeps. */
#define GROUP2_RING_ENTRIES (1u << 17)
/* Strips of about this many cells along axis 0: a ring of lag + 1 tile-slabs of 2D Taylor-Green
 * (13 particles and ~45 neighbours per cell, kept interleaved: four lanes a group, the last of a
 * cell's padded) then takes ~0.7 MB. 16 cells (~0.9 MB interleaved) made the gathers beside it
 * miss the core's 1 MB L2 on the test machine: tvf nx 250 serial, gather4 +25 % of samples. */
size_t pass_group2_strip_cells = 12;

unsigned long pass_group2_split = 0, pass_group2_deferred = 0;

/* Each cell's CELL_* on a decomposed system (*cls, ncells bytes): its particles all sources
 * (CELL_HALO), both (CELL_MIXED) or all the rank's own, then CELL_DEEP where every candidate of
 * its walk (consph_nnps_cell_runs) is the rank's own, else CELL_NEAR. */
static int cell_classes(const consph_sys *s, const consph_nnps_slots *v, unsigned char **cls)
{
    const size_t n = v->n;
    *cls = NULL;
    /* sources before each slot, so that a run's are a difference */
    size_t *src = malloc((n + 1) * sizeof *src);
    unsigned char *c = malloc(v->ncells ? v->ncells : 1);
    consph_nnps_runs runs;
    memset(&runs, 0, sizeof runs);
    int st =
        src && c ? CONSPH_OK : consph_fail(CONSPH_ENOMEM, "out of memory for the cells' kinds");
    if (st == CONSPH_OK) {
        src[0] = 0;
        for (size_t sl = 0; sl < n; ++sl)
            src[sl + 1] = src[sl] + !s->dest[consph_nnps_slot_particle(v, sl)];
    }
    for (size_t k = 0; st == CONSPH_OK && k < v->ncells; ++k) {
        const size_t first = v->cell_start[k], last = v->cell_start[k + 1];
        const size_t sources = src[last] - src[first];
        if (sources == last - first && first < last) {
            c[k] = CELL_HALO;
            continue;
        }
        if (sources) {
            c[k] = CELL_MIXED;
            continue;
        }
        c[k] = CELL_DEEP;
        if (first == last) continue;
        if (consph_nnps_cell_runs(s->nnps, k, &runs) == (size_t)-1) {
            st = consph_fail(CONSPH_ENOMEM, "runs of cell %zu: %s", k, consph_last_error());
            break;
        }
        for (size_t r = 0; r < runs.n; ++r)
            if (src[runs.run[r].s1] != src[runs.run[r].s0]) {
                c[k] = CELL_NEAR;
                break;
            }
    }
    consph_nnps_runs_free(&runs);
    free(src);
    if (st != CONSPH_OK) {
        free(c);
        return st;
    }
    *cls = c;
    return CONSPH_OK;
}

int pass_run_groups2(const consph_sys *s, const char *name1, unsigned need1, pass_group_fn visit1,
                     const char *name2, unsigned need2, pass_group_fn visit2, void *job,
                     size_t *pairs, int (*prepare2)(consph_sys *s, void *ctx), void *ctx)
{
    /* A mask without a split is declined; so is a decomposed system without prepare2, which
     * alone can bring the first pass's values into the halo before the second reads them. */
    const int split = s && s->split && s->dest;
    if (!s || !s->p || !s->nnps || !visit1 || !visit2 || (s->dest && !split) ||
        (split && !prepare2) || s->kernel.tensor || ((need1 ^ need2) & PASS_GROUP_SLOTS))
        return PASS_GROUP_UNSERVED;
    consph_sys *const sw = (consph_sys *)s;
    const size_t n = s->p->n;
    if (n == 0 && split) {
        sw->halo_fresh = 0;
        const int st = prepare2(sw, ctx);
        sw->halo_fresh = 0; /* as after the second pass */
        return st;
    }
    if (n == 0) return CONSPH_OK;
    consph_nnps_slots v;
    if (consph_nnps_slots_get(s->nnps, &v) != CONSPH_OK || v.n != n) return PASS_GROUP_UNSERVED;

    int64_t nc[CONSPH_MAX_DIM], reach[CONSPH_MAX_DIM];
    double edge[CONSPH_MAX_DIM];
    nnps_grid(s->nnps, nc, reach, edge);
    int outer = 0;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a)
        if (nc[a] > 1) outer = a;
    tiling tl = {(size_t)nc[0], 1, (size_t)nc[outer], 0, 0, 1};
    for (int a = 1; a < outer; ++a) tl.middle *= (size_t)nc[a];
    tl.lag0 = reach[0] > 0 ? (size_t)reach[0] : 0;
    tl.lag = reach[outer] > 0 ? (size_t)reach[outer] : 0;
    if (outer == 0 || tl.nc0 * tl.middle * tl.nslabs != v.ncells) {
        /* one slab, every cell an edge: the two passes one after the other */
        tl.nc0 = v.ncells;
        tl.middle = tl.nslabs = 1;
        tl.lag = 1;
    }
    const size_t strip_cells = pass_group2_strip_cells ? pass_group2_strip_cells : 1;
    tl.nstrips = (tl.nc0 + strip_cells / 2) / strip_cells;
    if (tl.nstrips < 1) tl.nstrips = 1;
    /* neighbour entries of one tile-slab, at ~π/9 (2D) or ~π/20 (3D) of the candidates */
    const double per_cell = (double)n / (double)v.ncells;
    double cand = per_cell;
    for (int a = 0; a < v.dim; ++a) cand *= (double)(2 * reach[a] + 1);
    const double entries = per_cell * cand * (v.dim == 2 ? 0.35 : 0.16) *
                           (double)(tl.nc0 / tl.nstrips + 1) * (double)tl.middle;
    if (tl.lag > GROUP2_MAX_LAG || (double)(tl.lag + 1) * entries > GROUP2_RING_ENTRIES)
        tl.lag = tl.nslabs; /* every slab an edge slab: no ring */
    /* A decomposed system without a ring (3D: the slabs' neighbourhoods too many to keep) gains
     * nothing over the passes one by one and would visit its later cells' groups interleaved:
     * measured 3-9 % slower a step (Beltrami edac nx 46, 2 ranks). */
    if (split && tl.lag >= tl.nslabs) return PASS_GROUP_UNSERVED;
    unsigned char *cls = NULL;
    if (split) {
        const int st = cell_classes(s, &v, &cls);
        if (st != CONSPH_OK) return st;
    }
    if (s->nlist && nlist_serves(s->nlist, n)) {
        if (!nlist_gathers(s->nlist)) {
            free(cls);
            return PASS_GROUP_UNSERVED;
        }
        (void)nlist_gathers(s->nlist); /* the second pass, counted as run too */
    }
    __atomic_fetch_add(&pass_group_runs, 2, __ATOMIC_RELAXED);

    const int il = (need2 & PASS_GROUP_INTERLEAVED) != 0;
    need2 &= ~PASS_GROUP_INTERLEAVED;
    sweep w = {s, &v, job, need1, need2, 0, 0, 0, 0, il, visit1, visit2, cls, 0};
    w.dx1 = !(need1 & CONSPH_PASS_NO_DX);
    w.dx2 = !(need2 & CONSPH_PASS_NO_DX);
    w.dx12 = w.dx1 || w.dx2;
    w.need12 = (need1 | need2) & (CONSPH_PASS_W | CONSPH_PASS_DW | CONSPH_PASS_D2W);
    w.need12 |= need1 & PASS_GROUP_SLOTS;
    const size_t lag = tl.lag, nslabs = tl.nslabs;

    int status = CONSPH_OK;
    char why[256] = "";
    const char *failed = name1;
    size_t total = 0;
#pragma omp parallel if (n >= s->parallel_min)
    {
        sweep_thread t;
        memset(&t, 0, sizeof t);
        slab_store *ring = lag < nslabs ? thread_ring() : NULL;
        if (lag < nslabs && !ring) {
            t.status = CONSPH_ENOMEM;
            snprintf(t.why, sizeof t.why, "out of memory for the ring of kept neighbourhoods");
        }
        /* 1. the first pass on every cell another tile's second pass reads: the edge slabs and
         * the edge columns */
#pragma omp for schedule(dynamic, 1)
        for (size_t strip = 0; strip < tl.nstrips; ++strip)
            for (size_t y = 0; y < nslabs; ++y) {
                const int yedge = y < lag || y + lag >= nslabs;
                run_tile(&w, &tl, &t, strip, y, yedge ? CELLS_ALL : CELLS_EDGE, SLAB_FIRST, NULL);
            }
        const int first_status = t.status;
        /* 2. each strip's sweep: the first pass on the inner cells of tile-slab tt, kept; the
         * second on tile-slab tt - lag, whose neighbours' first pass is then done */
#pragma omp for schedule(dynamic, 1)
        for (size_t strip = 0; strip < tl.nstrips; ++strip)
            for (size_t tt = 0; tt < nslabs + lag && t.status == CONSPH_OK; ++tt) {
                if (tt >= lag && tt + lag < nslabs) {
                    slab_store *st = &ring[tt % (lag + 1)];
                    st->nrec = st->used = 0;
                    run_tile(&w, &tl, &t, strip, tt, CELLS_INNER, SLAB_BOTH, st);
                }
                if (tt < lag) continue;
                const size_t y = tt - lag;
                if (y < lag || y + lag >= nslabs) {
                    run_tile(&w, &tl, &t, strip, y, CELLS_ALL, SLAB_SECOND, NULL);
                } else {
                    run_tile(&w, &tl, &t, strip, y, CELLS_EDGE, SLAB_SECOND, NULL);
                    if (t.status == CONSPH_OK) store_replay(&w, &ring[y % (lag + 1)]);
                    ++t.kept;
                }
            }
#pragma omp critical(consph_pass_run_groups)
        {
            total += t.pairs;
            pass_group_kept_slabs += t.kept;
            if (t.status != CONSPH_OK && (status == CONSPH_OK || t.status < status)) {
                status = t.status;
                failed = first_status != CONSPH_OK ? name1 : name2;
                memcpy(why, t.why, sizeof why);
            }
        }
        consph_nnps_runs_free(&t.runs);
        for (int l = 0; l < PASS_GROUP; ++l) nbhd_scratch_free(&t.sc[l]);
        store_free(&t.one);
    }
    if (split) {
        /* the first pass's values into the halo (a refresh: every rank makes it, as the passes
         * one by one would, whatever happened here), then the second pass where the sweep left
         * it */
        sw->halo_fresh = 0;
        const int st = prepare2(sw, ctx);
        sw->halo_fresh = 0;
        if (status == CONSPH_OK && st != CONSPH_OK) {
            free(cls);
            return st;
        }
        w.late = 1;
        const size_t chunk = pass_cells_per_chunk(v.ncells);
        (void)chunk; /* read by the OpenMP schedule alone */
        size_t left = 0;
        if (status == CONSPH_OK)
#pragma omp parallel reduction(+ : left) if (n >= s->parallel_min)
        {
            sweep_thread t;
            memset(&t, 0, sizeof t);
#pragma omp for schedule(dynamic, chunk)
            for (size_t c = 0; c < v.ncells; ++c)
                if (cls[c] == CELL_NEAR || cls[c] == CELL_MIXED) {
                    const size_t before = t.pairs;
                    run_cell(&w, &t, c, SLAB_SECOND, NULL);
                    left += t.pairs != before;
                }
#pragma omp critical(consph_pass_run_groups)
            {
                total += t.pairs;
                if (t.status != CONSPH_OK && (status == CONSPH_OK || t.status < status)) {
                    status = t.status;
                    failed = name2;
                    memcpy(why, t.why, sizeof why);
                }
            }
            consph_nnps_runs_free(&t.runs);
            for (int l = 0; l < PASS_GROUP; ++l) nbhd_scratch_free(&t.sc[l]);
            store_free(&t.one);
        }
        __atomic_fetch_add(&pass_group2_deferred, left, __ATOMIC_RELAXED);
        __atomic_fetch_add(&pass_group2_split, 1, __ATOMIC_RELAXED);
        free(cls);
    }
    if (pairs) *pairs += total;
    if (status != CONSPH_OK)
        return consph_fail(status, "pass '%s': %s", failed ? failed : "unnamed", why);
    return CONSPH_OK;
}
