/* The solver decomposed over MPI ranks, bit for bit the serial run (docs/mpi.md).
 *
 * Ranks own boxes of the neighbour search's cells (k_a pieces along axis a; k = 1, 1, K: slabs
 * along the last axis, the slowest of the cell order, src/nnps/nnps.c: cell = (c_2 nc_1 + c_1)
 * nc_0 + c_0). The serial order is rebuilt by each re-sort as a stable sort by cell of the
 * previous order; every particle carries its index in the previous serial order (g), and a rank
 * sorts the particles it holds by (cell, g): the serial order restricted to them. A rank's
 * particles are runs of the serial order (a row of cells within its piece along axis 0), whose
 * starts come from the particle counts per run summed over the ranks. Its search then visits,
 * for every owned particle, the serial run's neighbours in the serial order, the grid being the
 * whole set's (nnps_fix_grid).
 *
 * The halo: the particles of the cells within the search's reach plus one cell of a rank's box,
 * sources only (the system's destination mask), at their true positions so that the periodic
 * search finds the images the serial search finds. The pass layer calls refresh before every
 * pass and every search rebuild: positions, every named field and the system scratch of the
 * halo particles from their owners, sending only the columns (a field's component, an axis,
 * a scratch block) whose owned values changed since the last exchange; the migration at a
 * re-sort sends a particle the receiver's halo held as its slot there and those columns.
 * Particles move less than half a cell in a step (par_step_end checks it), so the halo made at
 * the step's start holds every particle within the radius of an owned one until the next
 * re-sort.
 *
 * What reads every particle (checks, diagnostics) runs on rank 0 over the owned particles
 * gathered into the serial order (par_global; par_global_some: only the fields it reads), so
 * sums over particles are the serial consph_sum whatever the rank count; rank 0 receives the
 * parts rank by rank in bounded messages, holding the assembled set and two of them. Files
 * (snapshots, checkpoints) are written on rank 0 from one array of the whole set at a time,
 * gathered in the serial order as the writer reads it (par_stream). */
#include "par/par_solver.h"

#include "consph/par.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef CONSPH_HAVE_MPI

#include <math.h>
#include <mpi.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "nnps/nnps_internal.h"
#include "pass/nlist.h"

/* a message of rank 0 to the others (consph_fail's text) */
#define PAR_MSG_BYTES 1024

struct par_solver {
    MPI_Comm comm;
    int rank, size;
    int dim;
    /* The boxes: k[a] pieces along axis a, rank (i_2 k_1 + i_1) k_0 + i_0 owning the cells
     * [cut[a][i_a], cut[a][i_a + 1]) along every axis a (k = 1, ..., 1, K: slabs along the
     * last axis). */
    int k[CONSPH_MAX_DIM];
    int periodic[CONSPH_MAX_DIM];
    int64_t nc[CONSPH_MAX_DIM];
    int64_t width[CONSPH_MAX_DIM]; /* halo width in cells: the walk's reach + 1 */
    double edge[CONSPH_MAX_DIM], len[CONSPH_MAX_DIM]; /* cell edge, box length */
    int64_t *cut[CONSPH_MAX_DIM];                     /* k[a] + 1 each */
    int *piece[CONSPH_MAX_DIM];                       /* per axis cell: its piece along the axis */
    /* per axis cell: the pieces along the axis whose box or halo holds it, ascending (cover
     * from cover_off[a][c] to cover_off[a][c + 1]); a cell's ranks are their products */
    int *cover_off[CONSPH_MAX_DIM], *cover[CONSPH_MAX_DIM];
    int *ranks;    /* size: scratch for covering */
    int64_t nrows; /* cells of the axes above the first (a row: c_0 varies) */
    int64_t *seg;  /* per row and piece along axis 0: particles (serial index) */
    size_t nglobal, nown;
    double *g;   /* per local particle: index in the serial order (halo: -1) */
    size_t *own; /* the owned particles' local indices, ascending (so is their g) */
    double *x0;  /* their coordinates at the last re-sort, dim per particle */
    /* halo refresh: per rank the particles sent (owned) and received (halo), ascending */
    int *scount, *sdispl, *rcount, *rdispl; /* in particles */
    int *sdbl, *sddis, *rdbl, *rddis;       /* in doubles, per call */
    size_t *sidx, *ridx;
    /* the same lists as runs of consecutive local indices (a box's boundary layers and its halo
     * are runs of the cell order), each within one rank's part (rank q's from srun_off[q]);
     * used where they are long (sruns, rruns) */
    struct idx_run *srun, *rrun;
    size_t *srun_off, *rrun_off;
    int sruns, rruns;
    double *sbuf, *rbuf;
    size_t sbuf_cap, rbuf_cap;
    /* The halo's columns (an axis of the positions, a field's component, a scratch block) as
     * last exchanged, column-major: sent[c·ns + k] for send slot k, got[c·nr + k] for receive
     * slot k. A refresh sends only the columns whose owned values changed since (bitwise) or
     * that the receiver holds no copy of, and writes every column of the halo from got, so the
     * halo ends as a full refresh leaves it. kept[c]: column c is kept; base: the columns of
     * positions and fields they were counted with (the scratch blocks follow). A pass that
     * declares what it reads at its neighbours (consph_sys_next_reads) refreshes only those
     * columns (sel[0..nsel)); the others keep what they held, on both sides. */
    size_t base;
    unsigned char *kept;
    size_t *sel;
    double *sent, *got;
    size_t sent_cap, got_cap;
    double **col;                /* per column: its values, indexed by local particle */
    unsigned char *mask, *masks; /* per column COL_CHANGED | COL_WANTED: this rank's, all ranks' */
    size_t col_cap, masks_cap;
    consph_sys_split split;
    /* the particle set the last install replaced: its storage serves the next one */
    consph_particles spare;
    size_t pairs_base; /* the solver's pair count when it was cut (counted on every rank) */
    size_t made;       /* the particles this rank held when it was cut (set-up's memory) */
    /* The cut's weights: per local particle, the pairs the pair cache held for it on the last
     * position state since the install that the cache served (pairs_epoch: the list's epoch
     * then, 0: none yet); the same integers for any thread count. */
    uint32_t *pairs;
    size_t pairs_cap;
    unsigned long pairs_epoch;
    int stepping; /* a step's re-sort: this rank's search holds its particles */
    int weighed;  /* the kind of weights of the last cut (WEIGH_*) */
    double bytes, seconds;
    struct stream_ctx *stream; /* inside par_stream: what rank 0's writer loads from */
};

enum { COL_CHANGED = 1, COL_WANTED = 2 }; /* changed on the owner; not held by the receiver */

static int par_fail_mem(void)
{
    return consph_fail(CONSPH_ENOMEM, "MPI decomposition: out of memory");
}

static int reserve(double **buf, size_t *cap, size_t need)
{
    if (need <= *cap) return CONSPH_OK;
    double *q = realloc(*buf, (need ? need : 1) * sizeof(double));
    if (!q) return par_fail_mem();
    *buf = q;
    *cap = need;
    return CONSPH_OK;
}

/* Doubles per particle: positions, then every field's components (in the particles' order). */
static size_t values_per_particle(const consph_particles *p)
{
    size_t k = (size_t)p->dim;
    for (int f = 0; f < p->nfields; ++f) k += (size_t)p->fields[f].ncomp;
    return k;
}

static void unpack(consph_particles *p, size_t i, const double *in)
{
    size_t k = 0;
    for (int a = 0; a < p->dim; ++a) p->x[a][i] = in[k++];
    for (int f = 0; f < p->nfields; ++f)
        for (int c = 0; c < p->fields[f].ncomp; ++c)
            p->fields[f].data[(size_t)c * p->cap + i] = in[k++];
}

/* A particle set with the fields of `like` (those with sel[f] when sel is given), in its
 * order, for n particles. */
static int particles_like_some(consph_particles *out, const consph_particles *like, size_t n,
                               const unsigned char *sel)
{
    int st = consph_particles_init(out, like->dim, n, &like->box);
    if (st != CONSPH_OK) return st;
    out->spacing = like->spacing;
    for (int f = 0; f < like->nfields; ++f)
        if ((!sel || sel[f]) &&
            !consph_particles_field(out, like->fields[f].name, like->fields[f].ncomp)) {
            consph_particles_free(out);
            return par_fail_mem();
        }
    return CONSPH_OK;
}

static int particles_like(consph_particles *out, const consph_particles *like, size_t n)
{
    return particles_like_some(out, like, n, NULL);
}

/* A set like `like` for n particles (a re-sort's install): the spare set's storage when its
 * fields are like's and it has room, else new storage with a quarter more room, so that the
 * particle counts moving a little at each re-sort neither allocate (zero-filled pages
 * touched afresh) nor change the capacity that the integrator's scratch is sized by. */
static int particles_for(consph_particles *spare, consph_particles *out,
                         const consph_particles *like, size_t n)
{
    int same = spare->x[0] && spare->cap >= n && spare->dim == like->dim &&
               spare->nfields == like->nfields;
    for (int f = 0; same && f < like->nfields; ++f)
        same = spare->fields[f].ncomp == like->fields[f].ncomp &&
               !strcmp(spare->fields[f].name, like->fields[f].name);
    if (!same) {
        if (spare->x[0]) consph_particles_free(spare);
        const size_t cap = n + n / 4;
        int st = particles_like(out, like, cap);
        if (st == CONSPH_OK) out->n = n;
        return st;
    }
    *out = *spare;
    memset(spare, 0, sizeof *spare);
    out->n = n;
    out->box = like->box;
    out->spacing = like->spacing;
    return CONSPH_OK;
}

/* pack of the positions and the selected fields */
static size_t values_selected(const consph_particles *p, const unsigned char *sel)
{
    size_t k = (size_t)p->dim;
    for (int f = 0; f < p->nfields; ++f)
        if (sel[f]) k += (size_t)p->fields[f].ncomp;
    return k;
}

static void pack_selected(const consph_particles *p, const unsigned char *sel, size_t i,
                          double *out)
{
    size_t k = 0;
    for (int a = 0; a < p->dim; ++a) out[k++] = p->x[a][i];
    for (int f = 0; f < p->nfields; ++f)
        if (sel[f])
            for (int c = 0; c < p->fields[f].ncomp; ++c)
                out[k++] = p->fields[f].data[(size_t)c * p->cap + i];
}

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__GLIBC__) &&       \
    !defined(__AVX2__)
#define PAR_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define PAR_CLONES
#endif

/* Whether v[idx[k]] differs bitwise from old[k] for some k < n. Every refresh scans each
 * column the owners did not change in full, so the scan is branch-free in blocks (gathers
 * where the processor has them). */
PAR_CLONES
static int column_changed(const double *v, const size_t *idx, const double *old, size_t n)
{
    enum { BLOCK = 256 };
    for (size_t k0 = 0; k0 < n; k0 += BLOCK) {
        const size_t k1 = n - k0 < BLOCK ? n : k0 + BLOCK;
        uint64_t diff = 0;
        for (size_t k = k0; k < k1; ++k) {
            uint64_t a, b;
            memcpy(&a, &v[idx[k]], sizeof a);
            memcpy(&b, &old[k], sizeof b);
            diff |= a ^ b;
        }
        if (diff) return 1;
    }
    return 0;
}

/* to[0..n) = from[0..n), the runs' block copy. A loop, not memcpy: glibc copies blocks of more
 * than a few kB (a box's boundary layers) with `rep movsb`, which valgrind counts per byte, so
 * the instruction counts of bench/mpi_instr.sh would show eight per value where the vector
 * loop takes about one; GCC is kept from turning the loop back into memcpy. */
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-tree-loop-distribute-patterns")))
#endif
PAR_CLONES static void
copy_doubles(double *restrict to, const double *restrict from, size_t n)
{
    for (size_t k = 0; k < n; ++k) to[k] = from[k];
}

/* out[k] = v[idx[k]] */
PAR_CLONES
static void gather_column(double *restrict out, const double *restrict v, const size_t *idx,
                          size_t n)
{
    for (size_t k = 0; k < n; ++k) out[k] = v[idx[k]];
}

/* A run of an index list: entries [k, k + len) are the local indices at, at + 1, ... */
typedef struct idx_run {
    size_t at, k, len;
} idx_run;

/* The runs of idx[0..), rank q's part [displ[q], displ[q] + count[q]) starting at run off[q];
 * *use: whether they are long enough (8 entries on average) that block compares and copies
 * beat the per-value gathers. */
static int runs_of(const par_solver *ps, const size_t *idx, const int *displ, const int *count,
                   idx_run **run, size_t **off, int *use)
{
    size_t n = 0, m = 0;
    for (int q = 0; q < ps->size; ++q)
        for (size_t k = (size_t)displ[q]; k < (size_t)displ[q] + (size_t)count[q]; ++k, ++n)
            m += k == (size_t)displ[q] || idx[k] != idx[k - 1] + 1;
    free(*run);
    free(*off);
    *run = malloc((m ? m : 1) * sizeof **run);
    *off = malloc(((size_t)ps->size + 1) * sizeof **off);
    if (!*run || !*off) return par_fail_mem();
    m = 0;
    for (int q = 0; q < ps->size; ++q) {
        (*off)[q] = m;
        for (size_t k = (size_t)displ[q]; k < (size_t)displ[q] + (size_t)count[q]; ++k)
            if (k == (size_t)displ[q] || idx[k] != idx[k - 1] + 1)
                (*run)[m++] = (idx_run){idx[k], k, 1};
            else
                ++(*run)[m - 1].len;
    }
    (*off)[ps->size] = m;
    *use = 8 * m <= n;
    return CONSPH_OK;
}

/* Whether v at the sent (recv 0) or received (1) particles differs bitwise from old. */
static int list_changed(const par_solver *ps, int recv, const double *v, const double *old)
{
    const int use = recv ? ps->rruns : ps->sruns;
    const idx_run *run = recv ? ps->rrun : ps->srun;
    const size_t nrun = (recv ? ps->rrun_off : ps->srun_off)[ps->size];
    if (use) {
        for (size_t r = 0; r < nrun; ++r)
            if (memcmp(v + run[r].at, old + run[r].k, run[r].len * sizeof(double))) return 1;
        return 0;
    }
    const size_t n = nrun ? run[nrun - 1].k + run[nrun - 1].len : 0;
    return column_changed(v, recv ? ps->ridx : ps->sidx, old, n);
}

/* out[k - k0] = v[idx[k]] for the sent (recv 0) or received (1) entries of ranks [q0, q1),
 * k0 the first of them. */
static void list_gather(const par_solver *ps, int recv, double *out, const double *v, int q0,
                        int q1)
{
    const size_t *off = recv ? ps->rrun_off : ps->srun_off;
    const idx_run *run = recv ? ps->rrun : ps->srun;
    const size_t r0 = off[q0], r1 = off[q1];
    if (r0 == r1) return;
    const size_t k0 = run[r0].k;
    if (recv ? ps->rruns : ps->sruns) {
        for (size_t r = r0; r < r1; ++r)
            copy_doubles(out + (run[r].k - k0), v + run[r].at, run[r].len);
        return;
    }
    const size_t k1 = run[r1 - 1].k + run[r1 - 1].len;
    gather_column(out, v, (recv ? ps->ridx : ps->sidx) + k0, k1 - k0);
}

/* ---- the halo refresh (consph_sys_split) ---- */

/* The columns of a refresh: positions, every named field's components, then the scratch
 * blocks; col[c][i] is column c of local particle i. Returns their count (0: out of memory). */
static size_t halo_columns(par_solver *ps, consph_sys *sys, size_t blocks)
{
    consph_particles *p = sys->p;
    const size_t ncols = values_per_particle(p) + blocks;
    if (ncols > ps->col_cap) {
        double **c = realloc(ps->col, ncols * sizeof *c);
        if (c) ps->col = c;
        unsigned char *m = c ? realloc(ps->mask, ncols) : NULL;
        if (m) ps->mask = m;
        unsigned char *kp = m ? realloc(ps->kept, ncols) : NULL;
        if (kp) {
            ps->kept = kp;
            memset(kp + ps->col_cap, 0, ncols - ps->col_cap);
        }
        size_t *sl = kp ? realloc(ps->sel, ncols * sizeof *sl) : NULL;
        if (sl) ps->sel = sl;
        if (!c || !m || !kp || !sl) return 0;
        ps->col_cap = ncols;
    }
    size_t k = 0;
    for (int a = 0; a < p->dim; ++a) ps->col[k++] = p->x[a];
    for (int f = 0; f < p->nfields; ++f)
        for (int c = 0; c < p->fields[f].ncomp; ++c)
            ps->col[k++] = p->fields[f].data + (size_t)c * p->cap;
    for (size_t b = 0; b < blocks; ++b) ps->col[k++] = sys->scratch + b * p->n;
    return ncols;
}

/* Room for ncols columns of the kept state, the columns already kept preserved. */
static int halo_state_reserve(par_solver *ps, size_t ncols)
{
    const size_t ns = ps->sdispl[ps->size - 1] + (size_t)ps->scount[ps->size - 1];
    const size_t nr = ps->rdispl[ps->size - 1] + (size_t)ps->rcount[ps->size - 1];
    int st = reserve(&ps->sent, &ps->sent_cap, ns * ncols);
    if (st == CONSPH_OK) st = reserve(&ps->got, &ps->got_cap, nr * ncols);
    if (st == CONSPH_OK && ncols * (size_t)ps->size > ps->masks_cap) {
        unsigned char *m = realloc(ps->masks, ncols * (size_t)ps->size);
        if (!m) return par_fail_mem();
        ps->masks = m;
        ps->masks_cap = ncols * (size_t)ps->size;
    }
    return st;
}

/* After a cut: install made the halo from its owners' packed values, so the kept state is
 * what every rank holds now, positions and fields (the scratch is not carried); the columns
 * without carry[c] are zero on every rank, and so are their kept copies. */
static int halo_state_from_cut(par_solver *ps, consph_sys *sys, const unsigned char *carry)
{
    const size_t ncols = halo_columns(ps, sys, 0);
    int st = ncols ? halo_state_reserve(ps, ncols) : par_fail_mem();
    if (st != CONSPH_OK) return st;
    const size_t ns = ps->sdispl[ps->size - 1] + (size_t)ps->scount[ps->size - 1];
    const size_t nr = ps->rdispl[ps->size - 1] + (size_t)ps->rcount[ps->size - 1];
    for (size_t c = 0; c < ncols; ++c) {
        const double *v = ps->col[c];
        if (!carry[c]) {
            memset(ps->sent + c * ns, 0, ns * sizeof(double));
            memset(ps->got + c * nr, 0, nr * sizeof(double));
            continue;
        }
        list_gather(ps, 0, ps->sent + c * ns, v, 0, ps->size);
        list_gather(ps, 1, ps->got + c * nr, v, 0, ps->size);
    }
    ps->base = ncols;
    memset(ps->kept, 1, ncols);
    memset(ps->kept + ncols, 0, ps->col_cap - ncols);
    return CONSPH_OK;
}

/* column c goes from rank q (mask mq) to rank r (mask mr) when it changed on q or r holds no
 * copy of it */
static int col_goes(const unsigned char *mq, const unsigned char *mr, size_t c)
{
    return (mq[c] & COL_CHANGED) || (mr[c] & COL_WANTED);
}

/* CONSPH_TEST_HALO_POISON set: after a refresh that a pass's declaration narrowed, the halo's
 * fields and scratch blocks it left out are NaN (the next refresh that brings one rewrites it
 * from the kept copy), so that a read the declaration misses shows in the results. Not the
 * positions: particles move only through consph_sys_update, whose refresh brings them, so the
 * halo's are current whatever a pass declares (a pass that gathers reads them). */
static int halo_poison = -1;

/* The components of field `name` that r names (a bit each; 0: none). */
static unsigned reads_comps(const consph_sys_reads *r, const char *name, int ncomp)
{
    const unsigned all = ncomp >= 32 ? ~0u : (1u << ncomp) - 1u;
    for (int k = 0; k < CONSPH_SYS_READS_MAX && r->fields[k]; ++k)
        if (!strcmp(r->fields[k], name)) return r->comps[k] ? r->comps[k] & all : all;
    return 0;
}

/* The columns this refresh brings, ascending, in ps->sel: the positions alone, those the next
 * pass declared (sys->reads), or all nall. Returns their count. */
static size_t halo_select(par_solver *ps, const consph_sys *sys, size_t nall, size_t blocks,
                          int positions_only)
{
    const consph_particles *p = sys->p;
    size_t m = 0;
    if (!positions_only && !sys->reads_set) {
        for (size_t c = 0; c < nall; ++c) ps->sel[m++] = c;
        return m;
    }
    const consph_sys_reads *r = &sys->reads;
    if (positions_only || r->positions)
        for (int a = 0; a < p->dim; ++a) ps->sel[m++] = (size_t)a;
    if (positions_only) return m;
    size_t c = (size_t)p->dim;
    for (int f = 0; f < p->nfields; ++f) {
        const int nc = p->fields[f].ncomp;
        const unsigned comps = reads_comps(r, p->fields[f].name, nc);
        for (int k = 0; k < nc; ++k)
            if (comps >> k & 1u) ps->sel[m++] = c + (size_t)k;
        c += (size_t)nc;
    }
    if (r->scratch)
        for (size_t b = 0; b < blocks; ++b) ps->sel[m++] = c + b;
    return m;
}

/* The halo's columns from their owners: every one (refresh), the positions alone
 * (refresh_positions), or those the next pass declared it reads (consph_sys_next_reads). */
static int refresh_some(consph_sys *sys, par_solver *ps, int positions_only)
{
    consph_particles *p = sys->p;
    const size_t n = p->n;
    const double t0 = MPI_Wtime();
    /* the scratch a job asked for in blocks of n (consph_sys_scratch: k·n values) */
    size_t blocks = 0;
    if (sys->scratch && n && sys->scratch_asked % n == 0) blocks = sys->scratch_asked / n;
    const size_t nall = halo_columns(ps, sys, blocks);
    const size_t ns = ps->sdispl[ps->size - 1] + (size_t)ps->scount[ps->size - 1];
    const size_t nr = ps->rdispl[ps->size - 1] + (size_t)ps->rcount[ps->size - 1];
    int st = nall ? halo_state_reserve(ps, nall) : par_fail_mem();
    if (st != CONSPH_OK) MPI_Abort(ps->comm, 1); /* the other ranks wait in the exchange */
    /* the kept columns still mean the same where the positions and fields are counted alike
     * (the scratch blocks follow them) */
    if (nall - blocks != ps->base) {
        memset(ps->kept, 0, ps->col_cap);
        ps->base = nall - blocks;
    }
    /* every rank selects alike: the same pass with the same fields and scratch blocks */
    const size_t nsel = halo_select(ps, sys, nall, blocks, positions_only);
    const size_t *sel = ps->sel;
    for (size_t j = 0; j < nsel; ++j) {
        const size_t c = sel[j];
        const int valid = ps->kept[c];
        const int changed = !valid || list_changed(ps, 0, ps->col[c], ps->sent + c * ns);
        ps->mask[j] = (unsigned char)((changed ? COL_CHANGED : 0) | (valid ? 0 : COL_WANTED));
    }
    /* a pass that reads nothing at the neighbours (the volumes) exchanges nothing: every rank
     * selected none */
    if (nsel)
        MPI_Allgather(ps->mask, (int)nsel, MPI_UNSIGNED_CHAR, ps->masks, (int)nsel,
                      MPI_UNSIGNED_CHAR, ps->comm);
    size_t sdbl = 0, rdbl = 0;
    for (int q = 0; q < ps->size; ++q) {
        const unsigned char *mq = ps->masks + (size_t)q * nsel;
        for (size_t j = 0; j < nsel; ++j) {
            if (col_goes(ps->mask, mq, j)) sdbl += (size_t)ps->scount[q];
            if (col_goes(mq, ps->mask, j)) rdbl += (size_t)ps->rcount[q];
        }
    }
    if (sdbl > INT32_MAX || rdbl > INT32_MAX)
        st = consph_fail(CONSPH_EINVAL, "MPI decomposition: more than 2^31 values to one rank; "
                                        "use more ranks");
    if (st == CONSPH_OK) st = reserve(&ps->sbuf, &ps->sbuf_cap, sdbl);
    if (st == CONSPH_OK) st = reserve(&ps->rbuf, &ps->rbuf_cap, rdbl);
    if (st != CONSPH_OK) MPI_Abort(ps->comm, 1);
    /* every rank sees every mask: when none asks for a column, none calls the exchange */
    int any = 0;
    for (size_t k = 0; k < nsel * (size_t)ps->size; ++k) any |= ps->masks[k] != 0;
    size_t so = 0, ro = 0;
    for (int q = 0; q < ps->size; ++q) {
        const unsigned char *mq = ps->masks + (size_t)q * nsel;
        const size_t s0 = (size_t)ps->sdispl[q], s1 = s0 + (size_t)ps->scount[q];
        const size_t r0 = (size_t)ps->rdispl[q], r1 = r0 + (size_t)ps->rcount[q];
        ps->sddis[q] = (int)so;
        ps->rddis[q] = (int)ro;
        for (size_t j = 0; j < nsel; ++j) {
            if (col_goes(ps->mask, mq, j)) {
                const double *v = ps->col[sel[j]];
                list_gather(ps, 0, ps->sbuf + so, v, q, q + 1);
                so += s1 - s0;
            }
            if (col_goes(mq, ps->mask, j)) ro += r1 - r0;
        }
        ps->sdbl[q] = (int)(so - (size_t)ps->sddis[q]);
        ps->rdbl[q] = (int)(ro - (size_t)ps->rddis[q]);
    }
    if (any)
        MPI_Alltoallv(ps->sbuf, ps->sdbl, ps->sddis, MPI_DOUBLE, ps->rbuf, ps->rdbl, ps->rddis,
                      MPI_DOUBLE, ps->comm);
    ro = 0;
    for (int q = 0; q < ps->size; ++q) {
        const unsigned char *mq = ps->masks + (size_t)q * nsel;
        const size_t r0 = (size_t)ps->rdispl[q], r1 = r0 + (size_t)ps->rcount[q];
        for (size_t j = 0; j < nsel; ++j)
            if (col_goes(mq, ps->mask, j)) {
                copy_doubles(ps->got + sel[j] * nr + r0, ps->rbuf + ro, r1 - r0);
                ro += r1 - r0;
            }
    }
    /* every selected column of the halo from what its owners sent last: a scheme may have
     * written halo values since, and the pass must read the owners'. A column whose halo holds
     * them already (most: neither its owners nor this rank changed it) is only read. */
    for (size_t j = 0; j < nsel; ++j) {
        const size_t c = sel[j];
        double *v = ps->col[c];
        const double *in = ps->got + c * nr;
        if (ps->rruns) {
            const idx_run *run = ps->rrun;
            for (size_t r = 0; r < ps->rrun_off[ps->size]; ++r)
                if (memcmp(v + run[r].at, in + run[r].k, run[r].len * sizeof(double)))
                    copy_doubles(v + run[r].at, in + run[r].k, run[r].len);
        } else if (column_changed(v, ps->ridx, in, nr)) {
            for (size_t k = 0; k < nr; ++k) v[ps->ridx[k]] = in[k];
        }
        if (ps->mask[j] & COL_CHANGED) {
            double *old = ps->sent + c * ns;
            list_gather(ps, 0, old, v, 0, ps->size);
        }
        ps->kept[c] = 1;
    }
    /* a full refresh keeps the columns it counted (scratch blocks beyond them are asked for
     * anew), as a narrowed one does; the positions alone leave the others as they were */
    if (!positions_only) memset(ps->kept + nall, 0, ps->col_cap - nall);
    if (halo_poison < 0) halo_poison = getenv("CONSPH_TEST_HALO_POISON") != NULL;
    if (halo_poison && !positions_only && sys->reads_set)
        for (size_t c = 0, j = 0; c < nall; ++c) {
            if (j < nsel && sel[j] == c) {
                ++j;
                continue;
            }
            if (c < (size_t)p->dim) continue;
            for (size_t k = 0; k < nr; ++k) ps->col[c][ps->ridx[k]] = NAN;
        }
    ps->bytes += (double)(sdbl * sizeof(double) + nsel * (size_t)(ps->size - 1));
    ps->seconds += MPI_Wtime() - t0;
    return CONSPH_OK;
}

/* The cache's pairs per particle, when it holds the current state's and they were not taken
 * yet: every pass starts with a refresh, so the last cache of a step is taken by the next pass
 * or by the re-sort (migrate), whichever comes first. */
static void pairs_take(par_solver *ps, const consph_sys *sys)
{
    if (!sys->nlist) return;
    const unsigned long e = nlist_pair_counts(sys->nlist, NULL);
    if (!e || e == ps->pairs_epoch) return;
    const size_t n = sys->p->n;
    if (n > ps->pairs_cap) {
        uint32_t *q = realloc(ps->pairs, n * sizeof *q);
        if (!q) return; /* the cut then counts particles */
        ps->pairs = q;
        ps->pairs_cap = n;
    }
    nlist_pair_counts(sys->nlist, ps->pairs);
    ps->pairs_epoch = e;
}

/* Where the pair cache kept no counts (a scheme with fewer passes per position state): each
 * owned particle's weight in ps->pairs is the candidates that the walk of its cell visits
 * (consph_nnps_cell_runs on this rank's search, built on the current positions, whose halo
 * holds every owned cell's neighbourhood): the gather's work, an integer. 0: not available. */
static int candidates_take(par_solver *ps, const consph_sys *sys)
{
    consph_nnps_slots v;
    const size_t n = sys->p->n;
    if (!sys->dest || consph_nnps_slots_get(sys->nnps, &v) != CONSPH_OK || v.n != n) return 0;
    if (n > ps->pairs_cap) {
        uint32_t *q = realloc(ps->pairs, n * sizeof *q);
        if (!q) return 0;
        ps->pairs = q;
        ps->pairs_cap = n;
    }
    consph_nnps_runs runs;
    memset(&runs, 0, sizeof runs);
    int ok = 1;
    for (size_t c = 0; ok && c < v.ncells; ++c) {
        const size_t s0 = v.cell_start[c], s1 = v.cell_start[c + 1];
        size_t s = s0;
        while (s < s1 && !sys->dest[consph_nnps_slot_particle(&v, s)]) ++s;
        if (s == s1) continue;
        ok = consph_nnps_cell_runs(sys->nnps, c, &runs) != (size_t)-1;
        for (s = s0; ok && s < s1; ++s)
            ps->pairs[consph_nnps_slot_particle(&v, s)] = (uint32_t)runs.candidates;
    }
    consph_nnps_runs_free(&runs);
    return ok;
}

static int refresh(consph_sys *sys, void *ctx)
{
    pairs_take(ctx, sys);
    return refresh_some(sys, ctx, 0);
}

/* Before a search rebuild (consph_sys_update) only the halo's positions are read; the pass
 * that follows refreshes every column that changed since. */
static int refresh_positions(consph_sys *sys, void *ctx)
{
    return refresh_some(sys, ctx, 1);
}

static double split_max(void *ctx, double v)
{
    par_solver *ps = ctx;
    double in[2] = {isnan(v) ? 1.0 : 0.0, isnan(v) ? -INFINITY : v}, out[2];
    MPI_Allreduce(in, out, 2, MPI_DOUBLE, MPI_MAX, ps->comm);
    return out[0] > 0.0 ? NAN : out[1];
}

/* ---- the boxes ---- */

/* Whether the axis cells' weights w[0..nc) fit k pieces of consecutive cells of at most cap
 * each. */
static int pieces_fit(const int64_t *w, int64_t nc, int k, int64_t cap)
{
    int pieces = 1;
    int64_t cur = 0;
    for (int64_t c = 0; c < nc; ++c) {
        if (w[c] > cap) return 0;
        if (cur + w[c] > cap) {
            if (++pieces > k) return 0;
            cur = 0;
        }
        cur += w[c];
    }
    return 1;
}

/* The cells of one axis to its k pieces (k <= nc, at least one cell each) so that the heaviest
 * piece is as light as the cells allow (weights per axis cell summed over the ranks: the same
 * cut on every rank): the least cap that k pieces fit, by bisection, then the pieces filled up
 * to it from the first cell. */
static void cut_axis(int64_t *cut, int *piece, int k, int64_t nc, const int64_t *w)
{
    int64_t lo = 0, hi = 0;
    for (int64_t c = 0; c < nc; ++c) {
        hi += w[c];
        if (w[c] > lo) lo = w[c];
    }
    while (lo < hi) {
        const int64_t mid = lo + (hi - lo) / 2;
        if (pieces_fit(w, nc, k, mid))
            hi = mid;
        else
            lo = mid + 1;
    }
    cut[0] = 0;
    int r = 1;
    int64_t cur = 0;
    for (int64_t c = 0; c < nc && r < k; ++c) {
        /* a new piece where the cap is reached, or where each piece left needs a cell */
        if ((c > cut[r - 1] && cur + w[c] > lo) || nc - c == k - r) {
            cut[r++] = c;
            cur = 0;
        }
        cur += w[c];
    }
    cut[k] = nc;
    for (int q = 0; q < k; ++q)
        for (int64_t x = cut[q]; x < cut[q + 1]; ++x) piece[x] = q;
}

/* The rank owning the cell whose axis cells are ac. */
static int owner_of(const par_solver *ps, const int64_t *ac)
{
    int q = 0;
    for (int a = ps->dim - 1; a >= 0; --a) q = q * ps->k[a] + ps->piece[a][ac[a]];
    return q;
}

/* Whether axis cell c is within the halo width of piece i along axis a (the nearest periodic
 * image), or in it (2). */
static int piece_covers(const par_solver *ps, int a, int i, int64_t c)
{
    const int64_t lo = ps->cut[a][i], hi = ps->cut[a][i + 1], n = ps->nc[a];
    if (c >= lo && c < hi) return 2;
    int64_t below = lo - c, above = c - (hi - 1);
    if (ps->periodic[a]) {
        below = ((below % n) + n) % n;
        above = ((above % n) + n) % n;
    } else {
        if (below < 0) below = INT64_MAX;
        if (above < 0) above = INT64_MAX;
    }
    return (below < above ? below : above) <= ps->width[a];
}

/* Whether the cell ac is in rank q's halo: not q's, and along every axis within the halo
 * width of q's box. */
static int in_halo(const par_solver *ps, int q, const int64_t *ac)
{
    int inside = 1;
    for (int a = 0; a < ps->dim; ++a) {
        const int iq = q % ps->k[a];
        q /= ps->k[a];
        const int cov = piece_covers(ps, a, iq, ac[a]);
        if (!cov) return 0;
        inside = inside && cov == 2;
    }
    return !inside;
}

/* The cover lists of every axis after a cut. */
static void cover_axes(par_solver *ps)
{
    for (int a = 0; a < ps->dim; ++a) {
        int m = 0;
        for (int64_t c = 0; c < ps->nc[a]; ++c) {
            ps->cover_off[a][c] = m;
            for (int i = 0; i < ps->k[a]; ++i)
                if (piece_covers(ps, a, i, c)) ps->cover[a][m++] = i;
        }
        ps->cover_off[a][ps->nc[a]] = m;
    }
}

/* The ranks whose box or halo holds the cell ac (its owner and the ranks whose halo holds
 * it), ascending, into ps->ranks; returns their count. Only they, not every rank, are looked
 * at per particle. */
static int covering(const par_solver *ps, const int64_t *ac)
{
    static const int zero = 0;
    const int *l[CONSPH_MAX_DIM];
    int m[CONSPH_MAX_DIM];
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        if (a < ps->dim) {
            const int o = ps->cover_off[a][ac[a]];
            l[a] = ps->cover[a] + o;
            m[a] = ps->cover_off[a][ac[a] + 1] - o;
        } else {
            l[a] = &zero;
            m[a] = 1;
        }
    }
    int n = 0;
    for (int t2 = 0; t2 < m[2]; ++t2)
        for (int t1 = 0; t1 < m[1]; ++t1)
            for (int t0 = 0; t0 < m[0]; ++t0)
                ps->ranks[n++] = (l[2][t2] * ps->k[1] + l[1][t1]) * ps->k[0] + l[0][t0];
    return n;
}

/* The pairs (rank, particle) of covering for particles idx[0..n) (ac: their axis cells, dim
 * per particle; only those with want[k], when given), in particle order, rank `skip` left
 * out; each rank's count added to count[rank + 1]. Covering is found once per particle. */
typedef struct cover_pairs {
    int *q;
    size_t *k, n, cap;
} cover_pairs;

static int cover_collect(par_solver *ps, cover_pairs *cp, const int64_t *ac, size_t n,
                         const unsigned char *want, int skip, size_t *count)
{
    cp->n = 0;
    const size_t dim = (size_t)ps->dim;
    /* the particles come in cell order, about ten to a cell: a particle in the previous one's
     * cell has its ranks (ps->ranks[0..nq), or none where alone and one == skip) */
    const int64_t *prev = NULL;
    int nq = 0, none = 0;
    for (size_t k = 0; k < n; ++k) {
        if (want && !want[k]) continue;
        const int64_t *a = ac + k * dim;
        int same = prev != NULL;
        for (size_t x = 0; same && x < dim; ++x) same = a[x] == prev[x];
        if (!same) {
            prev = a;
            /* a cell that one piece along every axis covers (most: away from the halos) has
             * one rank, found without covering's product */
            int one = 0, alone = 1;
            for (int x = ps->dim - 1; alone && x >= 0; --x) {
                const int o = ps->cover_off[x][a[x]];
                alone = ps->cover_off[x][a[x] + 1] - o == 1;
                one = one * ps->k[x] + ps->cover[x][o];
            }
            none = alone && one == skip;
            nq = 1;
            if (alone)
                ps->ranks[0] = one;
            else
                nq = covering(ps, a);
        }
        if (none) continue;
        if (cp->n + (size_t)nq > cp->cap) {
            const size_t cap = 2 * (cp->n + (size_t)nq) + 64;
            int *q = realloc(cp->q, cap * sizeof *q);
            if (q) cp->q = q;
            size_t *kk = q ? realloc(cp->k, cap * sizeof *kk) : NULL;
            if (kk) cp->k = kk;
            if (!q || !kk) return par_fail_mem();
            cp->cap = cap;
        }
        for (int t = 0; t < nq; ++t)
            if (ps->ranks[t] != skip) {
                cp->q[cp->n] = ps->ranks[t];
                cp->k[cp->n++] = k;
                ++count[ps->ranks[t] + 1];
            }
    }
    return CONSPH_OK;
}

static int count_cut; /* par_force_count_cut */

void par_force_count_cut(int on)
{
    count_cut = on;
}

/* The weights of a cut: none (particle counts), the pairs visited, the search's candidates. */
enum { WEIGH_COUNT, WEIGH_PAIRS, WEIGH_CANDIDATES, WEIGH_KINDS };

/* The cut of every axis by the owned particles' weights per axis cell (ac: dim per particle;
 * w: their weights of kind `kind`, NULL with WEIGH_COUNT): the pairs each visited plus one where
 * every rank has them, else the candidates of its cell plus one where every rank has those,
 * else the particle counts. One MPI_Allreduce of a histogram per kind and the ranks with each. */
static int cut_boxes(par_solver *ps, const int64_t *ac, const uint32_t *w, int kind, size_t n)
{
    int64_t total = 0;
    for (int a = 0; a < ps->dim; ++a) total += ps->nc[a];
    const size_t len = WEIGH_KINDS * (size_t)total + WEIGH_KINDS;
    int64_t *count = consph_calloc(len, sizeof(int64_t));
    int64_t *all = consph_calloc(len, sizeof(int64_t));
    if (!count || !all) {
        free(count);
        free(all);
        return par_fail_mem();
    }
    if (!w || count_cut) kind = WEIGH_COUNT;
    int64_t *with = count + WEIGH_KINDS * total; /* per kind: the ranks that weigh so */
    with[WEIGH_COUNT] = with[kind] = 1;
    int64_t *mine = count + (size_t)kind * (size_t)total;
    for (size_t o = 0; o < n; ++o) {
        int64_t off = 0;
        const int64_t wo = w ? (int64_t)w[o] + 1 : 1;
        for (int a = 0; a < ps->dim; ++a) {
            const int64_t c = off + ac[o * (size_t)ps->dim + (size_t)a];
            ++count[c];
            if (kind != WEIGH_COUNT) mine[c] += wo;
            off += ps->nc[a];
        }
    }
    MPI_Allreduce(count, all, (int)len, MPI_INT64_T, MPI_SUM, ps->comm);
    const int64_t *ranks_with = all + WEIGH_KINDS * total;
    const int by = ranks_with[WEIGH_PAIRS] == ps->size        ? WEIGH_PAIRS
                   : ranks_with[WEIGH_CANDIDATES] == ps->size ? WEIGH_CANDIDATES
                                                              : WEIGH_COUNT;
    ps->weighed = by;
    int64_t off = (int64_t)by * total;
    for (int a = 0; a < ps->dim; ++a) {
        cut_axis(ps->cut[a], ps->piece[a], ps->k[a], ps->nc[a], all + off);
        off += ps->nc[a];
    }
    cover_axes(ps);
    free(count);
    free(all);
    return CONSPH_OK;
}

typedef struct held {
    int64_t cell; /* the whole cell index, as the search bins it */
    double g;     /* index in the previous serial order */
    size_t at;    /* in the received values */
} held;

static int held_cmp(const void *pa, const void *pb)
{
    const held *a = pa, *b = pb;
    if (a->cell != b->cell) return a->cell < b->cell ? -1 : 1;
    return a->g < b->g ? -1 : a->g > b->g;
}

/* The row of the axis cells ac (the cells beyond axis 0: the whole cell index over nc[0]). */
static int64_t row_of(const par_solver *ps, const int64_t *ac)
{
    int64_t r = 0;
    for (int a = ps->dim - 1; a >= 1; --a) r = r * ps->nc[a] + ac[a];
    return r;
}

/* The whole cell index of x, and its cell along every axis in ac. */
static int64_t cell_of(const par_solver *ps, const consph_nnps *nn, const double *x, int64_t *ac)
{
    int64_t c = 0;
    for (int a = ps->dim - 1; a >= 0; --a) {
        ac[a] = nnps_axis_cell(nn, a, x[a]);
        c = c * ps->nc[a] + ac[a];
    }
    return c;
}

/* h[0..n) sorted by (cell, g), h being the runs [bound[r], bound[r + 1]) for r < nb, each
 * ascending in g (this rank's particles, then each sender's, in their serial order): the runs
 * merged by g, then a stable counting sort by cell over the cells they span (a rank's box and
 * halo), as the serial re-sort sorts by cell the previous order. (cell, g) is unique: any sort
 * gives the same order, and a span of cells far larger than the records (not met by boxes)
 * goes to qsort. */
static int sort_held(held *h, size_t n, const size_t *bound, int nb)
{
    if (n < 2) return CONSPH_OK;
    int64_t lo = h[0].cell, hi = h[0].cell;
    for (size_t k = 1; k < n; ++k) {
        if (h[k].cell < lo) lo = h[k].cell;
        if (h[k].cell > hi) hi = h[k].cell;
    }
    const size_t span = (size_t)(hi - lo) + 1;
    if (span > 8 * n + 4096) {
        qsort(h, n, sizeof *h, held_cmp);
        return CONSPH_OK;
    }
    held *t = malloc(n * sizeof *t);
    size_t *b = malloc(((size_t)nb + 1) * sizeof *b);
    size_t *start = consph_calloc(span + 1, sizeof *start);
    if (!t || !b || !start) {
        free(t);
        free(b);
        free(start);
        return par_fail_mem();
    }
    memcpy(b, bound, ((size_t)nb + 1) * sizeof *b);
    held *src = h, *dst = t;
    while (nb > 1) {
        int out = 0;
        for (int r = 0; r < nb; r += 2) {
            const size_t lo_r = b[r], mid = b[r + 1], hi_r = r + 2 <= nb ? b[r + 2] : mid;
            size_t i = lo_r, j = mid, o = lo_r;
            while (i < mid && j < hi_r) dst[o++] = src[j].g < src[i].g ? src[j++] : src[i++];
            while (i < mid) dst[o++] = src[i++];
            while (j < hi_r) dst[o++] = src[j++];
            b[out++] = lo_r;
        }
        b[out] = n;
        nb = out;
        held *x = src;
        src = dst;
        dst = x;
    }
    /* src: by g; dst: by cell, then g */
    for (size_t k = 0; k < n; ++k) ++start[src[k].cell - lo + 1];
    for (size_t c = 0; c < span; ++c) start[c + 1] += start[c];
    for (size_t k = 0; k < n; ++k) dst[start[src[k].cell - lo]++] = src[k];
    if (dst != h) memcpy(h, dst, n * sizeof *h);
    free(t);
    free(b);
    free(start);
    return CONSPH_OK;
}

/* The columns of p (positions, then every field's components), as values_per_particle counts
 * them. */
static void columns_of(const consph_particles *p, double **col)
{
    size_t k = 0;
    for (int a = 0; a < p->dim; ++a) col[k++] = p->x[a];
    for (int f = 0; f < p->nfields; ++f)
        for (int c = 0; c < p->fields[f].ncomp; ++c)
            col[k++] = p->fields[f].data + (size_t)c * p->cap;
}

/* A run of the new set's slots [k, k + len) whose values are consecutive in one source: this
 * rank's particles from `from` (kind 0), or the received columns from record `from` (1). */
typedef struct copy_run {
    size_t k, from, len;
    int kind;
} copy_run;

/* Every column of dst from the runs: between re-sorts few particles change cells or ranks, so
 * the runs are long and a column is a few block copies, not a gather per value. */
static void copy_runs(double *restrict dst, const double *own, const double *recv,
                      const copy_run *run, size_t nrun)
{
    for (size_t r = 0; r < nrun; ++r) {
        const double *from = (run[r].kind ? recv : own) + run[r].from;
        double *to = dst + run[r].k;
        if (run[r].len >= 8)
            copy_doubles(to, from, run[r].len);
        else
            for (size_t t = 0; t < run[r].len; ++t) to[t] = from[t];
    }
}

/* The particles this rank now holds become its system: sorted by (cell, g), the owned ones
 * marked, the exchange lists made. They are this rank's particles self[0..nself) (their axis
 * cells at sac, dim each), then the nrecv received, rcnt[q] from rank q in its order: column c
 * of record r at recv[c·nrecv + r] (positions, fields' components), g at rg[r]. A column
 * without carry[c] is not read: the new set holds zeros there. */
static int install(consph_solver *s, par_solver *ps, const double *recv, const double *rg,
                   size_t nrecv, const size_t *self, const int64_t *sac, size_t nself,
                   const int *rcnt, const unsigned char *carry)
{
    const size_t m = nself + nrecv;
    consph_particles *p = s->sys.p;
    const int dim = p->dim;
    const size_t nseg = (size_t)ps->nrows * (size_t)ps->k[0];
    held *h = malloc((m ? m : 1) * sizeof *h);
    int64_t *acell = malloc((m ? m : 1) * (size_t)dim * sizeof *acell);
    int *owner = malloc((m ? m : 1) * sizeof *owner);
    int64_t *segn = consph_calloc(nseg, sizeof(int64_t));
    /* per record: its axis cells and owner, found once */
    int64_t *rac = malloc((m ? m : 1) * (size_t)dim * sizeof *rac);
    int *rowner = malloc((m ? m : 1) * sizeof *rowner);
    if (!h || !acell || !owner || !segn || !rac || !rowner) {
        free(h);
        free(acell);
        free(owner);
        free(segn);
        free(rac);
        free(rowner);
        return par_fail_mem();
    }
    size_t kept = 0;
    /* the runs of records in the previous order: this rank's, then each sender's */
    size_t *bound = malloc(((size_t)ps->size + 2) * sizeof *bound);
    if (!bound) MPI_Abort(ps->comm, 1);
    int nb = 0, sender = 0;
    size_t next = nself;
    bound[nb++] = 0;
    int64_t last_cell = -1;
    int last_owner = 0, last_held = 0;
    /* records k < nself: this rank's particle self[k]; then the received ones */
    for (size_t k = 0; k < m; ++k) {
        for (; k == next && sender < ps->size; next += (size_t)rcnt[sender++])
            if (bound[nb - 1] != kept) bound[nb++] = kept;
        int64_t *ac = rac + k * (size_t)dim;
        int64_t c;
        if (k < nself) {
            /* the migration found this rank's cells */
            c = 0;
            for (int a = dim - 1; a >= 0; --a) {
                ac[a] = sac[k * (size_t)dim + (size_t)a];
                c = c * ps->nc[a] + ac[a];
            }
        } else {
            double xk[CONSPH_MAX_DIM];
            for (int a = 0; a < dim; ++a) xk[a] = recv[(size_t)a * nrecv + (k - nself)];
            c = cell_of(ps, s->sys.nnps, xk, ac);
        }
        /* records come mostly in cell order: the previous record's cell has its owner, and
         * whether this rank holds it */
        if (c != last_cell) {
            last_cell = c;
            last_owner = owner_of(ps, ac);
            last_held = last_owner == ps->rank || in_halo(ps, ps->rank, ac);
        }
        rowner[k] = last_owner;
        if (!last_held) continue;
        h[kept].cell = c;
        h[kept].g = k < nself ? ps->g[self[k]] : rg[k - nself];
        h[kept].at = k;
        ++kept;
    }
    if (bound[nb - 1] != kept || nb == 1) bound[nb++] = kept;
    int st = sort_held(h, kept, bound, nb - 1);
    free(bound);
    consph_particles np;
    if (st == CONSPH_OK) st = particles_for(&ps->spare, &np, p, kept);
    size_t nown = 0;
    unsigned char *dest = st == CONSPH_OK ? consph_calloc(kept ? kept : 1, 1) : NULL;
    size_t *origin = st == CONSPH_OK ? consph_calloc(kept ? kept : 1, sizeof(size_t)) : NULL;
    double *g = st == CONSPH_OK ? malloc((kept ? kept : 1) * sizeof(double)) : NULL;
    if (st == CONSPH_OK && (!dest || !origin || !g)) st = par_fail_mem();
    /* the new set column by column, from runs of consecutive sources */
    const size_t ncol = values_per_particle(p);
    copy_run *run = st == CONSPH_OK ? malloc((kept ? kept : 1) * sizeof *run) : NULL;
    double **ocol = st == CONSPH_OK ? malloc(2 * ncol * sizeof *ocol) : NULL;
    if (st == CONSPH_OK && (!run || !ocol)) st = par_fail_mem();
    if (st == CONSPH_OK) {
        size_t nrun = 0;
        for (size_t k = 0; k < kept; ++k) {
            const size_t at = h[k].at;
            const int kind = at >= nself;
            const size_t from = kind ? at - nself : self[at];
            copy_run *last = nrun ? &run[nrun - 1] : NULL;
            if (last && last->kind == kind && last->from + last->len == from)
                ++last->len;
            else
                run[nrun++] = (copy_run){k, from, 1, kind};
        }
        double **ncolp = ocol + ncol;
        columns_of(p, ocol);
        columns_of(&np, ncolp);
        for (size_t c = 0; c < ncol; ++c)
            if (carry[c])
                copy_runs(ncolp[c], ocol[c], recv + c * nrecv, run, nrun);
            else
                memset(ncolp[c], 0, kept * sizeof(double));
    }
    free(run);
    free(ocol);
    for (size_t k = 0; st == CONSPH_OK && k < kept; ++k) {
        int64_t *ac = acell + k * (size_t)dim;
        for (int a = 0; a < dim; ++a) ac[a] = rac[h[k].at * (size_t)dim + (size_t)a];
        owner[k] = rowner[h[k].at];
        dest[k] = owner[k] == ps->rank;
        nown += dest[k];
        origin[k] = k;
        /* the serial order: rows (the cells beyond axis 0), in each the pieces along axis 0 */
        if (dest[k]) ++segn[row_of(ps, ac) * ps->k[0] + ps->piece[0][ac[0]]];
    }
    /* every segment (a row's cells in one piece along axis 0) is one rank's: the sum over the
     * ranks is its count, and the serial index of its first particle their prefix sum */
    if (st == CONSPH_OK) {
        MPI_Allreduce(segn, ps->seg, (int)nseg, MPI_INT64_T, MPI_SUM, ps->comm);
        int64_t acc = 0;
        for (size_t q = 0; q < nseg; ++q) {
            const int64_t c = ps->seg[q];
            ps->seg[q] = acc;
            acc += c;
        }
    } else {
        MPI_Abort(ps->comm, 1); /* the other ranks wait in the counts' exchange */
    }
    if (st == CONSPH_OK) {
        free(ps->own);
        free(ps->x0);
        ps->own = malloc((nown ? nown : 1) * sizeof(size_t));
        ps->x0 = malloc((nown ? nown : 1) * (size_t)dim * sizeof(double));
        if (!ps->own || !ps->x0) st = par_fail_mem();
    }
    /* the exchange lists: what each rank's halo takes of ours, what ours takes of each */
    size_t ns = 0, nr = 0;
    cover_pairs cp = {NULL, NULL, 0, 0};
    size_t *scnt = st == CONSPH_OK ? consph_calloc((size_t)ps->size + 1, sizeof(size_t)) : NULL;
    if (st == CONSPH_OK &&
        (!scnt || cover_collect(ps, &cp, acell, kept, dest, ps->rank, scnt) != CONSPH_OK))
        st = par_fail_mem();
    for (int q = 0; q < ps->size; ++q) {
        ps->scount[q] = st == CONSPH_OK ? (int)scnt[q + 1] : 0;
        ps->rcount[q] = 0;
    }
    for (size_t k = 0; st == CONSPH_OK && k < kept; ++k)
        if (!dest[k]) ++ps->rcount[owner[k]];
    for (int q = 0; st == CONSPH_OK && q < ps->size; ++q) {
        ps->sdispl[q] = (int)ns;
        ps->rdispl[q] = (int)nr;
        ns += (size_t)ps->scount[q];
        nr += (size_t)ps->rcount[q];
    }
    if (st == CONSPH_OK) {
        free(ps->sidx);
        free(ps->ridx);
        ps->sidx = malloc((ns ? ns : 1) * sizeof(size_t));
        ps->ridx = malloc((nr ? nr : 1) * sizeof(size_t));
        if (!ps->sidx || !ps->ridx) st = par_fail_mem();
    }
    if (st == CONSPH_OK) {
        size_t o = 0;
        for (size_t k = 0; k < kept; ++k) {
            if (dest[k]) {
                const int64_t *ac = acell + k * (size_t)dim;
                g[k] = (double)ps->seg[row_of(ps, ac) * ps->k[0] + ps->piece[0][ac[0]]]++;
                ps->own[o] = k;
                for (int a = 0; a < dim; ++a) ps->x0[o * (size_t)dim + (size_t)a] = np.x[a][k];
                ++o;
            } else {
                g[k] = -1.0;
            }
        }
        /* ascending k within each rank's part; the counts serve as cursors */
        for (int q = 0; q < ps->size; ++q) ps->scount[q] = ps->rcount[q] = 0;
        for (size_t k = 0; k < kept; ++k)
            if (!dest[k])
                ps->ridx[(size_t)ps->rdispl[owner[k]] + (size_t)ps->rcount[owner[k]]++] = k;
        for (size_t e = 0; e < cp.n; ++e) {
            const int q = cp.q[e];
            ps->sidx[(size_t)ps->sdispl[q] + (size_t)ps->scount[q]++] = cp.k[e];
        }
        st = runs_of(ps, ps->sidx, ps->sdispl, ps->scount, &ps->srun, &ps->srun_off, &ps->sruns);
        if (st == CONSPH_OK)
            st =
                runs_of(ps, ps->ridx, ps->rdispl, ps->rcount, &ps->rrun, &ps->rrun_off, &ps->rruns);
    }
    free(cp.q);
    free(cp.k);
    free(scnt);
    free(owner);
    free(segn);
    free(h);
    free(acell);
    free(rac);
    free(rowner);
    if (st != CONSPH_OK) {
        if (np.x[0]) consph_particles_free(&np);
        free(dest);
        free(origin);
        free(g);
        return st;
    }
    const size_t oldcap = p->cap;
    ps->spare = *p;
    *p = np;
    free(s->sys.origin);
    s->sys.origin = origin;
    free(s->sys.dest);
    s->sys.dest = dest;
    s->sys.scratch_asked = 0;
    /* the integrator's scratch is sized by the particles' capacity */
    if (p->cap != oldcap) {
        free(s->integ_scratch);
        s->integ_scratch = NULL;
    }
    free(ps->g);
    ps->g = g;
    ps->nown = nown;
    ps->pairs_epoch = 0; /* the local indices are new */
    /* new halo lists, the halo as the owners packed it: the search is built without a
     * refresh, which would find nothing changed */
    st = halo_state_from_cut(ps, &s->sys, carry);
    if (st != CONSPH_OK) return st;
    const consph_sys_split *split = s->sys.split;
    s->sys.split = NULL;
    st = consph_sys_update(&s->sys, 0);
    s->sys.split = split;
    return st;
}

/* Every owned particle to the rank that owns its cell now and to the ranks whose halo holds
 * that cell; then install. At a step's re-sort (step 1) only the columns that the serial
 * re-sort carries travel and are copied (state_carried: the step writes the others before it
 * reads them); the others are zero on every rank after it, kept copies included, so the halo
 * refresh still finds them changed exactly where an owner wrote them. */
static int migrate(consph_solver *s, par_solver *ps, int step)
{
    consph_particles *p = s->sys.p;
    const size_t dim = (size_t)ps->dim;
    const double t0 = MPI_Wtime();
    int64_t *ac = malloc((ps->nown ? ps->nown : 1) * dim * sizeof(int64_t));
    if (!ac) return par_fail_mem();
    for (size_t a = 0; a < dim; ++a)
        nnps_axis_cells(s->sys.nnps, (int)a, p->x[a], ps->own, ps->nown, ac + a, dim);
    /* the weights: the pairs of the step's last cached state (none before the first pass) */
    pairs_take(ps, &s->sys);
    int kind = ps->pairs_epoch ? WEIGH_PAIRS : WEIGH_COUNT;
    if (kind == WEIGH_COUNT && ps->stepping && candidates_take(ps, &s->sys))
        kind = WEIGH_CANDIDATES;
    uint32_t *w = NULL;
    if (kind != WEIGH_COUNT && (w = malloc((ps->nown ? ps->nown : 1) * sizeof *w)) != NULL)
        for (size_t o = 0; o < ps->nown; ++o) w[o] = ps->pairs[ps->own[o]];
    if (cut_boxes(ps, ac, w, kind, ps->nown) != CONSPH_OK) MPI_Abort(ps->comm, 1);
    free(w);
    /* per rank, the owned particles it will hold (owns or has in its halo), ascending */
    size_t *go_off = consph_calloc((size_t)ps->size + 1, sizeof(size_t)), *go = NULL;
    if (!go_off) MPI_Abort(ps->comm, 1);
    cover_pairs cp = {NULL, NULL, 0, 0};
    if (cover_collect(ps, &cp, ac, ps->nown, NULL, -1, go_off) != CONSPH_OK) MPI_Abort(ps->comm, 1);
    for (int q = 0; q < ps->size; ++q) go_off[q + 1] += go_off[q];
    go = malloc((go_off[ps->size] ? go_off[ps->size] : 1) * sizeof(size_t));
    if (!go) MPI_Abort(ps->comm, 1);
    for (size_t e = 0; e < cp.n; ++e) go[go_off[cp.q[e]]++] = cp.k[e];
    free(cp.q);
    free(cp.k);
    for (int q = ps->size; q > 0; --q) go_off[q] = go_off[q - 1];
    go_off[0] = 0;
    const size_t ncol = values_per_particle(p);
    unsigned char *carry = malloc(ncol);
    if (!carry) MPI_Abort(ps->comm, 1);
    size_t ncarry = 0;
    {
        size_t c = 0;
        for (int a = 0; a < p->dim; ++a) carry[c++] = 1;
        for (int f = 0; f < p->nfields; ++f) {
            const int keep = !step || state_carried(s, p->fields[f].name);
            for (int k = 0; k < p->fields[f].ncomp; ++k) carry[c++] = (unsigned char)keep;
        }
        for (c = 0; c < ncol; ++c) ncarry += carry[c];
    }
    int *cnt = consph_calloc((size_t)ps->size, sizeof(int));
    int *rcnt = consph_calloc((size_t)ps->size, sizeof(int));
    int *sd = consph_calloc((size_t)ps->size, sizeof(int));
    int *sdis = consph_calloc((size_t)ps->size, sizeof(int));
    int *rd = consph_calloc((size_t)ps->size, sizeof(int));
    int *rdis = consph_calloc((size_t)ps->size, sizeof(int));
    long *slot = malloc((p->n ? p->n : 1) * sizeof(long));
    int st = cnt && rcnt && sd && sdis && rd && rdis && slot ? CONSPH_OK : par_fail_mem();
    /* A particle that goes to a rank whose halo held it travels as its slot in that halo and
     * the columns that changed since the last refresh (or that rank does not hold); the rank
     * takes the others from what it kept (got). Records: g, slot (-1: every column), values. */
    const size_t ons = ps->sdispl[ps->size - 1] + (size_t)ps->scount[ps->size - 1];
    const size_t onr = ps->rdispl[ps->size - 1] + (size_t)ps->rcount[ps->size - 1];
    const int same_cols = ps->base == ncol;
    if (st == CONSPH_OK && halo_columns(ps, &s->sys, 0) != ncol) st = par_fail_mem();
    if (st == CONSPH_OK) st = halo_state_reserve(ps, ncol);
    if (st != CONSPH_OK) MPI_Abort(ps->comm, 1); /* the other ranks wait in the exchange */
    for (size_t c = 0; c < ncol; ++c) {
        const int valid = same_cols && ps->kept[c];
        const int changed =
            carry[c] && (!valid || list_changed(ps, 0, ps->col[c], ps->sent + c * ons));
        ps->mask[c] =
            (unsigned char)((changed ? COL_CHANGED : 0) | (carry[c] && !valid ? COL_WANTED : 0));
    }
    MPI_Allgather(ps->mask, (int)ncol, MPI_UNSIGNED_CHAR, ps->masks, (int)ncol, MPI_UNSIGNED_CHAR,
                  ps->comm);
    for (size_t i = 0; i < p->n; ++i) slot[i] = -1;
    size_t ns = 0, nsd = 0;
    for (int q = 0; st == CONSPH_OK && q < ps->size; ++q) {
        const unsigned char *mq = ps->masks + (size_t)q * ncol;
        size_t sel = 0;
        for (size_t c = 0; c < ncol; ++c) sel += (size_t)col_goes(ps->mask, mq, c);
        const size_t s0 = (size_t)ps->sdispl[q], s1 = s0 + (size_t)ps->scount[q];
        for (size_t k = s0; k < s1; ++k) slot[ps->sidx[k]] = (long)(k - s0);
        size_t d = 0;
        /* what stays on this rank is read by install from the particles themselves */
        for (size_t t = go_off[q]; q != ps->rank && t < go_off[q + 1]; ++t) {
            ++cnt[q];
            d += 2 + (slot[ps->own[go[t]]] >= 0 ? sel : ncarry);
        }
        for (size_t k = s0; k < s1; ++k) slot[ps->sidx[k]] = -1;
        if (d > INT32_MAX || nsd > INT32_MAX)
            st = consph_fail(CONSPH_EINVAL, "MPI decomposition: more than 2^31 values to one "
                                            "rank; use more ranks");
        sd[q] = (int)d;
        sdis[q] = (int)nsd;
        ns += (size_t)cnt[q];
        nsd += d;
    }
    if (st == CONSPH_OK) MPI_Alltoall(cnt, 1, MPI_INT, rcnt, 1, MPI_INT, ps->comm);
    if (st == CONSPH_OK) MPI_Alltoall(sd, 1, MPI_INT, rd, 1, MPI_INT, ps->comm);
    size_t nr = 0, nrd = 0;
    for (int q = 0; st == CONSPH_OK && q < ps->size; ++q) {
        if (nrd > INT32_MAX)
            st = consph_fail(CONSPH_EINVAL, "MPI decomposition: more than 2^31 "
                                            "values to one rank; use more ranks");
        rdis[q] = (int)nrd;
        nr += (size_t)rcnt[q];
        nrd += (size_t)rd[q];
    }
    /* A message to rank q, column-wise: the records' g, their slots, then per column the
     * values of every record where the column goes to q, else those of the records without a
     * slot (q holds no copy of them), each in the local (serial) order. */
    double *sbuf = NULL, *rbuf = NULL, *rcol = NULL, *rg = NULL;
    size_t *iall = NULL, *ifull = NULL;
    if (st == CONSPH_OK) {
        sbuf = malloc((nsd ? nsd : 1) * sizeof(double));
        rbuf = malloc((nrd ? nrd : 1) * sizeof(double));
        iall = malloc((ps->nown ? ps->nown : 1) * sizeof(size_t));
        ifull = malloc((ps->nown ? ps->nown : 1) * sizeof(size_t));
        if (!sbuf || !rbuf || !iall || !ifull) st = par_fail_mem();
    }
    if (st != CONSPH_OK) MPI_Abort(ps->comm, 1);
    double *v = sbuf;
    for (int q = 0; q < ps->size; ++q) {
        if (q == ps->rank) continue;
        const unsigned char *mq = ps->masks + (size_t)q * ncol;
        const size_t s0 = (size_t)ps->sdispl[q], s1 = s0 + (size_t)ps->scount[q];
        for (size_t k = s0; k < s1; ++k) slot[ps->sidx[k]] = (long)(k - s0);
        size_t m = 0, mf = 0;
        for (size_t t = go_off[q]; t < go_off[q + 1]; ++t) {
            const size_t i = ps->own[go[t]];
            iall[m++] = i;
            if (slot[i] < 0) ifull[mf++] = i;
        }
        for (size_t k = 0; k < m; ++k) {
            v[k] = ps->g[iall[k]];
            v[m + k] = (double)slot[iall[k]];
        }
        v += 2 * m;
        for (size_t c = 0; c < ncol; ++c) {
            if (!carry[c]) continue;
            const int all = col_goes(ps->mask, mq, c);
            gather_column(v, ps->col[c], all ? iall : ifull, all ? m : mf);
            v += all ? m : mf;
        }
        for (size_t k = s0; k < s1; ++k) slot[ps->sidx[k]] = -1;
    }
    MPI_Alltoallv(sbuf, sd, sdis, MPI_DOUBLE, rbuf, rd, rdis, MPI_DOUBLE, ps->comm);
    /* each buffer freed as soon as it is read: at the set-up's first cut nearly every particle
     * travels, and the buffers would double the peak of the install */
    free(sbuf);
    sbuf = NULL;
    rcol = malloc((nr ? nr : 1) * ncol * sizeof(double));
    rg = malloc((nr ? nr : 1) * sizeof(double));
    if (!rcol || !rg) {
        par_fail_mem();
        MPI_Abort(ps->comm, 1);
    }
    /* the received records column by column (rcol[c·nr + r], g in rg), the columns not sent
     * from what this rank kept of its halo (got) */
    const double *in = rbuf;
    size_t r0 = 0;
    for (int q = 0; q < ps->size; ++q) {
        const unsigned char *mq = ps->masks + (size_t)q * ncol;
        const size_t m = (size_t)rcnt[q];
        const double *sl = in + m;
        memcpy(rg + r0, in, m * sizeof(double));
        in += 2 * m;
        size_t mf = 0;
        for (size_t r = 0; r < m; ++r) mf += sl[r] < 0.0;
        for (size_t c = 0; c < ncol; ++c) {
            if (!carry[c]) continue;
            double *out = rcol + c * nr + r0;
            if (mf == m || col_goes(mq, ps->mask, c)) {
                copy_doubles(out, in, m);
                in += m;
                continue;
            }
            const double *kept = ps->got + c * onr + (size_t)ps->rdispl[q];
            for (size_t r = 0; r < m; ++r) out[r] = sl[r] < 0.0 ? *in++ : kept[(size_t)sl[r]];
        }
        r0 += m;
    }
    free(rbuf);
    rbuf = NULL;
    /* what stays on this rank is a copy, as the serial re-sort's permutation */
    ps->bytes +=
        (double)((nsd - (size_t)sd[ps->rank]) * sizeof(double) + ncol * (size_t)(ps->size - 1));
    ps->seconds += MPI_Wtime() - t0;
    free(slot);
    free(iall);
    free(ifull);
    /* the owned particles that stay (owned here or in this rank's halo), as local indices */
    const size_t nself = go_off[ps->rank + 1] - go_off[ps->rank];
    int64_t *sac = malloc((nself ? nself : 1) * dim * sizeof *sac);
    if (!sac) MPI_Abort(ps->comm, 1);
    for (size_t t = 0; t < nself; ++t) {
        const size_t o = go[go_off[ps->rank] + t];
        go[t] = ps->own[o];
        for (size_t a = 0; a < dim; ++a) sac[t * dim + a] = ac[o * dim + a];
    }
    st = install(s, ps, rcol, rg, nr, go, sac, nself, rcnt, carry);
    free(sac);
    free(carry);
    free(rcol);
    free(rg);
    free(ac);
    free(go_off);
    free(go);
    free(cnt);
    free(rcnt);
    free(sd);
    free(sdis);
    free(rd);
    free(rdis);
    free(sbuf);
    free(rbuf);
    return st;
}

/* ---- consph_sum over the ranks ---- */

/* consph_sum's tree (src/core/util.c): leaves of at most SUM_LEAF values summed in order from
 * 0.0, nodes split on a leaf boundary so that the tree depends on n alone. */
#define SUM_LEAF 256

/* The items of several columns' sums over the same owned runs: per item its start and length
 * in the serial order (length 0: one value, or the sum in order of a leaf's first values), then
 * one value per column; the items' places depend on the runs alone, so one list serves every
 * column and travels in one message. */
typedef struct sum_items {
    double *v;
    size_t n, cap;
    int per;         /* 2 + the columns */
    const double *w; /* this run's first value of column 0 */
    size_t stride;   /* from one column to the next */
} sum_items;

static double *sum_next(sum_items *a, double start, double len)
{
    if (a->n == a->cap) {
        size_t cap = a->cap ? 2 * a->cap : 64;
        double *q = realloc(a->v, cap * (size_t)a->per * sizeof *q);
        if (!q) return NULL;
        a->v = q;
        a->cap = cap;
    }
    double *it = a->v + a->n++ * (size_t)a->per;
    it[0] = start;
    it[1] = len;
    return it;
}

/* The nodes of the tree over [0, N) that lie within this run [lo, hi), as sums; of a leaf it
 * shares with another rank, its first values as one partial sum when the leaf starts here (the
 * leaf's chain of additions from 0.0 passes through it), else its values one by one. */
static int sum_emit(sum_items *a, size_t lo, size_t hi, size_t s, size_t n)
{
    if (s + n <= lo || s >= hi || n == 0) return CONSPH_OK;
    const int c = a->per - 2;
    if (lo <= s && s + n <= hi) {
        double *it = sum_next(a, (double)s, (double)n);
        if (!it) return par_fail_mem();
        for (int k = 0; k < c; ++k) it[2 + k] = consph_sum(a->w + k * a->stride + (s - lo), n);
        return CONSPH_OK;
    }
    if (n <= SUM_LEAF) {
        if (s >= lo) { /* the leaf's first hi - s values: consph_sum of < SUM_LEAF is in order */
            double *it = sum_next(a, (double)s, 0.0);
            if (!it) return par_fail_mem();
            for (int k = 0; k < c; ++k)
                it[2 + k] = consph_sum(a->w + k * a->stride + (s - lo), hi - s);
            return CONSPH_OK;
        }
        for (size_t i = lo; i < s + n && i < hi; ++i) {
            double *it = sum_next(a, (double)i, 0.0);
            if (!it) return par_fail_mem();
            for (int k = 0; k < c; ++k) it[2 + k] = a->w[k * a->stride + (i - lo)];
        }
        return CONSPH_OK;
    }
    const size_t left = ((n + SUM_LEAF - 1) / SUM_LEAF / 2) * SUM_LEAF;
    int st = sum_emit(a, lo, hi, s, left);
    return st ? st : sum_emit(a, lo, hi, s + left, n - left);
}

/* The first item at or after start (items ascend by start). */
static size_t sum_find(const double *it, int per, size_t n, double start)
{
    size_t a = 0, b = n;
    while (a < b) {
        const size_t m = (a + b) / 2;
        if (it[m * (size_t)per] < start)
            a = m + 1;
        else
            b = m;
    }
    return a;
}

/* Column k's sum of the tree's node [s, s + n) from the m items. */
static double sum_eval(const double *it, int per, size_t m, int k, size_t s, size_t n)
{
    size_t q = sum_find(it, per, m, (double)s);
    /* a whole node on one rank; several items may start at s (a node and, as single values,
     * a shared leaf's first) only when len differs */
    for (size_t r = q; r < m && it[r * (size_t)per] == (double)s; ++r)
        if (it[r * (size_t)per + 1] == (double)n) return it[r * (size_t)per + 2 + k];
    if (n <= SUM_LEAF) {
        double acc = 0.0;
        for (; q < m && it[q * (size_t)per] < (double)(s + n); ++q)
            acc += it[q * (size_t)per + 2 + k];
        return acc;
    }
    const size_t left = ((n + SUM_LEAF - 1) / SUM_LEAF / 2) * SUM_LEAF;
    return sum_eval(it, per, m, k, s, left) + sum_eval(it, per, m, k, s + left, n - left);
}

static int item_cmp(const void *pa, const void *pb)
{
    const double *a = pa, *b = pb;
    if (a[0] != b[0]) return a[0] < b[0] ? -1 : 1;
    return a[1] < b[1] ? -1 : a[1] > b[1];
}

/* consph_sum of each of c columns over the serial order, each rank holding the values of its
 * owned particles (column k at w + k nown; runs of consecutive serial indices, ascending: the
 * rows of its box), bit for bit on every rank: one gather of every column's items to rank 0,
 * which evaluates the tree, and one broadcast of the c sums. */
static int par_sums(par_solver *ps, const double *w, int c, double *out)
{
    if (c < 1) return CONSPH_OK;
    sum_items a = {NULL, 0, 0, 2 + c, NULL, ps->nown};
    int st = CONSPH_OK;
    for (size_t o = 0; st == CONSPH_OK && o < ps->nown;) {
        size_t e = o + 1;
        const size_t lo = (size_t)ps->g[ps->own[o]];
        while (e < ps->nown && (size_t)ps->g[ps->own[e]] == lo + (e - o)) ++e;
        a.w = w + o;
        st = sum_emit(&a, lo, lo + (e - o), 0, ps->nglobal);
        o = e;
    }
    if (st != CONSPH_OK || a.n * (size_t)a.per > INT32_MAX) MPI_Abort(ps->comm, 1);
    const int mine = (int)(a.n * (size_t)a.per);
    int *cnt = NULL, *dis = NULL;
    double *all = NULL;
    size_t total = 0;
    if (ps->rank == 0) {
        cnt = malloc((size_t)ps->size * sizeof(int));
        dis = malloc((size_t)ps->size * sizeof(int));
        if (!cnt || !dis) MPI_Abort(ps->comm, 1);
    }
    MPI_Gather(&mine, 1, MPI_INT, cnt, 1, MPI_INT, 0, ps->comm);
    if (ps->rank == 0) {
        for (int q = 0; q < ps->size; ++q) {
            dis[q] = (int)total;
            total += (size_t)cnt[q];
        }
        all = malloc((total ? total : 1) * sizeof(double));
        if (!all) MPI_Abort(ps->comm, 1);
    }
    MPI_Gatherv(a.v, mine, MPI_DOUBLE, all, cnt, dis, MPI_DOUBLE, 0, ps->comm);
    if (ps->rank == 0) {
        const size_t m = total / (size_t)a.per;
        qsort(all, m, (size_t)a.per * sizeof(double), item_cmp); /* the ranks' runs interleave */
        for (int k = 0; k < c; ++k) out[k] = sum_eval(all, a.per, m, k, 0, ps->nglobal);
    }
    MPI_Bcast(out, c, MPI_DOUBLE, 0, ps->comm);
    if (ps->rank != 0) ps->bytes += (double)mine * sizeof(double);
    free(a.v);
    free(cnt);
    free(dis);
    free(all);
    return CONSPH_OK;
}

int par_owned_sums(consph_solver *s, const double *w, int c, double *out)
{
    const double t0 = MPI_Wtime();
    const int st = par_sums(s->par, w, c, out);
    s->par->seconds += MPI_Wtime() - t0;
    return st;
}

int par_owned_max(consph_solver *s, double *v, int c)
{
    par_solver *ps = s->par;
    const double t0 = MPI_Wtime();
    MPI_Allreduce(MPI_IN_PLACE, v, c, MPI_DOUBLE, MPI_MAX, ps->comm);
    ps->seconds += MPI_Wtime() - t0;
    return CONSPH_OK;
}

const size_t *par_owned(const consph_solver *s, size_t *nown, size_t *nglobal)
{
    *nown = s->par->nown;
    *nglobal = s->par->nglobal;
    return s->par->own;
}

int par_checks_clean(consph_solver *s, int *clean)
{
    par_solver *ps = s->par;
    const consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t cap = p->cap;
    const double t0 = MPI_Wtime();
    const consph_field *fu = consph_particles_find(p, SF_U),
                       *fr = consph_particles_find(p, SF_RHOF),
                       *fp = consph_particles_find(p, SF_P),
                       *fm = consph_particles_find(p, SF_MASS);
    double *w = malloc((ps->nown ? ps->nown : 1) * sizeof(double));
    if (!fu || !fr || !fp || !w) {
        free(w);
        MPI_Abort(ps->comm, 1);
    }
    const double *u = fu->data, *rf = fr->data, *pr = fp->data, r0 = s->prm.rho0;
    /* as solver_check_finite and solver_check_valid (src/solver/validity.c, with the kinetic
     * energy's terms of kinetic_energy_of) compute them, over the owned particles */
    const int compressible = !(s->scheme->evolve_p && s->scheme->closure);
    double finite = 0.0, u2max = 0.0, cmax = 0.0;
    for (size_t o = 0; o < ps->nown; ++o) {
        const size_t i = ps->own[o];
        finite += rf[i] - rf[i] + pr[i] - pr[i];
        double u2 = 0.0;
        for (int a = 0; a < d; ++a) {
            finite += p->x[a][i] - p->x[a][i] + u[a * cap + i] - u[a * cap + i];
            u2 += u[a * cap + i] * u[a * cap + i];
        }
        u2max = u2 > u2max ? u2 : u2max;
        if (compressible) {
            const double c = fabs(rf[i] / r0 - 1.0);
            cmax = c > cmax ? c : cmax;
        }
        const double m = fm ? fm->data[i] : s->mass, ux = u[i], uy = u[cap + i],
                     uz = d == 3 ? u[2 * cap + i] : 0.0;
        w[o] = 0.5 * m * (d == 3 ? ux * ux + uy * uy + uz * uz : ux * ux + uy * uy);
    }
    double in[3] = {finite == 0.0 ? 0.0 : 1.0, u2max, cmax}, out[3];
    MPI_Allreduce(in, out, 3, MPI_DOUBLE, MPI_MAX, ps->comm);
    double ke = 0.0;
    par_sums(ps, w, 1, &ke);
    free(w);
    ps->seconds += MPI_Wtime() - t0;
    const double ke0 = s->hist[6]; /* row 0: the initial state, on every rank */
    *clean = out[0] == 0.0 && sqrt(out[1]) / s->c0 <= CONSPH_VALID_MACH &&
             out[2] <= CONSPH_VALID_COMPRESSION && !(ke > ke0 * (1.0 + CONSPH_VALID_KE_GROWTH));
    return CONSPH_OK;
}

/* ---- the solver's hooks ---- */

int par_step_begin(consph_solver *s)
{
    s->par->stepping = 1;
    return migrate(s, s->par, 1);
}

int par_step_end(consph_solver *s, int status)
{
    par_solver *ps = s->par;
    /* the largest move along each axis since the re-sort in cell edges, nearest image */
    const consph_particles *p = s->sys.p;
    double mx = 0.0;
    int axis = 0;
    for (size_t o = 0; o < ps->nown; ++o)
        for (int a = 0; a < ps->dim; ++a) {
            double d = fabs(p->x[a][ps->own[o]] - ps->x0[o * (size_t)ps->dim + (size_t)a]);
            if (ps->periodic[a] && d > 0.5 * ps->len[a]) d = ps->len[a] - d;
            d /= ps->edge[a];
            if (d > mx || isnan(d)) { /* NaN: the checks name it */
                mx = isnan(d) ? 0.0 : d;
                axis = a;
            }
        }
    double in[2] = {status != CONSPH_OK ? 1.0 : 0.0, mx}, out[2];
    MPI_Allreduce(in, out, 2, MPI_DOUBLE, MPI_MAX, ps->comm);
    /* the axis: the lowest among the ranks that saw the maximum */
    int ax = out[1] == mx ? axis : CONSPH_MAX_DIM;
    int axmin = 0;
    MPI_Allreduce(&ax, &axmin, 1, MPI_INT, MPI_MIN, ps->comm);
    if (status != CONSPH_OK) return status;
    if (out[0] > 0.0)
        return consph_fail(CONSPH_EINVAL, "step %ld failed on another MPI rank", s->step);
    if (s->scheme->moves && out[1] >= 0.5)
        return consph_fail(CONSPH_EINVAL,
                           "step %ld: a particle moved %g along axis %d in one step, half a "
                           "search cell (%g) or more: the MPI halo may miss neighbours; run "
                           "with a smaller dt or without MPI",
                           s->step, out[1] * ps->edge[axmin], axmin, 0.5 * ps->edge[axmin]);
    return CONSPH_OK;
}

int par_global(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg)
{
    return par_global_some(s, fn, arg, NULL);
}

/* The gathers to rank 0 travel in messages of at most GATHER_MSG_BYTES (a rank's part in
 * several), received one at a time while the previous one is unpacked: rank 0 holds the
 * assembled set and two messages, not every rank's packed values besides it, and no count or
 * displacement is bounded by an int's range. */
enum { GATHER_MSG_BYTES = 4 << 20, TAG_GATHER = 1 };
static size_t gather_msg_bytes = GATHER_MSG_BYTES; /* par_force_gather_bytes */
static long whole_gathers;                         /* par_whole_gathers */

void par_force_gather_bytes(size_t bytes)
{
    gather_msg_bytes = bytes ? bytes : GATHER_MSG_BYTES;
}

long par_whole_gathers(void)
{
    return whole_gathers;
}

/* The messages of a gather to rank 0, in the order they are received: rank 1's part in pieces
 * of at most `chunk` particles, then rank 2's, ... */
typedef struct gather_msgs {
    const int *cnt; /* per rank: its owned particles */
    int size, q;
    size_t left, chunk;
} gather_msgs;

/* The next message's particle count (0: none left) and its sender. */
static size_t gather_next(gather_msgs *g, int *from)
{
    while (g->left == 0 && g->q + 1 < g->size) g->left = (size_t)g->cnt[++g->q];
    const size_t k = g->left < g->chunk ? g->left : g->chunk;
    g->left -= k;
    *from = g->q;
    return k;
}

/* Rank 0 receives the messages of a gather (gather_msgs over cnt, `per` doubles per particle)
 * into two buffers `room` doubles apart, the next one while place(ctx, sender, message, k)
 * takes the last. */
static void receive_parts(par_solver *ps, const int *cnt, size_t chunk, size_t per, int tag,
                          double *bufs, size_t room,
                          void (*place)(void *ctx, int from, const double *msg, size_t k),
                          void *ctx)
{
    gather_msgs it = {cnt, ps->size, 0, 0, chunk};
    MPI_Request req = MPI_REQUEST_NULL;
    int from = 0, cur = 0;
    size_t k = gather_next(&it, &from);
    if (k) MPI_Irecv(bufs, (int)(k * per), MPI_DOUBLE, from, tag, ps->comm, &req);
    while (k) {
        const double t0 = MPI_Wtime();
        MPI_Wait(&req, MPI_STATUS_IGNORE);
        const int sender = from;
        const size_t next = gather_next(&it, &from);
        if (next)
            MPI_Irecv(bufs + (size_t)(1 - cur) * room, (int)(next * per), MPI_DOUBLE, from, tag,
                      ps->comm, &req);
        ps->seconds += MPI_Wtime() - t0;
        place(ctx, sender, bufs + (size_t)cur * room, k);
        cur = 1 - cur;
        k = next;
    }
}

/* par_global_some's messages: each particle's values, its serial index last. */
typedef struct unpack_ctx {
    consph_particles *full;
    size_t per;
} unpack_ctx;

static void place_unpacked(void *ctx, int from, const double *v, size_t k)
{
    const unpack_ctx *u = ctx;
    (void)from;
    for (size_t j = 0; j < k; ++j)
        unpack(u->full, (size_t)v[j * u->per + u->per - 1], v + j * u->per);
}

/* Rank 0's status of a call that ran there, and its message (msg: PAR_MSG_BYTES), to every
 * rank: the status every rank returns. */
static int rank0_status(par_solver *ps, int st, char *msg)
{
    const double t1 = MPI_Wtime();
    MPI_Bcast(&st, 1, MPI_INT, 0, ps->comm);
    if (st != CONSPH_OK) {
        MPI_Bcast(msg, PAR_MSG_BYTES, MPI_CHAR, 0, ps->comm);
        consph_fail(st, "%s", msg);
    }
    ps->seconds += MPI_Wtime() - t1;
    return st;
}

int par_global_some(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg,
                    const char *const *only)
{
    par_solver *ps = s->par;
    consph_particles *p = s->sys.p;
    double t0 = MPI_Wtime();
    unsigned char sel[CONSPH_MAX_FIELDS];
    for (int f = 0; f < p->nfields; ++f) {
        sel[f] = !only;
        for (int k = 0; only && only[k]; ++k)
            if (!strcmp(p->fields[f].name, only[k])) sel[f] = 1;
    }
    const size_t per = values_selected(p, sel) + 1; /* + the serial index */
    if (!only) ++whole_gathers;
    size_t chunk = gather_msg_bytes / (per * sizeof(double));
    chunk = chunk ? chunk : 1;
    int st = CONSPH_OK;
    int *pcnt = ps->rank == 0 ? consph_calloc((size_t)ps->size, sizeof(int)) : NULL;
    if (ps->rank == 0 && !pcnt) MPI_Abort(ps->comm, 1);
    if (ps->nown > INT32_MAX) MPI_Abort(ps->comm, 1);
    const int mine = (int)ps->nown;
    MPI_Gather(&mine, 1, MPI_INT, pcnt, 1, MPI_INT, 0, ps->comm);
    /* a message's room: rank 0 receives the next while it unpacks the last */
    size_t most = ps->nown;
    for (int q = 0; ps->rank == 0 && q < ps->size; ++q)
        most = (size_t)pcnt[q] > most ? (size_t)pcnt[q] : most;
    const size_t room = (most < chunk ? most : chunk) + 1;
    const int nbuf = ps->rank == 0 ? 2 : 1;
    double *buf = malloc((size_t)nbuf * room * per * sizeof(double));
    if (!buf) MPI_Abort(ps->comm, 1);
    ps->seconds += MPI_Wtime() - t0;
    consph_particles full;
    memset(&full, 0, sizeof full);
    if (ps->rank != 0) {
        for (size_t o = 0; o < ps->nown; o += chunk) {
            const size_t k = ps->nown - o < chunk ? ps->nown - o : chunk;
            for (size_t j = 0; j < k; ++j) {
                const size_t i = ps->own[o + j];
                pack_selected(p, sel, i, buf + j * per);
                buf[j * per + per - 1] = ps->g[i];
            }
            t0 = MPI_Wtime();
            MPI_Send(buf, (int)(k * per), MPI_DOUBLE, 0, TAG_GATHER, ps->comm);
            ps->seconds += MPI_Wtime() - t0;
        }
        ps->bytes += (double)(ps->nown * per * sizeof(double));
    } else {
        /* into the serial order: each particle at its serial index */
        st = particles_like_some(&full, p, ps->nglobal, sel);
        if (st != CONSPH_OK) MPI_Abort(ps->comm, 1);
        for (size_t o = 0; o < ps->nown; ++o) {
            pack_selected(p, sel, ps->own[o], buf);
            unpack(&full, (size_t)ps->g[ps->own[o]], buf);
        }
        unpack_ctx u = {&full, per};
        receive_parts(ps, pcnt, chunk, per, TAG_GATHER, buf, room * per, place_unpacked, &u);
    }
    free(buf);
    free(pcnt);
    t0 = MPI_Wtime();
    unsigned long long pairs = s->pairs - ps->pairs_base, total = 0;
    MPI_Reduce(&pairs, &total, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, ps->comm);
    ps->seconds += MPI_Wtime() - t0;
    char msg[PAR_MSG_BYTES] = "";
    if (ps->rank == 0) {
        /* the serial view: the whole set, no mask, nothing decomposed (a nested
         * solver_global runs at once) */
        consph_particles local = *p;
        unsigned char *dest = s->sys.dest;
        size_t *origin = s->sys.origin;
        const size_t pairs_local = s->pairs;
        *p = full;
        s->sys.dest = NULL;
        s->sys.origin = NULL;
        s->par = NULL;
        s->pairs = ps->pairs_base + (size_t)total;
        st = fn(s, arg);
        if (st != CONSPH_OK) snprintf(msg, sizeof msg, "%s", consph_last_error());
        s->par = ps;
        s->pairs = pairs_local;
        s->sys.dest = dest;
        s->sys.origin = origin;
        full = *p;
        *p = local;
        consph_particles_free(&full);
        /* the diagnostics' per-particle buffers, sized for the whole set: kept, they would
         * stay on rank 0 between samples and add to the next gather's peak */
        free(s->diag_buf);
        free(s->wc_buf);
        s->diag_buf = s->wc_buf = NULL;
        s->diag_cap = s->wc_cap = 0;
    }
    return rank0_status(ps, st, msg);
}

/* ---- files from one array at a time (par_stream) ----
 *
 * Rank 0 runs the writer with its own part in place; each time the writer needs an array (the
 * positions or one field), rank 0 broadcasts which, and every rank sends its owned values of
 * that array, which rank 0 puts at their serial indices in one buffer of the whole set's
 * length: rank 0 holds one array of the whole set and two messages, never the whole set. A
 * rank's owned particles, ascending in the serial index, are runs of it (a row of cells within
 * its piece along axis 0): the runs travel once, at the first array, and the arrays travel as
 * values only. */
enum { STREAM_END = -2, TAG_STREAM = 2 };

typedef struct stream_ctx {
    consph_particles view; /* rank 0: the whole set's shape, the loaded array's values */
    int have_runs;
    int *cnt;          /* rank 0, per rank: its owned particles */
    size_t *run_off;   /* rank 0, per rank: its first run (size + 1) */
    uint64_t *runs;    /* rank 0: (first serial index, length) per run, rank by rank */
    double *buf, *msg; /* rank 0: the array's values; the messages (two) or a rank's one */
    size_t buf_cap, msg_cap;
} stream_ctx;

/* Rank 0's broadcast, waited for asleep by the others (rank 0 may be compressing a file while
 * they wait, on cores they share): polls from 50 µs up to every millisecond. */
static int stream_bcast(par_solver *ps, int v)
{
    MPI_Request req;
    MPI_Ibcast(&v, 1, MPI_INT, 0, ps->comm, &req);
    if (ps->rank == 0) {
        MPI_Wait(&req, MPI_STATUS_IGNORE);
        return v;
    }
    long ns = 50000;
    for (;;) {
        int done = 0;
        MPI_Test(&req, &done, MPI_STATUS_IGNORE);
        if (done) return v;
        const struct timespec ts = {0, ns};
        nanosleep(&ts, NULL);
        if (ns < 1000000) ns *= 2;
    }
}

/* Every rank's owned particles as runs of consecutive serial indices, to rank 0. */
static void stream_runs(par_solver *ps, stream_ctx *x)
{
    size_t n = 0;
    for (size_t o = 0; o < ps->nown; ++o)
        if (o == 0 || ps->g[ps->own[o]] != ps->g[ps->own[o - 1]] + 1.0) ++n;
    uint64_t *mine = malloc((n ? 2 * n : 1) * sizeof *mine);
    if (!mine || ps->nown > INT32_MAX || 2 * n > INT32_MAX) MPI_Abort(ps->comm, 1);
    size_t r = 0;
    for (size_t o = 0; o < ps->nown; ++o) {
        const uint64_t g = (uint64_t)ps->g[ps->own[o]];
        if (o == 0 || (double)g != ps->g[ps->own[o - 1]] + 1.0) {
            mine[2 * r] = g;
            mine[2 * r + 1] = 0;
            ++r;
        }
        ++mine[2 * r - 1];
    }
    const int two[2] = {(int)ps->nown, (int)(2 * n)};
    int *both = NULL, *displ = NULL;
    if (ps->rank == 0) {
        both = malloc((size_t)ps->size * 2 * sizeof(int));
        displ = malloc((size_t)ps->size * sizeof(int));
        x->cnt = malloc((size_t)ps->size * sizeof(int));
        x->run_off = malloc(((size_t)ps->size + 1) * sizeof(size_t));
        if (!both || !displ || !x->cnt || !x->run_off) MPI_Abort(ps->comm, 1);
    }
    MPI_Gather(two, 2, MPI_INT, both, 2, MPI_INT, 0, ps->comm);
    int *vals = NULL;
    if (ps->rank == 0) {
        size_t total = 0;
        vals = malloc((size_t)ps->size * sizeof(int));
        if (!vals) MPI_Abort(ps->comm, 1);
        for (int q = 0; q < ps->size; ++q) {
            x->cnt[q] = both[2 * q];
            vals[q] = both[2 * q + 1];
            x->run_off[q] = total / 2;
            if (total > INT32_MAX) MPI_Abort(ps->comm, 1);
            displ[q] = (int)total;
            total += (size_t)vals[q];
        }
        x->run_off[ps->size] = total / 2;
        x->runs = malloc((total ? total : 1) * sizeof(uint64_t));
        if (!x->runs || total > INT32_MAX) MPI_Abort(ps->comm, 1);
    }
    MPI_Gatherv(mine, (int)(2 * n), MPI_UINT64_T, x->runs, vals, displ, MPI_UINT64_T, 0, ps->comm);
    ps->bytes += (double)(2 * n * sizeof(uint64_t));
    free(mine);
    free(both);
    free(displ);
    free(vals);
    x->have_runs = 1;
}

/* A message of k particles of rank q's owned ones (component-major: component c of particle j
 * at msg[c k + j]) into the array out at their serial indices; *r, *off: where in q's runs the
 * message starts, moved past it. */
static void stream_place(const stream_ctx *x, double *out, size_t nglobal, int nc,
                         const double *msg, size_t k, size_t *r, uint64_t *off)
{
    for (size_t j = 0; j < k;) {
        const uint64_t first = x->runs[2 * *r], len = x->runs[2 * *r + 1];
        const size_t take = (size_t)(len - *off) < k - j ? (size_t)(len - *off) : k - j;
        for (int c = 0; c < nc; ++c)
            memcpy(out + (size_t)c * nglobal + first + *off, msg + (size_t)c * k + j,
                   take * sizeof(double));
        j += take;
        *off += take;
        if (*off == len) {
            ++*r;
            *off = 0;
        }
    }
}

/* stream_gather's messages, placed by the sender's runs (stream_place), from its first run at
 * its first message. */
typedef struct place_ctx {
    const stream_ctx *x;
    double *out;
    size_t ng;
    int nc, at;
    size_t r;
    uint64_t off;
} place_ctx;

static void place_runs(void *ctx, int from, const double *msg, size_t k)
{
    place_ctx *c = ctx;
    if (from != c->at) {
        c->at = from;
        c->r = c->x->run_off[from];
        c->off = 0;
    }
    stream_place(c->x, c->out, c->ng, c->nc, msg, k, &c->r, &c->off);
}

/* The values of the positions (field -1) or of field `field` of the owned particles: rank 0
 * puts every rank's at their serial indices in x->buf (component c from c·nglobal), the
 * others send theirs in messages of at most GATHER_MSG_BYTES. */
static void stream_gather(consph_solver *s, stream_ctx *x, int field)
{
    par_solver *ps = s->par;
    const consph_particles *p = s->sys.p;
    const int nc = field < 0 ? p->dim : p->fields[field].ncomp;
#define COL(c) (field < 0 ? p->x[c] : p->fields[field].data + (size_t)(c)*p->cap)
    size_t chunk = gather_msg_bytes / ((size_t)nc * sizeof(double));
    chunk = chunk ? chunk : 1;
    double t0 = MPI_Wtime();
    if (!x->have_runs) stream_runs(ps, x);
    ps->seconds += MPI_Wtime() - t0;
    if (ps->rank != 0) {
        for (size_t o = 0; o < ps->nown; o += chunk) {
            const size_t k = ps->nown - o < chunk ? ps->nown - o : chunk;
            for (int c = 0; c < nc; ++c) {
                const double *v = COL(c);
                for (size_t j = 0; j < k; ++j) x->msg[(size_t)c * k + j] = v[ps->own[o + j]];
            }
            t0 = MPI_Wtime();
            MPI_Send(x->msg, (int)(k * (size_t)nc), MPI_DOUBLE, 0, TAG_STREAM, ps->comm);
            ps->seconds += MPI_Wtime() - t0;
        }
        ps->bytes += (double)(ps->nown * (size_t)nc * sizeof(double));
        return;
    }
    const size_t ng = ps->nglobal;
    double *out = x->buf;
    for (int c = 0; c < nc; ++c) {
        const double *v = COL(c);
        for (size_t o = 0; o < ps->nown; ++o)
            out[(size_t)c * ng + (size_t)ps->g[ps->own[o]]] = v[ps->own[o]];
    }
#undef COL
    place_ctx c = {x, out, ng, nc, -1, 0, 0};
    receive_parts(ps, x->cnt, chunk, (size_t)nc, TAG_STREAM, x->msg, x->msg_cap / 2, place_runs,
                  &c);
}

/* Room for field's array (-1: the positions) and its messages on this rank; 0 when out of
 * memory. */
static int stream_room(consph_solver *s, stream_ctx *x, int field)
{
    const par_solver *ps = s->par;
    const consph_particles *p = s->sys.p;
    const size_t nc = (size_t)(field < 0 ? p->dim : p->fields[field].ncomp);
    size_t chunk = gather_msg_bytes / (nc * sizeof(double));
    chunk = chunk ? chunk : 1;
    size_t most = ps->nown;
    for (int q = 0; ps->rank == 0 && x->cnt && q < ps->size; ++q)
        most = (size_t)x->cnt[q] > most ? (size_t)x->cnt[q] : most;
    /* before the runs are known, rank 0 makes room for a whole message */
    if (ps->rank == 0 && !x->cnt) most = chunk;
    const size_t msg = (ps->rank == 0 ? 2 : 1) * ((most < chunk ? most : chunk) + 1) * nc;
    if (msg > x->msg_cap) {
        double *m = realloc(x->msg, msg * sizeof(double));
        if (!m) return 0;
        x->msg = m;
        x->msg_cap = msg;
    }
    const size_t need = ps->rank == 0 ? nc * (ps->nglobal ? ps->nglobal : 1) : 0;
    if (need > x->buf_cap) {
        free(x->buf); /* its values are the last array's: none to keep */
        x->buf = malloc(need * sizeof(double));
        x->buf_cap = x->buf ? need : 0;
        if (!x->buf) return 0;
    }
    return 1;
}

/* The writer's load on rank 0 (io_array_source): the array gathered into x->buf, the view's
 * pointers at it. */
static int stream_load(void *arg, int field)
{
    consph_solver *s = arg;
    par_solver *ps = s->par;
    stream_ctx *x = ps->stream;
    /* the room first: the others wait for the command, and serve only a gather announced */
    if (!stream_room(s, x, field))
        return consph_fail(CONSPH_ENOMEM, "out of memory gathering a file's array to rank 0");
    stream_bcast(ps, field);
    stream_gather(s, x, field);
    consph_particles *v = &x->view;
    if (field < 0)
        for (int a = 0; a < v->dim; ++a) v->x[a] = x->buf + (size_t)a * ps->nglobal;
    else
        v->fields[field].data = x->buf;
    return CONSPH_OK;
}

int par_stream_source(consph_solver *s, const consph_particles **view, io_array_source *src)
{
    par_solver *ps = s->par;
    stream_ctx *x = ps ? ps->stream : NULL;
    if (!x || ps->rank != 0)
        return consph_fail(CONSPH_EINVAL, "par_stream_source outside par_stream on rank 0");
    x->view = *s->sys.p;
    x->view.n = x->view.cap = ps->nglobal;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) x->view.x[a] = NULL;
    for (int f = 0; f < x->view.nfields; ++f) x->view.fields[f].data = NULL;
    *view = &x->view;
    src->load = stream_load;
    src->arg = s;
    return CONSPH_OK;
}

int par_stream(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg)
{
    par_solver *ps = s->par;
    stream_ctx x;
    memset(&x, 0, sizeof x);
    double t0 = MPI_Wtime();
    unsigned long long pairs = s->pairs - ps->pairs_base, total = 0;
    MPI_Reduce(&pairs, &total, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, ps->comm);
    ps->seconds += MPI_Wtime() - t0;
    ps->stream = &x;
    int st = CONSPH_OK;
    char msg[PAR_MSG_BYTES] = "";
    if (ps->rank == 0) {
        const size_t pairs_local = s->pairs;
        s->pairs = ps->pairs_base + (size_t)total;
        st = fn(s, arg);
        if (st != CONSPH_OK) snprintf(msg, sizeof msg, "%s", consph_last_error());
        s->pairs = pairs_local;
        stream_bcast(ps, STREAM_END);
    } else {
        for (int field; (field = stream_bcast(ps, STREAM_END)) != STREAM_END;) {
            if (!stream_room(s, &x, field)) MPI_Abort(ps->comm, 1);
            stream_gather(s, &x, field);
        }
    }
    ps->stream = NULL;
    free(x.cnt);
    free(x.run_off);
    free(x.runs);
    free(x.buf);
    free(x.msg);
    return rank0_status(ps, st, msg);
}

int par_sample_due(consph_solver *s)
{
    par_solver *ps = s->par;
    const int due = !solver_sampled_now(s);
    if (!ps) return due;
    return stream_bcast(ps, due);
}

int par_rank(const consph_solver *s)
{
    return s->par ? s->par->rank : 0;
}

int par_cut_weights(const consph_solver *s)
{
    return s->par ? s->par->weighed : 0;
}

int par_geometry(const consph_solver *s, int *k, long long *nc, long long *width)
{
    const par_solver *ps = s->par;
    if (!ps) return 0;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        k[a] = a < ps->dim ? ps->k[a] : 1;
        nc[a] = a < ps->dim ? (long long)ps->nc[a] : 1;
        width[a] = a < ps->dim ? (long long)ps->width[a] : 0;
    }
    return ps->dim;
}

int par_share_history(consph_solver *s)
{
    par_solver *ps = s->par;
    unsigned long long nh = s->nhist;
    MPI_Bcast(&nh, 1, MPI_UNSIGNED_LONG_LONG, 0, ps->comm);
    if (ps->rank != 0 && nh > s->caphist) {
        double *h = realloc(s->hist, (size_t)nh * HIST_COLS * sizeof(double));
        if (!h) MPI_Abort(ps->comm, 1); /* rank 0 waits in the broadcast */
        s->hist = h;
        s->caphist = (size_t)nh;
    }
    if (nh) MPI_Bcast(s->hist, (int)(nh * HIST_COLS), MPI_DOUBLE, 0, ps->comm);
    s->nhist = (size_t)nh;
    /* and the sums of the samples (the authors' first, at t = 0): the later samples, taken on
     * every rank (solver_sample_owned), add to them there */
    double acc[9] = {s->l1_u_acc,  s->l1_p_acc,  s->auth_u_acc,     s->auth_p_acc,    s->log_since,
                     s->wcs_u_acc, s->wcs_p_acc, s->wcs_auth_u_acc, s->wcs_auth_p_acc};
    int an = s->auth_n;
    MPI_Bcast(acc, 9, MPI_DOUBLE, 0, ps->comm);
    MPI_Bcast(&an, 1, MPI_INT, 0, ps->comm);
    s->l1_u_acc = acc[0];
    s->l1_p_acc = acc[1];
    s->auth_u_acc = acc[2];
    s->auth_p_acc = acc[3];
    s->log_since = acc[4];
    s->wcs_u_acc = acc[5];
    s->wcs_p_acc = acc[6];
    s->wcs_auth_u_acc = acc[7];
    s->wcs_auth_p_acc = acc[8];
    s->auth_n = an;
    return CONSPH_OK;
}

void par_solver_free(par_solver *ps)
{
    if (!ps) return;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        free(ps->cut[a]);
        free(ps->piece[a]);
        free(ps->cover_off[a]);
        free(ps->cover[a]);
    }
    free(ps->ranks);
    if (ps->spare.x[0]) consph_particles_free(&ps->spare);
    free(ps->seg);
    free(ps->g);
    free(ps->own);
    free(ps->x0);
    free(ps->scount);
    free(ps->sdispl);
    free(ps->rcount);
    free(ps->rdispl);
    free(ps->sdbl);
    free(ps->sddis);
    free(ps->rdbl);
    free(ps->rddis);
    free(ps->sidx);
    free(ps->ridx);
    free(ps->srun);
    free(ps->rrun);
    free(ps->srun_off);
    free(ps->rrun_off);
    free(ps->sbuf);
    free(ps->rbuf);
    free(ps->sent);
    free(ps->got);
    free(ps->col);
    free(ps->mask);
    free(ps->kept);
    free(ps->sel);
    free(ps->masks);
    free(ps->pairs);
    free(ps);
}

/* ---- set-up ---- */

static int forced_boxes[CONSPH_MAX_DIM];

void par_force_boxes(const int *k)
{
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) forced_boxes[a] = k ? k[a] : 0;
}

/* The pieces per axis, k_0 k_1 k_2 = K, each at most the axis' cells, that make the fewest
 * halo cells per rank (a box of (nc_a / k_a) cells along each axis and its halo of width w_a on
 * either side where k_a > 1); on a tie the slabs (pieces along the later axes). 0: none fits. */
static int choose_boxes(par_solver *ps)
{
    const int K = ps->size, d = ps->dim;
    double best = INFINITY;
    int found = 0;
    for (int k2 = d > 2 ? K : 1; k2 >= 1; --k2) {
        if (K % k2) continue;
        for (int k1 = K / k2; k1 >= 1; --k1) {
            if ((K / k2) % k1) continue;
            const int k[CONSPH_MAX_DIM] = {K / k2 / k1, k1, k2};
            double own = 1.0, ext = 1.0;
            int fits = d > 1 || k1 == 1;
            for (int a = 0; a < d; ++a) {
                fits = fits && k[a] <= ps->nc[a];
                const double o = (double)ps->nc[a] / k[a];
                double e = k[a] > 1 ? o + 2.0 * (double)ps->width[a] : o;
                if (e > (double)ps->nc[a]) e = (double)ps->nc[a];
                own *= o;
                ext *= e;
            }
            if (forced_boxes[0])
                for (int a = 0; a < CONSPH_MAX_DIM; ++a) fits = fits && k[a] == forced_boxes[a];
            if (fits && ext - own < best) {
                best = ext - own;
                for (int a = 0; a < CONSPH_MAX_DIM; ++a) ps->k[a] = k[a];
                found = 1;
            }
        }
        if (d < 2) break;
    }
    return found;
}

/* Cuts s, whose particles are the whole set (range NULL) or this rank's range of it (each
 * carrying its index in the set's order as "id"): the first migration hands them to the boxes'
 * owners, sorted by (cell, index), which is the serial set-up's stable sort by cell. */
static int decompose(consph_solver *s, const solver_range *range)
{
    int init = 0;
    MPI_Initialized(&init);
    if (!s) return consph_fail(CONSPH_EINVAL, "MPI decomposition: needs a solver");
    if (!init || s->par) return CONSPH_OK;
    int size = 1, rank = 0;
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    if (size == 1) return CONSPH_OK;
    consph_particles *p = s->sys.p;
    const size_t n = range ? range->n : p->n, m = p->n;
    const int axis = p->dim - 1;
    if (s->prm.skin > 0.0)
        return consph_fail(CONSPH_EINVAL,
                           "--skin %g: the neighbour list with a skin is not decomposed over MPI "
                           "ranks (its rebuild follows every particle's displacement); run with "
                           "--skin 0 or on one rank",
                           s->prm.skin);
    if (s->scheme->needs_lattice)
        return consph_fail(CONSPH_EINVAL,
                           "scheme %s remeshes every particle onto the lattice, which is not "
                           "decomposed over MPI ranks; run it on one rank",
                           s->scheme->name);
    par_solver *ps = consph_calloc(1, sizeof *ps);
    if (!ps) return par_fail_mem();
    ps->comm = MPI_COMM_WORLD;
    ps->rank = rank;
    ps->size = size;
    ps->dim = p->dim;
    ps->nglobal = n;
    ps->pairs_base = s->pairs;
    ps->made = m;
    /* the whole set's grid, from now on at every build of this rank's part (a range was built
     * on a grid for its own count) */
    nnps_fix_grid(s->sys.nnps, n);
    if (range && consph_nnps_build(s->sys.nnps, p) != CONSPH_OK) {
        free(ps);
        return CONSPH_ENOMEM;
    }
    int64_t reach[CONSPH_MAX_DIM];
    double edge[CONSPH_MAX_DIM];
    nnps_grid(s->sys.nnps, ps->nc, reach, edge);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) {
        ps->k[a] = 1;
        if (a >= ps->dim) continue;
        ps->periodic[a] = p->box.periodic[a] != 0;
        ps->len[a] = p->box.hi[a] - p->box.lo[a];
        ps->width[a] = reach[a] + 1;
        ps->edge[a] = edge[a];
    }
    if ((size_t)size > n) {
        free(ps);
        return consph_fail(CONSPH_EINVAL,
                           "%d MPI ranks for %zu particles: run on at most as many ranks as "
                           "particles",
                           size, n);
    }
    if (!choose_boxes(ps)) {
        const int64_t nca = ps->nc[axis];
        free(ps);
        return consph_fail(CONSPH_EINVAL,
                           "%d MPI ranks, but the decomposition cuts the box into %lld slabs of "
                           "search cells along axis %d (%zu particles), and %d does not factor "
                           "into as many pieces along the axes as their slabs allow: run on at "
                           "most %lld ranks",
                           size, (long long)nca, axis, n, size, (long long)nca);
    }
    int mem = 1;
    ps->nrows = 1;
    for (int a = 0; a < ps->dim; ++a) {
        ps->cut[a] = consph_calloc((size_t)ps->k[a] + 1, sizeof(int64_t));
        ps->piece[a] = consph_calloc((size_t)ps->nc[a], sizeof(int));
        ps->cover_off[a] = consph_calloc((size_t)ps->nc[a] + 1, sizeof(int));
        ps->cover[a] = consph_calloc((size_t)ps->nc[a] * (size_t)ps->k[a], sizeof(int));
        mem = mem && ps->cut[a] && ps->piece[a] && ps->cover_off[a] && ps->cover[a];
        if (a > 0) ps->nrows *= ps->nc[a];
    }
    ps->seg = consph_calloc((size_t)ps->nrows * (size_t)ps->k[0], sizeof(int64_t));
    ps->ranks = consph_calloc((size_t)size, sizeof(int));
    mem = mem && ps->ranks;
    ps->g = malloc((m ? m : 1) * sizeof(double));
    ps->own = malloc((m ? m : 1) * sizeof(size_t));
    ps->scount = consph_calloc((size_t)size, sizeof(int));
    ps->sdispl = consph_calloc((size_t)size, sizeof(int));
    ps->rcount = consph_calloc((size_t)size, sizeof(int));
    ps->rdispl = consph_calloc((size_t)size, sizeof(int));
    ps->sdbl = consph_calloc((size_t)size, sizeof(int));
    ps->sddis = consph_calloc((size_t)size, sizeof(int));
    ps->rdbl = consph_calloc((size_t)size, sizeof(int));
    ps->rddis = consph_calloc((size_t)size, sizeof(int));
    unsigned char *dest = consph_calloc(m ? m : 1, 1);
    if (!mem || !ps->seg || !ps->g || !ps->own || !ps->scount || !ps->sdispl || !ps->rcount ||
        !ps->rdispl || !ps->sdbl || !ps->sddis || !ps->rdbl || !ps->rddis || !dest) {
        free(dest);
        par_solver_free(ps);
        return par_fail_mem();
    }
    if (range) {
        /* This rank made (or read) the particles [lo, hi) of the set's order, which its search
         * sorted by cell: origin[i] is particle i's place in the range. The migration sorts runs
         * ascending in the set's index (own in the range's order). */
        for (size_t i = 0; i < m; ++i) {
            ps->g[i] = (double)(range->lo + s->sys.origin[i]);
            dest[i] = 1;
            ps->own[s->sys.origin[i]] = i;
        }
        ps->nown = m;
    } else {
        /* Every rank holds the whole set in the serial order: each starts from an equal share
         * of that order, which the migration hands to the slabs' owners. */
        const size_t lo = n * (size_t)rank / (size_t)size,
                     hi = n * (size_t)(rank + 1) / (size_t)size;
        for (size_t i = 0; i < n; ++i) {
            ps->g[i] = (double)i;
            dest[i] = i >= lo && i < hi;
        }
        for (size_t i = lo; i < hi; ++i) ps->own[i - lo] = i;
        ps->nown = hi - lo;
    }
    ps->split.refresh = refresh;
    ps->split.refresh_positions = refresh_positions;
    ps->split.max = split_max;
    ps->split.ctx = ps;
    free(s->sys.dest);
    s->sys.dest = dest;
    s->sys.split = &ps->split;
    s->par = ps;
    int st = migrate(s, ps, 0);
    if (st != CONSPH_OK) {
        s->sys.split = NULL;
        s->par = NULL;
        par_solver_free(ps);
    }
    return st;
}

int consph_par_solver_decompose(consph_solver *s)
{
    if (!s || !s->part) return decompose(s, NULL);
    /* a rank's part of a checkpoint (consph_par_run_restart): its neighbour list once cut */
    int st = decompose(s, s->part);
    if (st == CONSPH_OK && s->par) st = solver_nlist_start(s, 1);
    if (st == CONSPH_OK) {
        free(s->part);
        s->part = NULL;
    }
    return st;
}

size_t par_setup_made(const consph_solver *s)
{
    return s && s->par ? s->par->made : s ? s->sys.p->n : 0;
}

void consph_par_solver_comm(const consph_solver *s, double *bytes, double *seconds)
{
    *bytes = s && s->par ? s->par->bytes : 0.0;
    *seconds = s && s->par ? s->par->seconds : 0.0;
}

#else /* no MPI: one rank, nothing to cut */

int par_step_begin(consph_solver *s)
{
    return consph_sys_update(&s->sys, 1);
}

int par_step_end(consph_solver *s, int status)
{
    (void)s;
    return status;
}

int par_global(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg)
{
    return fn(s, arg);
}

int par_global_some(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg,
                    const char *const *only)
{
    (void)only;
    return fn(s, arg);
}

int par_stream(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg)
{
    return fn(s, arg);
}

int par_stream_source(consph_solver *s, const consph_particles **view, io_array_source *src)
{
    (void)s;
    (void)view;
    (void)src;
    return consph_fail(CONSPH_EINVAL, "par_stream_source: built without MPI");
}

int par_sample_due(consph_solver *s)
{
    return !solver_sampled_now(s);
}

int par_rank(const consph_solver *s)
{
    (void)s;
    return 0;
}

int par_cut_weights(const consph_solver *s)
{
    (void)s;
    return 0;
}

int par_geometry(const consph_solver *s, int *k, long long *nc, long long *width)
{
    (void)s;
    (void)k;
    (void)nc;
    (void)width;
    return 0;
}

int par_share_history(consph_solver *s)
{
    (void)s;
    return CONSPH_OK;
}

int par_checks_clean(consph_solver *s, int *clean)
{
    (void)s;
    *clean = 0;
    return CONSPH_OK;
}

int par_owned_sums(consph_solver *s, const double *w, int c, double *out)
{
    for (int k = 0; k < c; ++k) out[k] = consph_sum(w + (size_t)k * s->sys.p->n, s->sys.p->n);
    return CONSPH_OK;
}

int par_owned_max(consph_solver *s, double *v, int c)
{
    (void)s;
    (void)v;
    (void)c;
    return CONSPH_OK;
}

const size_t *par_owned(const consph_solver *s, size_t *nown, size_t *nglobal)
{
    *nown = *nglobal = s->sys.p->n;
    return NULL;
}

void par_solver_free(par_solver *ps)
{
    (void)ps;
}

void par_force_boxes(const int *k)
{
    (void)k;
}

void par_force_count_cut(int on)
{
    (void)on;
}

void par_force_gather_bytes(size_t bytes)
{
    (void)bytes;
}

long par_whole_gathers(void)
{
    return 0;
}

int consph_par_solver_decompose(consph_solver *s)
{
    (void)s;
    return CONSPH_OK;
}

size_t par_setup_made(const consph_solver *s)
{
    return s ? s->sys.p->n : 0;
}

void consph_par_solver_comm(const consph_solver *s, double *bytes, double *seconds)
{
    (void)s;
    *bytes = 0.0;
    *seconds = 0.0;
}

#endif

/* consph_par_solver_create's cut: whether the ranks joined the agreement, and this rank's
 * range of the set (NULL: every rank made the whole set). */
typedef struct create_cut {
    int *joined;
    const solver_range *range;
} create_cut;

/* The ranks agree that every one made its particles (status: this rank's set-up so far; a
 * rank that failed alone, e.g. its part of a packed layout no longer read back from the cache,
 * brings its message to every rank), then cut them (consph_par_solver_create). */
static int agree_and_cut(consph_solver *s, void *arg, int status)
{
    create_cut *c = arg;
    const int st = consph_par_agree(status);
    *c->joined = 1;
#ifdef CONSPH_HAVE_MPI
    return st == CONSPH_OK ? decompose(s, c->range) : st;
#else
    return st == CONSPH_OK ? consph_par_solver_decompose(s) : st;
#endif
}

/* The particles of the set-up and whether each rank can make only its share of them: a layout
 * made particle by particle from its index, a packed one (whose particles move together) that
 * every rank can read from the layout cache, or the given particles; not for a scheme that
 * remeshes onto the lattice (refused decomposed) or more ranks than particles (refused, the
 * message the whole set's cut gives). Collective: every rank calls it with the same run. */
static int setup_range(const consph_run_params *prm, const consph_particles *given, int rank,
                       int size, solver_range *r, consph_particles *keep)
{
    const scheme_def *sd = scheme_find(prm->scheme);
    consph_layout_params lp;
    if (!sd || sd->needs_lattice) return 0;
    size_t n = 0;
    if (given) {
        /* the run's count (the given set may hold all of them or this rank's range only) */
        const int dim = consph_problem_dim(prm->problem);
        n = prm->n > 0 ? (size_t)prm->n : (size_t)lround(pow((double)prm->nx, dim));
        if (dim < 1) return 0;
    } else {
        if (consph_run_layout_params(prm, &lp) != CONSPH_OK) return 0;
        n = 1;
        for (int a = 0; a < lp.dim; ++a) n *= lp.nx[a];
    }
    if (n < (size_t)size) return 0;
    r->n = n;
    r->lo = n * (size_t)rank / (size_t)size;
    r->hi = n * (size_t)(rank + 1) / (size_t)size;
    r->made = NULL;
    if (given || consph_layout_by_index(lp.kind)) return 1;
    /* a packed layout: its parts from the layout cache when every rank reads a valid file
     * there (each reads its range once, kept in *keep for the set-up: r->made), else the whole
     * set packed (or read) on every rank */
    consph_particles part;
    const int mine = consph_layout_cache_get() &&
                     consph_layout_generate_range(&lp, r->lo, r->hi - r->lo, &part) == CONSPH_OK;
    const int all = !consph_par_max_int(!mine);
    if (mine && all && keep) {
        *keep = part;
        r->made = keep;
    } else if (mine) {
        consph_particles_free(&part);
    }
    return all;
}

int consph_par_solver_create(consph_solver **out, const consph_run_params *prm,
                             const consph_particles *given, int *joined)
{
    int mine = 0;
    if (!joined) joined = &mine;
    *joined = 0;
    const int size = consph_par_size();
    if (size < 2) return consph_solver_create_from(out, prm, given);
    solver_range range;
    consph_particles part; /* a packed layout's part read from the cache: the set-up takes it */
    memset(&part, 0, sizeof part);
    const int ranged = setup_range(prm, given, consph_par_rank(), size, &range, &part);
    create_cut c = {joined, ranged ? &range : NULL};
    const int st = solver_create_cut(out, prm, given, c.range, agree_and_cut, &c);
    consph_particles_free(&part); /* left there when the set-up failed before taking it */
    return st;
}

#ifdef CONSPH_HAVE_MPI
/* One column of the given particles from rank 0: every rank's range [lo_q, hi_q) of it (rank 0
 * keeps its own), or with `whole` the whole column to every rank; in messages of at most
 * GATHER_MSG_BYTES. src: rank 0's whole column; dst: this rank's part (rank 0's may be src). */
static void share_column(MPI_Comm comm, int rank, int size, int whole, size_t n, const double *src,
                         double *dst)
{
    const size_t most = GATHER_MSG_BYTES / sizeof(double);
    if (whole) {
        double *buf = rank == 0 ? (double *)src : dst;
        for (size_t o = 0; o < n; o += most)
            MPI_Bcast(buf + o, (int)(n - o < most ? n - o : most), MPI_DOUBLE, 0, comm);
        if (rank == 0 && dst != src) memcpy(dst, src, n * sizeof(double));
        return;
    }
    for (int q = rank == 0 ? 0 : rank; q < (rank == 0 ? size : rank + 1); ++q) {
        const size_t lo = n * (size_t)q / (size_t)size, hi = n * (size_t)(q + 1) / (size_t)size;
        if (q == 0) {
            memcpy(dst, src, (hi - lo) * sizeof(double));
            continue;
        }
        for (size_t o = lo; o < hi; o += most) {
            const int k = (int)(hi - o < most ? hi - o : most);
            if (rank == 0)
                MPI_Send(src + o, k, MPI_DOUBLE, q, TAG_GATHER, comm);
            else
                MPI_Recv(dst + (o - lo), k, MPI_DOUBLE, 0, TAG_GATHER, comm, MPI_STATUS_IGNORE);
        }
    }
}
#endif

int consph_par_given_share(consph_run_params *prm, consph_particles *given)
{
    const int size = consph_par_size();
    if (size < 2) return CONSPH_OK;
#ifdef CONSPH_HAVE_MPI
    const int rank = consph_par_rank();
    MPI_Comm comm;
    MPI_Comm_dup(MPI_COMM_WORLD, &comm);
    /* rank 0's count, dimension, box and given fields */
    const consph_field *fu = rank == 0 ? consph_particles_find(given, "u") : NULL,
                       *fp = rank == 0 ? consph_particles_find(given, "p") : NULL;
    unsigned long long head[4] = {rank == 0 ? given->n : 0, rank == 0 ? (unsigned)given->dim : 0,
                                  fu != NULL, fp != NULL};
    MPI_Bcast(head, 4, MPI_UNSIGNED_LONG_LONG, 0, comm);
    consph_box box;
    if (rank == 0) box = given->box;
    MPI_Bcast(&box, (int)sizeof box, MPI_BYTE, 0, comm);
    const size_t n = (size_t)head[0];
    const int dim = (int)head[1];
    int st = rank == 0 ? CONSPH_OK : consph_run_params_particles(prm, n);
    /* ranged as consph_par_solver_create will be (every rank the same answer); else every
     * rank takes the whole set, as when each read the file */
    solver_range r;
    const int ranged = st == CONSPH_OK && setup_range(prm, given, rank, size, &r, NULL);
    const size_t m = ranged ? r.hi - r.lo : n;
    consph_particles mine;
    memset(&mine, 0, sizeof mine);
    if (st == CONSPH_OK && !(rank == 0 && !ranged)) {
        st = consph_particles_init(&mine, dim, m, &box);
        if (st == CONSPH_OK && ((head[2] && !consph_particles_field(&mine, "u", dim)) ||
                                (head[3] && !consph_particles_field(&mine, "p", 1))))
            st = CONSPH_ENOMEM;
    }
    /* the failing rank's message to every rank: rank 0 prints it */
    if ((st = consph_par_agree(st)) != CONSPH_OK) {
        consph_particles_free(&mine);
        MPI_Comm_free(&comm);
        return st;
    }
    /* rank 0 keeps the whole set when every rank takes it */
    consph_particles *dst = rank == 0 && !ranged ? given : &mine;
    const consph_field *du = consph_particles_find(dst, "u"), *dp = consph_particles_find(dst, "p");
    for (int a = 0; a < dim; ++a)
        share_column(comm, rank, size, !ranged, n, rank == 0 ? given->x[a] : NULL, dst->x[a]);
    for (int a = 0; head[2] && a < dim; ++a)
        share_column(comm, rank, size, !ranged, n,
                     rank == 0 ? fu->data + (size_t)a * given->cap : NULL,
                     du->data + (size_t)a * dst->cap);
    if (head[3]) share_column(comm, rank, size, !ranged, n, rank == 0 ? fp->data : NULL, dp->data);
    MPI_Comm_free(&comm);
    if (dst == &mine) {
        if (rank == 0) consph_particles_free(given);
        *given = mine;
    }
    return CONSPH_OK;
#else
    (void)prm;
    (void)given;
    return CONSPH_OK;
#endif
}

int consph_par_run_restart(consph_solver **s, const char *checkpoint)
{
    const int size = consph_par_size();
    *s = NULL;
    if (size < 2) return consph_run_restart(s, checkpoint);
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0, first = 0, total = 0;
    consph_particles p;
    int st = consph_checkpoint_read_part(checkpoint, consph_par_rank(), size, &meta, &p, &hist, &nh,
                                         &first, &total);
    if (st != CONSPH_OK) return st;
    if (total < (size_t)size) {
        /* more ranks than particles: the whole set's cut refuses the launch with its message */
        free(meta);
        free(hist);
        consph_particles_free(&p);
        return consph_run_restart(s, checkpoint);
    }
    const solver_range range = {first, first + p.n, total, NULL};
    return solver_restore_read(s, checkpoint, meta, &p, hist, nh, &range);
}
