/* The solver decomposed over MPI ranks (src/par/par_solver.c) against the serial run, bit for
 * bit: the whole state (positions and every field of every particle, in the serial order) and
 * the history after a few steps of one scheme of each family in 2D (random layout, so that
 * particles change cells and ranks) and of 3D Beltrami; a run's files (snapshots, log, summary,
 * checkpoint) on 2 and 3 ranks equal the serial run's; a checkpoint restarts on 2 and 3 ranks
 * to the serial run's final files; a launch on more ranks than slabs is refused on every rank;
 * the cases are cut at the set-up (consph_par_solver_create), the files' runs after it; on 4
 * ranks, some cases and the restart with the boxes forced to 2 x 2 pieces across two axes;
 * the files are written on rank 0 from one array at a time, never the whole set (also in
 * messages of a few hundred bytes); the halo refresh sends only changed columns and leaves the halo
 * equal to its owners (the positions alone for refresh_positions; a declared component alone,
 * the skipped ones at the next full refresh); a packed layout read from the
 * layout cache by each rank's share (the whole set packed on every rank when the file is corrupt);
 * runs that sample every step (the samples gather only the fields they read) keep the serial
 * history; the kit's chained passes forced on every rank (their sweep's visits and those it left
 * for after the refresh) and tvf's and edac's one sweep of density and rates keep the serial
 * state.
 *
 * Run without mpirun, the test computes the serial references and launches itself under
 * `mpirun -np 2` and `-np 3` (--oversubscribe: this machine may have fewer cores); skips (77)
 * without MPI or mpirun. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "check.h"
#include "consph/io.h"
#include "consph/par.h"
#include "consph/solver.h"
#include "par/par_solver.h"
#include "pass/group.h"
#include "pass/nlist.h"
#include "solver/solver_internal.h"

/* the group visits that ran (src/pass/group.c, src/schemes/negi/kit.c) */
extern unsigned long kit_group_passes, kit_first_packed, kit_coupled_packed;

#ifdef CONSPH_HAVE_MPI
#include <mpi.h>

typedef struct par_case {
    const char *name, *problem, *scheme;
    int nx, layout;
    long steps;
    const char *extra; /* "key=value" or NULL */
} par_case;

/* Sizes with more slabs of cells along the last axis than one rank's own and its halo (reach
 * plus one cell each way) span, so that every rank holds only a part of the particles. */
static const par_case cases[] = {
    {"wcsph-2d", "taylor-green", "wcsph", 40, CONSPH_LAYOUT_RANDOM, 8, NULL},
    /* stages between re-sorts: the halo's values change between a step's passes (its rates
     * are its owners' of the last refresh), so a pack whose halo rows were filled before the
     * pass's refresh would show */
    {"wcsph-rk2", "taylor-green", "wcsph", 40, CONSPH_LAYOUT_RANDOM, 5, "integrator=rk2"},
    {"edac-2d", "taylor-green", "edac", 40, CONSPH_LAYOUT_RANDOM, 8, NULL},
    {"lipstc-2d", "taylor-green", "l-ipst-c", 40, CONSPH_LAYOUT_RANDOM, 8, "ipst_every=3"},
    {"deltaplus-2d", "taylor-green", "delta-plus-sph", 40, CONSPH_LAYOUT_RANDOM, 8, NULL},
    {"tvf-2d", "taylor-green", "tvf", 40, CONSPH_LAYOUT_RANDOM, 6, NULL},
    {"ec-2d", "taylor-green", "e-c", 40, CONSPH_LAYOUT_LATTICE, 4, NULL},
    {"quasi-2d", "taylor-green", "wcsph", 40, CONSPH_LAYOUT_QUASI_RANDOM, 3, NULL},
    {"lipstc-3d", "beltrami", "l-ipst-c", 20, CONSPH_LAYOUT_LATTICE, 3,
     "ipst_every=2 kernel=cubic"},
    {"wcsph-3d", "beltrami", "wcsph", 20, CONSPH_LAYOUT_LATTICE, 3, "kernel=cubic"},
    /* the authors' error measure samples after every step: every step gathers the whole set */
    {"authors", "taylor-green", "edac", 40, CONSPH_LAYOUT_RANDOM, 6, "error=authors"},
    /* --tf: the steps land on the authors' output times, which every rank must know (the
     * samples taken on every rank; with --exact wc gathered to rank 0, the others move on to
     * the next output time by themselves) */
    {"authors-tf", "taylor-green", "edac", 40, CONSPH_LAYOUT_RANDOM, 0,
     "error=authors tf=0.0006 error_times=5"},
    {"authors-tf-wc", "taylor-green", "edac", 40, CONSPH_LAYOUT_RANDOM, 0,
     "error=authors tf=0.0006 error_times=5 exact=wc"},
    /* a sample at every step gathers only what the diagnostics read (solver_sample_fields):
     * a scheme with a per-particle mass, and the wc reference's errors besides */
    {"sampled", "taylor-green", "delta-plus-sph", 40, CONSPH_LAYOUT_RANDOM, 5,
     "log_every=1 exact=both"},
    {"sampled-3d", "beltrami", "l-ipst-c", 20, CONSPH_LAYOUT_LATTICE, 2,
     "ipst_every=2 kernel=cubic log_every=1"},
    /* "chain-": the volumes, pass 1 and the Laplacians chained on every rank whatever its halo
     * (nlist_chain_split_halo raised): the sweep runs each pass where the one before is known at
     * every neighbour, the rest after the refresh (the visits it left would show in the bits;
     * tests/cli_mpi_reads.sh runs the chains with a poisoned halo, TV-C's and L-PST-C's shift
     * chained after them too) */
    {"chain-lipstc-2d", "taylor-green", "l-ipst-c", 40, CONSPH_LAYOUT_RANDOM, 6, "ipst_every=2"},
    {"chain-lipstc-3d", "beltrami", "l-ipst-c", 20, CONSPH_LAYOUT_LATTICE, 2, "kernel=cubic"},
    /* leaves the model's validity at step 12 (kinetic energy growth): the checks' verdict
     * over the ranks, then the serial message */
    {"diverges", "taylor-green", "wcsph", 40, CONSPH_LAYOUT_RANDOM, 30, "cfl=1.5"},
};
#define NCASES (sizeof cases / sizeof cases[0])

static consph_run_params case_params(const par_case *c)
{
    consph_run_params p;
    consph_run_params_default(&p);
    if (consph_run_params_problem(&p, c->problem) != CONSPH_OK) {
        fprintf(stderr, "%s\n", consph_last_error());
        exit(1);
    }
    snprintf(p.scheme, sizeof p.scheme, "%s", c->scheme);
    p.nx = c->nx;
    p.steps = c->steps;
    p.tf = 0.0;
    p.layout = c->layout;
    /* "key=value key=value" */
    for (const char *e = c->extra; e && *e;) {
        char key[64], val[64];
        const char *eq = strchr(e, '='), *end = strchr(e, ' ');
        if (!end) end = e + strlen(e);
        snprintf(key, sizeof key, "%.*s", (int)(eq - e), e);
        snprintf(val, sizeof val, "%.*s", (int)(end - eq - 1), eq + 1);
        if (consph_run_param_set(&p, key, val) != CONSPH_OK) {
            fprintf(stderr, "%s\n", consph_last_error());
            exit(1);
        }
        e = *end ? end + 1 : end;
    }
    return p;
}

/* The whole state to a file: n, then per field (positions first) its values in the particle
 * order, then the history. */
static int dump(consph_solver *s, void *path)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return consph_fail(CONSPH_EIO, "cannot write %s", (const char *)path);
    const consph_particles *p = s->sys.p;
    fwrite(&p->n, sizeof p->n, 1, fp);
    for (int a = 0; a < p->dim; ++a) fwrite(p->x[a], sizeof(double), p->n, fp);
    for (int f = 0; f < p->nfields; ++f) {
        fwrite(p->fields[f].name, 1, sizeof p->fields[f].name, fp);
        for (int c = 0; c < p->fields[f].ncomp; ++c)
            fwrite(p->fields[f].data + (size_t)c * p->cap, sizeof(double), p->n, fp);
    }
    fwrite(s->hist, sizeof(double), s->nhist * HIST_COLS, fp);
    fwrite(&s->pairs, sizeof s->pairs, 1, fp);
    const double acc[] = {s->l1_u_acc,   s->l1_p_acc,       s->auth_u_acc,
                          s->auth_p_acc, (double)s->auth_n, s->prm.ipst_chi0};
    fwrite(acc, sizeof acc, 1, fp);
    fclose(fp);
    return CONSPH_OK;
}

/* Values of very different magnitudes, so that the order of a sum shows in its bits. */
static double sum_value(double id)
{
    return sin(id) * pow(10.0, fmod(id * 7.0, 13.0) - 6.0);
}

/* Three columns for the sums over the ranks (of different values, so that a column taken for
 * another shows), and the maxima of two. */
enum { SUM_COLS = 3, MAX_COLS = 2 };

static double col_value(double id, int k)
{
    return k == 0 ? sum_value(id) : k == 1 ? -sum_value(id + 0.5) : 1.0 / (1.0 + id);
}

static double whole_sum[SUM_COLS], whole_max[MAX_COLS];
static int order_shows; /* the sums of column 0 in order and reversed differ */

static int sum_whole(consph_solver *s, void *unused)
{
    (void)unused;
    const consph_particles *p = s->sys.p;
    const double *id = consph_particles_find(p, SF_ID)->data;
    double *w = malloc((p->n ? p->n : 1) * sizeof(double));
    for (int k = 0; k < SUM_COLS; ++k) {
        for (size_t i = 0; i < p->n; ++i) w[i] = col_value(id[i], k);
        whole_sum[k] = consph_sum(w, p->n);
        if (k == 0) {
            double fwd = 0.0, back = 0.0;
            for (size_t i = 0; i < p->n; ++i) fwd += w[i];
            for (size_t i = p->n; i-- > 0;) back += w[i];
            order_shows = fwd != back;
        }
    }
    whole_max[0] = whole_max[1] = 0.0;
    for (size_t i = 0; i < p->n; ++i) {
        whole_max[0] = fmax(whole_max[0], fabs(sum_value(id[i])));
        whole_max[1] = fmax(whole_max[1], id[i]);
    }
    free(w);
    return CONSPH_OK;
}

/* par_owned_sums (the diagnostics' sums and the checks' kinetic energy) against consph_sum over
 * the gathered serial order, bit for bit on every rank, for values whose sum depends on the
 * order (checked: in order and reversed differ); par_owned_max against the maxima over the
 * gathered set. */
static int check_owned_sum(consph_solver *s, const char *name)
{
    const consph_particles *p = s->sys.p;
    const double *id = consph_particles_find(p, SF_ID)->data;
    size_t m = 0, N = 0;
    const size_t *own = par_owned(s, &m, &N);
    double *w = malloc((m ? m : 1) * SUM_COLS * sizeof(double));
    double mx[MAX_COLS] = {0.0, 0.0};
    for (size_t o = 0; o < m; ++o) {
        const double q = id[own[o]];
        for (int k = 0; k < SUM_COLS; ++k) w[(size_t)k * m + o] = col_value(q, k);
        mx[0] = fmax(mx[0], fabs(sum_value(q)));
        mx[1] = fmax(mx[1], q);
    }
    double v[SUM_COLS];
    int st = par_owned_sums(s, w, SUM_COLS, v);
    free(w);
    if (st == CONSPH_OK) st = par_owned_max(s, mx, MAX_COLS);
    if (st == CONSPH_OK) st = solver_global(s, sum_whole, NULL);
    double ref[SUM_COLS + MAX_COLS + 1];
    memcpy(ref, whole_sum, sizeof whole_sum);
    memcpy(ref + SUM_COLS, whole_max, sizeof whole_max);
    ref[SUM_COLS + MAX_COLS] = order_shows;
    MPI_Bcast(ref, SUM_COLS + MAX_COLS + 1, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    int rank = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    if (st == CONSPH_OK && ref[SUM_COLS + MAX_COLS] == 0.0) {
        fprintf(stderr, "case %s: the test's sums do not depend on the order\n", name);
        st = CONSPH_EINVAL;
    }
    for (int k = 0; st == CONSPH_OK && k < SUM_COLS; ++k)
        if (memcmp(&v[k], &ref[k], sizeof v[k])) {
            fprintf(stderr,
                    "case %s, rank %d: column %d's sum over ranks %.17g, over the serial order "
                    "%.17g\n",
                    name, rank, k, v[k], ref[k]);
            st = CONSPH_EINVAL;
        }
    for (int k = 0; st == CONSPH_OK && k < MAX_COLS; ++k)
        if (memcmp(&mx[k], &ref[SUM_COLS + k], sizeof mx[k])) {
            fprintf(stderr, "case %s, rank %d: maximum %d over ranks %.17g, over the set %.17g\n",
                    name, rank, k, mx[k], ref[SUM_COLS + k]);
            st = CONSPH_EINVAL;
        }
    /* every rank takes the worst verdict: a rank that stopped alone would leave the others
     * waiting in the next collective */
    int bad = st != CONSPH_OK, any = 0;
    MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    return any ? CONSPH_EINVAL : CONSPH_OK;
}

/* Samples taken on every rank (solver_sample_owned) leave every rank rank 0's history and
 * sums, bit for bit (the steps read them there: the authors' output times, the checks' first
 * row). */
static int check_same_history(consph_solver *s, const char *name)
{
    if (!solver_sample_owned(s)) return CONSPH_OK;
    double mine[7] = {(double)s->nhist, s->l1_u_acc,       s->l1_p_acc,         s->auth_u_acc,
                      s->auth_p_acc,    (double)s->auth_n, (double)s->auth_next};
    double ref[7];
    memcpy(ref, mine, sizeof ref);
    MPI_Bcast(ref, 7, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    int bad = memcmp(mine, ref, sizeof ref) != 0, any = 0;
    MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (!any) { /* the same count of rows everywhere */
        double *h = malloc((s->nhist ? s->nhist : 1) * HIST_COLS * sizeof(double));
        memcpy(h, s->hist, s->nhist * HIST_COLS * sizeof(double));
        MPI_Bcast(h, (int)(s->nhist * HIST_COLS), MPI_DOUBLE, 0, MPI_COMM_WORLD);
        bad = memcmp(h, s->hist, s->nhist * HIST_COLS * sizeof(double)) != 0;
        free(h);
        MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    }
    if (bad) fprintf(stderr, "case %s: this rank's history or sums differ from rank 0's\n", name);
    return any ? CONSPH_EINVAL : CONSPH_OK;
}

static consph_step_diag whole_diag;

static int diag_whole(consph_solver *s, void *unused)
{
    (void)unused;
    return consph_solver_diag(s, &whole_diag);
}

/* consph_solver_diag called on every rank of a decomposed solver (the public function: not the
 * run's sample) gives the gathered set's diagnostics, bit for bit, on every rank: a sum over a
 * rank's particles would count its halo. */
static int check_public_diag(consph_solver *s, const char *name)
{
    consph_step_diag g;
    memset(&g, 0, sizeof g);
    memset(&whole_diag, 0, sizeof whole_diag);
    int st = consph_solver_diag(s, &g);
    if (st == CONSPH_OK) st = solver_global(s, diag_whole, NULL);
    MPI_Bcast(&whole_diag, (int)sizeof whole_diag, MPI_BYTE, 0, MPI_COMM_WORLD);
    int bad = st == CONSPH_OK && memcmp(&g, &whole_diag, sizeof g) != 0, any = 0;
    if (bad)
        fprintf(stderr, "case %s: consph_solver_diag on the ranks: ke %.17g, over the set %.17g\n",
                name, g.ke, whole_diag.ke);
    MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    return st != CONSPH_OK ? st : any ? CONSPH_EINVAL : CONSPH_OK;
}

static int rank_zero(void)
{
    int init = 0, rank = 0;
    MPI_Initialized(&init);
    if (init) MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    return rank == 0;
}

static int run_case(const par_case *c, const char *path)
{
    consph_run_params prm = case_params(c);
    consph_solver *s = NULL;
    /* cut at the set-up (consph_par_solver_create: the initial rates and the first sample
     * made decomposed); run_files and check_refresh cut a whole solver */
    int st = consph_par_solver_create(&s, &prm, NULL, NULL);
    const int dim = consph_problem_dim(c->problem);
    const size_t whole = (size_t)lround(pow((double)c->nx, (double)dim));
    /* decomposed: this rank owns a part of the particles, the ranks all of them, and on 3
     * ranks it holds a part (its own and its halo) */
    int size = 1;
    MPI_Initialized(&size);
    if (size) MPI_Comm_size(MPI_COMM_WORLD, &size);
    size_t own = 0;
    for (size_t i = 0; st == CONSPH_OK && s->sys.dest && i < s->sys.p->n; ++i)
        own += s->sys.dest[i] != 0;
    unsigned long long mine = own, owned = 0;
    if (size > 1) MPI_Allreduce(&mine, &owned, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
    if (st == CONSPH_OK && size > 1 && owned != whole) {
        fprintf(stderr, "case %s: the ranks own %llu of %zu particles\n", c->name, owned, whole);
        st = CONSPH_EINVAL;
    }
    if (st == CONSPH_OK && size > 1 &&
        !(s->sys.dest && own < whole && (size != 3 || s->sys.p->n < whole))) {
        fprintf(stderr, "case %s: %zu of %zu particles on this rank: not decomposed\n", c->name,
                s->sys.p->n, whole);
        st = CONSPH_EINVAL;
    }
    /* the set-up made this rank's share of the layout only (lattice and random are made by
     * index): at most ceil(N / K) particles before the cut, never the whole set */
    const size_t share = (whole + (size_t)size - 1) / (size_t)(size > 1 ? size : 1);
    if (st == CONSPH_OK && size > 1 && par_setup_made(s) > share) {
        fprintf(stderr,
                "case %s: the set-up made %zu particles on this rank, more than %zu of %zu\n",
                c->name, par_setup_made(s), share, whole);
        st = CONSPH_EINVAL;
    }
    const unsigned long groups0 = pass_group_runs, kit0 = kit_group_passes,
                        first0 = kit_first_packed, coupled0 = kit_coupled_packed,
                        chains0 = nlist_chain_split, left0 = nlist_chain_deferred,
                        sweeps0 = pass_group2_split, later0 = pass_group2_deferred;
    const int chain = !strncmp(c->name, "chain-", 6);
    const double halo_limit = nlist_chain_split_halo;
    if (chain) nlist_chain_split_halo = INFINITY;
    while (st == CONSPH_OK && !consph_solver_done(s)) st = consph_solver_step(s);
    nlist_chain_split_halo = halo_limit;
    /* decomposed, the chain ran on every rank and left some visits for after its sweep; at
     * these sizes the default limit declines it */
    if (size > 1 && (chain ? nlist_chain_split == chains0 || nlist_chain_deferred == left0
                           : nlist_chain_split != chains0)) {
        fprintf(stderr, "case %s: %lu chains on this rank, %lu visits after the sweep\n", c->name,
                nlist_chain_split - chains0, nlist_chain_deferred - left0);
        if (st == CONSPH_OK) st = CONSPH_EINVAL;
    }
    /* decomposed, the group visits run on every rank (the halo's rows of their packs filled
     * after the refresh: stale rows would show in the bits compared with the serial run): the
     * PySPH family's passes over groups; the kit's volumes over groups (the pair cache's fill)
     * and, in 2D, pass 1 and coupled_bc per particle from their packs (at these sizes a rank's
     * halo is too large for it to chain them, and groups read a filled cache only slower) */
    const int pysph =
        !strcmp(c->scheme, "wcsph") || !strcmp(c->scheme, "edac") || !strcmp(c->scheme, "tvf");
    /* tvf's and edac's density and rates in one sweep on every rank (pass_run_groups2), the rates
     * of the cells whose candidates reach the halo after the refresh */
    const int sweep2 = !strcmp(c->scheme, "edac") || !strcmp(c->scheme, "tvf");
    if (size > 1 && sweep2 && (pass_group2_split == sweeps0 || pass_group2_deferred == later0)) {
        fprintf(stderr, "case %s: %lu sweeps of both passes on this rank, %lu rates after them\n",
                c->name, pass_group2_split - sweeps0, pass_group2_deferred - later0);
        if (st == CONSPH_OK) st = CONSPH_EINVAL;
    }
    const int packs =
        dim == 2 && !chain && (!strcmp(c->scheme, "l-ipst-c") || !strcmp(c->scheme, "e-c"));
    if (size > 1 && ((pysph && pass_group_runs == groups0) ||
                     (!strcmp(c->scheme, "l-ipst-c") && !chain && kit_group_passes == kit0) ||
                     (packs && (kit_first_packed == first0 || kit_coupled_packed == coupled0)))) {
        fprintf(stderr, "case %s: the group visits did not run on this rank\n", c->name);
        if (st == CONSPH_OK) st = CONSPH_EINVAL;
    }
    if (st == CONSPH_ENUMERIC && !strcmp(c->name, "diverges")) {
        /* the message (and the state where it stopped) is what is compared */
        char msg[600];
        snprintf(msg, sizeof msg, "%s.msg", path);
        FILE *fp = rank_zero() ? fopen(msg, "w") : NULL;
        if (fp) {
            fprintf(fp, "%s\n", consph_last_error());
            fclose(fp);
        }
        st = CONSPH_OK;
    }
    if (st == CONSPH_OK && size > 1) st = check_owned_sum(s, c->name);
    if (st == CONSPH_OK && size > 1) st = check_same_history(s, c->name);
    if (st == CONSPH_OK && size > 1) st = check_public_diag(s, c->name);
    if (st == CONSPH_OK) st = solver_global(s, dump, (void *)path);
    if (st != CONSPH_OK) fprintf(stderr, "case %s: %s\n", c->name, consph_last_error());
    consph_solver_free(s);
    return st;
}

/* The first case from given particles that hold only this rank's range of the layout (a
 * library caller that reads its part of a file): the serial case's state, bit for bit. */
static int run_given_range(const char *path)
{
    const par_case *c = &cases[0];
    consph_run_params prm = case_params(c);
    consph_layout_params lp;
    int size = 1, rank = 0;
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    const size_t n = (size_t)c->nx * (size_t)c->nx, lo = n * (size_t)rank / (size_t)size,
                 hi = n * (size_t)(rank + 1) / (size_t)size;
    consph_particles part;
    memset(&part, 0, sizeof part);
    int st = consph_run_layout_params(&prm, &lp);
    if (st == CONSPH_OK) st = consph_layout_generate_range(&lp, lo, hi - lo, &part);
    consph_solver *s = NULL;
    if (st == CONSPH_OK) st = consph_par_solver_create(&s, &prm, &part, NULL);
    consph_particles_free(&part);
    if (st == CONSPH_OK && par_setup_made(s) != hi - lo) {
        fprintf(stderr, "given range: %zu particles made, not %zu\n", par_setup_made(s), hi - lo);
        st = CONSPH_EINVAL;
    }
    while (st == CONSPH_OK && !consph_solver_done(s)) st = consph_solver_step(s);
    if (st == CONSPH_OK) st = solver_global(s, dump, (void *)path);
    if (st != CONSPH_OK) fprintf(stderr, "given range: %s\n", consph_last_error());
    consph_solver_free(s);
    return st;
}

/* A packed layout with the layout cache in `cache`: from a valid file every rank reads only its
 * share (want_share), from a corrupt one every rank makes the whole set (packed again); the
 * run is the serial one either way. */
static int run_packed(const char *path, const char *cache, int want_share)
{
    par_case c = {"packed", "taylor-green", "wcsph", 24, CONSPH_LAYOUT_PACKED, 3, NULL};
    consph_run_params prm = case_params(&c);
    consph_solver *s = NULL;
    int st = consph_layout_cache_set(cache);
    if (st == CONSPH_OK) st = consph_par_solver_create(&s, &prm, NULL, NULL);
    int size = 1;
    MPI_Initialized(&size);
    if (size) MPI_Comm_size(MPI_COMM_WORLD, &size);
    const size_t whole = 24 * 24, share = (whole + (size_t)size - 1) / (size_t)size;
    if (st == CONSPH_OK && size > 1 &&
        (want_share ? par_setup_made(s) > share : par_setup_made(s) != whole)) {
        fprintf(stderr, "packed from %s: the set-up made %zu of %zu particles on this rank\n",
                cache, par_setup_made(s), whole);
        st = CONSPH_EINVAL;
    }
    while (st == CONSPH_OK && !consph_solver_done(s)) st = consph_solver_step(s);
    if (st == CONSPH_OK) st = solver_global(s, dump, (void *)path);
    if (st != CONSPH_OK) fprintf(stderr, "packed from %s: %s\n", cache, consph_last_error());
    consph_solver_free(s);
    consph_layout_cache_set(NULL);
    return st;
}

/* Flips a byte in the middle of the packed case's file in the cache `dir`. */
static int corrupt_cache(const char *dir)
{
    par_case c = {"packed", "taylor-green", "wcsph", 24, CONSPH_LAYOUT_PACKED, 3, NULL};
    consph_run_params prm = case_params(&c);
    consph_layout_params lp;
    char path[4608];
    int st = consph_run_layout_params(&prm, &lp);
    if (st == CONSPH_OK) st = consph_layout_cache_set(dir);
    if (st == CONSPH_OK) st = consph_layout_cache_path(&lp, path, sizeof path);
    consph_layout_cache_set(NULL);
    FILE *fp = st == CONSPH_OK ? fopen(path, "r+b") : NULL;
    if (!fp) return CONSPH_EIO;
    fseek(fp, 0, SEEK_END);
    const long mid = ftell(fp) / 2;
    fseek(fp, mid, SEEK_SET);
    const int b = fgetc(fp);
    fseek(fp, mid, SEEK_SET);
    fputc(b ^ 0x10, fp);
    return fclose(fp) == 0 ? CONSPH_OK : CONSPH_EIO;
}

/* A run with files: 10 steps, snapshots at steps 0 and 10, a checkpoint at step 5; the run id fixed
 * so that the files can be compared. With `restart`, from dir/checkpoint.ckpt instead: read whole
 * on every rank (1), or each rank its part (2: consph_par_run_restart, which never holds more
 * than its share of the particles before the cut). */
static int run_files(const char *dir, int restart)
{
    par_case c = {"files", "taylor-green", "edac", 40, CONSPH_LAYOUT_RANDOM, 10, NULL};
    consph_run_params prm = case_params(&c);
    consph_solver *s = NULL;
    int st;
    if (restart) {
        char ck[512];
        snprintf(ck, sizeof ck, "%s/checkpoint.ckpt", dir);
        st = restart == 2 ? consph_par_run_restart(&s, ck) : consph_run_restart(&s, ck);
    } else {
        mkdir(dir, 0755); /* every rank: one makes it */
        st = consph_solver_create(&s, &prm);
        if (st == CONSPH_OK) snprintf(s->run_id, sizeof s->run_id, "0123456789abcdef");
    }
    if (st == CONSPH_OK) st = consph_par_solver_decompose(s);
    int size = 1;
    MPI_Initialized(&size);
    if (size) MPI_Comm_size(MPI_COMM_WORLD, &size);
    if (st == CONSPH_OK && restart == 2 && size > 1 &&
        par_setup_made(s) > (1600 + (size_t)size - 1) / (size_t)size) {
        fprintf(stderr, "restart in %s: %zu particles read on this rank\n", dir, par_setup_made(s));
        st = CONSPH_EINVAL;
    }
    /* the checkpoint (step 5) between the snapshots (0 and 10): its output fields are still
     * those of that step, as the serial run's */
    consph_run_output out = {dir, 10, 5, 0, 0};
    consph_run_summary sum;
    int sig = 0;
    const long whole = par_whole_gathers();
    if (st == CONSPH_OK) st = consph_run(s, &out, &sum, &sig);
    if (st != CONSPH_OK) fprintf(stderr, "files run in %s: %s\n", dir, consph_last_error());
    /* the snapshots and the checkpoint go one array at a time (par_stream), and the run's end
     * gathers no field: rank 0 never assembles the whole set */
    if (st == CONSPH_OK && par_whole_gathers() != whole) {
        fprintf(stderr, "files run in %s: %ld gathers of every field\n", dir,
                par_whole_gathers() - whole);
        st = CONSPH_EINVAL;
    }
    consph_solver_free(s);
    return st;
}

/* ---- under mpirun ---- */

/* The halo refresh sends only the columns that changed (src/par/par_solver.c, refresh): after
 * the cut nothing travels but the column masks; a changed owned value reaches every copy; a
 * halo value written locally is put back to its owner's. */
static int check_refresh(void)
{
    par_case c = {"refresh", "taylor-green", "wcsph", 40, CONSPH_LAYOUT_RANDOM, 1, NULL};
    consph_run_params prm = case_params(&c);
    consph_solver *s = NULL;
    int st = consph_solver_create(&s, &prm);
    if (st == CONSPH_OK) st = consph_par_solver_decompose(s);
    if (st != CONSPH_OK) {
        fprintf(stderr, "refresh: %s\n", consph_last_error());
        consph_solver_free(s);
        return st;
    }
    int rank = 0, size = 1, bad = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    consph_sys *sys = &s->sys;
    consph_particles *p = sys->p;
    const double *id = consph_particles_find(p, SF_ID)->data;
    double *f0 = p->fields[0].data; /* the first field's first component */
    size_t ncols = (size_t)p->dim;
    for (int f = 0; f < p->nfields; ++f) ncols += (size_t)p->fields[f].ncomp;
    const double masks = (double)(ncols * (size_t)(size - 1));
    double b0 = 0, b1 = 0, b2 = 0, b3 = 0, sec = 0;
    consph_par_solver_comm(s, &b0, &sec);
    sys->split->refresh(sys, sys->split->ctx);
    consph_par_solver_comm(s, &b1, &sec);
    if (b1 - b0 != masks) {
        fprintf(stderr, "rank %d: a refresh after the cut sent %g bytes, the masks are %g\n", rank,
                b1 - b0, masks);
        bad = 1;
    }
    /* an owned value changes on rank 0; a halo value is overwritten on every rank */
    double target = -1.0;
    size_t first_halo = p->n;
    for (size_t i = 0; i < p->n && first_halo == p->n; ++i)
        if (!sys->dest[i]) first_halo = i;
    if (rank == 0)
        for (size_t i = 0; i < p->n; ++i)
            if (sys->dest[i]) {
                target = id[i];
                f0[i] = 12345.0;
                break;
            }
    MPI_Bcast(&target, 1, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    double kept = 0.0;
    if (first_halo < p->n && id[first_halo] != target) {
        kept = f0[first_halo];
        f0[first_halo] = -7.0;
    }
    sys->split->refresh(sys, sys->split->ctx);
    consph_par_solver_comm(s, &b2, &sec);
    for (size_t i = 0; i < p->n; ++i)
        if (id[i] == target && f0[i] != 12345.0) {
            fprintf(stderr, "rank %d: the changed value did not reach its copy (%g)\n", rank,
                    f0[i]);
            bad = 1;
        }
    if (first_halo < p->n && id[first_halo] != target && memcmp(&f0[first_halo], &kept, 8)) {
        fprintf(stderr, "rank %d: a halo value written here was not put back\n", rank);
        bad = 1;
    }
    if (rank == 0 && !(b2 - b1 > masks)) {
        fprintf(stderr, "rank 0: the changed column was not sent\n");
        bad = 1;
    }
    sys->split->refresh(sys, sys->split->ctx);
    consph_par_solver_comm(s, &b3, &sec);
    if (b3 - b2 != masks) {
        fprintf(stderr, "rank %d: a refresh with nothing changed sent %g bytes\n", rank, b3 - b2);
        bad = 1;
    }
    /* a halo position and a value of a column no owner changed, written here:
     * refresh_positions (consph_sys_update's) puts the position back and leaves the field to
     * the next refresh, which puts it back too */
    const int mine = first_halo < p->n && p->nfields > 1;
    double *f1 = p->nfields > 1 ? p->fields[1].data : NULL;
    const double kx = mine ? p->x[0][first_halo] : 0.0, kf = mine ? f1[first_halo] : 0.0;
    if (mine) {
        p->x[0][first_halo] = kx + 0.5 * p->spacing;
        f1[first_halo] = -9.0;
    }
    sys->split->refresh_positions(sys, sys->split->ctx);
    if (mine && (memcmp(&p->x[0][first_halo], &kx, 8) || f1[first_halo] != -9.0)) {
        fprintf(stderr, "rank %d: refresh_positions left x %g (owner's %g), field %g (-9)\n", rank,
                p->x[0][first_halo], kx, f1[first_halo]);
        bad = 1;
    }
    sys->split->refresh(sys, sys->split->ctx);
    if (mine && memcmp(&f1[first_halo], &kf, 8)) {
        fprintf(stderr, "rank %d: a halo value of an unchanged column was not put back\n", rank);
        bad = 1;
    }
    /* a pass that declares it reads u's second component (consph_sys_next_reads): an owned
     * change of both components on rank 0 and halo values written here; the narrowed refresh
     * brings the second component alone (one column's mask), the halo's first keeps what was
     * written here; the next full refresh finds the change of the first that the narrowed one
     * skipped */
    double *u = consph_particles_find(p, SF_U)->data;
    const size_t cap = p->cap;
    double k0 = 0.0;
    if (rank == 0)
        for (size_t i = 0; i < p->n; ++i)
            if (sys->dest[i] && id[i] == target) {
                u[i] = 111.0;
                u[cap + i] = 222.0;
            }
    if (mine) {
        k0 = u[first_halo];
        u[first_halo] = -5.0;
    }
    const consph_sys_reads second = {0, 0, {SF_U}, {2u}};
    consph_sys_next_reads(sys, &second);
    double b4 = 0, b5 = 0;
    consph_par_solver_comm(s, &b4, &sec);
    sys->halo_fresh = 0;
    pass_halo_refresh(sys);
    consph_par_solver_comm(s, &b5, &sec);
    if (sys->reads_set || (rank != 0 && b5 - b4 != (double)(size - 1)) ||
        (rank == 0 && !(b5 - b4 > (double)(size - 1)))) {
        fprintf(stderr, "rank %d: the narrowed refresh sent %g bytes (declaration %s)\n", rank,
                b5 - b4, sys->reads_set ? "kept" : "taken");
        bad = 1;
    }
    for (size_t i = 0; i < p->n; ++i)
        if (id[i] == target && (u[cap + i] != 222.0 || (!sys->dest[i] && u[i] == 111.0))) {
            fprintf(stderr, "rank %d: the narrowed refresh left u %g, %g at the changed particle\n",
                    rank, u[i], u[cap + i]);
            bad = 1;
        }
    if (mine && id[first_halo] != target && u[first_halo] != -5.0) {
        fprintf(stderr, "rank %d: the narrowed refresh wrote a column it was not asked for\n",
                rank);
        bad = 1;
    }
    sys->halo_fresh = 0;
    pass_halo_refresh(sys);
    for (size_t i = 0; i < p->n; ++i)
        if (id[i] == target && u[i] != 111.0) {
            fprintf(stderr, "rank %d: a change the narrowed refresh skipped did not arrive\n",
                    rank);
            bad = 1;
        }
    if (mine && id[first_halo] != target && memcmp(&u[first_halo], &k0, 8)) {
        fprintf(stderr, "rank %d: the full refresh did not put back a skipped column\n", rank);
        bad = 1;
    }
    consph_solver_free(s);
    return bad ? CONSPH_EINVAL : CONSPH_OK;
}

/* Whether every halo particle holds its owner's values in every column (positions, every
 * field's components), bitwise: every rank's owned rows gathered to all, by id. */
static int halo_is_owners(consph_solver *s, const char *when)
{
    const consph_particles *p = s->sys.p;
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    size_t nc = (size_t)p->dim;
    for (int f = 0; f < p->nfields; ++f) nc += (size_t)p->fields[f].ncomp;
    const double *id = consph_particles_find(p, SF_ID)->data;
    int mine = 0;
    for (size_t i = 0; i < p->n; ++i) mine += s->sys.dest[i] != 0;
    int *cnt = malloc((size_t)size * sizeof *cnt), *dis = malloc((size_t)size * sizeof *dis);
    MPI_Allgather(&mine, 1, MPI_INT, cnt, 1, MPI_INT, MPI_COMM_WORLD);
    int total = 0;
    for (int q = 0; q < size; ++q) {
        dis[q] = total * (int)(nc + 1);
        total += cnt[q];
        cnt[q] *= (int)(nc + 1);
    }
    double *row = malloc((size_t)(mine ? mine : 1) * (nc + 1) * sizeof *row);
    double *all = malloc((size_t)total * (nc + 1) * sizeof *all);
    double *by = malloc((size_t)total * nc * sizeof *by);
    size_t o = 0;
    for (size_t i = 0; i < p->n; ++i) {
        if (!s->sys.dest[i]) continue;
        double *r = row + o++ * (nc + 1);
        size_t k = 0;
        r[k++] = id[i];
        for (int a = 0; a < p->dim; ++a) r[k++] = p->x[a][i];
        for (int f = 0; f < p->nfields; ++f)
            for (int c = 0; c < p->fields[f].ncomp; ++c)
                r[k++] = p->fields[f].data[(size_t)c * p->cap + i];
    }
    MPI_Allgatherv(row, mine * (int)(nc + 1), MPI_DOUBLE, all, cnt, dis, MPI_DOUBLE,
                   MPI_COMM_WORLD);
    for (int t = 0; t < total; ++t)
        memcpy(by + (size_t)all[(size_t)t * (nc + 1)] * nc, all + (size_t)t * (nc + 1) + 1,
               nc * sizeof *by);
    int bad = 0;
    for (size_t i = 0; i < p->n && !bad; ++i) {
        if (s->sys.dest[i]) continue;
        const double *want = by + (size_t)id[i] * nc;
        size_t k = 0;
        for (int a = 0; a < p->dim; ++a, ++k) bad |= memcmp(&p->x[a][i], want + k, 8) != 0;
        for (int f = 0; f < p->nfields; ++f)
            for (int c = 0; c < p->fields[f].ncomp; ++c, ++k)
                if (memcmp(&p->fields[f].data[(size_t)c * p->cap + i], want + k, 8)) {
                    fprintf(stderr, "rank %d %s: halo particle %g's %s[%d] is not its owner's\n",
                            rank, when, id[i], p->fields[f].name, c);
                    bad = 1;
                }
    }
    free(cnt);
    free(dis);
    free(row);
    free(all);
    free(by);
    return bad;
}

/* A step's re-sort moves only the columns the serial re-sort carries (state_carried) and
 * leaves the others zero on every rank, kept copies included: the next refresh then gives the
 * halo its owners' values in every column, those an owner wrote since and those it did not. */
static int check_resort_columns(void)
{
    par_case c = {"resort", "taylor-green", "wcsph", 40, CONSPH_LAYOUT_RANDOM, 3, NULL};
    consph_run_params prm = case_params(&c);
    consph_solver *s = NULL;
    int st = consph_par_solver_create(&s, &prm, NULL, NULL);
    int bad = st != CONSPH_OK;
    for (int k = 0; k < 2 && !bad; ++k) bad = consph_solver_step(s) != CONSPH_OK;
    if (!bad) {
        /* an owned value of a column the re-sort does not carry, written after the step */
        consph_particles *p = s->sys.p;
        int f = 0, rank = 0;
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        while (f < p->nfields && state_carried(s, p->fields[f].name)) ++f;
        bad = f == p->nfields;
        if (bad) fprintf(stderr, "resort: wcsph has no field the re-sort leaves\n");
        for (size_t i = 0; !bad && i < p->n; ++i) p->fields[f].data[i] = (double)i + 0.5 * rank;
        bad = bad || par_step_begin(s) != CONSPH_OK;
        /* after the cut: the column is zero everywhere */
        for (size_t i = 0; !bad && i < p->n; ++i)
            if (p->fields[f].data[i] != 0.0) {
                fprintf(stderr, "rank %d: %s not zero after the re-sort\n", rank,
                        p->fields[f].name);
                bad = 1;
            }
        /* agreed before the refresh, a collective: one rank's failure must not hang the others */
        int any = bad;
        MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_LOR, MPI_COMM_WORLD);
        bad = any;
        if (!bad) {
            /* every halo column is its owners' after a refresh, with owned values written
             * since the cut and halo values written here */
            for (size_t i = 0; i < p->n; ++i)
                if (s->sys.dest[i] ? i % 3 == 0 : i % 5 == 0)
                    p->fields[f].data[i] = 1.0 + (double)i;
            s->sys.split->refresh(&s->sys, s->sys.split->ctx);
            bad = halo_is_owners(s, "after the re-sort");
        }
    }
    if (st != CONSPH_OK) fprintf(stderr, "resort: %s\n", consph_last_error());
    consph_solver_free(s);
    return bad ? CONSPH_EINVAL : CONSPH_OK;
}

/* On 4 ranks the boxes are forced to 2 x 2 pieces across the last two axes (3D) or both axes
 * (2D): each rank's particles are runs of the serial order, not one range. */
static const char *const boxes_cases[] = {"lipstc-3d", "wcsph-3d", "edac-2d", "diverges"};

static void force_boxes(const char *problem)
{
    static const int k3[CONSPH_MAX_DIM] = {1, 2, 2}, k2[CONSPH_MAX_DIM] = {2, 2, 1};
    par_force_boxes(consph_problem_dim(problem) == 3 ? k3 : k2);
}

static int child_boxes(const char *base)
{
    MPI_Init(NULL, NULL);
    consph_par_init(NULL, NULL);
    int bad = 0;
    for (size_t k = 0; k < NCASES; ++k)
        for (size_t b = 0; b < sizeof boxes_cases / sizeof boxes_cases[0]; ++b)
            if (!strcmp(cases[k].name, boxes_cases[b])) {
                char path[512];
                snprintf(path, sizeof path, "%s.%s.np4", base, cases[k].name);
                force_boxes(cases[k].problem);
                bad |= run_case(&cases[k], path) != CONSPH_OK;
            }
    char dir[512];
    force_boxes("taylor-green");
    snprintf(dir, sizeof dir, "%s.restart.np4", base);
    /* the files' arrays in messages of a few hundred bytes: a rank's boxes are many runs of
     * the serial order, each array many messages */
    par_force_gather_bytes(456);
    bad |= run_files(dir, 1) != CONSPH_OK;
    par_force_gather_bytes(0);
    par_force_boxes(NULL);
    int any = 0;
    MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    consph_par_finalize();
    MPI_Finalize();
    return any ? 1 : 0;
}

static int child(const char *base)
{
    MPI_Init(NULL, NULL);
    consph_par_init(NULL, NULL); /* joins this world: consph_par_solver_create's agreement */
    int rank = 0, size = 1, bad = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    for (size_t k = 0; k < NCASES; ++k) {
        char path[512];
        snprintf(path, sizeof path, "%s.%s.np%d", base, cases[k].name, size);
        bad |= run_case(&cases[k], path) != CONSPH_OK;
    }
    char dir[512];
    snprintf(dir, sizeof dir, "%s.files.np%d", base, size);
    par_force_gather_bytes(size == 3 ? 1000 : 0);
    bad |= run_files(dir, 0) != CONSPH_OK;
    par_force_gather_bytes(0);
    snprintf(dir, sizeof dir, "%s.restart.np%d", base, size);
    bad |= run_files(dir, 2) != CONSPH_OK;
    bad |= check_refresh() != CONSPH_OK;
    bad |= check_resort_columns() != CONSPH_OK;
    char cache[512];
    snprintf(dir, sizeof dir, "%s.packed.np%d", base, size);
    snprintf(cache, sizeof cache, "%s.cache", base);
    bad |= run_packed(dir, cache, 1) != CONSPH_OK;
    snprintf(dir, sizeof dir, "%s.packedbad.np%d", base, size);
    snprintf(cache, sizeof cache, "%s.badcache.np%d", base, size);
    bad |= run_packed(dir, cache, 0) != CONSPH_OK;
    snprintf(dir, sizeof dir, "%s.given.np%d", base, size);
    bad |= run_given_range(dir) != CONSPH_OK;
    /* more ranks than slabs: 4² particles in 2D have one or two cells per axis */
    {
        par_case c = {"tiny", "taylor-green", "wcsph", 4, CONSPH_LAYOUT_LATTICE, 1, NULL};
        consph_run_params prm = case_params(&c);
        prm.hdx = 1.0;
        consph_solver *s = NULL;
        int st = consph_solver_create(&s, &prm);
        if (st == CONSPH_OK) st = consph_par_solver_decompose(s);
        if (st != CONSPH_EINVAL || !strstr(consph_last_error(), "slabs")) {
            fprintf(stderr, "rank %d: a launch on too many ranks gave %d: %s\n", rank, st,
                    consph_last_error());
            bad = 1;
        }
        consph_solver_free(s);
    }
    int any = 0;
    MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    consph_par_finalize();
    MPI_Finalize();
    return any ? 1 : 0;
}

/* summary.json but its "seconds" line. */
static int same_summary(const char *a, const char *b)
{
    FILE *fa = fopen(a, "r"), *fb = fopen(b, "r");
    int same = fa && fb;
    char la[512], lb[512];
    while (same) {
        char *ra = fgets(la, sizeof la, fa), *rb = fgets(lb, sizeof lb, fb);
        if (!ra || !rb) {
            same = !ra && !rb;
            break;
        }
        if (strstr(la, "\"seconds\"") && strstr(lb, "\"seconds\"")) continue;
        same = !strcmp(la, lb);
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return same;
}

/* Two checkpoints hold the same state: metadata but its wall-clock "seconds", every particle
 * array and the history, bit for bit. */
static int same_checkpoint(const char *a, const char *b)
{
    char *ma = NULL, *mb = NULL;
    double *ha = NULL, *hb = NULL;
    size_t na = 0, nb = 0;
    consph_particles pa, pb;
    memset(&pa, 0, sizeof pa);
    memset(&pb, 0, sizeof pb);
    int same = consph_checkpoint_read(a, &ma, &pa, &ha, &na) == CONSPH_OK;
    same = same && consph_checkpoint_read(b, &mb, &pb, &hb, &nb) == CONSPH_OK;
    if (same) {
        char *sa = strstr(ma, "seconds="), *sb = strstr(mb, "seconds=");
        same = sa && sb;
        if (same) {
            char *ea = strchr(sa, '\n'), *eb = strchr(sb, '\n');
            same = ea && eb && !strncmp(ma, mb, (size_t)(sa - ma)) && sa - ma == sb - mb &&
                   !strcmp(ea, eb);
        }
    }
    same = same && na == nb && !memcmp(ha, hb, na * sizeof(double));
    same = same && pa.n == pb.n && pa.nfields == pb.nfields;
    for (int d = 0; same && d < pa.dim; ++d)
        same = !memcmp(pa.x[d], pb.x[d], pa.n * sizeof(double));
    for (int f = 0; same && f < pa.nfields; ++f) {
        same = !strcmp(pa.fields[f].name, pb.fields[f].name) &&
               pa.fields[f].ncomp == pb.fields[f].ncomp;
        for (int c = 0; same && c < pa.fields[f].ncomp; ++c)
            same = !memcmp(pa.fields[f].data + (size_t)c * pa.cap,
                           pb.fields[f].data + (size_t)c * pb.cap, pa.n * sizeof(double));
    }
    free(ma);
    free(mb);
    free(ha);
    free(hb);
    if (pa.x[0]) consph_particles_free(&pa);
    if (pb.x[0]) consph_particles_free(&pb);
    return same;
}

static const char *const run_files_list[] = {"log.csv", "run.pvd", "snap_000000.vtu",
                                             "snap_000010.vtu"};

static void compare_dirs(const char *ref, const char *dir)
{
    for (size_t k = 0; k < sizeof run_files_list / sizeof run_files_list[0]; ++k) {
        char a[600], b[600];
        snprintf(a, sizeof a, "%s/%s", ref, run_files_list[k]);
        snprintf(b, sizeof b, "%s/%s", dir, run_files_list[k]);
        CHECK(access(a, F_OK) == 0, "the serial run wrote no %s", a);
        CHECK(check_same_file(a, b), "%s differs from the serial %s", b, a);
    }
    char a[600], b[600];
    snprintf(a, sizeof a, "%s/checkpoint.ckpt", ref);
    snprintf(b, sizeof b, "%s/checkpoint.ckpt", dir);
    CHECK(same_checkpoint(a, b), "%s holds another state than the serial %s", b, a);
    snprintf(a, sizeof a, "%s/summary.json", ref);
    snprintf(b, sizeof b, "%s/summary.json", dir);
    CHECK(same_summary(a, b), "%s differs from the serial %s", b, a);
}

int main(int argc, char **argv)
{
    if (argc == 3 && !strcmp(argv[1], "--child")) return child(argv[2]);
    if (argc == 3 && !strcmp(argv[1], "--child-boxes")) return child_boxes(argv[2]);
    if (system("command -v mpirun >/dev/null 2>&1") != 0) {
        printf("test_par_solver: no mpirun: skipped\n");
        return 77;
    }
    char base[256];
    snprintf(base, sizeof base, "%s/consph-par-%d", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp",
             (int)getpid());
    for (size_t k = 0; k < NCASES; ++k) {
        char path[512];
        snprintf(path, sizeof path, "%s.%s.serial", base, cases[k].name);
        CHECK(run_case(&cases[k], path) == CONSPH_OK, "serial %s", cases[k].name);
    }
    char ref[512], cmd[2048];
    snprintf(ref, sizeof ref, "%s.files.serial", base);
    CHECK(run_files(ref, 0) == CONSPH_OK, "serial run with files");
    /* the packed case packs and fills the cache; a copy of it with a corrupt file per launch */
    char packed[512], cache[512];
    snprintf(packed, sizeof packed, "%s.packed.serial", base);
    snprintf(cache, sizeof cache, "%s.cache", base);
    CHECK(run_packed(packed, cache, 1) == CONSPH_OK, "serial packed run");
    for (int np = 2; np <= 3; ++np) {
        snprintf(cmd, sizeof cmd, "rm -rf %s.badcache.np%d && cp -r %s %s.badcache.np%d", base, np,
                 cache, base, np);
        CHECK(system(cmd) == 0, "%s", cmd);
        snprintf(cmd, sizeof cmd, "%s.badcache.np%d", base, np);
        CHECK(corrupt_cache(cmd) == CONSPH_OK, "corrupting the cache file in %s", cmd);
    }
    /* the restart directories start as the serial run's at its checkpoint (step 5): its files
     * up to there and the checkpoint */
    for (int np = 2; np <= 4; ++np) {
        snprintf(cmd, sizeof cmd,
                 "rm -rf %s.restart.np%d && cp -r %s %s.restart.np%d && rm -f "
                 "%s.restart.np%d/snap_000010.vtu %s.restart.np%d/summary.json",
                 base, np, ref, base, np, base, np, base, np);
        CHECK(system(cmd) == 0, "%s", cmd);
    }
    for (int np = 2; np <= 3; ++np) {
        snprintf(cmd, sizeof cmd,
                 "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
                 "OMPI_MCA_mpi_yield_when_idle=1 mpirun --oversubscribe -np %d %s --child %s",
                 np, argv[0], base);
        const int rc = system(cmd);
        CHECK(rc == 0, "%s exited with %d", cmd, rc);
        for (size_t k = 0; k < NCASES; ++k) {
            char a[512], b[512];
            snprintf(a, sizeof a, "%s.%s.serial", base, cases[k].name);
            snprintf(b, sizeof b, "%s.%s.np%d", base, cases[k].name, np);
            CHECK(check_same_file(a, b), "%s on %d ranks: the state differs from the serial run's",
                  cases[k].name, np);
            if (!strcmp(cases[k].name, "diverges")) {
                strcat(a, ".msg");
                strcat(b, ".msg");
                CHECK(access(a, F_OK) == 0, "the serial run did not diverge");
                CHECK(check_same_file(a, b),
                      "%s on %d ranks: another message than the serial run's", cases[k].name, np);
            }
        }
        char dir[512], a[512];
        snprintf(dir, sizeof dir, "%s.packed.np%d", base, np);
        CHECK(check_same_file(packed, dir), "packed from the cache on %d ranks: the state differs",
              np);
        snprintf(dir, sizeof dir, "%s.packedbad.np%d", base, np);
        CHECK(check_same_file(packed, dir),
              "packed from a corrupt cache on %d ranks: the state differs", np);
        snprintf(a, sizeof a, "%s.%s.serial", base, cases[0].name);
        snprintf(dir, sizeof dir, "%s.given.np%d", base, np);
        CHECK(check_same_file(a, dir), "%s from given ranges on %d ranks: the state differs",
              cases[0].name, np);
        snprintf(dir, sizeof dir, "%s.files.np%d", base, np);
        compare_dirs(ref, dir);
        snprintf(dir, sizeof dir, "%s.restart.np%d", base, np);
        compare_dirs(ref, dir);
    }
    /* 4 ranks in 2 x 2 boxes: a few cases, and the restart of the serial checkpoint */
    snprintf(cmd, sizeof cmd,
             "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
             "OMPI_MCA_mpi_yield_when_idle=1 mpirun --oversubscribe -np 4 %s --child-boxes %s",
             argv[0], base);
    const int rc4 = system(cmd);
    CHECK(rc4 == 0, "%s exited with %d", cmd, rc4);
    for (size_t k = 0; k < NCASES; ++k)
        for (size_t b = 0; b < sizeof boxes_cases / sizeof boxes_cases[0]; ++b)
            if (!strcmp(cases[k].name, boxes_cases[b])) {
                char a[512], c[512];
                snprintf(a, sizeof a, "%s.%s.serial", base, cases[k].name);
                snprintf(c, sizeof c, "%s.%s.np4", base, cases[k].name);
                CHECK(check_same_file(a, c), "%s on 4 ranks in 2 x 2 boxes: the state differs",
                      cases[k].name);
                if (!strcmp(cases[k].name, "diverges")) {
                    strcat(a, ".msg");
                    strcat(c, ".msg");
                    CHECK(check_same_file(a, c), "diverges on 4 ranks in boxes: another message");
                }
            }
    {
        char dir[512];
        snprintf(dir, sizeof dir, "%s.restart.np4", base);
        compare_dirs(ref, dir);
    }
    if (check_failures == 0) {
        snprintf(cmd, sizeof cmd, "rm -rf %s.*", base);
        if (system(cmd) != 0) fprintf(stderr, "could not remove %s.*\n", base);
    }
    return check_summary("test_par_solver");
}

#else

int main(void)
{
    printf("test_par_solver: built without MPI: skipped\n");
    return 77;
}

#endif
