/* One particle's neighbourhood as the pass layer hands it to a visit (consph_nbhd): the scratch
 * it lives in and the gather that fills it. consph_pass_run_counted (pass.c) and the group passes
 * (group.c) share it, so that both hand out the neighbours of consph_nnps_query_particle in the
 * same order, with the same separations and kernel values bit for bit. */
#ifndef CONSPH_PASS_NBHD_H
#define CONSPH_PASS_NBHD_H

#include <stddef.h>

#include "consph/pass.h"
#include "nnps/nnps_internal.h"

/* In a gather's `need`: hand out the neighbours' slots of the search (consph_nnps_slots) in
 * nb->j instead of their particles (nb->i stays the particle), which spares mapping each
 * neighbour's slot to its particle; group.h's PASS_GROUP_SLOTS. */
#define NBHD_SLOTS (1u << 17)

typedef struct nbhd_scratch {
    size_t cap;
    size_t *slot, *j;
    double *dx[CONSPH_MAX_DIM];
    double *r, *w, *dwr, *d2w;
} nbhd_scratch;

void nbhd_scratch_free(nbhd_scratch *sc);
/* Room for `need` neighbours (capacity doubles from 256); CONSPH_ENOMEM when it cannot grow. */
int nbhd_scratch_reserve(nbhd_scratch *sc, size_t need);

/* The rest of nbhd_gather once the gather has put the m neighbours of the particle in slot sl
 * into sc: their particles, the kernel values `need` asks for (a tensor-product kernel from the
 * separations, a radial one in one vectorised batch), and nb. */
static inline void nbhd_finish(const consph_sys *s, const consph_nnps_slots *v, size_t sl, size_t m,
                               unsigned need, int with_dx, nbhd_scratch *sc, consph_nbhd *nb)
{
    const int dim = v->dim;
    const consph_kernel *kernel = &s->kernel;
    const size_t *j = sc->slot;
    if (v->particle && !(need & NBHD_SLOTS)) {
        for (size_t p = 0; p < m; ++p) sc->j[p] = v->particle[sc->slot[p]];
        j = sc->j;
    }
    /* a tensor-product kernel is a function of the separation vector, not of r */
    if (kernel->tensor && (need & CONSPH_PASS_W)) {
        for (size_t p = 0; p < m; ++p) {
            double d[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
            for (int a = 0; a < dim; ++a) d[a] = sc->dx[a][p];
            sc->w[p] = consph_kernel_w_vec(kernel, d);
        }
    } else {
        /* Whole vectors: the batch's scalar remainder loop would cost more than the few extra
         * values (r = 0 is a valid distance; the extra values are unused). */
        const size_t m4 = (m + 3) & ~(size_t)3;
        for (size_t p = m; p < m4; ++p) sc->r[p] = 0.0;
        consph_kernel_eval_batch(kernel, m4, sc->r, need & CONSPH_PASS_W ? sc->w : NULL,
                                 need & (CONSPH_PASS_DW | CONSPH_PASS_D2W) ? sc->dwr : NULL,
                                 need & CONSPH_PASS_D2W ? sc->d2w : NULL);
    }
    nb->i = consph_nnps_slot_particle(v, sl);
    nb->n = m;
    nb->j = j;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) nb->dx[a] = with_dx && a < dim ? sc->dx[a] : NULL;
    nb->r = sc->r;
    /* Values the pass did not ask for were not evaluated: hand out no pointer to them, so that
     * reading one faults at once instead of summing stale scratch. */
    nb->w = need & CONSPH_PASS_W ? sc->w : NULL;
    nb->dwr = need & (CONSPH_PASS_DW | CONSPH_PASS_D2W) ? sc->dwr : NULL;
    nb->d2w = need & CONSPH_PASS_D2W ? sc->d2w : NULL;
}

/* The neighbourhood of the particle in slot sl among the candidate runs of its cell, with the
 * kernel values `need` asks for, into sc and nb. */
static inline void nbhd_gather(const consph_sys *s, const consph_nnps_slots *v,
                               const consph_nnps_runs *runs, size_t sl, unsigned need, int with_dx,
                               nbhd_scratch *sc, consph_nbhd *nb)
{
    double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
    for (int a = 0; a < v->dim; ++a) xi[a] = v->x[a][sl];
    const size_t m = consph_nnps_gather(v, runs, xi, sc->slot, with_dx ? sc->dx : NULL, sc->r);
    nbhd_finish(s, v, sl, m, need, with_dx, sc, nb);
}

/* nbhd_gather for the four particles in slots sl..sl+3 of the cell whose runs are `runs`, into
 * sc[0..4) and nb[0..4), with one sweep over the candidates (nnps_gather4); the same values in
 * the same order. Returns 0, having done nothing, where the gather has no such sweep. */
static inline int nbhd_gather4(const consph_sys *s, const consph_nnps_slots *v,
                               const consph_nnps_runs *runs, size_t sl, unsigned need, int with_dx,
                               nbhd_scratch *sc, consph_nbhd *nb)
{
    size_t *slot[4], m[4];
    double *const *dx[4];
    double *r[4];
    for (int l = 0; l < 4; ++l) {
        slot[l] = sc[l].slot;
        dx[l] = with_dx ? sc[l].dx : NULL;
        r[l] = sc[l].r;
    }
    if (!nnps_gather4(v, runs->run, runs->n, sl, slot, dx, r, m)) return 0;
    for (int l = 0; l < 4; ++l)
        nbhd_finish(s, v, sl + (size_t)l, m[l], need, with_dx, &sc[l], &nb[l]);
    return 1;
}

#endif
