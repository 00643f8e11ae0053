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

#endif
