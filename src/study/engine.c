/* Runs the figures of a study file and writes their CSV, markdown and gnuplot outputs. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "consph/io.h"
#include "consph/transport.h"
#include "io/outfile_internal.h"
#include "study/study_internal.h"

/* Timings behind T_r (the operator at a series' finest resolution) and their median. */
#define TR_TIMINGS 5

typedef enum fig_kind {
    KIND_APPROX,
    KIND_M0,
    KIND_APPC,
    KIND_CAUCHY,
    KIND_RUN,
    KIND_HEAT
} fig_kind;

/* Everything needed to run one series, parsed from its keys. */
typedef struct series_plan {
    consph_approx_spec spec;
    const char *kernel_name;
    int sweep_hdx; /* 0: sweep nx, 1: sweep hdx at fixed nx */
    int nvalues;
    double values[MAX_SWEEP];
    size_t nx_fixed;
    int bound; /* 0 none, 1 interp, 2 delta */
} series_plan;

typedef struct series_result {
    consph_approx_row rows[MAX_SWEEP];
    double bound[MAX_SWEEP];
    double nx[MAX_SWEEP]; /* the resolution fitted: nx, or N^(1/dim) for particle files */
    int nrows;
} series_result;

/* Particle files that replace the generated layouts (consph study --particles). */
typedef struct study_files {
    const consph_particles *sets;
    const char *const *names;
    int n;
} study_files;

/* N^(1/dim), exact when N is a perfect power, so that a file made by `consph layout --nx K`
 * reports nx = K. */
static double resolution_of(const consph_particles *p)
{
    double r = pow((double)p->n, 1.0 / p->dim), k = floor(r + 0.5), kd = 1.0;
    for (int a = 0; a < p->dim; ++a) kd *= k;
    return kd == (double)p->n ? k : r;
}

/* ---- small helpers ---- */

int study_key_error(const consph_study *s, const study_figure *f, const study_series *r,
                    const char *key, const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* A key that is not set (a required one) is reported where it is missing. */
    int line = study_line(s, f, r, key);
    if (!line) line = r ? r->line : f->line;
    return consph_fail(CONSPH_EFORMAT, "%s:%d: figure '%s', series '%s': key '%s': %s", s->path,
                       line, f->id, r ? r->label : "-", key, msg);
}

int study_get_double(const consph_study *s, const study_figure *f, const study_series *r,
                     const char *key, double def, double lo, double hi, double *out)
{
    const char *v = study_get(s, f, r, key);
    if (!v) {
        *out = def;
        return CONSPH_OK;
    }
    char *end;
    errno = 0;
    double d = strtod(v, &end);
    if (end == v || *end || errno || !isfinite(d) || d < lo || d > hi)
        return study_key_error(s, f, r, key, "'%s' is not a number in [%g, %g]", v, lo, hi);
    *out = d;
    return CONSPH_OK;
}

int study_get_list(const consph_study *s, const study_figure *f, const study_series *r,
                   const char *key, double lo, double hi, double *vals, int *n)
{
    const char *v = study_get(s, f, r, key);
    *n = 0;
    if (!v) return CONSPH_OK;
    /* Every element, empty ones included: `8,,16` is refused as the CLI refuses `10,,20`. */
    for (const char *t = v;; ++t) {
        char *end;
        double d = strtod(t, &end);
        while (*end == ' ' || *end == '\t') ++end;
        if (end == t || (*end && *end != ',') || !isfinite(d) || d < lo || d > hi)
            return study_key_error(s, f, r, key, "'%s' is not a list of numbers in [%g, %g]", v, lo,
                                   hi);
        if (*n == MAX_SWEEP) return study_key_error(s, f, r, key, "more than %d values", MAX_SWEEP);
        vals[(*n)++] = d;
        if (!*end) break;
        t = end;
    }
    return CONSPH_OK;
}

int study_get_choice(const consph_study *s, const study_figure *f, const study_series *r,
                     const char *key, const char *const *choices, int def, int *out)
{
    const char *v = study_get(s, f, r, key);
    if (!v) {
        *out = def;
        return CONSPH_OK;
    }
    char allowed[256] = "";
    for (int k = 0; choices[k]; ++k) {
        if (strcmp(v, choices[k]) == 0) {
            *out = k;
            return CONSPH_OK;
        }
        snprintf(allowed + strlen(allowed), sizeof allowed - strlen(allowed), "%s%s", k ? ", " : "",
                 choices[k]);
    }
    return study_key_error(s, f, r, key, "unknown value '%s'; allowed: %s", v, allowed);
}

static fig_kind figure_kind(const consph_study *s, const study_figure *f)
{
    const char *k = study_get(s, f, NULL, "kind");
    if (k && strcmp(k, "m0") == 0) return KIND_M0;
    if (k && strcmp(k, "appc") == 0) return KIND_APPC;
    if (k && strcmp(k, "cauchy") == 0) return KIND_CAUCHY;
    if (k && strcmp(k, "run") == 0) return KIND_RUN;
    if (k && strcmp(k, "heat") == 0) return KIND_HEAT;
    return KIND_APPROX;
}

/* How h was chosen, for the reports. */
static const char *h_policy_text(const consph_approx_spec *sp, char *buf, size_t size)
{
    const int d = sp->layout.dim;
    switch (sp->h_policy) {
    case CONSPH_H_SCALING:
        return "= N^(-1/6)";
    case CONSPH_H_ZHU:
        snprintf(buf, size, "= hdx·Δs at N = %.0f, then ∝ N^(-1/%d) (zhu: neighbours ∝ N^(1/2))",
                 sp->n_ref, 2 * d);
        return buf;
    case CONSPH_H_BETA:
        snprintf(buf, size,
                 "= hdx·Δs at N = %.0f, then ∝ N^(-1/%g) (004: N ∝ h^(-β), neighbours ∝ "
                 "N^%.3g)",
                 sp->n_ref, sp->beta, 1.0 - d / sp->beta);
        return buf;
    default:
        return "= hdx·Δs";
    }
}

static int build_plan(const consph_study *s, const study_figure *f, const study_series *r,
                      int quick, series_plan *pl)
{
    static const char *const kinds[] = {"approx", "m0", "appc", "cauchy", "heat", NULL};
    static const char *const ops[] = {"function", "grad", "div", "laplacian", "hessian", NULL};
    static const char *const default_form[] = {"standard", "f4", "div", "coupled", "korzilius"};
    static const char *const policies[] = {"hdx", "scaling", "zhu", "beta", NULL};
    static const char *const layouts[] = {"lattice", "random",          "quasi-random",
                                          "packed",  "packed-polished", NULL};
    static const char *const yesno[] = {"yes", "no", NULL};
    static const char *const masks[] = {"interior", "all", NULL};
    static const char *const sweeps[] = {"nx", "hdx", NULL};
    static const char *const bounds[] = {"none", "interp", "delta", NULL};
    static const char *const norms[] = {"l1", "l2", "linf", "mae", NULL};
    static const char *const xs[] = {"nx", "nbr", "sqrtN", NULL};
    const char *volumes[CONSPH_VOLUME_COUNT + 1];
    for (int v = 0; v < CONSPH_VOLUME_COUNT; ++v)
        volumes[v] = consph_volume_name((consph_volume_kind)v);
    volumes[CONSPH_VOLUME_COUNT] = NULL;

    memset(pl, 0, sizeof *pl);
    int rc, ikind, iop, ipol, ilay, iper, imask, isweep, ibound, ivol, dummy;
    double dim, hdx, match, eps, seed, sigma, tol, iters, beta;
    if ((rc = study_get_choice(s, f, r, "kind", kinds, 0, &ikind))) return rc;
    if ((rc = study_get_choice(s, f, r, "op", ops, 0, &iop))) return rc;
    if ((rc = study_get_choice(s, f, r, "h_policy", policies, 0, &ipol))) return rc;
    if ((rc = study_get_choice(s, f, r, "layout", layouts, 0, &ilay))) return rc;
    if ((rc = study_get_choice(s, f, r, "periodic", yesno, 0, &iper))) return rc;
    if ((rc = study_get_choice(s, f, r, "mask", masks, 0, &imask))) return rc;
    if ((rc = study_get_choice(s, f, r, "sweep", sweeps, 0, &isweep))) return rc;
    if ((rc = study_get_choice(s, f, r, "bound", bounds, 0, &ibound))) return rc;
    if ((rc = study_get_choice(s, f, r, "norm", norms, 0, &dummy))) return rc;
    if ((rc = study_get_choice(s, f, r, "x", xs, 0, &dummy))) return rc;
    if ((rc = study_get_choice(s, f, r, "volume", volumes, ikind == KIND_M0 ? 2 : 1, &ivol)))
        return rc;
    if ((rc = study_get_double(s, f, r, "dim", ikind == KIND_APPC ? 1 : 2, 1, 3, &dim))) return rc;
    if (dim != floor(dim)) return study_key_error(s, f, r, "dim", "must be 1, 2 or 3");
    if ((rc = study_get_double(s, f, r, "hdx", 1.2, 0.01, 100, &hdx))) return rc;
    if ((rc = study_get_double(s, f, r, "match_support", 0, 0, 100, &match))) return rc;
    if ((rc = study_get_double(s, f, r, "beta", 0, 0, 1e3, &beta))) return rc;
    if (ipol == CONSPH_H_BETA && !(beta > dim))
        return study_key_error(s, f, r, "beta",
                               "h_policy = beta needs beta > dim = %g (004: β > n)", dim);
    if ((ilay == CONSPH_LAYOUT_PACKED || ilay == CONSPH_LAYOUT_PACKED_POLISHED) && iper != 0 &&
        ikind != KIND_APPC)
        return study_key_error(s, f, r, "periodic", "layout %s needs a periodic box; allowed: yes",
                               layouts[ilay]);
    if ((rc = study_get_double(s, f, r, "eps", 0.2, 0, 2, &eps))) return rc;
    if ((rc = study_get_double(s, f, r, "seed", 1, 0, 1e15, &seed))) return rc;
    if ((rc = study_get_double(s, f, r, "sigma", 0.1, 1e-9, 10, &sigma))) return rc;
    if ((rc = study_get_double(s, f, r, "pack_tol", 1e-4, 1e-12, 1, &tol))) return rc;
    const int iters_def = consph_layout_defaults((consph_layout_kind)ilay, 2, 10).packing.max_iter;
    if ((rc = study_get_double(s, f, r, "pack_iter", iters_def, 1, 1e7, &iters))) return rc;

    consph_approx_spec *sp = &pl->spec;
    *sp = consph_approx_defaults((int)dim);
    const char *form = study_get(s, f, r, "form");
    const char *corr = study_get(s, f, r, "corr");
    if (consph_op_parse(ops[iop], form ? form : default_form[iop], corr ? corr : "none", (int)dim,
                        &sp->op) != CONSPH_OK)
        return study_key_error(s, f, r, "form", "%s", consph_last_error());
    pl->kernel_name = study_get(s, f, r, "kernel");
    if (!pl->kernel_name) pl->kernel_name = "quintic";
    if (ikind != KIND_APPC && consph_kernel_lookup(pl->kernel_name, &sp->kernel) != CONSPH_OK)
        return study_key_error(s, f, r, "kernel", "%s", consph_last_error());
    if (match > 0) hdx *= match / consph_kernel_info_get(sp->kernel)->support;
    sp->hdx = hdx;
    sp->h_policy = (consph_h_policy)ipol;
    sp->beta = beta;
    sp->layout = consph_layout_defaults((consph_layout_kind)ilay, (int)dim, 10);
    sp->layout.eps = eps;
    sp->layout.seed = (uint64_t)seed;
    sp->layout.packing.tol = tol;
    sp->layout.packing.max_iter = (int)iters;
    sp->layout.box = consph_box_unit((int)dim, iper == 0);
    const char *field = study_get(s, f, r, "field");
    if (!field) field = iop == 2 ? "tgv" : "sin2pi";
    if (consph_mfield_lookup(field, &sp->field) != CONSPH_OK)
        return study_key_error(s, f, r, "field", "%s", consph_last_error());
    sp->field_params.sigma = sigma;
    sp->volume = (consph_volume_kind)ivol;
    sp->interior_only = imask == 0;
    pl->bound = ibound;
    if (ikind == KIND_APPROX && consph_approx_check(sp) != CONSPH_OK)
        return study_key_error(s, f, r, "op", "%s", consph_last_error());

    double nxs[MAX_SWEEP];
    int nnx = 0;
    if (quick) {
        if ((rc = study_get_list(s, f, r, "quick.nx", 2, 1e5, nxs, &nnx))) return rc;
    }
    if (nnx == 0 && (rc = study_get_list(s, f, r, "nx", 2, 1e5, nxs, &nnx))) return rc;
    if (nnx == 0) return study_key_error(s, f, r, "nx", "no resolutions given");
    pl->sweep_hdx = isweep == 1 || ikind == KIND_APPC;
    if (pl->sweep_hdx) {
        const char *key = ikind == KIND_APPC ? "hdelta.values" : "hdx.values";
        char qkey[64];
        snprintf(qkey, sizeof qkey, "quick.%s", key);
        if (quick && (rc = study_get_list(s, f, r, qkey, 1e-3, 100, pl->values, &pl->nvalues)))
            return rc;
        if (pl->nvalues == 0 &&
            (rc = study_get_list(s, f, r, key, 1e-3, 100, pl->values, &pl->nvalues)))
            return rc;
        if (pl->nvalues == 0) return study_key_error(s, f, r, key, "no values given");
        pl->nx_fixed = (size_t)nxs[0];
    } else {
        memcpy(pl->values, nxs, sizeof(double) * (size_t)nnx);
        pl->nvalues = nnx;
    }
    /* zhu and beta agree with hdx at the first resolution. */
    sp->n_ref = pow(pl->sweep_hdx ? (double)pl->nx_fixed : pl->values[0], dim);
    return CONSPH_OK;
}

/* ---- layout cache: packed layouts are expensive and shared between series ---- */

typedef struct cached_layout {
    consph_layout_params lp;
    consph_particles p;
    double seconds;
    int used;
} cached_layout;

#define CACHE_SIZE 16
typedef struct layout_cache {
    cached_layout e[CACHE_SIZE];
    int next;
} layout_cache;

static int same_layout(const consph_layout_params *a, const consph_layout_params *b)
{
    if (a->kind != b->kind || a->dim != b->dim || a->seed != b->seed) return 0;
    for (int d = 0; d < a->dim; ++d)
        if (a->nx[d] != b->nx[d] || a->box.periodic[d] != b->box.periodic[d]) return 0;
    if (a->kind == CONSPH_LAYOUT_RANDOM && a->eps != b->eps) return 0;
    if ((a->kind == CONSPH_LAYOUT_PACKED || a->kind == CONSPH_LAYOUT_PACKED_POLISHED) &&
        (a->packing.tol != b->packing.tol || a->packing.max_iter != b->packing.max_iter ||
         a->packing.move_tol != b->packing.move_tol || a->packing.hdx != b->packing.hdx ||
         strcmp(a->packing.kernel, b->packing.kernel)))
        return 0;
    return 1;
}

static int cache_get(layout_cache *c, const consph_layout_params *lp, const consph_particles **p,
                     double *seconds, FILE *log)
{
    for (int k = 0; k < CACHE_SIZE; ++k)
        if (c->e[k].used && same_layout(&c->e[k].lp, lp)) {
            *p = &c->e[k].p;
            *seconds = 0.0;
            return CONSPH_OK;
        }
    cached_layout *e = &c->e[c->next];
    c->next = (c->next + 1) % CACHE_SIZE;
    if (e->used) consph_particles_free(&e->p);
    e->used = 0;
    double t0 = consph_wtime();
    consph_packing_report pack;
    memset(&pack, 0, sizeof pack);
    int rc = consph_layout_generate(lp, &e->p, &pack);
    if (rc == CONSPH_OK && lp->kind == CONSPH_LAYOUT_PACKED_POLISHED && log &&
        pack.rho_spread_final > lp->packing.tol)
        fprintf(log,
                "  warning: packing %zu^%d stopped at pack_iter %d with max|rho/rho0-1| = %.3g "
                "above pack_tol %g\n",
                lp->nx[0], lp->dim, lp->packing.max_iter, pack.rho_spread_final, lp->packing.tol);
    if (rc == CONSPH_OK && lp->kind == CONSPH_LAYOUT_PACKED && log && !pack.converged)
        fprintf(log,
                "  warning: packing %zu^%d stopped at pack_iter %d before the particles stopped "
                "moving (100 max|u| dt/h = %.3g above %g)\n",
                lp->nx[0], lp->dim, lp->packing.max_iter, pack.move_final, lp->packing.move_tol);
    consph_packing_report_free(&pack);
    if (rc) return rc;
    e->lp = *lp;
    e->used = 1;
    e->seconds = consph_wtime() - t0;
    *p = &e->p;
    *seconds = e->seconds;
    return CONSPH_OK;
}

static void cache_free(layout_cache *c)
{
    for (int k = 0; k < CACHE_SIZE; ++k)
        if (c->e[k].used) consph_particles_free(&c->e[k].p);
}

/* ---- output helpers ---- */

static int has_key(const study_kvlist *l, const char *key)
{
    for (int k = 0; k < l->n; ++k)
        if (strcmp(l->items[k].key, key) == 0) return 1;
    return 0;
}

/* A figure's own note: the study's note is printed once, in the study README. */
const char *study_figure_note(const study_figure *f)
{
    for (int k = 0; k < f->keys.n; ++k)
        if (strcmp(f->keys.items[k].key, "note") == 0) return f->keys.items[k].value;
    return NULL;
}

void study_report_head(FILE *o, const consph_study *s, const study_figure *f)
{
    study_report_head_as(o, s, f, study_get_or(s, f, NULL, "title", f->id));
}

/* The figure's title; with --particles the layout it names (e.g. "unperturbed lattice (UP)")
 * is not what ran, and it says so. */
static const char *files_title(const consph_study *s, const study_figure *f, int files, char *buf,
                               size_t size)
{
    const char *title = study_get_or(s, f, NULL, "title", f->id);
    if (!files) return title;
    int len = snprintf(buf, size,
                       "%s [this run: particles from files (--particles), not the layout the "
                       "title names]",
                       title);
    return len > 0 && (size_t)len < size ? buf : title;
}

void study_report_head_as(FILE *o, const consph_study *s, const study_figure *f, const char *title)
{
    (void)s;
    fprintf(o, "## %s: %s\n\n", f->id, title);
    const char *note = study_figure_note(f);
    if (note) fprintf(o, "%s\n\n", note);
}

/* Every published value (paper.*) of every series, for figures whose tables have no paper
 * columns. */
/* Particle files replace a plan's nx sweep, one resolution each; zhu and beta are anchored at
 * the first file. */
static void plan_take_files(series_plan *pl, const study_files *files)
{
    pl->nvalues = files->n;
    for (int j = 0; j < files->n; ++j) pl->values[j] = resolution_of(&files->sets[j]);
    pl->spec.n_ref = (double)files->sets[0].n;
}

/* The particles of resolution j of an nx sweep, and their nx: file j, or the plan's layout at
 * nx = values[j] from the cache. */
static int plan_particles(const series_plan *pl, int j, const study_files *files,
                          layout_cache *cache, FILE *log, const consph_particles **p, size_t *nx)
{
    if (files) {
        *p = &files->sets[j];
        *nx = (size_t)floor(resolution_of(*p) + 0.5);
        return CONSPH_OK;
    }
    *nx = (size_t)pl->values[j];
    consph_layout_params lp = pl->spec.layout;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) lp.nx[a] = a < lp.dim ? *nx : 1;
    double lsec;
    return cache_get(cache, &lp, p, &lsec, log);
}

void study_published_values(const consph_study *s, const study_figure *f, FILE *o)
{
    int any = 0;
    for (int r = 0; r < f->nseries; ++r) {
        const study_series *ser = &f->series[r];
        const study_kvlist *lists[3] = {&s->keys, &f->keys, &ser->keys};
        char line[1024] = "";
        for (int l = 0; l < 3; ++l)
            for (int k = 0; k < lists[l]->n; ++k) {
                const char *key = lists[l]->items[k].key;
                if (strncmp(key, "paper.", 6) != 0) continue;
                if (l < 2 && has_key(&ser->keys, key)) continue;
                if (l == 0 && has_key(&f->keys, key)) continue;
                size_t len = strlen(line);
                snprintf(line + len, sizeof line - len, "%s%s = %s", len ? "; " : "", key + 6,
                         lists[l]->items[k].value);
            }
        if (!line[0]) continue;
        if (!any) fprintf(o, "Published values (as the paper prints them):\n\n");
        any = 1;
        fprintf(o, "- %s: %s\n", ser->label, line);
    }
    if (any) fprintf(o, "\n");
}

/* DIR/NAME.EXT into buf (STUDY_PATH_MAX bytes), refused rather than truncated. */
int study_out_path(char *buf, const char *dir, const char *name, const char *ext)
{
    int n = snprintf(buf, STUDY_PATH_MAX, "%s/%s%s", dir, name, ext);
    if (n < 0 || n >= STUDY_PATH_MAX)
        return consph_fail(CONSPH_EINVAL, "output path '%s/%s%s' is too long", dir, name, ext);
    return CONSPH_OK;
}

int study_open_output(consph_outfile *of, const char *dir, const char *id, const char *ext)
{
    char path[STUDY_PATH_MAX];
    int rc = study_out_path(path, dir, id, ext);
    return rc ? rc : consph_outfile_open(of, path);
}

/* Creates `path` and its missing parents; *created is the length of the shortest prefix of
 * path this call created (0: none), so that a failed run can remove what it made. */
static int mkdir_p(const char *path, size_t *created)
{
    char buf[STUDY_PATH_MAX];
    *created = 0;
    if (snprintf(buf, sizeof buf, "%s", path) >= (int)sizeof buf)
        return consph_fail(CONSPH_EINVAL, "output path '%s' is too long", path);
    size_t len = strlen(buf);
    for (size_t k = 1; k <= len; ++k) {
        if (buf[k] != '/' && buf[k] != '\0') continue;
        char c = buf[k];
        buf[k] = '\0';
        if (mkdir(buf, 0777) == 0) {
            if (!*created) *created = k;
        } else if (errno != EEXIST) {
            return consph_fail(CONSPH_EIO, "cannot create directory '%s': %s", buf,
                               strerror(errno));
        }
        buf[k] = c;
    }
    return CONSPH_OK;
}

/* After a failed run: the directories it created go, with what it wrote into them. */
static void remove_created(const char *dir, size_t created)
{
    if (!created) return;
    DIR *d = opendir(dir);
    if (d) {
        struct dirent *e;
        char path[STUDY_PATH_MAX];
        while ((e = readdir(d)))
            if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..") &&
                study_out_path(path, dir, e->d_name, "") == CONSPH_OK)
                remove(path);
        closedir(d);
    }
    char buf[STUDY_PATH_MAX];
    snprintf(buf, sizeof buf, "%s", dir);
    for (size_t k = strlen(buf); k >= created; --k) {
        if (buf[k] != '/' && buf[k] != '\0') continue;
        buf[k] = '\0';
        if (rmdir(buf) != 0 && errno != ENOENT) break;
    }
}

static double norm_value(const consph_approx_row *r, const char *norm)
{
    return consph_approx_norm(r, norm);
}

static double x_value(const consph_approx_row *r, double nx, const char *x, int dim)
{
    if (strcmp(x, "nbr") == 0) return r->nbr_mean + 1.0;
    if (strcmp(x, "sqrtN") == 0) return pow((double)r->n, 1.0 / dim);
    return nx;
}

const char *study_get_or(const consph_study *s, const study_figure *f, const study_series *r,
                         const char *key, const char *def)
{
    const char *v = study_get(s, f, r, key);
    return v ? v : def;
}

/* A CSV-safe copy of a label (no commas or quotes). */
const char *study_csv_label(const char *label, char *buf, size_t size)
{
    snprintf(buf, size, "%s", label);
    for (char *c = buf; *c; ++c)
        if (*c == ',' || *c == '"') *c = ';';
    return buf;
}

int study_have_gnuplot(void)
{
    static int cached = -1;
    if (cached < 0) cached = system("command -v gnuplot >/dev/null 2>&1") == 0;
    return cached;
}

/* Writes `text` to a gnuplot script as a single-quoted string, the one form gnuplot never
 * interprets (no backquote commands, macros or escapes; '' is a quote). Every user string that
 * meets gnuplot goes through here; control characters cannot be quoted and are refused. */
int study_gp_put(FILE *o, const char *text)
{
    for (const char *c = text; *c; ++c)
        if ((unsigned char)*c < 0x20 || *c == 0x7f)
            return consph_fail(CONSPH_EFORMAT,
                               "'%s' cannot go into a gnuplot script (control character 0x%02x)",
                               text, (unsigned char)*c);
    fputc('\'', o);
    for (const char *c = text; *c; ++c) {
        if (*c == '\'') fputc('\'', o);
        fputc(*c, o);
    }
    fputc('\'', o);
    return CONSPH_OK;
}

/* The head of every figure script: SVG into `outfile` (ID.svg unless the caller sets it, so the
 * script also runs by hand) and a title. */
int study_gp_head(FILE *o, const char *id, const char *title)
{
    fprintf(o,
            "set terminal svg size 900,640 dynamic\nif (!exists('outfile')) outfile = '%s.svg'\n"
            "set output outfile\nset title ",
            id);
    int rc = study_gp_put(o, title);
    fprintf(o, " noenhanced\nset grid\nset key outside right noenhanced\n");
    return rc;
}

/* Draws DIR/ID.gp into DIR/ID.svg through a temporary file, so that a figure either is drawn
 * whole or leaves no SVG; gnuplot failing is an error. Without gnuplot: a warning, once. */
int study_render_figure(const char *dir, const char *id)
{
    static int warned;
    if (!study_have_gnuplot()) {
        if (!warned)
            fprintf(stderr,
                    "consph study: warning: gnuplot not found, so figures are left as "
                    "FIGURE.gp scripts without SVG (Debian: apt-get install gnuplot-nox)\n");
        warned = 1;
        return CONSPH_OK;
    }
    char tmp[STUDY_PATH_MAX], final[STUDY_PATH_MAX], script[STUDY_PATH_MAX / 4],
        setout[STUDY_PATH_MAX / 4];
    char tmp_name[STUDY_PATH_MAX / 4];
    snprintf(tmp_name, sizeof tmp_name, "%s.svg.tmp.%ld", id, (long)getpid());
    snprintf(script, sizeof script, "%s.gp", id);
    int rc = study_out_path(tmp, dir, tmp_name, "");
    if (rc == CONSPH_OK) rc = study_out_path(final, dir, id, ".svg");
    if (rc) return rc;
    FILE *mem = fmemopen(setout, sizeof setout, "w");
    if (!mem) return consph_fail(CONSPH_ENOMEM, "out of memory");
    fprintf(mem, "outfile = ");
    rc = study_gp_put(mem, tmp_name);
    fclose(mem);
    if (rc) return rc;
    fflush(NULL);
    /* SIGINT/SIGTERM while gnuplot draws: the child is killed and its output removed with the
     * other temporary files (src/io/outfile.c). */
    consph_tmp_register(tmp);
    sigset_t mask;
    consph_cleanup_signals_block(&mask);
    /* fork and exec rather than system(): the output directory never passes through a shell. */
    pid_t pid = fork();
    if (pid == 0) {
        consph_cleanup_signals_default();
        sigprocmask(SIG_SETMASK, &mask, NULL);
        int null = open("/dev/null", O_WRONLY);
        if (null >= 0) {
            dup2(null, 1);
            dup2(null, 2);
        }
        if (chdir(dir) == 0) execlp("gnuplot", "gnuplot", "-e", setout, script, (char *)NULL);
        _exit(127);
    }
    int fork_errno = errno;
    if (pid > 0) consph_child_register(pid);
    sigprocmask(SIG_SETMASK, &mask, NULL);
    if (pid < 0) {
        consph_tmp_unregister(tmp);
        return consph_fail(CONSPH_EIO, "cannot start gnuplot: %s", strerror(fork_errno));
    }
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) continue;
    consph_child_unregister(pid);
    struct stat st;
    int drawn =
        WIFEXITED(status) && WEXITSTATUS(status) == 0 && stat(tmp, &st) == 0 && st.st_size > 0;
    if (drawn && rename(tmp, final) == 0) {
        consph_tmp_unregister(tmp);
        return CONSPH_OK;
    }
    remove(tmp);
    consph_tmp_unregister(tmp);
    return consph_fail(CONSPH_EIO,
                       "gnuplot could not draw %s (exit status %d); run 'gnuplot %s' there to see "
                       "why",
                       final, WIFEXITED(status) ? WEXITSTATUS(status) : -1, script);
}

/* ---- approx figures ---- */

static void paper_columns(const consph_study *s, const study_figure *f, const study_series *r,
                          char *buf, size_t size)
{
    buf[0] = '\0';
    /* Every paper.* key not printed in its own column. */
    const study_kvlist *lists[2] = {&f->keys, &r->keys};
    for (int l = 0; l < 2; ++l)
        for (int k = 0; k < lists[l]->n; ++k) {
            const char *key = lists[l]->items[k].key;
            if (strncmp(key, "paper.", 6) != 0) continue;
            if (!strcmp(key, "paper.order") || !strcmp(key, "paper.l1") ||
                !strcmp(key, "paper.ft") || !strcmp(key, "paper.error") || !strcmp(key, "paper.tr"))
                continue;
            if (l == 0 && has_key(&r->keys, key)) continue;
            snprintf(buf + strlen(buf), size - strlen(buf), "%s%s = %s", buf[0] ? "; " : "",
                     key + 6, study_get(s, f, r, key));
        }
}

/* A published value that is a plain number (many are prose: "~2 (SOC)"). */
int study_paper_number(const consph_study *s, const study_figure *f, const study_series *r,
                       const char *key, double *out)
{
    const char *v = study_get(s, f, r, key);
    if (!v) return 0;
    char *end;
    double d = strtod(v, &end);
    if (end == v || *end || !isfinite(d)) return 0;
    *out = d;
    return 1;
}

/* Series whose published value is drawn (the rest still appear in the report). */
#define MAX_SERIES_POINTS 64

/* Where the paper's error of series r goes on the plot: at the last resolution of the full
 * (paper) `nx` list, when the abscissa is a resolution and the paper gives the fitted norm
 * (paper.l1 for l1, or paper.error) as a positive number. */
static int paper_point(const consph_study *s, const study_figure *f, const study_series *r,
                       const char *xname, const char *norm, double *x, double *y)
{
    if (strcmp(xname, "nbr") == 0) return 0;
    if (!(strcmp(norm, "l1") == 0 && study_paper_number(s, f, r, "paper.l1", y)) &&
        !study_paper_number(s, f, r, "paper.error", y))
        return 0;
    double nxs[MAX_SWEEP];
    int n = 0;
    if (study_get_list(s, f, r, "nx", 2, 1e5, nxs, &n) != CONSPH_OK || n == 0 || !(*y > 0))
        return 0;
    *x = nxs[n - 1];
    return 1;
}

/* Whether the figure's table has T_r: where a series publishes it (paper.tr, 001 Tables 3 and
 * 5). It costs TR_TIMINGS operator applications at each series' finest resolution. */
static int reports_tr(const consph_study *s, const study_figure *f)
{
    for (int k = 0; k < f->nseries; ++k)
        if (study_get(s, f, &f->series[k], "paper.tr")) return 1;
    return 0;
}

static int write_approx_outputs(const consph_study *s, const study_figure *f,
                                const series_plan *plans, const series_result *res, const char *dir,
                                int quick, const study_files *files, FILE *log)
{
    const char *norm = study_get_or(s, f, NULL, "norm", "l1");
    const char *xname = study_get_or(s, f, NULL, "x", "nx");
    int sweep_hdx = plans[0].sweep_hdx;
    int dim = plans[0].spec.layout.dim;
    char label[256];

    /* CSV: one row per measurement. */
    consph_outfile of;
    int rc = study_open_output(&of, dir, f->id, ".csv");
    if (rc) return rc;
    fprintf(of.fp, "series,sweep,kernel,hdx,form,corr,layout,field,nx,n,h,nbr_mean,l1,l2,linf,"
                   "mae,ft_over_fmax,seconds,fallbacks,bound\n");
    for (int k = 0; k < f->nseries; ++k) {
        const series_plan *pl = &plans[k];
        for (int j = 0; j < res[k].nrows; ++j) {
            const consph_approx_row *w = &res[k].rows[j];
            char layout_text[256], layout[256];
            if (files)
                snprintf(layout_text, sizeof layout_text, "file:%s",
                         files->names[pl->sweep_hdx ? files->n - 1 : j]);
            else
                snprintf(layout_text, sizeof layout_text, "%s",
                         consph_layout_name(pl->spec.layout.kind));
            study_csv_label(layout_text, layout, sizeof layout);
            fprintf(of.fp,
                    "%s,%g,%s,%g,%s,%s,%s,%s,%zu,%zu,%.10g,%.6g,%.6e,%.6e,%.6e,%.6e,%.6e,%.6g,"
                    "%zu,%.6e\n",
                    study_csv_label(f->series[k].label, label, sizeof label), pl->values[j],
                    pl->kernel_name, sweep_hdx ? pl->values[j] : pl->spec.hdx,
                    consph_form_name(pl->spec.op.form), consph_corr_name(pl->spec.op.corr), layout,
                    consph_mfield_name(pl->spec.field), w->nx, w->n, w->h, w->nbr_mean, w->err.l1,
                    w->err.l2, w->err.linf, w->err.mae, w->ft_over_fmax, w->seconds, w->fallbacks,
                    res[k].bound[j]);
        }
    }
    if ((rc = consph_outfile_commit(&of))) return rc;

    /* Every series' order verdict; a non-finite row fails the figure once its files are
     * written, a degenerate one is a warning. */
    consph_series_order *fits = calloc((size_t)f->nseries, sizeof *fits);
    if (!fits) return consph_fail(CONSPH_ENOMEM, "out of memory");
    char failure[1024] = "";
    for (int k = 0; k < f->nseries; ++k) {
        consph_series_order *so = &fits[k];
        if (consph_series_fit(res[k].rows, res[k].nx, res[k].nrows, norm, 2, "±", so) ==
            CONSPH_ENOMEM) {
            free(fits);
            return consph_fail(CONSPH_ENOMEM, "out of memory");
        }
        /* The sweep value or file beside the row's nx, which alone may not tell rows apart. */
        char where[320] = "";
        if (so->row >= 0 && sweep_hdx)
            snprintf(where, sizeof where, " (h/dx = %g)", plans[k].values[so->row]);
        else if (so->row >= 0 && files)
            snprintf(where, sizeof where, " (file %s)", files->names[so->row]);
        if (so->status == CONSPH_SERIES_NONFINITE && !failure[0])
            snprintf(failure, sizeof failure, "figure '%s', series '%s': %s%s", f->id,
                     f->series[k].label, so->why, where);
        if (so->status == CONSPH_SERIES_DEGENERATE && log)
            fprintf(log, "  warning: series '%s': %s%s\n", f->series[k].label, so->why, where);
    }

    /* Markdown report. */
    if ((rc = study_open_output(&of, dir, f->id, ".md"))) {
        free(fits);
        return rc;
    }
    FILE *o = of.fp;
    char tbuf[640];
    const char *title = files_title(s, f, files != NULL, tbuf, sizeof tbuf);
    study_report_head_as(o, s, f, title);
    const consph_approx_spec *sp = &plans[0].spec;
    fprintf(o,
            "Run: %s resolutions; op `%s`, layout `%s`, dim %d, periodic %s, field `%s`, "
            "volumes `%s`, compared particles: %s. Norm fitted: `%s`.\n\n",
            files   ? "the files'"
            : quick ? "quick"
                    : "full (paper)",
            consph_op_name(sp->op.op),
            files ? "particle files" : consph_layout_name(sp->layout.kind), dim,
            (files ? files->sets[0].box.periodic[0] : sp->layout.box.periodic[0]) ? "yes" : "no",
            consph_mfield_name(sp->field), consph_volume_name(sp->volume),
            sp->interior_only ? "interior (full support)" : "all", norm);
    if (sp->h_policy == CONSPH_H_ZHU || sp->h_policy == CONSPH_H_BETA) {
        char htext[160];
        fprintf(o, "Smoothing length: h %s.\n\n", h_policy_text(sp, htext, sizeof htext));
    }
    if (files) {
        fprintf(o, "Particles from files (`consph study --particles`)%s:",
                sweep_hdx ? "; the h/Δs sweep runs on the last one" : ", one row each");
        for (int j = 0; j < files->n; ++j)
            fprintf(o, "%s `%s` (N = %zu)", j ? "," : "", files->names[j], files->sets[j].n);
        fprintf(o, ".\n\n");
    }
    if (!sweep_hdx) {
        /* T_r (001 Tables 3, 5): operator time at the finest resolution relative to the first
         * series, shown only where the paper publishes it. */
        int tr = reports_tr(s, f);
        fprintf(o,
                "| series | order (%s) | paper order | %s at finest | paper %s | F_T/F_max | "
                "paper F_T/F_max |%s fallbacks | other published values |\n",
                norm, norm, norm, tr ? " T_r | paper T_r |" : "");
        fprintf(o, "|---|---|---|---|---|---|---|%s---|---|\n", tr ? "---|---|" : "");
        const series_result *first = &res[0];
        double t_first = first->nrows ? first->rows[first->nrows - 1].seconds : NAN;
        /* A function interpolation exerts no force: F_T/F_max is meaningless there. */
        int no_force = sp->op.op == CONSPH_OP_FUNCTION;
        int flagged = 0;
        for (int k = 0; k < f->nseries; ++k) {
            const series_result *sr = &res[k];
            const study_series *r = &f->series[k];
            size_t fb = 0;
            for (int j = 0; j < sr->nrows; ++j) fb += sr->rows[j].fallbacks;
            char ord[sizeof fits[k].text + 8];
            double paper;
            int off = fits[k].status == CONSPH_SERIES_ORDER &&
                      study_paper_number(s, f, r, "paper.order", &paper) &&
                      fabs(fits[k].fit.order - paper) > ORDER_TOLERANCE;
            snprintf(ord, sizeof ord, "%s%s", fits[k].text, off ? " ⚠" : "");
            flagged |= off;
            const consph_approx_row *last = &sr->rows[sr->nrows - 1];
            char other[512], ft[32] = "";
            paper_columns(s, f, r, other, sizeof other);
            if (!no_force) snprintf(ft, sizeof ft, "%.2e", last->ft_over_fmax);
            fprintf(o, "| %s | %s | %s | %.3e (nx=%zu) | %s | %s | %s |", r->label, ord,
                    study_get_or(s, f, r, "paper.order", "—"), norm_value(last, norm), last->nx,
                    study_get_or(s, f, r, "paper.l1", study_get_or(s, f, r, "paper.error", "—")),
                    ft, no_force ? "" : study_get_or(s, f, r, "paper.ft", "—"));
            if (tr)
                fprintf(o, " %.2f | %s |", last->seconds / t_first,
                        study_get_or(s, f, r, "paper.tr", "—"));
            fprintf(o, " %zu | %s |\n", fb, other);
        }
        fprintf(o, "\n");
        if (flagged)
            fprintf(o, "⚠ the fitted order differs from the paper's by more than %.1f%s.\n\n",
                    ORDER_TOLERANCE,
                    quick ? " (a quick run fits coarser resolutions than the paper's)" : "");
        if (tr)
            fprintf(o,
                    "T_r: operator time at the finest resolution (median of %d runs) relative to "
                    "the first series.\n\n",
                    TR_TIMINGS);
        if (no_force)
            fprintf(o, "F_T/F_max is left blank: a function interpolation exerts no force.\n\n");
    }
    if (sweep_hdx) study_published_values(s, f, o);
    fprintf(o, "<details><summary>every measurement</summary>\n\n");
    fprintf(o,
            "| series | %s | nx | N | h | neighbours | l1 | l2 | linf | mae | F_T/F_max | "
            "seconds | fallbacks |%s\n",
            sweep_hdx ? "h/Δs" : "sweep", plans[0].bound ? " bound |" : "");
    fprintf(o, "|---|---|---|---|---|---|---|---|---|---|---|---|---|%s\n",
            plans[0].bound ? "---|" : "");
    for (int k = 0; k < f->nseries; ++k)
        for (int j = 0; j < res[k].nrows; ++j) {
            const consph_approx_row *w = &res[k].rows[j];
            fprintf(o,
                    "| %s | %g | %zu | %zu | %.4g | %.1f | %.3e | %.3e | %.3e | %.3e | %.2e | "
                    "%.3g | %zu |",
                    f->series[k].label, plans[k].values[j], w->nx, w->n, w->h, w->nbr_mean,
                    w->err.l1, w->err.l2, w->err.linf, w->err.mae, w->ft_over_fmax, w->seconds,
                    w->fallbacks);
            if (plans[0].bound) fprintf(o, " %.4g |", res[k].bound[j]);
            fprintf(o, "\n");
        }
    fprintf(o, "\n</details>\n\n");
    if (study_have_gnuplot()) fprintf(o, "![%s](%s.svg)\n\n", f->id, f->id);
    free(fits);
    if ((rc = consph_outfile_commit(&of))) return rc;

    /* Plot data, one gnuplot index block per series, and the script. */
    if ((rc = study_open_output(&of, dir, f->id, ".dat"))) return rc;
    for (int k = 0; k < f->nseries; ++k) {
        fprintf(of.fp, "# %s\n", f->series[k].label);
        for (int j = 0; j < res[k].nrows; ++j)
            fprintf(of.fp, "%.10g %.10g %.10g\n",
                    x_value(&res[k].rows[j], res[k].nx[j], xname, dim),
                    norm_value(&res[k].rows[j], norm), res[k].bound[j]);
        fprintf(of.fp, "\n\n");
    }
    if ((rc = consph_outfile_commit(&of))) return rc;
    if ((rc = study_open_output(&of, dir, f->id, ".gp"))) return rc;
    o = of.fp;
    rc = study_gp_head(o, f->id, title);
    fprintf(o, "set logscale xy\nset format y '%%g'\nset xlabel '%s'\nset ylabel '%s error'\n",
            strcmp(xname, "nbr") == 0 ? "neighbours" : "particles per axis", norm);
    /* A slope -2 guide (second-order convergence in the particle spacing), half a step below
     * the lowest first point so that it does not hide a series that converges at that rate.
     * Meaningless against neighbours, across h/Δs, or when h is not proportional to the
     * spacing (003's h = N^(-1/6)). */
    double y0 = INFINITY;
    for (int k = 0; k < f->nseries; ++k) {
        double y = res[k].nrows ? norm_value(&res[k].rows[0], norm) : NAN;
        if (y > 0 && y < y0) y0 = y;
    }
    int guide = !sweep_hdx && res[0].nrows > 0 && strcmp(xname, "nbr") != 0 &&
                plans[0].spec.h_policy == CONSPH_H_HDX && isfinite(y0);
    if (guide)
        fprintf(o, "ref(x) = %.10g*(x/%.10g)**(-2)\n", 0.5 * y0,
                x_value(&res[0].rows[0], res[0].nx[0], xname, dim));
    /* The paper's value of each series as a marked point at the paper's finest resolution. */
    int paper_pt[MAX_SERIES_POINTS] = {0};
    for (int k = 0; k < f->nseries && k < MAX_SERIES_POINTS; ++k) {
        double px, py;
        if (sweep_hdx || !paper_point(s, f, &f->series[k], xname, norm, &px, &py)) continue;
        fprintf(o, "$paper%d << EOD\n%.10g %.10g\nEOD\n", k, px, py);
        paper_pt[k] = 1;
    }
    fprintf(o, "plot");
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
        fprintf(o, "%s '%s.dat' index %d using 1:2 with linespoints lc %d title ",
                k ? ", \\\n    " : " ", f->id, k, k + 1);
        rc = study_gp_put(o, f->series[k].label);
    }
    /* One key entry for every paper point: the colour says which series. */
    int keyed = 0;
    for (int k = 0; k < f->nseries && k < MAX_SERIES_POINTS; ++k) {
        if (!paper_pt[k]) continue;
        fprintf(o, ", \\\n    $paper%d with points pt 6 ps 2 lw 2 lc %d %s", k, k + 1,
                keyed ? "notitle" : "title 'paper (series colour)'");
        keyed = 1;
    }
    if (plans[0].bound)
        fprintf(o, ", \\\n    '%s.dat' index 0 using 1:3 with lines dashtype 2 title 'bound'",
                f->id);
    if (guide)
        fprintf(o, ", \\\n    ref(x) with lines dashtype 2 lw 2 lc rgb 'gray40' title 'slope -2 "
                   "(second order)'");
    fprintf(o, "\n");
    if (rc) {
        consph_outfile_abort(&of);
        return rc;
    }
    if ((rc = consph_outfile_commit(&of))) return rc;
    /* before drawing: gnuplot may refuse the non-finite points, and its failure would then
     * hide this one, which names figure, series and resolution */
    if (failure[0]) return consph_fail(CONSPH_ENUMERIC, "%s", failure);
    return study_render_figure(dir, f->id);
}

static int run_approx_figure(const consph_study *s, const study_figure *f, int quick,
                             layout_cache *cache, const char *dir, const study_files *files,
                             FILE *log)
{
    int tr = reports_tr(s, f);
    series_plan *plans = calloc((size_t)f->nseries, sizeof *plans);
    series_result *res = calloc((size_t)f->nseries, sizeof *res);
    int rc = (!plans || !res) ? consph_fail(CONSPH_ENOMEM, "out of memory") : CONSPH_OK;
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k)
        rc = build_plan(s, f, &f->series[k], quick, &plans[k]);
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
        series_plan *pl = &plans[k];
        /* Files replace the nx sweep, one row each; an h/Δs sweep runs on the last file. */
        if (files && !pl->sweep_hdx) plan_take_files(pl, files);
        for (int j = 0; rc == CONSPH_OK && j < pl->nvalues; ++j) {
            consph_approx_spec sp = pl->spec;
            size_t nx = pl->sweep_hdx ? pl->nx_fixed : (size_t)pl->values[j];
            if (pl->sweep_hdx) sp.hdx = pl->values[j];
            /* T_r compares the finest resolutions: a median there, single timings elsewhere. */
            if (tr && !pl->sweep_hdx && j == pl->nvalues - 1) sp.timing_runs = TR_TIMINGS;
            const consph_particles *p;
            double lsec = 0.0;
            if (files) {
                p = &files->sets[pl->sweep_hdx ? files->n - 1 : j];
                res[k].nx[j] = resolution_of(p);
                nx = (size_t)floor(res[k].nx[j] + 0.5);
                sp.layout.box = p->box;
            } else {
                consph_layout_params lp = sp.layout;
                for (int a = 0; a < CONSPH_MAX_DIM; ++a) lp.nx[a] = a < lp.dim ? nx : 1;
                rc = cache_get(cache, &lp, &p, &lsec, log);
                if (rc) break;
                res[k].nx[j] = (double)nx;
            }
            consph_approx_row *w = &res[k].rows[j];
            rc = consph_approx_run_particles(&sp, p, nx, w);
            if (rc) {
                consph_fail(rc, "figure '%s', series '%s', nx %zu: %s", f->id, f->series[k].label,
                            nx, consph_last_error());
                break;
            }
            w->layout_seconds = lsec;
            double b = NAN;
            if (pl->bound) {
                double nn = sp.h_policy == CONSPH_H_SCALING ? consph_scaling_nnbr((double)w->n)
                                                            : w->nbr_mean;
                if (pl->bound == 1)
                    b = consph_bound_interpolation(
                        consph_bound_kernel_factor(pl->kernel_name, sp.layout.dim), sp.layout.dim,
                        nn, w->h);
                else
                    b = consph_bound_delta(sp.layout.dim, nn, w->h, sp.field_params.sigma);
            }
            res[k].bound[j] = b;
            res[k].nrows = j + 1;
            if (log)
                fprintf(log, "  %-28s %s=%-6g N=%-8zu nbr=%-8.1f l1=%.3e mae=%.3e (%.2fs%s)\n",
                        f->series[k].label, pl->sweep_hdx ? "h/dx" : "nx", pl->values[j], w->n,
                        w->nbr_mean, w->err.l1, w->err.mae, w->seconds,
                        lsec > 0.5 ? ", layout generated" : "");
        }
    }
    if (rc == CONSPH_OK) rc = write_approx_outputs(s, f, plans, res, dir, quick, files, log);
    free(plans);
    free(res);
    return rc;
}

/* ---- m0 figures: distributions of the volume estimate M0 (003 Figs. 2-3) ---- */

static double smoothing_length(const consph_approx_spec *sp, const consph_particles *p)
{
    return consph_approx_h(sp, p->n, consph_box_volume(&p->box), p->spacing);
}

typedef struct m0_row {
    size_t nx, n;
    double h, nbr, mean, std, mean_in, std_in, peak;
    size_t *counts;
} m0_row;

static int m0_measure(const series_plan *pl, const consph_particles *src, size_t nx, int nbins,
                      double lo, double hi, m0_row *row)
{
    consph_kernel k;
    consph_sys sys;
    int have_sys = 0;
    consph_op_ctx ctx;
    int have_ctx = 0;
    double *m0 = NULL, *inner = NULL;
    int rc;
    row->nx = nx;
    row->n = src->n;
    row->h = smoothing_length(&pl->spec, src);
    if ((rc = consph_kernel_init(&k, pl->spec.kernel, src->dim, row->h))) goto done;
    if ((rc = consph_sys_init(&sys, src, &k, 0.0))) goto done;
    have_sys = 1;
    const consph_particles *p = sys.p;
    if ((rc = consph_op_ctx_init_sys(&ctx, &sys, pl->spec.volume))) goto done;
    have_ctx = 1;
    m0 = consph_calloc(p->n, sizeof(double));
    inner = consph_calloc(p->n, sizeof(double));
    if (!m0 || !inner) {
        rc = CONSPH_ENOMEM;
        goto done;
    }
    consph_op_report rep;
    if ((rc = consph_op_moments(&ctx, m0, NULL, NULL, NULL, &rep))) goto done;
    row->nbr = (double)rep.pairs / (double)p->n - 1.0;
    if ((rc = consph_histogram(m0, p->n, lo, hi, nbins, row->counts, NULL, NULL, &row->mean,
                               &row->std)))
        goto done;
    size_t m = 0;
    for (size_t i = 0; i < p->n; ++i) {
        int in = 1;
        for (int a = 0; a < p->dim; ++a)
            if (!p->box.periodic[a] &&
                (p->x[a][i] - p->box.lo[a] < k.radius || p->box.hi[a] - p->x[a][i] < k.radius))
                in = 0;
        if (in) inner[m++] = m0[i];
    }
    row->mean_in = row->std_in = NAN;
    size_t one_bin;
    if (m)
        rc = consph_histogram(inner, m, lo, hi, 1, &one_bin, NULL, NULL, &row->mean_in,
                              &row->std_in);
    int best = 0;
    for (int b = 1; b < nbins; ++b)
        if (row->counts[b] > row->counts[best]) best = b;
    row->peak = lo + (best + 0.5) * (hi - lo) / nbins;
done:
    free(m0);
    free(inner);
    if (have_ctx) consph_op_ctx_free(&ctx);
    if (have_sys) consph_sys_free(&sys);
    return rc;
}

static int run_m0_figure(const consph_study *s, const study_figure *f, int quick,
                         layout_cache *cache, const char *dir, const study_files *files, FILE *log)
{
    const study_series *r = &f->series[0];
    series_plan pl;
    int rc = build_plan(s, f, r, quick, &pl);
    if (rc) return rc;
    double nbins_d, lo = 0.9, hi = 1.1;
    if ((rc = study_get_double(s, f, r, "bins", 60, 2, 10000, &nbins_d))) return rc;
    const char *range = study_get(s, f, r, "range");
    if (range && (sscanf(range, "%lf:%lf", &lo, &hi) != 2 || !(hi > lo)))
        return study_key_error(s, f, r, "range", "'%s' is not lo:hi with lo < hi", range);
    int nbins = (int)nbins_d;
    m0_row rows[MAX_SWEEP];
    memset(rows, 0, sizeof rows);
    int nrows = 0;
    if (files) plan_take_files(&pl, files);
    for (int j = 0; rc == CONSPH_OK && j < pl.nvalues; ++j) {
        size_t nx;
        const consph_particles *p;
        if ((rc = plan_particles(&pl, j, files, cache, log, &p, &nx))) break;
        rows[j].counts = consph_calloc((size_t)nbins, sizeof(size_t));
        if (!rows[j].counts) {
            rc = CONSPH_ENOMEM;
            break;
        }
        nrows = j + 1;
        if ((rc = m0_measure(&pl, p, nx, nbins, lo, hi, &rows[j]))) break;
        if (log)
            fprintf(log, "  nx=%-6zu N=%-8zu nbr=%-9.1f M0 mean %.6f std %.3e (interior %.3e)\n",
                    nx, rows[j].n, rows[j].nbr, rows[j].mean, rows[j].std, rows[j].std_in);
    }
    consph_outfile of;
    if (rc == CONSPH_OK) rc = study_open_output(&of, dir, f->id, ".csv");
    if (rc == CONSPH_OK) {
        fprintf(of.fp, "nx,n,h,nbr_mean,m0_mean,m0_std,m0_mean_interior,m0_std_interior,m0_peak\n");
        for (int j = 0; j < nrows; ++j)
            fprintf(of.fp, "%zu,%zu,%.10g,%.6g,%.10g,%.6e,%.10g,%.6e,%.6g\n", rows[j].nx, rows[j].n,
                    rows[j].h, rows[j].nbr, rows[j].mean, rows[j].std, rows[j].mean_in,
                    rows[j].std_in, rows[j].peak);
        rc = consph_outfile_commit(&of);
    }
    if (rc == CONSPH_OK) rc = study_open_output(&of, dir, f->id, ".dat");
    if (rc == CONSPH_OK) {
        for (int j = 0; j < nrows; ++j) {
            fprintf(of.fp, "# nx = %zu: M0, fraction of particles per unit M0\n", rows[j].nx);
            for (int b = 0; b < nbins; ++b) {
                double w = (hi - lo) / nbins;
                fprintf(of.fp, "%.8g %.8g\n", lo + (b + 0.5) * w,
                        (double)rows[j].counts[b] / ((double)rows[j].n * w));
            }
            fprintf(of.fp, "\n\n");
        }
        rc = consph_outfile_commit(&of);
    }
    char tbuf[640];
    if (rc == CONSPH_OK) rc = study_open_output(&of, dir, f->id, ".md");
    if (rc == CONSPH_OK) {
        FILE *o = of.fp;
        char htext[160];
        study_report_head_as(o, s, f, files_title(s, f, files != NULL, tbuf, sizeof tbuf));
        fprintf(o, "Run: %s resolutions; kernel `%s`, layout `%s`, dim %d, volumes `%s`, h %s.\n\n",
                files   ? "the files'"
                : quick ? "quick"
                        : "full (paper)",
                pl.kernel_name, files ? "particle files" : consph_layout_name(pl.spec.layout.kind),
                pl.spec.layout.dim, consph_volume_name(pl.spec.volume),
                h_policy_text(&pl.spec, htext, sizeof htext));
        fprintf(o, "| nx | N | h | neighbours | mean M0 | σ(M0) all | mean M0 interior | σ(M0) "
                   "interior | peak |\n|---|---|---|---|---|---|---|---|---|\n");
        double xs[MAX_SWEEP], ys[MAX_SWEEP];
        for (int j = 0; j < nrows; ++j) {
            fprintf(o, "| %zu | %zu | %.4g | %.1f | %.6f | %.3e | %.6f | %.3e | %.4f |\n",
                    rows[j].nx, rows[j].n, rows[j].h, rows[j].nbr, rows[j].mean, rows[j].std,
                    rows[j].mean_in, rows[j].std_in, rows[j].peak);
            xs[j] = rows[j].nbr;
            ys[j] = rows[j].std_in;
        }
        consph_order_fit fit;
        char ptext[64];
        if (consph_fit_order(xs, ys, nrows, &fit) == CONSPH_OK)
            fprintf(o,
                    "\nFitted σ(M0, interior) ∝ 𝒩^-p with p = %s (Zhu et al., quoted by "
                    "003/000: p = 1 for low-discrepancy sets, 1/2 for random ones).\n\n",
                    consph_order_text(&fit, 2, "±", ptext, sizeof ptext));
        study_published_values(s, f, o);
        if (study_have_gnuplot()) fprintf(o, "![%s](%s.svg)\n\n", f->id, f->id);
        rc = consph_outfile_commit(&of);
    }
    if (rc == CONSPH_OK) rc = study_open_output(&of, dir, f->id, ".gp");
    if (rc == CONSPH_OK) {
        FILE *o = of.fp;
        rc = study_gp_head(o, f->id, files_title(s, f, files != NULL, tbuf, sizeof tbuf));
        fprintf(o, "set xlabel 'M0'\nset ylabel 'particles (density)'\nplot");
        for (int j = 0; j < nrows; ++j)
            fprintf(o, "%s '%s.dat' index %d using 1:2 with lines title 'N = %zu'",
                    j ? ", \\\n    " : " ", f->id, j, rows[j].n);
        fprintf(o, "\n");
        if (rc)
            consph_outfile_abort(&of);
        else
            rc = consph_outfile_commit(&of);
        if (rc == CONSPH_OK) rc = study_render_figure(dir, f->id);
    }
    for (int j = 0; j < nrows; ++j) free(rows[j].counts);
    return rc;
}

/* ---- appc: 003 App. C, the closed-form discrete error of a 1D Gaussian sum ---- */

/* The untruncated Gaussian of 003 eq. C.1, cut where it falls below 1e-21 of its peak. */
#define APPC_CUT 7.0

typedef struct appc_job {
    const double *f; /* per particle, in system order */
    double h, spacing, sum;
} appc_job;

static void appc_visit(void *job, const consph_nbhd *nb)
{
    appc_job *a = job;
    double s = 0.0;
    for (size_t k = 0; k < nb->n; ++k) {
        double q = nb->r[k] / a->h;
        s += a->f[nb->j[k]] * a->spacing * exp(-q * q) / (sqrt(M_PI) * a->h);
    }
    a->sum = s;
}

/* The Gaussian sum at the one particle that was `at` in the generated set: a pass over a
 * destination mask of that particle, reading only the distances (the Gaussian is evaluated
 * untruncated, not through the system's kernel, which only sets the search). */
static int appc_sum(consph_sys *sys, size_t at, appc_job *job)
{
    const size_t n = sys->p->n;
    unsigned char *dest = consph_calloc(n, 1);
    if (!dest) return CONSPH_ENOMEM;
    for (size_t i = 0; i < n; ++i) dest[i] = sys->origin[i] == at;
    int rc = consph_sys_set_dest(sys, dest);
    free(dest);
    const consph_pass pass = {"appc Gaussian sum", CONSPH_PASS_NO_DX, appc_visit};
    job->sum = NAN;
    return rc ? rc : consph_pass_run(sys, &pass, job);
}

static int run_appc_figure(const consph_study *s, const study_figure *f, int quick, const char *dir,
                           FILE *log)
{
    series_plan pl;
    int rc = build_plan(s, f, &f->series[0], quick, &pl);
    if (rc) return rc;
    size_t nx = pl.nx_fixed;
    double closed[MAX_SWEEP], per[MAX_SWEEP], lin[MAX_SWEEP];
    for (int j = 0; rc == CONSPH_OK && j < pl.nvalues; ++j) {
        double hd = pl.values[j];
        closed[j] = 0.0;
        for (int m = 1; m < 60; ++m) closed[j] += 2.0 * exp(-M_PI * M_PI * m * m * hd * hd);
        /* f = 1 on a periodic lattice: every image within the cut is summed. */
        for (int periodic = 1; periodic >= 0 && rc == CONSPH_OK; --periodic) {
            consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 1, nx);
            lp.box = consph_box_unit(1, periodic);
            consph_particles p;
            if ((rc = consph_layout_generate(&lp, &p, NULL))) break;
            double h = hd * p.spacing;
            consph_kernel k;
            consph_sys sys;
            memset(&sys, 0, sizeof sys);
            double *fv = NULL;
            appc_job job = {NULL, h, p.spacing, NAN};
            rc = consph_kernel_init(&k, CONSPH_KERNEL_GAUSSIAN, 1, h);
            if (rc == CONSPH_OK) rc = consph_sys_init(&sys, &p, &k, APPC_CUT * h);
            if (rc == CONSPH_OK && !(fv = consph_calloc(p.n, sizeof(double)))) rc = CONSPH_ENOMEM;
            if (rc == CONSPH_OK && periodic) {
                for (size_t i = 0; i < p.n; ++i) fv[i] = 1.0;
                job.f = fv;
                if ((rc = appc_sum(&sys, 0, &job)) == CONSPH_OK) per[j] = job.sum - 1.0;
            } else if (rc == CONSPH_OK) {
                /* f = α + βx at the central particle, whose cut support lies inside the box. */
                size_t c = p.n / 2;
                for (size_t i = 0; i < p.n; ++i) fv[i] = 1.0 + 2.0 * sys.p->x[0][i];
                job.f = fv;
                if (APPC_CUT * h >= 0.5)
                    rc = consph_fail(CONSPH_EINVAL, "appc: h too large");
                else if ((rc = appc_sum(&sys, c, &job)) == CONSPH_OK)
                    lin[j] = job.sum / (1.0 + 2.0 * p.x[0][c]) - 1.0;
            }
            free(fv);
            consph_sys_free(&sys);
            consph_particles_free(&p);
        }
        if (log && rc == CONSPH_OK)
            fprintf(log, "  h/Δ=%-5g closed form %.6e, periodic f=1 %.6e, linear f %.6e\n", hd,
                    closed[j], per[j], lin[j]);
    }
    if (rc) return rc;
    consph_outfile of;
    if ((rc = study_open_output(&of, dir, f->id, ".csv"))) return rc;
    fprintf(of.fp, "h_over_delta,closed_form,periodic_const,linear_centre\n");
    for (int j = 0; j < pl.nvalues; ++j)
        fprintf(of.fp, "%g,%.10e,%.10e,%.10e\n", pl.values[j], closed[j], per[j], lin[j]);
    if ((rc = consph_outfile_commit(&of))) return rc;
    if ((rc = study_open_output(&of, dir, f->id, ".md"))) return rc;
    study_report_head(of.fp, s, f);
    fprintf(of.fp,
            "Lattice of %zu particles on [0,1), Gaussian exp(-x²/h²)/(√π h) summed to "
            "%g h. Relative error of the SPH sum against 003 eq. C.4.\n\n",
            nx, APPC_CUT);
    fprintf(of.fp, "| h/Δ | closed form 2Σexp(-π²j²h²/Δ²) | ours, f = 1 periodic | ours, f = α+βx "
                   "| |ours − closed| |\n|---|---|---|---|---|\n");
    for (int j = 0; j < pl.nvalues; ++j)
        fprintf(of.fp, "| %g | %.6e | %.6e | %.6e | %.1e |\n", pl.values[j], closed[j], per[j],
                lin[j], fmax(fabs(per[j] - closed[j]), fabs(lin[j] - closed[j])));
    fprintf(of.fp, "\n");
    study_published_values(s, f, of.fp);
    return consph_outfile_commit(&of);
}

/* ---- study level ---- */

static int cauchy_validate(const consph_study *s, int quick, const study_files *files,
                           double *seconds);

static int study_validate(const consph_study *s, int quick, const study_files *files)
{
    for (int k = 0; k < s->nfigs; ++k) {
        if (figure_kind(s, &s->figs[k]) == KIND_RUN) {
            int rc = study_run_validate(s, &s->figs[k], quick);
            if (rc) return rc;
            continue;
        }
        for (int r = 0; r < s->figs[k].nseries; ++r) {
            series_plan pl;
            int rc = build_plan(s, &s->figs[k], &s->figs[k].series[r], quick, &pl);
            if (rc) return rc;
        }
    }
    double seconds = 0.0;
    return cauchy_validate(s, quick, files, &seconds);
}

int consph_study_validate(const consph_study *s, int quick)
{
    return study_validate(s, quick, NULL);
}

/* Neighbour pairs of one run, from geometry (the support volume in particle spacings). */
static double pairs_estimate(const series_plan *pl, double nx)
{
    double n = pow(nx, pl->spec.layout.dim);
    /* The unit box, Δs = 1/nx. */
    return n * (1.0 + consph_approx_neighbours(&pl->spec, (size_t)n, 1.0, 1.0 / nx));
}

/* Particle files replace the nx sweeps (one run per file at its N^(1/dim)) and need no
 * packing. */
static double estimate(const consph_study *s, int quick, const study_files *files)
{
    double pairs = 0.0, packed_particles = 0.0;
    /* Packed layouts are generated once per (dim, nx, seed) and shared through the cache. */
    double seen[256][3];
    int nseen = 0;
    series_plan first;
    int have_first = 0;
    double run_seconds = 0.0;
    for (int k = 0; k < s->nfigs; ++k) {
        if (figure_kind(s, &s->figs[k]) == KIND_HEAT) {
            run_seconds += study_heat_seconds(s, &s->figs[k], quick);
            continue;
        }
        if (figure_kind(s, &s->figs[k]) == KIND_RUN) {
            double steps;
            run_seconds += study_run_estimate(s, &s->figs[k], quick, &steps);
            continue;
        }
        if (figure_kind(s, &s->figs[k]) == KIND_APPC) continue;
        for (int r = 0; r < s->figs[k].nseries; ++r) {
            series_plan pl;
            if (build_plan(s, &s->figs[k], &s->figs[k].series[r], quick, &pl)) return NAN;
            if (files) {
                if (!pl.sweep_hdx) pl.nvalues = files->n;
                for (int j = 0; j < pl.nvalues && !pl.sweep_hdx; ++j)
                    pl.values[j] = resolution_of(&files->sets[j]);
                pl.nx_fixed = (size_t)floor(resolution_of(&files->sets[files->n - 1]) + 0.5);
                pl.spec.layout.kind = CONSPH_LAYOUT_LATTICE;
            }
            if (!have_first) {
                first = pl;
                have_first = 1;
            }
            for (int j = 0; j < pl.nvalues; ++j) {
                series_plan one = pl;
                double nx = pl.sweep_hdx ? (double)pl.nx_fixed : pl.values[j];
                if (pl.sweep_hdx) one.spec.hdx = pl.values[j];
                pairs += pairs_estimate(&one, nx);
                if (pl.spec.layout.kind == CONSPH_LAYOUT_PACKED ||
                    pl.spec.layout.kind == CONSPH_LAYOUT_PACKED_POLISHED) {
                    double key[3] = {pl.spec.layout.dim, nx, (double)pl.spec.layout.seed};
                    int dup = 0;
                    for (int q = 0; q < nseen && !dup; ++q) dup = !memcmp(seen[q], key, sizeof key);
                    if (!dup) {
                        if (nseen < 256) memcpy(seen[nseen++], key, sizeof key);
                        packed_particles += pow(nx, pl.spec.layout.dim);
                    }
                }
            }
        }
    }
    /* The transport of cauchy figures, from consph_wasserstein_estimate's rates. */
    double ot_seconds = 0.0;
    if (cauchy_validate(s, quick, files, &ot_seconds) == CONSPH_OK) run_seconds += ot_seconds;
    if (!have_first) return run_seconds;
    /* Calibrate on a small run of the first series (about 2500 particles). */
    double nx_cal = first.spec.layout.dim == 1 ? 2500 : first.spec.layout.dim == 2 ? 50 : 14;
    consph_approx_row row;
    double t0 = consph_wtime();
    if (consph_approx_run(&first.spec, (size_t)nx_cal, &row) != CONSPH_OK) return NAN;
    double total = consph_wtime() - t0;
    double per_pair = (total - row.layout_seconds) / pairs_estimate(&first, nx_cal);
    double per_packed = 0.0;
    if (packed_particles > 0) {
        consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, 40);
        consph_particles p;
        t0 = consph_wtime();
        if (consph_layout_generate(&lp, &p, NULL) == CONSPH_OK) {
            per_packed = (consph_wtime() - t0) / (double)p.n;
            consph_particles_free(&p);
        }
    }
    return run_seconds + pairs * per_pair + packed_particles * per_packed;
}

double consph_study_estimate(const consph_study *s, int quick)
{
    return estimate(s, quick, NULL);
}

double consph_study_estimate_particles(const consph_study *s, int quick,
                                       const consph_particles *sets, int nsets)
{
    if (nsets < 1 || nsets > MAX_SWEEP) return NAN;
    study_files files = {sets, NULL, nsets};
    return estimate(s, quick, &files);
}

/* Period-1 fields repeat on a periodic axis only when its length is a whole number. */
static int check_field_period(const consph_approx_spec *sp, const consph_box *box)
{
    if (sp->field == CONSPH_MFIELD_CONST || !consph_mfield_periodic_on_unit(sp->field))
        return CONSPH_OK;
    for (int a = 0; a < box->dim; ++a) {
        double len = consph_box_length(box, a);
        if (box->periodic[a] && fabs(len - floor(len + 0.5)) > 1e-12 * fmax(1.0, len))
            return consph_fail(CONSPH_EINVAL,
                               "field '%s' has period 1 but the periodic axis %c has length %g",
                               consph_mfield_name(sp->field), "xyz"[a], len);
    }
    return CONSPH_OK;
}

/* Every figure that runs on particles must take the files: same dimension, a field that fits
 * their box. Checked before anything is written. */
static int validate_files(const consph_study *s, int quick, const study_files *files)
{
    if (files->n < 1 || files->n > MAX_SWEEP)
        return consph_fail(CONSPH_EINVAL, "%d particle files; allowed: 1 to %d", files->n,
                           MAX_SWEEP);
    for (int k = 0; k < s->nfigs; ++k) {
        const study_figure *f = &s->figs[k];
        fig_kind kind = figure_kind(s, f);
        if (kind == KIND_APPC || kind == KIND_HEAT) continue;
        if (kind == KIND_RUN)
            return consph_fail(CONSPH_EINVAL,
                               "figure '%s' runs the solver, which makes its own particles; "
                               "--particles does not apply",
                               f->id);
        for (int r = 0; r < f->nseries; ++r) {
            series_plan pl;
            int rc = build_plan(s, f, &f->series[r], quick, &pl);
            if (rc) return rc;
            for (int j = 0; j < files->n; ++j) {
                const consph_particles *p = &files->sets[j];
                if (p->dim != pl.spec.layout.dim)
                    return consph_fail(CONSPH_EINVAL,
                                       "figure '%s' is %dD, but the particles of %s are %dD", f->id,
                                       pl.spec.layout.dim, files->names[j], p->dim);
                if (kind != KIND_APPROX) continue;
                consph_approx_spec sp = pl.spec;
                sp.layout.box = p->box;
                if (consph_approx_check(&sp) != CONSPH_OK ||
                    check_field_period(&sp, &p->box) != CONSPH_OK)
                    return consph_fail(CONSPH_EINVAL, "figure '%s', series '%s', %s: %s", f->id,
                                       f->series[r].label, files->names[j], consph_last_error());
            }
        }
    }
    return CONSPH_OK;
}

/* ---- cauchy: 004's convergence in the Wasserstein distance, W(μ_N(j-1), μ_N(j)) ---- */

typedef struct cauchy_row {
    size_t nx0, nx1, n0, n1;
    double h0, h1, distance, error;
} cauchy_row;

/* The measure of one resolution: the particles themselves (equal or given masses), or the
 * kernel-smoothed density Σ m_b W(x − x_b, h) on a grid of `grid` cells per axis, h from the
 * series' policy. */
typedef struct cauchy_measure {
    consph_measure mu;
    consph_grid_measure g;
    double *scratch;
    double h;
    int smoothed;
} cauchy_measure;

static void cauchy_measure_free(cauchy_measure *m)
{
    if (m->smoothed) consph_grid_measure_free(&m->g);
    free(m->scratch);
    memset(m, 0, sizeof *m);
}

static int cauchy_measure_make(const series_plan *pl, const consph_particles *p, int smoothed,
                               size_t grid, cauchy_measure *m)
{
    memset(m, 0, sizeof *m);
    int rc = consph_measure_from_particles(p, &m->mu, &m->scratch, NULL);
    m->h = consph_approx_h(&pl->spec, p->n, consph_box_volume(&p->box), p->spacing);
    if (rc || !smoothed) return rc;
    consph_kernel k;
    if ((rc = consph_kernel_init(&k, pl->spec.kernel, p->dim, m->h))) return rc;
    if ((rc = consph_grid_measure_sph(&p->box, grid, &m->mu, &k, &m->g))) return rc;
    m->smoothed = 1;
    m->mu = m->g.mu;
    return CONSPH_OK;
}

static int write_cauchy(const consph_study *s, const study_figure *f, int quick,
                        const study_files *files, const char *dir, const series_plan *plans,
                        cauchy_row (*rows)[MAX_SWEEP], const int *nrows, char (*fit_text)[64],
                        const char *const *method_of, const int *measure_of, const int *p_of);

static const char *const cauchy_measures[] = {"particles", "smoothed", NULL};
static const char *const cauchy_methods[] = {"exact", "sliced", "sinkhorn", NULL};

/* The keys of one cauchy series. */
typedef struct cauchy_keys {
    consph_ot_options opt;
    int measure; /* 0 particles, 1 smoothed */
    double grid;
} cauchy_keys;

static int cauchy_read_keys(const consph_study *s, const study_figure *f, const study_series *r,
                            int dim, cauchy_keys *c)
{
    double pw, dirs, seed;
    int imeth, rc;
    if ((rc = study_get_choice(s, f, r, "measure", cauchy_measures, 0, &c->measure))) return rc;
    if ((rc = study_get_choice(s, f, r, "ot_method", cauchy_methods, dim == 1 ? 0 : 1, &imeth)))
        return rc;
    if ((rc = study_get_double(s, f, r, "ot_p", 1, 1, 2, &pw))) return rc;
    if ((rc = study_get_double(s, f, r, "directions", 64, 1, 1e5, &dirs))) return rc;
    if ((rc = study_get_double(s, f, r, "grid",
                               dim == 1   ? 4096
                               : dim == 2 ? 128
                                          : 32,
                               2, 1e6, &c->grid)))
        return rc;
    if ((rc = study_get_double(s, f, r, "seed", 1, 0, 1e15, &seed))) return rc;
    if (pw != floor(pw)) return study_key_error(s, f, r, "ot_p", "must be 1 or 2");
    if (imeth == 0 && dim != 1)
        return study_key_error(s, f, r, "ot_method", "exact is 1D only; use sliced or sinkhorn");
    c->opt = consph_ot_defaults();
    c->opt.method = (consph_ot_method)imeth;
    c->opt.p = (int)pw;
    c->opt.directions = (int)dirs;
    c->opt.seed = (uint64_t)seed;
    return CONSPH_OK;
}

/* Whether the series reads `key` (directions: sliced in 2D/3D; grid: smoothed measures), and
 * why not in `why`. The seed is not among them: the random layouts read it too. */
static int cauchy_reads(const cauchy_keys *c, int dim, const char *key, char *why, size_t size)
{
    if (strcmp(key, "grid") == 0) {
        snprintf(why, size,
                 "only with measure = smoothed; measure here is particles, which "
                 "compares the particles themselves");
        return c->measure == 1;
    }
    if (consph_ot_param_read(c->opt.method, dim, CONSPH_OT_PARAM_DIRECTIONS)) return 1;
    if (c->opt.method == CONSPH_OT_SLICED)
        snprintf(why, size,
                 "the figure is 1D, where every direction is +-1 and the sliced "
                 "distance is the exact one: it does nothing");
    else
        snprintf(why, size,
                 "only with ot_method = sliced; ot_method here is %s, which does not "
                 "read it",
                 cauchy_methods[c->opt.method]);
    return 0;
}

/* The memory of a series' largest comparison (two measures of the last two resolutions, their
 * grids, the transport), against consph_memory_limit, before any work: the message names
 * `grid` for smoothed measures, else `nx`. */
static int cauchy_check_cost(const consph_study *s, const study_figure *f, const study_series *r,
                             const series_plan *pl, const cauchy_keys *c, const study_files *files,
                             double *seconds)
{
    const int dim = pl->spec.layout.dim, threads = consph_num_threads();
    const int nres = files ? files->n : pl->nvalues;
    double worst = 0.0, worst_seconds = 0.0, worst_grids = 0.0;
    for (int j = 1; j < nres; ++j) {
        double n[2], grid_bytes = 0.0, grid_seconds = 0.0;
        for (int q = 0; q < 2; ++q) {
            double np =
                files ? (double)files->sets[j - 1 + q].n
                      : pow(pl->sweep_hdx ? (double)pl->nx_fixed : pl->values[j - 1 + q], dim);
            n[q] = c->measure ? pow(c->grid, dim) : np;
            if (!c->measure) continue;
            consph_ot_estimate g =
                consph_grid_measure_estimate(dim, (size_t)c->grid, (size_t)np, threads);
            grid_bytes += g.bytes;
            grid_seconds += g.seconds;
        }
        consph_ot_estimate t = consph_wasserstein_estimate(&c->opt, dim, n[0], n[1], threads);
        /* Sinkhorn's estimate is per iteration: 100, as the CLI's announcement assumes. */
        *seconds +=
            grid_seconds / 2.0 + (c->opt.method == CONSPH_OT_SINKHORN ? 100.0 : 1.0) * t.seconds;
        if (grid_bytes + t.bytes > worst) {
            worst = grid_bytes + t.bytes;
            worst_grids = grid_bytes;
            worst_seconds = grid_seconds + t.seconds;
        }
    }
    double limit, cap, available;
    int rc = consph_memory_limit(&limit, &cap, &available);
    if (rc) return consph_fail(rc, "%s: figure '%s': %s", s->path, f->id, consph_last_error());
    if (worst <= limit) return CONSPH_OK;
    return study_key_error(s, f, r, c->measure ? "grid" : "nx",
                           "a comparison needs about %.3g GB (grids %.3g GB; about %.3g s on %d "
                           "threads); the limit is %.3g GB (the cap %.3g GB, CONSPH_MEMORY_LIMIT, "
                           "or the %.3g GB available, whichever is less); allowed: a smaller %s",
                           worst / 1e9, worst_grids / 1e9, worst_seconds, threads, limit / 1e9,
                           cap / 1e9, available / 1e9, c->measure ? "grid" : "nx");
}

/* A cauchy key set where no series that sees it reads it would do nothing: refused at its
 * line. A figure- or study-level one read by some series is kept. Then the cost. */
static int cauchy_validate(const consph_study *s, int quick, const study_files *files,
                           double *seconds)
{
    static const char *const keys[] = {"directions", "grid"};
    /* One entry per definition: its line, whether a series reads it, the first that does not. */
    struct {
        int line, read;
        const study_figure *f;
        const study_series *r;
        char why[192];
    } defs[64];
    for (int q = 0; q < 2; ++q) {
        int ndefs = 0;
        for (int k = 0; k < s->nfigs; ++k) {
            const study_figure *f = &s->figs[k];
            if (figure_kind(s, f) != KIND_CAUCHY) continue;
            for (int i = 0; i < f->nseries; ++i) {
                const study_series *r = &f->series[i];
                series_plan pl;
                cauchy_keys c;
                int rc = build_plan(s, f, r, quick, &pl);
                if (!rc) rc = cauchy_read_keys(s, f, r, pl.spec.layout.dim, &c);
                if (!rc && q == 0) rc = cauchy_check_cost(s, f, r, &pl, &c, files, seconds);
                if (rc) return rc;
                const int line = study_line(s, f, r, keys[q]);
                if (!line) continue;
                int at = 0;
                while (at < ndefs && defs[at].line != line) ++at;
                if (at == ndefs) {
                    if (ndefs == 64) continue;
                    defs[ndefs].line = line;
                    defs[ndefs].read = 0;
                    defs[ndefs++].f = NULL;
                }
                char why[192];
                if (cauchy_reads(&c, pl.spec.layout.dim, keys[q], why, sizeof why))
                    defs[at].read = 1;
                else if (!defs[at].f) {
                    defs[at].f = f;
                    defs[at].r = r;
                    memcpy(defs[at].why, why, sizeof why);
                }
            }
        }
        for (int at = 0; at < ndefs; ++at)
            if (!defs[at].read)
                return study_key_error(s, defs[at].f, defs[at].r, keys[q], "%s", defs[at].why);
    }
    return CONSPH_OK;
}

static int run_cauchy_figure(const consph_study *s, const study_figure *f, int quick,
                             layout_cache *cache, const char *dir, const study_files *files,
                             FILE *log)
{
    const int nseries = f->nseries < MAX_SERIES_POINTS ? f->nseries : MAX_SERIES_POINTS;
    int nrows[MAX_SERIES_POINTS] = {0};
    char fit_text[MAX_SERIES_POINTS][64];
    const char *method_of[MAX_SERIES_POINTS];
    int measure_of[MAX_SERIES_POINTS], p_of[MAX_SERIES_POINTS];
    cauchy_row(*rows)[MAX_SWEEP] = calloc((size_t)nseries + 1, sizeof *rows);
    series_plan *plans = calloc((size_t)nseries + 1, sizeof *plans);
    int rc = rows && plans ? CONSPH_OK : consph_fail(CONSPH_ENOMEM, "out of memory");
    for (int k = 0; rc == CONSPH_OK && k < nseries; ++k) {
        const study_series *r = &f->series[k];
        series_plan *pl = &plans[k];
        if ((rc = build_plan(s, f, r, quick, pl))) break;
        const int dim = pl->spec.layout.dim;
        cauchy_keys c;
        if ((rc = cauchy_read_keys(s, f, r, dim, &c))) break;
        const int imeas = c.measure, imeth = (int)c.opt.method;
        const double grid = c.grid;
        const consph_ot_options opt = c.opt;
        method_of[k] = cauchy_methods[imeth];
        measure_of[k] = imeas;
        p_of[k] = opt.p;
        if (files) plan_take_files(pl, files);
        cauchy_measure prev, cur;
        memset(&prev, 0, sizeof prev);
        size_t prev_nx = 0, prev_n = 0;
        for (int j = 0; rc == CONSPH_OK && j < pl->nvalues; ++j) {
            size_t nx;
            const consph_particles *p;
            if ((rc = plan_particles(pl, j, files, cache, log, &p, &nx))) break;
            if ((rc = cauchy_measure_make(pl, p, imeas, (size_t)grid, &cur))) break;
            if (j > 0) {
                consph_ot_result res;
                rc = consph_wasserstein(&prev.mu, &cur.mu, &opt, &res);
                if (rc) {
                    consph_fail(rc, "figure '%s', series '%s', nx %zu: %s", f->id, r->label, nx,
                                consph_last_error());
                } else {
                    cauchy_row *w = &rows[k][nrows[k]++];
                    *w = (cauchy_row){prev_nx, nx,    prev_n,       p->n,
                                      prev.h,  cur.h, res.distance, res.error};
                    if (log)
                        fprintf(log, "  %-12s nx %zu -> %zu  W%d = %.6e ± %.1e\n", r->label,
                                prev_nx, nx, opt.p, res.distance, res.error);
                }
            }
            cauchy_measure_free(&prev);
            prev = cur;
            memset(&cur, 0, sizeof cur);
            prev_nx = nx;
            prev_n = p->n;
        }
        cauchy_measure_free(&prev);
        cauchy_measure_free(&cur);
        if (rc) break;
        double xs[MAX_SWEEP], ys[MAX_SWEEP];
        for (int j = 0; j < nrows[k]; ++j) {
            xs[j] = (double)rows[k][j].nx1;
            ys[j] = rows[k][j].distance;
        }
        consph_order_fit fit;
        if (nrows[k] >= 2 && consph_fit_order(xs, ys, nrows[k], &fit) == CONSPH_OK)
            consph_order_text(&fit, 2, "±", fit_text[k], sizeof fit_text[k]);
        else
            snprintf(fit_text[k], sizeof fit_text[k], "n/a (needs three resolutions)");
    }
    if (rc == CONSPH_OK)
        rc = write_cauchy(s, f, quick, files, dir, plans, rows, nrows, fit_text, method_of,
                          measure_of, p_of);
    free(rows);
    free(plans);
    return rc;
}

static int write_cauchy(const consph_study *s, const study_figure *f, int quick,
                        const study_files *files, const char *dir, const series_plan *plans,
                        cauchy_row (*rows)[MAX_SWEEP], const int *nrows, char (*fit_text)[64],
                        const char *const *method_of, const int *measure_of, const int *p_of)
{
    static const char *const measures[] = {"particles", "smoothed", NULL};
    const int nseries = f->nseries < MAX_SERIES_POINTS ? f->nseries : MAX_SERIES_POINTS;
    int rc;
    consph_outfile of;
    if ((rc = study_open_output(&of, dir, f->id, ".csv"))) return rc;
    fprintf(of.fp, "series,measure,method,p,nx0,nx1,n0,n1,h0,h1,distance,error\n");
    for (int k = 0; k < nseries; ++k)
        for (int j = 0; j < nrows[k]; ++j) {
            const cauchy_row *w = &rows[k][j];
            char label[128];
            fprintf(of.fp, "%s,%s,%s,%d,%zu,%zu,%zu,%zu,%.10g,%.10g,%.6e,%.3e\n",
                    study_csv_label(f->series[k].label, label, sizeof label),
                    measures[measure_of[k]], method_of[k], p_of[k], w->nx0, w->nx1, w->n0, w->n1,
                    w->h0, w->h1, w->distance, w->error);
        }
    if ((rc = consph_outfile_commit(&of))) return rc;
    if ((rc = study_open_output(&of, dir, f->id, ".md"))) return rc;
    FILE *o = of.fp;
    study_report_head(o, s, f);
    fprintf(o,
            "Run: %s resolutions; layout `%s`, dim %d. Each row is the Wasserstein distance "
            "between successive resolutions (a Cauchy sequence when it falls); the rate p is "
            "the fit of W ∝ nx^-p.\n\n",
            quick ? "quick" : "full",
            files ? "particle files" : consph_layout_name(plans[0].spec.layout.kind),
            plans[0].spec.layout.dim);
    for (int k = 0; k < nseries; ++k) {
        char htext[160];
        fprintf(o, "### %s: %s measure, %s W%d, kernel `%s`, h %s\n\n", f->series[k].label,
                measures[measure_of[k]], method_of[k], p_of[k], plans[k].kernel_name,
                h_policy_text(&plans[k].spec, htext, sizeof htext));
        fprintf(
            o,
            "| nx | nx' | N | N' | h | h' | W | its error |\n|---|---|---|---|---|---|---|---|\n");
        for (int j = 0; j < nrows[k]; ++j) {
            const cauchy_row *w = &rows[k][j];
            fprintf(o, "| %zu | %zu | %zu | %zu | %.4g | %.4g | %.4e | %.1e |\n", w->nx0, w->nx1,
                    w->n0, w->n1, w->h0, w->h1, w->distance, w->error);
        }
        fprintf(o, "\nRate: %s\n\n", fit_text[k]);
    }
    study_published_values(s, f, o);
    return consph_outfile_commit(&of);
}

static int run_figures(const consph_study *s, const consph_study_options *opt,
                       const study_files *files, const char *dir)
{
    int rc = CONSPH_OK;
    layout_cache *cache = calloc(1, sizeof *cache);
    if (!cache) return consph_fail(CONSPH_ENOMEM, "out of memory");
    FILE *log = opt->log;
    for (int k = 0; rc == CONSPH_OK && k < s->nfigs; ++k) {
        const study_figure *f = &s->figs[k];
        if (log) fprintf(log, "[%s] %s\n", f->id, study_get_or(s, f, NULL, "title", ""));
        double t0 = consph_wtime();
        switch (figure_kind(s, f)) {
        case KIND_M0:
            rc = run_m0_figure(s, f, opt->quick, cache, dir, files, log);
            break;
        case KIND_APPC:
            rc = run_appc_figure(s, f, opt->quick, dir, log);
            break;
        case KIND_CAUCHY:
            rc = run_cauchy_figure(s, f, opt->quick, cache, dir, files, log);
            break;
        case KIND_RUN:
            rc = study_run_figure(s, f, opt->quick, dir, log);
            break;
        case KIND_HEAT:
            rc = study_heat_figure(s, f, opt->quick, dir, log);
            break;
        default:
            rc = run_approx_figure(s, f, opt->quick, cache, dir, files, log);
            break;
        }
        if (log && rc == CONSPH_OK)
            fprintf(log, "  -> %s/%s.md (%.1f s)\n", dir, f->id, consph_wtime() - t0);
    }
    cache_free(cache);
    free(cache);
    return rc;
}

/* The study's README: title, then every figure's report in order. */
static int write_readme(const consph_study *s, const consph_study_options *opt,
                        const study_files *files, const char *dir)
{
    char path[STUDY_PATH_MAX];
    consph_outfile of;
    int rc = study_out_path(path, dir, "README", ".md");
    if (rc == CONSPH_OK) rc = consph_outfile_open(&of, path);
    if (rc) return rc;
    fprintf(of.fp, "# %s: %s\n\n", consph_study_name(s), consph_study_title(s));
    const char *note = study_get(s, NULL, NULL, "note");
    if (note) fprintf(of.fp, "%s\n\n", note);
    fprintf(of.fp, "Generated by `consph study %s%s%s` (consph %s).\n\n", consph_study_name(s),
            opt->quick ? " --quick" : "", files ? " --particles ..." : "", CONSPH_VERSION);
    for (int k = 0; k < s->nfigs; ++k) {
        char md[STUDY_PATH_MAX], buf[4096];
        if (study_out_path(md, dir, s->figs[k].id, ".md") != CONSPH_OK) continue;
        FILE *in = fopen(md, "r");
        if (!in) continue;
        size_t got;
        while ((got = fread(buf, 1, sizeof buf, in)) > 0) fwrite(buf, 1, got, of.fp);
        fclose(in);
    }
    return consph_outfile_commit(&of);
}

static int study_run(const consph_study *s, const consph_study_options *opt,
                     const study_files *files)
{
    int rc = study_validate(s, opt->quick, files);
    if (rc) return rc;
    if (files && (rc = validate_files(s, opt->quick, files))) return rc;
    char dir[STUDY_PATH_MAX];
    size_t created = 0;
    if ((rc = study_out_path(dir, opt->out_dir, consph_study_name(s), ""))) return rc;
    struct stat st;
    if (lstat(dir, &st) == 0 && S_ISLNK(st.st_mode))
        return consph_fail(CONSPH_EINVAL,
                           "'%s' is a symbolic link, which would take the results out of the "
                           "output directory; allowed: a directory, or nothing, at that name",
                           dir);
    rc = mkdir_p(dir, &created);
    /* A signal removes what was made as a failure does (remove_created). */
    if (rc == CONSPH_OK) consph_made_dir_register(dir, created);
    if (rc == CONSPH_OK) rc = run_figures(s, opt, files, dir);
    if (rc == CONSPH_OK) rc = write_readme(s, opt, files, dir);
    if (rc) remove_created(dir, created);
    consph_made_dir_unregister();
    return rc;
}

int consph_study_run(const consph_study *s, const consph_study_options *opt)
{
    return study_run(s, opt, NULL);
}

int consph_study_run_particles(const consph_study *s, const consph_study_options *opt,
                               const consph_particles *sets, const char *const *names, int nsets)
{
    study_files files = {sets, names, nsets};
    return study_run(s, opt, &files);
}
