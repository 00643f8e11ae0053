/* CONSPH_HD: the qualifier of a function written once for the host and the GPU. Plain C11 code
 * (the library, the host emulation of src/gpu/) sees nothing; nvcc sees __host__ __device__, so
 * that the same static inline functions (the scheme families' iact.h pair terms, the per-particle
 * functions of src/gpu/dev.h) compile into the CUDA kernels of src/gpu/cuda.cu. */
#ifndef CONSPH_GPU_HD_H
#define CONSPH_GPU_HD_H

#if defined(__CUDACC__)
#define CONSPH_HD __host__ __device__
#else
#define CONSPH_HD
#endif

#endif
