/* What a checkpoint holds of a solver besides its particles: the parameters and the scalars of
 * the run as "key=value" lines, doubles in C99 hexadecimal (%a) so they read back bit for bit,
 * and the history of the sampled diagnostics. Parsing is strict: every key known, every value
 * checked. */
#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "solver/params.h"
#include "solver/solver_internal.h"

#define META_MAX 4096
/* 2: wcsph/edac default to pec and tvf's kdk reuses its rates, and rho_init was added; a
 * version-1 checkpoint would continue under other integrators than it started with.
 * 3: the run's identifier (key run), which a restart checks against its output directory's
 * run.id; a version-2 checkpoint has none, so nothing could tell its directory from another's. */
/* 4: the diagnostics are sampled every log_every steps (key log_every), the history holds one row
 * per sample, and log_since is the time since the last one. A version-3 checkpoint sampled every
 * step: it reads as log_every 1 with nothing pending (format3_implied). */
#define CHECKPOINT_FORMAT "consph-solver-4"
#define CHECKPOINT_FORMAT_3 "consph-solver-3"

/* The keys a version-3 checkpoint lacks and the values its run had. */
static const struct {
    const char *key, *value;
} format3_implied[] = {
    {"log_every", "1"}, {"log_since", "0"}, {"skin", "0"}, {"ipst_h_dt", "0"}, {"ipst_chi0", "-1"}};
#define FORMAT3_NIMPLIED (sizeof format3_implied / sizeof format3_implied[0])

/* Keys added to format 4 after its first checkpoints, and the value those checkpoints' runs had:
 * a key missing from a checkpoint reads as this (exact and the wcs_* sums: --exact came later;
 * ipst_h_dt and ipst_chi0: those runs shifted on their own steps with the lattice's χ_o). */
static const struct {
    const char *key, *value;
} format4_added[] = {
    {"exact", "incompressible"}, {"wcs_u_acc", "0"}, {"wcs_p_acc", "0"},  {"wcs_auth_u_acc", "0"},
    {"wcs_auth_p_acc", "0"},     {"ipst_h_dt", "0"}, {"ipst_chi0", "-1"}, {"n", "0"}};
#define FORMAT4_NADDED (sizeof format4_added / sizeof format4_added[0])

int consph_solver_checkpoint_meta(const consph_solver *s, char **meta, double **history,
                                  size_t *nhistory)
{
    const int joined = solver_sample_join((consph_solver *)s);
    if (joined != CONSPH_OK) return joined;
    const consph_run_params *p = &s->prm;
    char *m = malloc(META_MAX);
    double *h = malloc((s->nhist ? s->nhist : 1) * HIST_COLS * sizeof(double));
    if (!m || !h) {
        free(m);
        free(h);
        return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    int len = snprintf(m, META_MAX, "format=" CHECKPOINT_FORMAT "\n");
    if (len > 0) len = run_params_meta_write(p, m, META_MAX, (size_t)len);
    if (len > 0) {
        const int w = snprintf(
            m + len, META_MAX - (size_t)len,
            "t=%a\nstep=%ld\nl1_u_acc=%a\nl1_p_acc=%a\nseconds=%a\npairs=%zu\nregs=%ld\n"
            "passes=%d\nrun=%s\nauth_u_acc=%a\nauth_p_acc=%a\nauth_n=%d\nauth_next=%d\n"
            "log_since=%a\nwcs_u_acc=%a\nwcs_p_acc=%a\nwcs_auth_u_acc=%a\nwcs_auth_p_acc=%a\n",
            s->t, s->step, s->l1_u_acc, s->l1_p_acc, s->seconds, s->pairs, s->regs, s->passes,
            s->run_id, s->auth_u_acc, s->auth_p_acc, s->auth_n, s->auth_next, s->log_since,
            s->wcs_u_acc, s->wcs_p_acc, s->wcs_auth_u_acc, s->wcs_auth_p_acc);
        len = w < 0 ? -1 : len + w;
    }
    if (len < 0 || len >= META_MAX) {
        free(m);
        free(h);
        return consph_fail(CONSPH_EINVAL, "checkpoint metadata too long");
    }
    if (s->nhist) memcpy(h, s->hist, s->nhist * HIST_COLS * sizeof(double));
    *meta = m;
    *history = h;
    *nhistory = s->nhist * HIST_COLS;
    return CONSPH_OK;
}

/* Every key of the metadata, each exactly once (a missing key would read as 0): the format, the
 * parameters of the table (params.def) and the run's own state. Key index k: 0 the format,
 * 1..count the parameters in table order, then state_keys. */
static const char *const state_keys[] = {
    "t",         "step",      "l1_u_acc",  "l1_p_acc",   "seconds",        "pairs",
    "regs",      "passes",    "run",       "auth_u_acc", "auth_p_acc",     "auth_n",
    "auth_next", "log_since", "wcs_u_acc", "wcs_p_acc",  "wcs_auth_u_acc", "wcs_auth_p_acc"};
#define STATE_NKEYS (sizeof state_keys / sizeof state_keys[0])
#define META_NKEYS_MAX 128

static size_t meta_nkeys(void)
{
    return 1 + (size_t)consph_run_param_count() + STATE_NKEYS;
}

static const char *meta_key(size_t k)
{
    const size_t np = (size_t)consph_run_param_count();
    if (k == 0) return "format";
    if (k <= np) return consph_run_param_at((int)k - 1)->name;
    return state_keys[k - 1 - np];
}

static int meta_key_index(const char *k)
{
    for (size_t i = 0; i < meta_nkeys(); ++i)
        if (!strcmp(k, meta_key(i))) return (int)i;
    return -1;
}

static int read_double(const char *v, double *out)
{
    char *end;
    errno = 0;
    *out = strtod(v, &end);
    return end != v && *end == '\0' && errno == 0;
}

/* An integer in [lo, hi]: the range of the type it is stored in, or narrower. */
static int read_long(const char *v, long *out, long lo, long hi)
{
    char *end;
    errno = 0;
    *out = strtol(v, &end, 10);
    return end != v && *end == '\0' && errno == 0 && *out >= lo && *out <= hi;
}

/* 16 lower-case hexadecimal digits, as solver_new_run_id writes them. */
static int read_run_id(const char *v, char *out)
{
    if (strlen(v) != CONSPH_RUN_ID_LEN || strspn(v, "0123456789abcdef") != CONSPH_RUN_ID_LEN)
        return 0;
    strcpy(out, v);
    return 1;
}

/* The value of one known key; 0 when it is not a number of its kind and range. */
static int meta_set(consph_run_params *p, consph_solver *s, const char *k, const char *v)
{
    long l;
    if (!strcmp(k, "format"))
        return !strcmp(v, CHECKPOINT_FORMAT) || !strcmp(v, CHECKPOINT_FORMAT_3);
    const int pk = run_params_meta_read(p, k, v);
    if (pk >= 0) return pk;
#define D(name, dst)                                                                               \
    if (!strcmp(k, name)) return read_double(v, &dst);
#define L(name, dst, type, lo, hi)                                                                 \
    if (!strcmp(k, name)) return read_long(v, &l, lo, hi) ? (dst = (type)l, 1) : 0;
    if (!strcmp(k, "run")) return read_run_id(v, s->run_id);
    L("step", s->step, long, 0, LONG_MAX)
    L("pairs", s->pairs, size_t, 0, LONG_MAX)
    L("regs", s->regs, long, 0, LONG_MAX)
    L("passes", s->passes, int, 0, INT_MAX)
    L("auth_n", s->auth_n, int, 0, INT_MAX)
    L("auth_next", s->auth_next, int, 0, INT_MAX)
    D("t", s->t)
    D("l1_u_acc", s->l1_u_acc)
    D("l1_p_acc", s->l1_p_acc)
    D("auth_u_acc", s->auth_u_acc)
    D("auth_p_acc", s->auth_p_acc)
    D("seconds", s->seconds)
    D("log_since", s->log_since)
    D("wcs_u_acc", s->wcs_u_acc)
    D("wcs_p_acc", s->wcs_p_acc)
    D("wcs_auth_u_acc", s->wcs_auth_u_acc)
    D("wcs_auth_p_acc", s->wcs_auth_p_acc)
#undef D
#undef L
    return 0;
}

/* The metadata lines into s and its parameters: each key known, once, with a value of its kind;
 * the message names the line and the key. */
static int meta_parse(consph_solver *s, const char *meta)
{
    unsigned char seen[META_NKEYS_MAX] = {0};
    int format3 = 0;
    if (meta_nkeys() > META_NKEYS_MAX)
        return consph_fail(CONSPH_EFORMAT, "metadata: more keys than %d", META_NKEYS_MAX);
    const char *line = meta;
    for (int lineno = 1; *line; ++lineno) {
        const char *nl = strchr(line, '\n');
        size_t len = nl ? (size_t)(nl - line) : strlen(line);
        char buf[256];
        if (len >= sizeof buf)
            return consph_fail(CONSPH_EFORMAT, "metadata line %d: longer than %zu bytes", lineno,
                               sizeof buf - 1);
        memcpy(buf, line, len);
        buf[len] = '\0';
        line = nl ? nl + 1 : line + len;
        char *eq = strchr(buf, '=');
        if (!eq)
            return consph_fail(CONSPH_EFORMAT, "metadata line %d: '%.60s' is not key=value", lineno,
                               buf);
        *eq = '\0';
        const char *v = eq + 1;
        if (len && buf[len - 1] == '\r')
            return consph_fail(CONSPH_EFORMAT,
                               "metadata line %d (key '%.40s'): ends in a carriage return (CRLF "
                               "line endings; consph writes LF only)",
                               lineno, buf);
        int k = meta_key_index(buf);
        if (k < 0)
            return consph_fail(CONSPH_EFORMAT, "metadata line %d: unknown key '%.40s'", lineno,
                               buf);
        if (seen[k])
            return consph_fail(CONSPH_EFORMAT, "metadata line %d: key '%s' given twice", lineno,
                               buf);
        seen[k] = 1;
        if (k == 0 && strcmp(v, CHECKPOINT_FORMAT) && strcmp(v, CHECKPOINT_FORMAT_3))
            return consph_fail(CONSPH_EFORMAT,
                               "checkpoint format '%.40s' is not this consph's (%s or %s); start "
                               "the run again",
                               v, CHECKPOINT_FORMAT, CHECKPOINT_FORMAT_3);
        if (k == 0) format3 = !strcmp(v, CHECKPOINT_FORMAT_3);
        for (size_t j = 0; format3 && j < FORMAT3_NIMPLIED; ++j)
            if (!strcmp(buf, format3_implied[j].key))
                return consph_fail(CONSPH_EFORMAT,
                                   "metadata line %d: key '%s' is not one of format %s", lineno,
                                   buf, CHECKPOINT_FORMAT_3);
        if (!meta_set(&s->prm, s, buf, v))
            return consph_fail(CONSPH_EFORMAT, "metadata line %d: key '%s': bad value '%.60s'",
                               lineno, buf, v);
    }
    for (size_t j = 0; format3 && j < FORMAT3_NIMPLIED; ++j) {
        const int k = meta_key_index(format3_implied[j].key);
        if (k < 0 || !meta_set(&s->prm, s, format3_implied[j].key, format3_implied[j].value))
            return consph_fail(CONSPH_EFORMAT, "metadata: key '%s' of format %s",
                               format3_implied[j].key, CHECKPOINT_FORMAT_3);
        seen[k] = 1;
    }
    for (size_t j = 0; j < FORMAT4_NADDED; ++j) {
        const int k = meta_key_index(format4_added[j].key);
        if (k >= 0 && !seen[k]) {
            if (!meta_set(&s->prm, s, format4_added[j].key, format4_added[j].value))
                return consph_fail(CONSPH_EFORMAT, "metadata: key '%s'", format4_added[j].key);
            seen[k] = 1;
        }
    }
    for (size_t k = 0; k < meta_nkeys(); ++k)
        if (!seen[k])
            return consph_fail(CONSPH_EFORMAT, "metadata: key '%s' is missing", meta_key(k));
    return CONSPH_OK;
}

/* The key a message of consph_run_params_check is about (run_param_of_message). */
static const char *param_key(const char *msg)
{
    const consph_run_param *d = run_param_of_message(msg);
    return d ? d->name : "?";
}

/* The run's state against what a run can reach; the parameters were checked already and the
 * solver derived from them (s->prob). */
static int state_check(const consph_solver *s)
{
    const consph_run_params *p = &s->prm;
    /* the end of the run: tf, or steps of dt (summed, hence the rounding slack) */
    const double t_end = p->steps > 0 ? (double)p->steps * s->dt * (1.0 + 1e-9) : p->tf;
    if (!(isfinite(s->t) && s->t >= 0.0 && s->t <= t_end))
        return consph_fail(CONSPH_EFORMAT,
                           "metadata: key 't' = %g is not a time of the run, in [0, %.17g]", s->t,
                           t_end);
    if (p->steps > 0 && s->step > p->steps)
        return consph_fail(CONSPH_EFORMAT, "metadata: key 'step' = %ld is past steps = %ld",
                           s->step, p->steps);
    const double acc[2] = {s->l1_u_acc, s->l1_p_acc};
    for (int k = 0; k < 2; ++k) {
        /* a problem without an exact solution accumulates NaN (n/a) from its first step */
        const int ok = s->prob->has_exact ? isfinite(acc[k]) && acc[k] >= 0.0
                                          : isnan(acc[k]) || (s->step == 0 && acc[k] == 0.0);
        if (!ok)
            return consph_fail(CONSPH_EFORMAT, "metadata: key '%s' = %g is not %s",
                               k ? "l1_p_acc" : "l1_u_acc", acc[k],
                               s->prob->has_exact ? "a finite value >= 0"
                                                  : "nan (the problem has no exact solution)");
    }
    const double auth[2] = {s->auth_u_acc, s->auth_p_acc};
    for (int k = 0; k < 2; ++k)
        if (isinf(auth[k]) || auth[k] < 0.0)
            return consph_fail(CONSPH_EFORMAT, "metadata: key '%s' = %g is not a sum of errors",
                               k ? "auth_p_acc" : "auth_u_acc", auth[k]);
    if (s->auth_n > p->error_times + 1 || s->auth_next > p->error_times + 1)
        return consph_fail(CONSPH_EFORMAT,
                           "metadata: keys 'auth_n' = %d, 'auth_next' = %d: past error_times = %d",
                           s->auth_n, s->auth_next, p->error_times);
    /* a sum of the steps' Δt against t, which a step landing on an output time sets instead of
     * adding its Δt: the rounding slack of t_end above */
    if (!(isfinite(s->log_since) && s->log_since >= 0.0 && s->log_since <= s->t * (1.0 + 1e-9)))
        return consph_fail(CONSPH_EFORMAT,
                           "metadata: key 'log_since' = %g is not a time in [0, t = %.17g]",
                           s->log_since, s->t);
    if (!(isfinite(s->seconds) && s->seconds >= 0.0))
        return consph_fail(CONSPH_EFORMAT, "metadata: key 'seconds' = %g is not a time >= 0",
                           s->seconds);
    return CONSPH_OK;
}

/* The history against the run's state: rows of HIST_COLS whose steps start at 0 and increase up
 * to the current step, every multiple of log_every among them, and the last row this step's
 * exactly when nothing is pending since (log_since 0). */
static int history_check(const consph_solver *s, const double *h, size_t nh)
{
    if (nh == 0 || nh % HIST_COLS != 0)
        return consph_fail(CONSPH_EFORMAT, "history of %zu values is not rows of %d", nh,
                           HIST_COLS);
    const size_t rows = nh / HIST_COLS;
    double prev = -1.0;
    for (size_t r = 0; r < rows; ++r) {
        const double st = h[r * HIST_COLS];
        if (!(st == floor(st) && st > prev && st <= (double)s->step && (r || st == 0.0)))
            return consph_fail(CONSPH_EFORMAT,
                               "history row %zu: step %g is not after %g and at most step = %ld "
                               "(the first row is step 0)",
                               r, st, prev, s->step);
        prev = st;
    }
    size_t sampled = 0; /* the rows of the cadence's steps */
    for (size_t r = 0; r < rows; ++r)
        sampled += fmod(h[r * HIST_COLS], (double)s->prm.log_every) == 0.0;
    if (sampled != (size_t)(s->step / s->prm.log_every) + 1)
        return consph_fail(CONSPH_EFORMAT,
                           "history of %zu rows lacks samples of log_every = %d up to step %ld",
                           rows, s->prm.log_every, s->step);
    if ((prev == (double)s->step) != (s->log_since == 0.0))
        return consph_fail(CONSPH_EFORMAT,
                           "metadata: key 'log_since' = %g does not fit the history, whose last "
                           "row is step %g of %ld",
                           s->log_since, prev, s->step);
    return CONSPH_OK;
}

int consph_solver_restore(consph_solver **out, const char *meta, const consph_particles *particles,
                          const double *history, size_t nhistory)
{
    return solver_restore_range(out, meta, particles, history, nhistory, NULL);
}

int solver_restore_range(consph_solver **out, const char *meta, const consph_particles *particles,
                         const double *history, size_t nhistory, const solver_range *range)
{
    *out = NULL;
    consph_solver *s = consph_calloc(1, sizeof *s);
    if (!s) return CONSPH_ENOMEM;
    consph_run_params *p = &s->prm;
    memset(p, 0, sizeof *p);
    int st = meta_parse(s, meta);
    if (st == CONSPH_OK && consph_run_params_check(p) != CONSPH_OK) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", consph_last_error());
        st = consph_fail(CONSPH_EFORMAT, "metadata: key '%s': %s", param_key(msg), msg);
    }
    if (st == CONSPH_OK) st = derive_solver(s);
    if (st == CONSPH_OK) st = state_check(s);
    if (st == CONSPH_OK) st = history_check(s, history, nhistory);
    const size_t whole = range ? range->n : particles->n;
    if (st == CONSPH_OK &&
        (particles->dim != s->dim ||
         (double)whole != (p->n > 0 ? (double)p->n : pow((double)p->nx, s->dim))))
        st = consph_fail(CONSPH_EFORMAT, "%zu particles in %dD do not match nx = %d, n = %ld",
                         whole, particles->dim, p->nx, p->n);
    consph_kernel k;
    if (st == CONSPH_OK) st = consph_kernel_init(&k, p->kernel, s->dim, s->h);
    if (st == CONSPH_OK) st = consph_sys_init(&s->sys, particles, &k, 0.0);
    if (st == CONSPH_OK) {
        static const char *const need[] = {SF_U, SF_RHOF, SF_P, SF_VOL, SF_ID};
        for (size_t f = 0; f < sizeof need / sizeof need[0] && st == CONSPH_OK; ++f)
            if (!consph_particles_find(s->sys.p, need[f]))
                st = consph_fail(CONSPH_EFORMAT, "the particles lack field '%s'", need[f]);
    }
    /* a checkpoint of an earlier version may lack a field its run had not needed yet (created
     * zero, as that run would have) or carry one no longer declared (dropped) */
    if (st == CONSPH_OK) st = state_create(s);
    if (st == CONSPH_OK) st = state_undeclared(s, 1);
    if (st == CONSPH_OK && !range) st = solver_nlist_start(s, 1);
    if (st == CONSPH_OK && range) {
        s->part = malloc(sizeof *s->part);
        if (!s->part)
            st = consph_fail(CONSPH_ENOMEM, "out of memory");
        else
            *s->part = *range;
    }
    if (st == CONSPH_OK) {
        s->hist = malloc(nhistory * sizeof(double));
        if (!s->hist) st = consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    if (st != CONSPH_OK) {
        consph_solver_free(s);
        return st;
    }
    memcpy(s->hist, history, nhistory * sizeof(double));
    s->nhist = s->caphist = nhistory / HIST_COLS;
    s->step_dt = s->dt; /* the next sample follows a step, which sets it */
    *out = s;
    return CONSPH_OK;
}

int consph_solver_extend(consph_solver *s, double tf, long steps)
{
    const int joined = solver_sample_join(s);
    if (joined != CONSPH_OK) return joined;
    consph_run_params *p = &s->prm;
    if ((tf > 0.0) == (steps > 0))
        return consph_fail(CONSPH_EINVAL, "a new end of the run is tf > 0 or steps > 0: give one");
    if (steps > 0 ? steps == p->steps : p->steps == 0 && tf == p->tf) return CONSPH_OK;
    if (steps > 0 && steps <= s->step)
        return consph_fail(CONSPH_EINVAL,
                           "steps = %ld is not after the checkpoint's step %ld (t = %.17g): give "
                           "more steps",
                           steps, s->step, s->t);
    if (tf > 0.0 && !(tf > s->t))
        return consph_fail(CONSPH_EINVAL,
                           "tf = %.17g is not after the checkpoint's t = %.17g (step %ld): give a "
                           "later tf",
                           tf, s->t, s->step);
    /* 001's authors' measure averages over output times spread over [0, t_f] (or the steps'
     * ends): another end moves every one of them, the samples already taken included */
    if (p->error == CONSPH_ERROR_AUTHORS)
        return consph_fail(CONSPH_EINVAL,
                           "error = authors: its %d output times divide the run's own end (%s), "
                           "so a run with another end samples other times from t = 0 on; run it "
                           "again with the new end",
                           p->error_times, p->steps > 0 ? "steps" : "tf");
    /* A --tf run's last step is shortened to land on t_f: a run to a later end would have taken
     * a full step there (consph_solver_step). Only a finished run has taken it: its history's
     * last row is that step, with its Δt. */
    const double *last = s->nhist ? s->hist + (s->nhist - 1) * HIST_COLS : NULL;
    if (p->steps == 0 && s->t >= p->tf && last && (long)last[0] == s->step &&
        last[HIST_COLS - 1] != s->dt)
        return consph_fail(CONSPH_EINVAL,
                           "the checkpoint is the end of a run whose last step was shortened to "
                           "land on tf = %.17g (Δt %.17g, not %.17g): a run to another end "
                           "would not have taken that step; restart from an earlier checkpoint",
                           p->tf, last[HIST_COLS - 1], s->dt);
    consph_run_params q = *p;
    q.tf = steps > 0 ? 0.0 : tf;
    q.steps = steps > 0 ? steps : 0;
    int st = consph_run_params_check(&q);
    if (st != CONSPH_OK) return st;
    *p = q;
    s->tf = q.tf;
    s->nsteps = q.steps;
    return CONSPH_OK;
}
