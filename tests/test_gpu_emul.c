/* The GPU solver's per-particle functions (src/gpu/dev.h), run by the host emulation backend
 * exactly as the CUDA kernels run them (one call per particle or cell, the scatter in reverse
 * order so that the per-cell sort must restore the stable order), against the CPU solver: edac
 * on the 2D Taylor-Green vortex and the 3D Beltrami flow, every particle array (positions and
 * every field, the start-of-step copies and gradients included) and the particles' origins bit
 * for bit after one step and after 20, with the gradients every step and as consph_run skips
 * them (grads_lazy, the state copied back only at the log samples and the end). Then the
 * refusals: schemes not ported, and a build without CUDA. */
#include <string.h>

#include "check.h"
#include "consph/gpu.h"
#include "consph/solver.h"
#include "gpu/gpu_internal.h"
#include "solver/solver_internal.h"

static consph_solver *make(const char *problem, int nx, int steps, int lazy)
{
    consph_run_params p;
    consph_run_params_default(&p);
    CHECK(consph_run_params_problem(&p, problem) == CONSPH_OK, "problem %s", problem);
    snprintf(p.scheme, sizeof p.scheme, "edac");
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
}

static void compare(const char *problem, int nx, int lazy)
{
    enum { STEPS = 20 };
    consph_solver *cpu = make(problem, nx, STEPS, lazy), *emu = make(problem, nx, STEPS, lazy);
    if (!cpu || !emu) goto done;
    int st = gpu_attach(emu, &gpu_emulation);
    CHECK(st == CONSPH_OK, "attach: %s", consph_last_error());
    if (st != CONSPH_OK) goto done;
    char what[96];
    for (int k = 1; k <= STEPS; ++k) {
        int a = consph_solver_step(cpu), b = consph_solver_step(emu);
        CHECK(a == CONSPH_OK && b == CONSPH_OK, "%s step %d: %s", problem, k, consph_last_error());
        if (a != CONSPH_OK || b != CONSPH_OK) break;
        if ((!lazy && (k == 1 || k == STEPS)) || (lazy && (k % 7 == 0 || k == STEPS))) {
            snprintf(what, sizeof what, "%s nx %d%s after step %d", problem, nx,
                     lazy ? " (lazy gradients)" : "", k);
            same_state(cpu, emu, what);
        }
    }
    /* the diagnostics sampled from the copied-back state: the same log */
    CHECK(cpu->nhist == emu->nhist &&
              memcmp(cpu->hist, emu->hist, cpu->nhist * HIST_COLS * sizeof(double)) == 0,
          "%s: the logged diagnostics differ", problem);
    /* back to the host: the state stays, and the CPU steps on from it */
    CHECK(consph_solver_set_device(emu, CONSPH_DEVICE_CPU) == CONSPH_OK, "to the CPU: %s",
          consph_last_error());
    CHECK(emu->gpu == NULL, "still on the device");
done:
    consph_solver_free(cpu);
    consph_solver_free(emu);
}

static void refusals(void)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "wcsph");
    CHECK(consph_gpu_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "edac"),
          "wcsph on the GPU: %s", consph_last_error());
    snprintf(p.scheme, sizeof p.scheme, "edac");
    p.skin = 0.2;
    CHECK(consph_gpu_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "--skin"),
          "a skin on the GPU: %s", consph_last_error());
#ifndef CONSPH_HAVE_CUDA
    char why[256];
    CHECK(!consph_gpu_available(why, sizeof why) && strstr(why, "without GPU support"), "%s", why);
    p.skin = 0.0;
    CHECK(consph_gpu_check(&p) == CONSPH_EINVAL &&
              strstr(consph_last_error(), "without GPU support"),
          "%s", consph_last_error());
    p.nx = 8;
    p.steps = 1;
    p.tf = 0.0;
    consph_solver *s = NULL;
    if (consph_solver_create(&s, &p) == CONSPH_OK) {
        CHECK(consph_solver_set_device(s, CONSPH_DEVICE_GPU) == CONSPH_EINVAL, "no GPU build");
        CHECK(s->gpu == NULL, "attached without a GPU");
        CHECK(consph_solver_step(s) == CONSPH_OK, "the CPU steps on: %s", consph_last_error());
    }
    consph_solver_free(s);
#endif
}

int main(void)
{
    compare("taylor-green", 20, 0);
    compare("taylor-green", 20, 1);
    compare("beltrami", 10, 0);
    refusals();
    return check_summary("test_gpu_emul");
}
