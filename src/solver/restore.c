/* What a checkpoint holds of a solver besides its particles: the parameters and the scalars of
 * the run as "key=value" lines, doubles in C99 hexadecimal (%a) so they read back bit for bit,
 * and the per-step history. Parsing is strict: every key known, every value checked. */
#include <ctype.h>
#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "solver/solver_internal.h"

#define META_MAX 4096
/* 2: wcsph/edac default to pec and tvf's kdk reuses its rates, and rho_init was added; a
 * version-1 checkpoint would continue under other integrators than it started with.
 * 3: the run's identifier (key run), which a restart checks against its output directory's
 * run.id; a version-2 checkpoint has none, so nothing could tell its directory from another's. */
#define CHECKPOINT_FORMAT "consph-solver-3"

int consph_solver_checkpoint_meta(const consph_solver *s, char **meta, double **history,
                                  size_t *nhistory)
{
    const consph_run_params *p = &s->prm;
    char *m = malloc(META_MAX);
    double *h = malloc((s->nhist ? s->nhist : 1) * HIST_COLS * sizeof(double));
    if (!m || !h) {
        free(m);
        free(h);
        return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    int len = snprintf(
        m, META_MAX,
        "format=" CHECKPOINT_FORMAT "\nproblem=%s\nscheme=%s\nintegrator=%s\nnx=%d\nlayout=%d\n"
        "seed=%lu\nhdx=%a\nkernel=%d\nU=%a\nc0=%a\nre=%a\nnu=%a\nalpha=%a\nrho0=%a\ngamma=%a\neos=%"
        "d\n"
        "delta=%a\ntf=%a\nsteps=%ld\ndt=%a\ncfl=%a\nh_dt=%a\nipst_every=%d\nipst_max_iter=%d\n"
        "ipst_tol=%a\nt=%a\nstep=%ld\nl1_u_acc=%a\nl1_p_acc=%a\nseconds=%a\npairs=%zu\n"
        "regs=%ld\npasses=%d\nrho_init=%d\nrun=%s\nerror=%d\nerror_times=%d\n"
        "auth_u_acc=%a\nauth_p_acc=%a\nauth_n=%d\nauth_next=%d\n",
        p->problem, p->scheme, p->integrator, p->nx, p->layout, p->seed, p->hdx, (int)p->kernel,
        p->U, p->c0, p->re, p->nu, p->alpha, p->rho0, p->gamma, (int)p->eos, p->delta, p->tf,
        p->steps, p->dt, p->cfl, p->h_dt, p->ipst_every, p->ipst_max_iter, p->ipst_tol, s->t,
        s->step, s->l1_u_acc, s->l1_p_acc, s->seconds, s->pairs, s->regs, s->passes, p->rho_init,
        s->run_id, p->error, p->error_times, s->auth_u_acc, s->auth_p_acc, s->auth_n, s->auth_next);
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

/* Every key of the metadata, each exactly once (a missing key would read as 0). */
static const char *const meta_keys[] = {
    "format",   "problem",  "scheme",      "integrator", "nx",
    "layout",   "seed",     "hdx",         "kernel",     "U",
    "c0",       "re",       "nu",          "alpha",      "rho0",
    "gamma",    "eos",      "delta",       "tf",         "steps",
    "dt",       "cfl",      "h_dt",        "ipst_every", "ipst_max_iter",
    "ipst_tol", "t",        "step",        "l1_u_acc",   "l1_p_acc",
    "seconds",  "pairs",    "regs",        "passes",     "rho_init",
    "run",      "error",    "error_times", "auth_u_acc", "auth_p_acc",
    "auth_n",   "auth_next"};
#define META_NKEYS (sizeof meta_keys / sizeof meta_keys[0])

static int meta_key_index(const char *k)
{
    for (size_t i = 0; i < META_NKEYS; ++i)
        if (!strcmp(k, meta_keys[i])) return (int)i;
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

static int read_string(const char *v, char *out, size_t size)
{
    if (strlen(v) >= size) return 0;
    strcpy(out, v);
    return 1;
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
#define D(name, dst)                                                                               \
    if (!strcmp(k, name)) return read_double(v, &dst);
#define L(name, dst, type, lo, hi)                                                                 \
    if (!strcmp(k, name)) return read_long(v, &l, lo, hi) ? (dst = (type)l, 1) : 0;
    if (!strcmp(k, "format")) return !strcmp(v, CHECKPOINT_FORMAT);
    if (!strcmp(k, "problem")) return read_string(v, p->problem, sizeof p->problem);
    if (!strcmp(k, "scheme")) return read_string(v, p->scheme, sizeof p->scheme);
    if (!strcmp(k, "integrator")) return read_string(v, p->integrator, sizeof p->integrator);
    if (!strcmp(k, "run")) return read_run_id(v, s->run_id);
    L("nx", p->nx, int, INT_MIN, INT_MAX)
    L("layout", p->layout, int, INT_MIN, INT_MAX)
    L("seed", p->seed, unsigned long, 0, LONG_MAX)
    L("kernel", p->kernel, consph_kernel_id, INT_MIN, INT_MAX)
    L("eos", p->eos, consph_eos_kind, INT_MIN, INT_MAX)
    L("steps", p->steps, long, LONG_MIN, LONG_MAX)
    L("ipst_every", p->ipst_every, int, INT_MIN, INT_MAX)
    L("ipst_max_iter", p->ipst_max_iter, int, INT_MIN, INT_MAX)
    L("step", s->step, long, 0, LONG_MAX)
    L("pairs", s->pairs, size_t, 0, LONG_MAX)
    L("regs", s->regs, long, 0, LONG_MAX)
    L("passes", s->passes, int, 0, INT_MAX)
    L("rho_init", p->rho_init, int, INT_MIN, INT_MAX)
    L("error", p->error, int, INT_MIN, INT_MAX)
    L("error_times", p->error_times, int, INT_MIN, INT_MAX)
    L("auth_n", s->auth_n, int, 0, INT_MAX)
    L("auth_next", s->auth_next, int, 0, INT_MAX)
    D("hdx", p->hdx)
    D("U", p->U)
    D("c0", p->c0)
    D("re", p->re)
    D("nu", p->nu)
    D("alpha", p->alpha)
    D("rho0", p->rho0)
    D("gamma", p->gamma)
    D("delta", p->delta)
    D("tf", p->tf)
    D("dt", p->dt)
    D("cfl", p->cfl)
    D("h_dt", p->h_dt)
    D("ipst_tol", p->ipst_tol)
    D("t", s->t)
    D("l1_u_acc", s->l1_u_acc)
    D("l1_p_acc", s->l1_p_acc)
    D("auth_u_acc", s->auth_u_acc)
    D("auth_p_acc", s->auth_p_acc)
    D("seconds", s->seconds)
#undef D
#undef L
    return 0;
}

/* The metadata lines into s and its parameters: each key known, once, with a value of its kind;
 * the message names the line and the key. */
static int meta_parse(consph_solver *s, const char *meta)
{
    unsigned char seen[META_NKEYS] = {0};
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
        if (k == 0 && strcmp(v, CHECKPOINT_FORMAT))
            return consph_fail(CONSPH_EFORMAT,
                               "checkpoint format '%.40s' is not this consph's (%s); start the "
                               "run again",
                               v, CHECKPOINT_FORMAT);
        if (!meta_set(&s->prm, s, buf, v))
            return consph_fail(CONSPH_EFORMAT, "metadata line %d: key '%s': bad value '%.60s'",
                               lineno, buf, v);
    }
    for (size_t k = 0; k < META_NKEYS; ++k)
        if (!seen[k])
            return consph_fail(CONSPH_EFORMAT, "metadata: key '%s' is missing", meta_keys[k]);
    return CONSPH_OK;
}

/* The key a message of consph_run_params_check is about: it begins with the option ("--h-dt
 * must ...", key h_dt) or the parameter's own name ("rho0 must ...", "problem '...'"). */
static const char *param_key(const char *msg)
{
    for (size_t k = 0; k < META_NKEYS; ++k) {
        char opt[40] = "--";
        size_t n = 2;
        for (const char *c = meta_keys[k]; *c && n + 1 < sizeof opt; ++c)
            opt[n++] = *c == '_' ? '-' : (char)tolower((unsigned char)*c);
        opt[n] = '\0';
        const size_t klen = strlen(meta_keys[k]);
        if ((!strncmp(msg, opt, n) && (msg[n] == ' ' || msg[n] == '\'')) ||
            (!strncmp(msg, meta_keys[k], klen) && msg[klen] == ' '))
            return meta_keys[k];
    }
    return "?";
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
    if (!(isfinite(s->seconds) && s->seconds >= 0.0))
        return consph_fail(CONSPH_EFORMAT, "metadata: key 'seconds' = %g is not a time >= 0",
                           s->seconds);
    return CONSPH_OK;
}

int consph_solver_restore(consph_solver **out, const char *meta, const consph_particles *particles,
                          const double *history, size_t nhistory)
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
    if (st == CONSPH_OK &&
        (nhistory == 0 || nhistory % HIST_COLS != 0 || nhistory / HIST_COLS != (size_t)s->step + 1))
        st = consph_fail(CONSPH_EFORMAT,
                         "history of %zu values does not hold %ld "
                         "steps",
                         nhistory, s->step + 1);
    if (st == CONSPH_OK && (particles->dim != 2 || particles->n != (size_t)p->nx * (size_t)p->nx))
        st = consph_fail(CONSPH_EFORMAT, "%zu particles in %dD do not match nx = %d", particles->n,
                         particles->dim, p->nx);
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
    *out = s;
    return CONSPH_OK;
}
