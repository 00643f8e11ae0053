/* Pair evaluations per second per core of the particle operators.
 *
 * Cases: 2D 500² and 3D 100³ random particles (ε = 0.4) in the periodic unit box, quintic
 * kernel with h = 1.2Δs. For each: the bare neighbour query (consph_nnps_query_particle into a
 * buffer, summing r so it cannot be optimised away), the same neighbours through the inline
 * traversal the operators use (runs per cell + consph_nnps_gather), the plain summation
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

/* The same neighbours through the inline traversal the operators use (runs per cell shared by
 * its particles, consph_nnps_gather with r), reading every distance. */
static size_t traverse_only(const consph_nnps *g, size_t *pairs)
{
    consph_nnps_slots v;
    size_t total = 0, positive = 0;
    *pairs = 0;
    if (consph_nnps_slots_get(g, &v)) return 0;
#pragma omp parallel reduction(+ : total, positive)
    {
        consph_nnps_runs runs;
        memset(&runs, 0, sizeof runs);
        size_t cap = 0, *slot = NULL;
        double *r = NULL;
#pragma omp for schedule(dynamic, 16)
        for (size_t c = 0; c < v.ncells; ++c) {
            if (v.cell_start[c] == v.cell_start[c + 1]) continue;
            if (consph_nnps_cell_runs(g, c, &runs) == (size_t)-1) continue;
            if (runs.candidates + CONSPH_NNPS_GATHER_SLACK > cap) {
                cap = 2 * (runs.candidates + CONSPH_NNPS_GATHER_SLACK);
                slot = realloc(slot, cap * sizeof *slot);
                r = realloc(r, cap * sizeof *r);
            }
            for (size_t s = v.cell_start[c]; s < v.cell_start[c + 1]; ++s) {
                double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
                for (int a = 0; a < v.dim; ++a) xi[a] = v.x[a][s];
                size_t m = consph_nnps_gather(&v, &runs, xi, slot, NULL, r);
                for (size_t p = 0; p < m; ++p) positive += r[p] > 0.0;
                total += m;
            }
        }
        free(slot);
        free(r);
        consph_nnps_runs_free(&runs);
    }
    *pairs = total;
    return positive;
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
    consph_particles p;
    if (consph_layout_generate(&lp, &p, NULL) != CONSPH_OK) return 1;
    consph_kernel k;
    consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, dim, 1.2 / (double)nx);
    consph_nnps *g = consph_nnps_create(&p.box, k.radius, 0);
    if (!g || consph_nnps_sort(g, &p, NULL) != CONSPH_OK) return 1;
    const size_t n = p.n;
    double *f = malloc(n * sizeof(double)), *out = malloc((size_t)dim * n * sizeof(double));
    for (size_t i = 0; i < n; ++i) f[i] = p.x[0][i] * p.x[0][i] + (dim > 1 ? p.x[1][i] : 0.0);
    int tmax = max_threads();
    int tlist[2] = {1, tmax};
    int nt = tmax > 1 ? 2 : 1;
    for (int t = 0; t < nt; ++t) {
        set_threads(tlist[t]);
        consph_op_ctx ctx;
        if (consph_op_ctx_init(&ctx, &p, g, &k, CONSPH_VOLUME_SUMMATION) != CONSPH_OK) return 1;
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

        row tr = {"traversal only", tlist[t], 0.0, 0.0, 0};
        t0 = consph_wtime();
        c0 = cpu_seconds();
        for (int k2 = 0; k2 < reps; ++k2) {
            size_t pairs;
            volatile size_t sink = traverse_only(g, &pairs);
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
    consph_nnps_free(g);
    consph_particles_free(&p);
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
    printf("goal (issue #3): 3e8 pair evaluations/s/core for function standard; pairs/cpu_s is "
           "the per-core rate on a shared machine\n");
    if (st) fprintf(stderr, "bench_ops: %s\n", consph_last_error());
    return st;
}
