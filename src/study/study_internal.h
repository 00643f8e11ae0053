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

#endif
