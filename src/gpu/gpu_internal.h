/* The GPU solver's host side (gpu.c) and its backends: the CUDA one (cuda.cu, built with
 * CONSPH_CUDA) and the host emulation (gpu.c), which runs the same per-particle functions
 * (dev.h) in loops and is what make check tests against the CPU solver. */
#ifndef CONSPH_GPU_INTERNAL_H
#define CONSPH_GPU_INTERNAL_H

#include <stddef.h>

#include "gpu/dev.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The per-thread functions of dev.h a backend launches over `count` threads. */
typedef enum gpu_kernel {
    GK_BIN,       /* dev_bin, per particle */
    GK_COUNT,     /* dev_count */
    GK_SCATTER,   /* dev_scatter */
    GK_CELL_SORT, /* dev_cell_sort, per cell */
    GK_SLOTS,     /* dev_slots, per slot */
    GK_PERMUTE,   /* dev_permute, per slot */
    GK_SAVE,      /* dev_save_start */
    GK_ADVANCE,   /* dev_advance with the weight c */
    GK_KDK_DRIFT, /* dev_kdk_drift with c = Δt (tvf) */
    GK_KDK_KICK,  /* dev_kdk_kick with c = Δt/2 (tvf) */
    GK_PAIR_SUM,  /* dev_pair_sum, per GPU_PAIR_CHUNK particles */
    GK_DENSITY,   /* dev_pre_rates: edac's and tvf's density pass, wcsph's per-particle values */
    GK_RATES,     /* dev_rates */
    /* 001's family (dev_negi.h), per particle */
    GK_NEGI_VOLUMES, /* dev_negi_volumes */
    GK_NEGI_FIRST,   /* dev_negi_first_any: the sums the view's kit_* flags name */
    GK_NEGI_COUPLED, /* dev_negi_coupled_any */
    GK_NEGI_CLEARY,  /* dev_negi_cleary_any */
    GK_NEGI_FATEHI,  /* dev_negi_fatehi_any */
    GK_NEGI_KORZ,    /* dev_negi_korzilius_any */
    GK_NEGI_RATES,   /* dev_negi_rates */
    GK_IPST_VOLUMES, /* dev_ipst_volumes */
    GK_CHI_MAX,      /* dev_chi_max, per GPU_MAX_CHUNK particles */
    GK_IPST_SHIFT,   /* dev_ipst_shift_any */
    GK_IPST_MOVE,    /* dev_ipst_move */
    GK_PST_SHIFT,    /* dev_pst_shift_any */
    GK_SHIFT_END,    /* dev_shift_end, adding IPST's total when c != 0 */
    GK_REMESH,       /* dev_remesh_any, on the joint view */
    GK_REMESH_END,   /* dev_remesh_end */
    /* the δ-SPH family (dev_delta.h), per particle */
    GK_DELTA_VOLUMES, /* dev_delta_volumes */
    GK_DELTA_RENORM,  /* dev_delta_renorm */
    GK_DELTA_RATES    /* dev_delta_rates */
} gpu_kernel;

typedef struct gpu_backend {
    const char *name;
    /* 0 on success; else the backend's message is backend->error() */
    int (*alloc)(void **p, size_t bytes);
    void (*release)(void *p);
    int (*put)(void *dev, const void *host, size_t bytes);
    int (*get)(void *host, const void *dev, size_t bytes);
    int (*zero)(void *dev, size_t bytes);
    int (*launch)(gpu_kernel k, size_t count, const gpu_view *v, double c);
    /* start[0..ncells] = the exclusive prefix sums of count[0..ncells] (count[ncells] = 0) */
    int (*scan)(const gpu_view *v);
    const char *(*error)(void);
} gpu_backend;

/* Runs the per-thread functions in loops on the host (the scatter in reverse particle order,
 * so that the per-cell sort has to restore the order, as after a GPU's atomics). */
extern const gpu_backend gpu_emulation;

/* The CUDA backend (cuda.cu): NULL with a message in why when this build has none or no device
 * is found. */
const gpu_backend *gpu_cuda_backend(char *why, size_t len);

struct consph_solver;
typedef struct gpu_run gpu_run;
/* Moves a solver's particles onto the backend's device (a copy of every particle array); the
 * solver's steps then run there (gpu_step) until gpu_free. */
int gpu_attach(struct consph_solver *s, const gpu_backend *be);
/* One step of dt on the device; copies the state back to the host when the step's end is read
 * there (a log sample, a snapshot's gradients, the last step), and says so in *synced; the
 * authors' measure's output times are copied back by the solver's step_close. */
int gpu_step(struct consph_solver *s, double dt, int *synced);
/* After a step on the device, the scheme's regularisation there (IPST when due, as the CPU's
 * negi/scheme.c regularise_ipst), and the copy back as gpu_step decides it, in *synced. */
int gpu_regularise(struct consph_solver *s, int *synced);
/* Copies the device's state into the solver's particles and rebuilds the host search. */
int gpu_download(struct consph_solver *s);
/* The same for the arrays a log sample or the authors' measure reads only (diag.c's
 * solver_sample_fields and the positions); the others stay stale on the host until a
 * gpu_download. */
int gpu_download_sample(struct consph_solver *s);
/* How many times the state was copied back since the attach (either call; 0 on the CPU), and
 * the bytes those copies moved. */
long gpu_download_count(const struct consph_solver *s);
long long gpu_download_bytes(const struct consph_solver *s);
void gpu_free(struct gpu_run *g);
/* The device memory the solver's GPU state holds (what gpu_attach allocated; 0 on the CPU). */
size_t gpu_device_bytes(const struct consph_solver *s);
/* Whether the solver's steps run on the host emulation (CONSPH_GPU_BACKEND=emulation). */
int gpu_emulated(const struct consph_solver *s);

#ifdef __cplusplus
}
#endif

#endif
