/* What a checkpoint holds of a solver besides its particles: the parameters and the scalars of
 * the run as "key=value" lines, doubles in C99 hexadecimal (%a) so they read back bit for bit,
 * and the per-step history. Parsing is strict: every key known, every value checked. */
#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "schemes/solver_internal.h"

#define META_MAX 4096
/* 2: wcsph/edac default to pec and tvf's kdk reuses its rates, and rho_init was added; a
 * version-1 checkpoint would continue under other integrators than it started with. */
#define CHECKPOINT_FORMAT "consph-solver-2"

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
        "regs=%ld\npasses=%d\nrho_init=%d\nerror=%d\nerror_times=%d\nauth_u_acc=%a\n"
        "auth_p_acc=%a\nauth_n=%d\nauth_next=%d\n",
        p->problem, p->scheme, p->integrator, p->nx, p->layout, p->seed, p->hdx, (int)p->kernel,
        p->U, p->c0, p->re, p->nu, p->alpha, p->rho0, p->gamma, (int)p->eos, p->delta, p->tf,
        p->steps, p->dt, p->cfl, p->h_dt, p->ipst_every, p->ipst_max_iter, p->ipst_tol, s->t,
        s->step, s->l1_u_acc, s->l1_p_acc, s->seconds, s->pairs, s->regs, s->passes, p->rho_init,
        p->error, p->error_times, s->auth_u_acc, s->auth_p_acc, s->auth_n, s->auth_next);
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

typedef struct meta_reader {
    consph_run_params *p;
    consph_solver *s;
} meta_reader;

static int read_double(const char *v, double *out)
{
    char *end;
    errno = 0;
    *out = strtod(v, &end);
    return end != v && *end == '\0' && errno == 0;
}

static int read_long(const char *v, long *out)
{
    char *end;
    errno = 0;
    *out = strtol(v, &end, 10);
    return end != v && *end == '\0' && errno == 0;
}

static int read_string(const char *v, char *out, size_t size)
{
    if (strlen(v) >= size) return 0;
    strcpy(out, v);
    return 1;
}

/* One key=value line; 0 for an unknown key or a bad value. */
static int meta_set(consph_run_params *p, consph_solver *s, const char *k, const char *v)
{
    long l;
    double d;
#define D(name, dst)                                                                               \
    if (!strcmp(k, name)) return read_double(v, &dst);
#define L(name, dst, type)                                                                         \
    if (!strcmp(k, name)) return read_long(v, &l) ? (dst = (type)l, 1) : 0;
    if (!strcmp(k, "format")) return !strcmp(v, CHECKPOINT_FORMAT);
    if (!strcmp(k, "problem")) return read_string(v, p->problem, sizeof p->problem);
    if (!strcmp(k, "scheme")) return read_string(v, p->scheme, sizeof p->scheme);
    if (!strcmp(k, "integrator")) return read_string(v, p->integrator, sizeof p->integrator);
    L("nx", p->nx, int)
    L("layout", p->layout, int)
    L("seed", p->seed, unsigned long)
    L("kernel", p->kernel, consph_kernel_id)
    L("eos", p->eos, consph_eos_kind)
    L("steps", p->steps, long)
    L("ipst_every", p->ipst_every, int)
    L("ipst_max_iter", p->ipst_max_iter, int)
    L("step", s->step, long)
    L("pairs", s->pairs, size_t)
    L("regs", s->regs, long)
    L("passes", s->passes, int)
    L("rho_init", p->rho_init, int)
    L("error", p->error, int)
    L("error_times", p->error_times, int)
    L("auth_n", s->auth_n, int)
    L("auth_next", s->auth_next, int)
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
    (void)d;
    return 0;
}

int consph_solver_restore(consph_solver **out, const char *meta, const consph_particles *particles,
                          const double *history, size_t nhistory)
{
    *out = NULL;
    consph_solver *s = consph_calloc(1, sizeof *s);
    if (!s) return CONSPH_ENOMEM;
    consph_run_params *p = &s->prm;
    memset(p, 0, sizeof *p);
    int st = CONSPH_OK, nkeys = 0;
    const char *line = meta;
    while (st == CONSPH_OK && *line) {
        const char *nl = strchr(line, '\n');
        size_t len = nl ? (size_t)(nl - line) : strlen(line);
        char buf[256];
        if (len >= sizeof buf) {
            st = consph_fail(CONSPH_EFORMAT, "checkpoint metadata: line too long");
            break;
        }
        memcpy(buf, line, len);
        buf[len] = '\0';
        char *eq = strchr(buf, '=');
        if (eq && !strncmp(buf, "format=", 7) && strcmp(eq + 1, CHECKPOINT_FORMAT)) {
            st = consph_fail(CONSPH_EFORMAT,
                             "checkpoint format '%.40s' is not this consph's (%s); start the run "
                             "again",
                             eq + 1, CHECKPOINT_FORMAT);
            break;
        }
        if (!eq || (*eq = '\0', !meta_set(p, s, buf, eq + 1)))
            st = consph_fail(CONSPH_EFORMAT, "checkpoint metadata: bad line '%.60s'", buf);
        ++nkeys;
        line = nl ? nl + 1 : line + len;
    }
    if (st == CONSPH_OK && nkeys != 41)
        st = consph_fail(CONSPH_EFORMAT, "checkpoint metadata: %d keys, expected 41", nkeys);
    if (st == CONSPH_OK) st = consph_run_params_check(p);
    if (st == CONSPH_OK) st = derive_solver(s);
    if (st == CONSPH_OK &&
        (nhistory == 0 || nhistory % HIST_COLS != 0 || nhistory / HIST_COLS != (size_t)s->step + 1))
        st = consph_fail(CONSPH_EFORMAT,
                         "checkpoint: history of %zu values does not hold %ld "
                         "steps",
                         nhistory, s->step + 1);
    if (st == CONSPH_OK && (particles->dim != 2 || particles->n != (size_t)p->nx * (size_t)p->nx))
        st = consph_fail(CONSPH_EFORMAT, "checkpoint: %zu particles in %dD do not match nx = %d",
                         particles->n, particles->dim, p->nx);
    consph_kernel k;
    if (st == CONSPH_OK) st = consph_kernel_init(&k, p->kernel, s->dim, s->h);
    if (st == CONSPH_OK) st = consph_sys_init(&s->sys, particles, &k, 0.0);
    if (st == CONSPH_OK) {
        static const char *const need[] = {SF_U, SF_RHOF, SF_P, SF_VOL, SF_ID};
        for (size_t f = 0; f < sizeof need / sizeof need[0] && st == CONSPH_OK; ++f)
            if (!consph_particles_find(s->sys.p, need[f]))
                st = consph_fail(CONSPH_EFORMAT, "checkpoint: the particles lack field '%s'",
                                 need[f]);
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
    *out = s;
    return CONSPH_OK;
}
