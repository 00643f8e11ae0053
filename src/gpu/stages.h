/* Per-stage timing of the GPU step (bench_gpu --stages, bench/gpu_tune.sh): a backend that
 * forwards every call to another and, while enabled, brackets each timed call with two marks of
 * a timer (CUDA events in the device's stream order on the CUDA backend, the host clock on the
 * emulation), summed per stage when collected. Only bench_gpu wraps a backend, so a run's
 * path (consph run --device gpu) is untouched and pays nothing. */
#ifndef CONSPH_GPU_STAGES_H
#define CONSPH_GPU_STAGES_H

#include "gpu/gpu_internal.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The stages of a step: every kernel of gpu_kernel (other: one this table does not name), the
 * counting sort's prefix sums and zeroing, and the copies to and from the device. */
typedef enum gpu_stage {
    GST_BIN,
    GST_COUNT,
    GST_SCAN,
    GST_SCATTER,
    GST_CELL_SORT,
    GST_SLOTS,
    GST_PERMUTE,
    GST_SAVE,
    GST_ADVANCE,
    GST_DENSITY,
    GST_RATES,
    GST_NEGI_VOLUMES, /* 001's family (dev_negi.h) */
    GST_NEGI_FIRST,
    GST_NEGI_COUPLED,
    GST_NEGI_CLEARY,
    GST_NEGI_FATEHI,
    GST_NEGI_KORZ,
    GST_NEGI_RATES,
    GST_IPST_VOLUMES,
    GST_CHI_MAX,
    GST_IPST_SHIFT,
    GST_IPST_MOVE,
    GST_PST_SHIFT,
    GST_SHIFT_END,
    GST_REMESH,
    GST_REMESH_END,
    GST_DELTA_VOLUMES, /* the δ-SPH family (dev_delta.h) */
    GST_DELTA_RENORM,
    GST_DELTA_RATES,
    GST_OTHER,
    GST_ZERO,
    GST_PUT,
    GST_GET,
    GST_N
} gpu_stage;

/* The names bench_gpu prints (stage_<name>_ms). */
extern const char *const gpu_stage_names[GST_N];

/* Marks in the order of the device's work and the time between two of them. */
typedef struct gpu_timer {
    int (*mark)(void);          /* a new mark, recorded now; its index, or -1 */
    double (*ms)(int a, int b); /* milliseconds from mark a to mark b, once both have passed */
    void (*clear)(void);        /* forgets every mark (their storage is reused) */
} gpu_timer;

/* CUDA events (stages.cu); NULL in a build without CUDA. */
const gpu_timer *gpu_cuda_timer(void);
/* The host's clock: right for the emulation, whose calls return when their work is done. */
extern const gpu_timer gpu_host_timer;

/* The timing backend over `inner` (one at a time: a second call replaces the first); it starts
 * disabled, forwarding each call with no marks. */
const gpu_backend *gpu_stages_wrap(const gpu_backend *inner, const gpu_timer *timer);
void gpu_stages_enable(int on);
/* Milliseconds and calls per stage since the last collect (waits for the marked work), then
 * forgets them; 0, or 1 when a mark could not be made (the sums then miss those calls). */
int gpu_stages_collect(double ms[GST_N], long calls[GST_N]);

#ifdef __cplusplus
}
#endif

#endif
