/* Passes over groups of particles (group.h): the traversal of consph_pass_run_counted (pass.c),
 * handing the neighbourhoods of up to PASS_GROUP consecutive particles of a cell to one visit.
 *
 * A visit that sums one particle's neighbours in their order has one chain of dependent
 * additions per sum; a group visit runs the chains of several particles side by side in the
 * lanes of a vector, each lane adding its own particle's terms in that particle's neighbour
 * order, so the sums are those of the per-particle visit bit for bit. Each neighbourhood is
 * gathered and its kernel values evaluated exactly as pass.c does, into one scratch per lane. */
#include "pass/group.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pass/nlist.h"

/* as pass.c's PASS_CELLS_PER_CHUNK */
#define GROUP_CELLS_PER_CHUNK 16

typedef struct lane_scratch {
    size_t cap;
    size_t *slot, *j;
    double *dx[CONSPH_MAX_DIM];
    double *r, *w, *dwr, *d2w;
} lane_scratch;

static void lane_free(lane_scratch *sc)
{
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

static int lane_reserve(lane_scratch *sc, size_t need)
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

/* The neighbourhood of the particle in slot sl: pass.c's loop body, into lane scratch sc. */
static void lane_gather(const consph_sys *s, const consph_nnps_slots *v,
                        const consph_nnps_runs *runs, size_t sl, unsigned need, int with_dx,
                        lane_scratch *sc, consph_nbhd *nb)
{
    const int dim = v->dim;
    double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
    for (int a = 0; a < dim; ++a) xi[a] = v->x[a][sl];
    const size_t m = consph_nnps_gather(v, runs, xi, sc->slot, with_dx ? sc->dx : NULL, sc->r);
    const size_t *j = sc->slot;
    if (v->particle) {
        for (size_t p = 0; p < m; ++p) sc->j[p] = v->particle[sc->slot[p]];
        j = sc->j;
    }
    const size_t m4 = (m + 3) & ~(size_t)3;
    for (size_t p = m; p < m4; ++p) sc->r[p] = 0.0;
    consph_kernel_eval_batch(&s->kernel, m4, sc->r, need & CONSPH_PASS_W ? sc->w : NULL,
                             need & (CONSPH_PASS_DW | CONSPH_PASS_D2W) ? sc->dwr : NULL,
                             need & CONSPH_PASS_D2W ? sc->d2w : NULL);
    nb->i = consph_nnps_slot_particle(v, sl);
    nb->n = m;
    nb->j = j;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) nb->dx[a] = with_dx && a < dim ? sc->dx[a] : NULL;
    nb->r = sc->r;
    nb->w = need & CONSPH_PASS_W ? sc->w : NULL;
    nb->dwr = need & (CONSPH_PASS_DW | CONSPH_PASS_D2W) ? sc->dwr : NULL;
    nb->d2w = need & CONSPH_PASS_D2W ? sc->d2w : NULL;
}

/* Entries n..kmax of a lane: the particle itself with zero separation and kernel values. */
static void lane_pad(lane_scratch *sc, const consph_nbhd *nb, size_t kmax)
{
    size_t *j = (size_t *)nb->j;
    for (size_t p = nb->n; p < kmax; ++p) {
        j[p] = nb->i;
        for (int a = 0; a < CONSPH_MAX_DIM; ++a)
            if (nb->dx[a]) sc->dx[a][p] = 0.0;
        sc->r[p] = sc->w[p] = sc->dwr[p] = sc->d2w[p] = 0.0;
    }
}

unsigned long pass_group_runs = 0;

int pass_run_groups(const consph_sys *s, const char *name, unsigned need, pass_group_fn visit,
                    void *job, size_t *pairs)
{
    /* a decomposed system refreshes its halo in consph_pass_run_counted: that path serves it */
    if (!s || !s->p || !s->nnps || !visit || s->dest || s->kernel.tensor || s->split)
        return PASS_GROUP_UNSERVED;
    const size_t n = s->p->n;
    if (n == 0) return CONSPH_OK;
    consph_nnps_slots v;
    if (consph_nnps_slots_get(s->nnps, &v) != CONSPH_OK || v.n != n) return PASS_GROUP_UNSERVED;
    /* a list that serves this pass from its cache or its own filter: the per-particle pass */
    if (s->nlist && nlist_serves(s->nlist, n) && !nlist_gathers(s->nlist))
        return PASS_GROUP_UNSERVED;
    const int with_dx = !(need & CONSPH_PASS_NO_DX);
    ++pass_group_runs;
    int status = CONSPH_OK;
    char why[256] = "";
    size_t total = 0;
#pragma omp parallel if (n >= s->parallel_min)
    {
        consph_nnps_runs runs;
        memset(&runs, 0, sizeof runs);
        lane_scratch sc[PASS_GROUP];
        memset(sc, 0, sizeof sc);
        int my_status = CONSPH_OK;
        char my_why[256] = "";
        size_t my_pairs = 0;
#pragma omp for schedule(dynamic, GROUP_CELLS_PER_CHUNK)
        for (size_t c = 0; c < v.ncells; ++c) {
            const size_t first = v.cell_start[c], last = v.cell_start[c + 1];
            if (first == last || my_status != CONSPH_OK) continue;
            if (consph_nnps_cell_runs(s->nnps, c, &runs) == (size_t)-1) {
                my_status = CONSPH_ENOMEM;
                snprintf(my_why, sizeof my_why, "runs of cell %zu: %s", c, consph_last_error());
                continue;
            }
            for (int l = 0; l < PASS_GROUP && my_status == CONSPH_OK; ++l)
                if (lane_reserve(&sc[l], runs.candidates + CONSPH_NNPS_GATHER_SLACK) != CONSPH_OK) {
                    my_status = CONSPH_ENOMEM;
                    snprintf(my_why, sizeof my_why, "out of memory for %zu candidate neighbours",
                             runs.candidates);
                }
            if (my_status != CONSPH_OK) continue;
            for (size_t g = first; g < last; g += PASS_GROUP) {
                consph_nbhd nb[PASS_GROUP];
                const int count = last - g < PASS_GROUP ? (int)(last - g) : PASS_GROUP;
                size_t kmax = 0;
                for (int l = 0; l < count; ++l) {
                    lane_gather(s, &v, &runs, g + (size_t)l, need, with_dx, &sc[l], &nb[l]);
                    my_pairs += nb[l].n;
                    if (nb[l].n > kmax) kmax = nb[l].n;
                }
                for (int l = 0; l < count; ++l) lane_pad(&sc[l], &nb[l], kmax);
                for (int l = count; l < PASS_GROUP; ++l) nb[l] = nb[0];
                visit(job, nb, count);
            }
        }
#pragma omp critical(consph_pass_run_groups)
        {
            total += my_pairs;
            if (my_status != CONSPH_OK && (status == CONSPH_OK || my_status < status)) {
                status = my_status;
                memcpy(why, my_why, sizeof why);
            }
        }
        consph_nnps_runs_free(&runs);
        for (int l = 0; l < PASS_GROUP; ++l) lane_free(&sc[l]);
    }
    if (pairs) *pairs += total;
    if (status != CONSPH_OK)
        return consph_fail(status, "pass '%s': %s", name ? name : "unnamed", why);
    return CONSPH_OK;
}
