/* The MPI cut weighted by work (src/par/par_solver.c, cut_boxes): on particles four times
 * denser at one end of the cut axis than at the other, the pairs each rank visits are closer to
 * equal when the cut weighs each particle by its work than when it counts particles (both cuts
 * of the same run, on 2 ranks): L-IPST-C's particles weigh the pairs they visited (its pair
 * cache keeps them), WCSPH's the candidates of their cell (no cache); every run ends in the
 * serial run's state bit for bit.
 *
 * Run without mpirun, the test computes the serial reference and launches itself under
 * `mpirun -np 2` (--oversubscribe); skips (77) without MPI or mpirun. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "consph/layout.h"
#include "consph/par.h"
#include "consph/solver.h"
#include "par/par_solver.h"
#include "solver/solver_internal.h"

#ifdef CONSPH_HAVE_MPI
#include <mpi.h>

#define STEPS 4

/* the scheme and what the weighted cut weighs with it (par_cut_weights) */
static const struct {
    const char *scheme;
    int weights;
} schemes[] = {{"l-ipst-c", 1}, {"wcsph", 2}};
#define NSCHEMES (sizeof schemes / sizeof schemes[0])

static consph_run_params params(const char *scheme)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = 40;
    p.steps = STEPS;
    p.tf = 0.0;
    p.layout = CONSPH_LAYOUT_LATTICE;
    return p;
}

/* The lattice with the last axis squeezed towards its upper end, t -> t + a t (1 - t) on the
 * axis' unit coordinate: the spacing there shrinks by (1 - a) / (1 + a) from the lower end
 * (a = 0.6: a fourth), so the pairs per particle grow along the axis. */
static int clustered(const consph_run_params *prm, consph_particles *out)
{
    consph_layout_params lp;
    int st = consph_run_layout_params(prm, &lp);
    if (st == CONSPH_OK) st = consph_layout_generate(&lp, out, NULL);
    if (st != CONSPH_OK) return st;
    const int a = out->dim - 1;
    const double lo = out->box.lo[a], len = out->box.hi[a] - out->box.lo[a];
    for (size_t i = 0; i < out->n; ++i) {
        const double t = (out->x[a][i] - lo) / len;
        out->x[a][i] = lo + len * (t + 0.6 * t * (1.0 - t));
    }
    return CONSPH_OK;
}

/* The state, in the serial order, to a file. */
static int dump(consph_solver *s, void *path)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return consph_fail(CONSPH_EIO, "cannot write %s", (const char *)path);
    const consph_particles *p = s->sys.p;
    for (int a = 0; a < p->dim; ++a) fwrite(p->x[a], sizeof(double), p->n, fp);
    for (int f = 0; f < p->nfields; ++f)
        for (int c = 0; c < p->fields[f].ncomp; ++c)
            fwrite(p->fields[f].data + (size_t)c * p->cap, sizeof(double), p->n, fp);
    fwrite(s->hist, sizeof(double), s->nhist * HIST_COLS, fp);
    fclose(fp);
    return CONSPH_OK;
}

/* A run of STEPS steps to `path`; *spread: the largest rank's pairs over the mean, counted from
 * the second step on (the set-up's cut counts particles); *weights: par_cut_weights at the end. */
static int run(const char *scheme, const char *path, double *spread, int *weights)
{
    consph_run_params prm = params(scheme);
    consph_particles given;
    memset(&given, 0, sizeof given);
    consph_solver *s = NULL;
    int st = clustered(&prm, &given);
    if (st == CONSPH_OK) st = consph_par_solver_create(&s, &prm, &given, NULL);
    if (given.x[0]) consph_particles_free(&given);
    unsigned long long from = 0;
    for (long k = 0; st == CONSPH_OK && !consph_solver_done(s); ++k) {
        if (k == 1) from = s->pairs;
        st = consph_solver_step(s);
    }
    int init = 0, size = 1;
    MPI_Initialized(&init);
    if (init) MPI_Comm_size(MPI_COMM_WORLD, &size);
    if (st == CONSPH_OK && size > 1) {
        unsigned long long mine = s->pairs - from, mx = 0, sum = 0;
        MPI_Allreduce(&mine, &mx, 1, MPI_UNSIGNED_LONG_LONG, MPI_MAX, MPI_COMM_WORLD);
        MPI_Allreduce(&mine, &sum, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
        *spread = (double)mx * size / (double)sum;
        *weights = par_cut_weights(s);
    }
    if (st == CONSPH_OK) st = solver_global(s, dump, (void *)path);
    if (st != CONSPH_OK) fprintf(stderr, "%s: %s\n", path, consph_last_error());
    consph_solver_free(s);
    return st;
}

static int child(const char *base)
{
    MPI_Init(NULL, NULL);
    consph_par_init(NULL, NULL);
    int rank = 0, bad = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    for (size_t k = 0; k < NSCHEMES; ++k) {
        char path[512];
        double weighted = 0.0, counted = 0.0;
        int wk = -1, ck = -1;
        snprintf(path, sizeof path, "%s.%s.weighted", base, schemes[k].scheme);
        bad |= run(schemes[k].scheme, path, &weighted, &wk) != CONSPH_OK;
        par_force_count_cut(1);
        snprintf(path, sizeof path, "%s.%s.counted", base, schemes[k].scheme);
        bad |= run(schemes[k].scheme, path, &counted, &ck) != CONSPH_OK;
        par_force_count_cut(0);
        if (bad || rank != 0) continue;
        printf("%s: pairs of the busiest rank over the mean: %.4f cut by particles, %.4f by "
               "weights %d\n",
               schemes[k].scheme, counted, weighted, wk);
        if (wk != schemes[k].weights || ck != 0) {
            fprintf(stderr, "%s: the cut weighed by %d (expected %d), forced counts by %d\n",
                    schemes[k].scheme, wk, schemes[k].weights, ck);
            bad = 1;
        }
        /* the layout must make the counted cut unequal for the comparison to mean anything */
        if (!(counted > 1.15 && weighted < 1.0 + 0.5 * (counted - 1.0))) {
            fprintf(stderr, "%s: the weighted cut did not balance the pairs\n", schemes[k].scheme);
            bad = 1;
        }
    }
    int any = 0;
    MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    consph_par_finalize();
    MPI_Finalize();
    return any ? 1 : 0;
}

int main(int argc, char **argv)
{
    if (argc == 3 && !strcmp(argv[1], "--child")) return child(argv[2]);
    if (system("command -v mpirun >/dev/null 2>&1") != 0) {
        printf("test_par_balance: no mpirun: skipped\n");
        return 77;
    }
    char base[256], ref[400], cmd[1024];
    snprintf(base, sizeof base, "%s/consph-balance-%d",
             getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp", (int)getpid());
    for (size_t k = 0; k < NSCHEMES; ++k) {
        double unused = 0.0;
        int none = 0;
        snprintf(ref, sizeof ref, "%s.%s.serial", base, schemes[k].scheme);
        CHECK(run(schemes[k].scheme, ref, &unused, &none) == CONSPH_OK, "the serial %s run",
              schemes[k].scheme);
    }
    snprintf(cmd, sizeof cmd,
             "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
             "OMPI_MCA_mpi_yield_when_idle=1 mpirun --oversubscribe -np 2 %s --child %s",
             argv[0], base);
    const int rc = system(cmd);
    CHECK(rc == 0, "%s exited with %d", cmd, rc);
    static const char *const cuts[] = {"weighted", "counted"};
    for (size_t k = 0; k < NSCHEMES; ++k)
        for (int c = 0; c < 2; ++c) {
            char path[400];
            snprintf(ref, sizeof ref, "%s.%s.serial", base, schemes[k].scheme);
            snprintf(path, sizeof path, "%s.%s.%s", base, schemes[k].scheme, cuts[c]);
            CHECK(check_same_file(ref, path), "%s cut %s on 2 ranks: another state than the serial",
                  schemes[k].scheme, cuts[c]);
        }
    if (check_failures == 0) {
        snprintf(cmd, sizeof cmd, "rm -f %s.*", base);
        if (system(cmd) != 0) fprintf(stderr, "could not remove %s.*\n", base);
    }
    return check_summary("test_par_balance");
}

#else

int main(void)
{
    printf("test_par_balance: built without MPI: skipped\n");
    return 77;
}

#endif
