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
static const char *const known_keys[] = {"study",      "title",
                                         "paper",      "note",
                                         "kind",       "op",
                                         "form",       "corr",
                                         "kernel",     "hdx",
                                         "h_policy",   "match_support",
                                         "layout",     "dim",
                                         "eps",        "seed",
                                         "periodic",   "field",
                                         "sigma",      "volume",
                                         "mask",       "sweep",
                                         "nx",         "quick.nx",
                                         "hdx.values", "quick.hdx.values",
                                         "x",          "norm",
                                         "bound",      "bins",
                                         "range",      "pack_tol",
                                         "pack_iter",  "hdelta.values",
                                         "paper.",     "series.",
                                         NULL};

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

int consph_study_load(const char *path, consph_study **out)
{
    *out = NULL;
    FILE *fp = fopen(path, "r");
    if (!fp) return consph_fail(CONSPH_EIO, "cannot read '%s': %s", path, strerror(errno));
    consph_study *s = calloc(1, sizeof *s);
    if (!s) {
        fclose(fp);
        return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    s->path = dup_range(path, strlen(path));
    char buf[4096];
    int line = 0, rc = CONSPH_OK;
    study_figure *fig = NULL;
    study_series *ser = NULL;
    while (rc == CONSPH_OK && fgets(buf, sizeof buf, fp)) {
        ++line;
        char *hash = strchr(buf, '#');
        if (hash) *hash = '\0';
        char *t = trim(buf);
        if (!*t) continue;
        if (*t == '[') {
            char *close = strchr(t, ']');
            if (!close || close[1]) {
                rc = consph_fail(CONSPH_EFORMAT, "%s:%d: malformed section header", path, line);
                break;
            }
            *close = '\0';
            char *inner = trim(t + 1);
            char *space = inner;
            while (*space && !isspace((unsigned char)*space)) ++space;
            char *name = trim(space);
            if (*space) *space = '\0';
            if (!*name) {
                rc = consph_fail(CONSPH_EFORMAT, "%s:%d: section '[%s]' needs a name", path, line,
                                 inner);
            } else if (strcmp(inner, "figure") == 0) {
                fig = add_figure(s, name, line);
                ser = NULL;
                if (!fig) rc = consph_fail(CONSPH_ENOMEM, "out of memory");
            } else if (strcmp(inner, "series") == 0) {
                if (!fig)
                    rc = consph_fail(CONSPH_EFORMAT, "%s:%d: [series] before any [figure]", path,
                                     line);
                else if (!(ser = add_series(fig, name, line)))
                    rc = consph_fail(CONSPH_ENOMEM, "out of memory");
            } else {
                rc = consph_fail(CONSPH_EFORMAT,
                                 "%s:%d: unknown section '[%s]'; allowed: figure, series", path,
                                 line, inner);
            }
            continue;
        }
        char *eq = strchr(t, '=');
        if (!eq) {
            rc = consph_fail(CONSPH_EFORMAT, "%s:%d: expected 'key = value'", path, line);
            break;
        }
        *eq = '\0';
        char *key = trim(t), *value = trim(eq + 1);
        if (!key_known(key)) {
            rc = consph_fail(CONSPH_EFORMAT, "%s:%d: unknown key '%s' (see docs/studies.md)", path,
                             line, key);
            break;
        }
        if (!*value) {
            rc = consph_fail(CONSPH_EFORMAT, "%s:%d: key '%s' has no value", path, line, key);
            break;
        }
        study_kvlist *l = ser ? &ser->keys : fig ? &fig->keys : &s->keys;
        rc = kv_add(l, key, value, line);
        if (rc) consph_fail(rc, "%s:%d: %s", path, line, consph_last_error());
    }
    fclose(fp);
    if (rc == CONSPH_OK && !study_get(s, NULL, NULL, "study"))
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
