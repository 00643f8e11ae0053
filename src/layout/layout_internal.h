/* Helpers shared by the files of the layout module; not part of the public API. */
#ifndef CONSPH_LAYOUT_INTERNAL_H
#define CONSPH_LAYOUT_INTERNAL_H

#include <math.h>
#include <stdint.h>

#include "consph/kernels.h"
#include "consph/layout.h"
#include "consph/nnps.h"
#include "consph/pass.h"

/* Brings x back into [lo, lo + len) on a periodic axis. The final test catches the case where
 * x - lo is a tiny negative number and adding len rounds to exactly len. */
static inline double layout_wrap(double x, double lo, double len)
{
    /* fmod returns its argument exactly when |x - lo| < len, the common case of a particle moved
     * by less than the box: the library call is skipped there, with the same result. */
    const double off = x - lo;
    double s = fabs(off) < len ? off : fmod(off, len);
    if (s < 0.0) s += len;
    if (!(s < len)) s = 0.0;
    return lo + s;
}

/* Summation density rho_i = mass sum_j W(r_ij) (self included) for every destination particle
 * of the system, with its kernel. When nn_dist is non-NULL it also receives the distance from each
 * particle to its nearest other particle (or periodic image) within the search radius, +inf when
 * there is none; with rho NULL no kernel value is evaluated. One pass: independent of the number
 * of threads. */
int consph_layout_density(const consph_sys *s, double mass, double *rho, double *nn_dist);

/* A kernel of support radius `radius`, for systems whose passes ask for no kernel value (a
 * system needs a kernel no wider than its search). */
int consph_layout_probe_kernel(int dim, double radius, consph_kernel *k);

/* Adds amplitude·Δs·(2U - 1), U uniform in [0, 1) from the generator seeded with lp->seed, to
 * every coordinate (particle by particle, axis by axis) and wraps on periodic axes. */
void consph_layout_perturb(const consph_layout_params *lp, consph_particles *p, double ds,
                           double amplitude);

/* max_i |rho_i / rho0 - 1|. */
double consph_layout_spread(const double *rho, size_t n, double rho0);

/* The packing iteration of the packed kind: relaxes the positions already in `p` (a perturbed
 * lattice of spacing p->spacing in a periodic box). */
int consph_layout_pack(const consph_layout_params *lp, consph_particles *p,
                       consph_packing_report *report);

/* The packing's neighbour list (pairlist.c): for particle i, entries [start[i], start[i + 1])
 * hold each neighbour j within `radius` at the last build (i itself among them, at r = 0) and
 * the periodic image of the pair, so that x_ij = x_i - (x_j + image·len) per axis, which holds
 * as long as the positions are not wrapped between builds. x_ref holds the positions at the
 * build, to tell when a particle has moved far enough to need a new list. */
/* Tests: 1 makes the packing use its portable loops even where the processor has AVX2, 2 its
 * AVX2 loops even where it has AVX-512 (all give the same positions bit for bit); 0 restores the
 * choice by processor. */
void layout_pack_set_portable(int level);
/* Tests: on = 0 runs the packing's density and force walks one after the other instead of as a
 * wavefront (the same positions bit for bit), 1 restores the wavefront; ring_chunks > 0 sizes
 * its rings of W'/r in chunks (0: the default). */
void layout_pack_set_wavefront(int on, int ring_chunks);

/* The packing's parameter checks (those consph_layout_pack makes first). */
int layout_check_packing(const consph_layout_params *lp);
/* The fewest frozen layers packed's walls may have with this kernel: half its support, in Δs. */
int layout_min_walls(consph_kernel_id id, double hdx);

/* The cache (cache.c): 1 when it is on and the kind is cached; a hit fills the positions of p
 * (initialised, n and dim of lp) and the report (when non-NULL) and returns 1; a miss or a bad
 * file returns 0 (a bad file with one line on stderr). store writes a file (a failure to write
 * warns once on stderr and turns the writes off). */
int layout_cache_enabled(const consph_layout_params *lp);
int layout_cache_load(const consph_layout_params *lp, consph_particles *p,
                      consph_packing_report *report);
void layout_cache_store(const consph_layout_params *lp, const consph_particles *p,
                        const consph_packing_report *report);
/* The particles [first, first + p->n) of a layout of n particles from its cache file (p
 * initialised with their count and dim), after the checks layout_cache_load makes of the whole
 * file (read in blocks: the range and 1 MiB are held); 1 when read, 0 (nothing printed) when
 * the file is missing or not a valid one. */
int layout_cache_load_range(const consph_layout_params *lp, size_t n, size_t first,
                            consph_particles *p);
/* An exclusive lock (flock) on the layout's key while it is packed, so that a process asking for
 * a layout another one is packing waits and reads its file rather than packing it again (a
 * study's worker processes, concurrent runs); the kernel releases it if its holder dies. The
 * lock's descriptor, or -1 when none could be taken (the packing then goes on unlocked). */
int layout_cache_lock(const consph_layout_params *lp);
void layout_cache_unlock(int fd);

/* Entries past the end of the list arrays that a vector loop may read (whole blocks of eight). */
#define PACK_SLACK 8
/* Doubles per particle in the list's interleaved copy xv: the coordinates from slot 0, the force's
 * per-particle weight in slot 3, so that one particle is one aligned 32-byte row. */
#define PACK_XV_STRIDE 4
#define PACK_XV_WEIGHT 3

typedef struct pack_list_part pack_list_part;

typedef struct pack_list {
    int dim;
    size_t n, cap, max_len;
    size_t *start;
    /* Per entry: the neighbour's row in xv, i.e. j itself for the image in the box and
     * n + g for ghost g, a periodic image of a particle (built by pack_list_build). */
    uint32_t *j;
    double *dwr; /* per entry: W'/r of the force's kernel at the current step */
    /* Per particle: the least and greatest particle (a ghost's source) among its neighbours, i
     * itself included, at the last build. */
    uint32_t *j_lo, *j_hi;
    double *x_ref[CONSPH_MAX_DIM];
    double radius, len[CONSPH_MAX_DIM];
    /* Ghosts: the periodic images x_j + image·len that the list refers to, one per distinct
     * (j, image); their rows in xv are refreshed from their source particle every step
     * (pack_list_fill_ghosts), so that a list entry is x_i - xv[row] with no image arithmetic. */
    size_t n_ghost, ghost_cap;
    uint32_t *ghost_src;
    int32_t *ghost_key; /* the image, one byte per axis (pack_image_key) */
    int32_t *ghost_head, *ghost_next;
    /* Positions (and the force's weights) of the particles then the ghosts, PACK_XV_STRIDE per
     * row, plus PACK_SLACK rows; aligned to 32 bytes. */
    double *xv;
    size_t xv_rows;
    /* The particles' rows of xv hold their positions (written by the packing's step since the
     * last build): pack_list_fill_positions refreshes only the ghosts'. */
    int rows_current;
    long builds;
    /* The build's per-thread buffers (pairlist.c), kept from build to build. */
    struct pack_list_part *parts;
    int nparts;
} pack_list;

int pack_list_init(pack_list *L, const consph_particles *p, double radius);
/* Lists the neighbours of every particle of p from `grid` (built on p, radius L->radius) and
 * records the positions. */
int pack_list_build(pack_list *L, const consph_nnps *grid, const consph_particles *p);
void pack_list_free(pack_list *L);
/* The coordinates of every particle of p (unless rows_current) and ghost into xv (slots
 * 0..dim-1): x_src + image·len for a ghost, the same expression as the image arithmetic it
 * replaces, so the same values. */
void pack_list_fill_positions(pack_list *L, const consph_particles *p);
/* pack_list_fill_positions' work on the rows r0..r1 only. */
void pack_list_fill_range(pack_list *L, const consph_particles *p, size_t r0, size_t r1);
/* Copies each ghost's weight (slot PACK_XV_WEIGHT) from its source particle. */
void pack_list_fill_ghost_weights(pack_list *L);

#endif
