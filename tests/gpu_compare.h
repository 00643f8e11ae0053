/* Shared by the GPU tests (test_gpu_emul: the host emulation; test_gpu_cuda: the CUDA backend):
 * edac stepped by a GPU backend against the CPU solver, every particle array bit for bit. */
#ifndef CONSPH_TESTS_GPU_COMPARE_H
#define CONSPH_TESTS_GPU_COMPARE_H

#include <string.h>

#include "check.h"
#include "consph/gpu.h"
#include "consph/solver.h"
#include "gpu/gpu_internal.h"
#include "solver/solver_internal.h"

static consph_solver *make(const char *scheme, const char *problem, int nx, int steps, int lazy)
{
    consph_run_params p;
    consph_run_params_default(&p);
    CHECK(consph_run_params_problem(&p, problem) == CONSPH_OK, "problem %s", problem);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = nx;
    p.steps = steps;
    p.tf = 0.0;
    p.log_every = 7;
    consph_solver *s = NULL;
    const int st = consph_solver_create(&s, &p);
    CHECK(st == CONSPH_OK, "create %s: %s", problem, consph_last_error());
    if (s && lazy) s->grads_lazy = 1; /* as consph_run without snapshots */
    return s;
}

/* Every array of the particles bit for bit, and the origins. */
static void same_state(const consph_solver *a, const consph_solver *b, const char *what)
{
    const consph_particles *p = a->sys.p, *q = b->sys.p;
    CHECK(p->n == q->n && p->nfields == q->nfields, "%s: particle sets differ in shape", what);
    if (p->n != q->n || p->nfields != q->nfields) return;
    size_t differ = 0, values = 0;
    char first[128] = "";
    for (int k = -1; k < p->nfields; ++k) {
        const int nc = k < 0 ? p->dim : p->fields[k].ncomp;
        for (int c = 0; c < nc; ++c) {
            const double *x = k < 0 ? p->x[c] : p->fields[k].data + (size_t)c * p->cap;
            const double *y = k < 0 ? q->x[c] : q->fields[k].data + (size_t)c * q->cap;
            for (size_t i = 0; i < p->n; ++i, ++values)
                if (memcmp(&x[i], &y[i], sizeof(double)) != 0) {
                    if (!differ++)
                        snprintf(first, sizeof first, "%s[%d] of particle %zu: %.17g vs %.17g",
                                 k < 0 ? "x" : p->fields[k].name, c, i, x[i], y[i]);
                }
        }
    }
    CHECK(differ == 0, "%s: %zu of %zu values differ, first %s", what, differ, values, first);
    size_t orig = 0;
    for (size_t i = 0; i < p->n; ++i) orig += a->sys.origin[i] != b->sys.origin[i];
    CHECK(orig == 0, "%s: %zu particles have other origins", what, orig);
    CHECK(a->step == b->step && a->t == b->t, "%s: step %ld t %.17g vs step %ld t %.17g", what,
          a->step, a->t, b->step, b->t);
    /* the pair evaluations of the counted passes (the GPU's counted on the device) */
    CHECK(a->pairs == b->pairs && a->pairs > 0, "%s: %zu pairs vs %zu", what, a->pairs, b->pairs);
}

static void gpu_compare(const gpu_backend *be, const char *scheme, const char *problem, int nx,
                        int lazy)
{
    enum { STEPS = 20 };
    char what[128];
    /* one step more than the GPU runs: the last on the CPU, from the state copied back */
    consph_solver *cpu = make(scheme, problem, nx, STEPS + 1, lazy),
                  *emu = make(scheme, problem, nx, STEPS + 1, lazy);
    if (!cpu || !emu) goto done;
    int st = gpu_attach(emu, be);
    CHECK(st == CONSPH_OK, "attach: %s", consph_last_error());
    if (st != CONSPH_OK) goto done;
    for (int k = 1; k <= STEPS; ++k) {
        int a = consph_solver_step(cpu), b = consph_solver_step(emu);
        CHECK(a == CONSPH_OK && b == CONSPH_OK, "%s %s step %d: %s", scheme, problem, k,
              consph_last_error());
        if (a != CONSPH_OK || b != CONSPH_OK) break;
        /* lazily, the state is on the host at the log samples only (log_every 7) */
        if ((!lazy && (k == 1 || k == STEPS)) || (lazy && k % 7 == 0)) {
            /* a log sample copies back only what the host reads there: every array first */
            if (lazy) CHECK(gpu_download(emu) == CONSPH_OK, "copy back: %s", consph_last_error());
            snprintf(what, sizeof what, "%s: %s %s nx %d%s after step %d", be->name, scheme,
                     problem, nx, lazy ? " (lazy gradients)" : "", k);
            same_state(cpu, emu, what);
        }
    }
    /* the same regularisations (IPST's shifts of L-IPST-C), the same χ_o */
    CHECK(cpu->regs == emu->regs && cpu->prm.ipst_chi0 == emu->prm.ipst_chi0,
          "%s %s: %ld regularisations, χ_o %.17g vs %ld, %.17g", scheme, problem, (long)cpu->regs,
          cpu->prm.ipst_chi0, (long)emu->regs, emu->prm.ipst_chi0);
    /* the diagnostics sampled from the copied-back state: the same log */
    CHECK(cpu->nhist == emu->nhist &&
              memcmp(cpu->hist, emu->hist, cpu->nhist * HIST_COLS * sizeof(double)) == 0,
          "%s %s: the logged diagnostics differ", scheme, problem);
    /* back to the host: the state comes back, and the CPU steps on from it */
    CHECK(consph_solver_set_device(emu, CONSPH_DEVICE_CPU) == CONSPH_OK, "to the CPU: %s",
          consph_last_error());
    CHECK(emu->gpu == NULL, "still on the device");
    snprintf(what, sizeof what, "%s: %s %s nx %d%s back on the host", be->name, scheme, problem, nx,
             lazy ? " (lazy gradients)" : "");
    same_state(cpu, emu, what);
    CHECK(consph_solver_step(cpu) == CONSPH_OK && consph_solver_step(emu) == CONSPH_OK,
          "the step after: %s", consph_last_error());
    snprintf(what, sizeof what, "%s: %s %s nx %d%s, a CPU step after the GPU's", be->name, scheme,
             problem, nx, lazy ? " (lazy gradients)" : "");
    same_state(cpu, emu, what);
done:
    consph_solver_free(cpu);
    consph_solver_free(emu);
}

/* Two runs on the backend, stepped alike: bit for bit (no order-dependent atomics in any sum). */
static void gpu_twice(const gpu_backend *be, const char *scheme, const char *problem, int nx,
                      int steps)
{
    consph_solver *a = make(scheme, problem, nx, steps, 1),
                  *b = make(scheme, problem, nx, steps, 1);
    int st = a && b ? gpu_attach(a, be) : CONSPH_EINVAL;
    if (st == CONSPH_OK) st = gpu_attach(b, be);
    CHECK(st == CONSPH_OK, "attach: %s", consph_last_error());
    for (int k = 0; st == CONSPH_OK && k < steps; ++k) {
        st = consph_solver_step(a);
        if (st == CONSPH_OK) st = consph_solver_step(b);
    }
    CHECK(st == CONSPH_OK, "steps: %s", consph_last_error());
    char what[128];
    snprintf(what, sizeof what, "%s: two runs of %s %s nx %d", be->name, scheme, problem, nx);
    if (st == CONSPH_OK) same_state(a, b, what);
    consph_solver_free(a);
    consph_solver_free(b);
}

#endif
