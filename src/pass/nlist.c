/* The neighbour list with a skin and the pair-geometry cache (include/consph/pass.h,
 * consph_sys_nlist).
 *
 * Layout: the sorted slots of the search are cut into blocks of NLIST_BLOCK consecutive slots;
 * each block owns its candidates (particle j as uint32 and the periodic image as one code) and
 * its cached pairs (j, x_ij, r and the kernel values), each slot a contiguous range. Blocks are
 * filled independently (any thread, any order) and every particle's range is a function of the
 * build alone, so nothing depends on the thread count; no prefix sum over all particles is
 * needed and a block's arrays are kept (grown, never shrunk) from one cache to the next.
 *
 * Candidates come from consph_nnps_gather, one run at a time so that each hit knows its image
 * shift; their order is the gather's. The cache filters them by r² < radius² with
 *   x_ij = (u_i - shift) - u_j,  u = (positions at the build) + (displacement since),
 * the operations of the gather in its order (consph_nnps_scan_run), so on the build's own
 * positions (skin 0 always) it reproduces the gather's neighbours and values bit for bit. */
#include "pass/nlist.h"
#include "nnps/nnps_internal.h"
#include "pass/group.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#if defined(__x86_64__) && defined(__SSE2__)
#include <emmintrin.h>
#define NLIST_SSE2 1
#endif

#define NLIST_BLOCK 64
/* Passes on the previous position state from which a state's pairs are cached. */
#define NLIST_CACHE_PASSES 3
/* Image index per axis in [-NLIST_IMAGE_MAX, NLIST_IMAGE_MAX], 4 bits per axis in a code. */
#define NLIST_IMAGE_MAX 7
/* The candidate radius is widened by this much (skin > 0 only), so that rounding in the
 * distances and displacements cannot lose a pair at the edge of the skin. */
#define NLIST_MARGIN 1e-9

typedef struct nlist_block {
    size_t s0, s1;
    size_t *coff; /* s1 - s0 + 1 offsets into cj, cimg */
    uint32_t *cj;
    uint16_t *cimg;
    size_t ccap;
    size_t *poff; /* s1 - s0 + 1 offsets into the cache */
    size_t *pj;
    double *pdx[CONSPH_MAX_DIM], *pr, *pw, *pdwr, *pd2w;
    size_t pcap;
    size_t slo, shi; /* the slots of every candidate of the last cache_block_gather */
} nlist_block;

struct consph_nlist {
    double skin, radius, radius2, trigger2;
    char field[64]; /* the build positions' field; "" keeps them in xb_own */
    int dim, off;
    size_t n;
    size_t *particle; /* slot -> particle; NULL: the identity */
    /* particle's storage, kept while the list holds the identity: a step's re-sort leaves the
     * identity and its later builds do not, and allocating it again at each step gave fresh
     * pages where n size_t pass glibc's mmap threshold */
    size_t *particle_buf, particle_cap;
    double *xb_own; /* dim × n */
    double *u;      /* dim × n */
    double len[CONSPH_MAX_DIM];
    int periodic[CONSPH_MAX_DIM];
    double shift_of[CONSPH_MAX_DIM][2 * NLIST_IMAGE_MAX + 1];
    size_t nblocks;
    nlist_block *blocks;
    unsigned long epoch, cache_epoch;
    unsigned have; /* CONSPH_PASS_W / DW / D2W values in the cache */
    /* passes run on this position state and on the one before (whether a cache pays) */
    unsigned long state_epoch;
    int passes_state, passes_last;
    /* consph_sys_expect_passes: the state (epoch) it was given for, how many passes and the
     * kernel values they need together */
    unsigned long hint_epoch;
    int hint_passes;
    unsigned hint_need;
    size_t builds, caches, ncand, npairs;
    /* the pairs a cache of the current state would hold (the last cache's count, else a sample
     * at the build: pairs_estimate) and the bytes the cache may take (pair_cache_budget) */
    size_t est_pairs;
    /* a decomposed system's chain: which passes its sweep ran at each particle (chain_state) */
    unsigned char *done;
    size_t done_cap;
    double budget;
    char note[200];
};

static void block_free(nlist_block *b)
{
    free(b->coff);
    free(b->cj);
    free(b->cimg);
    free(b->poff);
    free(b->pj);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(b->pdx[a]);
    free(b->pr);
    free(b->pw);
    free(b->pdwr);
    free(b->pd2w);
    memset(b, 0, sizeof *b);
}

static void free_arrays(consph_nlist *l)
{
    for (size_t k = 0; k < l->nblocks; ++k) block_free(&l->blocks[k]);
    free(l->blocks);
    free(l->particle_buf);
    free(l->xb_own);
    free(l->u);
    free(l->done);
    l->done = NULL;
    l->done_cap = 0;
    l->blocks = NULL;
    l->nblocks = 0;
    l->particle = l->particle_buf = NULL;
    l->particle_cap = 0;
    l->xb_own = l->u = NULL;
    l->n = 0;
}

void nlist_free(consph_nlist *l)
{
    if (!l) return;
    free_arrays(l);
    free(l);
}

static int grow(void **p, size_t count, size_t size)
{
    void *q = realloc(*p, (count ? count : 1) * size);
    if (!q) return CONSPH_ENOMEM;
    *p = q;
    return CONSPH_OK;
}

static int cand_reserve(nlist_block *b, size_t need)
{
    if (need <= b->ccap) return CONSPH_OK;
    size_t cap = b->ccap + b->ccap / 2;
    if (cap < need) cap = need;
    int st = grow((void **)&b->cj, cap, sizeof(uint32_t));
    st = st ? st : grow((void **)&b->cimg, cap, sizeof(uint16_t));
    if (st == CONSPH_OK) b->ccap = cap;
    return st;
}

/* Room for `need` cached pairs plus the padding of the kernel batch. */
static int pair_reserve(nlist_block *b, int dim, size_t need)
{
    need += 4;
    if (need <= b->pcap) return CONSPH_OK;
    size_t cap = b->pcap + b->pcap / 4;
    if (cap < need) cap = need;
    int st = grow((void **)&b->pj, cap, sizeof(size_t));
    for (int a = 0; a < dim; ++a) st = st ? st : grow((void **)&b->pdx[a], cap, sizeof(double));
    st = st ? st : grow((void **)&b->pr, cap, sizeof(double));
    /* Kernel values are (re)allocated when first asked for (values_reserve). */
    if (st == CONSPH_OK) {
        if (b->pw) st = grow((void **)&b->pw, cap, sizeof(double));
        if (!st && b->pdwr) st = grow((void **)&b->pdwr, cap, sizeof(double));
        if (!st && b->pd2w) st = grow((void **)&b->pd2w, cap, sizeof(double));
    }
    if (st == CONSPH_OK) b->pcap = cap;
    return st;
}

static int values_reserve(nlist_block *b, unsigned want)
{
    int st = CONSPH_OK;
    if ((want & CONSPH_PASS_W) && !b->pw) st = grow((void **)&b->pw, b->pcap, sizeof(double));
    if (!st && (want & CONSPH_PASS_DW) && !b->pdwr)
        st = grow((void **)&b->pdwr, b->pcap, sizeof(double));
    if (!st && (want & CONSPH_PASS_D2W) && !b->pd2w)
        st = grow((void **)&b->pd2w, b->pcap, sizeof(double));
    return st;
}

/* The positions of the last build: axis a of particle i at xb[a * stride + i]. */
static double *build_positions(consph_sys *s, size_t *stride)
{
    consph_nlist *l = s->nlist;
    if (!l->field[0]) {
        *stride = l->n;
        return l->xb_own;
    }
    double *f = consph_particles_field(s->p, l->field, s->p->dim);
    *stride = s->p->cap;
    return f;
}

static inline size_t particle_of(const consph_nlist *l, size_t slot)
{
    return l->particle ? l->particle[slot] : slot;
}

/* The candidates of one block's slots from the search just built. */
static int index_block(const consph_sys *s, const consph_nnps_slots *v, nlist_block *b,
                       consph_nnps_runs *runs, size_t **slot, double **r, size_t *cap, char *why,
                       size_t why_size)
{
    const consph_nlist *l = s->nlist;
    const int dim = v->dim;
    /* the cell of the block's first slot: cell_start[c] <= s0 < cell_start[c + 1] */
    size_t lo = 0, hi = v->ncells;
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        if (v->cell_start[mid] <= b->s0)
            lo = mid;
        else
            hi = mid;
    }
    size_t c = lo, runs_cell = (size_t)-1, used = 0;
    for (size_t sl = b->s0; sl < b->s1; ++sl) {
        while (sl >= v->cell_start[c + 1]) ++c;
        if (c != runs_cell) {
            if (consph_nnps_cell_runs(s->nnps, c, runs) == (size_t)-1) {
                snprintf(why, why_size, "runs of cell %zu: %s", c, consph_last_error());
                return CONSPH_ENOMEM;
            }
            runs_cell = c;
            const size_t need = runs->candidates + CONSPH_NNPS_GATHER_SLACK;
            if (need > *cap) {
                if (grow((void **)slot, need, sizeof(size_t)) ||
                    grow((void **)r, need, sizeof(double))) {
                    snprintf(why, why_size, "out of memory for %zu candidates", need);
                    return CONSPH_ENOMEM;
                }
                *cap = need;
            }
        }
        b->coff[sl - b->s0] = used;
        if (cand_reserve(b, used + runs->candidates)) {
            snprintf(why, why_size, "out of memory for the neighbour list");
            return CONSPH_ENOMEM;
        }
        double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        for (int a = 0; a < dim; ++a) xi[a] = v->x[a][sl];
        for (size_t k = 0; k < runs->n; ++k) {
            const consph_nnps_run *run = &runs->run[k];
            consph_nnps_runs one = {1, 1, (consph_nnps_run *)run, run->s1 - run->s0};
            const size_t m = consph_nnps_gather(v, &one, xi, *slot, NULL, *r);
            unsigned code = 0;
            for (int a = 0; a < dim; ++a) {
                const double q = l->periodic[a] ? run->shift[a] / l->len[a] : 0.0;
                const long img = lround(q);
                if (labs(img) > NLIST_IMAGE_MAX) {
                    snprintf(why, why_size,
                             "the radius spans more than %d periodic images of axis %d",
                             NLIST_IMAGE_MAX, a);
                    return CONSPH_EINVAL;
                }
                code |= (unsigned)(img + NLIST_IMAGE_MAX) << (4 * a);
            }
            for (size_t p = 0; p < m; ++p) {
                b->cj[used] = (uint32_t)consph_nnps_slot_particle(v, (*slot)[p]);
                b->cimg[used] = (uint16_t)code;
                ++used;
            }
        }
    }
    b->coff[b->s1 - b->s0] = used;
    return CONSPH_OK;
}

/* ---- the pair cache's memory budget ---- */

static int node_processes = 1;

void nlist_node_processes(int count)
{
    node_processes = count > 0 ? count : 1;
}

/* Bytes the pair cache may take in this process: CONSPH_PAIR_CACHE_MB where set, else half the
 * machine's physical memory shared by the processes on this node (MPI ranks on one machine
 * each keep their own cache). */
static int pair_cache_budget(double *bytes)
{
    const char *v = getenv("CONSPH_PAIR_CACHE_MB");
    if (v && *v) {
        char *end = NULL;
        const double mb = strtod(v, &end);
        while (end && (*end == ' ' || *end == '\t')) ++end;
        if (!end || end == v || *end || !isfinite(mb) || mb < 0.0)
            return consph_fail(CONSPH_EINVAL,
                               "CONSPH_PAIR_CACHE_MB '%s': expected the pair cache's budget in "
                               "megabytes, a number >= 0 (0: never cache the pairs)",
                               v);
        *bytes = mb * 1048576.0;
        return CONSPH_OK;
    }
    const long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGE_SIZE);
    *bytes = pages > 0 && size > 0 ? 0.5 * (double)pages * (double)size / node_processes : HUGE_VAL;
    return CONSPH_OK;
}

/* Bytes per cached pair: j, x_ij, r and the kernel values (those cached so far, at least W and
 * W'/r, which most passes read). */
static double pair_bytes(const consph_nlist *l)
{
    int values =
        !!(l->have & CONSPH_PASS_W) + !!(l->have & CONSPH_PASS_DW) + !!(l->have & CONSPH_PASS_D2W);
    if (values < 2) values = 2;
    return (double)sizeof(size_t) + sizeof(double) * (double)(l->dim + 1 + values);
}

static int cache_over_budget(const consph_nlist *l)
{
    return (double)l->est_pairs * pair_bytes(l) > l->budget;
}

/* The pairs a cache of the state just built would hold, before any cache was filled: the
 * neighbours of the first destination of every block, times the block's destinations. Integer
 * counts from the build alone (any thread count gives the same); about 1/64 of a pass's gather,
 * so it is taken again only where the last state had passes enough to want a cache. */
static int pairs_estimate(const consph_sys *s, const consph_nnps_slots *v)
{
    consph_nlist *l = s->nlist;
    if (l->caches) {
        l->est_pairs = l->npairs;
        return CONSPH_OK;
    }
    if (l->builds && l->passes_state < 2) return CONSPH_OK;
    size_t est = 0;
    int st = CONSPH_OK;
    /* on the threads: an integer sum, the same in any order */
#pragma omp parallel reduction(+ : est) if (v->n >= s->parallel_min)
    {
        consph_nnps_runs runs;
        memset(&runs, 0, sizeof runs);
        size_t *slot = NULL, cap = 0;
        int my_st = CONSPH_OK;
#pragma omp for schedule(static)
        for (size_t k = 0; k < l->nblocks; ++k) {
            if (my_st != CONSPH_OK) continue;
            const nlist_block *b = &l->blocks[k];
            size_t dests = 0, first = b->s1;
            for (size_t sl = b->s0; sl < b->s1; ++sl)
                if (!s->dest || s->dest[particle_of(l, sl)]) {
                    if (!dests++) first = sl;
                }
            if (!dests) continue;
            double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
            for (int a = 0; a < l->dim; ++a) xi[a] = v->x[a][first];
            if (consph_nnps_point_runs(s->nnps, xi, &runs) == (size_t)-1) {
                my_st = CONSPH_ENOMEM;
                continue;
            }
            const size_t need = runs.candidates + CONSPH_NNPS_GATHER_SLACK;
            if (need > cap) {
                if (grow((void **)&slot, need, sizeof(size_t))) {
                    my_st = CONSPH_ENOMEM;
                    continue;
                }
                cap = need;
            }
            est += dests * consph_nnps_gather(v, &runs, xi, slot, NULL, NULL);
        }
        consph_nnps_runs_free(&runs);
        free(slot);
        if (my_st != CONSPH_OK) {
#pragma omp atomic write
            st = my_st;
        }
    }
    l->est_pairs = est;
    return st;
}

/* Turns the list off for good (the passes gather from here on) with a note saying why, and
 * gives the search back its own radius. */
static int switch_off(consph_sys *s, const char *why)
{
    consph_nlist *l = s->nlist;
    snprintf(l->note, sizeof l->note, "%s", why);
    size_t stride;
    double *xb = build_positions(s, &stride);
    /* a restart from these particles must not resume a list the run no longer keeps */
    if (xb && l->field[0])
        for (int a = 0; a < s->p->dim; ++a)
            for (size_t i = 0; i < s->p->n; ++i) xb[a * stride + i] = NAN;
    free_arrays(l);
    l->off = 1;
    if (consph_nnps_radius(s->nnps) != l->radius) {
        consph_nnps *g = consph_nnps_create(&s->p->box, l->radius, 0);
        if (!g) return CONSPH_ENOMEM;
        consph_nnps_free(s->nnps);
        s->nnps = g;
    }
    return consph_nnps_build(s->nnps, s->p);
}

/* The list from the search just built on the current positions. */
static int nlist_index(consph_sys *s)
{
    consph_nlist *l = s->nlist;
    consph_nnps_slots v;
    if (consph_nnps_slots_get(s->nnps, &v) != CONSPH_OK) return CONSPH_EINVAL;
    const size_t n = v.n;
    const int dim = v.dim;
    if ((uint64_t)n > (uint64_t)INT32_MAX)
        return switch_off(s, "the neighbour list holds particle indices as 31 bits; more "
                             "particles than that: the passes gather");
    if (n != l->n || !l->u) {
        /* The blocks that remain keep their candidate and pair buffers: an MPI rank's particle
         * count changes at every re-sort (src/par/par_solver.c), and growing them again from
         * nothing each time copied more than the passes computed. */
        const size_t nb = (n + NLIST_BLOCK - 1) / NLIST_BLOCK, sz = (size_t)dim * (n ? n : 1);
        for (size_t k = nb; k < l->nblocks; ++k) block_free(&l->blocks[k]);
        if (nb < l->nblocks) l->nblocks = nb;
        if (grow((void **)&l->blocks, nb, sizeof(nlist_block))) return CONSPH_ENOMEM;
        memset(l->blocks + l->nblocks, 0, (nb - l->nblocks) * sizeof(nlist_block));
        l->nblocks = nb;
        l->n = 0; /* until every array below has its size */
        if (grow((void **)&l->u, sz, sizeof(double))) return CONSPH_ENOMEM;
        if (!l->field[0] && grow((void **)&l->xb_own, sz, sizeof(double))) return CONSPH_ENOMEM;
        for (size_t k = 0; k < l->nblocks; ++k) {
            nlist_block *b = &l->blocks[k];
            b->s0 = k * NLIST_BLOCK;
            b->s1 = b->s0 + NLIST_BLOCK < n ? b->s0 + NLIST_BLOCK : n;
            if (!b->coff) b->coff = malloc((NLIST_BLOCK + 1) * sizeof(size_t));
            if (!b->poff) b->poff = malloc((NLIST_BLOCK + 1) * sizeof(size_t));
            if (!b->coff || !b->poff) return CONSPH_ENOMEM;
        }
        l->n = n;
    }
    if (v.particle) {
        if (n > l->particle_cap) {
            l->particle = NULL;
            if (grow((void **)&l->particle_buf, n, sizeof(size_t))) return CONSPH_ENOMEM;
            l->particle_cap = n;
        }
        l->particle = l->particle_buf;
        memcpy(l->particle, v.particle, n * sizeof(size_t));
    } else {
        l->particle = NULL;
    }
    if (l->skin == 0.0) {
        /* rebuilt at every move: the search itself is the list (cache_block_gather) */
        if (pairs_estimate(s, &v)) return CONSPH_ENOMEM;
        ++l->builds;
        ++l->epoch;
        return CONSPH_OK;
    }
    size_t stride;
    double *xb = build_positions(s, &stride);
    if (!xb) return CONSPH_ENOMEM;
    for (int a = 0; a < dim; ++a)
        for (size_t sl = 0; sl < n; ++sl) {
            const size_t i = particle_of(l, sl);
            xb[(size_t)a * stride + i] = l->u[(size_t)a * n + i] = v.x[a][sl];
        }
    int status = CONSPH_OK;
    char why[200] = "";
#pragma omp parallel if (n >= s->parallel_min)
    {
        consph_nnps_runs runs;
        memset(&runs, 0, sizeof runs);
        size_t *slot = NULL, cap = 0;
        double *r = NULL;
        int my_status = CONSPH_OK;
        char my_why[200] = "";
#pragma omp for schedule(dynamic, 1)
        for (size_t k = 0; k < l->nblocks; ++k)
            if (my_status == CONSPH_OK)
                my_status = index_block(s, &v, &l->blocks[k], &runs, &slot, &r, &cap, my_why,
                                        sizeof my_why);
#pragma omp critical(consph_nlist_index)
        if (my_status != CONSPH_OK && (status == CONSPH_OK || my_status < status)) {
            status = my_status;
            memcpy(why, my_why, sizeof why);
        }
        consph_nnps_runs_free(&runs);
        free(slot);
        free(r);
    }
    if (status == CONSPH_EINVAL) return switch_off(s, why);
    if (status != CONSPH_OK) return consph_fail(status, "neighbour list: %s", why);
    size_t total = 0;
    for (size_t k = 0; k < l->nblocks; ++k)
        total += l->blocks[k].coff[l->blocks[k].s1 - l->blocks[k].s0];
    l->ncand = total;
    if (pairs_estimate(s, &v)) return CONSPH_ENOMEM;
    ++l->builds;
    ++l->epoch;
    if (n && (double)total / (double)n > CONSPH_NLIST_MAX_CANDIDATES) {
        char note[200];
        snprintf(note, sizeof note,
                 "%.0f candidate neighbours per particle, above the list's budget of %d: the "
                 "passes gather (O(N) memory)",
                 (double)total / (double)n, CONSPH_NLIST_MAX_CANDIDATES);
        return switch_off(s, note);
    }
    return CONSPH_OK;
}

/* u = build positions + displacement since the build (the nearest periodic image of it);
 * *max_d2: the largest squared displacement, *changed: whether any u changed. */
static int nlist_displace(consph_sys *s, double *max_d2, int *changed)
{
    consph_nlist *l = s->nlist;
    const consph_particles *p = s->p;
    const size_t n = l->n;
    const int dim = l->dim;
    size_t stride;
    const double *xb = build_positions(s, &stride);
    if (!xb) return CONSPH_ENOMEM;
    double m2 = 0.0;
    int ch = 0;
#pragma omp parallel for schedule(static) reduction(max                                            \
                                                    : m2)                                          \
    reduction(|                                                                                    \
              : ch) if (n >= s->parallel_min)
    for (size_t i = 0; i < n; ++i) {
        double d2 = 0.0;
        for (int a = 0; a < dim; ++a) {
            const double b = xb[(size_t)a * stride + i];
            double d = p->x[a][i] - b;
            if (l->periodic[a]) {
                if (d > 0.5 * l->len[a])
                    d -= l->len[a];
                else if (d < -0.5 * l->len[a])
                    d += l->len[a];
            }
            const double u = b + d;
            double *ua = &l->u[(size_t)a * n + i];
            ch |= !(*ua == u);
            *ua = u;
            d2 += d * d;
        }
        /* NaN counts as a move beyond the skin: the rebuild then fails as a search would */
        if (!(d2 <= m2)) m2 = isnan(d2) ? INFINITY : d2;
    }
    *max_d2 = m2;
    *changed = ch;
    return CONSPH_OK;
}

int nlist_serves(const consph_nlist *l, size_t n)
{
    return !l->off && l->n == n;
}

static int rebuild_search(consph_sys *s, int resort)
{
    if (!resort) return consph_nnps_build(s->nnps, s->p);
    size_t *perm = sys_resort_buffer(s, s->p->n); /* every entry written by the sort */
    if (!perm) return CONSPH_ENOMEM;
    int rc = consph_nnps_sort(s->nnps, s->p, perm);
    if (rc == CONSPH_OK) rc = sys_carry_permutation(s, perm);
    return rc;
}

int nlist_update(consph_sys *s, int resort)
{
    consph_nlist *l = s->nlist;
    if (l->off) return rebuild_search(s, resort);
    if (s->p->n != l->n) {
        int rc = rebuild_search(s, resort);
        return rc ? rc : nlist_index(s);
    }
    if (l->skin == 0.0) {
        /* the search's own schedule, as without a list */
        int rc = rebuild_search(s, resort);
        return rc ? rc : nlist_index(s);
    }
    double max_d2;
    int changed;
    int rc = nlist_displace(s, &max_d2, &changed);
    if (rc) return rc;
    if (max_d2 > l->trigger2) {
        rc = rebuild_search(s, resort);
        return rc ? rc : nlist_index(s);
    }
    if (changed) ++l->epoch;
    return CONSPH_OK;
}

/* ---- the cache ---- */

/* Where one slot's filtered pairs go. */
typedef struct pair_out {
    size_t *j;
    double *d[CONSPH_MAX_DIM], *r;
} pair_out;

/* The candidates of slot sl (of block b) within the radius, appended from entry `used` of o;
 * r holds r² on return. Every candidate is written and the count advances only on a hit, so o
 * needs room for used + (the slot's candidates). */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline size_t
filter_slot(const consph_nlist *l, const nlist_block *b, size_t sl, pair_out o, size_t used)
{
    const int dim = l->dim;
    const size_t n = l->n;
    const double r2max = l->radius2;
    const double *u0 = l->u, *u1 = dim > 1 ? l->u + n : NULL, *u2 = dim > 2 ? l->u + 2 * n : NULL;
    const double *t0 = l->shift_of[0], *t1 = l->shift_of[1], *t2 = l->shift_of[2];
    const size_t k0 = b->coff[sl - b->s0], k1 = b->coff[sl - b->s0 + 1];
    const size_t i = particle_of(l, sl);
    const uint32_t *cj = b->cj;
    const uint16_t *ci = b->cimg;
    size_t *pj = o.j;
    double *d0 = o.d[0], *d1 = o.d[1], *d2 = o.d[2], *pr = o.r;
    /* the operations of consph_nnps_scan_run in its order: q = x_i - shift, x_ij = q - x_j, r²
     * summed from axis 0 up */
    if (dim == 1) {
        const double x0 = u0[i];
        for (size_t k = k0; k < k1; ++k) {
            const size_t j = cj[k];
            const double e0 = (x0 - t0[ci[k] & 15]) - u0[j];
            const double rr = e0 * e0;
            pj[used] = j;
            d0[used] = e0;
            pr[used] = rr;
            used += rr < r2max;
        }
    } else if (dim == 2) {
        const double x0 = u0[i], x1 = u1[i];
        for (size_t k = k0; k < k1; ++k) {
            const size_t j = cj[k];
            const unsigned c = ci[k];
            const double e0 = (x0 - t0[c & 15]) - u0[j];
            const double e1 = (x1 - t1[(c >> 4) & 15]) - u1[j];
            const double rr = e0 * e0 + e1 * e1;
            pj[used] = j;
            d0[used] = e0;
            d1[used] = e1;
            pr[used] = rr;
            used += rr < r2max;
        }
    } else {
        const double x0 = u0[i], x1 = u1[i], x2 = u2[i];
        for (size_t k = k0; k < k1; ++k) {
            const size_t j = cj[k];
            const unsigned c = ci[k];
            const double e0 = (x0 - t0[c & 15]) - u0[j];
            const double e1 = (x1 - t1[(c >> 4) & 15]) - u1[j];
            const double e2 = (x2 - t2[(c >> 8) & 15]) - u2[j];
            const double rr = e0 * e0 + e1 * e1 + e2 * e2;
            pj[used] = j;
            d0[used] = e0;
            d1[used] = e1;
            d2[used] = e2;
            pr[used] = rr;
            used += rr < r2max;
        }
    }
    return used;
}

#if defined(NLIST_SSE2) && defined(__GNUC__)
#include <immintrin.h>
#define NLIST_AVX2 1
static const unsigned char hit_count[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};

#define NLIST_STORE(dst, v, perm)                                                                  \
    _mm256_storeu_si256((__m256i *)(dst), _mm256_permutevar8x32_epi32(_mm256_castpd_si256(v), perm))

/* filter_slot on four candidates at a time: the same operations on the same values (no
 * fused multiply-add), the hits compressed to the front of each block of four. Whole blocks
 * are stored, so o needs 3 entries of slack past the candidates. */
__attribute__((target("avx2"))) static size_t
filter_slot_avx2(const consph_nlist *l, const nlist_block *b, size_t sl, pair_out o, size_t used)
{
    const int dim = l->dim;
    const size_t n = l->n;
    const double *u0 = l->u, *u1 = dim > 1 ? l->u + n : l->u, *u2 = dim > 2 ? l->u + 2 * n : l->u;
    const size_t k0 = b->coff[sl - b->s0], k1 = b->coff[sl - b->s0 + 1];
    const size_t i = particle_of(l, sl);
    const __m256d lim = _mm256_set1_pd(l->radius2);
    const __m256d x0 = _mm256_set1_pd(u0[i]), x1 = _mm256_set1_pd(dim > 1 ? u1[i] : 0.0);
    const __m256d x2 = _mm256_set1_pd(dim > 2 ? u2[i] : 0.0);
    /* the shift (double)m · L of the table, computed the same way from the image index m */
    const __m128i m15 = _mm_set1_epi32(15), seven = _mm_set1_epi32(NLIST_IMAGE_MAX);
    const __m256d len0 = _mm256_set1_pd(l->periodic[0] ? l->len[0] : 0.0);
    const __m256d len1 = _mm256_set1_pd(dim > 1 && l->periodic[1] ? l->len[1] : 0.0);
    const __m256d len2 = _mm256_set1_pd(dim > 2 && l->periodic[2] ? l->len[2] : 0.0);
    const uint32_t *cj = b->cj;
    size_t k = k0;
    for (; k + 4 <= k1; k += 4) {
        const __m128i j = _mm_loadu_si128((const __m128i *)(cj + k));
        const size_t ja = cj[k], jb = cj[k + 1], jc = cj[k + 2], jd = cj[k + 3];
        const __m128i c = _mm_cvtepu16_epi32(_mm_loadl_epi64((const __m128i *)(b->cimg + k)));
        const __m256d m0 = _mm256_cvtepi32_pd(_mm_sub_epi32(_mm_and_si128(c, m15), seven));
        __m256d e0 = _mm256_sub_pd(_mm256_sub_pd(x0, _mm256_mul_pd(m0, len0)),
                                   _mm256_set_pd(u0[jd], u0[jc], u0[jb], u0[ja]));
        __m256d rr = _mm256_mul_pd(e0, e0), e1 = e0, e2 = e0;
        if (dim > 1) {
            const __m256d m1 =
                _mm256_cvtepi32_pd(_mm_sub_epi32(_mm_and_si128(_mm_srli_epi32(c, 4), m15), seven));
            e1 = _mm256_sub_pd(_mm256_sub_pd(x1, _mm256_mul_pd(m1, len1)),
                               _mm256_set_pd(u1[jd], u1[jc], u1[jb], u1[ja]));
            rr = _mm256_add_pd(rr, _mm256_mul_pd(e1, e1));
        }
        if (dim > 2) {
            const __m256d m2 =
                _mm256_cvtepi32_pd(_mm_sub_epi32(_mm_and_si128(_mm_srli_epi32(c, 8), m15), seven));
            e2 = _mm256_sub_pd(_mm256_sub_pd(x2, _mm256_mul_pd(m2, len2)),
                               _mm256_set_pd(u2[jd], u2[jc], u2[jb], u2[ja]));
            rr = _mm256_add_pd(rr, _mm256_mul_pd(e2, e2));
        }
        const int m = _mm256_movemask_pd(_mm256_cmp_pd(rr, lim, _CMP_LT_OQ));
        const __m256i perm = _mm256_loadu_si256((const __m256i *)nnps_hit_permute[m]);
        _mm256_storeu_si256((__m256i *)(o.j + used),
                            _mm256_permutevar8x32_epi32(_mm256_cvtepu32_epi64(j), perm));
        NLIST_STORE(o.r + used, rr, perm);
        NLIST_STORE(o.d[0] + used, e0, perm);
        if (dim > 1) NLIST_STORE(o.d[1] + used, e1, perm);
        if (dim > 2) NLIST_STORE(o.d[2] + used, e2, perm);
        used += hit_count[m];
    }
    /* the last candidates one by one */
    if (k < k1) {
        nlist_block tail = *b;
        size_t coff[2] = {k, k1};
        tail.s0 = sl;
        tail.coff = coff;
        used = filter_slot(l, &tail, sl, o, used);
    }
    return used;
}
#endif

#ifdef NLIST_AVX2
/* Set once by consph_sys_nlist, before any pass can read it. */
static int use_avx2 = -1;
#endif

/* filter_slot, vectorised where the processor allows. */
static inline size_t filter(const consph_nlist *l, const nlist_block *b, size_t sl, pair_out o,
                            size_t used)
{
#ifdef NLIST_AVX2
    if (__atomic_load_n(&use_avx2, __ATOMIC_RELAXED) > 0)
        return filter_slot_avx2(l, b, sl, o, used);
#endif
    return filter_slot(l, b, sl, o, used);
}

/* r = sqrt(r²) over [from, to), then zeros up to whole vectors for the kernel batch (r = 0 is a
 * valid distance; the values are unused). */
static inline void roots_and_pad(double *r, size_t from, size_t to)
{
    size_t k = from;
#ifdef NLIST_SSE2
    /* packed square roots are correctly rounded like sqrt(), without its errno branch */
    for (; k + 2 <= to; k += 2) _mm_storeu_pd(r + k, _mm_sqrt_pd(_mm_loadu_pd(r + k)));
#endif
    for (; k < to; ++k) r[k] = sqrt(r[k]);
    for (k = to; k < ((to + 3) & ~(size_t)3); ++k) r[k] = 0.0;
}

/* After the first destination of a block's first fill (`used` pairs): room for as many
 * at each of its destinations and an eighth more. Without it a block's first fill grew its
 * arrays a quarter at a time from one particle's candidates, each growth a copy into fresh
 * pages: at 3D L-IPST-C's 200 pairs per particle about a dozen copies per array, and the
 * copies' page faults a third of a one-step run's kernel time. */
static int reserve_like_first(const consph_sys *s, nlist_block *b, size_t used)
{
    const consph_nlist *l = s->nlist;
    size_t dests = 0;
    for (size_t sl = b->s0; sl < b->s1; ++sl) dests += !s->dest || s->dest[particle_of(l, sl)];
    const size_t want = used * dests + used * dests / 8;
    return want > b->pcap ? pair_reserve(b, l->dim, want) : CONSPH_OK;
}

static int cache_block(const consph_sys *s, nlist_block *b)
{
    const consph_nlist *l = s->nlist;
    size_t used = 0;
    int first = b->pcap == 0; /* the block's first fill */
    for (size_t sl = b->s0; sl < b->s1; ++sl) {
        b->poff[sl - b->s0] = used;
        if (s->dest && !s->dest[particle_of(l, sl)]) continue; /* a source only: no pairs */
        if (pair_reserve(b, l->dim, used + (b->coff[sl - b->s0 + 1] - b->coff[sl - b->s0])))
            return CONSPH_ENOMEM;
        pair_out o = {b->pj, {b->pdx[0], b->pdx[1], b->pdx[2]}, b->pr};
        used = filter(l, b, sl, o, used);
        if (first && reserve_like_first(s, b, used)) return CONSPH_ENOMEM;
        first = 0;
    }
    b->poff[b->s1 - b->s0] = used;
    roots_and_pad(b->pr, 0, used);
    return CONSPH_OK;
}

/* cache_block for skin 0: the gather's own neighbourhoods, stored. */
static int cache_block_gather(const consph_sys *s, nlist_block *b, consph_nnps_runs *runs,
                              size_t **slot, size_t *cap)
{
    const consph_nlist *l = s->nlist;
    consph_nnps_slots v;
    if (consph_nnps_slots_get(s->nnps, &v) != CONSPH_OK) return CONSPH_EINVAL;
    size_t lo = 0, hi = v.ncells;
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        if (v.cell_start[mid] <= b->s0)
            lo = mid;
        else
            hi = mid;
    }
    size_t c = lo, runs_cell = (size_t)-1, used = 0;
    int fresh = b->pcap == 0; /* the block's first fill */
    b->slo = b->s0;
    b->shi = b->s1 - 1;
    for (size_t sl = b->s0; sl < b->s1; ++sl) {
        while (sl >= v.cell_start[c + 1]) ++c;
        b->poff[sl - b->s0] = used;
        /* a source only (the MPI halo): no pass visits its pairs, so none are kept, and a cell
         * of sources only needs no runs */
        if (s->dest && !s->dest[particle_of(l, sl)]) continue;
        if (c != runs_cell) {
            if (consph_nnps_cell_runs(s->nnps, c, runs) == (size_t)-1) return CONSPH_ENOMEM;
            runs_cell = c;
            for (size_t k = 0; k < runs->n; ++k) {
                if (runs->run[k].s0 < b->slo) b->slo = runs->run[k].s0;
                if (runs->run[k].s1 > b->shi + 1) b->shi = runs->run[k].s1 - 1;
            }
            const size_t need = runs->candidates + CONSPH_NNPS_GATHER_SLACK;
            if (need > *cap) {
                if (grow((void **)slot, need, sizeof(size_t))) return CONSPH_ENOMEM;
                *cap = need;
            }
        }
        if (pair_reserve(b, l->dim, used + runs->candidates + CONSPH_NNPS_GATHER_SLACK))
            return CONSPH_ENOMEM;
        double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        for (int a = 0; a < l->dim; ++a) xi[a] = v.x[a][sl];
        double *dx[CONSPH_MAX_DIM] = {b->pdx[0] + used, l->dim > 1 ? b->pdx[1] + used : NULL,
                                      l->dim > 2 ? b->pdx[2] + used : NULL};
        /* the neighbours' particles in place (slots are particles where the search is in the
         * particles' order, after a re-sort; else, as between IPST's moves, the gather maps
         * them) */
        used += nnps_gather_particles(&v, runs, xi, *slot, b->pj + used, dx, b->pr + used);
        if (fresh && reserve_like_first(s, b, used)) return CONSPH_ENOMEM;
        fresh = 0;
    }
    b->poff[b->s1 - b->s0] = used;
    for (size_t k = used; k < ((used + 3) & ~(size_t)3); ++k) b->pr[k] = 0.0;
    return CONSPH_OK;
}

static int values_block(const consph_sys *s, nlist_block *b, unsigned want)
{
    if (values_reserve(b, want)) return CONSPH_ENOMEM;
    const size_t used = b->poff[b->s1 - b->s0], m4 = (used + 3) & ~(size_t)3;
    consph_kernel_eval_batch(&s->kernel, m4, b->pr, want & CONSPH_PASS_W ? b->pw : NULL,
                             want & CONSPH_PASS_DW ? b->pdwr : NULL,
                             want & CONSPH_PASS_D2W ? b->pd2w : NULL);
    return CONSPH_OK;
}

/* One pass without the cache: each particle's pairs are filtered and evaluated into the
 * thread's buffers and visited at once. */
static int stream_pass(const consph_sys *s, const consph_pass *pass, void *job, size_t *pairs)
{
    const consph_nlist *l = s->nlist;
    const unsigned need = pass->need;
    const unsigned char *dest = s->dest;
    const int with_dx = !(need & CONSPH_PASS_NO_DX);
    size_t visited = 0;
    int status = CONSPH_OK;
#pragma omp parallel reduction(+ : visited) if (l->n >= s->parallel_min)
    {
        nlist_block buf;
        memset(&buf, 0, sizeof buf);
        int ok = values_reserve(&buf, 0) == CONSPH_OK;
#pragma omp for schedule(dynamic, 1)
        for (size_t k = 0; k < l->nblocks; ++k) {
            const nlist_block *b = &l->blocks[k];
            for (size_t sl = b->s0; sl < b->s1 && ok; ++sl) {
                const size_t i = particle_of(l, sl);
                if (dest && !dest[i]) continue;
                if (pair_reserve(&buf, l->dim, b->coff[sl - b->s0 + 1] - b->coff[sl - b->s0]) ||
                    values_reserve(&buf, CONSPH_PASS_W | CONSPH_PASS_DW | CONSPH_PASS_D2W)) {
                    ok = 0;
                    break;
                }
                pair_out o = {buf.pj, {buf.pdx[0], buf.pdx[1], buf.pdx[2]}, buf.pr};
                const size_t m = filter(l, b, sl, o, 0);
                roots_and_pad(buf.pr, 0, m);
                consph_kernel_eval_batch(
                    &s->kernel, (m + 3) & ~(size_t)3, buf.pr, need & CONSPH_PASS_W ? buf.pw : NULL,
                    need & (CONSPH_PASS_DW | CONSPH_PASS_D2W) ? buf.pdwr : NULL,
                    need & CONSPH_PASS_D2W ? buf.pd2w : NULL);
                consph_nbhd nb;
                nb.i = i;
                nb.n = m;
                nb.j = buf.pj;
                for (int a = 0; a < CONSPH_MAX_DIM; ++a)
                    nb.dx[a] = with_dx && a < l->dim ? buf.pdx[a] : NULL;
                nb.r = buf.pr;
                nb.w = need & CONSPH_PASS_W ? buf.pw : NULL;
                nb.dwr = need & (CONSPH_PASS_DW | CONSPH_PASS_D2W) ? buf.pdwr : NULL;
                nb.d2w = need & CONSPH_PASS_D2W ? buf.pd2w : NULL;
                pass->visit(job, &nb);
                visited += m;
            }
        }
        if (!ok) {
#pragma omp critical(consph_nlist_stream)
            status = CONSPH_ENOMEM;
        }
        block_free(&buf);
    }
    if (status != CONSPH_OK)
        return consph_fail(status, "pass '%s': out of memory for a neighbourhood",
                           pass->name ? pass->name : "unnamed");
    if (pairs) *pairs += visited;
    return CONSPH_OK;
}

/* Whether nlist_pass_run would hand this pass to the search's own gather (NLIST_GATHER): then
 * it counts the pass as nlist_pass_run does, so that the choice of the state's later passes is
 * the same whoever runs this one (src/pass/group.c). */
int nlist_gathers(consph_nlist *l)
{
    if (l->skin != 0.0) return 0;
    const unsigned long state = l->state_epoch;
    const int last = l->passes_last, count = l->passes_state;
    if (l->state_epoch != l->epoch) {
        l->state_epoch = l->epoch;
        l->passes_last = l->passes_state;
        l->passes_state = 0;
    }
    const int fresh = l->cache_epoch != l->epoch || !l->caches;
    if (fresh && (l->passes_last < NLIST_CACHE_PASSES ||
                  l->npairs > CONSPH_NLIST_MAX_CANDIDATES * l->n || cache_over_budget(l))) {
        ++l->passes_state;
        return 1;
    }
    l->state_epoch = state;
    l->passes_last = last;
    l->passes_state = count;
    return 0;
}

/* Whether the cache serves the next pass on this position state (else the search's gather, skin
 * 0, or a stream, skin > 0). Reads the list only: nlist_cache_ready counts the pass. */
static int cache_serves(const consph_nlist *l)
{
    const int passes_last = l->state_epoch != l->epoch ? l->passes_state : l->passes_last;
    const int fresh = l->cache_epoch != l->epoch || !l->caches;
    const int hinted = l->hint_epoch == l->epoch && l->hint_passes >= 2;
    /* A cache pays where several passes read one position state; one or two passes are served
     * better by filtering each particle's candidates into a small buffer that stays in the
     * processor's cache (measured: edac and tvf, two passes per state, ran 5 % slower from a
     * cache; L-IPST-C, three, 15 % faster). Both compute the same values, so the choice changes
     * no result. A caller that knows how many passes will read the state says so
     * (consph_sys_expect_passes) and is believed over the previous state's count. Nor is a
     * cache made whose pairs would exceed the memory budget (pair_cache_budget): the filtering
     * then serves every pass, at the cost measured in docs/mpi.md. */
    return !(fresh && ((!hinted && passes_last < NLIST_CACHE_PASSES) ||
                       l->npairs > CONSPH_NLIST_MAX_CANDIDATES * l->n || cache_over_budget(l)));
}

unsigned long nlist_pair_counts(const consph_nlist *l, uint32_t *count)
{
    if (l->off || !l->caches || l->cache_epoch != l->epoch || !l->epoch) return 0;
    for (size_t k = 0; count && k < l->nblocks; ++k) {
        const nlist_block *b = &l->blocks[k];
        for (size_t sl = b->s0; sl < b->s1; ++sl)
            count[particle_of(l, sl)] = (uint32_t)(b->poff[sl - b->s0 + 1] - b->poff[sl - b->s0]);
    }
    return l->epoch;
}

/* A pass's visits: per particle (pass) or over groups of slots (group, src/pass/group.h). */
typedef struct block_visitor {
    const consph_pass *pass;
    pass_group_fn group;
    void *job;
    unsigned need;
    int uncounted; /* its pairs are not added to the chain's count */
    /* the particles visited, one byte each (NULL: the system's destinations, every particle
     * without a mask) */
    const unsigned char *mask;
} block_visitor;

/* Slot sl's cached neighbourhood with the values `need` asks for. */
static inline void cached_nbhd(const consph_nlist *l, const nlist_block *b, size_t sl,
                               unsigned need, consph_nbhd *nb)
{
    const int with_dx = !(need & CONSPH_PASS_NO_DX);
    const size_t o = b->poff[sl - b->s0];
    nb->i = particle_of(l, sl);
    nb->n = b->poff[sl - b->s0 + 1] - o;
    nb->j = b->pj + o;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a)
        nb->dx[a] = with_dx && a < l->dim ? b->pdx[a] + o : NULL;
    nb->r = b->pr + o;
    nb->w = need & CONSPH_PASS_W ? b->pw + o : NULL;
    nb->dwr = need & (CONSPH_PASS_DW | CONSPH_PASS_D2W) ? b->pdwr + o : NULL;
    nb->d2w = need & CONSPH_PASS_D2W ? b->pd2w + o : NULL;
}

/* The visits of one block's slots; returns the pairs visited. */
static size_t visit_block(const consph_sys *s, const nlist_block *b, const block_visitor *bv)
{
    const consph_nlist *l = s->nlist;
    const unsigned char *dest = bv->mask ? bv->mask : s->dest;
    size_t visited = 0;
    if (bv->group) {
        for (size_t sl = b->s0; sl < b->s1;) {
            if (dest && !dest[particle_of(l, sl)]) {
                ++sl; /* a source only (the MPI halo): not visited */
                continue;
            }
            /* up to four consecutive destinations (without a mask: the block in fours) */
            int count = 1;
            while (count < PASS_GROUP && sl + (size_t)count < b->s1 &&
                   (!dest || dest[particle_of(l, sl + (size_t)count)]))
                ++count;
            consph_nbhd nb[PASS_GROUP];
            for (int g = 0; g < PASS_GROUP; ++g) {
                /* the lanes past count repeat the first (src/pass/group.h) */
                cached_nbhd(l, b, g < count ? sl + (size_t)g : sl, bv->need, &nb[g]);
                if (g < count) visited += nb[g].n;
            }
            bv->group(bv->job, nb, count);
            sl += (size_t)count;
        }
        return bv->uncounted ? 0 : visited;
    }
    for (size_t sl = b->s0; sl < b->s1; ++sl) {
        if (dest && !dest[particle_of(l, sl)]) continue;
        consph_nbhd nb;
        cached_nbhd(l, b, sl, bv->need, &nb);
        bv->pass->visit(bv->job, &nb);
        visited += nb.n;
    }
    return bv->uncounted ? 0 : visited;
}

/* Counts a pass on the current position state and, where the cache serves it (cache_serves
 * before the count), fills what it lacks for `need`: *served 1; else *served 0 and nothing
 * else done. */
static int cache_ready(const consph_sys *s, unsigned need, const char *name, int *served,
                       const block_visitor *fuse, size_t *fused_pairs)
{
    *fused_pairs = (size_t)-1;
    consph_nlist *l = s->nlist;
    unsigned want = 0;
    if (need & CONSPH_PASS_W) want |= CONSPH_PASS_W;
    if (need & (CONSPH_PASS_DW | CONSPH_PASS_D2W)) want |= CONSPH_PASS_DW;
    if (need & CONSPH_PASS_D2W) want |= CONSPH_PASS_D2W;
    *served = cache_serves(l);
    if (l->state_epoch != l->epoch) {
        l->state_epoch = l->epoch;
        l->passes_last = l->passes_state;
        l->passes_state = 0;
    }
    ++l->passes_state;
    if (!*served) return CONSPH_OK;
    const int fresh = l->cache_epoch != l->epoch || !l->caches;
    const int hinted = l->hint_epoch == l->epoch && l->hint_passes >= 2;
    if (hinted) {
        if (l->hint_need & CONSPH_PASS_W) want |= CONSPH_PASS_W;
        if (l->hint_need & (CONSPH_PASS_DW | CONSPH_PASS_D2W)) want |= CONSPH_PASS_DW;
        if (l->hint_need & CONSPH_PASS_D2W) want |= CONSPH_PASS_D2W;
    }
    if (fresh) l->have = 0;
    const unsigned missing = want & ~l->have;
    const int par = l->n >= s->parallel_min;
    (void)par; /* read by the OpenMP if alone */
    int status = CONSPH_OK;
    if (fresh || missing) {
        size_t total = 0, visited = 0;
        /* the pass that fills the cache visits each block as soon as it is filled, while its
         * pairs are still in the processor's caches */
        const block_visitor *now = fresh ? fuse : NULL;
#pragma omp parallel reduction(+ : total, visited) if (par)
        {
            consph_nnps_runs runs;
            memset(&runs, 0, sizeof runs);
            size_t *slot = NULL, cap = 0;
#pragma omp for schedule(dynamic, 1)
            for (size_t k = 0; k < l->nblocks; ++k) {
                nlist_block *b = &l->blocks[k];
                int st = !fresh           ? CONSPH_OK
                         : l->skin == 0.0 ? cache_block_gather(s, b, &runs, &slot, &cap)
                                          : cache_block(s, b);
                if (!st && missing) st = values_block(s, b, missing);
                if (!st && now) visited += visit_block(s, b, now);
                if (st) {
#pragma omp critical(consph_nlist_cache)
                    status = st;
                }
                total += b->poff[b->s1 - b->s0];
            }
            consph_nnps_runs_free(&runs);
            free(slot);
        }
        if (status != CONSPH_OK) {
            l->cache_epoch = l->epoch - 1;
            return consph_fail(status, "pass '%s': out of memory for the pair cache",
                               name ? name : "unnamed");
        }
        if (fresh) {
            l->npairs = total;
            l->cache_epoch = l->epoch;
            ++l->caches;
        }
        l->have |= missing;
        if (now) *fused_pairs = visited;
    }
    return CONSPH_OK;
}

/* A pass the cache served: the visits cache_ready left to a sweep of the filled blocks
 * (visited (size_t)-1), then the pass's count. */
static void visit_served(const consph_sys *s, const block_visitor *bv, size_t visited,
                         size_t *pairs)
{
    const consph_nlist *l = s->nlist;
    if (visited == (size_t)-1) {
        visited = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : visited) if (l->n >= s->parallel_min)
        for (size_t k = 0; k < l->nblocks; ++k) visited += visit_block(s, &l->blocks[k], bv);
    }
    if (pairs) *pairs += visited;
}

int nlist_pass_run(const consph_sys *s, const consph_pass *pass, void *job, size_t *pairs)
{
    consph_nlist *l = s->nlist;
    const unsigned need = pass->need;
    int served = 0;
    const block_visitor bv = {pass, NULL, job, need, 0, NULL};
    size_t visited = 0;
    const int st = cache_ready(s, need, pass->name, &served, &bv, &visited);
    if (st != CONSPH_OK) return st;
    if (!served) return l->skin == 0.0 ? NLIST_GATHER : stream_pass(s, pass, job, pairs);
    visit_served(s, &bv, visited, pairs);
    return CONSPH_OK;
}

int nlist_group_run(const consph_sys *s, const char *name, unsigned need, pass_group_fn visit,
                    void *job, size_t *pairs, int *ran)
{
    consph_nlist *l = s->nlist;
    *ran = -1;
    const int fresh = l->cache_epoch != l->epoch || !l->caches;
    /* Groups read the cache only while filling it: four lanes read four ranges of every array
     * side by side, which the processor's prefetching follows worse than the one range of a
     * per-particle visit once the cache no longer fits its caches (measured 15-25 % slower per
     * pair at nx 100-250 in 2D, 8 % faster at nx 60). A stream (skin > 0 without a cache) and a
     * filled cache are left to the per-particle pass, which counts the pass. */
    if (cache_serves(l) ? !fresh : l->skin != 0.0) return CONSPH_OK;
    int served = 0;
    const block_visitor bv = {NULL, visit, job, need, 0, NULL};
    size_t visited = 0;
    const int st = cache_ready(s, need, name, &served, &bv, &visited);
    *ran = served;
    if (st != CONSPH_OK || !served) return st;
    visit_served(s, &bv, visited, pairs);
    return CONSPH_OK;
}

/* ---- chained passes: a wavefront over the blocks ----
 *
 * Pass k + 1 of a chain reads, at the neighbours, what pass k wrote. Run one after the other,
 * each pass streams the whole cache from memory once it no longer fits the processor's caches
 * (about 50 bytes per pair written and 30 to 40 read per pass). Here one sweep fills block f
 * (or finds it filled) and runs pass 0 on it, and runs pass k on block b as soon as pass k - 1 is
 * done on every block that holds a neighbour of b: the passes trail the fill by the blocks a
 * neighbourhood spans, so a block's pairs are read again while they are still cached. A block whose
 * neighbours lie outside its thread's share of blocks or span more than NLIST_CHAIN_SPAN of
 * them (the periodic images across the box) waits until the sweep is over. Every visit reads
 * the same values as in the passes run one after the other, so the results are those, for any
 * thread count. */
#define NLIST_CHAIN_MAX 4

enum { CHAIN_PENDING = 0, CHAIN_DONE = 1, CHAIN_LATE = 2 };

unsigned long nlist_chain_trailing = 0, nlist_chain_filled = 0, nlist_chain_recycled = 0;
unsigned long nlist_chain_split = 0, nlist_chain_deferred = 0;

/* A decomposed system's sweep runs pass k only k neighbourhoods or more inside its halo; the rest
 * run after it, per particle, from pairs no longer in the processor's caches, and the blocks they
 * read cannot lend their arrays to the fill. So a rank chains where its halo is small beside
 * what it owns. Measured with the chain forced on and off (2 ranks on a 2-core AMD EPYC,
 * Taylor-Green L-IPST-C on a lattice; halo / owned in brackets): nx 283 (0.10) 2-15 % faster
 * a step, nx 200 (0.14) 0-5 %, nx 141 (0.21) and nx 100 (0.27-0.31) no faster; 3D Beltrami nx
 * 46 (0.46-0.55) 4-17 % slower. The limit lets in 16 ranks' boxes at bench/mpi.sh's 2D size (4x4
 * of 55 x 55 cells, halo 0.16). The refreshes are the same either way, so ranks may choose apart.
 */
double nlist_chain_split_halo = 0.2;
/* CONSPH_TEST_CHAIN_SPLIT set: every decomposed chain runs, whatever its halo (tests) */
static int chain_test_split = -1;

typedef struct chain_state {
    const consph_sys *s;
    const block_visitor *bv;
    int count;
    unsigned char *st; /* count × nblocks */
    size_t *lo, *hi;   /* the blocks holding a block's neighbours */
    size_t span;
    /* where the chain is the state's last reader: per thread, from entry c0 of its share, a
     * stack of its blocks that every pass is done with, whose pair arrays the fill may take
     * (NULL: the cache is kept) */
    size_t *spent;
    /* a decomposed system: row k (n bytes) the particles whose pass k the sweep ran, row 0 the
     * destinations (NULL: every destination in the sweep) */
    unsigned char *done;
    size_t n;
    /* with done: row k (nblocks entries) the slots of each block whose pass k the sweep did not
     * run (row 0: the halo's), so that a block whose neighbours' blocks all ran pass k - 1 is
     * passed without reading its pairs */
    size_t *miss;
} chain_state;

/* Gives block b the pair arrays of block g (and g those of b): the fill of b then writes
 * memory that the passes on g have just read, still in the processor's caches, instead of
 * b's own, last written a whole sweep ago. */
static void swap_pairs(nlist_block *b, nlist_block *g)
{
    nlist_block t = *b;
    b->pj = g->pj;
    b->pr = g->pr;
    b->pw = g->pw;
    b->pdwr = g->pdwr;
    b->pd2w = g->pd2w;
    b->pcap = g->pcap;
    g->pj = t.pj;
    g->pr = t.pr;
    g->pw = t.pw;
    g->pdwr = t.pdwr;
    g->pd2w = t.pd2w;
    g->pcap = t.pcap;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        b->pdx[a] = g->pdx[a];
        g->pdx[a] = t.pdx[a];
    }
}

/* Pass k >= 1 on block b, whose neighbours' blocks pass k - 1 is done with. On a decomposed
 * system only at the destinations where pass k - 1 ran in the sweep, at the particle and at every
 * neighbour (a halo particle's values come with the refresh after the sweep): those make row k
 * of c->done, which the visits take as their mask. */
static size_t chain_visit(chain_state *c, int k, size_t b)
{
    const consph_nlist *l = c->s->nlist;
    const nlist_block *blk = &l->blocks[b];
    if (c->done) {
        const size_t nb = l->nblocks;
        const unsigned char *prev = c->done + (size_t)(k - 1) * c->n;
        unsigned char *mine = c->done + (size_t)k * c->n;
        size_t around = 0, missed = 0;
        for (size_t x = c->lo[b]; x <= c->hi[b]; ++x) around += c->miss[(size_t)(k - 1) * nb + x];
        for (size_t sl = blk->s0; sl < blk->s1; ++sl) {
            const size_t i = particle_of(l, sl);
            unsigned ok = prev[i];
            if (around) {
                /* without an early exit: the loads overlap */
                const size_t *pj = blk->pj;
                for (size_t o = blk->poff[sl - blk->s0], o1 = blk->poff[sl - blk->s0 + 1]; o < o1;
                     ++o)
                    ok &= prev[pj[o]];
            }
            mine[i] = (unsigned char)ok;
            missed += !ok;
        }
        c->miss[(size_t)k * nb + b] = missed;
    }
    return visit_block(c->s, blk, &c->bv[k]);
}

/* Whether every destination of block b ran the chain's last pass in the sweep (nothing is left
 * to read its pairs after it), once that pass's visit of b counted what it missed: a halo slot is
 * missed by every pass, so the destinations left are the last row's count over row 0's. */
static int chain_block_spent(const chain_state *c, size_t b)
{
    const size_t nb = c->s->nlist->nblocks;
    return !c->done || c->miss[(size_t)(c->count - 1) * nb + b] == c->miss[b];
}

/* Pass k on block b if it can run now: CHAIN_DONE (run), CHAIN_LATE (left for after the sweep)
 * or CHAIN_PENDING (pass k - 1 has yet to reach some of its neighbours). */
static int chain_try(chain_state *c, int k, size_t b, size_t c0, size_t c1, size_t *visited,
                     size_t *nspent)
{
    const size_t nb = c->s->nlist->nblocks;
    unsigned char *prev = c->st + (size_t)(k - 1) * nb, *mine = c->st + (size_t)k * nb;
    const size_t lo = c->lo[b], hi = c->hi[b];
    int verdict = CHAIN_DONE;
    if (lo < c0 || hi >= c1 || hi - lo > c->span) {
        verdict = CHAIN_LATE;
    } else {
        for (size_t x = lo; x <= hi; ++x) {
            if (prev[x] == CHAIN_LATE) {
                verdict = CHAIN_LATE;
                break;
            }
            if (prev[x] == CHAIN_PENDING) verdict = CHAIN_PENDING;
        }
    }
    if (verdict == CHAIN_DONE) {
        *visited += chain_visit(c, k, b);
#pragma omp atomic
        ++nlist_chain_trailing;
        /* the last pass done on b: every pass before it is done on b's neighbours, b among
         * them, so nothing reads b's pairs again (a decomposed system: unless a destination
         * of b has passes left for after the sweep) */
        if (c->spent && k == c->count - 1 && chain_block_spent(c, b))
            c->spent[c0 + (*nspent)++] = b;
    }
    if (verdict != CHAIN_PENDING) mine[b] = (unsigned char)verdict;
    return verdict;
}

int nlist_chain_run(const consph_sys *s, const block_visitor_in *in, int count, size_t *pairs,
                    int *ran)
{
    consph_nlist *l = s->nlist;
    *ran = 0;
    const int fresh = l->cache_epoch != l->epoch || !l->caches;
    /* a decomposed system: its halo's values come with a refresh between the passes (the
     * visits that need them wait for it, after the sweep); a mask without one is declined */
    const int split = s->split && s->dest;
    if (count < 2 || count > NLIST_CHAIN_MAX || (s->dest && !split) || !cache_serves(l) ||
        l->nblocks == 0)
        return CONSPH_OK;
    if (split) {
        size_t own = 0;
        for (size_t i = 0; i < l->n; ++i) own += s->dest[i] != 0;
        if (__atomic_load_n(&chain_test_split, __ATOMIC_RELAXED) < 0)
            __atomic_store_n(&chain_test_split, getenv("CONSPH_TEST_CHAIN_SPLIT") != NULL,
                             __ATOMIC_RELAXED);
        if (!__atomic_load_n(&chain_test_split, __ATOMIC_RELAXED) &&
            (double)(l->n - own) > nlist_chain_split_halo * (double)own)
            return CONSPH_OK;
    }
    block_visitor bv[NLIST_CHAIN_MAX];
    unsigned want = 0;
    for (int k = 0; k < count; ++k) {
        bv[k] = (block_visitor){in[k].pass,       in[k].group,     in[k].job,
                                in[k].pass->need, in[k].uncounted, NULL};
        const unsigned need = in[k].pass->need;
        if (need & CONSPH_PASS_W) want |= CONSPH_PASS_W;
        if (need & (CONSPH_PASS_DW | CONSPH_PASS_D2W)) want |= CONSPH_PASS_DW;
        if (need & CONSPH_PASS_D2W) want |= CONSPH_PASS_D2W;
    }
    if (l->hint_epoch == l->epoch && l->hint_passes >= 2) {
        if (l->hint_need & CONSPH_PASS_W) want |= CONSPH_PASS_W;
        if (l->hint_need & (CONSPH_PASS_DW | CONSPH_PASS_D2W)) want |= CONSPH_PASS_DW;
        if (l->hint_need & CONSPH_PASS_D2W) want |= CONSPH_PASS_D2W;
    }
    const size_t nb = l->nblocks;
    chain_state c = {s, bv, count, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL};
    /* The chain is the last reader of a fresh state where the caller announced exactly its
     * passes (consph_sys_expect_passes; L-IPST-C's rates): its blocks' pairs are then needed
     * only from the fill to the last pass on them, and a block's fill takes the arrays of one
     * the chain is done with (swap_pairs), so that the sweep writes and reads a few blocks' worth
     * of memory that stays in the processor's caches instead of streaming the whole cache
     * through memory. The cache then holds no state (cache_epoch below): a later pass on this
     * state would fill it again, the same values. */
    const int recycle = fresh && l->hint_epoch == l->epoch && l->hint_passes == count;
    const size_t n = l->n;
    if (split) {
        /* row 0 the destinations; row k is written for every slot by pass k's visit of its
         * block (chain_visit) */
        if ((size_t)count * n > l->done_cap) {
            unsigned char *d = realloc(l->done, (size_t)count * n);
            if (!d) return CONSPH_OK; /* *ran 0: the passes one by one make the same refreshes */
            l->done = d;
            l->done_cap = (size_t)count * n;
        }
        memcpy(l->done, s->dest, n);
        c.done = l->done;
        c.n = n;
        c.miss = malloc((size_t)count * nb * sizeof(size_t));
        if (!c.miss) return CONSPH_OK;
        for (size_t x = 0; x < nb; ++x) {
            size_t m = 0;
            for (size_t sl = l->blocks[x].s0; sl < l->blocks[x].s1; ++sl)
                m += !s->dest[particle_of(l, sl)];
            c.miss[x] = m;
        }
        for (int k = 1; k < count; ++k) bv[k].mask = l->done + (size_t)k * n;
    }
    c.st = consph_calloc((size_t)count * nb, 1);
    c.lo = malloc(nb * sizeof(size_t));
    c.hi = malloc(nb * sizeof(size_t));
    c.spent = recycle ? malloc(nb * sizeof(size_t)) : NULL;
    /* a search built without a re-sort (inside a step) orders its slots otherwise than the
     * particles: the slot of each particle */
    size_t *slot_of = l->particle && l->skin != 0.0 ? malloc(l->n * sizeof(size_t)) : NULL;
    if (!c.st || !c.lo || !c.hi || (l->particle && l->skin != 0.0 && !slot_of) ||
        (recycle && !c.spent)) {
        free(c.st);
        free(c.lo);
        free(c.hi);
        free(c.spent);
        free(c.miss);
        free(slot_of);
        /* a decomposed system's passes one by one make the refreshes the other ranks make */
        return split ? CONSPH_OK : CONSPH_ENOMEM;
    }
    if (slot_of)
        for (size_t sl = 0; sl < l->n; ++sl) slot_of[l->particle[sl]] = sl;
    c.span = nb / 8 > 4 ? nb / 8 : 4;
    int status = CONSPH_OK;
    /* what pass 0 reads in the halo (collective: every rank makes it, the chain running or not) */
    if (split && in[0].prepare) status = in[0].prepare((consph_sys *)s, in[0].prepare_ctx);
    if (split) ((consph_sys *)s)->halo_fresh = 0; /* the passes write fields */
    /* the count of the passes on this state, as nlist_pass_run keeps it */
    if (l->state_epoch != l->epoch) {
        l->state_epoch = l->epoch;
        l->passes_last = l->passes_state;
        l->passes_state = 0;
    }
    l->passes_state += count;
    /* a cache already filled on this state (the gradients before an IPST shift leave one for
     * its first volumes and shift) is swept the same way, evaluating only the kernel values it
     * lacks: the passes then read each block while it is cached, instead of streaming the whole
     * cache from memory once per pass */
    const unsigned missing = fresh ? want : want & ~l->have;
    if (fresh) l->have = 0;
    *ran = 1;
    const int par = l->n >= s->parallel_min;
    (void)par; /* read by the OpenMP if alone */
    size_t total = 0, visited = 0;
    const int prepared = status;
    if (status == CONSPH_OK)
#pragma omp parallel reduction(+ : total, visited) if (par)
    {
#ifdef _OPENMP
        const size_t nt = (size_t)omp_get_num_threads(), t = (size_t)omp_get_thread_num();
#else
        const size_t nt = 1, t = 0;
#endif
        const size_t c0 = nb * t / nt, c1 = nb * (t + 1) / nt;
        consph_nnps_runs runs;
        memset(&runs, 0, sizeof runs);
        size_t *slot = NULL, cap = 0, next[NLIST_CHAIN_MAX], nspent = 0;
        int my_status = CONSPH_OK;
        for (int k = 1; k < count; ++k) next[k] = c0;
        for (size_t f = c0; f < c1 && my_status == CONSPH_OK; ++f) {
            nlist_block *b = &l->blocks[f];
            /* the most recently spent block's arrays: the likeliest still cached */
            if (nspent) swap_pairs(b, &l->blocks[c.spent[c0 + --nspent]]);
            int st = !fresh           ? CONSPH_OK
                     : l->skin == 0.0 ? cache_block_gather(s, b, &runs, &slot, &cap)
                                      : cache_block(s, b);
            if (!st && missing) st = values_block(s, b, missing);
            if (st) {
                my_status = st;
                break;
            }
            const size_t used = b->poff[b->s1 - b->s0];
            /* skin 0: the slots of the candidate runs; else those of the pairs */
            size_t jlo = b->slo, jhi = b->shi;
            if (l->skin != 0.0) {
                jlo = b->s0;
                jhi = b->s1 - 1;
                for (size_t p = 0; p < used; ++p) {
                    const size_t j = slot_of ? slot_of[b->pj[p]] : b->pj[p];
                    if (j < jlo) jlo = j;
                    if (j > jhi) jhi = j;
                }
            }
            c.lo[f] = jlo / NLIST_BLOCK;
            c.hi[f] = jhi / NLIST_BLOCK;
            total += used;
            visited += visit_block(s, b, &bv[0]);
            c.st[f] = CHAIN_DONE;
            for (int k = 1; k < count; ++k)
                while (next[k] <= f &&
                       chain_try(&c, k, next[k], c0, c1, &visited, &nspent) != CHAIN_PENDING)
                    ++next[k];
        }
        /* what the sweep left: every block of pass k - 1 is done or late by now */
        for (int k = 1; k < count && my_status == CONSPH_OK; ++k)
            for (; next[k] < c1; ++next[k]) chain_try(&c, k, next[k], c0, c1, &visited, &nspent);
        consph_nnps_runs_free(&runs);
        free(slot);
        if (my_status != CONSPH_OK) {
#pragma omp critical(consph_nlist_chain)
            status = my_status;
        }
        /* the late blocks, pass by pass: each pass's are done on all threads before the next */
        for (int k = 1; k < count; ++k) {
#pragma omp barrier
            if (status == CONSPH_OK)
                for (size_t x = c0; x < c1; ++x)
                    if (c.st[(size_t)k * nb + x] == CHAIN_LATE) visited += chain_visit(&c, k, x);
        }
    }
    /* a failure of the sweep's (the pair cache's memory), not of a refresh */
    const int swept = prepared == CONSPH_OK ? status : CONSPH_OK;
    /* A decomposed system: pass k at the destinations the sweep left, after the refresh that
     * brings pass k - 1's values into the halo, pass by pass. Every rank makes every refresh,
     * a failure here included, so that none waits in one alone. */
    for (int k = 1; split && k < count; ++k) {
        if (in[k].prepare) {
            const int st = in[k].prepare((consph_sys *)s, in[k].prepare_ctx);
            if (status == CONSPH_OK) status = st;
        }
        ((consph_sys *)s)->halo_fresh = 0;
        if (status != CONSPH_OK) continue;
        unsigned char *left = l->done + (size_t)k * n;
        const unsigned char *dest = s->dest;
        size_t nleft = 0;
#pragma omp parallel for schedule(static) reduction(+ : nleft) if (par)
        for (size_t i = 0; i < n; ++i) {
            left[i] = dest[i] && !left[i];
            nleft += left[i];
        }
        __atomic_fetch_add(&nlist_chain_deferred, nleft, __ATOMIC_RELAXED);
        /* per particle: over a filled cache the lanes' four streams are prefetched worse than
         * one (nlist_group_run) */
        block_visitor later = bv[k];
        later.group = NULL;
        later.mask = left;
        size_t more = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : more) if (par && nleft)
        for (size_t x = 0; x < nb; ++x)
            if (nleft) more += visit_block(s, &l->blocks[x], &later);
        visited += more;
    }
    if (split) __atomic_fetch_add(&nlist_chain_split, 1, __ATOMIC_RELAXED);
    free(c.miss);
    free(c.st);
    free(c.lo);
    free(c.hi);
    free(c.spent);
    free(slot_of);
    if (status != CONSPH_OK) {
        l->cache_epoch = l->epoch - 1;
        if (swept == CONSPH_OK) return status; /* the refresh said why */
        return consph_fail(status, "pass '%s': out of memory for the pair cache",
                           in[0].pass->name ? in[0].pass->name : "unnamed");
    }
    l->npairs = total;
    l->cache_epoch = recycle ? l->epoch - 1 : l->epoch;
    if (recycle) __atomic_fetch_add(&nlist_chain_recycled, 1, __ATOMIC_RELAXED);
    if (fresh)
        ++l->caches;
    else
        __atomic_fetch_add(&nlist_chain_filled, 1, __ATOMIC_RELAXED);
    l->have |= want;
    if (pairs) *pairs += visited;
    return CONSPH_OK;
}

void consph_sys_expect_passes(consph_sys *s, int passes, unsigned need)
{
    consph_nlist *l = s ? s->nlist : NULL;
    if (!l || l->off) return;
    l->hint_epoch = l->epoch;
    l->hint_passes = passes;
    l->hint_need = need;
}

/* ---- turning it on ---- */

/* Puts the particles back into the order they were given to consph_sys_init. */
static int unsort(consph_sys *s)
{
    const size_t n = s->p->n;
    size_t *perm = consph_calloc(n ? n : 1, sizeof(size_t));
    if (!perm) return CONSPH_ENOMEM;
    for (size_t i = 0; i < n; ++i) perm[s->origin[i]] = i;
    int rc = consph_particles_permute(s->p, perm);
    if (rc == CONSPH_OK) rc = sys_carry_permutation(s, perm);
    free(perm);
    return rc;
}

static int resume_from_field(consph_sys *s)
{
    consph_nlist *l = s->nlist;
    consph_particles *p = s->p;
    const size_t n = p->n, cap = p->cap;
    int rc = s->origin ? unsort(s) : CONSPH_OK;
    if (rc) return rc;
    const consph_field *f = consph_particles_find(p, l->field);
    if (!f || f->ncomp != p->dim)
        return consph_fail(CONSPH_EINVAL, "neighbour list: no build positions '%s' to resume from",
                           l->field);
    for (size_t k = 0; k < (size_t)p->dim * cap; k += cap)
        for (size_t i = 0; i < n; ++i)
            if (isnan(f->data[k + i]))
                return switch_off(s, "the run this resumes had turned its neighbour list off");
    double *keep = malloc((size_t)p->dim * (n ? n : 1) * sizeof(double));
    if (!keep) return CONSPH_ENOMEM;
    for (int a = 0; a < p->dim; ++a) {
        memcpy(keep + (size_t)a * n, p->x[a], n * sizeof(double));
        memcpy(p->x[a], f->data + (size_t)a * cap, n * sizeof(double));
    }
    rc = consph_nnps_build(s->nnps, p);
    if (rc == CONSPH_OK) rc = nlist_index(s);
    for (int a = 0; a < p->dim; ++a) memcpy(p->x[a], keep + (size_t)a * n, n * sizeof(double));
    free(keep);
    if (rc || l->off) return rc;
    double max_d2;
    int changed;
    rc = nlist_displace(s, &max_d2, &changed);
    if (rc == CONSPH_OK && changed) ++l->epoch;
    return rc;
}

int consph_sys_nlist(consph_sys *s, double skin, const char *build_field, int resume)
{
    if (!s || !s->p || !s->nnps)
        return consph_fail(CONSPH_EINVAL, "neighbour list: needs an initialised system");
    if (skin < 0.0) {
        if (s->nlist) {
            const double radius = s->nlist->radius;
            nlist_free(s->nlist);
            s->nlist = NULL;
            if (consph_nnps_radius(s->nnps) != radius) {
                consph_nnps *g = consph_nnps_create(&s->p->box, radius, 0);
                if (!g) return CONSPH_ENOMEM;
                consph_nnps_free(s->nnps);
                s->nnps = g;
            }
            return consph_nnps_build(s->nnps, s->p);
        }
        return CONSPH_OK;
    }
    if (!isfinite(skin) || skin > 10.0)
        return consph_fail(CONSPH_EINVAL, "neighbour list: skin %g is not in [0, 10]", skin);
    if (!s->owned)
        return consph_fail(CONSPH_EINVAL,
                           "neighbour list: the system must own its search (consph_sys_init)");
    if (build_field && strlen(build_field) >= sizeof s->nlist->field)
        return consph_fail(CONSPH_EINVAL, "neighbour list: field name '%s' is too long",
                           build_field);
    if (s->nlist) consph_sys_nlist(s, -1.0, NULL, 0);
#ifdef NLIST_AVX2
    if (__atomic_load_n(&use_avx2, __ATOMIC_RELAXED) < 0)
        __atomic_store_n(&use_avx2, __builtin_cpu_supports("avx2") ? 1 : 0, __ATOMIC_RELAXED);
#endif
    double budget = 0.0;
    const int bst = pair_cache_budget(&budget);
    if (bst != CONSPH_OK) return bst;
    consph_nlist *l = consph_calloc(1, sizeof *l);
    if (!l) return CONSPH_ENOMEM;
    s->nlist = l;
    l->budget = budget;
    const consph_particles *p = s->p;
    l->skin = skin;
    l->dim = p->dim;
    l->radius = consph_nnps_radius(s->nnps);
    l->radius2 = l->radius * l->radius;
    if (build_field) snprintf(l->field, sizeof l->field, "%s", build_field);
    double trigger = 0.5 * skin * l->radius;
    for (int a = 0; a < p->dim; ++a) {
        l->periodic[a] = p->box.periodic[a];
        l->len[a] = p->box.hi[a] - p->box.lo[a];
        /* a displacement is taken as the nearest image, which needs it below half the box */
        if (l->periodic[a] && trigger > 0.25 * l->len[a]) trigger = 0.25 * l->len[a];
        for (int m = -NLIST_IMAGE_MAX; m <= NLIST_IMAGE_MAX; ++m)
            l->shift_of[a][m + NLIST_IMAGE_MAX] = l->periodic[a] ? (double)m * l->len[a] : 0.0;
    }
    l->trigger2 = trigger * trigger;
    if (s->kernel.tensor) return switch_off(s, "a tensor-product kernel: the passes gather");
    if (skin > 0.0) {
        consph_nnps *g =
            consph_nnps_create(&p->box, l->radius * (1.0 + skin) * (1.0 + NLIST_MARGIN), 0);
        if (!g) return CONSPH_ENOMEM;
        consph_nnps_free(s->nnps);
        s->nnps = g;
        if (resume) return resume_from_field(s);
    }
    int rc = consph_nnps_build(s->nnps, s->p);
    return rc ? rc : nlist_index(s);
}

void consph_sys_nlist_info(const consph_sys *s, consph_nlist_info *info)
{
    memset(info, 0, sizeof *info);
    const consph_nlist *l = s ? s->nlist : NULL;
    if (!l) return;
    info->on = !l->off;
    info->skin = l->skin;
    info->builds = l->builds;
    info->caches = l->caches;
    snprintf(info->note, sizeof info->note, "%s", l->note);
    if (l->off || !l->n) return;
    const double n = (double)l->n;
    info->candidates = (double)l->ncand / n;
    info->pairs = (double)l->npairs / n;
    /* a cache refused for the budget holds no pairs (consph_sys_nlist_info's bytes stay true) */
    const int refused = cache_over_budget(l);
    if (refused)
        snprintf(info->note, sizeof info->note,
                 "pair cache off: its pairs would exceed the budget (CONSPH_PAIR_CACHE_MB, else "
                 "half the memory per process); the passes filter the neighbours at every pass");
    /* from the counts of the last build and cache, not the buffers' capacities, so that a run
     * and its restart report the same */
    const double values = l->npairs && !refused ? (l->have & CONSPH_PASS_W ? 1.0 : 0.0) +
                                                      (l->have & CONSPH_PASS_DW ? 1.0 : 0.0) +
                                                      (l->have & CONSPH_PASS_D2W ? 1.0 : 0.0)
                                                : 0.0;
    double bytes = n * (sizeof(double) * 2.0 * l->dim + (l->particle ? 8.0 : 0.0)) +
                   (double)l->ncand * (sizeof(uint32_t) + sizeof(uint16_t)) +
                   (refused ? 0.0 : (double)l->npairs) *
                       (sizeof(size_t) + sizeof(double) * (l->dim + 1 + values));
    info->bytes = bytes / n;
}
