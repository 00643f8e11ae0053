/* The solver decomposed over MPI ranks: time per step, the communication per particle-step and
 * the fraction of the step time spent in MPI calls (bench/mpi.md).
 *
 *   mpirun -np K build/bench/bench_par PROBLEM SCHEME NX STEPS [key=value ...]
 *   (boxes=K0xK1xK2 forces the pieces per axis of the decomposition; default: the fewest halo
 *   cells)
 *
 * Set-up (consph_par_solver_create: every rank makes the whole set's particles, then they are
 * cut) is not timed; the steps are. Rank 0
 * prints one line per rank and the totals. Without MPI it runs the serial solver. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/par.h"
#include "consph/solver.h"
#include "par/par_solver.h"
#include "solver/solver_internal.h"

#ifdef CONSPH_HAVE_MPI
#include <mpi.h>
#endif

#ifdef CONSPH_HAVE_MPI
/* bench_par --bandwidth BYTES: every rank exchanges BYTES with a partner (rank r with r ^ 1; an
 * odd last rank idles) all pairs at once, as the halo refresh's largest messages go, and rank 0
 * prints the slowest pair's rate per rank (bytes sent / seconds, minimum time of 10 rounds of
 * 4 exchanges): the per-byte cost the extrapolation in bench/mpi.sh takes from the machine
 * instead of assuming one. */
static int bandwidth(size_t bytes)
{
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    const int partner = (rank ^ 1) < size ? rank ^ 1 : -1;
    char *out = malloc(bytes ? bytes : 1), *in = malloc(bytes ? bytes : 1);
    int ok = out && in, all = 0;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_LAND, MPI_COMM_WORLD);
    if (!all) {
        if (rank == 0) fprintf(stderr, "bench_par: out of memory for %zu bytes\n", bytes);
        free(out);
        free(in);
        return 1;
    }
    memset(out, rank & 0xff, bytes);
    double best = 0.0;
    for (int round = 0; round < 11; ++round) {
        MPI_Barrier(MPI_COMM_WORLD);
        const double t0 = MPI_Wtime();
        for (int k = 0; partner >= 0 && k < 4; ++k)
            MPI_Sendrecv(out, (int)bytes, MPI_BYTE, partner, 7, in, (int)bytes, MPI_BYTE, partner,
                         7, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        double t = MPI_Wtime() - t0, slowest = 0.0;
        MPI_Allreduce(&t, &slowest, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
        if (round > 0 && (best == 0.0 || slowest < best)) best = slowest; /* round 0: warm-up */
    }
    if (rank == 0)
        printf("bandwidth: %d ranks in pairs, %zu bytes each way: %.3g bytes/s per rank\n", size,
               bytes, best > 0.0 ? 4.0 * (double)bytes / best : 0.0);
    free(out);
    free(in);
    return 0;
}
#endif

int main(int argc, char **argv)
{
#ifdef CONSPH_HAVE_MPI
    if (argc == 3 && !strcmp(argv[1], "--bandwidth")) {
        char *end = NULL;
        const unsigned long long b = strtoull(argv[2], &end, 10);
        if (!end || *end || b == 0 || b > (1ull << 30)) {
            fprintf(stderr, "bench_par: --bandwidth BYTES: an integer in [1, 2^30], not '%s'\n",
                    argv[2]);
            return 2;
        }
        MPI_Init(&argc, &argv);
        const int rc = bandwidth((size_t)b);
        MPI_Finalize();
        return rc;
    }
#endif
    if (argc < 5) {
        fprintf(stderr,
                "usage: %s PROBLEM SCHEME NX STEPS [key=value ...]\n       %s --bandwidth BYTES "
                "(with MPI)\n",
                argv[0], argv[0]);
        return 2;
    }
    int rank = 0, size = 1;
#ifdef CONSPH_HAVE_MPI
    MPI_Init(&argc, &argv);
    consph_par_init(&argc, &argv); /* joins this world */
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
#endif
    consph_run_params prm;
    consph_run_params_default(&prm);
    int st = consph_run_params_problem(&prm, argv[1]);
    if (st == CONSPH_OK) st = consph_run_param_set(&prm, "scheme", argv[2]);
    if (st == CONSPH_OK) st = consph_run_param_set(&prm, "nx", argv[3]);
    if (st == CONSPH_OK) st = consph_run_param_set(&prm, "steps", argv[4]);
    if (st == CONSPH_OK) st = consph_run_param_set(&prm, "layout", "lattice");
    for (int k = 5; st == CONSPH_OK && k < argc; ++k) {
        char key[64];
        const char *eq = strchr(argv[k], '=');
        if (!eq) {
            st = CONSPH_EINVAL;
            break;
        }
        snprintf(key, sizeof key, "%.*s", (int)(eq - argv[k]), argv[k]);
        int kb[3] = {0, 0, 0};
        if (!strcmp(key, "boxes")) { /* boxes=K0xK1xK2: the pieces per axis, forced */
            if (sscanf(eq + 1, "%dx%dx%d", &kb[0], &kb[1], &kb[2]) != 3) st = CONSPH_EINVAL;
            par_force_boxes(kb);
            continue;
        }
        st = consph_run_param_set(&prm, key, eq + 1);
    }
    prm.tf = 0.0;
    consph_solver *s = NULL;
    if (st == CONSPH_OK) st = consph_par_solver_create(&s, &prm, NULL, NULL);
    size_t own = 0;
    for (size_t i = 0; st == CONSPH_OK && i < s->sys.p->n; ++i)
        own += !s->sys.dest || s->sys.dest[i];
    const size_t whole = (size_t)consph_par_sum_long((long)own);
    double b0 = 0.0, c0 = 0.0, t0 = consph_wtime();
    if (st == CONSPH_OK) consph_par_solver_comm(s, &b0, &c0);
    while (st == CONSPH_OK && !consph_solver_done(s)) st = consph_solver_step(s);
    const double secs = consph_wtime() - t0;
    if (st != CONSPH_OK) {
        if (rank == 0) fprintf(stderr, "bench_par: %s\n", consph_last_error());
#ifdef CONSPH_HAVE_MPI
        consph_par_finalize();
        MPI_Finalize();
#endif
        return 1;
    }
    double b1 = 0.0, c1 = 0.0;
    consph_par_solver_comm(s, &b1, &c1);
    own = 0;
    for (size_t i = 0; i < s->sys.p->n; ++i) own += !s->sys.dest || s->sys.dest[i];
    /* per rank: owned, held, seconds, bytes sent, MPI seconds */
    double mine[5] = {(double)own, (double)s->sys.p->n, secs, b1 - b0, c1 - c0};
    double *all = malloc(5 * (size_t)size * sizeof(double));
#ifdef CONSPH_HAVE_MPI
    MPI_Gather(mine, 5, MPI_DOUBLE, all, 5, MPI_DOUBLE, 0, MPI_COMM_WORLD);
#else
    memcpy(all, mine, sizeof mine);
#endif
    if (rank == 0) {
        const double steps = (double)s->step;
        double bytes = 0.0, tmax = 0.0, cmean = 0.0;
        printf("%s %s nx %s: %zu particles, %d rank(s), %.0f steps\n", argv[1], argv[2], argv[3],
               whole, size, steps);
        for (int r = 0; r < size; ++r) {
            const double *a = all + 5 * r;
            printf("  rank %d: owns %.0f, holds %.0f (halo %.2f of owned), %.4f s/step, "
                   "%.1f bytes sent per owned particle-step, MPI %.1f%% of the time\n",
                   r, a[0], a[1], (a[1] - a[0]) / a[0], a[2] / steps, a[3] / (a[0] * steps),
                   100.0 * a[4] / a[2]);
            bytes += a[3];
            if (a[2] > tmax) tmax = a[2];
            cmean += a[4] / a[2] / size;
        }
        printf("  total: %.4f s/step, %.1f bytes per particle-step, MPI %.1f%% of the step time "
               "(mean over ranks)\n",
               tmax / steps, bytes / ((double)whole * steps), 100.0 * cmean);
        int k[CONSPH_MAX_DIM];
        long long nc[CONSPH_MAX_DIM], width[CONSPH_MAX_DIM];
        const int d = par_geometry(s, k, nc, width);
        if (d > 0) {
            printf("  boxes");
            for (int a = 0; a < d; ++a) printf("%s%d", a ? "x" : " ", k[a]);
            printf(" of cells");
            for (int a = 0; a < d; ++a) printf("%s%lld", a ? "x" : " ", nc[a]);
            printf(", halo width");
            for (int a = 0; a < d; ++a) printf(" %lld", width[a]);
            printf(" cells\n");
        }
    }
    free(all);
    consph_solver_free(s);
#ifdef CONSPH_HAVE_MPI
    consph_par_finalize();
    MPI_Finalize();
#endif
    return 0;
}
