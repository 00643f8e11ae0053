/* consph pass: the one traversal every pair sum in consph runs on, and the way a user adds an
 * equation.
 *
 * A *system* is what a pass runs over: particles (positions and named fields, kept in cell
 * order), a radial kernel, a neighbour search built on the particles, and a destination mask.
 * Particles outside the mask are sources only: they appear among the neighbours of the others
 * but receive no sums (walls, ghosts and MPI halo particles).
 *
 * A *pass* visits every destination particle once with its neighbourhood: the neighbours j (i
 * itself included, at r = 0), the separations x_ij = x_i - x_j, r = |x_ij| and, as the pass asks,
 * W(r), W'(r)/r and W''(r). The visit is one call per particle: it initialises its sums, runs
 * over the pairs and finalises, so a pass pays one indirect call per particle and none per pair.
 * Several quantities are fused in one pass by summing them in the same visit over the shared
 * pair geometry.
 *
 * Conventions (001 App. C, 002 eq. 15): x_ij = x_i - x_j, ∇W_ij = ∇_i W(|x_i - x_j|) = dwr·x_ij
 * with dwr = W'(r)/r; at r = 0, dwr holds the limit W''(0), which keeps the kernel Hessian
 * (W'' - W'/r) e e + (W'/r) I continuous and ∇W = 0 there.
 *
 * Passes are gathers: a visit writes only to particle nb->i. Particles are visited in parallel,
 * in an order that varies with the thread count, and each neighbourhood comes in a fixed order,
 * so results do not depend on the number of threads. */
#ifndef CONSPH_PASS_H
#define CONSPH_PASS_H

#include <stddef.h>

#include "consph/core.h"
#include "consph/kernels.h"
#include "consph/nnps.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What a pass needs evaluated per pair. CONSPH_PASS_NO_DX: the visit reads no separation
 * (nb->dx is then NULL), which spares their stores. */
enum {
    CONSPH_PASS_W = 1u,    /* nb->w */
    CONSPH_PASS_DW = 2u,   /* nb->dwr */
    CONSPH_PASS_D2W = 4u,  /* nb->d2w (and nb->dwr) */
    CONSPH_PASS_NO_DX = 8u /* nb->dx[] NULL */
};

/* One destination particle's neighbourhood as a pass sees it. Arrays hold nb->n entries; those
 * the pass did not ask for are NULL. */
typedef struct consph_nbhd {
    size_t i, n;                      /* the particle, and its neighbour count */
    const size_t *j;                  /* the neighbours (i among them) */
    const double *dx[CONSPH_MAX_DIM]; /* x_i - x_j per axis; NULL past dim */
    const double *r;
    const double *w;
    const double *dwr; /* W'(r)/r */
    const double *d2w; /* W''(r) */
} consph_nbhd;

/* Called once per destination particle, possibly from several threads at once; writes results
 * for nb->i only. */
typedef void (*consph_visit_fn)(void *job, const consph_nbhd *nb);

typedef struct consph_pass {
    const char *name; /* for messages */
    unsigned need;    /* CONSPH_PASS_* */
    consph_visit_fn visit;
} consph_pass;

/* ---- the system ---- */

typedef struct consph_nlist consph_nlist; /* src/pass/nlist.c */
struct consph_sys;

/* A system that is one part of a particle set decomposed over processes (src/par: MPI ranks).
 * Its particles outside the destination mask are the halo: copies of other parts' particles.
 * refresh brings the halo's positions, named fields and the system scratch (in blocks of n
 * values) up to date with their owners (only what the next pass declared it reads, where it
 * did: consph_sys_next_reads); it runs at the start of every pass and of every
 * consph_sys_update (refresh_positions there, where given), so a pass reads the neighbours'
 * current values whatever the caller changed since. max is the maximum of v over every part (NaN
 * when any part's is NaN), for a loop over the particles that must agree on every part. */
typedef struct consph_sys_split {
    int (*refresh)(struct consph_sys *s, void *ctx);
    double (*max)(void *ctx, double v);
    void *ctx;
    /* optional: the halo's positions alone, at consph_sys_update (whose search reads nothing
     * else; the next pass refreshes the rest); NULL: refresh */
    int (*refresh_positions)(struct consph_sys *s, void *ctx);
} consph_sys_split;

/* What the next pass reads at its neighbours, for a decomposed system's halo refresh
 * (consph_sys_next_reads): the positions (the search's and the gathers' separations: the
 * refresh at consph_sys_update brings them, so a pass over the current search needs them only
 * where the positions changed since), the named fields (comps[k]: a bit per component, 0: every
 * one; a name the particles lack is no column) and every block of the system scratch. The halo's
 * other columns are left as they are, neither compared nor sent. */
#define CONSPH_SYS_READS_MAX 8
typedef struct consph_sys_reads {
    int positions, scratch;
    const char *fields[CONSPH_SYS_READS_MAX]; /* up to the first NULL */
    unsigned comps[CONSPH_SYS_READS_MAX];
} consph_sys_reads;

typedef struct consph_sys {
    consph_particles *p; /* in cell order after consph_sys_init */
    consph_nnps *nnps;
    consph_kernel kernel;
    unsigned char *dest; /* NULL: every particle receives sums; else those with dest[i] != 0 */
    size_t *origin;      /* origin[i]: index in the particles given to consph_sys_init of the
                            particle now at i (NULL for a wrapped system) */
    size_t parallel_min; /* passes over fewer particles run on one thread (default 2048): a
                            parallel region costs more than it saves on tiny sets */
    int owned;           /* 1 when p, nnps, origin and dest belong to the system */
    double *scratch;     /* consph_sys_scratch's buffer, always the system's own */
    size_t scratch_cap;
    consph_nlist *nlist;           /* consph_sys_nlist's neighbour list; NULL: every pass gathers */
    size_t scratch_asked;          /* the count of the last consph_sys_scratch */
    const consph_sys_split *split; /* NULL: the system is the whole particle set */
    size_t *resort_buf;            /* a re-sort's permutation and carried copies, kept */
    size_t resort_cap;
    double *ipst_buf; /* reg_ipst's sums and shifts, kept: fresh pages at each call otherwise */
    size_t ipst_cap;
    /* the group visits' packs on a decomposed system (src/pass/group.h, sys_pack_buffer): not
     * the scratch, whose blocks the halo refresh carries as columns */
    double *pack_buf;
    size_t pack_cap;
    int halo_fresh; /* split: refreshed for the next pass, which then does not refresh again */
    /* split: what the next pass reads at its neighbours (reads_set 0: every column), taken by
     * the refresh before it (pass_halo_refresh) */
    consph_sys_reads reads;
    int reads_set;
} consph_sys;

/* The distance within which the kernel can be non-zero: the radius a system's search needs
 * (kernel->radius, or kernel->radius·sqrt(dim) for a tensor-product kernel). */
double consph_sys_reach(const consph_kernel *kernel);

/* Copies src, sorts the copy into cell order and builds a neighbour search of radius
 * max(radius, kernel->radius) on it (kernel->radius·sqrt(dim) for a tensor-product kernel, whose
 * support is a cube: consph_sys_wrap asks the same of the caller's search). The kernel must be
 * radial unless every pass run on the system asks for W alone. */
int consph_sys_init(consph_sys *s, const consph_particles *src, const consph_kernel *kernel,
                    double radius);
/* A system over particles and a search the caller owns and has built (nothing is copied or
 * sorted; the caller keeps them alive and rebuilds the search after moving particles). */
int consph_sys_wrap(consph_sys *s, consph_particles *p, consph_nnps *nnps,
                    const consph_kernel *kernel);
/* After the particles moved: rebuilds the search; with resort, first sorts the particles (every
 * named field, origin and the destination mask with them) back into cell order. */
int consph_sys_update(consph_sys *s, int resort);
/* ---- the neighbour list (opt-in) ----
 *
 * consph_sys_nlist gives the system a per-particle list of candidate neighbours within
 * (1 + skin)·radius (radius: consph_sys_reach), built from the search's cell traversal in the
 * order a pass gathers them, with the periodic image of each candidate (every image, also when
 * the radius exceeds half the box). The first pass after the particles moved filters each
 * particle's candidates by the current separations into a cache of the neighbours within the
 * radius with x_ij, r and, as passes ask, W, W'/r and W''; every later pass until the next move
 * is handed pointers into it, so the gather and the kernel are evaluated once per position
 * state instead of once per pass.
 *
 * consph_sys_update is then the one call after every move: it invalidates the cache and
 * rebuilds the list (with resort: re-sorted into cell order first) only when some particle has
 * moved more than skin·radius/2 since the list was built (then no pair can have crossed the
 * skin). The test is a maximum over particles, so it does not depend on the thread count.
 *
 * With skin 0 the list is rebuilt at every consph_sys_update exactly as the search is today, and
 * the neighbours, their order, separations and kernel values are those of the gather bit for
 * bit. With skin > 0 the neighbours come in the candidates' order and x_ij is computed from the
 * positions at the build plus each particle's displacement since (a round-off change). The list
 * is a function of the particles' order and their positions at the build: a caller that must
 * restart bit for bit keeps those positions in a named particle field (build_field) and, on
 * resuming, calls consph_sys_nlist with resume = 1 on the particles in the order they were
 * saved, which rebuilds the same list from them.
 *
 * Memory: per candidate 6 bytes, per cached pair 8 + 8·dim + 8 per kernel value (see
 * consph_sys_nlist_info). Above CONSPH_NLIST_MAX_CANDIDATES candidates per particle on average
 * the list turns itself off (passes gather as without it) and the info's note says so. */
#define CONSPH_NLIST_MAX_CANDIDATES 400

/* skin >= 0 turns the list on (the system must own its search: consph_sys_init, and have a
 * radial kernel); skin < 0 turns it off. build_field: NULL, or the name of a dim-component
 * particle field (created if absent) that holds the positions of the last build, so that it
 * follows re-sorts and is saved with the particles. resume: build from build_field's positions
 * and, for a system made by consph_sys_init, in the order of the particles it was given. */
int consph_sys_nlist(consph_sys *s, double skin, const char *build_field, int resume);

typedef struct consph_nlist_info {
    int on;            /* the passes run on the list */
    double skin;       /* as set (also when the list turned itself off) */
    size_t builds;     /* list builds so far */
    size_t caches;     /* pair caches computed so far */
    double candidates; /* per particle, mean at the last build */
    double pairs;      /* per particle, mean in the last cache */
    double bytes;      /* per particle: list, cache and build positions */
    char note[200];    /* why the list is off, or "" */
} consph_nlist_info;

void consph_sys_nlist_info(const consph_sys *s, consph_nlist_info *info);

/* Tells the system's neighbour list that `passes` passes, needing together the kernel values
 * `need` (CONSPH_PASS_W, _DW, _D2W), will read the current positions (until the next
 * consph_sys_update). With 2 or more the first of them caches the pairs with all those values
 * (one gather and one kernel batch for all), whatever the previous state's passes were. A hint
 * only: it changes no result, and does nothing on a system without a list. */
void consph_sys_expect_passes(consph_sys *s, int passes, unsigned need);

/* The next pass (the next consph_pass_run or group run, or the refresh a caller makes before
 * filling its packs' halo rows: pass_halo_refresh) reads at its neighbours only what r names:
 * a decomposed system's refresh then compares, sends and rewrites only those columns of its
 * halo (the others keep what they held, and their kept copies what was last exchanged, so a
 * later pass that reads one finds every change since). Without a call a pass reads every
 * column. Nothing without a split. */
void consph_sys_next_reads(consph_sys *s, const consph_sys_reads *r);

/* Sets the destination mask (n entries in the system's particle order; copied), or clears it
 * with NULL. */
int consph_sys_set_dest(consph_sys *s, const unsigned char *dest);
void consph_sys_free(consph_sys *s);
/* A buffer of at least `count` doubles that the system owns, for per-particle values that a job
 * derives from the state before a pass (a value per particle computed once instead of once per
 * pair) without adding a particle field, which would appear in every snapshot. The contents
 * are undefined on return, kept until the next call, and do not follow a re-sort. NULL (with an
 * error) when out of memory. */
double *consph_sys_scratch(consph_sys *s, size_t count);

/* Runs the pass over every destination particle. */
int consph_pass_run(const consph_sys *s, const consph_pass *pass, void *job);
/* The same, adding the number of pairs visited to *pairs. */
int consph_pass_run_counted(const consph_sys *s, const consph_pass *pass, void *job, size_t *pairs);

#ifdef __cplusplus
}
#endif

#endif
