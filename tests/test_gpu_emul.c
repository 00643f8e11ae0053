/* The GPU solver's per-particle functions (src/gpu/dev.h), run by the host emulation backend
 * exactly as the CUDA kernels run them (one call per particle or cell, the scatter in reverse
 * order so that the per-cell sort must restore the stable order), against the CPU solver: edac
 * and wcsph on the 2D Taylor-Green vortex and the 3D Beltrami flow, every particle array (positions
 * and every field, the start-of-step copies and gradients included) and the particles' origins bit
 * for bit after one step and after 20, with the gradients every step and as consph_run skips
 * them (grads_lazy, the state copied back only at the log samples and the end); 001's schemes
 * (rk2, the kit's passes, IPST over two shifts, the other regularisations) the same way. Then the
 * refusals: schemes not ported, and a build without CUDA. */
#include "gpu_compare.h"

static void refusals(void)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "tvf");
    CHECK(consph_gpu_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "edac,wcsph"),
          "tvf on the GPU: %s", consph_last_error());
    snprintf(p.scheme, sizeof p.scheme, "delta-plus-sph");
    CHECK(consph_gpu_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "l-ipst-c"),
          "delta-plus-sph on the GPU: %s", consph_last_error());
    snprintf(p.scheme, sizeof p.scheme, "l-ipst-c");
    snprintf(p.integrator, sizeof p.integrator, "pec");
    CHECK(consph_gpu_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "rk2"),
          "l-ipst-c under pec on the GPU: %s", consph_last_error());
    p.integrator[0] = 0;
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

int main(void)
{
    static const char *const schemes[] = {"edac", "wcsph"};
    for (int k = 0; k < 2; ++k) {
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
    gpu_twice(&gpu_emulation, "edac", "taylor-green", 20, 5);
    refusals();
    return check_summary("test_gpu_emul");
}
