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
#include "regularise/regularise.h"
#include "solver/solver_internal.h"

struct gpu_run {
    const gpu_backend *be;
    gpu_view v;       /* device pointers */
    int nfields;      /* the particles' field count at the attach (checked at each copy) */
    double *dev_a[2]; /* the two blocks of arrays (v.a, v.b swap at each re-sort) */
    size_t bytes;     /* device memory allocated */
    int built;        /* the cell lists of particles that do not move are built */
    /* L-RR-C: the search of reg_remesh_m4's joint system (lattice points and particles, the M4
     * kernel's reach): its grid, and the particles' cell lists and slots in it */
    gpu_grid joint_grid;
    uint32_t *jcell, *jcount, *jstart, *jorder;
    long downloads;       /* copies of the state back to the host (gpu_download_count) */
    long long down_bytes; /* the bytes those copies moved (gpu_download_bytes) */

    /* the pair count: the solver's pairs at the attach (the device counts the rest), and
     * dev_pair_sum's threads and their sums, copied back */
    size_t pairs_base, nchunks;
    unsigned long long *chunks_host;
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
    case GK_KDK_DRIFT:
        for (size_t i = 0; i < count; ++i) dev_kdk_drift(v, i, c);
        break;
    case GK_KDK_KICK:
        for (size_t i = 0; i < count; ++i) dev_kdk_kick(v, i, c);
        break;
    case GK_PAIR_SUM:
        for (size_t i = 0; i < count; ++i) dev_pair_sum(v, i);
        break;
    case GK_DENSITY:
        for (size_t i = 0; i < count; ++i) dev_pre_rates(v, i);
        break;
    case GK_RATES:
        for (size_t i = 0; i < count; ++i) dev_rates(v, i);
        break;
    case GK_NEGI_VOLUMES:
        for (size_t i = 0; i < count; ++i) dev_negi_volumes(v, i);
        break;
    case GK_NEGI_FIRST:
        for (size_t i = 0; i < count; ++i) dev_negi_first_any(v, i);
        break;
    case GK_NEGI_COUPLED:
        for (size_t i = 0; i < count; ++i) dev_negi_coupled_any(v, i);
        break;
    case GK_NEGI_KORZ:
        for (size_t i = 0; i < count; ++i) dev_negi_korzilius_any(v, i);
        break;
    case GK_NEGI_FATEHI:
        for (size_t i = 0; i < count; ++i) dev_negi_fatehi_any(v, i);
        break;
    case GK_NEGI_CLEARY:
        for (size_t i = 0; i < count; ++i) dev_negi_cleary_any(v, i);
        break;
    case GK_NEGI_RATES:
        for (size_t i = 0; i < count; ++i) dev_negi_rates(v, i);
        break;
    case GK_IPST_VOLUMES:
        for (size_t i = 0; i < count; ++i) dev_ipst_volumes(v, i);
        break;
    case GK_CHI_MAX:
        for (size_t i = 0; i < count; ++i) dev_chi_max(v, i);
        break;
    case GK_IPST_SHIFT:
        for (size_t i = 0; i < count; ++i) dev_ipst_shift_any(v, i);
        break;
    case GK_IPST_MOVE:
        for (size_t i = 0; i < count; ++i) dev_ipst_move(v, i);
        break;
    case GK_PST_SHIFT:
        for (size_t i = 0; i < count; ++i) dev_pst_shift_any(v, i, c);
        break;
    case GK_SHIFT_END:
        for (size_t i = 0; i < count; ++i) dev_shift_end(v, i, c != 0.0);
        break;
    case GK_REMESH:
        for (size_t i = 0; i < count; ++i) dev_remesh_any(v, i);
        break;
    case GK_REMESH_END:
        for (size_t i = 0; i < count; ++i) dev_remesh_end(v, i);
        break;
    case GK_DELTA_VOLUMES:
        for (size_t i = 0; i < count; ++i) dev_delta_volumes(v, i);
        break;
    case GK_DELTA_RENORM:
        for (size_t i = 0; i < count; ++i) dev_delta_renorm(v, i);
        break;
    case GK_DELTA_RATES:
        for (size_t i = 0; i < count; ++i) dev_delta_rates(v, i);
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
    return "edac,wcsph,tvf,l-ipst-c,l-ipst-f,l-ipst-k,pe-ipst-c,l-pst-c,l-rr-c,tv-c,e-c,ewcsph,"
           "delta-sph,delta-plus-sph,delta-plus-sph-d";
}

/* 001's family on the GPU (rk2, coupled_bc): L-IPST-C, L-IPST-F (Fatehi_c) and PE-IPST-C (IPST),
 * L-PST-C (Sun et al.'s shifting), L-RR-C (M4 remeshing), TV-C (its shifting velocity), E-C and
 * EWCSPH (Eulerian; EWCSPH with Cleary's Laplacian and its frozen ϱ_c). */
static int is_negi(const char *scheme)
{
    return strcmp(scheme, "l-ipst-c") == 0 || strcmp(scheme, "l-ipst-f") == 0 ||
           strcmp(scheme, "l-ipst-k") == 0 || strcmp(scheme, "pe-ipst-c") == 0 ||
           strcmp(scheme, "l-pst-c") == 0 || strcmp(scheme, "l-rr-c") == 0 ||
           strcmp(scheme, "tv-c") == 0 || strcmp(scheme, "e-c") == 0 ||
           strcmp(scheme, "ewcsph") == 0;
}

/* The δ-SPH family (rk2): δ-SPH, δ+-SPH (Sun's shifting velocity) and δ+-SPH-D. */
static int is_delta(const char *scheme)
{
    return strcmp(scheme, "delta-sph") == 0 || strcmp(scheme, "delta-plus-sph") == 0 ||
           strcmp(scheme, "delta-plus-sph-d") == 0;
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
    const int negi = is_negi(prm->scheme), rk2 = negi || is_delta(prm->scheme);
    const int tvf = strcmp(prm->scheme, "tvf") == 0;
    if (strcmp(prm->scheme, "edac") != 0 && strcmp(prm->scheme, "wcsph") != 0 && !tvf && !rk2)
        return consph_fail(CONSPH_EINVAL,
                           "--device gpu: scheme '%s' does not run on the GPU yet (allowed: %s)",
                           prm->scheme, consph_gpu_schemes());
    if (prm->integrator[0] && strcmp(prm->integrator, rk2 ? "rk2" : tvf ? "kdk" : "pec") != 0)
        return consph_fail(CONSPH_EINVAL,
                           "--device gpu: integrator '%s' does not run %s on the GPU yet "
                           "(allowed: pec, the default of edac and wcsph; kdk, tvf's; rk2, that "
                           "of 001's schemes and the δ-SPH family)",
                           prm->integrator, prm->scheme);
    /* Tait's EOS and sound speed by multiplication (solver_eos's γ = 7 loop) */
    const int tait =
        prm->eos == CONSPH_EOS_TAIT ||
        (prm->eos == CONSPH_EOS_DEFAULT &&
         (strcmp(prm->scheme, "wcsph") == 0 || strcmp(prm->scheme, "l-ipst-c") == 0 ||
          strcmp(prm->scheme, "l-ipst-f") == 0 || strcmp(prm->scheme, "l-pst-c") == 0 ||
          strcmp(prm->scheme, "l-rr-c") == 0 || strcmp(prm->scheme, "ewcsph") == 0));
    if ((rk2 || strcmp(prm->scheme, "wcsph") == 0) && tait && prm->gamma != 7.0)
        return consph_fail(CONSPH_EINVAL,
                           "--device gpu: %s's Tait EOS runs on the GPU with γ = 7 only, not %g",
                           prm->scheme, prm->gamma);
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
    /* edac, wcsph and tvf start from the rates the previous step left (pec, kdk); 001's family
     * and the δ-SPH family evaluate afresh (rk2), 001's regularisation changing the state after
     * the last evaluation */
    const int rk2 = is_negi(s->prm.scheme) || is_delta(s->prm.scheme);
    if (s->reuse_rates == rk2 || s->sys.dest || s->sys.kernel.tensor || !s->sys.p)
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

/* want[k]: whether host array k is copied (NULL: every array). */
static int copy_arrays(consph_solver *s, int to_device, const unsigned char *want)
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
        if (want && !want[k]) continue;
        if (!to_device) g->down_bytes += (long long)bytes;
        double *dev = g->v.a + (size_t)k * p->n;
        const int rc = to_device ? g->be->put(dev, arr[k], bytes) : g->be->get(arr[k], dev, bytes);
        if (rc) return be_fail(g->be, to_device ? "copy to the device" : "copy from the device");
    }
    return CONSPH_OK;
}

/* The solver's pairs: those of the set-up and of the CPU before the attach, and the device's
 * count since (dev_pair_sum's chunk sums, added here: integers, exact in any order). */
static int pairs_back(consph_solver *s)
{
    gpu_run *g = s->gpu;
    const gpu_backend *be = g->be;
    const gpu_view *v = &g->v;
    if (v->n == 0) return CONSPH_OK;
    const size_t bytes = g->nchunks * sizeof(unsigned long long);
    if (be->launch(GK_PAIR_SUM, g->nchunks, v, 0.0)) return be_fail(be, "GK_PAIR_SUM");
    if (be->get(g->chunks_host, v->pair_chunks, bytes)) return be_fail(be, "copy from the device");
    g->down_bytes += (long long)bytes;
    size_t total = 0;
    for (size_t t = 0; t < g->nchunks; ++t) total += (size_t)g->chunks_host[t];
    s->pairs = g->pairs_base + total;
    return CONSPH_OK;
}

static int copy_back(consph_solver *s, int all)
{
    if (!s->gpu) return CONSPH_OK;
    /* a sample on the host thread may still read the arrays this copy writes */
    const int joined = solver_sample_join(s);
    if (joined != CONSPH_OK) return joined;
    consph_particles *p = s->sys.p;
    unsigned char want[CONSPH_MAX_DIM + CONSPH_MAX_FIELDS * 9] = {0};
    if (!all) {
        int k = 0;
        for (int a = 0; a < p->dim; ++a) want[k++] = 1;
        for (int f = 0; f < p->nfields; ++f) {
            int read = 0;
            /* what the host reads at a log sample or an output time of the authors' measure
             * (besides the positions, which the host search reads) */
            for (size_t j = 0; solver_sample_fields[j]; ++j)
                read |= strcmp(p->fields[f].name, solver_sample_fields[j]) == 0;
            for (int c = 0; c < p->fields[f].ncomp; ++c)
                if (k < (int)sizeof want) want[k++] = (unsigned char)read;
        }
    }
    double t0 = consph_wtime();
    int st = copy_arrays(s, 0, all ? NULL : want);
    if (st == CONSPH_OK) st = pairs_back(s);
    s->sample_seconds[SAMPLE_COPY] += consph_wtime() - t0;
    if (st != CONSPH_OK) return st;
    ++s->gpu->downloads;
    const double *id = sv_field(s, SF_ID, 1);
    if (!id) return CONSPH_EINVAL;
    if (s->sys.origin)
        for (size_t i = 0; i < p->n; ++i) s->sys.origin[i] = (size_t)id[i];
    /* the host search on the positions the step left, as the CPU's drift leaves it */
    t0 = consph_wtime();
    st = consph_sys_update(&s->sys, 0);
    s->sample_seconds[SAMPLE_SEARCH] += consph_wtime() - t0;
    return st;
}

int gpu_download(consph_solver *s)
{
    return copy_back(s, 1);
}

int gpu_download_sample(consph_solver *s)
{
    return copy_back(s, 0);
}

long gpu_download_count(const consph_solver *s)
{
    return s->gpu ? s->gpu->downloads : 0;
}

long long gpu_download_bytes(const consph_solver *s)
{
    return s->gpu ? s->gpu->down_bytes : 0;
}

void gpu_free(gpu_run *g)
{
    if (!g) return;
    const gpu_backend *be = g->be;
    /* a test hook: tests/cli_gpu.sh counts the copies back of a CLI run */
    if (getenv("CONSPH_GPU_COUNT_COPIES"))
        fprintf(stderr, "GPU: %ld copies back to the host\nGPU: %lld bytes copied back\n",
                g->downloads, g->down_bytes);
    void *bufs[] = {g->dev_a[0], g->dev_a[1],   g->v.vol,     g->v.mrho,  g->v.cs,
                    g->v.cell,   g->v.count,    g->v.start,   g->v.order, g->v.step,
                    g->v.total,  g->v.chi_max,  g->jcell,     g->jcount,  g->jstart,
                    g->jorder,   g->v.bonet_ok, g->v.slot_of, g->v.pack,  g->v.xp};
    for (size_t k = 0; k < sizeof bufs / sizeof bufs[0]; ++k)
        if (bufs[k]) be->release(bufs[k]);
    if (g->v.pairs) be->release(g->v.pairs);
    if (g->v.pair_chunks) be->release(g->v.pair_chunks);
    free(g->chunks_host);
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
    const int edac = strcmp(s->prm.scheme, "edac") == 0, negi = is_negi(s->prm.scheme);
    const int tvf = strcmp(s->prm.scheme, "tvf") == 0, delta = is_delta(s->prm.scheme);
    v->scheme = edac ? GS_EDAC : tvf ? GS_TVF : negi ? GS_NEGI : delta ? GS_DELTA : GS_WCSPH;
    const int evolve_p = edac || (negi && s->scheme->evolve_p);
    const int moves = !negi || s->scheme->moves;
    v->moves = moves;
    /* who: 1 every scheme, 2 edac and tvf (pysph/scheme.c's tvdu, auhat, rhos, numden, pavg), 4
     * 001's family only (negi/scheme.c's fields), 8 the schemes that move (x0, dx/dt), 16
     * EWCSPH's ϱ_c, 32 L-RR-C's lattice */
    struct {
        int q;
        const char *name;
        int ncomp, who;
    } const map[] = {{GA_U, SF_U, d, 1},         {GA_P, SF_P, 1, 1},
                     {GA_AU, SF_AU, d, 1},       {GA_AQ, SF_AQ, 1, 1},
                     {GA_AX, SF_AX, d, 8},       {GA_AUHAT, "auhat", d, 2},
                     {GA_TVDU, "tvdu", d, 2},    {GA_RHOS, "rhos", 1, 2},
                     {GA_RHOF, SF_RHOF, 1, 1},   {GA_NUMD, "numden", 1, 2},
                     {GA_PAVG, "pavg", 1, 2},    {GA_GRADP, SF_GRADP, d, 1},
                     {GA_DIVU, SF_DIVU, 1, 1},   {GA_GRADU, SF_GRADU, d * d, 1},
                     {GA_U0, SF_U0, d, 1},       {GA_Q0, SF_Q0, 1, 1},
                     {GA_X0, SF_X0, d, 8},       {GA_Q, evolve_p ? SF_P : SF_RHOF, 1, 1},
                     {GA_VOL, SF_VOL, 1, 4},     {GA_BONET, SF_BONET, d * d, 4},
                     {GA_GRADQ, SF_GRADQ, d, 4}, {GA_LAPU, SF_LAPU, d, 4},
                     {GA_LAPQ, SF_LAPQ, 1, 4},   {GA_SHIFT, SF_SHIFT, d, 4},
                     {GA_RHOC, "rhoc", 1, 16}, /* negi/scheme.c's SF_RHOC */
                     {GA_LAT, SF_LATTICE, d, 32}};
    const int frozen = negi && ((const negi_terms *)s->scheme->terms)->frozen_rho;
    const int lattice = negi && s->scheme->needs_lattice;
    const int mine = 1 | (edac || tvf ? 2 : 0) | (negi ? 4 : 0) | (moves ? 8 : 0) |
                     (frozen ? 16 : 0) | (lattice ? 32 : 0);
    for (int q = 1; q < GA_COUNT; ++q) v->at[q] = -1;
    for (size_t k = 0; st == CONSPH_OK && k < sizeof map / sizeof map[0]; ++k)
        if (map[k].who & mine) st = array_of(s, map[k].name, map[k].ncomp, &v->at[map[k].q]);
    if (negi) {
        /* negi/scheme.c's rates: the scheme's terms, ν (Cleary's per unit mass density), D */
        const negi_terms *t = s->scheme->terms;
        v->nt = *t;
        v->evolve_p = s->scheme->evolve_p;
        v->nu = t->lap == KIT_LAP_CLEARY ? s->nu * s->prm.rho0 : s->nu;
        v->Dq = s->D;
        v->cond_max = 1e8; /* the kit_req of negi/scheme.c */
        v->ipst_h = s->h;
        v->ipst_hd = pow(s->h, d);
        /* negi/scheme.c's regularise_pst: CFL 0.5, Ma = U/c_o, R = 0.24, n = 4, no cap
         * (reg_pst_shift's constants from them) */
        const double twoh = 2.0 * s->h, wds = consph_kernel_w(&s->sys.kernel, s->ds);
        v->pst_coef = -0.5 * (s->prm.U / s->c0) * twoh * twoh;
        v->pst_inv_wds = 1.0 / wds;
        v->pst_R = 0.24;
        v->pst_cap = INFINITY;
        v->c0_over_h = s->c0 / s->h;
        /* regularise_remesh: reg_remesh_m4's kernel and joint system of 2n points */
        consph_kernel m4;
        if (st == CONSPH_OK) st = consph_kernel_init(&m4, CONSPH_KERNEL_M4, d, s->ds);
        if (st == CONSPH_OK) {
            v->m4_norm = m4.norm;
            v->m4_inv_h = m4.inv_h;
            v->m4_support = m4.support;
            grid_setup(&g->joint_grid, &p->box, d, consph_sys_reach(&m4), 2 * p->n);
        }
    }
    if (delta) {
        /* delta/scheme.c's fields: V = m/ρ, L_i, ⟨∇ρ⟩^L (its SF_GRADRHO_L), δu, the masses */
        if (st == CONSPH_OK) st = array_of(s, SF_VOL, 1, &v->at[GA_VOL]);
        if (st == CONSPH_OK) st = array_of(s, SF_BONET, d * d, &v->at[GA_BONET]);
        if (st == CONSPH_OK) st = array_of(s, "gradrho_l", d, &v->at[GA_GRADQ]);
        if (st == CONSPH_OK) st = array_of(s, SF_SHIFT, d, &v->at[GA_SHIFT]);
        if (st == CONSPH_OK) st = array_of(s, SF_MASS, 1, &v->at[GA_MASS]);
        /* delta/scheme.c's delta_rates: the shifting form, δ h c_o, the viscosity's constant,
         * visit_renorm's cond_max; solver_shift_velocity's reg_pst_shift constants but the CFL
         * number, which depends on the step's Δt (gpu_step) */
        const char *name = s->scheme->name;
        v->dshift = strcmp(name, "delta-plus-sph") == 0     ? DELTA_SHIFT_SUN
                    : strcmp(name, "delta-plus-sph-d") == 0 ? DELTA_SHIFT_APP_D
                                                            : DELTA_SHIFT_NONE;
        v->Dq = s->D;
        v->dvisc =
            ((s->prm.alpha >= 0.0 ? s->prm.alpha : 0.0) * s->h * s->c0 + 2.0 * (d + 2) * s->nu) *
            s->prm.rho0;
        v->cond_max = 1e8;
        v->pst_inv_wds = 1.0 / consph_kernel_w(&s->sys.kernel, s->ds);
        v->pst_R = 0.2;
        v->pst_cap = INFINITY;
    }
    v->av = (s->prm.alpha >= 0.0 ? s->prm.alpha : 0.1) > 0.0; /* job_fields' α */
    v->tait = s->eos == CONSPH_EOS_TAIT;
    v->rho0 = s->prm.rho0;
    v->c2 = s->c0 * s->c0;
    v->gamma = s->prm.gamma;
    v->cs_exp = eos_int_exponent(0.5 * (s->prm.gamma - 1.0));
    if (st == CONSPH_OK && v->scheme == GS_WCSPH && v->av && v->cs_exp < 0)
        st = consph_fail(CONSPH_EINVAL, "--device gpu: wcsph's sound speed needs an odd γ, not %g",
                         s->prm.gamma);
    grid_setup(&v->g, &p->box, d, consph_nnps_radius(s->sys.nnps), p->n);
    /* dev.h's walk holds cell coordinates in 32 bits: c ± reach with c < 2^30 (the remeshing's
     * walk is in the joint grid) */
    for (int a = 0; st == CONSPH_OK && a < d; ++a) {
        const int64_t reach = lattice && g->joint_grid.reach[a] > v->g.reach[a]
                                  ? g->joint_grid.reach[a]
                                  : v->g.reach[a];
        if (reach > (1 << 29))
            st = consph_fail(CONSPH_EINVAL, "GPU: the search reaches %lld cells along axis %d",
                             (long long)reach, a);
    }
    if (st == CONSPH_OK && v->g.ncells != consph_nnps_cells(s->sys.nnps))
        st = consph_fail(CONSPH_EINVAL, "GPU: %zu cells, the CPU search has %zu", v->g.ncells,
                         consph_nnps_cells(s->sys.nnps));
    const consph_kernel *kr = &s->sys.kernel;
    v->k.norm = kr->norm;
    v->k.inv_h = kr->inv_h;
    v->k.support = kr->support;
    v->k.norm1 = kr->norm * kr->inv_h;
    v->k.at_zero = kr->norm * kr->inv_h * kr->inv_h * gpu_quintic_d2f(0.0);
    v->k.norm2 = kr->norm * kr->inv_h * kr->inv_h;
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
    /* per particle: edac's 1/V and m/ϱ, wcsph's p/ϱ², m/ϱ and c; 001's family IPST's χ in
     * mrho and its two shifts */
    const size_t nvol = negi || delta ? 1 : n * sizeof(double);
    const size_t ncs = v->scheme == GS_WCSPH ? n : 1;
    const size_t nstep = negi || delta ? (size_t)d * n * sizeof(double) : 1;
    /* the rate passes' neighbour records: edac's and wcsph's (dev.h's gpu_pack_width), the δ
     * family's (dev_delta.h's gpu_delta_pack_width) */
    const size_t npack = negi    ? 1
                         : delta ? (size_t)gpu_delta_pack_width(d, v->dshift) * n
                                 : (size_t)(4 + 2 * d) * n;
    s->gpu = g;
    if (st == CONSPH_OK &&
        (be->alloc((void **)&g->dev_a[0], nd) || be->alloc((void **)&g->dev_a[1], nd) ||
         be->alloc((void **)&v->vol, nvol) || be->alloc((void **)&v->mrho, n * sizeof(double)) ||
         be->alloc((void **)&v->cs, ncs * sizeof(double)) ||
         be->alloc((void **)&v->xp, 4 * n * sizeof(double)) ||
         be->alloc((void **)&v->slot_of, n * sizeof(uint32_t)) ||
         be->alloc((void **)&v->pack, npack * sizeof(double)) ||
         be->alloc((void **)&v->cell, n * sizeof(uint32_t)) || be->alloc((void **)&v->count, nc) ||
         be->alloc((void **)&v->start, nc) || be->alloc((void **)&v->order, n * sizeof(uint32_t)) ||
         be->alloc((void **)&v->step, nstep) || be->alloc((void **)&v->total, nstep) ||
         be->alloc((void **)&v->chi_max, sizeof(unsigned long long)) ||
         be->alloc((void **)&v->bonet_ok, negi ? n : 1)))
        st = be_fail(be, "device memory");
    g->pairs_base = s->pairs;
    g->nchunks = (n + GPU_PAIR_CHUNK - 1) / GPU_PAIR_CHUNK;
    const size_t npairs = n * sizeof(unsigned long long);
    const size_t nchunk_bytes = g->nchunks * sizeof(unsigned long long);
    if (st == CONSPH_OK &&
        (be->alloc((void **)&v->pairs, npairs) ||
         be->alloc((void **)&v->pair_chunks, nchunk_bytes) || be->zero(v->pairs, npairs)))
        st = be_fail(be, "device memory");
    if (st == CONSPH_OK && !(g->chunks_host = malloc(nchunk_bytes)))
        st = consph_fail(CONSPH_ENOMEM, "out of memory");
    const size_t njc = lattice ? (g->joint_grid.ncells + 1) * sizeof(uint32_t) : 1;
    const size_t nj = lattice ? n : 1;
    if (st == CONSPH_OK &&
        (be->alloc((void **)&g->jcell, nj * sizeof(uint32_t)) ||
         be->alloc((void **)&g->jcount, njc) || be->alloc((void **)&g->jstart, njc) ||
         be->alloc((void **)&g->jorder, nj * sizeof(uint32_t))))
        st = be_fail(be, "device memory");
    v->a = g->dev_a[0];
    v->b = g->dev_a[1];
    v->chi = v->mrho;
    g->bytes = 2 * nd + nvol + n * sizeof(double) + ncs * sizeof(double) + 4 * n * sizeof(double) +
               npack * sizeof(double) + 3 * n * sizeof(uint32_t) + 2 * nc + 2 * nstep +
               (negi ? n : 1) + npairs + nchunk_bytes;
    if (lattice) g->bytes += 2 * n * sizeof(uint32_t) + 2 * njc;
    if (st == CONSPH_OK) st = copy_arrays(s, 1, NULL);
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

/* Bins the particles and sorts the slots by cell (consph_nnps_build), in the view's grid. */
static int build_cells_in(const gpu_backend *be, const gpu_view *v)
{
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

static int build_cells(gpu_run *g)
{
    return build_cells_in(g->be, &g->v);
}

/* The start of a pec or kdk step: bins the particles, permutes them into cell order (the two
 * copies of every array swap roles) and saves the start of the step. */
static int resort_save(gpu_run *g)
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
    int st = resort_save(g);
    if (st != CONSPH_OK) return st;
    LAUNCH(GK_ADVANCE, v->n, 0.5 * dt);
    if ((st = build_cells(g)) != CONSPH_OK) return st;
    LAUNCH(GK_SLOTS, v->n, 0.0);
    v->grads = grads;
    LAUNCH(GK_DENSITY, v->n, 0.0);
    LAUNCH(GK_RATES, v->n, 0.0);
    LAUNCH(GK_ADVANCE, v->n, dt);
    return CONSPH_OK;
}

/* tvf under kdk, as consph_solver_step and step_kdk run it on the CPU: re-sort into cell order,
 * save the start, the first half kick with the previous step's rates, the transport velocity
 * and the drift by Δt (dev_kdk_drift), rebuild the search, the density and rate passes, the
 * second half kick. */
static int step_kdk(gpu_run *g, double dt, int grads)
{
    const gpu_backend *be = g->be;
    gpu_view *v = &g->v;
    int st = resort_save(g);
    if (st != CONSPH_OK) return st;
    LAUNCH(GK_KDK_DRIFT, v->n, dt);
    if ((st = build_cells(g)) != CONSPH_OK) return st;
    LAUNCH(GK_SLOTS, v->n, 0.0);
    v->grads = grads;
    LAUNCH(GK_DENSITY, v->n, 0.0);
    LAUNCH(GK_RATES, v->n, 0.0);
    LAUNCH(GK_KDK_KICK, v->n, 0.5 * dt);
    return CONSPH_OK;
}

/* The search after a move: the cell lists and the slots' coordinates (consph_sys_update without
 * the re-sort). */
static int rebuild(gpu_run *g)
{
    const gpu_backend *be = g->be;
    const gpu_view *v = &g->v;
    int st = build_cells(g);
    if (st == CONSPH_OK) LAUNCH(GK_SLOTS, v->n, 0.0);
    return st;
}

/* The kit's first pass with the sums named (kit_derivatives' want, negi/scheme.c). */
static int negi_first(gpu_run *g, int with_p, int with_q, int with_div)
{
    const gpu_backend *be = g->be;
    gpu_view *v = &g->v;
    v->kit_p = with_p;
    v->kit_u = 1;
    v->kit_q = with_q;
    v->kit_div = with_div;
    if (!gpu_negi_first_known(v))
        return consph_fail(CONSPH_EINVAL, "GPU: no kernel for these derivatives");
    LAUNCH(GK_NEGI_FIRST, v->n, 0.0);
    return CONSPH_OK;
}

/* negi/scheme.c's rates: the volumes, the kit's two passes (∇p, G, ∇·u; coupled_bc's ∇²u), the
 * per-particle rates. */
static int negi_rates(gpu_run *g)
{
    const gpu_backend *be = g->be;
    gpu_view *v = &g->v;
    const negi_terms *t = &v->nt;
    if (v->moves) LAUNCH(GK_NEGI_VOLUMES, v->n, 0.0); /* fixed for the Eulerian schemes */
    int st = negi_first(g, 1, t->diffuse_q || t->advect_q || t->transport, 1);
    if (st != CONSPH_OK) return st;
    v->lap_u = 1;
    v->lap_q = t->diffuse_q;
    if (t->lap == KIT_LAP_CLEARY)
        LAUNCH(GK_NEGI_CLEARY, v->n, 0.0);
    else if (t->lap == KIT_LAP_FATEHI_C)
        LAUNCH(GK_NEGI_FATEHI, v->n, 0.0);
    else if (t->lap == KIT_LAP_KORZILIUS)
        LAUNCH(GK_NEGI_KORZ, v->n, 0.0);
    else
        LAUNCH(GK_NEGI_COUPLED, v->n, 0.0);
    /* TV-C's shifting velocity δu = (c_o/h) δr of Sun et al.'s shift at 001's authors'
     * constants (solver_shift_velocity_tvc), in the shift field */
    if (t->transport) LAUNCH(GK_PST_SHIFT, v->n, v->c0_over_h);
    LAUNCH(GK_NEGI_RATES, v->n, 0.0);
    return CONSPH_OK;
}

/* delta/scheme.c's delta_rates: the volumes m/ρ, δ+-SPH's shifting velocity δu = δr/Δt
 * (solver_shift_velocity: Sun's shift of dev_pst_shift_d, times 1/Δt, into the shift field), L_i
 * and ⟨∇ρ⟩^L, the rates. */
static int delta_rates(gpu_run *g)
{
    const gpu_backend *be = g->be;
    const gpu_view *v = &g->v;
    LAUNCH(GK_DELTA_VOLUMES, v->n, 0.0);
    if (v->dshift != DELTA_SHIFT_NONE) LAUNCH(GK_PST_SHIFT, v->n, v->dinv_dt);
    LAUNCH(GK_DELTA_RENORM, v->n, 0.0);
    LAUNCH(GK_DELTA_RATES, v->n, 0.0);
    return CONSPH_OK;
}

/* The rates of a scheme under rk2. */
static int rk2_rates(gpu_run *g)
{
    return g->v.scheme == GS_DELTA ? delta_rates(g) : negi_rates(g);
}

/* 001's family and the δ-SPH family under rk2, as consph_solver_step runs it: re-sort into cell
 * order and rebuild the search, save the start, the rates, advance by Δt/2 (the closure: the
 * EOS), the rates there, advance by Δt from the start. */
static int step_rk2(gpu_run *g, double dt)
{
    const gpu_backend *be = g->be;
    gpu_view *v = &g->v;
    int st = CONSPH_OK;
    if (v->moves) {
        if ((st = build_cells(g)) != CONSPH_OK) return st;
        LAUNCH(GK_PERMUTE, v->n, 0.0);
        double *t = v->a;
        v->a = v->b;
        v->b = t;
        if ((st = rebuild(g)) != CONSPH_OK) return st;
    } else if (!g->built) {
        /* the Eulerian schemes' particles stay where they are: one search for the run */
        if ((st = rebuild(g)) != CONSPH_OK) return st;
        g->built = 1;
    }
    LAUNCH(GK_SAVE, v->n, 0.0);
    if ((st = rk2_rates(g)) != CONSPH_OK) return st;
    LAUNCH(GK_ADVANCE, v->n, 0.5 * dt);
    if (v->moves && (st = rebuild(g)) != CONSPH_OK) return st;
    if ((st = rk2_rates(g)) != CONSPH_OK) return st;
    LAUNCH(GK_ADVANCE, v->n, dt);
    return v->moves ? rebuild(g) : CONSPH_OK;
}

/* What the host reads of the state after this step (counted in s->step + ahead): 2, every
 * array (a snapshot's gradients, the end); 1, the log sample's (gpu_download_sample); 0, none.
 * The authors' measure's output times are not known
 * here (a --tf run's step lands on one as consph_solver_step decides): its step_close copies
 * the state back at those, so every other step leaves it on the device. */
static int host_reads(const consph_solver *s, long ahead)
{
    return !s->grads_skip ? 2 : (s->step + ahead) % s->prm.log_every == 0;
}

static int copy_back_read(consph_solver *s, int reads, int *synced)
{
    const int st = reads == 2 ? gpu_download(s) : gpu_download_sample(s);
    *synced = st == CONSPH_OK;
    return st;
}

int gpu_step(consph_solver *s, double dt, int *synced)
{
    *synced = 0;
    const int negi = s->gpu->v.scheme == GS_NEGI;
    if (s->gpu->v.scheme == GS_DELTA) {
        /* solver_shift_velocity's reg_pst_params at this step's Δt (cut where a run lands on
         * its end or an output time) */
        gpu_view *v = &s->gpu->v;
        const double cfl = s->dt * s->c0 / s->h, mach = s->prm.U / s->c0, twoh = 2.0 * s->h;
        v->pst_coef = -cfl * mach * twoh * twoh;
        v->dinv_dt = 1.0 / s->dt;
    }
    int st = negi || s->gpu->v.scheme == GS_DELTA ? step_rk2(s->gpu, dt)
             : s->gpu->v.scheme == GS_TVF         ? step_kdk(s->gpu, dt, !s->grads_skip)
                                                  : step_pec(s->gpu, dt, !s->grads_skip);
    if (st != CONSPH_OK) return st;
    /* 001's family copies back after its regularisation where it has one (gpu_regularise) */
    const int reads = host_reads(s, 1);
    if (!(negi && s->scheme->regularise) && reads) st = copy_back_read(s, reads, synced);
    return st;
}

/* max χ of the current positions, with the volumes ω (reg_ipst's ipst_volumes). */
static int ipst_volumes(gpu_run *g, double *chi_max)
{
    const gpu_backend *be = g->be;
    const gpu_view *v = &g->v;
    if (be->zero(v->chi_max, sizeof(unsigned long long))) return be_fail(be, "zero");
    LAUNCH(GK_IPST_VOLUMES, v->n, 0.0);
    LAUNCH(GK_CHI_MAX, (v->n + GPU_MAX_CHUNK - 1) / GPU_MAX_CHUNK, 0.0);
    unsigned long long bits = 0;
    if (be->get(&bits, v->chi_max, sizeof bits)) return be_fail(be, "copy from the device");
    memcpy(chi_max, &bits, sizeof bits);
    return CONSPH_OK;
}

/* negi/scheme.c's regularise_ipst and reg_ipst on the device: the gradients before the shift
 * (fresh volumes, G and ∇q), then until eq. 21 holds or max_iter shifts were made: the volumes
 * and max χ, the shift (eq. 19) and the move; then the Taylor update and the closure. The
 * schedule and χ_o as on the CPU. */
static int ipst(consph_solver *s)
{
    gpu_run *g = s->gpu;
    const gpu_backend *be = g->be;
    gpu_view *v = &g->v;
    const double period_dt =
        s->prm.ipst_h_dt > 0.0 ? s->prm.cfl * s->prm.ipst_h_dt / (s->prm.U + s->c0) : 0.0;
    if (!reg_ipst_due(s->step, s->t - s->dt, s->t, s->prm.ipst_every, period_dt)) return CONSPH_OK;
    LAUNCH(GK_NEGI_VOLUMES, v->n, 0.0);
    int st = negi_first(g, 0, 1, 0);
    if (st != CONSPH_OK) return st;
    const size_t n = v->n, dn = (size_t)v->d * n * sizeof(double);
    if (be->zero(v->a + (size_t)v->at[GA_SHIFT] * n, dn) || be->zero(v->total, dn))
        return be_fail(be, "zero");
    reg_ipst_params ip = {s->h, s->chi0, s->prm.ipst_tol, s->prm.ipst_max_iter, 1};
    const int first = s->prm.ipst_chi0 == 0.0;
    if (s->prm.ipst_chi0 > 0.0) ip.chi0 = s->prm.ipst_chi0;
    if (first) ip.max_iter = 1;
    if (!(ip.chi0 > 0.0) || !isfinite(ip.chi0) || !(ip.tol > 0.0) || ip.max_iter < 0)
        return consph_fail(CONSPH_EINVAL, "IPST: needs chi0 > 0, tol > 0 and max_iter >= 0");
    double chi_max = NAN;
    for (int it = 0;; ++it) {
        if ((st = ipst_volumes(g, &chi_max)) != CONSPH_OK) return st;
        if ((it >= ip.min_iter && fabs(chi_max - ip.chi0) < ip.tol) || it >= ip.max_iter) break;
        LAUNCH(GK_IPST_SHIFT, n, 0.0);
        LAUNCH(GK_IPST_MOVE, n, 0.0);
        if ((st = rebuild(g)) != CONSPH_OK) return st;
    }
    if (first) s->prm.ipst_chi0 = chi_max;
    LAUNCH(GK_SHIFT_END, n, 1.0);
    ++s->regs;
    return CONSPH_OK;
}

/* negi/scheme.c's regularise_pst on the device: the gradients before the shift, Sun et al.'s
 * shift (reg_pst_shift) into the shift field, the move, the Taylor update and the closure. */
static int pst(consph_solver *s)
{
    gpu_run *g = s->gpu;
    const gpu_backend *be = g->be;
    gpu_view *v = &g->v;
    LAUNCH(GK_NEGI_VOLUMES, v->n, 0.0);
    int st = negi_first(g, 0, 1, 0);
    if (st != CONSPH_OK) return st;
    if (be->zero(v->total, (size_t)v->d * v->n * sizeof(double))) return be_fail(be, "zero");
    LAUNCH(GK_PST_SHIFT, v->n, 1.0);
    LAUNCH(GK_IPST_MOVE, v->n, 0.0);
    if ((st = rebuild(g)) != CONSPH_OK) return st;
    LAUNCH(GK_SHIFT_END, v->n, 0.0);
    ++s->regs;
    return CONSPH_OK;
}

/* negi/scheme.c's regularise_remesh on the device: reg_remesh_m4's sums at every lattice point
 * over the particles, in its joint search's order (the particles binned in the joint grid), then
 * u, q and x replaced, the closure, and the search rebuilt. */
static int remesh(consph_solver *s)
{
    gpu_run *g = s->gpu;
    const gpu_backend *be = g->be;
    gpu_view jv = g->v;
    jv.g = g->joint_grid;
    jv.cell = g->jcell;
    jv.count = g->jcount;
    jv.start = g->jstart;
    jv.order = g->jorder;
    int st = build_cells_in(be, &jv);
    if (st != CONSPH_OK) return st;
    const gpu_view *v = &jv;
    /* the joint slots into the search's xp and slot_of, which the rebuild below restores */
    LAUNCH(GK_SLOTS, v->n, 0.0);
    jv.at[GA_X] = jv.at[GA_LAT]; /* the walks start at the lattice points */
    LAUNCH(GK_REMESH, v->n, 0.0);
    v = &g->v;
    LAUNCH(GK_REMESH_END, v->n, 0.0);
    if ((st = rebuild(g)) != CONSPH_OK) return st;
    ++s->regs;
    return CONSPH_OK;
}

int gpu_regularise(consph_solver *s, int *synced)
{
    *synced = 0;
    const char *name = s->scheme->name;
    int st = strcmp(name, "l-ipst-c") == 0 || strcmp(name, "l-ipst-f") == 0 ||
                     strcmp(name, "l-ipst-k") == 0 || strcmp(name, "pe-ipst-c") == 0
                 ? ipst(s)
             : strcmp(name, "l-pst-c") == 0 ? pst(s)
             : strcmp(name, "l-rr-c") == 0
                 ? remesh(s)
                 : consph_fail(CONSPH_EINVAL, "GPU: no regularisation of %s", name);
    const int reads = host_reads(s, 0);
    if (st == CONSPH_OK && reads) st = copy_back_read(s, reads, synced);
    return st;
}

int consph_solver_set_device(consph_solver *s, consph_device device)
{
    if (device == CONSPH_DEVICE_CPU) {
        if (!s->gpu) return CONSPH_OK;
        /* the CPU's pass 1 computes B_i again before it keeps it (what the GPU left in the field
         * is its copy, but the CPU keeps only what it made on this build of the list) */
        s->bonet_kept = 0;
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

consph_device consph_solver_device(const consph_solver *s)
{
    return s && s->gpu ? CONSPH_DEVICE_GPU : CONSPH_DEVICE_CPU;
}

int consph_solver_sync(consph_solver *s)
{
    if (!s) return consph_fail(CONSPH_EINVAL, "consph_solver_sync: no solver");
    return s->gpu ? gpu_download(s) : CONSPH_OK;
}

int gpu_emulated(const consph_solver *s)
{
    return s->gpu && s->gpu->be == &gpu_emulation;
}

size_t gpu_device_bytes(const consph_solver *s)
{
    return s->gpu ? s->gpu->bytes : 0;
}
