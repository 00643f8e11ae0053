/* The GPU probe's CUDA build: the pair loop of probe_iact.h on one NVIDIA GPU, one thread per
 * particle, each gathering its neighbours in the fixed cell order; the cell list is built on the
 * device (cell index and counts by atomics, a blocked scan, an atomic scatter made deterministic by
 * sorting each cell's few entries by particle index, then the particles permuted into that order).
 * Its results must equal probe_cpu's in the same order (bitwise with -fmad=false and
 * -ffp-contract=off on the host). */
#include <cuda_runtime.h>

#include "probe_host.h"

#define CHECK(call)                                                                                \
    do {                                                                                           \
        cudaError_t e_ = (call);                                                                   \
        if (e_ != cudaSuccess) {                                                                   \
            fprintf(stderr, "probe_cuda: %s failed: %s (%s:%d)\n", #call, cudaGetErrorString(e_),  \
                    __FILE__, __LINE__);                                                           \
            exit(1);                                                                               \
        }                                                                                          \
    } while (0)

#define BLOCK 128

/* The run's constants, in constant memory: a kernel parameter whose address the shared functions
 * take would be copied to each thread's local memory. */
__constant__ probe_consts d_c;

static int blocks(long n)
{
    return (int)((n + BLOCK - 1) / BLOCK);
}

__global__ void k_cell_count(const double *pos, int *cell, int *count)
{
    const probe_consts &c = d_c;
    const int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= c.n) return;
    cell[i] = probe_cell_of(&c, pos, i);
    atomicAdd(&count[cell[i]], 1);
}

__global__ void k_scan_sum(const int *count, int *bsum, int ncell)
{
    const int b = blockIdx.x * blockDim.x + threadIdx.x;
    if (b < PROBE_SCAN_BLOCKS) bsum[b] = probe_scan_block_sum(count, ncell, b);
}

__global__ void k_scan_top(int *bsum, int *off, int ncell)
{
    probe_scan_blocks(bsum, off, ncell);
}

__global__ void k_scan_write(const int *count, const int *bsum, int *off, int ncell)
{
    const int b = blockIdx.x * blockDim.x + threadIdx.x;
    if (b < PROBE_SCAN_BLOCKS) probe_scan_block_write(count, bsum, off, ncell, b);
}

__global__ void k_scatter(int n, const int *cell, const int *off, int *fill, int *idx)
{
    const int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    const int slot = atomicAdd(&fill[cell[i]], 1);
    idx[off[cell[i]] + slot] = i;
}

__global__ void k_sort_cells(int ncell, const int *off, int *idx)
{
    const int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k < ncell) probe_sort_cell(off, idx, k);
}

__global__ void k_permute(const int *idx, const double *pos, const double *vel, const double *rho,
                          double *spos, double *svel, double *srho)
{
    const probe_consts &c = d_c;
    const long n = c.n;
    const int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= c.n) return;
    const long i = idx[k];
    for (int a = 0; a < c.d; ++a) {
        spos[a * n + k] = pos[a * n + i];
        svel[a * n + k] = vel[a * n + i];
    }
    srho[k] = rho[i];
}

__global__ void k_density(const double *spos, const int *off, double *rho_a)
{
    const probe_consts &c = d_c;
    const int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k < c.n) rho_a[k] = probe_density(&c, spos, off, k);
}

__global__ void k_count(const double *spos, const int *off, int *cnt)
{
    const probe_consts &c = d_c;
    const int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k < c.n) cnt[k] = probe_count(&c, spos, off, k);
}

__global__ void k_eos(const double *srho, double *p)
{
    const probe_consts &c = d_c;
    const int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k < c.n) p[k] = probe_tait(&c, srho[k]);
}

__global__ void k_rate(const double *spos, const double *svel, const double *srho, const double *p,
                       const int *off, double *rate)
{
    const probe_consts &c = d_c;
    const long n = c.n;
    const int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= c.n) return;
    double out[4];
    probe_rate(&c, spos, svel, srho, p, off, k, out);
    for (int q = 0; q < 4; ++q) rate[q * n + k] = out[q];
}

int main(int argc, char **argv)
{
    probe_opts o;
    int rc = probe_parse(argc, argv, &o);
    if (rc) return rc;
    int ndev = 0;
    cudaError_t e = cudaGetDeviceCount(&ndev);
    if (e != cudaSuccess || ndev < 1) {
        fprintf(stderr, "probe_cuda: no CUDA device (%s)\n",
                e != cudaSuccess ? cudaGetErrorString(e) : "count 0");
        return 3;
    }
    cudaDeviceProp prop;
    CHECK(cudaGetDeviceProperties(&prop, 0));
    int drv = 0, rt = 0;
    cudaDriverGetVersion(&drv);
    cudaRuntimeGetVersion(&rt);
    printf("DEVICE name=\"%s\" sm=%d%d mem_GiB=%.1f sms=%d driver=%d runtime=%d\n", prop.name,
           prop.major, prop.minor, prop.totalGlobalMem / 1073741824.0, prop.multiProcessorCount,
           drv, rt);
    const probe_consts c = probe_setup(&o);
    const long n = c.n, d = c.d;
    double *pos = (double *)malloc(sizeof(double) * d * n);
    double *vel = (double *)malloc(sizeof(double) * d * n);
    double *rho = (double *)malloc(sizeof(double) * n);
    double *rho_a = (double *)malloc(sizeof(double) * n);
    double *rate = (double *)malloc(sizeof(double) * n * 4);
    int *cnt = (int *)malloc(sizeof(int) * n);
    if (!pos || !vel || !rho || !rho_a || !rate || !cnt) {
        fprintf(stderr, "probe_cuda: out of host memory for N = %ld\n", n);
        return 1;
    }
    probe_init(&c, pos, vel, rho);

    CHECK(cudaFree(0)); /* the context, before measuring free memory */
    CHECK(cudaMemcpyToSymbol(d_c, &c, sizeof c));
    size_t free0 = 0, total = 0, free1 = 0;
    CHECK(cudaMemGetInfo(&free0, &total));
    double *d_pos, *d_vel, *d_rho, *d_spos, *d_svel, *d_srho, *d_rho_a, *d_p, *d_rate;
    int *d_cell, *d_count, *d_off, *d_bsum, *d_fill, *d_idx, *d_cnt;
    CHECK(cudaMalloc(&d_pos, sizeof(double) * d * n));
    CHECK(cudaMalloc(&d_vel, sizeof(double) * d * n));
    CHECK(cudaMalloc(&d_rho, sizeof(double) * n));
    CHECK(cudaMalloc(&d_spos, sizeof(double) * d * n));
    CHECK(cudaMalloc(&d_svel, sizeof(double) * d * n));
    CHECK(cudaMalloc(&d_srho, sizeof(double) * n));
    CHECK(cudaMalloc(&d_rho_a, sizeof(double) * n));
    CHECK(cudaMalloc(&d_p, sizeof(double) * n));
    CHECK(cudaMalloc(&d_rate, sizeof(double) * n * 4));
    CHECK(cudaMalloc(&d_cell, sizeof(int) * n));
    CHECK(cudaMalloc(&d_idx, sizeof(int) * n));
    CHECK(cudaMalloc(&d_count, sizeof(int) * c.ncell));
    CHECK(cudaMalloc(&d_fill, sizeof(int) * c.ncell));
    CHECK(cudaMalloc(&d_off, sizeof(int) * (c.ncell + 1)));
    CHECK(cudaMalloc(&d_bsum, sizeof(int) * PROBE_SCAN_BLOCKS));
    CHECK(cudaMemGetInfo(&free1, &total));
    CHECK(cudaMalloc(&d_cnt, sizeof(int) * n)); /* the pair count's, not the step's */
    CHECK(cudaMemcpy(d_pos, pos, sizeof(double) * d * n, cudaMemcpyHostToDevice));
    CHECK(cudaMemcpy(d_vel, vel, sizeof(double) * d * n, cudaMemcpyHostToDevice));
    CHECK(cudaMemcpy(d_rho, rho, sizeof(double) * n, cudaMemcpyHostToDevice));

    char where[300];
    snprintf(where, sizeof where, "%s", prop.name);
    for (char *s = where; *s; ++s)
        if (*s == ' ') *s = '_';
    probe_result r = {"cuda", where, 1, 0, 1e30, 1e30, 1e30, 0.0};
    r.bytes_per_particle = (double)(free0 - free1) / n;
    const int sb = (PROBE_SCAN_BLOCKS + BLOCK - 1) / BLOCK;
    for (int rep = -1; rep < o.reps; ++rep) { /* rep -1: warm-up, not timed */
        CHECK(cudaDeviceSynchronize());
        double t0 = probe_now();
        CHECK(cudaMemset(d_count, 0, sizeof(int) * c.ncell));
        CHECK(cudaMemset(d_fill, 0, sizeof(int) * c.ncell));
        k_cell_count<<<blocks(n), BLOCK>>>(d_pos, d_cell, d_count);
        k_scan_sum<<<sb, BLOCK>>>(d_count, d_bsum, c.ncell);
        k_scan_top<<<1, 1>>>(d_bsum, d_off, c.ncell);
        k_scan_write<<<sb, BLOCK>>>(d_count, d_bsum, d_off, c.ncell);
        k_scatter<<<blocks(n), BLOCK>>>(c.n, d_cell, d_off, d_fill, d_idx);
        k_sort_cells<<<blocks(c.ncell), BLOCK>>>(c.ncell, d_off, d_idx);
        k_permute<<<blocks(n), BLOCK>>>(d_idx, d_pos, d_vel, d_rho, d_spos, d_svel, d_srho);
        CHECK(cudaGetLastError());
        CHECK(cudaDeviceSynchronize());
        double t1 = probe_now();
        k_density<<<blocks(n), BLOCK>>>(d_spos, d_off, d_rho_a);
        CHECK(cudaGetLastError());
        CHECK(cudaDeviceSynchronize());
        double t2 = probe_now();
        k_eos<<<blocks(n), BLOCK>>>(d_srho, d_p);
        k_rate<<<blocks(n), BLOCK>>>(d_spos, d_svel, d_srho, d_p, d_off, d_rate);
        CHECK(cudaGetLastError());
        CHECK(cudaDeviceSynchronize());
        double t3 = probe_now();
        if (rep < 0) continue;
        if (t1 - t0 < r.t_cells) r.t_cells = t1 - t0;
        if (t2 - t1 < r.t_a) r.t_a = t2 - t1;
        if (t3 - t2 < r.t_b) r.t_b = t3 - t2;
    }
    k_count<<<blocks(n), BLOCK>>>(d_spos, d_off, d_cnt);
    CHECK(cudaGetLastError());
    CHECK(cudaMemcpy(cnt, d_cnt, sizeof(int) * n, cudaMemcpyDeviceToHost));
    for (long k = 0; k < n; ++k) r.pairs += cnt[k];
    CHECK(cudaMemcpy(rho_a, d_rho_a, sizeof(double) * n, cudaMemcpyDeviceToHost));
    CHECK(cudaMemcpy(rate, d_rate, sizeof(double) * n * 4, cudaMemcpyDeviceToHost));
    probe_print(&c, &o, &r);
    if (o.dump && probe_dump(o.dump, &c, rho_a, rate)) rc = 1;

    /* the device's cell order must be the host's stable counting sort */
    int *cell = (int *)malloc(sizeof(int) * n), *idx = (int *)malloc(sizeof(int) * n);
    int *off = (int *)malloc(sizeof(int) * (c.ncell + 1)), *didx = (int *)malloc(sizeof(int) * n);
    probe_cells_host(&c, pos, cell, off, idx);
    CHECK(cudaMemcpy(didx, d_idx, sizeof(int) * n, cudaMemcpyDeviceToHost));
    long bad = 0;
    for (long k = 0; k < n; ++k) bad += didx[k] != idx[k];
    printf("CELLORDER %s mismatches=%ld\n", bad ? "FAIL" : "ok", bad);
    if (bad) rc = 1;
    return rc;
}
