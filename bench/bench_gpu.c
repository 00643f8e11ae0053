/* The GPU solver against the CPU solver on one case (bench/gpu.sh runs it per size): two solvers
 * set up alike (--scheme, edac by default; the set-up on --setup-threads), then
 *   1. one step each, the GPU's (or the host emulation's, --emulate) against the CPU's on
 *      --threads-max threads: values differing and the largest relative difference;
 *   2. --gpu-steps steps on the GPU, timed to the copy back that ends them, less that copy;
 *   3. --cpu-steps steps on --threads-max threads, then --serial-steps on one thread.
 * Every solver runs as consph run does without snapshots (gradients only where read, no log
 * samples in between). One line of key=value on stdout; a part whose step count is 0 is skipped.
 *
 *   bench_gpu --problem taylor-green --nx 1000 [--scheme edac] [--gpu-steps 20] [--cpu-steps 3]
 *             [--serial-steps 1] [--threads-max 16] [--setup-threads 16] [--emulate]
 *             [--layout scheme|lattice]
 * --layout lattice starts from the lattice whatever the scheme's layout (l-ipst-c's packed start
 * takes minutes to pack at 10^7 particles; for a speed measurement the lattice serves). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/gpu.h"
#include "consph/solver.h"
#include "gpu/gpu_internal.h"
#include "solver/solver_internal.h"

static consph_solver *make(const char *scheme, const char *problem, int nx, int layout)
{
    consph_run_params p;
    consph_run_params_default(&p);
    if (consph_run_params_problem(&p, problem) != CONSPH_OK) return NULL;
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.layout = layout;
    p.nx = nx;
    p.steps = 1000000000L;
    p.tf = 0.0;
    p.log_every = 1000000000L;
    consph_solver *s = NULL;
    if (consph_solver_create(&s, &p) != CONSPH_OK) return NULL;
    s->grads_lazy = 1; /* as consph_run: gradients only where a snapshot or the end reads them */
    return s;
}

/* Seconds of k steps. */
static double steps(consph_solver *s, long k, int *st)
{
    const double t0 = consph_wtime();
    for (long i = 0; i < k && *st == CONSPH_OK; ++i) *st = consph_solver_step(s);
    return consph_wtime() - t0;
}

/* Values differing and the largest |x - y| / max |x| over each array, over every particle
 * array. */
static void agreement(const consph_solver *a, const consph_solver *b, size_t *differ,
                      size_t *values, double *maxrel)
{
    const consph_particles *p = a->sys.p, *q = b->sys.p;
    *differ = *values = 0;
    *maxrel = 0.0;
    for (int k = -1; k < p->nfields; ++k) {
        const int nc = k < 0 ? p->dim : p->fields[k].ncomp;
        for (int c = 0; c < nc; ++c) {
            const double *x = k < 0 ? p->x[c] : p->fields[k].data + (size_t)c * p->cap;
            const double *y = k < 0 ? q->x[c] : q->fields[k].data + (size_t)c * q->cap;
            double big = 0.0, diff = 0.0;
            for (size_t i = 0; i < p->n; ++i) {
                big = fmax(big, fabs(x[i]));
                if (memcmp(&x[i], &y[i], sizeof(double)) != 0) {
                    ++*differ;
                    diff = fmax(diff, fabs(x[i] - y[i]));
                }
            }
            *values += p->n;
            if (big > 0.0) *maxrel = fmax(*maxrel, diff / big);
        }
    }
}

int main(int argc, char **argv)
{
    const char *problem = "taylor-green", *scheme = "edac";
    int nx = 100, emulate = 0, threads_max = 16, setup_threads = 16, layout = -1;
    long gpu_steps = 20, cpu_steps = 3, serial_steps = 1;
    for (int k = 1; k < argc; ++k) {
        const char *o = argv[k], *v = k + 1 < argc ? argv[k + 1] : NULL;
        if (!strcmp(o, "--emulate")) {
            emulate = 1;
            continue;
        }
        if (!v) {
            fprintf(stderr, "bench_gpu: option %s needs a value\n", o);
            return 2;
        }
        ++k;
        if (!strcmp(o, "--problem"))
            problem = v;
        else if (!strcmp(o, "--scheme"))
            scheme = v;
        else if (!strcmp(o, "--nx"))
            nx = atoi(v);
        else if (!strcmp(o, "--gpu-steps"))
            gpu_steps = atol(v);
        else if (!strcmp(o, "--cpu-steps"))
            cpu_steps = atol(v);
        else if (!strcmp(o, "--serial-steps"))
            serial_steps = atol(v);
        else if (!strcmp(o, "--threads-max"))
            threads_max = atoi(v);
        else if (!strcmp(o, "--setup-threads"))
            setup_threads = atoi(v);
        else if (!strcmp(o, "--layout") && (!strcmp(v, "scheme") || !strcmp(v, "lattice")))
            layout = !strcmp(v, "lattice") ? CONSPH_LAYOUT_LATTICE : -1;
        else {
            fprintf(
                stderr,
                "bench_gpu: unknown option %s (allowed: --problem, --scheme, --nx, --gpu-steps, "
                "--cpu-steps, --serial-steps, --threads-max, --setup-threads, --emulate, "
                "--layout scheme|lattice)\n",
                o);
            return 2;
        }
    }
    char why[256] = "";
    const gpu_backend *be = emulate ? &gpu_emulation : gpu_cuda_backend(why, sizeof why);
    consph_set_num_threads(setup_threads);
    double t0 = consph_wtime();
    consph_solver *cpu = make(scheme, problem, nx, layout);
    const double setup = consph_wtime() - t0;
    consph_solver *gpu = be ? make(scheme, problem, nx, layout) : NULL;
    if (!cpu || (be && !gpu)) {
        fprintf(stderr, "bench_gpu: set-up: %s\n", consph_last_error());
        return 1;
    }
    int st = CONSPH_OK;
    printf("scheme=%s problem=%s dim=%d n=%zu setup_s=%.3f layout=%s", scheme, problem, cpu->dim,
           cpu->sys.p->n, setup, layout == CONSPH_LAYOUT_LATTICE ? "lattice" : "scheme");
    /* 1. one step each */
    consph_set_num_threads(threads_max);
    size_t before = cpu->pairs;
    const double cpu_first = steps(cpu, 1, &st);
    double pairs = (double)(cpu->pairs - before);
    double per_pass = pairs / (double)cpu->passes;
    if (strcmp(scheme, "l-ipst-c") == 0) {
        /* rk2's two evaluations of three counted passes (the volumes, the kit's two), and after
         * step 1 IPST's gradients (two more); a step's pairs: the six of the evaluations (IPST's
         * own passes, every ipst_every steps, uncounted) */
        per_pass = pairs / 8.0;
        pairs = 6.0 * per_pass;
    }
    printf(" pairs_per_step=%.0f pairs_per_particle=%.2f", pairs, /* per pass */
           per_pass / (double)cpu->sys.p->n);
    if (be && st == CONSPH_OK) {
        t0 = consph_wtime();
        st = gpu_attach(gpu, be);
        const double attach = consph_wtime() - t0;
        if (st == CONSPH_OK) {
            printf(" backend=\"%s\" attach_s=%.3f gpu_bytes_per_particle=%.1f", be->name, attach,
                   (double)gpu_device_bytes(gpu) / (double)gpu->sys.p->n);
            st = consph_solver_step(gpu);
        }
        if (st == CONSPH_OK) st = gpu_download(gpu);
        if (st == CONSPH_OK) {
            size_t differ, values;
            double maxrel;
            agreement(cpu, gpu, &differ, &values, &maxrel);
            printf(" step1_differing=%zu step1_values=%zu step1_maxrel=%.3e", differ, values,
                   maxrel);
        }
        /* 2. the GPU's steps, to the copy back that ends them, less that copy */
        if (st == CONSPH_OK && gpu_steps > 0) {
            t0 = consph_wtime();
            const double run = steps(gpu, gpu_steps, &st);
            if (st == CONSPH_OK) st = gpu_download(gpu);
            const double total = consph_wtime() - t0;
            t0 = consph_wtime();
            if (st == CONSPH_OK) st = gpu_download(gpu);
            const double copy = consph_wtime() - t0;
            const double per = (total - copy) / (double)gpu_steps;
            printf(" gpu_steps=%ld gpu_launch_s=%.4f gpu_copy_back_s=%.4f gpu_step_s=%.6g "
                   "gpu_us_per_particle_step=%.6g gpu_pairs_per_s=%.4g",
                   gpu_steps, run, copy, per, per * 1e6 / (double)gpu->sys.p->n, pairs / per);
        }
    } else if (!be) {
        printf(" backend=none gpu_why=\"%s\"", why);
    }
    /* 3. the CPU on all threads, then on one */
    if (st == CONSPH_OK && cpu_steps > 0) {
        const double per = steps(cpu, cpu_steps, &st) / (double)cpu_steps;
        printf(" threads=%d cpu_step_s=%.6g cpu_us_per_particle_step=%.6g cpu_pairs_per_s=%.4g",
               threads_max, per, per * 1e6 / (double)cpu->sys.p->n, pairs / per);
    }
    if (st == CONSPH_OK && serial_steps > 0) {
        consph_set_num_threads(1);
        const double per = steps(cpu, serial_steps, &st) / (double)serial_steps;
        printf(" serial_step_s=%.6g serial_us_per_particle_step=%.6g serial_pairs_per_s=%.4g", per,
               per * 1e6 / (double)cpu->sys.p->n, pairs / per);
    }
    (void)cpu_first;
    printf("\n");
    if (st != CONSPH_OK) fprintf(stderr, "bench_gpu: %s\n", consph_last_error());
    consph_solver_free(cpu);
    consph_solver_free(gpu);
    return st == CONSPH_OK ? 0 : 1;
}
