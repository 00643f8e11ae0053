/* The CUDA backend of the GPU solver on the device (ctest label "gpu"; skipped, 77, where the
 * build has no CUDA or the machine no device): edac, wcsph, tvf and 001's nine schemes (l-ipst-c,
 * l-ipst-f, l-ipst-k, pe-ipst-c, l-pst-c, tv-c, l-rr-c, e-c, ewcsph) and the δ-SPH family
 * (delta-sph, delta-plus-sph, delta-plus-sph-d) on the 2D Taylor-Green vortex
 * and the 3D Beltrami flow stepped on the GPU equals the CPU solver bit for bit, every
 * particle array and the pair count after one step and after 20 (nvcc -fmad=false against C11's
 * uncontracted arithmetic), and two GPU runs are bitwise equal. */
#include "gpu_compare.h"

int main(void)
{
    char why[256];
    const gpu_backend *be = gpu_cuda_backend(why, sizeof why);
    if (!be) {
        printf("test_gpu_cuda: skipped: %s\n", why);
        return 77;
    }
    static const char *const schemes[] = {"edac", "wcsph", "tvf"};
    for (int k = 0; k < 3; ++k) {
        gpu_compare(be, schemes[k], "taylor-green", 100, 0);
        gpu_compare(be, schemes[k], "taylor-green", 100, 1);
        gpu_compare(be, schemes[k], "beltrami", 20, 0);
        gpu_twice(be, schemes[k], "taylor-green", 200, 10);
        gpu_twice(be, schemes[k], "beltrami", 24, 5);
    }
    /* L-IPST-C packs its start on the host for each solver (about 5 s a core each at these
     * sizes); 20 steps span two IPST shifts (after steps 1 and 11) */
    gpu_compare(be, "l-ipst-c", "taylor-green", 64, 0);
    gpu_compare(be, "l-ipst-c", "taylor-green", 64, 1);
    gpu_compare(be, "l-ipst-c", "beltrami", 12, 0);
    gpu_twice(be, "l-ipst-c", "taylor-green", 64, 12);
    /* the rest of 001-table9's schemes, l-ipst-f and l-ipst-k, small (packed starts: pe-ipst-c,
     * l-pst-c, tv-c, l-ipst-f, l-ipst-k) */
    static const char *const others[] = {"pe-ipst-c", "l-pst-c", "tv-c",     "l-rr-c",
                                         "e-c",       "ewcsph",  "l-ipst-f", "l-ipst-k"};
    for (int k = 0; k < 8; ++k) {
        gpu_compare(be, others[k], "taylor-green", 32, 0);
        gpu_compare(be, others[k], "beltrami", 8, 1);
    }
    /* the δ-SPH family (packed starts) */
    static const char *const deltas[] = {"delta-sph", "delta-plus-sph", "delta-plus-sph-d"};
    for (int k = 0; k < 3; ++k) {
        gpu_compare(be, deltas[k], "taylor-green", 32, 0);
        gpu_compare(be, deltas[k], "taylor-green", 32, 1);
        gpu_compare(be, deltas[k], "beltrami", 8, 0);
    }
    gpu_twice(be, "delta-plus-sph", "taylor-green", 32, 10);
    return check_summary("test_gpu_cuda");
}
