/* A host emulation of the few CUDA features probe.cu uses, so that its kernels and their launch
 * sizes run, serially, on a machine without a GPU (check_emul.sh). Blocks and threads run in
 * reverse order, so that the atomic scatter fills each cell backwards and the per-cell sort must
 * restore the index order. Not a CUDA implementation: no concurrency, no memory spaces. */
#ifndef PROBE_CUDA_EMUL_H
#define PROBE_CUDA_EMUL_H
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define __global__ static
#define __constant__ static

struct emul_dim3 {
    unsigned x;
};
static emul_dim3 blockIdx, threadIdx, blockDim;

#define EMUL_LAUNCH(kernel, grid, block, ...)                                                      \
    do {                                                                                           \
        blockDim.x = (unsigned)(block);                                                            \
        for (long bb_ = (long)(grid)-1; bb_ >= 0; --bb_)                                           \
            for (long tt_ = (long)(block)-1; tt_ >= 0; --tt_) {                                    \
                blockIdx.x = (unsigned)bb_;                                                        \
                threadIdx.x = (unsigned)tt_;                                                       \
                kernel(__VA_ARGS__);                                                               \
            }                                                                                      \
    } while (0)

static int atomicAdd(int *p, int v)
{
    int old = *p;
    *p += v;
    return old;
}

typedef int cudaError_t;
enum { cudaSuccess = 0 };
enum cudaMemcpyKind { cudaMemcpyHostToDevice, cudaMemcpyDeviceToHost };
struct cudaDeviceProp {
    char name[256];
    int major, minor, multiProcessorCount;
    size_t totalGlobalMem;
};
static size_t emul_used;
static const char *cudaGetErrorString(cudaError_t)
{
    return "emulated error";
}
static cudaError_t cudaGetDeviceCount(int *n)
{
    *n = 1;
    return cudaSuccess;
}
static cudaError_t cudaGetDeviceProperties(cudaDeviceProp *p, int)
{
    memset(p, 0, sizeof *p);
    strcpy(p->name, "host emulation");
    p->totalGlobalMem = (size_t)1 << 34;
    return cudaSuccess;
}
static cudaError_t cudaDriverGetVersion(int *v)
{
    *v = 0;
    return cudaSuccess;
}
static cudaError_t cudaRuntimeGetVersion(int *v)
{
    *v = 0;
    return cudaSuccess;
}
static cudaError_t cudaFree(void *p)
{
    free(p);
    return cudaSuccess;
}
static cudaError_t cudaMemGetInfo(size_t *free_b, size_t *total)
{
    *total = (size_t)1 << 34;
    *free_b = *total - emul_used;
    return cudaSuccess;
}
template <class T> static cudaError_t cudaMalloc(T **p, size_t bytes)
{
    *p = (T *)malloc(bytes);
    /* poison, so that a kernel that reads what nobody wrote shows */
    if (*p) memset((void *)*p, 0xA5, bytes);
    emul_used += bytes;
    return *p ? cudaSuccess : 2;
}
static cudaError_t cudaMemcpy(void *d, const void *s, size_t bytes, cudaMemcpyKind)
{
    memcpy(d, s, bytes);
    return cudaSuccess;
}
static cudaError_t cudaMemset(void *d, int v, size_t bytes)
{
    memset(d, v, bytes);
    return cudaSuccess;
}
template <class T> static cudaError_t cudaMemcpyToSymbol(T &sym, const void *s, size_t bytes)
{
    memcpy((void *)&sym, s, bytes);
    return cudaSuccess;
}
static cudaError_t cudaGetLastError(void)
{
    return cudaSuccess;
}
static cudaError_t cudaDeviceSynchronize(void)
{
    return cudaSuccess;
}
#endif
