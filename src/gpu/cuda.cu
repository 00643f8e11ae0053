/* The CUDA backend of the GPU solver (gpu_internal.h): one thread per particle (or cell, or
 * slot) running dev.h's function, the device memory and copies, and the counting sort's prefix
 * sums (CUB's, exact on integers). Built only with CONSPH_CUDA and nvcc, with -fmad=false: a
 * contracted multiply-add rounds once where the CPU rounds twice, and the GPU run would then
 * leave the CPU's at round-off. */
#include <cuda_runtime.h>
#include <cub/device/device_scan.cuh>
#include <stdio.h>
#include <stdlib.h>

#include "gpu/gpu_internal.h"

namespace {

/* Per host thread, as the rest of this backend's state: the rows of a study on threads
 * (--jobs with --device gpu) each step their own solver on the GPU at once, on the calling
 * thread's own default stream (nvcc --default-stream per-thread, CMakeLists.txt), so their kernels
 * run side by side and one thread's copy back waits for its own work only. */
thread_local char cuda_err[256];

int fail(cudaError_t e, const char *what)
{
    if (e == cudaSuccess) return 0;
    snprintf(cuda_err, sizeof cuda_err, "%s: %s", what, cudaGetErrorString(e));
    return 1;
}

/* The view goes by value: each launch sees the current arrays (a and b swap at a re-sort). */
#define GPU_KERNEL(name, call)                                                                     \
    __global__ void name(const gpu_view v, size_t count, double c)                                \
    {                                                                                              \
        const size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;                          \
        (void)c;                                                                                   \
        if (i < count) call;                                                                       \
    }

GPU_KERNEL(k_bin, dev_bin(&v, i))
GPU_KERNEL(k_count, dev_count(&v, i))
GPU_KERNEL(k_scatter, dev_scatter(&v, i))
GPU_KERNEL(k_cell_sort, dev_cell_sort(&v, i))
GPU_KERNEL(k_slots, dev_slots(&v, i))
GPU_KERNEL(k_permute, dev_permute(&v, i))
GPU_KERNEL(k_save, dev_save_start(&v, i))
GPU_KERNEL(k_advance, dev_advance(&v, i, c))
GPU_KERNEL(k_kdk_drift, dev_kdk_drift(&v, i, c))
GPU_KERNEL(k_kdk_kick, dev_kdk_kick(&v, i, c))
GPU_KERNEL(k_pair_sum, dev_pair_sum(&v, i))
GPU_KERNEL(k_density2, dev_edac_density_d(&v, i, 2))
GPU_KERNEL(k_density3, dev_edac_density_d(&v, i, 3))
GPU_KERNEL(k_tdensity2, dev_tv_density_d(&v, i, 2, 0))
GPU_KERNEL(k_tdensity3, dev_tv_density_d(&v, i, 3, 0))
GPU_KERNEL(k_wprep, dev_wcsph_prep(&v, i))
/* The rate kernels under a register cap each (__maxnreg__): on an H200 a cap of 80 to 128 made
 * them 1.2-2x faster than the compiler's own choice (bench/gpu_tune.sh, docs/gpu.md), in 2D
 * with spills; 3D edac best at 128. A build with CONSPH_CUDA_MAXRREG (the sweep's cap for every
 * kernel) leaves them uncapped, so that the cap it names is the one that holds. */
#if defined(CONSPH_CUDA_MAXRREG_SET)
#define GPU_RATE_KERNEL(name, regs, call) GPU_KERNEL(name, call)
#else
#define GPU_RATE_KERNEL(name, regs, call)                                                          \
    __global__ void __maxnreg__(regs) name(const gpu_view v, size_t count, double c)              \
    {                                                                                              \
        const size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;                          \
        (void)c;                                                                                   \
        if (i < count) call;                                                                       \
    }
#endif
/* one kernel per dimension and gradients: each holds only its own variant's registers */
GPU_RATE_KERNEL(k_rates2, 80, dev_edac_rates_d(&v, i, 2, 0))
GPU_RATE_KERNEL(k_rates2g, 80, dev_edac_rates_d(&v, i, 2, 1))
GPU_RATE_KERNEL(k_rates3, 128, dev_edac_rates_d(&v, i, 3, 0))
GPU_RATE_KERNEL(k_rates3g, 128, dev_edac_rates_d(&v, i, 3, 1))
/* tvf: edac's pair terms without p̄ and dp/dt, under edac's caps (not measured for tvf) */
GPU_RATE_KERNEL(k_trates2, 80, dev_tvf_rates_d(&v, i, 2, 0))
GPU_RATE_KERNEL(k_trates2g, 80, dev_tvf_rates_d(&v, i, 2, 1))
GPU_RATE_KERNEL(k_trates3, 128, dev_tvf_rates_d(&v, i, 3, 0))
GPU_RATE_KERNEL(k_trates3g, 128, dev_tvf_rates_d(&v, i, 3, 1))
GPU_RATE_KERNEL(k_wrates2, 80, dev_wcsph_rates_d(&v, i, 2, 0))
GPU_RATE_KERNEL(k_wrates2g, 80, dev_wcsph_rates_d(&v, i, 2, 1))
GPU_RATE_KERNEL(k_wrates3, 80, dev_wcsph_rates_d(&v, i, 3, 0))
GPU_RATE_KERNEL(k_wrates3g, 80, dev_wcsph_rates_d(&v, i, 3, 1))
/* 001's family (dev_negi.h): one kernel per dimension and set of sums */
GPU_KERNEL(k_nvol, dev_negi_volumes(&v, i))
GPU_KERNEL(k_nfirst2r, dev_negi_first_d(&v, i, 2, 1, 1, 0, 1))
GPU_KERNEL(k_nfirst3r, dev_negi_first_d(&v, i, 3, 1, 1, 0, 1))
GPU_KERNEL(k_nfirst2rq, dev_negi_first_d(&v, i, 2, 1, 1, 1, 1))
GPU_KERNEL(k_nfirst3rq, dev_negi_first_d(&v, i, 3, 1, 1, 1, 1))
GPU_KERNEL(k_nfirst2s, dev_negi_first_d(&v, i, 2, 0, 1, 1, 0))
GPU_KERNEL(k_nfirst3s, dev_negi_first_d(&v, i, 3, 0, 1, 1, 0))
GPU_KERNEL(k_ncoupled2, dev_negi_coupled_d(&v, i, 2, 1, 0))
GPU_KERNEL(k_ncoupled3, dev_negi_coupled_d(&v, i, 3, 1, 0))
GPU_KERNEL(k_ncoupled2q, dev_negi_coupled_d(&v, i, 2, 1, 1))
GPU_KERNEL(k_ncoupled3q, dev_negi_coupled_d(&v, i, 3, 1, 1))
GPU_KERNEL(k_nkorz2, dev_negi_korzilius_d(&v, i, 2))
GPU_KERNEL(k_nkorz3, dev_negi_korzilius_d(&v, i, 3))
GPU_KERNEL(k_nfatehi2, dev_negi_fatehi_d(&v, i, 2))
GPU_KERNEL(k_nfatehi3, dev_negi_fatehi_d(&v, i, 3))
GPU_KERNEL(k_ncleary2, dev_negi_cleary_d(&v, i, 2))
GPU_KERNEL(k_ncleary3, dev_negi_cleary_d(&v, i, 3))
GPU_KERNEL(k_nrates2, dev_negi_rates_d(&v, i, 2))
GPU_KERNEL(k_nrates3, dev_negi_rates_d(&v, i, 3))
GPU_KERNEL(k_ipst_vol, dev_ipst_volumes(&v, i))
GPU_KERNEL(k_chi_max, dev_chi_max(&v, i))
GPU_KERNEL(k_ipst_shift2, dev_ipst_shift_d(&v, i, 2))
GPU_KERNEL(k_ipst_shift3, dev_ipst_shift_d(&v, i, 3))
GPU_KERNEL(k_ipst_move, dev_ipst_move(&v, i))
GPU_KERNEL(k_pst_shift2, dev_pst_shift_d(&v, i, 2, c))
GPU_KERNEL(k_pst_shift3, dev_pst_shift_d(&v, i, 3, c))
GPU_KERNEL(k_shift_end, dev_shift_end(&v, i, c != 0.0))
GPU_KERNEL(k_remesh2, dev_remesh_d(&v, i, 2))
GPU_KERNEL(k_remesh3, dev_remesh_d(&v, i, 3))
GPU_KERNEL(k_remesh_end, dev_remesh_end(&v, i))
/* the δ-SPH family (dev_delta.h): one rate kernel per dimension and shifting form */
GPU_KERNEL(k_dvol, dev_delta_volumes(&v, i))
GPU_KERNEL(k_drenorm2, dev_delta_renorm_d(&v, i, 2))
GPU_KERNEL(k_drenorm3, dev_delta_renorm_d(&v, i, 3))
GPU_KERNEL(k_drates2, dev_delta_rates_d(&v, i, 2, DELTA_SHIFT_NONE))
GPU_KERNEL(k_drates3, dev_delta_rates_d(&v, i, 3, DELTA_SHIFT_NONE))
GPU_KERNEL(k_drates2s, dev_delta_rates_d(&v, i, 2, DELTA_SHIFT_SUN))
GPU_KERNEL(k_drates3s, dev_delta_rates_d(&v, i, 3, DELTA_SHIFT_SUN))
GPU_KERNEL(k_drates2d, dev_delta_rates_d(&v, i, 2, DELTA_SHIFT_APP_D))
GPU_KERNEL(k_drates3d, dev_delta_rates_d(&v, i, 3, DELTA_SHIFT_APP_D))

int cu_alloc(void **p, size_t bytes)
{
    *p = NULL;
    return fail(cudaMalloc(p, bytes ? bytes : 1), "cudaMalloc");
}
void cu_release(void *p)
{
    cudaFree(p);
}
int cu_put(void *dev, const void *host, size_t bytes)
{
    return fail(cudaMemcpy(dev, host, bytes, cudaMemcpyHostToDevice), "cudaMemcpy to the device");
}
int cu_get(void *host, const void *dev, size_t bytes)
{
    return fail(cudaMemcpy(host, dev, bytes, cudaMemcpyDeviceToHost), "cudaMemcpy from the device");
}
int cu_zero(void *dev, size_t bytes)
{
    return fail(cudaMemsetAsync(dev, 0, bytes), "cudaMemset");
}

/* Threads per block: the pair passes (density, rates) hold many registers, and smaller blocks
 * keep more of them resident (64 was the fastest or within 3 % of it on an H200 at the rate
 * kernels' caps, bench/gpu_tune.sh); CONSPH_GPU_BLOCK_PAIR (the pair passes) and CONSPH_GPU_BLOCK (every
 * other kernel) override the defaults for the launch-shape sweep (bench/gpu_tune.sh). Read at
 * each launch (a lookup in the environment, far below a launch's few microseconds); 0 with the
 * message set when the value is not a multiple of 32 from 32 to 1024. */
unsigned block_size(gpu_kernel k)
{
    const int pair = k == GK_DENSITY || k == GK_RATES;
    const char *name = pair ? "CONSPH_GPU_BLOCK_PAIR" : "CONSPH_GPU_BLOCK";
    const char *e = getenv(name);
    if (!e || !*e) return pair ? 64u : 256u;
    char *end = NULL;
    const long b = strtol(e, &end, 10);
    if (*end || b < 32 || b > 1024 || b % 32) {
        snprintf(cuda_err, sizeof cuda_err,
                 "%s=%s: threads per block must be a multiple of 32 from 32 to 1024", name, e);
        return 0;
    }
    return (unsigned)b;
}

int cu_launch(gpu_kernel k, size_t count, const gpu_view *v, double c)
{
    if (count == 0) return 0;
    const unsigned threads = block_size(k);
    if (!threads) return 1;
    const unsigned blocks = (unsigned)((count + threads - 1) / threads);
    switch (k) {
    case GK_BIN: k_bin<<<blocks, threads>>>(*v, count, c); break;
    case GK_COUNT: k_count<<<blocks, threads>>>(*v, count, c); break;
    case GK_SCATTER: k_scatter<<<blocks, threads>>>(*v, count, c); break;
    case GK_CELL_SORT: k_cell_sort<<<blocks, threads>>>(*v, count, c); break;
    case GK_SLOTS: k_slots<<<blocks, threads>>>(*v, count, c); break;
    case GK_PERMUTE: k_permute<<<blocks, threads>>>(*v, count, c); break;
    case GK_SAVE: k_save<<<blocks, threads>>>(*v, count, c); break;
    case GK_ADVANCE: k_advance<<<blocks, threads>>>(*v, count, c); break;
    case GK_KDK_DRIFT: k_kdk_drift<<<blocks, threads>>>(*v, count, c); break;
    case GK_KDK_KICK: k_kdk_kick<<<blocks, threads>>>(*v, count, c); break;
    case GK_PAIR_SUM: k_pair_sum<<<blocks, threads>>>(*v, count, c); break;
    case GK_DENSITY:
        (v->scheme == GS_TVF    ? (v->d == 2 ? k_tdensity2 : k_tdensity3)
         : v->scheme != GS_EDAC ? k_wprep
         : v->d == 2            ? k_density2
                                : k_density3)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_RATES:
        if (v->scheme == GS_TVF && v->d == 2)
            (v->grads ? k_trates2g : k_trates2)<<<blocks, threads>>>(*v, count, c);
        else if (v->scheme == GS_TVF)
            (v->grads ? k_trates3g : k_trates3)<<<blocks, threads>>>(*v, count, c);
        else if (v->scheme == GS_EDAC && v->d == 2)
            (v->grads ? k_rates2g : k_rates2)<<<blocks, threads>>>(*v, count, c);
        else if (v->scheme == GS_EDAC)
            (v->grads ? k_rates3g : k_rates3)<<<blocks, threads>>>(*v, count, c);
        else if (v->d == 2)
            (v->grads ? k_wrates2g : k_wrates2)<<<blocks, threads>>>(*v, count, c);
        else
            (v->grads ? k_wrates3g : k_wrates3)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_NEGI_VOLUMES: k_nvol<<<blocks, threads>>>(*v, count, c); break;
    case GK_NEGI_FIRST:
        if (v->kit_p && v->kit_q)
            (v->d == 2 ? k_nfirst2rq : k_nfirst3rq)<<<blocks, threads>>>(*v, count, c);
        else if (v->kit_p)
            (v->d == 2 ? k_nfirst2r : k_nfirst3r)<<<blocks, threads>>>(*v, count, c);
        else
            (v->d == 2 ? k_nfirst2s : k_nfirst3s)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_NEGI_COUPLED:
        if (v->lap_q)
            (v->d == 2 ? k_ncoupled2q : k_ncoupled3q)<<<blocks, threads>>>(*v, count, c);
        else
            (v->d == 2 ? k_ncoupled2 : k_ncoupled3)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_NEGI_KORZ:
        (v->d == 2 ? k_nkorz2 : k_nkorz3)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_NEGI_FATEHI:
        (v->d == 2 ? k_nfatehi2 : k_nfatehi3)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_NEGI_CLEARY:
        (v->d == 2 ? k_ncleary2 : k_ncleary3)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_NEGI_RATES:
        (v->d == 2 ? k_nrates2 : k_nrates3)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_IPST_VOLUMES: k_ipst_vol<<<blocks, threads>>>(*v, count, c); break;
    case GK_CHI_MAX: k_chi_max<<<blocks, threads>>>(*v, count, c); break;
    case GK_IPST_SHIFT:
        (v->d == 2 ? k_ipst_shift2 : k_ipst_shift3)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_IPST_MOVE: k_ipst_move<<<blocks, threads>>>(*v, count, c); break;
    case GK_PST_SHIFT:
        (v->d == 2 ? k_pst_shift2 : k_pst_shift3)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_SHIFT_END: k_shift_end<<<blocks, threads>>>(*v, count, c); break;
    case GK_REMESH: (v->d == 2 ? k_remesh2 : k_remesh3)<<<blocks, threads>>>(*v, count, c); break;
    case GK_REMESH_END: k_remesh_end<<<blocks, threads>>>(*v, count, c); break;
    case GK_DELTA_VOLUMES: k_dvol<<<blocks, threads>>>(*v, count, c); break;
    case GK_DELTA_RENORM:
        (v->d == 2 ? k_drenorm2 : k_drenorm3)<<<blocks, threads>>>(*v, count, c);
        break;
    case GK_DELTA_RATES:
        if (v->dshift == DELTA_SHIFT_SUN)
            (v->d == 2 ? k_drates2s : k_drates3s)<<<blocks, threads>>>(*v, count, c);
        else if (v->dshift == DELTA_SHIFT_APP_D)
            (v->d == 2 ? k_drates2d : k_drates3d)<<<blocks, threads>>>(*v, count, c);
        else
            (v->d == 2 ? k_drates2 : k_drates3)<<<blocks, threads>>>(*v, count, c);
        break;
    }
    return fail(cudaGetLastError(), "kernel launch");
}

/* CUB's scratch of the scan, kept per thread and given back when the thread ends. */
struct scan_scratch {
    void *p = nullptr;
    size_t bytes = 0;
    ~scan_scratch()
    {
        if (p) cudaFree(p);
    }
};
thread_local scan_scratch scan_tmp;

int cu_scan(const gpu_view *v)
{
    const int items = (int)(v->g.ncells + 1);
    size_t need = 0;
    if (fail(cub::DeviceScan::ExclusiveSum(NULL, need, v->count, v->start, items), "scan size"))
        return 1;
    if (need > scan_tmp.bytes) {
        cudaFree(scan_tmp.p);
        scan_tmp.p = nullptr;
        scan_tmp.bytes = 0;
        if (fail(cudaMalloc(&scan_tmp.p, need), "cudaMalloc (scan)")) return 1;
        scan_tmp.bytes = need;
    }
    return fail(cub::DeviceScan::ExclusiveSum(scan_tmp.p, need, v->count, v->start, items),
                "scan");
}

const char *cu_error(void)
{
    return cuda_err;
}

const gpu_backend cuda_backend = {"CUDA", cu_alloc, cu_release, cu_put, cu_get,
                                  cu_zero, cu_launch, cu_scan,   cu_error};

} // namespace

extern "C" const gpu_backend *gpu_cuda_backend(char *why, size_t len)
{
    int count = 0;
    const cudaError_t e = cudaGetDeviceCount(&count);
    if (e != cudaSuccess || count == 0) {
        snprintf(why, len, "no CUDA device found (%s)",
                 e != cudaSuccess ? cudaGetErrorString(e) : "cudaGetDeviceCount: 0 devices");
        return NULL;
    }
    return &cuda_backend;
}
