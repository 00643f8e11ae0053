/* The kit's volumes, pass 1 and Laplacians (src/schemes/negi/kit.c) chained in one wavefront over
 * the neighbour list's pair cache (src/pass/nlist.c, nlist_chain_run), the volumes over groups of
 * particles (one per vector lane) from the blocks the list has just filled (unpadded lanes) or
 * from the group traversal's own gather (padded lanes, src/pass/group.c, a system without a
 * list): every field after every step equals, bit for bit, the passes run one after the other
 * with per-particle visits (kit_chain_passes = kit_group_visits = 0). 001's schemes that use them
 * (L-IPST-C with IPST, L-PST-C, PE-IPST-C's ∇²p, TV-C's ∇q and PST, E-C's fixed volumes, EWCSPH's
 * Cleary and L-IPST-F's Fatehi_c Laplacians), 2D and 3D, from a random layout (uneven neighbour
 * counts: lanes of different lengths, groups of fewer than four), skin 0 and 0.2, 1 and 2
 * threads (the wavefront's share of blocks per thread), and nx 100 (more blocks than a
 * neighbourhood spans, so that the later passes trail the fill inside the sweep). */
#include <string.h>

#include "check.h"
#include "same_state.h"
#include "consph/solver.h"
#include "pass/nlist.h"
#include "solver/solver_internal.h"

/* src/schemes/negi/kit.c */
extern int kit_group_visits, kit_chain_passes, kit_keep_bonet;
extern unsigned long kit_group_passes, kit_chains, kit_group_firsts, kit_group_coupled,
    kit_coupled_packed, kit_first_packed, kit_first_kept;
extern double kit_coupled_lanes_bytes;

static consph_solver *make(const char *scheme, const char *problem, int nx, double skin)
{
    consph_run_params p;
    consph_run_params_default(&p);
    CHECK(consph_run_params_problem(&p, problem) == CONSPH_OK, "problem %s", problem);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = nx;
    p.layout = CONSPH_LAYOUT_RANDOM;
    p.steps = 100;
    p.skin = skin;
    p.ipst_every = 2;
    consph_solver *s = NULL;
    int st = consph_solver_create(&s, &p);
    CHECK(st == CONSPH_OK, "create %s on %s: %s", scheme, problem, consph_last_error());
    return s;
}

/* no_list: the group solver runs without a neighbour list, so its group passes gather (padded
 * lanes) while the per-particle solver reads its list's cache. */
static void compare(const char *scheme, const char *problem, int nx, double skin, int no_list,
                    int threads)
{
    const int fixed = !strcmp(scheme, "e-c") || !strcmp(scheme, "ewcsph");
    char what[160];
    snprintf(what, sizeof what, "%s on %s, nx %d, skin %g, %s, %d thread(s)", scheme, problem, nx,
             skin, no_list ? "no list" : "list", threads);
    check_set_threads(threads);
    consph_solver *g = make(scheme, problem, nx, skin), *v = make(scheme, problem, nx, skin);
    if (!g || !v) {
        consph_solver_free(g);
        consph_solver_free(v);
        return;
    }
    if (no_list) CHECK(consph_sys_nlist(&g->sys, -1.0, NULL, 0) == CONSPH_OK, "%s: list off", what);
    /* small systems run their passes on one thread unless told otherwise */
    if (threads > 1) g->sys.parallel_min = v->sys.parallel_min = 1;
    size_t pairs_g = 0, pairs_v = 0;
    const unsigned long runs = kit_group_passes, chains = kit_chains;
    for (int step = 0; step < (nx > 50 ? 2 : 5); ++step) {
        int st = consph_solver_step(g);
        kit_group_visits = kit_chain_passes = kit_keep_bonet = 0;
        st = st ? st : consph_solver_step(v);
        kit_group_visits = kit_chain_passes = kit_keep_bonet = 1;
        CHECK(st == CONSPH_OK, "%s: step %d: %s", what, step, consph_last_error());
        if (st != CONSPH_OK || !same_state(g, v, what)) break;
        pairs_g = g->pairs;
        pairs_v = v->pairs;
    }
    CHECK(pairs_g == pairs_v && pairs_g > 0, "%s: pairs %zu against %zu", what, pairs_g, pairs_v);
    /* the comparison compared something: a chain per stage of rk2 with the list (where the
     * volumes are not fixed), the volumes over groups per stage without */
    if (!no_list && !fixed)
        CHECK(kit_chains - chains >= (nx > 50 ? 4u : 10u), "%s: %lu chains", what,
              kit_chains - chains);
#if defined(__GNUC__)
    if (no_list && !fixed)
        CHECK(kit_group_passes - runs >= 10, "%s: %lu group passes", what, kit_group_passes - runs);
#endif
    (void)runs;
    consph_solver_free(g);
    consph_solver_free(v);
}

/* u and p times f (exact for f a power of two) */
static void scale_up(consph_solver *s, double f)
{
    const char *names[2] = {SF_U, SF_P};
    consph_particles *p = s->sys.p;
    for (int k = 0; k < 2; ++k) {
        const consph_field *fl = consph_particles_find(p, names[k]);
        if (!fl) continue;
        for (int c = 0; c < fl->ncomp; ++c)
            for (size_t i = 0; i < p->n; ++i) fl->data[(size_t)c * p->cap + i] *= f;
    }
}

/* The kit's passes called directly, every combination of derivatives (∇p, G, ∇·u, ∇q, ∇²u
 * coupled or Fatehi_c, ∇²q), over groups on g and per particle (neither chained nor grouped) on v,
 * from the same state: every field bit for bit. mode 0: volumes and derivatives chained on a
 * fresh pair cache (pass 1 and coupled_bc over groups of unpadded lanes); 1: the derivatives
 * with the volumes fixed, pass 1 over groups while it fills the cache; 2: g without a list, both
 * passes over the group traversal's padded lanes; 3: as 0 after a first run on the same
 * positions with u and p doubled, so that the second chains over the cache the first filled and
 * any value it read before its pass wrote it would be the first run's; 4: as 0 with coupled_bc
 * per particle from pass 1's pack (coupled_pk_210 and coupled_pk_211, in 3D coupled_pk_31, where
 * the state's pairs outgrow the caches at run time). Random layouts (uneven neighbour counts: lanes
 * that run out at different entries) with n not a multiple of four (groups of fewer lanes). */
static void compare_kit(const char *problem, int nx, int mode)
{
    char what[200];
    check_set_threads(1);
    consph_solver *g = make("l-ipst-c", problem, nx, 0.0), *v = make("l-ipst-c", problem, nx, 0.0);
    if (!g || !v) {
        consph_solver_free(g);
        consph_solver_free(v);
        return;
    }
    if (mode == 2) CHECK(consph_sys_nlist(&g->sys, -1.0, NULL, 0) == CONSPH_OK, "list off");
    const double bytes = kit_coupled_lanes_bytes;
    /* coupled_bc over groups at any size, or (mode 4) at none */
    kit_coupled_lanes_bytes = mode == 4 ? 0.0 : 1e300;
    const unsigned long firsts = kit_group_firsts, coupled = kit_group_coupled;
    const unsigned long packed = kit_coupled_packed;
    const unsigned long filled = nlist_chain_filled, recycled = nlist_chain_recycled;
    size_t pairs = 0;
    int passes = 0;
    if (mode == 1) {
        /* the volumes, so that the derivatives can run without them */
        CHECK(kit_volumes(&g->sys, &pairs) == CONSPH_OK && kit_volumes(&v->sys, &pairs) == 0,
              "volumes");
    }
    for (unsigned want = 1; want < 64; ++want)
        for (int lap = 0; lap < ((want & KIT_LAPU) ? 2 : 1); ++lap) {
            const kit_req rq = {want, lap ? KIT_LAP_FATEHI_C : KIT_LAP_COUPLED, SF_P, 1e12, 0};
            snprintf(what, sizeof what, "kit on %s, nx %d, mode %d, want %#x, %s", problem, nx,
                     mode, want, lap ? "fatehi_c" : "coupled");
            int st = CONSPH_OK;
            for (int side = 0; side < 2 && st == CONSPH_OK; ++side) {
                consph_solver *s = side ? v : g;
                kit_group_visits = kit_chain_passes = !side;
                /* a fresh pair cache on the same positions, which the passes will be served */
                st = consph_sys_update(&s->sys, 0);
                /* mode 3: the two chains' passes (the first then keeps its pairs for the
                 * second); else the chain's own, whose pairs it recycles where it has three */
                consph_sys_expect_passes(&s->sys, mode == 3 && !side ? 6 : 3,
                                         CONSPH_PASS_W | CONSPH_PASS_DW);
                if (st == CONSPH_OK && mode == 3 && !side) {
                    scale_up(s, 2.0);
                    st = kit_volumes_derivatives(&s->sys, &rq, &pairs, &passes);
                    scale_up(s, 0.5);
                }
                if (st == CONSPH_OK)
                    st = mode == 1 ? kit_derivatives(&s->sys, &rq, &pairs, &passes)
                                   : kit_volumes_derivatives(&s->sys, &rq, &pairs, &passes);
            }
            kit_group_visits = kit_chain_passes = 1;
            CHECK(st == CONSPH_OK, "%s: %s", what, consph_last_error());
            if (st != CONSPH_OK || !same_state(g, v, what)) break;
        }
    kit_coupled_lanes_bytes = bytes;
#if defined(__GNUC__)
    /* pass 1 over groups in every call (95); coupled_bc wherever it is the only Laplacian (∇²u
     * coupled: 32 combinations, ∇²q alone: 16), except after a pass 1 that filled the cache */
    CHECK(kit_group_firsts - firsts == (mode == 3 ? 190u : 95u),
          "%s mode %d: %lu passes 1 over groups", problem, mode, kit_group_firsts - firsts);
    CHECK(kit_group_coupled - coupled == (mode == 1 || mode == 4 ? 0u
                                          : mode == 3            ? 96u
                                                                 : 48u),
          "%s mode %d: %lu coupled_bc passes over groups", problem, mode,
          kit_group_coupled - coupled);
    /* mode 4: every ∇²u coupled (32 combinations) from the pack (3D: by columns, coupled_pk_31) */
    CHECK(kit_coupled_packed - packed == (mode == 4 ? 32u : 0u),
          "%s mode %d: %lu coupled_bc passes from the pack", problem, mode,
          kit_coupled_packed - packed);
#endif
    CHECK(nlist_chain_filled - filled == (mode == 3 ? 95u : 0u),
          "%s mode %d: %lu chains over a filled cache", problem, mode, nlist_chain_filled - filled);
    /* modes 0 and 4: the 80 chains with a Laplacian (three passes, as announced) */
    CHECK(nlist_chain_recycled - recycled == (mode == 0 || mode == 4 ? 80u : 0u),
          "%s mode %d: %lu chains recycled their pairs", problem, mode,
          nlist_chain_recycled - recycled);
    (void)firsts;
    (void)coupled;
    (void)packed;
    consph_solver_free(g);
    consph_solver_free(v);
}

int main(void)
{
    for (int mode = 0; mode < 5; ++mode) {
        compare_kit("taylor-green", 13, mode);
        compare_kit("beltrami", 5, mode);
    }
    /* IPST every 2 steps: the stage after a shift, and IPST's first volumes and shift, chain
     * over the cache that IPST, or the gradients before it, filled */
    const unsigned long filled = nlist_chain_filled;
    compare("l-ipst-c", "taylor-green", 14, 0.0, 0, 1);
    CHECK(nlist_chain_filled - filled >= 2, "nx 14: %lu chains over a filled cache",
          nlist_chain_filled - filled);
    compare("l-ipst-c", "taylor-green", 40, 0.0, 0, 1);
    /* 156 blocks, a neighbourhood spanning about 12: the later passes trail the fill */
    const unsigned long trailing = nlist_chain_trailing;
    compare("l-ipst-c", "taylor-green", 100, 0.0, 0, 1);
    CHECK(nlist_chain_trailing - trailing > 500, "nx 100: %lu blocks visited in the sweep",
          nlist_chain_trailing - trailing);
    compare("l-ipst-c", "taylor-green", 100, 0.0, 0, 2);
    compare("l-ipst-c", "taylor-green", 14, 0.0, 1, 2);
    compare("l-ipst-c", "taylor-green", 14, 0.2, 0, 2);
    compare("l-ipst-c", "beltrami", 6, 0.0, 0, 1);
    compare("l-ipst-c", "beltrami", 6, 0.0, 1, 1);
    compare("l-pst-c", "taylor-green", 12, 0.0, 0, 1);
    compare("pe-ipst-c", "taylor-green", 12, 0.0, 0, 2);
    compare("pe-ipst-c", "beltrami", 5, 0.0, 1, 1);
    compare("tv-c", "taylor-green", 12, 0.0, 0, 1);
    /* the fixed volumes' pass 1 over the filled cache per particle from its pack (first_pk_of),
     * E-C's with ∇q, EWCSPH's without, after the first with B_i kept (kit_req.bonet_kept):
     * against the per-particle visits, which compute B_i at every pass */
    const unsigned long first_packed = kit_first_packed, first_kept = kit_first_kept;
    compare("e-c", "taylor-green", 12, 0.0, 0, 1);
    compare("ewcsph", "taylor-green", 12, 0.0, 0, 1);
#if defined(__GNUC__)
    CHECK(kit_first_packed - first_packed >= 16, "%lu passes 1 from the pack",
          kit_first_packed - first_packed);
    CHECK(kit_first_kept - first_kept >= 16, "%lu passes 1 with B_i kept",
          kit_first_kept - first_kept);
#endif
    (void)first_packed;
    /* 3D: per particle from the pack (first_pk_kept_3110/3111) */
    const unsigned long kept2 = kit_first_kept;
    compare("e-c", "beltrami", 5, 0.0, 0, 1);
    compare("ewcsph", "beltrami", 5, 0.0, 0, 2);
    CHECK(kit_first_kept - kept2 >= 16, "3D: %lu passes 1 with B_i kept", kit_first_kept - kept2);
    (void)first_kept;
    compare("ewcsph", "taylor-green", 12, 0.0, 1, 1);
    compare("l-ipst-f", "taylor-green", 12, 0.0, 0, 1);
    return check_summary("test_kit_group");
}
