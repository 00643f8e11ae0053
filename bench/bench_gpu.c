/* The GPU solver against the CPU solver on one case (bench/gpu.sh runs it per size): two solvers
 * set up alike (--scheme, edac by default; the set-up on --setup-threads), then
 *   1. one step each, the GPU's (or the host emulation's, --emulate) against the CPU's on
 *      --threads-max threads: values differing and the largest relative difference, and
 *      whether the pair counts agree;
 *   2. --gpu-steps steps on the GPU, timed to the copy back that ends them, less that copy;
 *   2b. with --stages S, S more steps with each launch, prefix sum, zeroing and copy between
 *      two timer marks (src/gpu/stages.h: CUDA events): stage_<name>_ms, per step, and
 *      stage_wall_ms, the steps' time with the marks (part 2's steps run without them);
 *   3. --cpu-steps steps on --threads-max threads, then --serial-steps on one thread.
 * With --blocks B1,B2,... parts 1 and 2 run once per pair-pass block size (a fresh GPU solver
 * each, CONSPH_GPU_BLOCK_PAIR=B set for the CUDA backend), one line each, the CPU's step 1
 * computed once. Every solver runs as consph run does without snapshots (gradients only where
 * read, no log samples in between). One line of key=value on stdout; a part whose step count is
 * 0 is skipped.
 *
 *   bench_gpu --problem taylor-green --nx 1000 [--scheme edac] [--gpu-steps 20] [--cpu-steps 3]
 *             [--serial-steps 1] [--threads-max 16] [--setup-threads 16] [--emulate]
 *             [--stages S] [--blocks 64,128,256] [--layout scheme|lattice]
 * --layout lattice starts from the lattice whatever the scheme's layout (l-ipst-c's packed start
 * takes minutes to pack at 10^7 particles; for a speed measurement the lattice serves). */
#define _POSIX_C_SOURCE 200809L /* setenv */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/gpu.h"
#include "consph/solver.h"
#include "gpu/gpu_internal.h"
#include "gpu/stages.h"
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

/* Parts 1, 2 and 2b on a fresh GPU solver: its step 1 against the CPU's (cpu, one step done),
 * then the timed steps. */
static int gpu_part(const gpu_backend *be, const consph_solver *cpu, const char *scheme,
                    const char *problem, int nx, int layout, long gpu_steps, long stage_steps,
                    double pairs, int setup_threads, int threads_max)
{
    consph_set_num_threads(setup_threads);
    consph_solver *gpu = make(scheme, problem, nx, layout);
    consph_set_num_threads(threads_max);
    if (!gpu) {
        fprintf(stderr, "bench_gpu: set-up: %s\n", consph_last_error());
        return CONSPH_EINVAL;
    }
    double t0 = consph_wtime();
    int st = gpu_attach(gpu, be);
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
        printf(" step1_differing=%zu step1_values=%zu step1_maxrel=%.3e", differ, values, maxrel);
        /* the pair evaluations counted on the device, against the CPU's */
        printf(" step1_pairs_equal=%d", gpu->pairs == cpu->pairs);
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
    /* 2b. the same steps with each stage between two marks (summed before the copy back) */
    if (st == CONSPH_OK && stage_steps > 0) {
        double ms[GST_N];
        long calls[GST_N];
        gpu_stages_collect(ms, calls); /* forgets anything marked before */
        gpu_stages_enable(1);
        t0 = consph_wtime();
        steps(gpu, stage_steps, &st);
        const int missed = gpu_stages_collect(ms, calls);
        const double wall = consph_wtime() - t0;
        gpu_stages_enable(0);
        double sum = 0.0;
        printf(" stage_steps=%ld", stage_steps);
        for (int k = 0; k < GST_N; ++k) {
            sum += ms[k];
            if (calls[k])
                printf(" stage_%s_ms=%.5g stage_%s_calls=%.3g", gpu_stage_names[k],
                       ms[k] / (double)stage_steps, gpu_stage_names[k],
                       (double)calls[k] / (double)stage_steps);
        }
        printf(" stage_sum_ms=%.5g stage_wall_ms=%.5g%s", sum / (double)stage_steps,
               1e3 * wall / (double)stage_steps, missed ? " stage_missed=1" : "");
    }
    if (st != CONSPH_OK) fprintf(stderr, "bench_gpu: %s\n", consph_last_error());
    consph_solver_free(gpu);
    return st;
}

int main(int argc, char **argv)
{
    const char *problem = "taylor-green", *scheme = "edac", *blocks = NULL;
    int nx = 100, emulate = 0, threads_max = 16, setup_threads = 16, layout = -1;
    long gpu_steps = 20, cpu_steps = 3, serial_steps = 1, stage_steps = 0;
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
        else if (!strcmp(o, "--stages"))
            stage_steps = atol(v);
        else if (!strcmp(o, "--blocks"))
            blocks = v;
        else if (!strcmp(o, "--layout") && (!strcmp(v, "scheme") || !strcmp(v, "lattice")))
            layout = !strcmp(v, "lattice") ? CONSPH_LAYOUT_LATTICE : -1;
        else {
            fprintf(
                stderr,
                "bench_gpu: unknown option %s (allowed: --problem, --scheme, --nx, --gpu-steps, "
                "--cpu-steps, --serial-steps, --threads-max, --setup-threads, --stages, --blocks, "
                "--emulate, --layout scheme|lattice)\n",
                o);
            return 2;
        }
    }
    if (blocks && strspn(blocks, "0123456789,") != strlen(blocks)) {
        fprintf(stderr, "bench_gpu: --blocks %s: a comma-separated list of block sizes\n", blocks);
        return 2;
    }
    char why[256] = "";
    const gpu_backend *be = emulate ? &gpu_emulation : gpu_cuda_backend(why, sizeof why);
    if (be && stage_steps > 0) {
        const gpu_timer *timer = emulate ? &gpu_host_timer : gpu_cuda_timer();
        if (timer) be = gpu_stages_wrap(be, timer);
    }
    consph_set_num_threads(setup_threads);
    double t0 = consph_wtime();
    consph_solver *cpu = make(scheme, problem, nx, layout);
    const double setup = consph_wtime() - t0;
    if (!cpu) {
        fprintf(stderr, "bench_gpu: set-up: %s\n", consph_last_error());
        return 1;
    }
    int st = CONSPH_OK;
    char prefix[512];
    snprintf(prefix, sizeof prefix, "scheme=%s problem=%s dim=%d n=%zu setup_s=%.3f layout=%s",
             scheme, problem, cpu->dim, cpu->sys.p->n, setup,
             layout == CONSPH_LAYOUT_LATTICE ? "lattice" : "scheme");
    /* 1. one step each */
    consph_set_num_threads(threads_max);
    size_t before = cpu->pairs;
    steps(cpu, 1, &st);
    double pairs = (double)(cpu->pairs - before);
    double per_pass = pairs / (double)cpu->passes;
    if (strcmp(scheme, "l-ipst-c") == 0) {
        /* rk2's two evaluations of three counted passes (the volumes, the kit's two), and after
         * step 1 IPST's gradients (two more); a step's pairs: the six of the evaluations (IPST's
         * own passes, every ipst_every steps, uncounted) */
        per_pass = pairs / 8.0;
        pairs = 6.0 * per_pass;
    } else if (strncmp(scheme, "delta-", 6) == 0) {
        /* rk2's two evaluations of two counted passes (L_i and ⟨∇ρ⟩^L, the rates); δ+-SPH's
         * shift (a third pass over the same neighbours) uncounted */
        per_pass = pairs / 4.0;
        pairs = (strcmp(scheme, "delta-sph") == 0 ? 4.0 : 6.0) * per_pass;
    }
    char pairs_text[128];
    snprintf(pairs_text, sizeof pairs_text, " pairs_per_step=%.0f pairs_per_particle=%.2f",
             pairs, /* per pass */
             per_pass / (double)cpu->sys.p->n);
    printf("%s%s", prefix, pairs_text);
    if (be && st == CONSPH_OK) {
        if (!blocks) {
            st = gpu_part(be, cpu, scheme, problem, nx, layout, gpu_steps, stage_steps, pairs,
                          setup_threads, threads_max);
        } else {
            /* a block size that fails (too many registers for it) is reported, and the sweep
             * goes on */
            int first = 1, failed = 0;
            for (const char *b = blocks; *b;) {
                const size_t len = strcspn(b, ",");
                char val[16];
                snprintf(val, sizeof val, "%.*s", (int)(len < 15 ? len : 15), b);
                b += len + (b[len] == ',');
                if (!*val) continue;
                if (!first) printf("\n%s%s", prefix, pairs_text);
                first = 0;
                printf(" block=%s", val);
                fflush(stdout);
                setenv("CONSPH_GPU_BLOCK_PAIR", val, 1);
                if (gpu_part(be, cpu, scheme, problem, nx, layout, gpu_steps, stage_steps, pairs,
                             setup_threads, threads_max) != CONSPH_OK) {
                    printf(" block_failed=1");
                    failed = 1;
                }
            }
            if (failed) st = CONSPH_EINVAL;
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
    printf("\n");
    if (st != CONSPH_OK) fprintf(stderr, "bench_gpu: %s\n", consph_last_error());
    consph_solver_free(cpu);
    return st == CONSPH_OK ? 0 : 1;
}
