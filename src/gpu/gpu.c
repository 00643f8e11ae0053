/* The GPU solver's host side: what runs where (docs/gpu.md), the step as a sequence of launches
 * of dev.h's per-particle functions, the copies between the solver's particles and the device,
 * and the host emulation backend that make check runs. */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/gpu.h"
#include "gpu/gpu_internal.h"
#include "solver/solver_internal.h"

struct gpu_run {
    const gpu_backend *be;
    gpu_view v;       /* device pointers */
    int nfields;      /* the particles' field count at the attach (checked at each copy) */
    double *dev_a[2]; /* the two blocks of arrays (v.a, v.b swap at each re-sort) */
    size_t bytes;     /* device memory allocated */
};

/* ---- the emulation backend ---- */

static int emu_alloc(void **p, size_t bytes)
{
    *p = malloc(bytes ? bytes : 1);
    if (*p) memset(*p, 0xff, bytes); /* poisoned, as fresh device memory may hold anything */
    return *p ? 0 : 1;
}
static void emu_release(void *p)
{
    free(p);
}
static int emu_copy(void *dst, const void *src, size_t bytes)
{
    if (bytes) memcpy(dst, src, bytes);
    return 0;
}
static int emu_zero(void *dst, size_t bytes)
{
    if (bytes) memset(dst, 0, bytes);
    return 0;
}
static int emu_launch(gpu_kernel k, size_t count, const gpu_view *v, double c)
{
    switch (k) {
    case GK_BIN:
        for (size_t i = 0; i < count; ++i) dev_bin(v, i);
        break;
    case GK_COUNT:
        for (size_t i = 0; i < count; ++i) dev_count(v, i);
        break;
    case GK_SCATTER:
        for (size_t i = count; i-- > 0;) dev_scatter(v, i);
        break;
    case GK_CELL_SORT:
        for (size_t i = 0; i < count; ++i) dev_cell_sort(v, i);
        break;
    case GK_SLOTS:
        for (size_t i = 0; i < count; ++i) dev_slots(v, i);
        break;
    case GK_PERMUTE:
        for (size_t i = 0; i < count; ++i) dev_permute(v, i);
        break;
    case GK_SAVE:
        for (size_t i = 0; i < count; ++i) dev_save_start(v, i);
        break;
    case GK_ADVANCE:
        for (size_t i = 0; i < count; ++i) dev_advance(v, i, c);
        break;
    case GK_DENSITY:
        for (size_t i = 0; i < count; ++i) dev_pre_rates(v, i);
        break;
    case GK_RATES:
        for (size_t i = 0; i < count; ++i) dev_rates(v, i);
        break;
    }
    return 0;
}
static int emu_scan(const gpu_view *v)
{
    uint32_t run = 0;
    for (size_t c = 0; c <= v->g.ncells; ++c) {
        const uint32_t k = v->count[c];
        v->start[c] = run;
        run += k;
    }
    return 0;
}
static const char *emu_error(void)
{
    return "host emulation: out of memory";
}

const gpu_backend gpu_emulation = {"host emulation", emu_alloc,  emu_release, emu_copy, emu_copy,
                                   emu_zero,         emu_launch, emu_scan,    emu_error};

#ifndef CONSPH_HAVE_CUDA
const gpu_backend *gpu_cuda_backend(char *why, size_t len)
{
    snprintf(why, len,
             "this consph was built without GPU support (CUDA: configure with nvcc on the PATH "
             "and -DCONSPH_CUDA=ON)");
    return NULL;
}
#endif

/* ---- what the GPU runs ---- */

/* The CUDA backend; CONSPH_GPU_BACKEND=emulation in the environment puts the host emulation in
 * its place, so that the CLI's GPU path (lazy copies, snapshots, checkpoints) is tested end to end
 * on machines without a GPU (tests/cli_gpu.sh). */
static const gpu_backend *find_backend(char *why, size_t len)
{
    const char *e = getenv("CONSPH_GPU_BACKEND");
    if (e && strcmp(e, "emulation") == 0) return &gpu_emulation;
    return gpu_cuda_backend(why, len);
}

const char *consph_gpu_schemes(void)
{
    return "edac,wcsph";
}

int consph_gpu_available(char *why, size_t len)
{
    char buf[256];
    const gpu_backend *be = find_backend(buf, sizeof buf);
    if (why && len) snprintf(why, len, "%s", be ? "" : buf);
    return be != NULL;
}

static int check_params(const consph_run_params *prm)
{
    if (strcmp(prm->scheme, "edac") != 0 && strcmp(prm->scheme, "wcsph") != 0)
        return consph_fail(CONSPH_EINVAL,
                           "--device gpu: scheme '%s' does not run on the GPU yet (allowed: %s)",
                           prm->scheme, consph_gpu_schemes());
    if (prm->integrator[0] && strcmp(prm->integrator, "pec") != 0)
        return consph_fail(CONSPH_EINVAL,
                           "--device gpu: integrator '%s' does not run on the GPU yet (allowed: "
                           "pec, the default of edac and wcsph)",
                           prm->integrator);
    /* wcsph's Tait EOS and sound speed by multiplication (solver_eos's γ = 7 loop) */
    if (strcmp(prm->scheme, "wcsph") == 0 && prm->eos != CONSPH_EOS_LINEAR && prm->gamma != 7.0)
        return consph_fail(CONSPH_EINVAL,
                           "--device gpu: wcsph's Tait EOS runs on the GPU with γ = 7 only, not %g",
                           prm->gamma);
    if (prm->kernel != CONSPH_KERNEL_QUINTIC)
        return consph_fail(CONSPH_EINVAL,
                           "--device gpu: only the quintic kernel runs on the GPU yet (--kernel "
                           "quintic)");
    if (prm->skin != 0.0)
        return consph_fail(CONSPH_EINVAL,
                           "--device gpu: --skin must be 0 (the GPU rebuilds its cell lists "
                           "every step), not %g",
                           prm->skin);
    return CONSPH_OK;
}

int consph_gpu_check(const consph_run_params *prm)
{
    int st = check_params(prm);
    if (st != CONSPH_OK) return st;
    char why[256];
    if (!consph_gpu_available(why, sizeof why))
        return consph_fail(CONSPH_EINVAL, "--device gpu: %s", why);
    return CONSPH_OK;
}

/* The solver's own checks beyond the parameters (a restarted run's parameters come from its
 * checkpoint). */
static int check_solver(consph_solver *s)
{
    int st = check_params(&s->prm);
    if (st != CONSPH_OK) return st;
    if (!s->reuse_rates || s->sys.dest || s->sys.kernel.tensor || !s->sys.p)
        return consph_fail(CONSPH_EINVAL, "--device gpu: this run's set-up does not run there");
    return CONSPH_OK;
}

/* ---- the grid (src/nnps/nnps.c's setup_grid, for a search made with cells_per_radius 0) ---- */

static int cells_per_radius(int dim, double mean)
{
    if (dim == 1) return 4;
    if (dim == 2) return mean < 75.0 ? 1 : mean < 150.0 ? 2 : 3;
    return mean < 150.0 ? 1 : mean < 700.0 ? 2 : 3;
}

static void grid_setup(gpu_grid *g, const consph_box *box, int dim, double radius, size_t n)
{
    memset(g, 0, sizeof *g);
    g->dim = dim;
    g->radius2 = radius * radius;
    double slack[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < 3; ++a) {
        g->nc[a] = 1;
        g->len[a] = g->inv_h[a] = 1.0;
    }
    for (int a = 0; a < dim; ++a) {
        g->periodic[a] = box->periodic[a] != 0;
        g->lo[a] = box->lo[a];
        g->hi[a] = box->hi[a];
        g->len[a] = box->hi[a] - box->lo[a];
        slack[a] =
            64.0 * DBL_EPSILON * (fmax(fabs(box->lo[a]), fabs(box->hi[a])) + g->len[a] + radius);
    }
    const double pi = 3.14159265358979323846;
    const double unit_ball[4] = {0.0, 2.0, pi, 4.0 * pi / 3.0};
    double volume = 1.0, v[3] = {1.0, 1.0, 1.0};
    for (int a = 0; a < dim; ++a) volume *= g->len[a];
    const int cpr = cells_per_radius(dim, (double)n * unit_ball[dim] * pow(radius, dim) / volume);
    for (int a = 0; a < dim; ++a) {
        double want = floor(g->len[a] * cpr / radius * (1.0 - 1.0e-9));
        v[a] = fmin(fmax(want, 1.0), 1073741824.0);
    }
    const double max_cells = 4.0 * (double)n + 1024.0;
    double total = v[0] * v[1] * v[2];
    if (total > max_cells) {
        double f = pow(max_cells / total, 1.0 / dim);
        for (int a = 0; a < dim; ++a) v[a] = fmax(1.0, floor(v[a] * f));
    }
    while (v[0] * v[1] * v[2] > max_cells) {
        int big = 0;
        for (int a = 1; a < dim; ++a)
            if (v[a] > v[big]) big = a;
        v[big] = ceil(v[big] / 2.0);
    }
    g->ncells = 1;
    for (int a = 0; a < 3; ++a) {
        g->nc[a] = (int64_t)v[a];
        g->ncells *= (size_t)g->nc[a];
        if (a >= dim) continue;
        const double h = g->len[a] / v[a];
        g->h[a] = h;
        g->inv_h[a] = v[a] / g->len[a];
        double k = ceil((radius + 2.0 * slack[a]) / h);
        if (!g->periodic[a]) k = fmin(k, v[a] - 1.0);
        g->reach[a] = (int64_t)k;
    }
    const double slack_max = fmax(slack[0], fmax(slack[1], slack[2]));
    g->prune2 = (radius + 4.0 * slack_max) * (radius + 4.0 * slack_max);
}

/* ---- the copies between the solver's particles and the device ---- */

/* Host array k of the particles (x, then every field's components), and the count. */
static int host_arrays(consph_particles *p, double **arr, int max)
{
    int k = 0;
    for (int a = 0; a < p->dim; ++a) {
        if (k < max) arr[k] = p->x[a];
        ++k;
    }
    for (int f = 0; f < p->nfields; ++f)
        for (int c = 0; c < p->fields[f].ncomp; ++c) {
            if (k < max) arr[k] = p->fields[f].data + (size_t)c * p->cap;
            ++k;
        }
    return k;
}

static int be_fail(const gpu_backend *be, const char *what)
{
    return consph_fail(CONSPH_ENOMEM, "GPU (%s): %s: %s", be->name, what, be->error());
}

static int copy_arrays(consph_solver *s, int to_device)
{
    gpu_run *g = s->gpu;
    consph_particles *p = s->sys.p;
    double *arr[CONSPH_MAX_DIM + CONSPH_MAX_FIELDS * 9];
    const int narr = host_arrays(p, arr, (int)(sizeof arr / sizeof arr[0]));
    if (narr != g->v.narr || p->nfields != g->nfields || p->n != g->v.n)
        return consph_fail(CONSPH_EINVAL,
                           "GPU: the solver's particles changed since they were put on the device "
                           "(%d arrays of %zu, now %d of %zu)",
                           g->v.narr, g->v.n, narr, p->n);
    const size_t bytes = p->n * sizeof(double);
    for (int k = 0; k < narr; ++k) {
        double *dev = g->v.a + (size_t)k * p->n;
        const int rc = to_device ? g->be->put(dev, arr[k], bytes) : g->be->get(arr[k], dev, bytes);
        if (rc) return be_fail(g->be, to_device ? "copy to the device" : "copy from the device");
    }
    return CONSPH_OK;
}

int gpu_download(consph_solver *s)
{
    if (!s->gpu) return CONSPH_OK;
    int st = copy_arrays(s, 0);
    if (st != CONSPH_OK) return st;
    consph_particles *p = s->sys.p;
    const double *id = sv_field(s, SF_ID, 1);
    if (!id) return CONSPH_EINVAL;
    if (s->sys.origin)
        for (size_t i = 0; i < p->n; ++i) s->sys.origin[i] = (size_t)id[i];
    /* the host search on the positions the step left, as the CPU's drift leaves it */
    return consph_sys_update(&s->sys, 0);
}

void gpu_free(gpu_run *g)
{
    if (!g) return;
    const gpu_backend *be = g->be;
    void *bufs[] = {g->dev_a[0],  g->dev_a[1], g->v.vol,   g->v.mrho,  g->v.cs,
                    g->v.xs,      g->v.cell,   g->v.count, g->v.start, g->v.order,
                    g->v.slot_of, g->v.pack,   g->v.xp};
    for (size_t k = 0; k < sizeof bufs / sizeof bufs[0]; ++k)
        if (bufs[k]) be->release(bufs[k]);
    free(g);
}

/* The first array of a field in the block, checking its components. */
static int array_of(consph_solver *s, const char *name, int ncomp, int *at)
{
    consph_particles *p = s->sys.p;
    if (!sv_field(s, name, ncomp)) return CONSPH_EINVAL;
    int k = p->dim;
    for (int f = 0; f < p->nfields; ++f) {
        if (strcmp(p->fields[f].name, name) == 0) {
            *at = k;
            return CONSPH_OK;
        }
        k += p->fields[f].ncomp;
    }
    return consph_fail(CONSPH_EINVAL, "GPU: no field '%s'", name);
}

int gpu_attach(consph_solver *s, const gpu_backend *be)
{
    if (s->gpu) return CONSPH_OK;
    consph_particles *p = s->sys.p;
    const int d = s->dim;
    int st = check_solver(s);
    if (st != CONSPH_OK) return st;
    if (p->n >= UINT32_MAX / 2)
        return consph_fail(CONSPH_EINVAL, "GPU: %zu particles, at most %u", p->n, UINT32_MAX / 2);
    gpu_run *g = consph_calloc(1, sizeof *g);
    if (!g) return CONSPH_ENOMEM;
    g->be = be;
    gpu_view *v = &g->v;
    v->n = p->n;
    v->d = d;
    double *arr[CONSPH_MAX_DIM + CONSPH_MAX_FIELDS * 9];
    v->narr = host_arrays(p, arr, (int)(sizeof arr / sizeof arr[0]));
    g->nfields = p->nfields;
    v->at[GA_X] = 0;
    const int edac = strcmp(s->prm.scheme, "edac") == 0;
    v->scheme = edac ? GS_EDAC : GS_WCSPH;
    struct {
        int q;
        const char *name;
        int ncomp, edac_only;
    } const map[] = {{GA_U, SF_U, d, 0},       {GA_P, SF_P, 1, 0},
                     {GA_AU, SF_AU, d, 0},     {GA_AQ, SF_AQ, 1, 0},
                     {GA_AX, SF_AX, d, 0},     {GA_AUHAT, "auhat", d, 1},
                     {GA_TVDU, "tvdu", d, 1},  {GA_RHOS, "rhos", 1, 1},
                     {GA_RHOF, SF_RHOF, 1, 0}, {GA_NUMD, "numden", 1, 1},
                     {GA_PAVG, "pavg", 1, 1},  {GA_GRADP, SF_GRADP, d, 0},
                     {GA_DIVU, SF_DIVU, 1, 0}, {GA_GRADU, SF_GRADU, d * d, 0},
                     {GA_U0, SF_U0, d, 0},     {GA_Q0, SF_Q0, 1, 0},
                     {GA_X0, SF_X0, d, 0},     {GA_Q, edac ? SF_P : SF_RHOF, 1, 0}};
    /* tvdu, auhat, rhos, numden, pavg: pysph/scheme.c */
    for (int q = 1; q < GA_COUNT; ++q) v->at[q] = -1;
    for (size_t k = 0; st == CONSPH_OK && k < sizeof map / sizeof map[0]; ++k)
        if (edac || !map[k].edac_only)
            st = array_of(s, map[k].name, map[k].ncomp, &v->at[map[k].q]);
    v->av = (s->prm.alpha >= 0.0 ? s->prm.alpha : 0.1) > 0.0; /* job_fields' α */
    v->tait = s->eos == CONSPH_EOS_TAIT;
    v->rho0 = s->prm.rho0;
    v->c2 = s->c0 * s->c0;
    v->gamma = s->prm.gamma;
    v->cs_exp = eos_int_exponent(0.5 * (s->prm.gamma - 1.0));
    if (st == CONSPH_OK && !edac && v->av && v->cs_exp < 0)
        st = consph_fail(CONSPH_EINVAL, "--device gpu: wcsph's sound speed needs an odd γ, not %g",
                         s->prm.gamma);
    grid_setup(&v->g, &p->box, d, consph_nnps_radius(s->sys.nnps), p->n);
    /* dev.h's walk holds cell coordinates in 32 bits: c ± reach with c < 2^30 */
    for (int a = 0; st == CONSPH_OK && a < d; ++a)
        if (v->g.reach[a] > (1 << 29))
            st = consph_fail(CONSPH_EINVAL, "GPU: the search reaches %lld cells along axis %d",
                             (long long)v->g.reach[a], a);
    if (st == CONSPH_OK && v->g.ncells != consph_nnps_cells(s->sys.nnps))
        st = consph_fail(CONSPH_EINVAL, "GPU: %zu cells, the CPU search has %zu", v->g.ncells,
                         consph_nnps_cells(s->sys.nnps));
    const consph_kernel *kr = &s->sys.kernel;
    v->k.norm = kr->norm;
    v->k.inv_h = kr->inv_h;
    v->k.support = kr->support;
    v->k.norm1 = kr->norm * kr->inv_h;
    v->k.at_zero = kr->norm * kr->inv_h * kr->inv_h * gpu_quintic_d2f(0.0);
    /* pysph/scheme.c's job_fields */
    v->c.m = s->mass;
    v->c.minv = 1.0 / s->mass;
    v->c.h = s->h;
    v->c.h2 = 0.01 * s->h * s->h;
    v->c.c0 = s->c0;
    v->c.nu = s->nu;
    v->c.alpha = s->prm.alpha >= 0.0 ? s->prm.alpha : 0.1;
    v->c.pb = s->c0 * s->c0 * s->prm.rho0;
    v->c.nu_edac = 0.5 * s->h * s->c0 / 8.0;
    const size_t n = p->n ? p->n : 1, nd = (size_t)v->narr * n * sizeof(double);
    const size_t nc = (v->g.ncells + 1) * sizeof(uint32_t);
    s->gpu = g;
    if (st == CONSPH_OK &&
        (be->alloc((void **)&g->dev_a[0], nd) || be->alloc((void **)&g->dev_a[1], nd) ||
         be->alloc((void **)&v->vol, n * sizeof(double)) ||
         be->alloc((void **)&v->mrho, n * sizeof(double)) ||
         be->alloc((void **)&v->cs, n * sizeof(double)) ||
         be->alloc((void **)&v->xs, (size_t)d * n * sizeof(double)) ||
         be->alloc((void **)&v->xp, 4 * n * sizeof(double)) ||
         be->alloc((void **)&v->slot_of, n * sizeof(uint32_t)) ||
         be->alloc((void **)&v->pack, (size_t)(4 + 2 * d) * n * sizeof(double)) ||
         be->alloc((void **)&v->cell, n * sizeof(uint32_t)) || be->alloc((void **)&v->count, nc) ||
         be->alloc((void **)&v->start, nc) || be->alloc((void **)&v->order, n * sizeof(uint32_t))))
        st = be_fail(be, "device memory");
    v->a = g->dev_a[0];
    v->b = g->dev_a[1];
    g->bytes = 2 * nd + 3 * n * sizeof(double) + (size_t)(d + 4) * n * sizeof(double) +
               (size_t)(4 + 2 * d) * n * sizeof(double) + 3 * n * sizeof(uint32_t) + 2 * nc;
    if (st == CONSPH_OK) st = copy_arrays(s, 1);
    if (st != CONSPH_OK) {
        s->gpu = NULL;
        gpu_free(g);
    }
    return st;
}

/* ---- the step ---- */

#define LAUNCH(k, count, c)                                                                        \
    do {                                                                                           \
        if (be->launch(k, count, v, c)) return be_fail(be, #k);                                    \
    } while (0)

/* Bins the particles and sorts the slots by cell (consph_nnps_build). */
static int build_cells(gpu_run *g)
{
    const gpu_backend *be = g->be;
    const gpu_view *v = &g->v;
    const size_t nc = (v->g.ncells + 1) * sizeof(uint32_t);
    if (be->zero(v->count, nc)) return be_fail(be, "zero");
    LAUNCH(GK_BIN, v->n, 0.0);
    LAUNCH(GK_COUNT, v->n, 0.0);
    if (be->scan(v)) return be_fail(be, "scan");
    if (be->zero(v->count, nc)) return be_fail(be, "zero");
    LAUNCH(GK_SCATTER, v->n, 0.0);
    LAUNCH(GK_CELL_SORT, v->g.ncells, 0.0);
    return CONSPH_OK;
}

/* edac or wcsph under pec, as consph_solver_step runs it on the CPU: re-sort into cell order,
 * save the start, advance by Δt/2 with the previous step's rates, rebuild the search, the
 * scheme's passes (edac: density, then rates; wcsph: per-particle values, then rates), advance
 * by Δt. */
static int step_pec(gpu_run *g, double dt, int grads)
{
    const gpu_backend *be = g->be;
    gpu_view *v = &g->v;
    int st = build_cells(g);
    if (st != CONSPH_OK) return st;
    LAUNCH(GK_PERMUTE, v->n, 0.0);
    double *t = v->a;
    v->a = v->b;
    v->b = t;
    LAUNCH(GK_SAVE, v->n, 0.0);
    LAUNCH(GK_ADVANCE, v->n, 0.5 * dt);
    if ((st = build_cells(g)) != CONSPH_OK) return st;
    LAUNCH(GK_SLOTS, v->n, 0.0);
    v->grads = grads;
    LAUNCH(GK_DENSITY, v->n, 0.0);
    LAUNCH(GK_RATES, v->n, 0.0);
    LAUNCH(GK_ADVANCE, v->n, dt);
    return CONSPH_OK;
}

int gpu_step(consph_solver *s, double dt, int *synced)
{
    *synced = 0;
    int st = step_pec(s->gpu, dt, !s->grads_skip);
    if (st != CONSPH_OK) return st;
    /* what the host reads after this step: the log sample, a snapshot's gradients, the end */
    if (!s->grads_skip || (s->step + 1) % s->prm.log_every == 0 ||
        s->prm.error == CONSPH_ERROR_AUTHORS) {
        st = gpu_download(s);
        *synced = st == CONSPH_OK;
    }
    return st;
}

int consph_solver_set_device(consph_solver *s, consph_device device)
{
    if (device == CONSPH_DEVICE_CPU) {
        if (!s->gpu) return CONSPH_OK;
        const int st = gpu_download(s);
        gpu_free(s->gpu);
        s->gpu = NULL;
        return st;
    }
    if (device != CONSPH_DEVICE_GPU)
        return consph_fail(CONSPH_EINVAL, "device %d is neither the CPU nor the GPU", (int)device);
    char why[256];
    const gpu_backend *be = find_backend(why, sizeof why);
    if (!be) return consph_fail(CONSPH_EINVAL, "--device gpu: %s", why);
    return gpu_attach(s, be);
}

size_t gpu_device_bytes(const consph_solver *s)
{
    return s->gpu ? s->gpu->bytes : 0;
}
