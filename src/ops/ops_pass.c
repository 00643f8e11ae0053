/* The particle pass driver: every particle's neighbourhood with its kernel values, handed to a
 * visitor.
 *
 * The pass walks the search's cells rather than querying particle by particle: the runs of
 * candidate slots are found once per cell (consph_nnps_cell_runs) and shared by its particles,
 * the hits come from the search's own test (consph_nnps_gather), and the kernel values come from
 * one vectorised batch per particle (consph_kernel_eval_batch). Each particle's neighbours are
 * those of consph_nnps_query_particle, in the same order and with the same separations and kernel
 * values bit for bit, so a visitor sums exactly what it summed over a query. Particles are
 * independent and written only by their own visit, so results do not depend on how the cells
 * are shared out among threads. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ops/ops_internal.h"

/* Cells per dynamic chunk: at the default cells per radius a 2D cell holds ~13 particles at
 * h = 1.2Δs with the quintic kernel, a 3D one ~6. */
#define OPS_CELLS_PER_CHUNK 16

typedef struct pass_scratch {
    consph_nnps_runs runs;
    size_t cap;
    size_t *slot, *j;
    double *dx[CONSPH_MAX_DIM];
    double *r, *w, *dwr, *d2w;
} pass_scratch;

static void scratch_free(pass_scratch *sc)
{
    consph_nnps_runs_free(&sc->runs);
    free(sc->slot);
    free(sc->j);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(sc->dx[a]);
    free(sc->r);
    free(sc->w);
    free(sc->dwr);
    free(sc->d2w);
    memset(sc, 0, sizeof *sc);
}

static int grow(void **p, size_t count, size_t size)
{
    void *q = realloc(*p, count * size);
    if (!q) return CONSPH_ENOMEM;
    *p = q;
    return CONSPH_OK;
}

static int scratch_reserve(pass_scratch *sc, size_t need)
{
    if (need <= sc->cap) return CONSPH_OK;
    size_t cap = sc->cap ? sc->cap : 256;
    while (cap < need) cap *= 2;
    int st = grow((void **)&sc->slot, cap, sizeof(size_t));
    st = st ? st : grow((void **)&sc->j, cap, sizeof(size_t));
    for (int a = 0; a < CONSPH_MAX_DIM; ++a)
        st = st ? st : grow((void **)&sc->dx[a], cap, sizeof(double));
    st = st ? st : grow((void **)&sc->r, cap, sizeof(double));
    st = st ? st : grow((void **)&sc->w, cap, sizeof(double));
    st = st ? st : grow((void **)&sc->dwr, cap, sizeof(double));
    st = st ? st : grow((void **)&sc->d2w, cap, sizeof(double));
    if (st == CONSPH_OK) sc->cap = cap;
    return st;
}

int ops_run(const consph_op_ctx *ctx, unsigned need, ops_visit_fn visit, void *job, size_t *pairs)
{
    const size_t n = ctx->n;
    consph_nnps_slots v;
    if (n == 0) return CONSPH_OK;
    if (consph_nnps_slots_get(ctx->nnps, &v) != CONSPH_OK)
        return consph_fail(CONSPH_EINVAL, "operator pass: %s", consph_last_error());
    if (v.n != n)
        return consph_fail(CONSPH_EINVAL,
                           "operator pass: the neighbour search holds %zu particles, the "
                           "context %zu; rebuild the search and refresh the context",
                           v.n, n);
    const int dim = v.dim, with_dx = !(need & OPS_SKIP_DX);
    const consph_kernel *kernel = &ctx->kernel;
    int status = CONSPH_OK;
    size_t total = 0;
    /* consph_fail records per thread: a worker's message is copied out here. */
    char why[256] = "";
#pragma omp parallel if (n >= ctx->parallel_min)
    {
        pass_scratch sc;
        memset(&sc, 0, sizeof sc);
        int my_status = CONSPH_OK;
        char my_why[256] = "";
        size_t my_pairs = 0;
#pragma omp for schedule(dynamic, OPS_CELLS_PER_CHUNK)
        for (size_t c = 0; c < v.ncells; ++c) {
            const size_t first = v.cell_start[c], last = v.cell_start[c + 1];
            if (first == last || my_status != CONSPH_OK) continue;
            if (consph_nnps_cell_runs(ctx->nnps, c, &sc.runs) == (size_t)-1) {
                my_status = CONSPH_ENOMEM;
                snprintf(my_why, sizeof my_why, "runs of cell %zu: %s", c, consph_last_error());
                continue;
            }
            if (scratch_reserve(&sc, sc.runs.candidates + CONSPH_NNPS_GATHER_SLACK) != CONSPH_OK) {
                my_status = CONSPH_ENOMEM;
                snprintf(my_why, sizeof my_why, "out of memory for %zu candidate neighbours",
                         sc.runs.candidates);
                continue;
            }
            for (size_t s = first; s < last; ++s) {
                double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
                for (int a = 0; a < dim; ++a) xi[a] = v.x[a][s];
                const size_t m =
                    consph_nnps_gather(&v, &sc.runs, xi, sc.slot, with_dx ? sc.dx : NULL, sc.r);
                const size_t *j = sc.slot;
                if (v.particle) {
                    for (size_t p = 0; p < m; ++p) sc.j[p] = v.particle[sc.slot[p]];
                    j = sc.j;
                }
                /* Whole vectors: the batch's scalar remainder loop would cost more than the
                 * few extra values (r = 0 is a valid distance; the extra values are unused). */
                const size_t m4 = (m + 3) & ~(size_t)3;
                for (size_t p = m; p < m4; ++p) sc.r[p] = 0.0;
                consph_kernel_eval_batch(kernel, m4, sc.r, need & OPS_NEED_W ? sc.w : NULL,
                                         need & (OPS_NEED_DW | OPS_NEED_D2W) ? sc.dwr : NULL,
                                         need & OPS_NEED_D2W ? sc.d2w : NULL);
                ops_nbhd nb;
                nb.i = consph_nnps_slot_particle(&v, s);
                nb.n = m;
                nb.j = j;
                for (int a = 0; a < CONSPH_MAX_DIM; ++a)
                    nb.dx[a] = with_dx && a < dim ? sc.dx[a] : NULL;
                nb.r = sc.r;
                /* Values the visitor did not ask for were not evaluated: hand out no pointer to
                 * them, so that reading one faults at once instead of summing stale scratch. */
                nb.w = need & OPS_NEED_W ? sc.w : NULL;
                nb.dwr = need & (OPS_NEED_DW | OPS_NEED_D2W) ? sc.dwr : NULL;
                nb.d2w = need & OPS_NEED_D2W ? sc.d2w : NULL;
                visit(job, &nb);
                my_pairs += m;
            }
        }
#pragma omp critical(consph_ops_run)
        {
            total += my_pairs;
            /* Several threads may fail; keep the lowest status so the message is reproducible. */
            if (my_status != CONSPH_OK && (status == CONSPH_OK || my_status < status)) {
                status = my_status;
                memcpy(why, my_why, sizeof why);
            }
        }
        scratch_free(&sc);
    }
    if (pairs) *pairs += total;
    if (status != CONSPH_OK) return consph_fail(status, "operator pass: %s", why);
    return CONSPH_OK;
}
