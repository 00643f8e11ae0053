/* Reader of study files: sections, keys, inheritance, validation (docs/studies.md). */
#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/solver.h"
#include "study/study_internal.h"
#include "study/kinds/kinds.h"
#include "study/keyrules.h"

static char *dup_range(const char *a, size_t n)
{
    char *d = malloc(n + 1);
    if (!d) return NULL;
    memcpy(d, a, n);
    d[n] = '\0';
    return d;
}

/* Appends with truncation (labels are for display only). */
static void append(char *buf, size_t size, const char *s)
{
    size_t len = strlen(buf), n = strlen(s);
    if (len + 1 >= size) return;
    if (n > size - len - 1) n = size - len - 1;
    memcpy(buf + len, s, n);
    buf[len + n] = '\0';
}

static char *trim(char *s)
{
    while (isspace((unsigned char)*s)) ++s;
    char *e = s + strlen(s);
    while (e > s && isspace((unsigned char)e[-1])) --e;
    *e = '\0';
    return s;
}

static int kv_add(study_kvlist *l, const char *key, const char *value, int line)
{
    for (int k = 0; k < l->n; ++k)
        if (strcmp(l->items[k].key, key) == 0)
            return consph_fail(CONSPH_EFORMAT, "key '%s' set twice (first on line %d)", key,
                               l->items[k].line);
    if (l->n == l->cap) {
        int cap = l->cap ? 2 * l->cap : 16;
        study_kv *it = realloc(l->items, (size_t)cap * sizeof *it);
        if (!it) return consph_fail(CONSPH_ENOMEM, "out of memory");
        l->items = it;
        l->cap = cap;
    }
    study_kv *kv = &l->items[l->n];
    kv->key = dup_range(key, strlen(key));
    kv->value = dup_range(value, strlen(value));
    kv->line = line;
    if (!kv->key || !kv->value) return consph_fail(CONSPH_ENOMEM, "out of memory");
    l->n++;
    return CONSPH_OK;
}

static const study_kv *kv_find(const study_kvlist *l, const char *key)
{
    for (int k = 0; k < l->n; ++k)
        if (strcmp(l->items[k].key, key) == 0) return &l->items[k];
    return NULL;
}

static void kv_free(study_kvlist *l)
{
    for (int k = 0; k < l->n; ++k) {
        free(l->items[k].key);
        free(l->items[k].value);
    }
    free(l->items);
    memset(l, 0, sizeof *l);
}

static const study_kv *lookup(const consph_study *s, const study_figure *f, const study_series *r,
                              const char *key)
{
    const study_kv *kv = NULL;
    if (r) kv = kv_find(&r->keys, key);
    if (!kv && f) kv = kv_find(&f->keys, key);
    if (!kv) kv = kv_find(&s->keys, key);
    return kv;
}

const char *study_get(const consph_study *s, const study_figure *f, const study_series *r,
                      const char *key)
{
    const study_kv *kv = lookup(s, f, r, key);
    return kv ? kv->value : NULL;
}

int study_line(const consph_study *s, const study_figure *f, const study_series *r, const char *key)
{
    const study_kv *kv = lookup(s, f, r, key);
    return kv ? kv->line : 0;
}

int study_series_sets(const consph_study *s, const study_figure *f, const study_series *r,
                      const char *key)
{
    return r && lookup(s, f, r, key) != lookup(s, f, NULL, key);
}

static study_figure *add_figure(consph_study *s, const char *id, int line)
{
    if (s->nfigs == s->capfigs) {
        int cap = s->capfigs ? 2 * s->capfigs : 8;
        study_figure *f = realloc(s->figs, (size_t)cap * sizeof *f);
        if (!f) return NULL;
        s->figs = f;
        s->capfigs = cap;
    }
    study_figure *f = &s->figs[s->nfigs++];
    memset(f, 0, sizeof *f);
    f->id = dup_range(id, strlen(id));
    f->line = line;
    return f->id ? f : NULL;
}

static study_series *add_series(study_figure *f, const char *label, int line)
{
    if (f->nseries == f->capseries) {
        int cap = f->capseries ? 2 * f->capseries : 8;
        study_series *r = realloc(f->series, (size_t)cap * sizeof *r);
        if (!r) return NULL;
        f->series = r;
        f->capseries = cap;
    }
    study_series *r = &f->series[f->nseries++];
    memset(r, 0, sizeof *r);
    r->label = dup_range(label, strlen(label));
    r->line = line;
    return r->label ? r : NULL;
}

/* The idx-th comma-separated element of `list`, trimmed, into buf (size STUDY_NAME_MAX + 1);
 * -1 when longer. */
static int list_element(const char *list, int idx, char *buf)
{
    const char *v = list;
    for (int k = 0; k < idx; ++k) v = strchr(v, ',') + 1;
    size_t len = strcspn(v, ",");
    while (len && isspace((unsigned char)*v)) ++v, --len;
    while (len && isspace((unsigned char)v[len - 1])) --len;
    if (len > STUDY_NAME_MAX) return -1;
    memcpy(buf, v, len);
    buf[len] = '\0';
    return 0;
}

/* Checks one series.KEY list: no empty element (the CLI refuses `10,,20` too), none repeated
 * (two series would get one label) and at most STUDY_MAX_SERIES; *count gets its length. */
static int check_series_list(const char *path, const study_kv *kv, int *count)
{
    *count = 1;
    for (const char *c = kv->value; *c; ++c) *count += *c == ',';
    if (*count > STUDY_MAX_SERIES)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: %s: %d values; at most %d series per figure",
                           path, kv->line, kv->key, *count, STUDY_MAX_SERIES);
    char a[STUDY_NAME_MAX + 1], b[STUDY_NAME_MAX + 1];
    for (int i = 0; i < *count; ++i) {
        if (list_element(kv->value, i, a) || !a[0])
            return consph_fail(CONSPH_EFORMAT,
                               "%s:%d: %s: value %d is %s; allowed: comma-separated values of at "
                               "most %d characters",
                               path, kv->line, kv->key, i + 1, a[0] ? "too long" : "empty",
                               STUDY_NAME_MAX);
        for (int j = 0; j < i; ++j) {
            list_element(kv->value, j, b);
            if (strcmp(a, b) == 0)
                return consph_fail(CONSPH_EFORMAT,
                                   "%s:%d: %s: value '%s' given twice (values %d and %d); each "
                                   "value is one series",
                                   path, kv->line, kv->key, a, j + 1, i + 1);
        }
    }
    return CONSPH_OK;
}

/* A figure without [series] sections gets one series per combination of its series.KEY lists
 * (or a single series named after the figure). */
static int expand_series(const char *path, study_figure *f)
{
    const study_kv *lists[8];
    int nl = 0;
    for (int k = 0; k < f->keys.n; ++k) {
        const study_kv *kv = &f->keys.items[k];
        if (strncmp(kv->key, "series.", 7) != 0) continue;
        /* [series] sections name their series themselves: a list beside them would be lost. */
        if (f->nseries)
            return consph_fail(CONSPH_EFORMAT,
                               "%s:%d: %s on figure '%s', which has [series] sections (line %d); "
                               "use one or the other",
                               path, kv->line, kv->key, f->id, f->series[0].line);
        if (nl == 8)
            return consph_fail(CONSPH_EFORMAT, "%s:%d: more than 8 series.KEY lists on figure '%s'",
                               path, kv->line, f->id);
        lists[nl++] = kv;
    }
    if (f->nseries) return CONSPH_OK;
    if (nl == 0) return add_series(f, f->id, f->line) ? CONSPH_OK : CONSPH_ENOMEM;
    int count[8], idx[8] = {0};
    int total = 1;
    for (int l = 0; l < nl; ++l) {
        int rc = check_series_list(path, lists[l], &count[l]);
        if (rc) return rc;
        total *= count[l];
        if (total > STUDY_MAX_SERIES)
            return consph_fail(
                CONSPH_EFORMAT,
                "%s:%d: the series.KEY lists of figure '%s' make more than %d series "
                "(every combination is one)",
                path, lists[l]->line, f->id, STUDY_MAX_SERIES);
    }
    for (int t = 0; t < total; ++t) {
        char label[256] = "";
        char values[8][STUDY_NAME_MAX + 1];
        for (int l = 0; l < nl; ++l) {
            list_element(lists[l]->value, idx[l], values[l]);
            if (l) append(label, sizeof label, " ");
            append(label, sizeof label, lists[l]->key + 7);
            append(label, sizeof label, "=");
            append(label, sizeof label, values[l]);
        }
        /* A label cut short could equal another. */
        if (strlen(label) + 1 >= sizeof label)
            return consph_fail(CONSPH_EFORMAT,
                               "%s:%d: the series label '%s...' of figure '%s' is longer than %zu "
                               "characters",
                               path, lists[0]->line, label, f->id, sizeof label - 2);
        study_series *r = add_series(f, label, lists[0]->line);
        if (!r) return CONSPH_ENOMEM;
        for (int l = 0; l < nl; ++l) {
            int rc = kv_add(&r->keys, lists[l]->key + 7, values[l], lists[l]->line);
            if (rc) return rc;
        }
        for (int l = nl - 1; l >= 0; --l) {
            if (++idx[l] < count[l]) break;
            idx[l] = 0;
        }
    }
    return CONSPH_OK;
}

int study_plain_name(const char *name, int series)
{
    size_t n = strlen(name);
    if (n == 0 || n > STUDY_NAME_MAX || name[0] == '.' || name[0] == ' ' || name[n - 1] == ' ')
        return 0;
    for (const char *c = name; *c; ++c)
        if (!isalnum((unsigned char)*c) && *c != '-' && *c != '_' && *c != '.' &&
            !(series && (*c == ' ' || *c == '=')))
            return 0;
    return 1;
}

/* Index of figure `id`, or -1. */
static int find_figure(const consph_study *s, const char *id)
{
    for (int k = 0; k < s->nfigs; ++k)
        if (strcmp(s->figs[k].id, id) == 0) return k;
    return -1;
}

static int find_series(const study_figure *f, const char *label)
{
    for (int k = 0; k < f->nseries; ++k)
        if (strcmp(f->series[k].label, label) == 0) return k;
    return -1;
}

/* One section header `[KIND NAME]` (brackets stripped into `t`). */
static int parse_section(consph_study *s, char *t, const char *path, int line, study_figure **fig,
                         study_series **ser)
{
    char *close = strchr(t, ']');
    if (!close || close[1])
        return consph_fail(CONSPH_EFORMAT, "%s:%d: malformed section header", path, line);
    *close = '\0';
    char *inner = trim(t + 1);
    char *space = inner;
    while (*space && !isspace((unsigned char)*space)) ++space;
    char *name = trim(space);
    if (*space) *space = '\0';
    int is_fig = strcmp(inner, "figure") == 0, is_ser = strcmp(inner, "series") == 0;
    if (!is_fig && !is_ser)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: unknown section '[%s]'; allowed: figure, series",
                           path, line, inner);
    if (!*name)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: section '[%s]' needs a name", path, line, inner);
    /* Figure ids name output files; series labels go into tables and plot keys. */
    if (!study_plain_name(name, is_ser))
        return consph_fail(CONSPH_EFORMAT,
                           "%s:%d: %s name '%s' is not a plain name (letters, digits, '-', '_', "
                           "'.'%s; not starting with '.'; at most %d characters)",
                           path, line, inner, name, is_ser ? ", '=' and inner spaces" : "",
                           STUDY_NAME_MAX);
    if (is_fig) {
        int prev = find_figure(s, name);
        if (prev >= 0)
            return consph_fail(CONSPH_EFORMAT, "%s:%d: figure '%s' already defined on line %d",
                               path, line, name, s->figs[prev].line);
        *ser = NULL;
        if (!(*fig = add_figure(s, name, line))) return consph_fail(CONSPH_ENOMEM, "out of memory");
        return CONSPH_OK;
    }
    if (!*fig)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: [series] before any [figure]", path, line);
    if ((*fig)->nseries == STUDY_MAX_SERIES)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: more than %d series in figure '%s'", path, line,
                           STUDY_MAX_SERIES, (*fig)->id);
    int prev = find_series(*fig, name);
    if (prev >= 0)
        return consph_fail(CONSPH_EFORMAT,
                           "%s:%d: series '%s' of figure '%s' already defined on line %d", path,
                           line, name, (*fig)->id, (*fig)->series[prev].line);
    if (!(*ser = add_series(*fig, name, line))) return consph_fail(CONSPH_ENOMEM, "out of memory");
    return CONSPH_OK;
}

/* Where the reading is: the study, its file, the figure and series being read. */
typedef struct parse_state {
    consph_study *s;
    const char *path;
    study_figure *fig;
    study_series *ser;
} parse_state;

/* One line as consph_kv_parse hands it: a section header (value NULL) or key = value. */
static int parse_line(void *ctx, int line, char *key, char *value)
{
    parse_state *ps = ctx;
    consph_study *s = ps->s;
    const char *path = ps->path;
    study_figure **fig = &ps->fig;
    study_series **ser = &ps->ser;
    if (!value) return parse_section(s, key, path, line, fig, ser);
    key_rule rule_row, inner_row;
    const key_rule *rule = study_key_rule_of(key, &rule_row) ? &rule_row : NULL;
    if (!rule)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: unknown key '%s' (see docs/studies.md)", path,
                           line, key);
    if (!*value)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: key '%s' has no value", path, line, key);
    if (strcmp(key, "study") == 0 && *fig)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: 'study' belongs before the first [figure]", path,
                           line);
    if (strcmp(key, "study") == 0 && !study_plain_name(value, 0))
        return consph_fail(CONSPH_EFORMAT,
                           "%s:%d: study name '%s' is not a plain name (letters, digits, '-', "
                           "'_', '.'; not starting with '.')",
                           path, line, value);
    const int at = *ser ? AT_SERIES : *fig ? AT_FIGURE : AT_STUDY;
    if (at == AT_SERIES && !(rule->at & AT_SERIES))
        return consph_fail(CONSPH_EFORMAT,
                           "%s:%d: key '%s' is one per figure: set it on [figure %s], not in "
                           "[series %s]",
                           path, line, key, (*fig)->id, (*ser)->label);
    if (at == AT_STUDY && !(rule->at & AT_STUDY))
        return consph_fail(CONSPH_EFORMAT, "%s:%d: key '%s' belongs on a [figure]", path, line,
                           key);
    const key_rule *inner =
        rule->at == AT_FIGURE && study_key_rule_of(key + 7, &inner_row) ? &inner_row : NULL;
    if (rule->at == AT_FIGURE && (!inner || !(inner->at & AT_SERIES) || inner->at == AT_FIGURE))
        return consph_fail(CONSPH_EFORMAT,
                           "%s:%d: '%s': '%s' is not a key a series may set (see docs/studies.md)",
                           path, line, key, key + 7);
    study_kvlist *l = *ser ? &(*ser)->keys : *fig ? &(*fig)->keys : &s->keys;
    int rc = kv_add(l, key, value, line);
    if (rc) consph_fail(rc, "%s:%d: %s", path, line, consph_last_error());
    return rc;
}

/* The file name without directories and without ".study" (NULL when it has no such suffix). */
static char *name_from_path(const char *path)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    size_t n = strlen(base);
    if (n <= 6 || strcmp(base + n - 6, ".study") != 0) return NULL;
    return dup_range(base, n - 6);
}

int study_parse(const char *path, const char *data, size_t size, consph_study **out)
{
    *out = NULL;
    consph_study *s = calloc(1, sizeof *s);
    if (!s || !(s->path = dup_range(path, strlen(path)))) {
        free(s);
        return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    parse_state ps = {s, path, NULL, NULL};
    int rc = consph_kv_parse(path, data, size, STUDY_LINE_MAX, parse_line, &ps);
    const char *name = study_get(s, NULL, NULL, "study");
    if (rc == CONSPH_OK && !name)
        rc = consph_fail(CONSPH_EFORMAT, "%s: no 'study = NAME' line", path);
    if (rc == CONSPH_OK && s->nfigs == 0)
        rc = consph_fail(CONSPH_EFORMAT, "%s: no [figure] section", path);
    for (int k = 0; rc == CONSPH_OK && k < s->nfigs; ++k) rc = expand_series(path, &s->figs[k]);
    if (rc == CONSPH_OK) rc = study_check_kinds(s);
    if (rc) {
        consph_study_free(s);
        return rc;
    }
    *out = s;
    return CONSPH_OK;
}

int consph_study_load(const char *path, consph_study **out)
{
    *out = NULL;
    FILE *fp = fopen(path, "rb");
    if (!fp) return consph_fail(CONSPH_EIO, "cannot read '%s': %s", path, strerror(errno));
    /* Study files are small; a bound keeps a mistaken path from filling memory. */
    enum { MAX_SIZE = 1 << 20 };
    char *data = malloc(MAX_SIZE + 1);
    size_t size = data ? fread(data, 1, MAX_SIZE + 1, fp) : 0;
    int err = ferror(fp);
    fclose(fp);
    if (!data) return consph_fail(CONSPH_ENOMEM, "out of memory");
    int rc = CONSPH_OK;
    if (err)
        rc = consph_fail(CONSPH_EIO, "cannot read '%s'", path);
    else if (size > MAX_SIZE)
        rc = consph_fail(CONSPH_EFORMAT, "%s: larger than %d bytes", path, MAX_SIZE);
    else
        rc = study_parse(path, data, size, out);
    free(data);
    if (rc) return rc;
    /* The name given to `consph study` finds the file, so the two must agree. */
    char *expect = name_from_path(path);
    const char *name = consph_study_name(*out);
    if (expect && strcmp(expect, name) != 0)
        rc = consph_fail(CONSPH_EFORMAT, "%s:%d: study = %s, but the file name says '%s'", path,
                         study_line(*out, NULL, NULL, "study"), name, expect);
    free(expect);
    if (rc) {
        consph_study_free(*out);
        *out = NULL;
    }
    return rc;
}

void consph_study_free(consph_study *s)
{
    if (!s) return;
    for (int k = 0; k < s->nfigs; ++k) {
        study_figure *f = &s->figs[k];
        for (int r = 0; r < f->nseries; ++r) {
            free(f->series[r].label);
            kv_free(&f->series[r].keys);
        }
        free(f->series);
        free(f->id);
        kv_free(&f->keys);
    }
    free(s->figs);
    kv_free(&s->keys);
    free(s->path);
    free(s);
}

const char *consph_study_name(const consph_study *s)
{
    return study_get(s, NULL, NULL, "study");
}

const char *consph_study_title(const consph_study *s)
{
    const char *t = study_get(s, NULL, NULL, "title");
    return t ? t : "";
}
