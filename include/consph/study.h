/* consph study: what a convergence study needs besides the operators — manufactured fields with
 * exact derivatives, error norms, the least-squares order of convergence with its standard
 * error, the error bounds and resolution scaling law of 003, and 001's total-force ratio. */
#ifndef CONSPH_STUDY_H
#define CONSPH_STUDY_H

#include <stdio.h>

#include "consph/core.h"
#include "consph/io.h"
#include "consph/layout.h"
#include "consph/ops.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- Order of convergence (001 footnote 2) ------------------------------------------------- */

/* Least-squares fit log(err) = c - order * log(resolution) over the points with err > 0.
 * A positive order means the error falls as the resolution grows. */
typedef struct consph_order_fit {
    double order;
    double order_stderr; /* standard error of the slope (NaN with two points: none can be had) */
    double intercept;
    int npoints;
} consph_order_fit;
/* CONSPH_ENUMERIC when fewer than two errors are positive, the resolutions are all equal, or
 * any error or resolution is not finite (a wrong result is never left out silently). */
int consph_fit_order(const double *resolution, const double *err, int n, consph_order_fit *fit);
/* "2.013 ± 0.004" (digits decimals, `pm` between), "2.013 ± n/a" without a standard error, "n/a"
 * without an order; returns buf. */
const char *consph_order_text(const consph_order_fit *fit, int digits, const char *pm, char *buf,
                              size_t size);

/* ---- Error norms ---------------------------------------------------------------------------- */

/* Per-particle error e_i = |g_i - g_o,i| (Euclidean over components) over the particles with
 * mask[i] != 0 (mask NULL: all). l1 = Σ e_i / Σ |g_o,i| (001 eq. 7 with |g_o| in the
 * denominator, docs/deviations.md; NaN when Σ|g_o| = 0), l2 = sqrt(mean e²) (002 eq. 44),
 * linf = max e (002 eq. 45), mae = mean e (003 eq. 58). Arrays are component-major with stride n
 * between components. */
typedef struct consph_error_norms {
    double l1, l2, linf, mae;
    size_t count;
} consph_error_norms;
int consph_error_norms_compute(const double *approx, const double *exact, size_t n, int ncomp,
                               const unsigned char *mask, consph_error_norms *out);

/* 001 Tables 3/5: F_T/F_max = Σ_i F_i / max_i |F_i| of the x-components
 * (001 does not name the component; docs/deviations.md). */
double consph_total_force_ratio(const double *fx, size_t n, const unsigned char *mask);

/* ---- Manufactured fields -------------------------------------------------------------------- */

typedef enum consph_mfield_id {
    CONSPH_MFIELD_SIN2PI,     /* sin(2π Σ x_a): 001 eq. 6 made periodic on the unit cell */
    CONSPH_MFIELD_SINPI,      /* sin(π Σ x_a): 001 eq. 6 as printed (anti-periodic on [0,1)) */
    CONSPH_MFIELD_SINPROD,    /* Π sin(π x_a): 003 eqs. 53-54 */
    CONSPH_MFIELD_CONST,      /* 1 */
    CONSPH_MFIELD_LINEAR,     /* 1 + 2x - 3y + 0.5z */
    CONSPH_MFIELD_QUADRATIC,  /* x² + 3xy - y² + 2z² - yz (x² + 3xy - y² in 2D) */
    CONSPH_MFIELD_CUBIC,      /* x³ - 2xy² + y³ + xz² */
    CONSPH_MFIELD_TGV,        /* vector, 001 eq. 12: (-cos2πx sin2πy, sin2πx cos2πy), div 0 */
    CONSPH_MFIELD_SIN2PI_VEC, /* vector: every component sin(2π Σ x_a) (001 §4.2, periodic) */
    CONSPH_MFIELD_SINPI_VEC,  /* vector: every component sin(π Σ x_a) (001 §4.2 as printed) */
    CONSPH_MFIELD_DELTA,      /* scalar nascent Gaussian δ of width sigma at x0 (003 eq. 73) */
    CONSPH_MFIELD_COUNT
} consph_mfield_id;

typedef struct consph_mfield_params {
    double sigma;              /* DELTA: width */
    double x0[CONSPH_MAX_DIM]; /* DELTA: centre */
} consph_mfield_params;

/* Value and derivatives at one point. Scalars use comp 0 only; vectors have dim components. */
typedef struct consph_mfield_value {
    int ncomp;
    double f[CONSPH_MAX_DIM];
    double grad[CONSPH_MAX_DIM][CONSPH_MAX_DIM]; /* grad[c][a] = ∂f_c/∂x_a */
    double hess[CONSPH_MAX_DIM][CONSPH_MAX_DIM]; /* ∂²f_0/∂x_a∂x_b (component 0) */
    double lap[CONSPH_MAX_DIM];                  /* ∇² f_c */
    double div;                                  /* vector fields: Σ_a ∂f_a/∂x_a */
} consph_mfield_value;

const char *consph_mfield_name(consph_mfield_id id);
const char *consph_mfield_description(consph_mfield_id id);
int consph_mfield_lookup(const char *name, consph_mfield_id *id);
const char *consph_mfield_names(void);
int consph_mfield_is_vector(consph_mfield_id id);
/* Whether the field is periodic on the unit box (so it may be used on a periodic unit cell). */
int consph_mfield_periodic_on_unit(consph_mfield_id id);
consph_mfield_params consph_mfield_defaults(int dim);
void consph_mfield_eval(consph_mfield_id id, int dim, const consph_mfield_params *prm,
                        const double *x, consph_mfield_value *v);

/* ---- 003: error bounds and the scaling-law resolution policy -------------------------------- */

#define CONSPH_EULER_GAMMA 0.57721566490153286

/* A_W^(n) = (2/π)^n ... kernel factor of 003 eqs. 63-65 from its definition A_W^(2) = 4π h² W_max,
 * A_W^(3) = (32π/3) h³ W_max (support radius h). kernel: a name understood by kernels.h with
 * support h; returns NaN for other kernels or dims. */
double consph_bound_kernel_factor(const char *kernel, int dim);
/* 003 eqs. 56/57 (Wendland C4) and 64/65 (general A_W): bound on ‖Sf − If‖∞ for the test
 * functions Π sin(πx_a), with 𝒩 neighbours and smoothing length h (support h). */
double consph_bound_interpolation(double a_w, int dim, double nnbr, double h);
/* 003 eqs. 81/82: bound for the nascent δ of width sigma (Wendland C4). */
double consph_bound_delta(int dim, double nnbr, double h, double sigma);
/* 003 §6.2 scaling law: h = N^(-1/6), 𝒩 = 2.81 N^0.675. */
double consph_scaling_h(double n);
double consph_scaling_nnbr(double n);

/* ---- One operator-accuracy measurement: `consph approx` and the static studies ----------- */

/* How h follows the resolution. For zhu and beta, h = hdx·Δs_ref·(N/N_ref)^(-1/β) with
 * Δs_ref = (V/N_ref)^(1/d): the policy agrees with hdx at the reference count N_ref (the first
 * resolution of a sweep) and from there lets the neighbour count 𝒩 ∝ N h^d grow as
 * N^(1 - d/β). */
typedef enum consph_h_policy {
    CONSPH_H_HDX,     /* "hdx": h = hdx · Δs (001, 002): 𝒩 fixed */
    CONSPH_H_SCALING, /* "scaling": 003 §6.2, h = N^(-1/6) (unit box; scaled by V^(1/d)) */
    CONSPH_H_ZHU,     /* "zhu": Zhu et al. as 000 eq. 14 states it for 3D, 𝒩 ∝ N^(1/2), taken
                         as 𝒩 ∝ N^(1/2) in every dimension: β = 2d (h ∝ N^(-1/6) in 3D) */
    CONSPH_H_BETA,    /* "beta": 004's global law N ∝ h^(-β) with β > d given by the user */
    CONSPH_H_COUNT
} consph_h_policy;

const char *consph_h_policy_name(consph_h_policy policy);
/* CONSPH_EINVAL listing the allowed names when unknown. */
int consph_h_policy_lookup(const char *name, consph_h_policy *policy);

/* What to measure. Resolution is set per call (nx particles per axis). */
typedef struct consph_approx_spec {
    consph_op_spec op;
    consph_kernel_id kernel;
    double hdx; /* h/Δs, in the kernel's own convention of h */
    consph_h_policy h_policy;
    double beta;  /* the exponent of CONSPH_H_BETA, > dim */
    double n_ref; /* the particle count where zhu and beta give h = hdx·Δs (0: the run's own) */
    consph_layout_params layout; /* kind, dim, box, seed, eps, packing; nx is overridden */
    consph_mfield_id field;
    consph_mfield_params field_params;
    consph_volume_kind volume;
    /* Particles compared: all (0), or only those whose support lies inside the box on every
     * non-periodic axis (1, the default used when a non-periodic axis exists). */
    int interior_only;
    /* Operator applications timed (1 to CONSPH_APPROX_MAX_TIMINGS, default 1): the row's
     * seconds is their median. The extra ones run after the measurement, each on a fresh
     * correction cache, and change no other value. */
    int timing_runs;
} consph_approx_spec;
#define CONSPH_APPROX_MAX_TIMINGS 15

/* One row of `consph approx`: the CSV columns nx,n,h,nbr_mean,l1,l2,linf,mae,ft_over_fmax,
 * seconds,fallbacks. */
typedef struct consph_approx_row {
    size_t nx;
    size_t n;
    double h;
    double nbr_mean; /* mean neighbours within the support, self excluded */
    consph_error_norms err;
    double ft_over_fmax; /* Σ F_x / max |F_x| of the output's first component */
    double seconds;      /* operator time, layout and neighbour search excluded */
    size_t fallbacks;
    double layout_seconds;
    /* Packed layouts generated by consph_approx_run: the packing's final max|ρ/ρ0 − 1|, to be
     * compared with the tolerance (it stops at its iteration cap otherwise); NaN otherwise. */
    double layout_spread;
    /* Packed layouts: whether the packing met its stopping rule before its iteration cap. */
    int layout_converged;
} consph_approx_row;

/* The error norm named "l1", "l2", "linf" or "mae" of a row (l1 for any other name). */
double consph_approx_norm(const consph_approx_row *row, const char *norm);

/* The verdict on the order of a series of rows, as every report states it. */
typedef enum consph_series_status {
    CONSPH_SERIES_ORDER,      /* fitted (text: the order, with its standard error from 3 rows) */
    CONSPH_SERIES_NONFINITE,  /* a row's error is not finite: a wrong result, an error */
    CONSPH_SERIES_DEGENERATE, /* a row where no particle has a neighbour or every one fell back:
                                 the error measures no operator; a warning, no order */
    CONSPH_SERIES_NO_FIT      /* no order can be fitted (text says why): l1 of a zero field,
                                 fewer than two non-zero errors, a single resolution */
} consph_series_status;

typedef struct consph_series_order {
    consph_series_status status;
    int row;              /* the row the status is about, -1 when none */
    consph_order_fit fit; /* order NaN unless fitted */
    char text[160]; /* for a report's order column: "1.86 ± 0.02", "1.86 ± n/a", "n/a (why)" */
    char why[192];  /* NONFINITE, DEGENERATE: "nx = 20: ...", naming the resolution */
} consph_series_order;

/* Fits the order of `norm` over rows measured at resolutions res[k] (digits and pm as in
 * consph_order_text). Returns CONSPH_ENUMERIC (message = why) for a non-finite row, which the
 * caller reports with the series' name and turns into a failure; CONSPH_OK otherwise. */
int consph_series_fit(const consph_approx_row *rows, const double *res, int nrows, const char *norm,
                      int digits, const char *pm, consph_series_order *out);

/* Defaults: op function/standard/none, quintic, hdx 1.2, lattice 2D unit
 * periodic, field sin2pi, volumes 1/ΣW (001 eq. 5). */
consph_approx_spec consph_approx_defaults(int dim);
/* Checks the spec (field kind vs op, dims, periodicity of the field on a periodic box). */
int consph_approx_check(const consph_approx_spec *spec);
/* The smoothing length spec->h_policy gives n particles in a box of the given volume whose
 * nominal spacing is `spacing` (used by hdx only). */
double consph_approx_h(const consph_approx_spec *spec, size_t n, double box_volume, double spacing);
/* The mean neighbours per particle expected from geometry: the kernel's support ball at that h,
 * in particle spacings (periodic images included, so it may pass n). */
double consph_approx_neighbours(const consph_approx_spec *spec, size_t n, double box_volume,
                                double spacing);
/* What one resolution will cost, before it runs: every pass holds one scratch entry (72 bytes)
 * per neighbour of the particle at hand on each of `threads` threads, and a pair costs about
 * 1/CONSPH_APPROX_PAIRS_PER_SECOND seconds (volumes and operator together: measured 2.1e7 for
 * grad in 3D with the gaussian, 3.8e7 in 2D with the quintic, on 2 shared cores). */
#define CONSPH_APPROX_PAIRS_PER_SECOND 2.0e7
typedef struct consph_approx_cost {
    double neighbours, bytes, seconds;
} consph_approx_cost;
consph_approx_cost consph_approx_estimate(const consph_approx_spec *spec, size_t n,
                                          double box_volume, double spacing, int threads);
/* Runs one resolution: generates spec->layout with nx particles per axis, then measures. */
int consph_approx_run(const consph_approx_spec *spec, size_t nx, consph_approx_row *row);
/* Measures on given particles (copied; the box and periodicity are the particles' own). `nx` is
 * only reported. */
int consph_approx_run_particles(const consph_approx_spec *spec, const consph_particles *p,
                                size_t nx, consph_approx_row *row);
/* The exact answer of spec->op at one point, ncomp_out components, given the particle density
 * rho_i (for the forms that approximate ∇p/ρ). */
void consph_approx_exact(const consph_approx_spec *spec, const double *x, double rho_i,
                         double *out);

/* ---- Particle files as the measurements take them (`consph approx --particles`, `consph study
 * --particles`): read in one place, with one rule for their volumes ---------------------------- */

/* A particle file read for a measurement. Its given volumes (the "volume" field, used where a
 * measurement asks for CONSPH_VOLUME_GIVEN) are the file's `volume` column, else its m/rho,
 * else box volume / N: the volume of each particle of a lattice of N filling the box. `volume`
 * is the kind a measurement uses unless told otherwise: given when the file carries volumes,
 * else number (1/ΣW, 001 eq. 5); a study figure's `volume` key tells otherwise. */
typedef struct consph_particle_input {
    const char *path; /* as given (not copied) */
    consph_particles p;
    consph_read_report rep;
    double nx; /* N^(1/dim), exact when N is a perfect power: the resolution an order fit sees */
    consph_volume_kind volume;
    char volume_text[96]; /* where the volumes come from, for reports */
} consph_particle_input;

/* N^(1/dim), exact when N is a perfect power, so that a file made by `consph layout --nx K`
 * reports nx = K. */
double consph_resolution_of(size_t n, int dim);
/* Reads `path` (consph_read_particles with `ro`) and applies the volume rule above. On error
 * nothing is held; the message names the file. */
int consph_particle_input_read(const char *path, const consph_read_options *ro,
                               consph_particle_input *in);
/* Replaces the file's volumes by box volume / N for every particle and uses them (given). */
int consph_particle_input_lattice_volumes(consph_particle_input *in);
void consph_particle_input_free(consph_particle_input *in);

/* ---- A sweep of `consph approx`: one spec over resolutions or particle files --------------- */

typedef struct consph_approx_sweep {
    consph_approx_spec spec;
    int nrows;
    const double *nx;                   /* layouts: particles per axis of each row */
    const consph_particle_input *files; /* files: one row each (NULL for layouts); each runs
                                           in its own box with its own `volume` */
} consph_approx_sweep;

/* The cost of every row before it runs (consph_approx_estimate): total seconds, and the row
 * with the most memory. */
typedef struct consph_approx_sweep_cost {
    double seconds;
    consph_approx_cost worst;
    int worst_row;
} consph_approx_sweep_cost;
consph_approx_sweep_cost consph_approx_sweep_estimate(const consph_approx_sweep *sw, int threads);
/* Checks the spec on every file's box: the operator (consph_approx_check) and a period-1 field
 * on a periodic axis of whole-number length. The message names the file. */
int consph_approx_sweep_check(const consph_approx_sweep *sw);
/* Measures every row in order into rows[] and res[] (the resolution fitted: nx, or the file's
 * N^(1/dim)); on_row (may be NULL) sees each as it is done. An error names the row ("nx = 20:
 * ..." or "FILE: ..."). */
typedef void (*consph_approx_row_fn)(void *ctx, int row, const consph_approx_row *r, double res);
int consph_approx_sweep_run(const consph_approx_sweep *sw, consph_approx_row *rows, double *res,
                            consph_approx_row_fn on_row, void *ctx);
/* The order verdicts of the four norms l1, l2, linf and mae, in that order (3 decimals). */
int consph_approx_sweep_fit(const consph_approx_row *rows, const double *res, int nrows,
                            const char *pm, consph_series_order fits[4]);

/* ---- Studies: declared in files (docs/studies.md), run by `consph study` ------------------- */

typedef struct consph_study consph_study;

/* The figure kinds a study may use (a figure's `kind` key), comma-separated: "approx, m0, appc,
 * cauchy, run, heat", generated from the kinds' registry (src/study/kinds/kinds.h). */
const char *consph_study_kind_names(void);

/* Reads and validates the syntax of a study file; CONSPH_EFORMAT naming file and line. */
int consph_study_load(const char *path, consph_study **out);
void consph_study_free(consph_study *s);
const char *consph_study_name(const consph_study *s);
const char *consph_study_title(const consph_study *s);
/* Checks every figure and series (names and values) without running anything. */
int consph_study_validate(const consph_study *s, int quick);
/* A rough run-time estimate in seconds: neighbour pairs of every run times a per-pair cost
 * measured on a small run of the study's own first series. */
double consph_study_estimate(const consph_study *s, int quick);
/* The same for consph_study_run_particles on these sets (NaN for 0 or more than 64 sets). */
double consph_study_estimate_particles(const consph_study *s, int quick,
                                       const consph_particles *sets, int nsets);

typedef struct consph_study_options {
    int quick;           /* the reduced resolutions (quick.* keys) */
    const char *out_dir; /* results go to out_dir/<study>/ */
    FILE *log;           /* progress lines (NULL: silent) */
    /* Rows: a progress line on stderr (live on a terminal, one line per finished row
     * otherwise), each finished row kept in out_dir/<study>/ for --resume. */
    int progress;
    int resume;             /* read the rows an earlier run of the same study and options kept */
    const char *resume_cmd; /* the command line that resumes, for the message after a stop */
    /* NULL, or where the signal that stopped the study goes (0: none); non-NULL also says that
     * the caller installed the stop handlers (consph_stop_install), which solver rows then
     * watch at every step. */
    int *stopped_by;
    /* > 1: the rows run on that many forked worker processes, the report as a serial one's
     * (0 or 1: this process alone; ignored under MPI on several ranks) */
    int jobs;
    /* Where the solver rows (kind = run) run: a consph_study_device; 0 (DEFAULT) takes the
     * study file's key `device`, else the CPU. Other kinds run on the CPU whatever it says. */
    int device;
} consph_study_options;

/* Where a study's solver rows run (`consph study --device`, the study file's key `device`;
 * docs/studies.md). DEFAULT: neither given, the CPU, and the reports as ever; any other value
 * adds a line per run figure saying which device ran each row. AUTO: on the GPU the rows that
 * consph_gpu_check passes (every row on the CPU where no GPU is found), the others on the CPU. */
typedef enum consph_study_device {
    CONSPH_STUDY_DEVICE_DEFAULT,
    CONSPH_STUDY_DEVICE_CPU,
    CONSPH_STUDY_DEVICE_GPU,
    CONSPH_STUDY_DEVICE_AUTO
} consph_study_device;
/* "cpu", "gpu", "auto" (DEFAULT: "cpu"). */
const char *consph_study_device_name(int device);
/* The device a study runs on: `asked` unless DEFAULT (an option wins), else the study file's key
 * `device` (checked by consph_study_validate), else DEFAULT. */
int consph_study_device_of(const consph_study *s, int asked);
/* Before anything runs: CONSPH_OK when every solver row of `s` can run on `device` (resolved by
 * consph_study_device_of). GPU: CONSPH_EINVAL with what the build or the machine lacks
 * (consph_gpu_available), or naming every row that cannot run there (figure, series, its
 * resolutions) and why (consph_gpu_check); the other devices always can. */
int consph_study_device_check(const consph_study *s, int quick, int device);

/* "mm:ss", "h:mm:ss", or "D.d days" when long; "--" when unknown (NaN, negative). */
const char *consph_study_duration_text(double seconds, char *buf, size_t size);

/* Runs every figure; writes FIGURE.csv, FIGURE.md, FIGURE.gp (+ .svg when gnuplot is
 * installed) per figure and README.md per study, each atomically. A figure gnuplot fails to
 * draw is an error (CONSPH_EIO, no SVG); a failed run removes the directories it created.
 * Every finished row is kept (hidden files beside the outputs); with opt->resume the rows and
 * figures an earlier run kept are read back, not run again, when the study file, --quick and
 * the particle files are those it ran with (CONSPH_EINVAL naming the difference otherwise).
 * A stop request (consph_stop_install: SIGINT, SIGTERM) ends the current row at its next step;
 * the partial README.md says which rows ran and how to resume; CONSPH_OK with
 * *opt->stopped_by set to the signal. */
int consph_study_run(const consph_study *s, const consph_study_options *opt);
/* Runs `s` like consph_study_run, with the particle sets in place of every layout: a figure
 * sweeping nx gets one row per set, in order, reported at nx = N^(1/dim); a figure sweeping h/Δs
 * runs on the last set; App. C figures (no particles) run as usual. Every figure that uses
 * particles must have their dimension, and its field must be periodic on their box where the
 * box is periodic; this is checked before anything is written (CONSPH_EINVAL). */
int consph_study_run_particles(const consph_study *s, const consph_study_options *opt,
                               const consph_particles *sets, const char *const *names, int nsets);

#ifdef __cplusplus
}
#endif
#endif
