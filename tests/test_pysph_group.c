/* wcsph, tvf and edac sum their neighbours over groups of particles, one particle per vector
 * lane (src/pass/group.c, the group visits of src/schemes/pysph/scheme.c): every field after
 * every step equals, bit for bit, the per-particle visits' (pysph_group_visits = 0), in 2D and
 * 3D, from a random layout (uneven neighbour counts, so lanes of different lengths and groups of
 * fewer than four), with and without the artificial viscosity and ∇u/∇p, on 1 and 2 threads;
 * tvf's and edac's two passes in one sweep (pass_run_groups2) likewise. */
#include <string.h>

#include "check.h"
#include "same_state.h"
#include "consph/solver.h"
#include "pass/group.h"
#include "solver/solver_internal.h"

extern int pysph_group_visits; /* src/schemes/pysph/scheme.c */

static consph_solver *make(const char *scheme, const char *problem, int nx, double alpha)
{
    consph_run_params p;
    consph_run_params_default(&p);
    CHECK(consph_run_params_problem(&p, problem) == CONSPH_OK, "problem %s", problem);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = nx;
    p.layout = CONSPH_LAYOUT_RANDOM;
    p.steps = 100;
    if (alpha >= 0.0) p.alpha = alpha;
    consph_solver *s = NULL;
    int st = consph_solver_create(&s, &p);
    CHECK(st == CONSPH_OK, "create %s on %s: %s", scheme, problem, consph_last_error());
    return s;
}

/* The solver of the group visits (*g) and the one of the per-particle visits (*v), both of the
 * same set-up on `threads` threads; 0 (both freed) where one could not be made. */
static int make_both(const char *scheme, const char *problem, int nx, double alpha, int threads,
                     consph_solver **g, consph_solver **v)
{
    check_set_threads(threads);
    *g = make(scheme, problem, nx, alpha);
    *v = make(scheme, problem, nx, alpha);
    if (*g && *v) {
        /* small systems run their passes on one thread unless told otherwise */
        (*g)->sys.parallel_min = (*v)->sys.parallel_min = threads > 1 ? 1 : (*g)->sys.parallel_min;
        return 1;
    }
    consph_solver_free(*g);
    consph_solver_free(*v);
    return 0;
}

static void compare(const char *scheme, const char *problem, int nx, double alpha, int lazy,
                    int threads)
{
    char what[160];
    snprintf(what, sizeof what, "%s on %s, nx %d, alpha %g, lazy grads %d, %d thread(s)", scheme,
             problem, nx, alpha, lazy, threads);
    consph_solver *g, *v;
    if (!make_both(scheme, problem, nx, alpha, threads, &g, &v)) return;
    /* lazy: ∇u and ∇p every third step only (grads_skip in the others) */
    g->grads_lazy = v->grads_lazy = lazy;
    g->grads_every = v->grads_every = 3;
    size_t pairs_g = 0, pairs_v = 0;
    const unsigned long runs = pass_group_runs;
    for (int step = 0; step < 6; ++step) {
        pysph_group_visits = 1;
        int st = consph_solver_step(g);
        pysph_group_visits = 0;
        st = st ? st : consph_solver_step(v);
        pysph_group_visits = 1;
        CHECK(st == CONSPH_OK, "%s: step %d: %s", what, step, consph_last_error());
        if (st != CONSPH_OK || !same_state(g, v, what)) break;
        pairs_g = g->pairs;
        pairs_v = v->pairs;
    }
    CHECK(pairs_g == pairs_v && pairs_g > 0, "%s: pairs %zu against %zu", what, pairs_g, pairs_v);
#if defined(__GNUC__)
    /* one group pass per step (wcsph), two (tvf, edac): the comparison compared something */
    CHECK(pass_group_runs - runs >= 6, "%s: %lu group passes", what, pass_group_runs - runs);
#else
    (void)runs;
#endif
    consph_solver_free(g);
    consph_solver_free(v);
}

/* The group passes read their neighbours by slot of the search (PASS_GROUP_SLOTS: wcsph's pass,
 * tvf's and edac's two in pass_run_groups2): the rates where the slots are not the particles
 * (positions shifted along x by a fraction of the period and the search rebuilt without the
 * re-sort, so that the particles wrapped across the boundary change places in the cell order)
 * equal the per-particle visits' bit for bit. */
static void compare_unsorted(const char *scheme, const char *problem, int nx, double alpha,
                             int threads)
{
    char what[160];
    snprintf(what, sizeof what, "%s unsorted on %s, nx %d, alpha %g, %d thread(s)", scheme, problem,
             nx, alpha, threads);
    consph_solver *g, *v;
    if (!make_both(scheme, problem, nx, alpha, threads, &g, &v)) return;
    pysph_group_visits = 0;
    int st = consph_solver_step(g);
    st = st ? st : consph_solver_step(v);
    pysph_group_visits = 1;
    CHECK(st == CONSPH_OK, "%s: step: %s", what, consph_last_error());
    consph_solver *both[2] = {g, v};
    for (int k = 0; k < 2 && st == CONSPH_OK; ++k) {
        consph_particles *p = both[k]->sys.p;
        const double lo = p->box.lo[0], len = p->box.hi[0] - p->box.lo[0];
        for (size_t i = 0; i < p->n; ++i) {
            double x = p->x[0][i] + 0.37 * len;
            p->x[0][i] = x >= lo + len ? x - len : x;
        }
        st = consph_sys_update(&both[k]->sys, 0);
    }
    consph_nnps_slots slots;
    CHECK(st == CONSPH_OK && consph_nnps_slots_get(g->sys.nnps, &slots) == CONSPH_OK &&
              slots.particle != NULL,
          "%s: the slots are the particles", what);
    const unsigned long runs = pass_group_runs;
    if (st == CONSPH_OK) st = g->scheme->rhs(g);
    pysph_group_visits = 0;
    if (st == CONSPH_OK) st = v->scheme->rhs(v);
    pysph_group_visits = 1;
    CHECK(st == CONSPH_OK, "%s: rates: %s", what, consph_last_error());
    CHECK(pass_group_runs > runs, "%s: no group pass", what);
    if (st == CONSPH_OK) same_state(g, v, what);
    consph_solver_free(g);
    consph_solver_free(v);
}

int main(void)
{
    compare_unsorted("wcsph", "taylor-green", 14, 0.0, 1);
    compare_unsorted("wcsph", "taylor-green", 14, 0.1, 2);
    compare_unsorted("wcsph", "beltrami", 6, 0.1, 1);
    /* tvf and edac: also grids whose sweep keeps neighbourhoods for the rates */
    for (int k = 0; k < 2; ++k) {
        const char *tv = k ? "edac" : "tvf";
        const unsigned long kept = pass_group_kept_slabs;
        compare_unsorted(tv, "taylor-green", 14, -1.0, 1);
        compare_unsorted(tv, "taylor-green", 40, -1.0, 1);
        compare_unsorted(tv, "taylor-green", 40, -1.0, 2);
        compare_unsorted(tv, "beltrami", 6, -1.0, 1);
        compare_unsorted(tv, "beltrami", 16, -1.0, 2);
        CHECK(pass_group_kept_slabs > kept, "%s unsorted: no slab kept its neighbourhoods", tv);
    }
    const char *schemes[] = {"wcsph", "tvf", "edac"};
    for (int k = 0; k < 3; ++k) {
        const int wc = k == 0;
        compare(schemes[k], "taylor-green", 14, wc ? 0.1 : -1.0, 0, 1);
        compare(schemes[k], "taylor-green", 14, wc ? 0.0 : -1.0, 1, 2);
        compare(schemes[k], "beltrami", 6, wc ? 0.1 : -1.0, 0, 1);
    }
    /* tvf and edac run their two passes in one sweep (pass_run_groups2): grids of enough slabs
     * that neighbourhoods are kept from the density pass for the rates, on each thread's band */
    for (int k = 1; k < 3; ++k) {
        const unsigned long kept = pass_group_kept_slabs;
        compare(schemes[k], "taylor-green", 40, -1.0, 0, 1);
        compare(schemes[k], "taylor-green", 40, -1.0, 1, 2);
        compare(schemes[k], "beltrami", 16, -1.0, 0, 2);
        /* strips of 4 cells (3 strips of an 11-cell axis): edge columns between the strips */
        const size_t strip_cells = pass_group2_strip_cells;
        pass_group2_strip_cells = 4;
        compare(schemes[k], "taylor-green", 40, -1.0, 0, 1);
        compare(schemes[k], "taylor-green", 40, -1.0, 0, 2);
        pass_group2_strip_cells = strip_cells;
        CHECK(pass_group_kept_slabs > kept, "%s: no slab kept its neighbourhoods", schemes[k]);
    }
    return check_summary("test_pysph_group");
}
