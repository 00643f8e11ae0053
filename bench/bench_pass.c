/* The fused L-IPST-C-like pass pair (bench/fused_lipst.h: Bonet moment + ∇p + ∇u + ∇·u in one
 * traversal, then the coupled Laplacian of u from G_j) against the same quantities by separate
 * consph_apply calls (asym_bc, f4 per component, div_bc, coupled_bc per component).
 *
 * Cases: 2D 500² and 3D 100³ particles on a lattice perturbed by ε = 0.1 (the random layout) in
 * the periodic unit box, quintic kernel, h = 1.2Δs, volumes 1/Σ W. For each on 1 and 2 threads:
 * the pairs visited, the wall time, pairs/s/core (pairs visited / time / threads) and the
 * speed-up (separate time / fused time); and whether the two give identical numbers. The
 * volumes, the search and the context are built before timing and shared by both sides; the
 * separate side starts from an empty matrix cache, so it pays its own Bonet pass as the fused
 * pass does.
 *
 * Usage: bench_pass [NX2 NX3] (particles per axis; default 500 100; a smoke run: 40 10). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/consph.h"
#include "fused_lipst.h"

static int run_case(int dim, size_t nx)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, dim, nx);
    lp.eps = 0.1;
    lp.seed = 1;
    consph_sys sys;
    consph_op_ctx ctx;
    int st = fused_lipst_world(&lp, &sys, &ctx);
    fused_lipst fused, sep;
    memset(&fused, 0, sizeof fused);
    if (st == CONSPH_OK) st = fused_lipst_bind(&fused, &sys, &ctx);
    const size_t n = sys.p ? sys.p->n : 0;
    double *in = st == CONSPH_OK ? calloc(n * (size_t)(dim + 1), sizeof(double)) : NULL;
    sep = fused;
    double *m1 = in ? fused_lipst_outputs(&fused) : NULL,
           *m2 = m1 ? fused_lipst_outputs(&sep) : NULL;
    if (!m2) {
        fprintf(stderr, "bench_pass: %dD setup: %s\n", dim, consph_last_error());
        free(in);
        free(m1);
        consph_op_ctx_free(&ctx);
        consph_sys_free(&sys);
        return 1;
    }
    for (size_t i = 0; i < n; ++i) {
        double x = sys.p->x[0][i], y = sys.p->x[1][i], z = dim > 2 ? sys.p->x[2][i] : 0.0;
        in[i] = x * y + z;
        for (int a = 0; a < dim; ++a) in[(size_t)(1 + a) * n + i] = x - y * (a + 1) + z * z;
    }
    fused.p = sep.p = in;
    fused.u = sep.u = in + n;
    const size_t nout = n * (size_t)(2 * dim + 1 + dim * dim);
    for (int threads = 1; threads <= 2; ++threads) {
        fused_set_threads(threads);
        size_t pf = 0, ps = 0;
        double t0 = consph_wtime();
        st = fused_lipst_run(&sys, &fused, &pf);
        double tf = consph_wtime() - t0;
        if (st == CONSPH_OK) st = consph_op_ctx_refresh(&ctx);
        t0 = consph_wtime();
        if (st == CONSPH_OK) st = fused_lipst_separate(&ctx, &sep, &ps);
        double ts = consph_wtime() - t0;
        if (st != CONSPH_OK) {
            fprintf(stderr, "bench_pass: %dD: %s\n", dim, consph_last_error());
            break;
        }
        const int same = memcmp(m1, m2, nout * sizeof(double)) == 0;
        printf("%dD %zu^%d  threads %d  fused: %6.2e pairs %7.3f s %6.2e pairs/s/core  "
               "separate: %6.2e pairs %7.3f s %6.2e pairs/s/core  speed-up %.2f  identical %s\n",
               dim, nx, dim, threads, (double)pf, tf, (double)pf / tf / threads, (double)ps, ts,
               (double)ps / ts / threads, ts / tf, same ? "yes" : "NO");
        fflush(stdout);
    }
    free(in);
    free(m1);
    free(m2);
    consph_op_ctx_free(&ctx);
    consph_sys_free(&sys);
    return st == CONSPH_OK ? 0 : 1;
}

int main(int argc, char **argv)
{
    size_t nx2 = 500, nx3 = 100;
    if (argc == 3) {
        nx2 = strtoul(argv[1], NULL, 10);
        nx3 = strtoul(argv[2], NULL, 10);
    }
    if (argc == 2 || argc > 3 || nx2 < 8 || nx3 < 6 || nx2 > 100000 || nx3 > 2000) {
        fprintf(stderr, "usage: bench_pass [NX2 NX3] (particles per axis: NX2 >= 8, NX3 >= 6)\n");
        return 2;
    }
    printf("fused L-IPST-C-like pass pair vs separate consph_apply calls (quintic, h = 1.2 dx, "
           "perturbed lattice eps 0.1, periodic)\n");
    int rc = run_case(2, nx2);
    rc |= run_case(3, nx3);
    return rc;
}
