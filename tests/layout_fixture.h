/* Shared test fixtures: particle layouts generated on one thread, and the operator "world". The
 * layout is input, not under test, and the packing's many short parallel regions crawl when the
 * machine is oversubscribed (as under parallel CTest). */
#ifndef CONSPH_TESTS_LAYOUT_FIXTURE_H
#define CONSPH_TESTS_LAYOUT_FIXTURE_H

#ifdef _OPENMP
#include <omp.h>
#endif
#include <string.h>

#include "consph/layout.h"
#include "consph/nnps.h"
#include "consph/ops.h"

static inline int generate_layout(const consph_layout_params *lp, consph_particles *p)
{
#ifdef _OPENMP
    int saved = omp_get_max_threads();
    omp_set_num_threads(1);
#endif
    int st = consph_layout_generate(lp, p, NULL);
#ifdef _OPENMP
    omp_set_num_threads(saved);
#endif
    return st;
}

/* Particles, a quintic kernel with h = hdx/nx, a sorted neighbour search and an operator context:
 * what the operator tests evaluate on. The random layout uses eps 0.4. */
typedef struct world {
    consph_particles p;
    consph_kernel k;
    consph_nnps *g;
    consph_op_ctx ctx;
} world;

/* The world on the particles of `lp` (any box and periodicity), h = hdx/nx[0]. */
static inline int world_setup_params(world *w, const consph_layout_params *lp, double hdx,
                                     consph_volume_kind vk)
{
    memset(w, 0, sizeof *w);
    if (generate_layout(lp, &w->p) != CONSPH_OK) return 0;
    if (consph_kernel_init(&w->k, CONSPH_KERNEL_QUINTIC, lp->dim, hdx / (double)lp->nx[0]) !=
        CONSPH_OK)
        return 0;
    w->g = consph_nnps_create(&w->p.box, w->k.radius, 0);
    if (!w->g || consph_nnps_sort(w->g, &w->p, NULL) != CONSPH_OK) return 0;
    return consph_op_ctx_init(&w->ctx, &w->p, w->g, &w->k, vk) == CONSPH_OK;
}

static inline int world_setup(world *w, consph_layout_kind kind, int dim, size_t nx, double hdx,
                              consph_volume_kind vk, uint64_t seed)
{
    consph_layout_params lp = consph_layout_defaults(kind, dim, nx);
    lp.eps = 0.4;
    lp.seed = seed;
    return world_setup_params(w, &lp, hdx, vk);
}

static inline void world_free(world *w)
{
    consph_op_ctx_free(&w->ctx);
    consph_nnps_free(w->g);
    consph_particles_free(&w->p);
}

#endif
