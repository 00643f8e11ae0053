/* Study kinds as table rows: one const row per figure kind (kinds/approx.c, m0.c, appc.c,
 * cauchy.c, run.c, heat.c), listed once in the registry (engine.c). The engine validates,
 * estimates and runs a study through the rows; the kinds share the series plan (plan.c) and
 * one writer for CSV, markdown and gnuplot figures (writer.c). */
#ifndef CONSPH_STUDY_KINDS_H
#define CONSPH_STUDY_KINDS_H

#include <stdio.h>

#include "consph/io.h"
#include "consph/study.h"
#include "study/study_internal.h"

/* Particle files that replace the generated layouts (consph study --particles). */
typedef struct study_files {
    const consph_particles *sets;
    const char *const *names;
    int n;
} study_files;

/* ---- the series plan shared by the kinds that measure operators on particles (plan.c) ---- */

/* Everything needed to run one series, parsed from its keys. */
typedef struct series_plan {
    consph_approx_spec spec;
    const char *kernel_name;
    int sweep_hdx; /* 0: sweep nx, 1: sweep hdx at fixed nx */
    int nvalues;
    double values[MAX_SWEEP];
    size_t nx_fixed;
    int bound; /* 0 none, 1 interp, 2 delta */
} series_plan;

/* Packed layouts are expensive and shared between series: generated once per study run. */
typedef struct cached_layout {
    consph_layout_params lp;
    consph_particles p;
    double seconds;
    int used;
} cached_layout;

#define CACHE_SIZE 16
typedef struct layout_cache {
    cached_layout e[CACHE_SIZE];
    int next;
} layout_cache;

/* Series whose published value is drawn, and series of a cauchy figure. */
#define MAX_SERIES_POINTS 64

int study_plan_build(const consph_study *s, const study_figure *f, const study_series *r, int quick,
                     series_plan *pl);
/* N^(1/dim), exact when N is a perfect power. */
double study_resolution_of(const consph_particles *p);
/* How h was chosen, for the reports. */
const char *study_h_policy_text(const consph_approx_spec *sp, char *buf, size_t size);
int study_layout_get(layout_cache *c, const consph_layout_params *lp, const consph_particles **p,
                     double *seconds, FILE *log);
void study_layout_cache_free(layout_cache *c);
/* Particle files replace a plan's nx sweep, one resolution each. */
void study_plan_take_files(series_plan *pl, const study_files *files);
/* The particles of resolution j of an nx sweep, and their nx. */
int study_plan_particles(const series_plan *pl, int j, const study_files *files,
                         layout_cache *cache, FILE *log, const consph_particles **p, size_t *nx);
/* Neighbour pairs of one run at nx particles per axis of the unit box, from geometry. */
double study_pairs_estimate(const series_plan *pl, double nx);
/* The work of row j of a plan (neighbour pairs), and the rows of an operator figure with their
 * work: study_kind.rows of the kinds that report rows. */
double study_plan_row_work(const series_plan *pl, int j);
/* The layout row j of the plan reads: its kind at nx = values[j], or nx_fixed across an h/dx
 * sweep. */
consph_layout_params study_plan_row_layout(const series_plan *pl, int j);
int study_plan_rows(const consph_study *s, const study_figure *f, int quick,
                    const study_files *files, double *work);
/* Period-1 fields repeat on a periodic axis only when its length is a whole number. */
int study_check_field_period(const consph_approx_spec *sp, const consph_box *box);

/* ---- the writer shared by every kind (writer.c) ---- */

/* Whether the list holds `key`. */
int study_kv_has(const study_kvlist *l, const char *key);
/* The figure's title; with --particles it says that the layout it names is not what ran. */
const char *study_files_title(const consph_study *s, const study_figure *f, int files, char *buf,
                              size_t size);
/* "the files'", "quick" or "full (paper)": which resolutions ran, for a report's Run line. */
const char *study_resolutions_text(int files, int quick);
/* Commits `of`, or aborts it when rc is already an error; returns the first error. */
int study_close_output(consph_outfile *of, int rc);
/* Closes a figure's gnuplot script as study_close_output does and draws it into ID.svg. */
int study_gp_finish(consph_outfile *of, int rc, const char *dir, const char *id);
/* The markdown line that shows the figure's SVG, when gnuplot draws it. */
void study_md_figure(FILE *o, const char *id);
/* Creates `path` and its missing parents, and removes what a failed run created. */
int study_mkdir_p(const char *path, size_t *created);
void study_remove_created(const char *dir, size_t created);
/* Removes the files directly inside dir (what a study writes there), not dir itself. */
void study_remove_files(const char *dir);
/* The study's README: title, then every figure's report in order. */
int study_write_readme(const consph_study *s, int quick, int files, const char *dir);

/* ---- rows: progress, the store that --resume reads, stop requests (writer.c) ---- */

/* A study's rows (one run of a figure's series at one resolution) as they finish: the progress
 * line, and each finished row's result kept in DIR/.FIGURE.sS.rJ.row (written atomically), so
 * that a resumed study reads it instead of running it again. Kinds that do not report rows
 * (m0, appc, cauchy) count as one row per figure. */
/* What the worker processes of --jobs share (engine.c, memory mapped before they fork): the
 * claims on the units, one byte each, and the rows they finished, counted together for the
 * progress lines. Every access is atomic. */
typedef struct study_shared {
    long nunits;
    int done;
    long long work_done; /* the work model's units, rounded */
    int abandon;         /* a row thread failed: the others claim no more units */
    unsigned char claim[];
} study_shared;

/* A packed layout the rows read that the layout cache lacked when they started (none made
 * ahead: MPI; or one whose packing ahead failed): its cache file, the packing model's seconds
 * (study_packing_seconds), and whether the file is there now. */
typedef struct study_packing_due {
    char path[4352];
    double seconds;
    int made;
} study_packing_due;

typedef struct study_rows {
    const char *dir;
    int total, done;            /* rows of the study, rows finished (run now or read back) */
    double work_total;          /* the work model's units (particle-steps, pairs) of every row */
    double work_done, work_run; /* of the finished rows; of those run by this process */
    double t0, seconds_run;     /* start; wall time of the rows run by this process */
    int print;                  /* progress on stderr at all */
    int tty;                    /* a live line on stderr, else one plain line per finished row */
    int stop_after;             /* tests: a stop request after this many rows run (0: never) */
    int run_now;                /* rows run by this process */
    /* the caller installed consph_stop_install (opt->stopped_by): 1, each row's run installs
     * and gives back its own; CONSPH_RUN_SIGNALS_WATCH, the rows on threads only watch them */
    int signals;
    int stopped;       /* the signal that stopped the study, 0 when none */
    char current[192]; /* the row now running, for the progress line and the partial
                          report */
    double row_t0, row_work;
    /* On a terminal the figures' log goes through `mem` and out to `out` between redraws, so
     * that its lines do not run into the live line. */
    FILE *out, *mem;
    char *membuf;
    size_t memlen, memdone;
    /* A study spread over MPI ranks (engine.c, docs/mpi.md): while share_size > 1 this rank runs
     * only its units (a row, or a figure without rows) and keeps their rows; rank 0 then writes
     * the reports from the kept rows. */
    int share_rank, share_size;
    long share_units; /* units met so far, in the study's order */
    /* --jobs: the workers share these (memory mapped before the fork): a unit is run by the
     * worker that claims it first, and the rows finished by all of them are counted together */
    study_shared *shared;
    int shared_done;       /* the count of every worker's rows this worker's last row made */
    int fig_rows, fig_met; /* rows of the figure now running; rows of it met so far */
    int shared_report;     /* rank 0's pass over the rows the ranks kept */
    /* The ETA's models (engine.c): the rows' seconds per unit of work by the estimate, their
     * packing left out (NAN when not made: nothing to pack), made before the packing ahead; the
     * layouts still to pack (row_made: those made when the running row began). A row during
     * which one was made packed it: its time is not a rate of its work. */
    double model_per_work;
    study_packing_due *due;
    int ndue, row_made;
} study_rows;

/* Writes what the figures logged since the last call (terminal only); the next row redraws the
 * live line. */
void study_rows_flush(study_rows *r);
/* The study's seconds to go as the progress lines give them: the rows' work left at the rate of
 * the rows this process ran (the model's, model_per_work, before the first), plus the due
 * packings' price; NAN when unknown. */
double study_rows_eta(const study_rows *r);

/* ---- the kind rows ---- */

/* What one figure run sees. */
typedef struct study_job {
    const consph_study *s;
    int quick;
    const char *dir;
    const study_files *files; /* NULL: the layouts the study names */
    layout_cache *cache;
    FILE *log;
    study_rows *rows; /* NULL: no progress, no store (the estimate's runs) */
    int device;       /* consph_study_device, resolved (consph_study_device_of) */
    int gpu_ok;       /* a GPU was found (consph_gpu_available); read under DEVICE_AUTO */
} study_job;

/* The stored result of row j of series k of figure f: 1 when read into row (size bytes) and
 * *extra (*nextra doubles, malloc'd, NULL when none; extra may be NULL), 0 when absent. */
int study_row_load(const study_job *job, const study_figure *f, int k, int j, void *row,
                   size_t size, double **extra, size_t *nextra);
/* Shows that row j of series k (labelled `what`, e.g. "nx=32") starts; `work` in the units of
 * the figure's study_kind.rows. */
void study_row_begin(const study_job *job, const study_figure *f, int k, const char *what,
                     double work);
/* Keeps a finished row (as study_row_load reads it) and counts it; `stored` 1 when it was read
 * back rather than run. */
int study_row_finish(const study_job *job, const study_figure *f, int k, int j, const void *row,
                     size_t size, const double *extra, size_t nextra, int stored);
/* In a study spread over ranks: STUDY_ELSEWHERE when another rank runs row j of series k (the
 * kind skips the row), STUDY_SHARED when that was also the figure's last row (the kind returns
 * without writing its report, which rank 0 writes from the kept rows); CONSPH_OK when this rank
 * runs it, and always in a serial study. study_row_finish returns STUDY_SHARED after the
 * figure's last row in the same way. */
int study_row_elsewhere(const study_job *job);
#define STUDY_ELSEWHERE 101
#define STUDY_SHARED 102
/* The signal that asks the study to stop (consph_stop_requested, or the tests' row count). */
int study_rows_stop(const study_job *job);
/* Internal status of a figure stopped by a signal between or inside rows: not an error. */
#define STUDY_STOPPED 100

/* What a study's estimate adds up: neighbour pairs (timed on a small run of the first series),
 * and seconds: the packings (study_packing_seconds) and what the kinds estimate themselves. */
typedef struct study_estimate {
    double pairs, seconds;
    double seen[256][3]; /* packed layouts counted once per (dim, nx, seed) */
    int nseen;
    series_plan first;
    int have_first;
} study_estimate;

/* How a kind meets --particles. */
typedef enum study_particles_use {
    STUDY_PARTICLES_IGNORED, /* makes no particles of its own layout (appc, heat) */
    STUDY_PARTICLES_USED,    /* runs on the files in place of its layouts */
    STUDY_PARTICLES_REFUSED  /* the solver makes its own particles */
} study_particles_use;

typedef struct study_kind {
    const char *name;
    study_particles_use particles;
    /* With --particles: the files must also suit the operator and field of every series. */
    int checks_operator_on_files;
    /* Checks the figure's keys without running anything. */
    int (*validate)(const consph_study *s, const study_figure *f, int quick);
    /* Checks that span the study's figures of this kind (a study-level key that some series
     * reads); NULL when none. */
    int (*validate_study)(const consph_study *s, int quick, const study_files *files);
    /* Adds the figure's cost to *e; NULL: free. */
    int (*estimate)(const consph_study *s, const study_figure *f, int quick,
                    const study_files *files, study_estimate *e);
    /* The figure's rows and their work (study_row_begin's units); NULL: one row. */
    int (*rows)(const consph_study *s, const study_figure *f, int quick, const study_files *files,
                double *work);
    /* Runs the figure and writes FIGURE.csv, .md and its plot files into job->dir. */
    int (*run)(const study_job *job, const study_figure *f);
} study_kind;

/* The registry: one row per kind, in the order a figure's `kind` key lists them (the first is
 * the default). The rows, their names and their list are generated from this one list
 * (engine.c). */
#define STUDY_KINDS(X) X(approx) X(m0) X(appc) X(cauchy) X(run) X(heat)
#define STUDY_KIND_DECLARE(name) extern const study_kind study_kind_##name;
STUDY_KINDS(STUDY_KIND_DECLARE)
#undef STUDY_KIND_DECLARE
/* Every row, and every name (NULL-terminated), in registry order. */
extern const study_kind *const study_kinds[];
extern const char *const study_kind_names[];

const study_kind *study_kind_of(const consph_study *s, const study_figure *f);
/* The kind named `name`, NULL when none. */
const study_kind *study_kind_lookup(const char *name);
/* Checks every series through study_plan_build: the validate of the operator kinds. */
int study_validate_plans(const consph_study *s, const study_figure *f, int quick);
/* Neighbour pairs and packings of every series: the estimate of the operator kinds. */
int study_estimate_plans(const consph_study *s, const study_figure *f, int quick,
                         const study_files *files, study_estimate *e);
/* Seconds to pack the layout lp (its nx[] set): 0 for an unpacked kind or a layout the cache
 * holds, else particles × modelled iterations × the time of one iteration per particle on this
 * machine (timed once per process). */
double study_packing_seconds(const consph_layout_params *lp);
/* Processor seconds of this process per thread of the runs (consph_num_threads): on an idle
 * machine the seconds a run takes, and nearly that on one that others share, where the wall time
 * of a short calibration is mostly the waits for a core. The clock of the estimates'
 * calibrations. */
double study_cpu_seconds(void);

#endif
