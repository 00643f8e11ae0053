/* The neighbour list with a skin and the pair-geometry cache behind consph_sys_nlist (nlist.c):
 * internal to the pass layer. */
#ifndef CONSPH_PASS_NLIST_H
#define CONSPH_PASS_NLIST_H

#include "consph/pass.h"
#include "pass/group.h"

#include <stdint.h>

/* consph_sys_update when the system has a list: the same contract (rebuild after a move; with
 * resort, the re-sort into cell order where the list is rebuilt). */
int nlist_update(consph_sys *s, int resort);
/* consph_pass_run_counted over the list and its cache; NLIST_GATHER (and nothing done) where
 * the search's own gather serves the pass as well (skin 0 without a cache). */
#define NLIST_GATHER 1
int nlist_pass_run(const consph_sys *s, const consph_pass *pass, void *job, size_t *pairs);
/* A pass over groups of particles (src/pass/group.h) from the cache, where the cache serves
 * this pass: the lanes' arrays are the cache's, NOT padded past each lane's n. *ran: 1 ran it;
 * 0 not, the pass counted as one the search's gather serves (skin 0, no cache); -1 not,
 * nothing counted (the per-particle pass serves it: a filled cache, a stream). Under a
 * destination mask the groups are runs of consecutive destinations cut in fours. */
int nlist_group_run(const consph_sys *s, const char *name, unsigned need, pass_group_fn visit,
                    void *job, size_t *pairs, int *ran);
/* One pass of a chain (nlist_chain_run): its per-particle visit, and a group visit or NULL;
 * uncounted: its pairs are left out of *pairs (a pass whose caller does not count it). */
typedef struct block_visitor_in {
    const consph_pass *pass;
    pass_group_fn group;
    void *job;
    int uncounted;
    /* A decomposed system (s->split) only: brings into the halo what this pass reads there (its
     * refresh, and any rows of a pack that the halo's sources fill), before the sweep for pass
     * 0 and before the visits the sweep left for a later pass. Every rank calls the same ones,
     * in order, whether its chain ran or not: the caller's passes run one by one make the same
     * refreshes (they are collective). NULL: nothing. */
    int (*prepare)(consph_sys *s, void *ctx);
    void *prepare_ctx;
} block_visitor_in;
/* Passes in[0..count) on the current position state, each reading at the neighbours what the
 * one before wrote, in one wavefront over the pair cache (nlist.c), which it fills where this
 * state has none yet: the values of running them one after the other. *ran 0 (nothing done)
 * where the cache would not serve them so (a destination mask without a split, a chain of one
 * or more than four): the caller runs them one by one. On a decomposed system the sweep runs
 * pass k at a particle only where pass k - 1 is done at every neighbour, which the halo's are
 * not (their values come with the refresh); the rest of each pass k >= 1 runs after the sweep,
 * after in[k].prepare, in order. */
int nlist_chain_run(const consph_sys *s, const block_visitor_in *in, int count, size_t *pairs,
                    int *ran);
/* Blocks that a chain's later passes visited during its sweep, not after it, and chains that
 * ran over a cache already filled on their state (for tests). */
extern unsigned long nlist_chain_trailing, nlist_chain_filled;
/* Chains that recycled their blocks' pair arrays (the state's announced last readers). */
extern unsigned long nlist_chain_recycled;
/* Chains that ran on a decomposed system, and the visits of a particle they left for after the
 * sweep (for tests). */
extern unsigned long nlist_chain_split, nlist_chain_deferred;
/* The largest halo, over the particles a rank owns, at which a decomposed system chains its
 * passes (nlist.c says why; tests raise it). */
extern double nlist_chain_split_halo;
/* Whether nlist_pass_run would leave the next pass to the search's gather; if so, counts it as
 * run (a caller that runs the pass itself asks this instead of calling nlist_pass_run). */
int nlist_gathers(consph_nlist *l);
void nlist_free(consph_nlist *l);
/* The processes sharing this machine's memory (MPI ranks on one node; 1 without MPI): the pair
 * cache's default budget is half the physical memory shared among them. Set once at start-up
 * (src/par/world.c), before any list is made. */
void nlist_node_processes(int count);
/* Whether the passes run on the list (it is on and holds the system's n particles). */
int nlist_serves(const consph_nlist *l, size_t n);

/* The pairs the cache holds for each particle (count[i] for particle i; 0 for a source only)
 * when it holds those of the current position state: returns that state's epoch (nonzero),
 * else 0 and count untouched. count NULL: only whether (and which epoch). Integers filled by
 * the build alone, so the same for any thread count (the MPI cut's weights, src/par). */
unsigned long nlist_pair_counts(const consph_nlist *l, uint32_t *count);

/* Carries the origin and the destination mask of a system through new[i] = old[perm[i]]
 * (pass.c). */
int sys_carry_permutation(consph_sys *s, const size_t *perm);
/* The system's re-sort buffer (kept between re-sorts: fresh buffers of hundreds of kB every step
 * came back from the kernel as zeroed pages each time), at least 2n + n/8 + 1 entries: the
 * permutation in its first n, which sys_carry_permutation leaves alone (it takes the rest, and
 * does not move the buffer once it holds n particles' room); NULL with CONSPH_ENOMEM recorded. */
size_t *sys_resort_buffer(consph_sys *s, size_t n);

#endif
