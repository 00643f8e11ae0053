/* Reader of study files: sections, keys, inheritance, validation (docs/studies.md). */
#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "study/study_internal.h"

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

/* Every key a study file may set; names ending in '.' are prefixes. */
static const char *const known_keys[] = {
    "study",       "title",    "paper",      "note",
    "kind",        "op",       "form",       "corr",
    "kernel",      "hdx",      "h_policy",   "match_support",
    "beta",        "measure",  "ot_method",  "ot_p",
    "directions",  "grid",     "layout",     "dim",
    "eps",         "seed",     "periodic",   "field",
    "sigma",       "volume",   "mask",       "sweep",
    "nx",          "quick.nx", "hdx.values", "quick.hdx.values",
    "x",           "norm",     "bound",      "bins",
    "range",       "pack_tol", "pack_iter",  "hdelta.values",
    "problem",     "scheme",   "c0",         "re",
    "tf",          "quick.tf", "steps",      "quick.steps",
    "dt_rule",     "tr_ref",   "laplacian",  "walls",
    "report",      "paper.",   "series.",    "dt",
    "l1",          "rho_init", "y",          "error",
    "error_times", NULL};

static int key_known(const char *key)
{
    for (int k = 0; known_keys[k]; ++k) {
        size_t n = strlen(known_keys[k]);
        if (known_keys[k][n - 1] == '.') {
            if (strncmp(key, known_keys[k], n) == 0 && key[n]) return 1;
        } else if (strcmp(key, known_keys[k]) == 0) {
            return 1;
        }
    }
    return 0;
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

/* A figure without [series] sections gets one series per combination of its series.KEY lists
 * (or a single series named after the figure). */
static int expand_series(study_figure *f)
{
    if (f->nseries) return CONSPH_OK;
    const study_kv *lists[8];
    int nl = 0;
    for (int k = 0; k < f->keys.n && nl < 8; ++k)
        if (strncmp(f->keys.items[k].key, "series.", 7) == 0) lists[nl++] = &f->keys.items[k];
    if (nl == 0) return add_series(f, f->id, f->line) ? CONSPH_OK : CONSPH_ENOMEM;
    int count[8], idx[8] = {0};
    int total = 1;
    for (int l = 0; l < nl; ++l) {
        count[l] = 1;
        for (const char *c = lists[l]->value; *c; ++c) count[l] += *c == ',';
        total *= count[l];
    }
    for (int t = 0; t < total; ++t) {
        char label[256] = "";
        char values[8][96];
        for (int l = 0; l < nl; ++l) {
            /* The idx[l]-th comma-separated value. */
            const char *v = lists[l]->value;
            for (int k = 0; k < idx[l]; ++k) v = strchr(v, ',') + 1;
            const char *e = strchr(v, ',');
            size_t len = e ? (size_t)(e - v) : strlen(v);
            if (len >= sizeof values[l]) len = sizeof values[l] - 1;
            memcpy(values[l], v, len);
            values[l][len] = '\0';
            char *tv = trim(values[l]);
            memmove(values[l], tv, strlen(tv) + 1);
            if (l) append(label, sizeof label, " ");
            append(label, sizeof label, lists[l]->key + 7);
            append(label, sizeof label, "=");
            append(label, sizeof label, values[l]);
        }
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
    int prev = find_series(*fig, name);
    if (prev >= 0)
        return consph_fail(CONSPH_EFORMAT,
                           "%s:%d: series '%s' of figure '%s' already defined on line %d", path,
                           line, name, (*fig)->id, (*fig)->series[prev].line);
    if (!(*ser = add_series(*fig, name, line))) return consph_fail(CONSPH_ENOMEM, "out of memory");
    return CONSPH_OK;
}

/* One logical line, comments and surrounding blanks included. */
static int parse_line(consph_study *s, char *buf, const char *path, int line, study_figure **fig,
                      study_series **ser)
{
    char *hash = strchr(buf, '#');
    if (hash) *hash = '\0';
    char *t = trim(buf);
    if (!*t) return CONSPH_OK;
    for (const char *c = t; *c; ++c)
        if ((unsigned char)*c < 0x20 && *c != '\t')
            return consph_fail(CONSPH_EFORMAT, "%s:%d: control character 0x%02x", path, line,
                               (unsigned char)*c);
    if (*t == '[') return parse_section(s, t, path, line, fig, ser);
    char *eq = strchr(t, '=');
    if (!eq) return consph_fail(CONSPH_EFORMAT, "%s:%d: expected 'key = value'", path, line);
    *eq = '\0';
    char *key = trim(t), *value = trim(eq + 1);
    if (!key_known(key))
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
    char buf[STUDY_LINE_MAX + 1];
    int line = 0, rc = CONSPH_OK;
    study_figure *fig = NULL;
    study_series *ser = NULL;
    size_t pos = 0;
    while (rc == CONSPH_OK && pos < size) {
        ++line;
        const char *nl = memchr(data + pos, '\n', size - pos);
        size_t len = nl ? (size_t)(nl - (data + pos)) : size - pos;
        if (memchr(data + pos, '\0', len)) {
            rc = consph_fail(CONSPH_EFORMAT, "%s:%d: NUL byte", path, line);
        } else if (len > STUDY_LINE_MAX) {
            rc = consph_fail(CONSPH_EFORMAT, "%s:%d: line longer than %d characters", path, line,
                             STUDY_LINE_MAX);
        } else {
            memcpy(buf, data + pos, len);
            buf[len] = '\0';
            rc = parse_line(s, buf, path, line, &fig, &ser);
        }
        pos += len + 1;
    }
    const char *name = study_get(s, NULL, NULL, "study");
    if (rc == CONSPH_OK && !name)
        rc = consph_fail(CONSPH_EFORMAT, "%s: no 'study = NAME' line", path);
    if (rc == CONSPH_OK && s->nfigs == 0)
        rc = consph_fail(CONSPH_EFORMAT, "%s: no [figure] section", path);
    for (int k = 0; rc == CONSPH_OK && k < s->nfigs; ++k) rc = expand_series(&s->figs[k]);
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
