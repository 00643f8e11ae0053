/* consph solver: weakly-compressible SPH (001, Negi & Ramachandran) on the pass layer.
 *
 * A run is a problem (domain, initial state, exact solution: data), a scheme (the passes of its
 * right-hand side, its regularisation, its time-step rule, selected by name) and an integrator
 * (explicit midpoint RK2 as 001 uses, forward Euler, kick-drift-kick). Each particle carries its
 * position, velocity "u", the fluid density "rhof" (ϱ, evolved, 001 eq. 17), the pressure "p"
 * from the equation of state, and the numerical volume "volume" (ω = 1/Σ_j W_ij, so that the
 * summation density ρ = m/ω is kept apart from ϱ, 001 §5.1).
 *
 * Errors (001 eq. 26): L1 of a quantity is Σ_steps Δt · (1/N) Σ_i |f_i - f_o(x_i, t)|, summed
 * over the steps after t = 0, with f the velocity magnitude |u| or the pressure p; L∞ is the
 * largest |f_i - f_o| at the final time; a problem with no exact solution after t = 0 (the shear
 * layer) reports its errors as NaN (n/a, JSON null), which is not a failure. Sums over particles
 * are blocked and combined in a fixed tree (consph_sum), so results do not depend on the thread
 * count. */
#ifndef CONSPH_SOLVER_H
#define CONSPH_SOLVER_H

#include <stddef.h>

#include "consph/core.h"
#include "consph/kernels.h"
#include "consph/layout.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum consph_eos_kind {
    CONSPH_EOS_DEFAULT = -1, /* the scheme's own */
    CONSPH_EOS_TAIT = 0,     /* 001 eq. 18: p = ρ_o c_o²/γ ((ϱ/ρ_o)^γ - 1) */
    CONSPH_EOS_LINEAR = 1    /* 001 eq. 28: p = c_o² (ϱ - ρ_o) */
} consph_eos_kind;

/* The initial density of a scheme whose pressure comes from its evolved density by the EOS. */
typedef enum consph_rho_init {
    CONSPH_RHO_INIT_EOS = 0, /* ϱ from the exact pressure, the EOS inverted (001 §5.2) */
    CONSPH_RHO_INIT_RHO0 = 1 /* ϱ = ρ_o, so p = EOS(ρ_o) = 0 whatever the exact pressure: how
                                PySPH's and 001's Taylor-Green scripts start their one-density
                                schemes (docs/schemes.md, the δ-SPH family) */
} consph_rho_init;

/* The error measure (docs/schemes.md, "Errors and diagnostics"). eq26: 001 eq. 26 only, the
 * steps as the time-step rule gives them. authors: also the measure of 001's post-processing
 * (pypr/convergence_sph, taylor_green.py, TaylorGreen.post_process) averaged over
 * error_times output times equally spaced in [0, t_f], t = 0 included: at each,
 * mean| |u| - |u_e| | / mean |u_e| and mean |p - p_e| / max |p_e|. With --tf the steps are
 * shortened to land on those times, as PySPH's solver does for output_at_times; with --steps
 * no step is shortened and the output times are the ends of steps round(k S/(N - 1)). */
typedef enum consph_error_kind {
    CONSPH_ERROR_EQ26 = 0,
    CONSPH_ERROR_AUTHORS = 1
} consph_error_kind;

/* What the errors are taken against (docs/schemes.md, "The weakly-compressible reference").
 * incompressible: the problem's exact solution. wc: a pseudo-spectral solution of the
 * weakly-compressible equations the scheme discretises (continuity, the run's EOS, ν), from
 * the run's own initial state, interpolated spectrally at the particles; for problems whose row
 * allows it (taylor-green). both: the errors against the incompressible solution, and beside
 * them (consph_run_summary's wc_*) the same measures against wc. */
typedef enum consph_exact_kind {
    CONSPH_EXACT_INCOMPRESSIBLE = 0,
    CONSPH_EXACT_WC = 1,
    CONSPH_EXACT_BOTH = 2
} consph_exact_kind;

/* Everything a run is made from. consph_run_params_default fills 001's Taylor-Green values. */
typedef struct consph_run_params {
    char problem[32];    /* "taylor-green" */
    char scheme[32];     /* consph_scheme_names() */
    char integrator[16]; /* "" (the scheme's), "rk2", "euler", "kdk", "pec" */
    int nx;              /* particles per side */
    int layout;          /* consph_layout_kind, or -1 for the scheme's (packed or lattice) */
    unsigned long seed;  /* for random and packed layouts */
    double hdx;          /* h/Δs */
    consph_kernel_id kernel;
    double U;    /* velocity scale */
    double c0;   /* speed of sound; 0: 10 U */
    double re;   /* Reynolds number (ν = U L / Re, L = the box side) */
    double nu;   /* kinematic viscosity; < 0: from re (ν = U L / Re); 0: inviscid */
    double rho0; /* reference density ρ_o */
    double gamma;
    consph_eos_kind eos;
    double delta;      /* δ of the diffusive terms D = δ h c_o (001 eq. 27 prints δ h c_o²;
                          docs/deviations.md) */
    double alpha;      /* artificial viscosity α (wcsph, δ-SPH family); < 0: the scheme's default
                          (wcsph 0.1 as PySPH's WCSPHScheme, δ-SPH family 0) */
    double tf;         /* final time (used when steps = 0) */
    long steps;        /* number of steps (0: up to tf) */
    double dt;         /* fixed time step (0: the rule cfl · h_dt/(U + c_o)) */
    double cfl;        /* 0.3 (001 §5.2) */
    double h_dt;       /* h in the time-step rule (0: this run's h); studies pass the finest h */
    double skin;       /* neighbour-list skin in support radii (0: rebuild every step) */
    int ipst_every;    /* IPST every this many steps (001: 10) */
    int ipst_max_iter; /* at most this many shifts (001: 10) */
    double ipst_tol;   /* ε of 001 eq. 21 */
    int rho_init;      /* consph_rho_init */
    int error;         /* consph_error_kind: what the run reports as its L1 beside eq. 26 */
    int error_times;   /* the authors' measure: this many output times in [0, t_f] (001's: 50) */
    int log_every;     /* the diagnostics (log.csv rows, eq. 26's samples) every this many steps,
                          at t = 0, the last step and each snapshot; never otherwise */
    double ipst_h_dt;  /* IPST every ipst_every steps of the time-step rule's Δt at this h instead
                          of the run's own steps (0: the run's steps); 001's studies pass the
                          paper's finest h, so every resolution shifts as often per unit time */
    double ipst_chi0;  /* χ_o of 001 eq. 21: -1 the unperturbed lattice's, 0 max χ after one
                          shift at the run's first IPST (001's authors; the run then stores that
                          value here, and a checkpoint carries it), > 0 that value */
    int exact;         /* consph_exact_kind: what every error is taken against */
    long n;            /* the particle count of a run from given particles when it is not nx^dim
                          (then Δs = (box volume / n)^(1/dim) and nx the nearest integer to
                          n^(1/dim)); 0: nx^dim particles, Δs = the box side / nx */
} consph_run_params;

void consph_run_params_default(consph_run_params *prm);
/* Sets prm->problem and the problem's own defaults (final time, ν, c_o, layout; docs/schemes.md
 * gives their sources): taylor-green keeps consph_run_params_default's. CONSPH_EINVAL naming the
 * allowed problems for an unknown name. */
int consph_run_params_problem(consph_run_params *prm, const char *problem);

/* Names, for help and messages: "l-ipst-c,l-ipst-f,..." and "taylor-green,...". */
const char *consph_scheme_names(void);
/* 1 when the scheme `name` shifts its particles by IPST (the ipst_* parameters act), else 0. */
int consph_scheme_uses_ipst(const char *name);
/* The parameters of consph_run_params that only some schemes read: an option or key setting one
 * for a scheme that does not read it would do nothing, so callers refuse it. */
typedef enum consph_scheme_param {
    CONSPH_PARAM_ALPHA = 1u << 0, /* alpha: artificial viscosity */
    CONSPH_PARAM_DELTA = 1u << 1, /* delta: the diffusive term D = δ h c_o */
    CONSPH_PARAM_EOS = 1u << 2,   /* eos: p from the evolved ϱ (not edac, pe-ipst-c, tvf) */
    CONSPH_PARAM_IPST = 1u << 3   /* ipst_every, ipst_max_iter, ipst_tol, ipst_h_dt, ipst_chi0 */
} consph_scheme_param;
/* 1 when the scheme `name` reads `param` (one consph_scheme_param), else 0 (also for an unknown
 * name). */
int consph_scheme_reads(const char *name, unsigned param);
/* The schemes that read `param`, comma-separated in table order, into buf (truncated to size);
 * returns buf. */
const char *consph_scheme_readers(unsigned param, char *buf, size_t size);
/* The layout the run starts from: prm->layout, else the scheme's (-1 for an unknown scheme). */
int consph_run_params_layout(const consph_run_params *prm);
/* The layout parameters a run of prm starts from (kind, box, particles per axis, seed, the
 * packing's h/Δs): what consph_solver_create generates, and what keys its layout cache entry. */
int consph_run_layout_params(const consph_run_params *prm, consph_layout_params *lp);
const char *consph_problem_names(void);
const char *consph_integrator_names(void);
/* CONSPH_EINVAL naming the parameter and the allowed values when something is out of range (the
 * bounds of the parameter table, then the rules between parameters); run before any work. */
int consph_run_params_check(const consph_run_params *prm);

/* The parameter table (src/solver/params.def): one row per member of consph_run_params. */
typedef enum consph_param_type {
    CONSPH_PTYPE_INT,    /* int */
    CONSPH_PTYPE_LONG,   /* long */
    CONSPH_PTYPE_ULONG,  /* unsigned long */
    CONSPH_PTYPE_DOUBLE, /* double */
    CONSPH_PTYPE_STRING, /* char[]: a name of `names()` */
    CONSPH_PTYPE_ENUM,   /* int-sized enum: one of `choices` */
    CONSPH_PTYPE_KERNEL, /* consph_kernel_id by its name (radial kernels) */
    CONSPH_PTYPE_LAYOUT  /* int: consph_layout_kind by its name, or "default" (-1) */
} consph_param_type;

enum {
    CONSPH_PFLAG_QUICK = 1u << 0, /* a study's quick.KEY replaces KEY in a quick run */
    CONSPH_PFLAG_NX = 1u << 1     /* bounded by consph_run_nx_check; a study sweeps a list */
};

typedef struct consph_run_param {
    const char *name; /* the member, the checkpoint key, the name in library messages */
    consph_param_type type;
    const char *option;    /* consph run's option ("--ipst-iter"); NULL: none */
    const char *study_key; /* the key of a run figure in a study file; NULL: none */
    double lo, hi;         /* numbers: allowed lo..hi, lo excluded when lo_open; DBL_MAX: no hi */
    int lo_open;
    double special;           /* numbers: one more allowed value outside lo..hi (NaN: none), */
    const char *special_name; /* given as text by this name ("re", "default", "none") */
    const char *choices;      /* ENUM: comma-separated names, the k-th having value first + k */
    int first;
    const char *(*names)(void); /* STRING: the allowed names (NULL: any) */
    unsigned reads;    /* consph_scheme_param bits of the schemes reading it (0: every run) */
    unsigned flags;    /* CONSPH_PFLAG_* */
    const char *owner; /* what reads it: "run", "problem", "scheme", "time step", ... */
    const char *metavar, *help;
    double def;           /* the default of a number or enum */
    const char *def_text; /* the default of a string */
    size_t offset, size;  /* the member in consph_run_params */
} consph_run_param;

/* The table's rows in order; k in [0, consph_run_param_count()) else NULL. */
int consph_run_param_count(void);
const consph_run_param *consph_run_param_at(int k);
/* The row named `name` (the member), NULL when none. */
const consph_run_param *consph_run_param_find(const char *name);
/* Parses `text` as the parameter `name` and sets it in prm when it is of its type and allowed
 * (numbers: in bounds; names: one of the allowed), else CONSPH_EINVAL with a message that names
 * the parameter and the allowed values, prm unchanged. What consph run, a study file and a
 * checkpoint's metadata set parameters with. */
int consph_run_param_set(consph_run_params *prm, const char *name, const char *text);
/* The value of `name` in prm as text that consph_run_param_set reads back to the same value
 * (doubles to the bit). CONSPH_EINVAL for an unknown name or a buffer too small. */
int consph_run_param_format(const consph_run_params *prm, const char *name, char *buf, size_t size);
/* What the row allows, for help and messages: "[0.5, 4]", "(0, 2]", "[0, 10] or -1",
 * "default,tait,linear", ... into buf; returns buf. */
const char *consph_run_param_allowed(const consph_run_param *d, char *buf, size_t size);
/* The most particles per side of a 2D run (10^8 particles, as consph layout and approx allow;
 * a 3D run has at most as many particles: nx <= 464). */
#define CONSPH_RUN_NX_MAX 10000
/* CONSPH_OK when a run of nx^dim particles can be held: nx in [4, CONSPH_RUN_NX_MAX] (3D: [4,
 * 464]) and its memory estimate (2D: 1 KiB per particle, about twice the measured peak; 3D: 2
 * KiB) within this machine's physical memory; else CONSPH_EINVAL, the message naming --nx, the
 * estimate and the limit. Called by consph_run_params_check, so before any set-up. */
int consph_run_nx_check(int nx, int dim);
/* The dimension of a problem (2 or 3), 0 for an unknown name. */
int consph_problem_dim(const char *problem);

/* What a run measured. */
typedef struct consph_run_summary {
    char scheme[32], problem[32], integrator[16];
    size_t n;
    int dim;
    long steps;
    double t, dt, h, c0;
    double l1_u, l1_p;     /* 001 eq. 26, integrated over time */
    int error;             /* consph_error_kind of the run */
    double l1n_u, l1n_p;   /* the authors' measure (error = authors; NaN otherwise) */
    int error_samples;     /* output times it averages (0 with eq26) */
    double linf_u, linf_p; /* at the final time */
    double ke;             /* kinetic energy ½ Σ m |u|², m = ρ_o ω at t = 0 */
    double momentum[3], angular_momentum;
    double ft_fmax; /* Σ_i m_i a_i / max_i |a_i| of the x-components, a = du/dt (the whole
                       acceleration), m = the particle mass (ρ_o Δs²): 001's authors' F_T/F_max */
    double max_divu;
    double seconds; /* wall time of the time steps (set-up excluded) */
    size_t pairs;   /* pair evaluations of the time steps */
    int passes_per_stage, passes_min;
    long regularisations; /* IPST/PST/remesh steps applied */
    /* the neighbour list of a moving scheme with skin > 0 (src/pass/nlist.c): bytes per
     * particle of list, pair cache and build positions, its builds (in this process), and why
     * it is off ("" when on); nlist_skin 0 otherwise, and the summary's JSON then leaves these
     * out (builds always: a restart counts its own) */
    double nlist_skin, nlist_bytes;
    long nlist_builds;
    char nlist_note[200];
    int exact; /* consph_exact_kind of the run */
    /* exact both: eq. 26 (wc_l1_*) and the authors' measure (wc_l1n_*, error authors) against
     * the weakly-compressible reference; NaN otherwise */
    double wc_l1_u, wc_l1_p, wc_l1n_u, wc_l1n_p;
} consph_run_summary;

/* ---- run parameter files (consph run --config FILE; docs/solver-files.md) ---- */
#define CONSPH_RUN_FILE_KEYS 64
#define CONSPH_RUN_FILE_VALUE 256
/* A run parameter file: `key = value` lines with '#' comments (consph_kv_parse), the keys the
 * parameter table's study keys (`problem`, `scheme`, `nx`, `tf`, ...), each at most once. */
typedef struct consph_run_file {
    const char *path; /* as given to consph_run_file_load (the caller keeps it) */
    int n;
    struct {
        const consph_run_param *param;
        char value[CONSPH_RUN_FILE_VALUE];
        int line;
        int dropped; /* replaced by the caller's own setting (consph_run_file_apply) */
    } key[CONSPH_RUN_FILE_KEYS];
} consph_run_file;
/* Reads the file (at most 1 MiB): CONSPH_EIO when it cannot be read; CONSPH_EFORMAT
 * "PATH:LINE: ..." for a section, an unknown key (naming the allowed), a key without a value or
 * given twice, a value too long, or what consph_kv_parse refuses. */
int consph_run_file_load(consph_run_file *rf, const char *path);
/* The file's keys into prm (after the problem's defaults, before the caller's own settings),
 * but `problem`: a key whose parameter the caller sets itself (given(ctx, name) nonzero; given
 * NULL: none), or that clashes with one it sets (tf and steps, re and nu, dt and cfl or h_dt),
 * is checked (a bad value is never ignored) but not applied, and marked dropped. CONSPH_EINVAL
 * "PATH:LINE: key 'K': ..." for a bad value, "PATH:LINE: keys 'A' and 'B' (line M) both set
 * ...: give one" for two clashing keys that stay. */
int consph_run_file_apply(consph_run_file *rf, consph_run_params *prm,
                          int (*given)(void *ctx, const char *param), void *ctx);
/* The index of the key of the parameter `name` (the table's name) that stays (not dropped);
 * -1 when none (or rf NULL). */
int consph_run_file_find(const consph_run_file *rf, const char *name);
/* Settings that would do nothing are refused, not ignored: CONSPH_EINVAL "WHERE does nothing for
 * SCHEME_WORD S (it acts on: ...)" for the first parameter of the table that is set (given(ctx,
 * name, where, size) nonzero, writing where it was set: "option --alpha", "FILE:LINE: key
 * 'alpha'") and that the scheme of prm does not read (consph_scheme_reads; eos 'default' is no
 * setting), or "WHERE does nothing for LAYOUT_WORD L (given|the problem's or scheme's default),
 * which draws no random numbers (it acts on: ...)" for a seed the layout does not draw. The words
 * name the scheme and layout as the caller's user gives them ("--scheme", "scheme"). */
int consph_run_params_unread(const consph_run_params *prm,
                             int (*given)(void *ctx, const char *name, char *where, size_t size),
                             void *ctx, const char *scheme_word, const char *layout_word);

/* ---- the solver ---- */
typedef struct consph_solver consph_solver;

/* Builds particles and initial state from the parameters (checked first). */
int consph_solver_create(consph_solver **out, const consph_run_params *prm);
/* The same from given particles instead of the layout (consph run --particles): their positions,
 * in the stored order (the field "id" numbers them so), and where `given` has them the fields
 * "u" (dim components) and "p" (1) instead of the problem's solution at t = 0 (ϱ then follows
 * from p as at set-up). Its count, box and periodicity must be the run's
 * (consph_run_params_particles) and every position inside the box; other fields are ignored,
 * volumes and masses being the run's own (box volume / N, as a layout's). Given the particles of
 * the layout the parameters name, the run is the same bit for bit. */
int consph_solver_create_from(consph_solver **out, const consph_run_params *prm,
                              const consph_particles *given);
/* Sets prm->nx and prm->n for a run from `count` particles (prm->problem set): nx = count^(1/dim)
 * and n = 0 when count is a perfect power, else nx = count^(1/dim) rounded and n = count (the
 * spacing then (box volume / count)^(1/dim)). CONSPH_EINVAL naming the count when the run could
 * not hold it (consph_run_nx_check). */
int consph_run_params_particles(consph_run_params *prm, size_t count);
/* Restores a solver from a checkpoint's metadata and particles (consph_solver_checkpoint_meta);
 * takes ownership of nothing. */
int consph_solver_restore(consph_solver **out, const char *meta, const consph_particles *p,
                          const double *history, size_t nhistory);
void consph_solver_free(consph_solver *s);

/* The bounds of a weakly-compressible run's validity (docs/schemes.md, "Validity of a run"),
 * checked after every step: the Mach number max_i |u_i|/c_o, the compression max_i |ϱ_i/ρ_o − 1|
 * (every scheme but edac, whose p is evolved with no EOS), and the kinetic energy's growth
 * KE(t)/KE(0) − 1 (no problem here has an energy source). */
#define CONSPH_VALID_MACH 1.0
#define CONSPH_VALID_COMPRESSION 0.3
#define CONSPH_VALID_KE_GROWTH 0.1
/* The stability bounds of Δt: acoustic CONSPH_DT_ACOUSTIC h/(U + c_o) (001's rule of the
 * default Δt) and viscous CONSPH_DT_VISCOUS h²/ν (Morris et al. 1997), h of this run. */
#define CONSPH_DT_ACOUSTIC 0.3
#define CONSPH_DT_VISCOUS 0.125

/* One time step. A non-finite value, or a state beyond a CONSPH_VALID_* bound, stops it with
 * CONSPH_ENUMERIC and a message naming the step, t, the particle (its index in the initial
 * particle set), its position, the quantity, its value and the bound. */
int consph_solver_step(consph_solver *s);
/* 1 and a sentence naming the bound, its value and the run's Δt in buf when Δt exceeds a
 * CONSPH_DT_* bound (a warning: the run may then stop at a CONSPH_VALID_* bound); 0 when not. */
int consph_solver_dt_warning(const consph_solver *s, char *buf, size_t size);
/* 1 when the run reached its final time or step count. */
int consph_solver_done(const consph_solver *s);

long consph_solver_step_count(const consph_solver *s);
double consph_solver_time(const consph_solver *s);
double consph_solver_dt(const consph_solver *s);
const consph_run_params *consph_solver_params(const consph_solver *s);
/* The particles (current order; the field "id" holds each one's index in the initial set),
 * with the fields "u", "p", "rhof", "volume" and, for the output, "u_exact", "p_exact" and
 * "vorticity" refreshed by consph_solver_output_fields. */
const consph_particles *consph_solver_particles(const consph_solver *s);
int consph_solver_output_fields(consph_solver *s);

/* The diagnostics of the log at this instant (computed on demand; a run samples them every
 * log_every steps): t, L1 and L∞ of |u| and p, kinetic energy, momentum, angular momentum,
 * F_T/F_max, max |∇·u|. */
typedef struct consph_step_diag {
    long step;
    double t, l1_u, linf_u, l1_p, linf_p, ke, mom[3], ang, ft_fmax, max_divu;
} consph_step_diag;
/* A solver decomposed over MPI ranks (include/consph/par.h) gives the whole set's diagnostics,
 * the same bits on every rank and as the serial run's: every rank must call it. */
int consph_solver_diag(const consph_solver *s, consph_step_diag *d);
/* The run's history, as log.csv holds it: one row per sample of the diagnostics (t = 0, every
 * log_every steps, the last step, each snapshot of consph_run), the initial state (step 0)
 * first, so a run of n steps with log_every 1 has n + 1 rows; a run that diverged ends at its
 * last sample before the stop.
 * consph_solver_history_row fills *d with row k (its step, t, errors, momentum and angular
 * momentum about the box centre as consph_solver_diag computed them then); CONSPH_EINVAL for
 * k >= consph_solver_history_size(s). */
size_t consph_solver_history_size(const consph_solver *s);
int consph_solver_history_row(const consph_solver *s, size_t k, consph_step_diag *d);
int consph_solver_summary(const consph_solver *s, consph_run_summary *sum);

/* The metadata text and history a checkpoint of this solver holds (malloc'd). */
int consph_solver_checkpoint_meta(const consph_solver *s, char **meta, double **history,
                                  size_t *nhistory);

/* ---- a whole run, with its files ---- */

/* Where and how often a run writes. In `dir`: snapshots snap_NNNNNN.vtu (every field of the
 * particles) indexed by run.pvd (a ParaView time series), log.csv (one row per sample, log_every:
 * the consph_step_diag columns and dt), summary.json, and checkpoint.ckpt. Every file is written to
 * a temporary name and renamed when complete. */
typedef struct consph_run_output {
    const char *dir;       /* NULL: no files */
    long snapshot_every;   /* a snapshot every this many steps (0: the first and the last) */
    long checkpoint_every; /* a checkpoint every this many steps (0: none) */
    int progress;          /* a progress line on stderr when it is a terminal */
    /* SIGINT/SIGTERM: finish the step, checkpoint, stop. 1: the run installs the handlers
     * (consph_stop_install) and gives back those it found; CONSPH_RUN_SIGNALS_WATCH: the
     * caller's handlers are in place and the run only watches them (consph_stop_requested), so
     * runs on several threads at once share one stop request */
    int signals;
} consph_run_output;
#define CONSPH_RUN_SIGNALS_WATCH 2

/* Steps the solver to its end. Returns CONSPH_OK; CONSPH_ENUMERIC when it diverged (the
 * message names step, particle, position and quantity; the snapshots written so far stay);
 * another code on a failure; with *stopped_by set to the signal that stopped it (0 when
 * none). *sum is filled in every case. */
int consph_run(consph_solver *s, const consph_run_output *out, consph_run_summary *sum,
               int *stopped_by);
/* Restores a solver from a checkpoint file; a refusal names the file and the metadata key. */
int consph_run_restart(consph_solver **s, const char *checkpoint);
/* Gives a restored run another end: tf > 0 (a run to t_f) or steps > 0 (a run of that many
 * steps), after the checkpoint's t and step. The run then continues as an uninterrupted run
 * with that end would have (bit for bit), which holds because every step before the end of a
 * run is a full Δt. CONSPH_EINVAL, the run unchanged, when it cannot: an end not after the
 * checkpoint, a run with the authors' error measure (its output times divide the whole run),
 * or a checkpoint at the end of a run whose last step was shortened to land on its t_f. The
 * same end as the run's is no change. */
int consph_solver_extend(consph_solver *s, double tf, long steps);

/* A run's identifier: CONSPH_RUN_ID_LEN hexadecimal digits drawn when the solver is set up,
 * kept by its checkpoints and written to DIR/run.id by consph_run, so that a restart can tell
 * its own output directory from another run's. */
#define CONSPH_RUN_ID_LEN 16
const char *consph_solver_run_id(const consph_solver *s);
/* Whether the run `run_id` (NULL: a new run) may write its files in dir (a missing dir may).
 * A new run needs a directory holding none of the files a run writes (run.pvd, log.csv,
 * summary.json, checkpoint.ckpt, run.id, snap_N.vtu, profile.csv, vorticity.*, their temporary
 * files); with overwrite those files, and nothing else, are removed first. A restarted run
 * needs a directory without such files, or one whose run.id names run_id and whose run.pvd, if
 * any, reads back. CONSPH_EINVAL names the directory and what is there (CONSPH_EFORMAT the
 * file that does not read back, or an entry named like a run's file that is a directory,
 * checked before anything is removed; CONSPH_EIO a file that could not be removed). */
int consph_run_dir_check(const char *dir, const char *run_id, int overwrite);

#include <stdio.h>
/* The summary as one JSON object (non-finite values as null). */
void consph_run_summary_json(FILE *fp, const consph_run_summary *sum);

#ifdef __cplusplus
}
#endif
#endif
