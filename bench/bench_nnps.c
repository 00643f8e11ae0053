/* Neighbour-search benchmark: random particles in the unit periodic box, build + sort + a query
 * of every particle's neighbours (OpenMP over particles, one buffer per thread).
 *
 *   bench_nnps [--n N] [--dims 2,3] [--nbrs 50,1000] [--cpr C | --sweep] [--brute-n M]
 *
 * Columns: build_s = first build of the unsorted set (includes allocation), sort_s =
 * consph_nnps_sort (build + permute), rebuild_s = build of the sorted set (the per-step cost),
 * query_s = every particle's neighbours, traverse_s = the same through the inline traversal
 * (runs per cell + consph_nnps_gather, as the operators use it), MiB_g = consph_nnps_bytes,
 * MiB_rss = peak RSS.
 * --sweep times cells_per_radius 1, 2 and 3 (to choose the default); --brute-n compares the
 * cell search with the O(N^2) reference at M particles (0 skips). */
#include "consph/nnps.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double radius_for(int dim, size_t n, double nbrs)
{
    const double pi = 3.14159265358979323846;
    double unit_ball = dim == 1 ? 2.0 : dim == 2 ? pi : 4.0 * pi / 3.0;
    return pow(nbrs / ((double)n * unit_ball), 1.0 / dim);
}

static int parse_list(const char *s, double *out, int max)
{
    int k = 0;
    while (*s && k < max) {
        char *end;
        out[k++] = strtod(s, &end);
        if (end == s) return -1;
        s = *end == ',' ? end + 1 : end;
        if (*end && *end != ',') return -1;
    }
    return k;
}

static void fill_random(consph_particles *p, uint64_t seed)
{
    consph_rng rng;
    consph_rng_seed(&rng, seed);
    for (size_t i = 0; i < p->n; ++i)
        for (int a = 0; a < p->dim; ++a) p->x[a][i] = consph_rng_uniform(&rng);
}

/* Queries every particle; returns seconds, stores the summed count. */
static double query_all(const consph_nnps *g, size_t n, size_t *counts, size_t *total, int *failed)
{
    int bad = 0;
    double t0 = consph_wtime();
#pragma omp parallel
    {
        consph_nbrs nb;
        memset(&nb, 0, sizeof nb);
#pragma omp for schedule(dynamic, 256)
        for (size_t i = 0; i < n; ++i) {
            size_t m = consph_nnps_query_particle(g, i, &nb);
            if (m == (size_t)-1) {
#pragma omp atomic write
                bad = 1;
                m = 0;
            }
            counts[i] = m;
        }
        consph_nbrs_free(&nb);
    }
    double t = consph_wtime() - t0;
    size_t sum = 0;
    for (size_t i = 0; i < n; ++i) sum += counts[i];
    *total = sum;
    *failed = bad;
    return t;
}

/* Every particle's neighbours through the inline traversal (the runs of each cell, shared by
 * its particles, and consph_nnps_gather with x_ij and r), as the operators find them; returns
 * seconds and stores the summed count, which must equal the query's. */
static double traverse_all(const consph_nnps *g, size_t *total, int *failed)
{
    consph_nnps_slots v;
    if (consph_nnps_slots_get(g, &v)) {
        *failed = 1;
        return 0.0;
    }
    size_t sum = 0;
    int bad = 0;
    double t0 = consph_wtime();
#pragma omp parallel reduction(+ : sum)
    {
        consph_nnps_runs runs;
        memset(&runs, 0, sizeof runs);
        size_t cap = 0, *slot = NULL;
        double *dx[CONSPH_MAX_DIM] = {NULL, NULL, NULL}, *r = NULL;
#pragma omp for schedule(dynamic, 16)
        for (size_t c = 0; c < v.ncells; ++c) {
            if (v.cell_start[c] == v.cell_start[c + 1]) continue;
            if (consph_nnps_cell_runs(g, c, &runs) == (size_t)-1) {
#pragma omp atomic write
                bad = 1;
                continue;
            }
            size_t need = runs.candidates + CONSPH_NNPS_GATHER_SLACK;
            if (need > cap) {
                cap = 2 * need;
                slot = realloc(slot, cap * sizeof *slot);
                for (int a = 0; a < v.dim; ++a) dx[a] = realloc(dx[a], cap * sizeof(double));
                r = realloc(r, cap * sizeof *r);
            }
            for (size_t s = v.cell_start[c]; s < v.cell_start[c + 1]; ++s) {
                double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
                for (int a = 0; a < v.dim; ++a) xi[a] = v.x[a][s];
                sum += consph_nnps_gather(&v, &runs, xi, slot, dx, r);
            }
        }
        free(slot);
        for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(dx[a]);
        free(r);
        consph_nnps_runs_free(&runs);
    }
    *total = sum;
    *failed = bad;
    return consph_wtime() - t0;
}

static int run_case(int dim, size_t n, double nbrs, int cpr)
{
    consph_box box = consph_box_unit(dim, 1);
    consph_particles p;
    if (consph_particles_init(&p, dim, n, &box)) return 1;
    fill_random(&p, 1000 + (uint64_t)dim);
    double radius = radius_for(dim, n, nbrs);
    consph_nnps *g = consph_nnps_create(&box, radius, cpr);
    size_t *counts = malloc(n * sizeof *counts);
    if (!g || !counts) {
        fprintf(stderr, "bench_nnps: %s\n", consph_last_error());
        return 1;
    }
    double t0 = consph_wtime();
    int st = consph_nnps_build(g, &p);
    double t_build = consph_wtime() - t0;
    t0 = consph_wtime();
    st |= consph_nnps_sort(g, &p, NULL);
    double t_sort = consph_wtime() - t0;
    /* What a time step pays: rebuilding over particles that are already nearly sorted. */
    t0 = consph_wtime();
    st |= consph_nnps_build(g, &p);
    double t_rebuild = consph_wtime() - t0;
    if (st) {
        fprintf(stderr, "bench_nnps: %s\n", consph_last_error());
        return 1;
    }
    size_t total;
    int failed;
    double t_query = query_all(g, n, counts, &total, &failed);
    size_t total_traversed;
    int failed_traversal;
    double t_traverse = traverse_all(g, &total_traversed, &failed_traversal);
    failed |= failed_traversal || total_traversed != total;
    printf("%3d %6.0f %3d %9zu %9.3g %9zu %8.3f %8.3f %9.3f %9.3f %10.3f %8.1f %12zu %9.1f "
           "%9.1f%s\n",
           dim, nbrs, consph_nnps_cells_per_radius(g), n, radius, consph_nnps_cells(g), t_build,
           t_sort, t_rebuild, t_query, t_traverse, (double)total / (double)n, total,
           (double)consph_nnps_bytes(g) / 1048576.0, (double)consph_peak_rss() / 1048576.0,
           failed ? "  QUERY OR TRAVERSAL FAILED" : "");
    fflush(stdout);
    free(counts);
    consph_nnps_free(g);
    consph_particles_free(&p);
    return failed;
}

/* Brute force against the cell search at a small size: times and agreement of the counts. */
static int run_brute(int dim, size_t n, double nbrs)
{
    consph_box box = consph_box_unit(dim, 1);
    consph_particles p;
    if (consph_particles_init(&p, dim, n, &box)) return 1;
    fill_random(&p, 7);
    double radius = radius_for(dim, n, nbrs);
    consph_nnps *g = consph_nnps_create(&box, radius, 0);
    size_t *counts = malloc(n * sizeof *counts);
    if (!g || !counts || consph_nnps_build(g, &p)) return 1;
    size_t total;
    int failed;
    double t_cell = query_all(g, n, counts, &total, &failed);
    /* Brute force on a sample of particles, extrapolated to all. */
    const size_t sample = n < 500 ? n : 500;
    consph_nbrs nb;
    memset(&nb, 0, sizeof nb);
    size_t mismatched = 0;
    double t0 = consph_wtime();
    for (size_t s = 0; s < sample; ++s) {
        size_t i = s * (n / sample);
        double x[3] = {p.x[0][i], dim > 1 ? p.x[1][i] : 0.0, dim > 2 ? p.x[2][i] : 0.0};
        mismatched += consph_nnps_brute(&p, radius, x, &nb) != counts[i];
    }
    double t_brute = (consph_wtime() - t0) * (double)n / (double)sample;
    printf("brute %dD N=%zu nbrs~%.0f: cell search (all threads) %.4f s, brute (1 thread, "
           "extrapolated from %zu queries) %.2f s, ratio %.0f; count mismatches %zu of %zu\n",
           dim, n, nbrs, t_cell, sample, t_brute, t_brute / t_cell, mismatched, sample);
    consph_nbrs_free(&nb);
    free(counts);
    consph_nnps_free(g);
    consph_particles_free(&p);
    return mismatched != 0 || failed;
}

int main(int argc, char **argv)
{
    size_t n = 1000000, brute_n = 20000;
    double dims[3] = {2, 3}, nbrs[8] = {50, 1000};
    int ndims = 2, nnbrs = 2, cpr = 0, sweep = 0;
    for (int k = 1; k < argc; ++k) {
        const char *arg = argv[k], *val = k + 1 < argc ? argv[k + 1] : NULL;
        if (!strcmp(arg, "--sweep")) {
            sweep = 1;
        } else if (!val) {
            fprintf(stderr, "bench_nnps: unknown option or missing value: %s\n", arg);
            return 2;
        } else if (!strcmp(arg, "--n")) {
            n = (size_t)strtod(val, NULL), ++k;
        } else if (!strcmp(arg, "--brute-n")) {
            brute_n = (size_t)strtod(val, NULL), ++k;
        } else if (!strcmp(arg, "--cpr")) {
            cpr = atoi(val), ++k;
        } else if (!strcmp(arg, "--dims")) {
            ndims = parse_list(val, dims, 3), ++k;
        } else if (!strcmp(arg, "--nbrs")) {
            nnbrs = parse_list(val, nbrs, 8), ++k;
        } else {
            fprintf(stderr, "bench_nnps: unknown option %s\n", arg);
            return 2;
        }
    }
    if (ndims < 1 || nnbrs < 1 || n < 1) {
        fprintf(stderr, "bench_nnps: bad --dims, --nbrs or --n\n");
        return 2;
    }
    printf("bench_nnps: %d threads; random particles in the unit periodic box; query = all "
           "particles after sorting\n",
           consph_num_threads());
    printf("dim   nbrs cpr         N    radius     cells  build_s   sort_s rebuild_s   query_s "
           "traverse_s mean_nbr    sum_count     MiB_g   MiB_rss\n");
    int status = 0;
    for (int d = 0; d < ndims; ++d) {
        for (int b = 0; b < nnbrs; ++b) {
            if (sweep) {
                for (int c = 1; c <= 3; ++c) status |= run_case((int)dims[d], n, nbrs[b], c);
            } else {
                status |= run_case((int)dims[d], n, nbrs[b], cpr);
            }
        }
    }
    if (brute_n > 0)
        for (int d = 0; d < ndims; ++d) status |= run_brute((int)dims[d], brute_n, nbrs[0]);
    return status;
}
