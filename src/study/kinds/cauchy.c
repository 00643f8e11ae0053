/* Study kind `cauchy`: 004's convergence in the Wasserstein distance, W(μ_N(j-1), μ_N(j))
 * between successive resolutions, of the particles themselves or of their kernel-smoothed
 * density, and its rate. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/transport.h"
#include "study/kinds/kinds.h"

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
            if (study_kind_of(s, f) != &study_kind_cauchy) continue;
            for (int i = 0; i < f->nseries; ++i) {
                const study_series *r = &f->series[i];
                series_plan pl;
                cauchy_keys c;
                int rc = study_plan_build(s, f, r, quick, &pl);
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

static int run_cauchy_figure(const study_job *job, const study_figure *f)
{
    const consph_study *s = job->s;
    const int quick = job->quick;
    const char *dir = job->dir;
    const study_files *files = job->files;
    layout_cache *cache = job->cache;
    FILE *log = job->log;
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
        if ((rc = study_plan_build(s, f, r, quick, pl))) break;
        const int dim = pl->spec.layout.dim;
        cauchy_keys c;
        if ((rc = cauchy_read_keys(s, f, r, dim, &c))) break;
        const int imeas = c.measure, imeth = (int)c.opt.method;
        const double grid = c.grid;
        const consph_ot_options opt = c.opt;
        method_of[k] = cauchy_methods[imeth];
        measure_of[k] = imeas;
        p_of[k] = opt.p;
        if (files) study_plan_take_files(pl, files);
        cauchy_measure prev, cur;
        memset(&prev, 0, sizeof prev);
        size_t prev_nx = 0, prev_n = 0;
        for (int j = 0; rc == CONSPH_OK && j < pl->nvalues; ++j) {
            size_t nx;
            const consph_particles *p;
            if ((rc = study_plan_particles(pl, j, files, cache, log, &p, &nx))) break;
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
                study_h_policy_text(&plans[k].spec, htext, sizeof htext));
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

static int cauchy_validate_study(const consph_study *s, int quick, const study_files *files)
{
    double seconds = 0.0;
    return cauchy_validate(s, quick, files, &seconds);
}

/* The neighbour pairs of the measures, and the transport from consph_wasserstein_estimate's
 * rates (a key error is left to the validation). */
static int cauchy_estimate(const consph_study *s, const study_figure *f, int quick,
                           const study_files *files, study_estimate *e)
{
    int rc = study_estimate_plans(s, f, quick, files, e);
    for (int i = 0; rc == CONSPH_OK && i < f->nseries; ++i) {
        const study_series *r = &f->series[i];
        series_plan pl;
        cauchy_keys c;
        double seconds = 0.0;
        if (study_plan_build(s, f, r, quick, &pl) ||
            cauchy_read_keys(s, f, r, pl.spec.layout.dim, &c) ||
            cauchy_check_cost(s, f, r, &pl, &c, files, &seconds))
            continue;
        e->seconds += seconds;
    }
    return rc;
}

const study_kind study_kind_cauchy = {
    .name = "cauchy",
    .particles = STUDY_PARTICLES_USED,
    .validate = study_validate_plans,
    .validate_study = cauchy_validate_study,
    .estimate = cauchy_estimate,
    .run = run_cauchy_figure,
};
