/* Pair evaluations per second per core of the particle operators.
 *
 * Cases: 2D 500² and 3D 100³ random particles (ε = 0.4) in the periodic unit box, quintic
 * kernel with h = 1.2Δs. For each: the bare neighbour query (consph_nnps_query_particle into a
 * buffer, summing r so it cannot be optimised away), the same neighbours through the pass layer
 * the operators run on (consph_pass_run asking only r), the plain summation
 * Σ ω_j f_j W_ij
 * (function/standard) and the Bonet-corrected pressure gradient asym_bc, whose first call also
 * builds the B matrices (reported separately). Each on 1 thread and on all threads.
 *
 * Usage: bench_ops [--quick] (quick: 200² and 40³). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "consph/consph.h"
#include "consph/ops.h"

static int max_threads(void)
{
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

static void set_threads(int t)
{
#ifdef _OPENMP
    omp_set_num_threads(t);
#else
    (void)t;
#endif
}

/* The neighbour query alone, as the operators call it; reads every distance so the work is
 * not optimised away. Returns the pairs with r > 0. */
static size_t query_only(const consph_nnps *g, size_t n, size_t *pairs)
{
    size_t total = 0, positive = 0;
#pragma omp parallel reduction(+ : total, positive)
    {
        consph_nbrs nb;
        memset(&nb, 0, sizeof nb);
#pragma omp for schedule(dynamic, 128)
        for (size_t i = 0; i < n; ++i) {
            size_t m = consph_nnps_query_particle(g, i, &nb);
            for (size_t p = 0; p < m; ++p) positive += nb.r[p] > 0.0;
            total += m;
        }
        consph_nbrs_free(&nb);
    }
    *pairs = total;
    return positive;
}

/* The same neighbours through the pass layer the operators run on (runs per cell shared by its
 * particles, consph_nnps_gather with r, no kernel values), reading every distance. */
static void visit_positive(void *job, const consph_nbhd *nb)
{
    size_t c = 0;
    for (size_t k = 0; k < nb->n; ++k) c += nb->r[k] > 0.0;
    ((size_t *)job)[nb->i] = c;
}

static size_t pass_only(const consph_sys *s, size_t *positive, size_t *pairs)
{
    const consph_pass pass = {"distances", CONSPH_PASS_NO_DX, visit_positive};
    size_t total = 0;
    *pairs = 0;
    if (consph_pass_run_counted(s, &pass, positive, pairs) != CONSPH_OK) return 0;
    for (size_t i = 0; i < s->p->n; ++i) total += positive[i];
    return total;
}

/* CPU seconds of the whole process: on a shared machine this, not the wall time, says what a
 * pair costs (it excludes time the threads were descheduled, though it includes OpenMP spin
 * waits). */
static double cpu_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct row {
    const char *what;
    int threads;
    double seconds, cpu;
    size_t pairs;
} row;

static void print_row(const char *label, const row *r)
{
    double rate = (double)r->pairs / r->seconds;
    printf("%-10s %-24s %3d %8.3f %8.3f %10.3e %11.3e %11.3e %11.3e\n", label, r->what, r->threads,
           r->seconds, r->cpu, (double)r->pairs, rate, rate / r->threads,
           (double)r->pairs / r->cpu);
}

static int bench_case(const char *label, int dim, size_t nx, int reps)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, dim, nx);
    lp.eps = 0.4;
    consph_particles src;
    if (consph_layout_generate(&lp, &src, NULL) != CONSPH_OK) return 1;
    consph_kernel k;
    consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, dim, 1.2 / (double)nx);
    consph_sys sys;
    int rc = consph_sys_init(&sys, &src, &k, 0.0);
    consph_particles_free(&src);
    if (rc != CONSPH_OK) return 1;
    const consph_particles *p = sys.p;
    const consph_nnps *g = sys.nnps;
    const size_t n = p->n;
    double *f = malloc(n * sizeof(double)), *out = malloc((size_t)dim * n * sizeof(double));
    size_t *positive = malloc(n * sizeof(size_t));
    for (size_t i = 0; i < n; ++i) f[i] = p->x[0][i] * p->x[0][i] + (dim > 1 ? p->x[1][i] : 0.0);
    int tmax = max_threads();
    int tlist[2] = {1, tmax};
    int nt = tmax > 1 ? 2 : 1;
    for (int t = 0; t < nt; ++t) {
        set_threads(tlist[t]);
        consph_op_ctx ctx;
        if (consph_op_ctx_init_sys(&ctx, &sys, CONSPH_VOLUME_SUMMATION) != CONSPH_OK) return 1;
        row r = {"query only", tlist[t], 0.0, 0.0, 0};
        double t0 = consph_wtime(), c0 = cpu_seconds();
        for (int k2 = 0; k2 < reps; ++k2) {
            size_t pairs;
            volatile size_t sink = query_only(g, n, &pairs);
            (void)sink;
            r.pairs += pairs;
        }
        r.seconds = consph_wtime() - t0;
        r.cpu = cpu_seconds() - c0;
        print_row(label, &r);

        row tr = {"pass, distances only", tlist[t], 0.0, 0.0, 0};
        t0 = consph_wtime();
        c0 = cpu_seconds();
        for (int k2 = 0; k2 < reps; ++k2) {
            size_t pairs;
            volatile size_t sink = pass_only(&sys, positive, &pairs);
            (void)sink;
            tr.pairs += pairs;
        }
        tr.seconds = consph_wtime() - t0;
        tr.cpu = cpu_seconds() - c0;
        print_row(label, &tr);

        consph_op_report rep;
        row s = {"function standard", tlist[t], 0.0, 0.0, 0};
        c0 = cpu_seconds();
        for (int k2 = 0; k2 < reps; ++k2) {
            consph_apply(&ctx, CONSPH_OP_FUNCTION, CONSPH_FORM_STANDARD, CONSPH_CORR_NONE, f, out,
                         &rep);
            s.seconds += rep.seconds;
            s.pairs += rep.pairs;
        }
        s.cpu = cpu_seconds() - c0;
        print_row(label, &s);

        row b = {"asym_bc, B matrix + op", tlist[t], 0.0, 0.0, 0};
        c0 = cpu_seconds();
        consph_apply(&ctx, CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_CORR_BC, f, out, &rep);
        b.seconds = rep.seconds;
        b.pairs = rep.pairs;
        b.cpu = cpu_seconds() - c0;
        print_row(label, &b);
        row c = {"asym_bc, B cached", tlist[t], 0.0, 0.0, 0};
        c0 = cpu_seconds();
        for (int k2 = 0; k2 < reps; ++k2) {
            consph_apply(&ctx, CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_CORR_BC, f, out, &rep);
            c.seconds += rep.seconds;
            c.pairs += rep.pairs;
        }
        c.cpu = cpu_seconds() - c0;
        print_row(label, &c);
        consph_op_ctx_free(&ctx);
    }
    set_threads(tmax);
    free(f);
    free(out);
    free(positive);
    consph_sys_free(&sys);
    return 0;
}

int main(int argc, char **argv)
{
    int quick = argc > 1 && strcmp(argv[1], "--quick") == 0;
    printf("%-10s %-24s %3s %8s %8s %10s %11s %11s %11s\n", "case", "what", "thr", "wall_s",
           "cpu_s", "pairs", "pairs/s", "pairs/s/thr", "pairs/cpu_s");
    int st = 0;
    st |= bench_case(quick ? "2D 200^2" : "2D 500^2", 2, quick ? 200 : 500, 3);
    st |= bench_case(quick ? "3D 40^3" : "3D 100^3", 3, quick ? 40 : 100, 1);
    printf("goal: 3e8 pair evaluations/s/core for function standard; pairs/cpu_s is "
           "the per-core rate on a shared machine\n");
    if (st) fprintf(stderr, "bench_ops: %s\n", consph_last_error());
    return st;
}
