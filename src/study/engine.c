/* Runs the figures of a study file through the registry of study kinds (kinds/kinds.h): checks
 * every figure before anything runs, estimates the run time, and writes each figure's outputs
 * and the study README into OUT/STUDY/. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "consph/io.h"
#include "io/outfile_internal.h"
#include "study/kinds/kinds.h"

/* ---- the registry ---- */

#define STUDY_KIND_ROW(name) &study_kind_##name,
const study_kind *const study_kinds[] = {STUDY_KINDS(STUDY_KIND_ROW) NULL};
#undef STUDY_KIND_ROW
#define STUDY_KIND_NAME(name) #name,
const char *const study_kind_names[] = {STUDY_KINDS(STUDY_KIND_NAME) NULL};
#undef STUDY_KIND_NAME

const study_kind *study_kind_lookup(const char *name)
{
    for (int k = 0; study_kinds[k]; ++k)
        if (strcmp(study_kinds[k]->name, name) == 0) return study_kinds[k];
    return NULL;
}

/* A figure without `kind`, or with an unknown one (refused by study_plan_build, naming the allowed
 * kinds), is an approx figure. */
const study_kind *study_kind_of(const consph_study *s, const study_figure *f)
{
    const char *name = study_get(s, f, NULL, "kind");
    const study_kind *k = name ? study_kind_lookup(name) : NULL;
    return k ? k : study_kinds[0];
}

const char *consph_study_kind_names(void)
{
    static char list[128];
    if (!list[0])
        for (int k = 0; study_kind_names[k]; ++k)
            snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s", k ? ", " : "",
                     study_kind_names[k]);
    return list;
}

/* ---- the operator kinds' shared validation and estimate ---- */

int study_validate_plans(const consph_study *s, const study_figure *f, int quick)
{
    for (int r = 0; r < f->nseries; ++r) {
        series_plan pl;
        int rc = study_plan_build(s, f, &f->series[r], quick, &pl);
        if (rc) return rc;
    }
    return CONSPH_OK;
}

/* Particle files replace the nx sweeps (one run per file at its N^(1/dim)) and need no
 * packing. */
int study_estimate_plans(const consph_study *s, const study_figure *f, int quick,
                         const study_files *files, study_estimate *e)
{
    for (int r = 0; r < f->nseries; ++r) {
        series_plan pl;
        int rc = study_plan_build(s, f, &f->series[r], quick, &pl);
        if (rc) return rc;
        if (files) {
            if (!pl.sweep_hdx) pl.nvalues = files->n;
            for (int j = 0; j < pl.nvalues && !pl.sweep_hdx; ++j)
                pl.values[j] = study_resolution_of(&files->sets[j]);
            pl.nx_fixed = (size_t)floor(study_resolution_of(&files->sets[files->n - 1]) + 0.5);
            pl.spec.layout.kind = CONSPH_LAYOUT_LATTICE;
        }
        if (!e->have_first) {
            e->first = pl;
            e->have_first = 1;
        }
        for (int j = 0; j < pl.nvalues; ++j) {
            series_plan one = pl;
            double nx = pl.sweep_hdx ? (double)pl.nx_fixed : pl.values[j];
            if (pl.sweep_hdx) one.spec.hdx = pl.values[j];
            e->pairs += study_pairs_estimate(&one, nx);
            if (pl.spec.layout.kind == CONSPH_LAYOUT_PACKED ||
                pl.spec.layout.kind == CONSPH_LAYOUT_PACKED_POLISHED) {
                /* Packed layouts are generated once per (dim, nx, seed), shared through the
                 * cache. */
                double key[3] = {pl.spec.layout.dim, nx, (double)pl.spec.layout.seed};
                int dup = 0;
                for (int q = 0; q < e->nseen && !dup; ++q)
                    dup = !memcmp(e->seen[q], key, sizeof key);
                if (!dup) {
                    if (e->nseen < 256) memcpy(e->seen[e->nseen++], key, sizeof key);
                    e->packed_particles += pow(nx, pl.spec.layout.dim);
                }
            }
        }
    }
    return CONSPH_OK;
}

/* ---- study level ---- */

static int study_validate(const consph_study *s, int quick, const study_files *files)
{
    for (int k = 0; k < s->nfigs; ++k) {
        int rc = study_kind_of(s, &s->figs[k])->validate(s, &s->figs[k], quick);
        if (rc) return rc;
    }
    for (int k = 0; study_kinds[k]; ++k) {
        if (!study_kinds[k]->validate_study) continue;
        int rc = study_kinds[k]->validate_study(s, quick, files);
        if (rc) return rc;
    }
    return CONSPH_OK;
}

int consph_study_validate(const consph_study *s, int quick)
{
    return study_validate(s, quick, NULL);
}

static double estimate(const consph_study *s, int quick, const study_files *files)
{
    study_estimate *e = calloc(1, sizeof *e);
    if (!e) return NAN;
    for (int k = 0; k < s->nfigs; ++k) {
        const study_kind *kind = study_kind_of(s, &s->figs[k]);
        if (kind->estimate && kind->estimate(s, &s->figs[k], quick, files, e)) {
            free(e);
            return NAN;
        }
    }
    double total_seconds = e->seconds;
    if (!e->have_first) {
        free(e);
        return total_seconds;
    }
    /* Calibrate on a small run of the first series (about 2500 particles). */
    const series_plan first = e->first;
    double nx_cal = first.spec.layout.dim == 1 ? 2500 : first.spec.layout.dim == 2 ? 50 : 14;
    consph_approx_row row;
    double t0 = consph_wtime();
    if (consph_approx_run(&first.spec, (size_t)nx_cal, &row) != CONSPH_OK) {
        free(e);
        return NAN;
    }
    double total = consph_wtime() - t0;
    double per_pair = (total - row.layout_seconds) / study_pairs_estimate(&first, nx_cal);
    double per_packed = 0.0;
    if (e->packed_particles > 0) {
        consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, 40);
        consph_particles p;
        t0 = consph_wtime();
        if (consph_layout_generate(&lp, &p, NULL) == CONSPH_OK) {
            per_packed = (consph_wtime() - t0) / (double)p.n;
            consph_particles_free(&p);
        }
    }
    total_seconds += e->pairs * per_pair + e->packed_particles * per_packed;
    free(e);
    return total_seconds;
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

/* Every figure that runs on particles must take the files: same dimension, a field that fits
 * their box. Checked before anything is written. */
static int validate_files(const consph_study *s, int quick, const study_files *files)
{
    if (files->n < 1 || files->n > MAX_SWEEP)
        return consph_fail(CONSPH_EINVAL, "%d particle files; allowed: 1 to %d", files->n,
                           MAX_SWEEP);
    for (int k = 0; k < s->nfigs; ++k) {
        const study_figure *f = &s->figs[k];
        const study_kind *kind = study_kind_of(s, f);
        if (kind->particles == STUDY_PARTICLES_IGNORED) continue;
        if (kind->particles == STUDY_PARTICLES_REFUSED)
            return consph_fail(CONSPH_EINVAL,
                               "figure '%s' runs the solver, which makes its own particles; "
                               "--particles does not apply",
                               f->id);
        for (int r = 0; r < f->nseries; ++r) {
            series_plan pl;
            int rc = study_plan_build(s, f, &f->series[r], quick, &pl);
            if (rc) return rc;
            for (int j = 0; j < files->n; ++j) {
                const consph_particles *p = &files->sets[j];
                if (p->dim != pl.spec.layout.dim)
                    return consph_fail(CONSPH_EINVAL,
                                       "figure '%s' is %dD, but the particles of %s are %dD", f->id,
                                       pl.spec.layout.dim, files->names[j], p->dim);
                if (!kind->checks_operator_on_files) continue;
                consph_approx_spec sp = pl.spec;
                sp.layout.box = p->box;
                if (consph_approx_check(&sp) != CONSPH_OK ||
                    study_check_field_period(&sp, &p->box) != CONSPH_OK)
                    return consph_fail(CONSPH_EINVAL, "figure '%s', series '%s', %s: %s", f->id,
                                       f->series[r].label, files->names[j], consph_last_error());
            }
        }
    }
    return CONSPH_OK;
}

static int run_figures(const consph_study *s, const consph_study_options *opt,
                       const study_files *files, const char *dir)
{
    int rc = CONSPH_OK;
    layout_cache *cache = calloc(1, sizeof *cache);
    if (!cache) return consph_fail(CONSPH_ENOMEM, "out of memory");
    FILE *log = opt->log;
    const study_job job = {s, opt->quick, dir, files, cache, log};
    for (int k = 0; rc == CONSPH_OK && k < s->nfigs; ++k) {
        const study_figure *f = &s->figs[k];
        if (log) fprintf(log, "[%s] %s\n", f->id, study_get_or(s, f, NULL, "title", ""));
        double t0 = consph_wtime();
        rc = study_kind_of(s, f)->run(&job, f);
        if (log && rc == CONSPH_OK)
            fprintf(log, "  -> %s/%s.md (%.1f s)\n", dir, f->id, consph_wtime() - t0);
    }
    study_layout_cache_free(cache);
    free(cache);
    return rc;
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
    rc = study_mkdir_p(dir, &created);
    /* A signal removes what was made as a failure does (study_remove_created). */
    if (rc == CONSPH_OK) consph_made_dir_register(dir, created);
    if (rc == CONSPH_OK) rc = run_figures(s, opt, files, dir);
    if (rc == CONSPH_OK) rc = study_write_readme(s, opt->quick, files != NULL, dir);
    if (rc) study_remove_created(dir, created);
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
