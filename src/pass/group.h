/* Passes over groups of particles (group.c): internal to the library, for visits that sum the
 * neighbourhoods of several particles at once in the lanes of a vector. */
#ifndef CONSPH_PASS_GROUP_H
#define CONSPH_PASS_GROUP_H

#include "consph/pass.h"
#include "pass/nbhd.h"

/* Particles per group: the lanes of a vector of doubles on AVX2. */
#define PASS_GROUP 4

/* Called once per group of count (1..PASS_GROUP) destination particles, nb[0..count), each
 * neighbourhood exactly as consph_pass_run hands it to a visit (the same neighbours in the same
 * order, the same separations and kernel values bit for bit). Its arrays extend past nb[l].n to
 * the group's largest n with entries of the particle itself (j = i, zero separations, r and
 * kernel values), so that the lanes of a vector can run to the same end; nb[count..PASS_GROUP)
 * repeat nb[0]. Writes results for the group's particles only. */
typedef void (*pass_group_fn)(void *job, const consph_nbhd *nb, int count);

/* consph_pass_run_counted with a group visit; `need` and `name` as a consph_pass's. The groups
 * are consecutive destination particles of one cell of the search (a run of destinations cut in
 * fours: the halo of a decomposed system is sources only, never visited). Returns
 * PASS_GROUP_UNSERVED (having done nothing but a decomposed system's refresh, which the
 * per-particle pass then does not repeat) where it does not serve the system: a neighbour list
 * that serves the pass from its cache or its own filter, a tensor-product kernel or particles
 * not in cell order; the caller then runs the pass with a per-particle visit, which sums the
 * same values. */
#define PASS_GROUP_UNSERVED 1
/* In `need`: the visit reads no entry of a lane past its own n (it masks the lanes that have
 * run out), so a neighbour list's pair cache (src/pass/nlist.c) can serve the pass as it
 * stands, without the padding, where it serves the state's passes. */
#define PASS_GROUP_UNPADDED (1u << 16)
/* In `need`: the visit reads nb->j as slots of the search (consph_nnps_slots: cell order), not
 * as particles, and the padding repeats the lane's own slot (nb->i stays its particle). The
 * gather then skips mapping every neighbour's slot to its particle, and a visit that reads
 * per-neighbour values from an array in slot order reads the neighbours of a cell from nearby
 * lines. pass_run_groups and pass_run_groups2 (not the neighbour list's unpadded run). */
#define PASS_GROUP_SLOTS NBHD_SLOTS
/* In pass_run_groups2's need2: the second visit gets each group's entries interleaved, entry k of
 * lane l at index 4k + l of every array (nb[l].j, .dx[a], .r, .w, .dwr, .d2w point at lane l's
 * first entry: read with a stride of PASS_GROUP, or as one vector per entry from nb[0]'s), so
 * that a visit that sums the lanes side by side reads an entry's four values with one load. The
 * neighbourhoods are kept that way (the copy that keeps them interleaves), and the ones gathered
 * for the second pass alone are interleaved before its visit. Only pass_run_groups2 honours it. */
#define PASS_GROUP_INTERLEAVED (1u << 18)
/* Cells per dynamic chunk of a pass over ncells cells: up to 16 (at the default cells per radius a
 * 2D cell holds ~13 particles at h = 1.2Δs with the quintic kernel, a 3D one ~6), fewer where the
 * cells are few for the threads, so that the last chunks leave no thread waiting long. */
size_t pass_cells_per_chunk(size_t ncells);

/* A decomposed system's halo refresh (consph_sys_split) now, unless the system was refreshed for
 * the next pass already: a caller that fills per-particle rows of a pack (values a group visit
 * reads at the neighbours) for the halo calls it before, and the pass that follows (this one,
 * pass_run_groups or consph_pass_run_counted) reads the halo as refreshed here instead of
 * refreshing again. Nothing without a split. */
int pass_halo_refresh(consph_sys *s);
/* A buffer of at least count doubles that the system owns, for the packs of the group visits
 * on a decomposed system: the halo refresh carries the system scratch (consph_sys_scratch) as
 * columns of n values, which would overwrite a pack's rows. Undefined contents, kept until the
 * next call; NULL (with an error) when out of memory. */
double *sys_pack_buffer(consph_sys *s, size_t count);

/* Calls of pass_run_groups that ran their pass (for tests: that the group visits did run). */
extern unsigned long pass_group_runs;
int pass_run_groups(const consph_sys *s, const char *name, unsigned need, pass_group_fn visit,
                    void *job, size_t *pairs);

/* Two passes over one position state where the second reads what the first wrote of the
 * neighbours (a summation density, then the rates): the results of pass_run_groups(first)
 * followed by pass_run_groups(second), bit for bit, with each neighbourhood gathered and its
 * kernel values evaluated once for both where it can be (group.c: the passes run slab by slab
 * of cells, the second a few slabs behind the first, the neighbourhoods in between kept). The
 * first visit must write results of its own particles only and read nothing that the first
 * visit writes; the second may read any particle's. PASS_GROUP_SLOTS in both needs or in
 * neither. Returns PASS_GROUP_UNSERVED where pass_run_groups would, under a destination mask
 * without a split, or where the needs differ in PASS_GROUP_SLOTS; pairs counts both passes'
 * pairs. On a decomposed system (the caller has made the first pass's refresh) the sweep runs
 * the second pass only on the cells whose candidates are all the rank's own; then
 * prepare2(s, ctx) makes the second pass's refresh (and fills whatever the halo's rows need)
 * and the second pass runs on the other cells of the rank (a cell holding halo particles too, as
 * particles drift between re-sorts, is visited at the rank's own). It declines (before any
 * refresh) without prepare2 or where the list declines; the caller's passes one by one make the
 * same refreshes, so ranks may choose apart. */
/* Tile-slabs whose second pass read the neighbourhoods the first kept (for tests: that it did),
 * and the strips' width in cells (12; tests narrow it to have edge columns on small grids). */
extern unsigned long pass_group_kept_slabs;
extern size_t pass_group2_strip_cells;
/* Calls on a decomposed system, and the cells whose second pass they left for after the sweep
 * (for tests). */
extern unsigned long pass_group2_split, pass_group2_deferred;
int pass_run_groups2(const consph_sys *s, const char *name1, unsigned need1, pass_group_fn visit1,
                     const char *name2, unsigned need2, pass_group_fn visit2, void *job,
                     size_t *pairs, int (*prepare2)(consph_sys *s, void *ctx), void *ctx);

#endif
