/* Wasserstein distances at scale, 2D, random points against a translate-free second random set
 * (both uniform on the unit square): sliced W2 (64 directions) for N = 10^4 .. 10^6, and
 * log-domain Sinkhorn W2 at eps = 1e-3 C_max for N = M = 1000 and 3000 run to convergence, and
 * for N = M = 10^4 the time per iteration (20 iterations). Prints seconds, iterations, the
 * distance and its error estimate; threads as OMP_NUM_THREADS says. */
#include <stdio.h>
#include <stdlib.h>

#include "consph/transport.h"

static double *points(size_t n, uint64_t seed)
{
    double *x = consph_calloc(2 * n, sizeof *x);
    consph_rng r;
    consph_rng_seed(&r, seed);
    for (size_t i = 0; x && i < 2 * n; ++i) x[i] = consph_rng_uniform(&r);
    return x;
}

static int run(size_t n, consph_ot_options o, const char *label)
{
    double *x = points(n, 1), *y = points(n, 2);
    if (!x || !y) {
        free(x);
        free(y);
        return 1;
    }
    consph_measure a = {2, n, {x, x + n, NULL}, NULL}, b = {2, n, {y, y + n, NULL}, NULL};
    consph_ot_result res;
    double t0 = consph_wtime();
    int rc = consph_wasserstein(&a, &b, &o, &res);
    double t = consph_wtime() - t0;
    if (rc)
        fprintf(stderr, "bench_transport: %s\n", consph_last_error());
    else
        printf("%-22s %9zu %10.3f %8ld %12.4e %12.4e %s\n", label, n, t, res.iterations,
               res.distance, res.error, res.converged ? "yes" : "no");
    free(x);
    free(y);
    return rc != 0;
}

int main(void)
{
    printf("bench_transport: 2D, W2, %d threads\n", consph_num_threads());
    printf("%-22s %9s %10s %8s %12s %12s %s\n", "method", "N", "seconds", "iter", "distance",
           "error", "converged");
    consph_ot_options o = consph_ot_defaults();
    o.p = 2;
    o.method = CONSPH_OT_SLICED;
    int bad = 0;
    for (size_t n = 10000; n <= 1000000; n *= 10) bad |= run(n, o, "sliced K=64");
    o.method = CONSPH_OT_SINKHORN;
    o.eps = 1e-3;
    bad |= run(1000, o, "sinkhorn eps=1e-3");
    bad |= run(3000, o, "sinkhorn eps=1e-3");
    o.max_iter = 20;
    bad |= run(10000, o, "sinkhorn 20 iterations");
    return bad;
}
