/* consph gpu: the solver step on one NVIDIA GPU (docs/gpu.md).
 *
 * `consph run ... --device gpu` runs the whole step on the GPU: the particles stay resident
 * there, the cell lists are built and sorted there (a deterministic counting sort), one kernel
 * per pass; the host gets the state back only for the log, snapshots and the end of the run. The
 * GPU computes with the same per-particle functions and pair terms as the CPU solver, in the same
 * neighbour order: without FMA contraction (nvcc -fmad=false, which the build sets) a GPU run
 * equals the CPU run bit for bit. A build without CUDA (CONSPH_CUDA off, or no nvcc) has no GPU
 * and says so. */
#ifndef CONSPH_GPU_H
#define CONSPH_GPU_H

#include <stddef.h>

#include "consph/solver.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum consph_device { CONSPH_DEVICE_CPU, CONSPH_DEVICE_GPU } consph_device;

/* The schemes the GPU runs, comma-separated (e.g. "edac,wcsph,l-ipst-c,..."). */
const char *consph_gpu_schemes(void);
/* 1 when this build has GPU support and finds a device; else 0 with the reason in why. */
int consph_gpu_available(char *why, size_t len);
/* CONSPH_OK when a run of these parameters can go on the GPU; CONSPH_EINVAL naming the option
 * (scheme, integrator, kernel, skin) and its allowed values when not, or naming what the build
 * or the machine lacks. */
int consph_gpu_check(const consph_run_params *prm);
/* Moves the solver's steps onto the device (CPU: back to the host, with the state copied
 * back). On the device, consph_solver_particles holds every array as of the last step that
 * ended the run or a snapshot, and at log samples and the authors' output times only the
 * arrays the host reads there (positions, u, p, ϱ, ids, mass, the rates' au and ∇·u;
 * docs/gpu.md): call this with CONSPH_DEVICE_CPU to read any other array mid-run. */
int consph_solver_set_device(consph_solver *s, consph_device device);
/* Where the solver's steps run: CONSPH_DEVICE_GPU from a consph_solver_set_device to the GPU
 * until one back to the CPU. */
consph_device consph_solver_device(const consph_solver *s);
/* Makes the host's copy of every array the state the last step left, mid-run: on the device,
 * every array copied back (and the host's search rebuilt on the positions), the steps staying
 * on the device; on the CPU, nothing. For reading a field, a checkpoint or the particles of a
 * run on the GPU between two steps (the Python module's Solver.field does). */
int consph_solver_sync(consph_solver *s);

#ifdef __cplusplus
}
#endif

#endif
