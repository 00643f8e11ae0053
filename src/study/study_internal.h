/* The parsed form of a study file (docs/studies.md). */
#ifndef CONSPH_STUDY_INTERNAL_H
#define CONSPH_STUDY_INTERNAL_H

#include "consph/study.h"

typedef struct study_kv {
    char *key;
    char *value;
    int line;
} study_kv;

typedef struct study_kvlist {
    study_kv *items;
    int n, cap;
} study_kvlist;

typedef struct study_series {
    char *label;
    study_kvlist keys;
    int line;
} study_series;

typedef struct study_figure {
    char *id;
    study_kvlist keys;
    study_series *series;
    int nseries, capseries;
    int line;
} study_figure;

struct consph_study {
    char *path;
    study_kvlist keys;
    study_figure *figs;
    int nfigs, capfigs;
};

/* The value of `key` seen from a series (series, then figure, then study), or NULL. */
const char *study_get(const consph_study *s, const study_figure *f, const study_series *r,
                      const char *key);
/* 1 when the series r itself sets key (not its figure or the study, whose keys are defaults for
 * series that may not read them). */
int study_series_sets(const consph_study *s, const study_figure *f, const study_series *r,
                      const char *key);
/* Line of the definition found by study_get (0 when absent). */
int study_line(const consph_study *s, const study_figure *f, const study_series *r,
               const char *key);

/* Longest line of a study file, and longest figure id or series label. */
#define STUDY_LINE_MAX 4095
#define STUDY_NAME_MAX 64
/* Series of one figure: each is a run per resolution, so a typo in a list must not start
 * thousands (the shipped studies have at most 30). */
#define STUDY_MAX_SERIES 256

/* Parses a study held in memory (`path` names it in messages); no file-name check. The entry
 * point of consph_study_load and of the study fuzz target. */
int study_parse(const char *path, const char *data, size_t size, consph_study **out);
/* Whether `name` is a plain name: letters, digits, '-', '_', '.', not starting with '.', at most
 * STUDY_NAME_MAX characters; `series` also allows '=' and inner spaces ("F1 eta=1.5"). */
int study_plain_name(const char *name, int series);

/* ---- shared by the figure kinds (keys.c, writer.c; kinds/kinds.h has the rest) ---- */

#include <stdio.h>

#define MAX_SWEEP 64
/* Room for any output path: the CLI refuses --out directories that would not fit. */
#define STUDY_PATH_MAX 4096
/* Orders further than this from the paper's are flagged in the report. */
#define ORDER_TOLERANCE 0.3

/* CONSPH_EFORMAT naming file:line, figure, series and key. */
int study_key_error(const consph_study *s, const study_figure *f, const study_series *r,
                    const char *key, const char *fmt, ...);
/* A key's value checked against a range (def when absent), a list of numbers, or one of
 * `choices` (NULL-terminated; *out is its index). */
int study_get_double(const consph_study *s, const study_figure *f, const study_series *r,
                     const char *key, double def, double lo, double hi, double *out);
int study_get_list(const consph_study *s, const study_figure *f, const study_series *r,
                   const char *key, double lo, double hi, double *vals, int *n);
int study_get_choice(const consph_study *s, const study_figure *f, const study_series *r,
                     const char *key, const char *const *choices, int def, int *out);
const char *study_get_or(const consph_study *s, const study_figure *f, const study_series *r,
                         const char *key, const char *def);
/* A published value that is a plain number. */
int study_paper_number(const consph_study *s, const study_figure *f, const study_series *r,
                       const char *key, double *out);
/* Every paper.* value of every series, as a list. */
void study_published_values(const consph_study *s, const study_figure *f, FILE *o);
const char *study_figure_note(const study_figure *f);
/* The head of a figure's report: "## ID: title" and the figure's note. */
void study_report_head(FILE *o, const consph_study *s, const study_figure *f);
/* The same with a title of the caller's (one that says what this run was). */
void study_report_head_as(FILE *o, const consph_study *s, const study_figure *f, const char *title);
/* DIR/NAME.EXT into buf (STUDY_PATH_MAX bytes), refused rather than truncated. */
int study_out_path(char *buf, const char *dir, const char *name, const char *ext);
/* Opens DIR/ID.EXT as a consph_outfile (written to a temporary name, renamed on commit). */
#include "consph/io.h"
int study_open_output(consph_outfile *of, const char *dir, const char *id, const char *ext);
const char *study_csv_label(const char *label, char *buf, size_t size);
/* gnuplot: whether installed, a quoted string, the head of a script, and drawing ID.gp into
 * ID.svg. */
int study_have_gnuplot(void);
int study_gp_put(FILE *o, const char *text);
int study_gp_head(FILE *o, const char *id, const char *title, const char *ran);
int study_gp_title(FILE *o, const char *title, const char *ran);
/* Series k's colour and marker (" lc rgb '...' pt N"), the paper point's style for series k,
 * and the colour and marker alone. */
void study_gp_style(FILE *o, int k);
void study_gp_paper_style(FILE *o, int k);
const char *study_gp_colour(int k);
int study_gp_point(int k);
/* The extent of what a figure draws on one axis, and `set Xrange` cropped to it. */
typedef struct study_extent {
    double lo, hi;
} study_extent;
void study_extent_init(study_extent *e);
void study_extent_add(study_extent *e, double v, int log);
void study_gp_range(FILE *o, const char *axis, const study_extent *e, int log);
/* `set Xtics` at these values (the resolutions that ran and the paper's), at most 12. */
void study_gp_tics(FILE *o, const char *axis, const double *v, int n);
/* "NAME = v1, v2, ..." appended at buf + *len, for the line of a title that says what ran. */
void study_list_text(char *buf, size_t size, size_t *len, const char *name, const double *v, int n);
int study_render_figure(const char *dir, const char *id);

/* ---- kind = run: solver runs over resolutions (runstudy.c) ---- */

/* Checks every key of a run figure's series. */
int study_run_validate(const consph_study *s, const study_figure *f, int quick);
/* Runs the figure (job: kinds/kinds.h) and writes FIGURE.csv, .md, .dat, .gp and .svg into
 * job->dir. */
struct study_job;
int study_run_figure(const struct study_job *job, const study_figure *f);
/* The figure's runs, and their particle-steps added to *work. */
int study_run_rows(const consph_study *s, const study_figure *f, int quick, double *work);
/* Appends to buf (size bytes, *len used) a line for every series of the run figure f that cannot
 * run on the GPU ("figure 'F', series 'S' (nx 16, 24): why", consph_gpu_check) and counts them
 * in *bad. */
void study_run_gpu_refusals(const consph_study *s, const study_figure *f, int quick, char *buf,
                            size_t size, size_t *len, int *bad);
/* Particle-steps of the figure's runs, and the seconds they should take (calibrated on a short
 * run of its first series). */
double study_run_estimate(const consph_study *s, const study_figure *f, int quick,
                          double *particle_steps);
/* Calls add(lp, ctx) with the layout of every run of the figure (consph_run_layout_params, as
 * its rows make them), in row order: what a study packs before its workers start (engine.c). */
int study_run_layouts(const consph_study *s, const study_figure *f, int quick,
                      void (*add)(const consph_layout_params *lp, void *ctx), void *ctx);
#define STUDY_MAX_SWEEP MAX_SWEEP

/* ---- kind = heat (kinds/heat.c): 002's heat-conduction runs, S3 against S4 (docs/heat.md) ---- */
/* The estimated run time of a heat figure in seconds, calibrated on a small run. */
double study_heat_seconds(const consph_study *s, const study_figure *f, int quick);

#endif
