/* Kernel evaluation throughput: W and dW/dr of quintic and wendland-c4 (3D) over 10^7
 * distances spread uniformly over the support, through the public inline API (one indirect
 * call per evaluation). One short single-threaded run; prints evaluations per second. */
#include <stdio.h>
#include <stdlib.h>

#include "consph/kernels.h"

#define NVALUES 10000000

int main(void)
{
    double *r = consph_calloc(NVALUES, sizeof *r);
    if (!r) {
        fprintf(stderr, "bench_kernels: %s\n", consph_last_error());
        return 1;
    }
    const consph_kernel_id ids[2] = {CONSPH_KERNEL_QUINTIC, CONSPH_KERNEL_WENDLAND_C4};
    const double h = 0.01;
    printf("bench_kernels: %d evaluations per function, dim 3, h = %g, 1 thread\n", NVALUES, h);
    printf("%-12s %-6s %10s %14s %24s\n", "kernel", "value", "seconds", "evals/s", "checksum");
    for (int t = 0; t < 2; ++t) {
        consph_kernel k;
        if (consph_kernel_init(&k, ids[t], 3, h) != CONSPH_OK) {
            fprintf(stderr, "bench_kernels: %s\n", consph_last_error());
            free(r);
            return 1;
        }
        consph_rng rng;
        consph_rng_seed(&rng, 12345u);
        for (size_t i = 0; i < NVALUES; ++i) r[i] = consph_rng_uniform(&rng) * k.radius;

        /* The checksum keeps the loops from being optimised away and lets runs be compared. */
        double t0 = consph_wtime(), sum_w = 0.0;
        for (size_t i = 0; i < NVALUES; ++i) sum_w += consph_kernel_w(&k, r[i]);
        double t1 = consph_wtime(), sum_dw = 0.0;
        for (size_t i = 0; i < NVALUES; ++i) sum_dw += consph_kernel_dw(&k, r[i]);
        double t2 = consph_wtime();
        printf("%-12s %-6s %10.4f %14.4e %24.16e\n", k.name, "W", t1 - t0, NVALUES / (t1 - t0),
               sum_w);
        printf("%-12s %-6s %10.4f %14.4e %24.16e\n", k.name, "dW/dr", t2 - t1, NVALUES / (t2 - t1),
               sum_dw);
    }
    free(r);
    return 0;
}
