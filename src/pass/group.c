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

#include "pass/nbhd.h"
#include "pass/nlist.h"

/* as pass.c's PASS_CELLS_PER_CHUNK */
#define GROUP_CELLS_PER_CHUNK 16

/* Entries n..kmax of a lane: the particle itself with zero separation and kernel values. */
static void lane_pad(nbhd_scratch *sc, const consph_nbhd *nb, size_t kmax)
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
    if (s->nlist && nlist_serves(s->nlist, n)) {
        if (need & PASS_GROUP_UNPADDED) {
            int ran;
            const int st = nlist_group_run(s, name, need, visit, job, pairs, &ran);
            if (st != CONSPH_OK || ran > 0) {
                if (st == CONSPH_OK) ++pass_group_runs;
                return st;
            }
            if (ran < 0) return PASS_GROUP_UNSERVED;
        } else if (!nlist_gathers(s->nlist)) {
            /* a list that serves this pass from its cache or its own filter: the per-particle
             * pass */
            return PASS_GROUP_UNSERVED;
        }
    }
    need &= ~PASS_GROUP_UNPADDED;
    const int with_dx = !(need & CONSPH_PASS_NO_DX);
    ++pass_group_runs;
    int status = CONSPH_OK;
    char why[256] = "";
    size_t total = 0;
#pragma omp parallel if (n >= s->parallel_min)
    {
        consph_nnps_runs runs;
        memset(&runs, 0, sizeof runs);
        nbhd_scratch sc[PASS_GROUP];
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
                if (nbhd_scratch_reserve(&sc[l], runs.candidates + CONSPH_NNPS_GATHER_SLACK) !=
                    CONSPH_OK) {
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
                    nbhd_gather(s, &v, &runs, g + (size_t)l, need, with_dx, &sc[l], &nb[l]);
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
        for (int l = 0; l < PASS_GROUP; ++l) nbhd_scratch_free(&sc[l]);
    }
    if (pairs) *pairs += total;
    if (status != CONSPH_OK)
        return consph_fail(status, "pass '%s': %s", name ? name : "unnamed", why);
    return CONSPH_OK;
}
