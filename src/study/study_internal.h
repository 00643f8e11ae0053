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
/* Line of the definition found by study_get (0 when absent). */
int study_line(const consph_study *s, const study_figure *f, const study_series *r,
               const char *key);

/* Longest line of a study file, and longest figure id or series label. */
#define STUDY_LINE_MAX 4095
#define STUDY_NAME_MAX 64

/* Parses a study held in memory (`path` names it in messages); no file-name check. The entry
 * point of consph_study_load and of the study fuzz target. */
int study_parse(const char *path, const char *data, size_t size, consph_study **out);
/* Whether `name` is a plain name: letters, digits, '-', '_', '.', not starting with '.', at most
 * STUDY_NAME_MAX characters; `series` also allows '=' and inner spaces ("F1 eta=1.5"). */
int study_plain_name(const char *name, int series);

/* Helpers of the engine (engine.c) for the figure kinds that live in their own files. */
#define STUDY_MAX_SWEEP 64
#include <stdio.h>
int study_out_path(char *buf, const char *dir, const char *name, const char *ext);
int study_get_double(const consph_study *s, const study_figure *f, const study_series *r,
                     const char *key, double def, double lo, double hi, double *out);
/* A comma-separated list (at most STUDY_MAX_SWEEP values); *n = 0 when the key is absent. */
int study_get_list(const consph_study *s, const study_figure *f, const study_series *r,
                   const char *key, double lo, double hi, double *vals, int *n);
/* CONSPH_EFORMAT naming the file, line, figure, series and key. */
int study_key_error(const consph_study *s, const study_figure *f, const study_series *r,
                    const char *key, const char *msg);
const char *study_csv_label(const char *label, char *buf, size_t size);
/* The head of a figure's gnuplot script, and a user string quoted for gnuplot. */
int study_gp_head(FILE *o, const char *id, const char *title);
int study_gp_put(FILE *o, const char *text);
int study_have_gnuplot(void);
/* DIR/ID.gp into DIR/ID.svg (a warning, once, without gnuplot). */
int study_render_figure(const char *dir, const char *id);
/* The figure's own note key, or NULL. */
const char *study_figure_note(const study_figure *f);

/* kind = heat (heat_study.c): 002's heat-conduction runs, S3 against S4 (docs/heat.md). */
int study_heat_figure(const consph_study *s, const study_figure *f, int quick, const char *dir,
                      FILE *log);
/* The estimated run time of a heat figure in seconds, calibrated on a small run. */
double study_heat_seconds(const consph_study *s, const study_figure *f, int quick);

#endif
