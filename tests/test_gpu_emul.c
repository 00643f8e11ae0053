/* The GPU solver's per-particle functions (src/gpu/dev.h), run by the host emulation backend
 * exactly as the CUDA kernels run them (one call per particle or cell, the scatter in reverse
 * order so that the per-cell sort must restore the stable order), against the CPU solver: edac,
 * wcsph and tvf on the 2D Taylor-Green vortex and the 3D Beltrami flow, every particle array
 * (positions and every field, the start-of-step copies and gradients included) and the particles'
 * origins bit for bit after one step and after 20, and the count of pair evaluations, with the
 * gradients every step and as consph_run skips them (grads_lazy, the state copied back only at the
 * log samples and the end); 001's schemes (rk2, the kit's passes, IPST over two shifts, the other
 * regularisations) and the δ-SPH family (rk2, δ+-SPH's shifting velocity) the same way. Then the
 * refusals: schemes not ported, and a build without CUDA. Under error = authors, the copies back
 * are counted: only the steps the host reads. The log samples beside the steps give the CPU's
 * history and sums. */
#include <dirent.h>
#include <unistd.h>

#include "consph/layout.h"
#include "gpu_compare.h"

static void refusals(void)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "tvf");
    snprintf(p.integrator, sizeof p.integrator, "pec");
    CHECK(consph_gpu_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "kdk, tvf's"),
          "tvf under pec on the GPU: %s", consph_last_error());
    p.integrator[0] = 0;
    CHECK(consph_gpu_check(&p) == CONSPH_OK || !strstr(consph_last_error(), "does not run"),
          "tvf on the GPU: %s", consph_last_error());
    snprintf(p.scheme, sizeof p.scheme, "delta-plus-sph");
    snprintf(p.integrator, sizeof p.integrator, "ssprk3");
    CHECK(consph_gpu_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "rk2"),
          "delta-plus-sph under ssprk3 on the GPU: %s", consph_last_error());
    p.integrator[0] = 0;
    snprintf(p.scheme, sizeof p.scheme, "l-ipst-c");
    snprintf(p.integrator, sizeof p.integrator, "pec");
    CHECK(consph_gpu_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "rk2"),
          "l-ipst-c under pec on the GPU: %s", consph_last_error());
    p.integrator[0] = 0;
    /* the δ-SPH family is accepted (a study's rows under --device gpu|auto, consph_gpu_check):
     * refused here only for want of a GPU */
    static const char *const deltas[] = {"delta-sph", "delta-plus-sph", "delta-plus-sph-d"};
    for (int k = 0; k < 3; ++k) {
        snprintf(p.scheme, sizeof p.scheme, "%s", deltas[k]);
        const int st = consph_gpu_check(&p);
        CHECK(st == CONSPH_OK || !strstr(consph_last_error(), "does not run on the GPU"),
              "%s on the GPU: %s", deltas[k], consph_last_error());
    }
    snprintf(p.scheme, sizeof p.scheme, "edac");
    p.skin = 0.2;
    CHECK(consph_gpu_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "--skin"),
          "a skin on the GPU: %s", consph_last_error());
    char why[256];
#ifdef CONSPH_HAVE_CUDA
    if (!consph_gpu_available(why, sizeof why))
        CHECK(strstr(why, "no CUDA device"), "a CUDA build without a device: %s", why);
#else
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

/* error = authors (001's measure at its output times): the GPU run copies its state back after
 * the steps whose end the host reads (the output times, the log samples, the last step) and no
 * other, and the measure's sums, the log and the state equal the CPU's bit for bit; by --steps
 * (output times rounded to steps) and by --tf (steps cut to land on them). */
/* Two solvers of p, s[0] on the CPU and s[1] on the emulation, stepping as consph_run without
 * snapshots does (grads_lazy); 0 (the caller frees what was made) when one could not be made. */
static int emul_pair(const consph_run_params *p, consph_solver *s[2])
{
    for (int k = 0; k < 2; ++k) {
        CHECK(consph_solver_create(&s[k], p) == CONSPH_OK, "create: %s", consph_last_error());
        if (!s[k]) return 0;
        s[k]->grads_lazy = 1;
    }
    CHECK(gpu_attach(s[1], &gpu_emulation) == CONSPH_OK, "attach: %s", consph_last_error());
    return s[1]->gpu != NULL;
}

/* A case's parameters: the defaults with this scheme on 16 particles per side. */
static consph_run_params emul_params(const char *scheme)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = 16;
    return p;
}

static void authors_copies(const char *scheme, int by_steps)
{
    consph_solver *s[2] = {NULL, NULL};
    consph_run_params prm = emul_params(scheme);
    prm.error = CONSPH_ERROR_AUTHORS;
    prm.error_times = 5;
    prm.log_every = 7;
    prm.steps = by_steps ? 24 : 0;
    prm.dt = by_steps ? 0.0 : 1.1e-3;
    prm.tf = by_steps ? 0.0 : 0.0255; /* output times k·0.006375: steps 6, 12, 18, 24 cut */
    if (!emul_pair(&prm, s)) goto done;
    consph_solver *cpu = s[0], *emu = s[1];
    long steps = 0, reads = 0;
    while (!consph_solver_done(cpu)) {
        const int before = cpu->auth_n;
        const int a = consph_solver_step(cpu), b = consph_solver_step(emu);
        CHECK(a == CONSPH_OK && b == CONSPH_OK, "%s step %ld: %s", scheme, steps + 1,
              consph_last_error());
        if (a != CONSPH_OK || b != CONSPH_OK) goto done;
        ++steps;
        reads += cpu->step % 7 == 0 || consph_solver_done(cpu) || cpu->auth_n > before;
    }
    char what[128];
    snprintf(what, sizeof what, "%s error = authors by %s", scheme, by_steps ? "steps" : "tf");
    CHECK(gpu_download_count(emu) == reads && reads < steps / 2,
          "%s: %ld copies back in %ld steps, the host reads %ld", what, gpu_download_count(emu),
          steps, reads);
    /* the samples copy back the arrays the host reads only: fewer bytes than whole copies */
    const consph_particles *p = emu->sys.p;
    long long arrays = p->dim;
    for (int f = 0; f < p->nfields; ++f) arrays += p->fields[f].ncomp;
    const long long whole = arrays * (long long)p->n * (long long)sizeof(double);
    CHECK(gpu_download_bytes(emu) > whole && gpu_download_bytes(emu) < reads * whole,
          "%s: %lld bytes copied back in %ld copies of %lld bytes each at most", what,
          gpu_download_bytes(emu), reads, whole);
    /* the last step's copy is whole (the end of the run), the others the samples' */
    printf("%s: %ld copies back, %lld bytes (whole copies: %lld); per particle: %lld B a sample, "
           "%lld B whole\n",
           what, reads, gpu_download_bytes(emu), reads * whole,
           reads > 1 ? (gpu_download_bytes(emu) - whole) / (reads - 1) / (long long)p->n : 0,
           whole / (long long)p->n);
    CHECK(consph_solver_done(emu) && cpu->auth_n == 5 && emu->auth_n == cpu->auth_n &&
              memcmp(&cpu->auth_u_acc, &emu->auth_u_acc, sizeof(double)) == 0 &&
              memcmp(&cpu->auth_p_acc, &emu->auth_p_acc, sizeof(double)) == 0,
          "%s: %d samples, sums %.17g %.17g vs %d, %.17g %.17g", what, cpu->auth_n, cpu->auth_u_acc,
          cpu->auth_p_acc, emu->auth_n, emu->auth_u_acc, emu->auth_p_acc);
    CHECK(cpu->nhist == emu->nhist &&
              memcmp(cpu->hist, emu->hist, cpu->nhist * HIST_COLS * sizeof(double)) == 0,
          "%s: the logged diagnostics differ", what);
    same_state(cpu, emu, what);
done:
    consph_solver_free(s[0]);
    consph_solver_free(s[1]);
}

/* The log samples on a host thread beside the steps (src/solver/sampler.c, forced on the
 * emulation): after every step the history read through the API (which waits for a sample still
 * running) equals the CPU's row for row, and so do the summary's sums at the end (eq. 26, the
 * authors' measure, both against the weakly-compressible reference too). */
static void overlapped(const char *scheme)
{
    setenv("CONSPH_SAMPLE_OVERLAP", "1", 1);
    consph_solver *s[2] = {NULL, NULL};
    consph_run_params p = emul_params(scheme);
    p.error = CONSPH_ERROR_AUTHORS;
    p.error_times = 4;
    p.exact = CONSPH_EXACT_BOTH;
    p.log_every = 3;
    p.steps = 14;
    p.tf = 0.0;
    if (!emul_pair(&p, s)) goto done;
    consph_solver *cpu = s[0], *emu = s[1];
    int rows_equal = 1;
    while (!consph_solver_done(cpu)) {
        const int a = consph_solver_step(cpu), b = consph_solver_step(emu);
        CHECK(a == CONSPH_OK && b == CONSPH_OK, "%s overlapped step: %s", scheme,
              consph_last_error());
        if (a != CONSPH_OK || b != CONSPH_OK) goto done;
        const size_t n = consph_solver_history_size(cpu);
        rows_equal &= consph_solver_history_size(emu) == n;
        if (n == 0 || !rows_equal) continue;
        consph_step_diag dc, de;
        rows_equal &= consph_solver_history_row(cpu, n - 1, &dc) == CONSPH_OK &&
                      consph_solver_history_row(emu, n - 1, &de) == CONSPH_OK &&
                      memcmp(&dc, &de, sizeof dc) == 0;
    }
    CHECK(rows_equal, "%s overlapped: the history read after each step differs", scheme);
    CHECK(emu->sampler != NULL, "%s overlapped: no sample ran on the host thread", scheme);
    consph_run_summary sc, se;
    CHECK(consph_solver_summary(cpu, &sc) == CONSPH_OK &&
              consph_solver_summary(emu, &se) == CONSPH_OK,
          "summary: %s", consph_last_error());
    const double c[] = {sc.l1_u,    sc.l1_p,    sc.l1n_u,    sc.l1n_p,
                        sc.wc_l1_u, sc.wc_l1_p, sc.wc_l1n_u, sc.wc_l1n_p};
    const double e[] = {se.l1_u,    se.l1_p,    se.l1n_u,    se.l1n_p,
                        se.wc_l1_u, se.wc_l1_p, se.wc_l1n_u, se.wc_l1n_p};
    CHECK(memcmp(c, e, sizeof c) == 0 && isfinite(c[0]) && isfinite(c[4]) && isfinite(c[6]),
          "%s overlapped: sums %.17g %.17g %.17g against the CPU's %.17g %.17g %.17g", scheme, e[0],
          e[4], e[6], c[0], c[4], c[6]);
done:
    consph_solver_free(s[0]);
    consph_solver_free(s[1]);
    unsetenv("CONSPH_SAMPLE_OVERLAP");
}

/* consph_solver_sync mid-run: between two log samples the host holds only what the samples read
 * (wcsph's rates of the last step among what it lacks); after a sync every array equals the
 * CPU's at the same step, and the steps after it on the device go on as the CPU's, bit for bit.
 * consph_solver_device says where each solver steps; a sync of a CPU solver changes nothing. */
static void synced(const char *scheme)
{
    consph_solver *s[2] = {NULL, NULL};
    consph_run_params p = emul_params(scheme);
    p.log_every = 100;
    p.steps = 12;
    p.tf = 0.0;
    if (!emul_pair(&p, s)) goto done;
    consph_solver *cpu = s[0], *emu = s[1];
    CHECK(consph_solver_device(cpu) == CONSPH_DEVICE_CPU &&
              consph_solver_device(emu) == CONSPH_DEVICE_GPU,
          "%s: consph_solver_device", scheme);
    char what[96];
    for (int k = 1; k <= 12; ++k) {
        const int a = consph_solver_step(cpu), b = consph_solver_step(emu);
        CHECK(a == CONSPH_OK && b == CONSPH_OK, "%s step %d: %s", scheme, k, consph_last_error());
        if (a != CONSPH_OK || b != CONSPH_OK) goto done;
        if (k != 5 && k != 9) continue;
        const long copies = gpu_download_count(emu);
        CHECK(consph_solver_sync(cpu) == CONSPH_OK && consph_solver_sync(emu) == CONSPH_OK &&
                  gpu_download_count(emu) == copies + 1 &&
                  consph_solver_device(emu) == CONSPH_DEVICE_GPU,
              "%s: sync at step %d: %s", scheme, k, consph_last_error());
        snprintf(what, sizeof what, "%s synced at step %d", scheme, k);
        same_state(cpu, emu, what);
    }
    snprintf(what, sizeof what, "%s: the steps after two syncs", scheme);
    same_state(cpu, emu, what);
done:
    consph_solver_free(s[0]);
    consph_solver_free(s[1]);
}

int main(void)
{
    /* tvf: kick-drift-kick, its transport velocity and summation density */
    static const char *const schemes[] = {"edac", "wcsph", "tvf"};
    for (int k = 0; k < 3; ++k) {
        gpu_compare(&gpu_emulation, schemes[k], "taylor-green", 20, 0);
        gpu_compare(&gpu_emulation, schemes[k], "taylor-green", 20, 1);
        gpu_compare(&gpu_emulation, schemes[k], "beltrami", 10, 0);
    }
    /* L-IPST-C from its packed start: IPST after steps 1 (one shift, χ_o from it) and 11 (to
     * eq. 21 or ten shifts) */
    gpu_compare(&gpu_emulation, "l-ipst-c", "taylor-green", 16, 0);
    gpu_compare(&gpu_emulation, "l-ipst-c", "beltrami", 8, 0);
    /* L-IPST-F: Fatehi_c's Laplacian (its B̂ from a walk of its own) */
    gpu_compare(&gpu_emulation, "l-ipst-f", "taylor-green", 16, 0);
    /* L-IPST-K: Korzilius' Laplacian (the kernel's W'', a 3×3 or 6×6 inverse) */
    gpu_compare(&gpu_emulation, "l-ipst-k", "taylor-green", 16, 0);
    gpu_compare(&gpu_emulation, "l-ipst-k", "beltrami", 8, 0);
    /* the other ported schemes of 001's family: PE-IPST-C (p evolves, the δ-term's ∇²p),
     * L-PST-C (Sun et al.'s shifting every step), TV-C (moved with u + δu, its δu terms), E-C
     * (Eulerian: fixed particles and volumes, both advection terms) */
    gpu_compare(&gpu_emulation, "pe-ipst-c", "taylor-green", 16, 1);
    gpu_compare(&gpu_emulation, "l-pst-c", "taylor-green", 16, 0);
    gpu_compare(&gpu_emulation, "tv-c", "taylor-green", 16, 0);
    /* L-RR-C: M4 remeshing to the lattice after every step */
    gpu_compare(&gpu_emulation, "l-rr-c", "taylor-green", 16, 0);
    gpu_compare(&gpu_emulation, "l-rr-c", "beltrami", 8, 1);
    gpu_compare(&gpu_emulation, "e-c", "taylor-green", 16, 0);
    /* EWCSPH: Eulerian, Cleary's Laplacian, ∇p over its frozen ϱ_c */
    gpu_compare(&gpu_emulation, "ewcsph", "taylor-green", 16, 0);
    gpu_compare(&gpu_emulation, "ewcsph", "beltrami", 8, 0);
    /* the δ-SPH family (rk2): δ-SPH, δ+-SPH (Sun's shifting velocity, its sum and difference
     * terms), δ+-SPH-D (001 eq. D.5), from their packed starts */
    static const char *const deltas[] = {"delta-sph", "delta-plus-sph", "delta-plus-sph-d"};
    /* the two solvers of a case from one packing: a layout cache of this test's own */
    char cache[] = "/tmp/consph-gpu-emul-XXXXXX";
    const int cached = mkdtemp(cache) && consph_layout_cache_set(cache) == CONSPH_OK;
    for (int k = 0; k < 3; ++k) {
        gpu_compare(&gpu_emulation, deltas[k], "taylor-green", 16, k == 1);
        gpu_compare(&gpu_emulation, deltas[k], "beltrami", 6, k == 2);
    }
    consph_layout_cache_set(NULL);
    if (cached) {
        DIR *dir = opendir(cache);
        for (struct dirent *e; dir && (e = readdir(dir));) {
            char path[sizeof cache + 256];
            if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
            snprintf(path, sizeof path, "%s/%s", cache, e->d_name);
            unlink(path);
        }
        if (dir) closedir(dir);
        rmdir(cache);
    }
    gpu_twice(&gpu_emulation, "edac", "taylor-green", 20, 5);
    gpu_twice(&gpu_emulation, "tvf", "taylor-green", 20, 5);
    authors_copies("edac", 1);
    authors_copies("tvf", 0);
    synced("wcsph");
    synced("l-ipst-c");
    authors_copies("edac", 0);
    authors_copies("l-ipst-c", 0);
    authors_copies("delta-plus-sph", 0); /* steps cut to land: δu = δr/Δt of the cut Δt */
    overlapped("edac");
    overlapped("l-ipst-c");
    refusals();
    return check_summary("test_gpu_emul");
}
