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
