/* Run parameter files (consph run --config FILE, the Python module's Solver(config=...)):
 * `key = value` lines with '#' comments, read by the study files' lexer (consph_kv_parse,
 * src/io/kvtext.c), with the run keys of study files (the parameter table's study keys,
 * src/solver/params.def). docs/solver-files.md, "Runs from the user's inputs". */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/io.h"
#include "consph/solver.h"

/* The pairs of parameters that set one thing, each replacing the other. */
static const char *const clash_pairs[][3] = {{"tf", "steps", "the end of the run"},
                                             {"re", "nu", "the viscosity"},
                                             {"dt", "cfl", "the time step"},
                                             {"dt", "h_dt", "the time step"}};
#define NCLASH (sizeof clash_pairs / sizeof clash_pairs[0])

static int run_file_line(void *ctx, int line, char *key, char *value)
{
    consph_run_file *rf = ctx;
    if (!value)
        return consph_fail(CONSPH_EFORMAT,
                           "%s:%d: '%.40s': a run file has no sections, only key = value lines "
                           "(sections are for study files)",
                           rf->path, line, key);
    const consph_run_param *d = NULL;
    char allowed[640] = "";
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *r = consph_run_param_at(k);
        if (!r->study_key) continue;
        if (!strcmp(r->study_key, key)) d = r;
        size_t len = strlen(allowed);
        snprintf(allowed + len, sizeof allowed - len, "%s%s", len ? ", " : "", r->study_key);
    }
    if (!d)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: unknown key '%.40s' (allowed: %s)", rf->path,
                           line, key, allowed);
    if (!*value)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: key '%s' has no value", rf->path, line, key);
    for (int k = 0; k < rf->n; ++k)
        if (rf->key[k].param == d)
            return consph_fail(CONSPH_EFORMAT, "%s:%d: key '%s' set twice (first on line %d)",
                               rf->path, line, key, rf->key[k].line);
    if (strlen(value) >= CONSPH_RUN_FILE_VALUE || rf->n == CONSPH_RUN_FILE_KEYS)
        return consph_fail(CONSPH_EFORMAT, "%s:%d: key '%s': a value of at most %d characters",
                           rf->path, line, key, CONSPH_RUN_FILE_VALUE - 1);
    rf->key[rf->n].param = d;
    strcpy(rf->key[rf->n].value, value);
    rf->key[rf->n].line = line;
    rf->key[rf->n].dropped = 0;
    ++rf->n;
    return CONSPH_OK;
}

int consph_run_file_load(consph_run_file *rf, const char *path)
{
    enum { MAX_SIZE = 1 << 20 }; /* run files are small: a mistaken path must not fill memory */
    rf->path = path;
    rf->n = 0;
    FILE *fp = fopen(path, "rb");
    if (!fp) return consph_fail(CONSPH_EIO, "cannot read '%s': %s", path, strerror(errno));
    char *data = malloc(MAX_SIZE + 1);
    const size_t size = data ? fread(data, 1, MAX_SIZE + 1, fp) : 0;
    const int err = ferror(fp);
    fclose(fp);
    if (!data) return consph_fail(CONSPH_ENOMEM, "out of memory");
    int st;
    if (err)
        st = consph_fail(CONSPH_EIO, "cannot read '%s'", path);
    else if (size > MAX_SIZE)
        st = consph_fail(CONSPH_EFORMAT, "%s: larger than %d bytes", path, MAX_SIZE);
    else
        st = consph_kv_parse(path, data, size, 4095, run_file_line, rf);
    free(data);
    return st;
}

int consph_run_file_find(const consph_run_file *rf, const char *name)
{
    for (int k = 0; rf && k < rf->n; ++k)
        if (!rf->key[k].dropped && !strcmp(rf->key[k].param->name, name)) return k;
    return -1;
}

int consph_run_file_apply(consph_run_file *rf, consph_run_params *prm,
                          int (*given)(void *ctx, const char *param), void *ctx)
{
    for (int k = 0; k < rf->n; ++k) {
        const consph_run_param *d = rf->key[k].param;
        int dropped = (given && given(ctx, d->name)) || !strcmp(d->name, "problem");
        for (size_t c = 0; c < NCLASH; ++c)
            for (int side = 0; side < 2; ++side)
                if (!strcmp(d->name, clash_pairs[c][side]) && given &&
                    given(ctx, clash_pairs[c][1 - side]))
                    dropped = 1;
        consph_run_params scratch = *prm;
        if (consph_run_param_set(dropped ? &scratch : prm, d->name, rf->key[k].value) !=
            CONSPH_OK) {
            char why[512]; /* consph_fail writes the buffer consph_last_error reads */
            snprintf(why, sizeof why, "%s", consph_last_error());
            return consph_fail(CONSPH_EINVAL, "%s:%d: key '%s': %s", rf->path, rf->key[k].line,
                               d->study_key, why);
        }
        rf->key[k].dropped = dropped;
    }
    for (size_t c = 0; c < NCLASH; ++c) {
        const int a = consph_run_file_find(rf, clash_pairs[c][0]),
                  b = consph_run_file_find(rf, clash_pairs[c][1]);
        if (a < 0 || b < 0) continue;
        const int later = a > b ? a : b, earlier = a > b ? b : a;
        return consph_fail(
            CONSPH_EINVAL, "%s:%d: keys '%s' and '%s' (line %d) both set %s: give one", rf->path,
            rf->key[later].line, rf->key[later].param->study_key, rf->key[earlier].param->study_key,
            rf->key[earlier].line, clash_pairs[c][2]);
    }
    return CONSPH_OK;
}

int consph_run_params_unread(const consph_run_params *prm,
                             int (*given)(void *ctx, const char *name, char *where, size_t size),
                             void *ctx, const char *scheme_word, const char *layout_word)
{
    char list[512], where[320], lw[320];
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        if (!d->reads || !given(ctx, d->name, where, sizeof where) ||
            (d->reads == CONSPH_PARAM_EOS && !strcmp(d->name, "eos") &&
             prm->eos == CONSPH_EOS_DEFAULT) ||
            consph_scheme_reads(prm->scheme, d->reads))
            continue;
        return consph_fail(CONSPH_EINVAL, "%s does nothing for %s %s (it acts on: %s)", where,
                           scheme_word, prm->scheme,
                           consph_scheme_readers(d->reads, list, sizeof list));
    }
    const int layout = consph_run_params_layout(prm);
    if (!given(ctx, "seed", where, sizeof where) || layout < 0 ||
        consph_layout_uses_seed((consph_layout_kind)layout))
        return CONSPH_OK;
    return consph_fail(CONSPH_EINVAL,
                       "%s does nothing for %s %s (%s), which draws no random numbers (it acts "
                       "on: %s)",
                       where, layout_word, consph_layout_name((consph_layout_kind)layout),
                       given(ctx, "layout", lw, sizeof lw) ? "given"
                                                           : "the problem's or scheme's default",
                       consph_layout_seeded_names(list, sizeof list));
}
