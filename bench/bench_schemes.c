/* Cost of every scheme on Taylor-Green: seconds per particle-step, pair evaluations
 * per second per core, passes per stage beside the minimum the scheme's equations need, and the
 * peak memory, at nx = 100 and 250 with 1 and 2 threads.
 *
 * Each case runs in its own process (fork), so its peak resident set is its own. The particles
 * start on the lattice for every scheme (packing 250² particles would take far longer than the
 * steps measured); the Lagrangian schemes disorder them as they run, and IPST runs every 10
 * steps as in 001, so STEPS below is a multiple of 10.
 * Usage: bench_schemes [nx,...] [steps]   (default 100,250 and 20) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "consph/solver.h"

static int one_case(const char *scheme, int nx, int threads, long steps)
{
    consph_set_num_threads(threads);
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = nx;
    p.layout = CONSPH_LAYOUT_LATTICE;
    p.steps = steps;
    p.tf = 0.0;
    consph_solver *s;
    if (consph_solver_create(&s, &p) != CONSPH_OK) {
        fprintf(stderr, "%s: %s\n", scheme, consph_last_error());
        return 1;
    }
    consph_run_summary sum;
    int sig = 0, st = consph_run(s, NULL, &sum, &sig);
    consph_solver_free(s);
    if (st != CONSPH_OK) {
        fprintf(stderr, "%s: %s\n", scheme, consph_last_error());
        return 1;
    }
    const double ps = (double)sum.n * (double)sum.steps;
    printf("%-10s %5d %2d %6ld %10.3e %12.3e %7d %7d %9.1f\n", scheme, nx, threads, sum.steps,
           sum.seconds / ps, (double)sum.pairs / sum.seconds / threads, sum.passes_per_stage,
           sum.passes_min, (double)consph_peak_rss() / 1048576.0);
    fflush(stdout);
    return 0;
}

int main(int argc, char **argv)
{
    int nxs[8] = {100, 250}, nnx = 2;
    long steps = argc > 2 ? atol(argv[2]) : 20;
    if (argc > 1) {
        nnx = 0;
        for (char *t = strtok(argv[1], ","); t && nnx < 8; t = strtok(NULL, ","))
            nxs[nnx++] = atoi(t);
    }
    printf("# Taylor-Green, quintic, h = 1.2 Δs, c_o = 10, lattice start, %ld steps, each "
           "scheme's default integrator (rk2: two evaluations per step; pec and kdk of wcsph, "
           "edac and tvf: one)\n",
           steps);
    printf("%-10s %5s %2s %6s %10s %12s %7s %7s %9s\n", "scheme", "nx", "th", "steps", "s/(p·step)",
           "pairs/s/core", "passes", "min", "peak MiB");
    int fail = 0;
    for (int k = 0; k < nnx; ++k) {
        char names[256];
        snprintf(names, sizeof names, "%s", consph_scheme_names());
        for (char *t = strtok(names, ","); t; t = strtok(NULL, ",")) {
            for (int th = 1; th <= 2; ++th) {
                fflush(stdout);
                pid_t pid = fork();
                if (pid == 0) _exit(one_case(t, nxs[k], th, steps));
                int status = 0;
                waitpid(pid, &status, 0);
                if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) fail = 1;
            }
        }
    }
    return fail;
}
