/* Runs the figures of a study file through the registry of study kinds (kinds/kinds.h): checks
 * every figure before anything runs, estimates the run time, and writes each figure's outputs
 * and the study README into OUT/STUDY/. */
#include <dirent.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "consph/gpu.h"
#include "consph/io.h"
#include "consph/par.h"
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

/* Iterations a packing takes to meet its stopping rule: they grow slowly with nx (packed, 2D,
 * the defaults: 2651, 3551 and 5401 iterations at nx 20, 40 and 80), capped by pack_iter. A
 * model rather than a measurement, so that the estimate need not pack a layout to the end. */
static double packing_iterations(double nx, const consph_layout_params *lp)
{
    return fmin((double)lp->packing.max_iter, 3550.0 * sqrt(nx / 40.0));
}

double study_cpu_seconds(void)
{
    struct timespec t;
    if (clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t) != 0) return consph_wtime();
    const int threads = consph_num_threads();
    return ((double)t.tv_sec + 1e-9 * (double)t.tv_nsec) / (threads > 1 ? threads : 1);
}

/* Seconds of one packing iteration per particle, timed once per process on 200 iterations at
 * 40² with the layout cache off (a cached calibration would time a file read), and the threads
 * it ran on (*threads): processor seconds per thread are the wall time at that thread count. */
static double packing_seconds_per_iteration(int *threads)
{
    static double per = -1.0;
    static int per_threads = 1;
    *threads = per_threads;
    if (per >= 0.0) return per;
    per = 0.0;
    per_threads = *threads = consph_num_threads() > 1 ? consph_num_threads() : 1;
    char dir[4096] = "";
    const char *cache = consph_layout_cache_get();
    if (cache) snprintf(dir, sizeof dir, "%s", cache);
    consph_layout_cache_set(NULL);
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, 40);
    lp.packing.max_iter = 200;
    consph_particles p;
    consph_packing_report rep;
    memset(&rep, 0, sizeof rep);
    const double t0 = study_cpu_seconds();
    if (consph_layout_generate(&lp, &p, &rep) == CONSPH_OK) {
        per = (study_cpu_seconds() - t0) / ((double)p.n * fmax(1, rep.iterations));
        consph_particles_free(&p);
    }
    consph_packing_report_free(&rep);
    if (dir[0]) consph_layout_cache_set(dir);
    return per;
}

/* Set while a running study prices its rows without their packing (rows_model_seconds): the
 * packings are priced one by one beside them. */
static int packing_priced_apart;

double study_packing_seconds(const consph_layout_params *lp)
{
    if (lp->kind != CONSPH_LAYOUT_PACKED && lp->kind != CONSPH_LAYOUT_PACKED_POLISHED) return 0.0;
    if (packing_priced_apart) return 0.0;
    char path[4352];
    /* a layout the cache already holds costs a file read */
    if (consph_layout_cache_get() && consph_layout_cache_path(lp, path, sizeof path) == CONSPH_OK &&
        access(path, R_OK) == 0)
        return 0.0;
    double n = 1.0;
    for (int a = 0; a < lp->dim; ++a) n *= (double)lp->nx[a];
    int cal_threads;
    const double per = packing_seconds_per_iteration(&cal_threads);
    /* timed at one thread count, priced at another (a study's estimate at a worker's threads,
     * its packing ahead on all of them): the packing's loops share a layout's particles between
     * the threads */
    const int threads = consph_num_threads() > 1 ? consph_num_threads() : 1;
    return n * packing_iterations((double)lp->nx[0], lp) * per * cal_threads / threads;
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
                    const consph_layout_params lp = study_plan_row_layout(&pl, j);
                    e->seconds += study_packing_seconds(&lp);
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

/* The seconds of the study's figures (those `skip` does not mark: a resumed study's finished
 * ones), calibrated on this machine. */
static double estimate_figures(const consph_study *s, int quick, const study_files *files,
                               const unsigned char *skip)
{
    study_estimate *e = calloc(1, sizeof *e);
    if (!e) return NAN;
    for (int k = 0; k < s->nfigs; ++k) {
        if (skip && skip[k]) continue;
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
    /* Calibrate on a small run of the first series (about 2500 particles) on a lattice: the cost
     * per pair does not depend on the arrangement, and a packed one would take longer to make
     * than the whole calibration may. */
    series_plan first = e->first;
    first.spec.layout.kind = CONSPH_LAYOUT_LATTICE;
    double nx_cal = first.spec.layout.dim == 1 ? 2500 : first.spec.layout.dim == 2 ? 50 : 14;
    consph_approx_row row;
    double t0 = consph_wtime();
    if (consph_approx_run(&first.spec, (size_t)nx_cal, &row) != CONSPH_OK) {
        free(e);
        return NAN;
    }
    double total = consph_wtime() - t0;
    double per_pair = (total - row.layout_seconds) / study_pairs_estimate(&first, nx_cal);
    total_seconds += e->pairs * per_pair;
    free(e);
    return total_seconds;
}

static double estimate(const consph_study *s, int quick, const study_files *files)
{
    return estimate_figures(s, quick, files, NULL);
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

/* ---- rows, their store and --resume ---- */

static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *c = data;
    for (size_t k = 0; k < n; ++k) h = (h ^ c[k]) * 1099511628211ull;
    return h;
}

/* FNV-1a of a file's bytes into h; 0 when it cannot be read. */
static int hash_file(const char *path, uint64_t *h)
{
    FILE *in = fopen(path, "rb");
    if (!in) return 0;
    char buf[65536];
    size_t got;
    while ((got = fread(buf, 1, sizeof buf, in)) > 0) *h = fnv1a(*h, buf, got);
    int ok = !ferror(in);
    fclose(in);
    return ok;
}

/* What a resumed run must share with the run that kept the rows: the study file's contents,
 * --quick and the particle files (names and contents). One line each, compared line by line. */
static int state_text(const consph_study *s, int quick, const study_files *files, char *buf,
                      size_t size)
{
    uint64_t hs = 14695981039346656037ull, hp = hs;
    if (!hash_file(s->path, &hs))
        return consph_fail(CONSPH_EIO, "cannot read the study file '%s'", s->path);
    for (int k = 0; files && k < files->n; ++k) {
        hp = fnv1a(hp, files->names[k], strlen(files->names[k]) + 1);
        if (!hash_file(files->names[k], &hp))
            return consph_fail(CONSPH_EIO, "cannot read the particle file '%s'", files->names[k]);
    }
    snprintf(buf, size, "consph-study-state 1\nstudy file %016llx\nquick %s\nparticles %s%016llx\n",
             (unsigned long long)hs, quick ? "yes" : "no", files ? "" : "none ",
             (unsigned long long)(files ? hp : 0));
    return CONSPH_OK;
}

#define STATE_NAME ".study-state"

/* A fresh run forgets what an earlier one kept: its rows, figures and state. */
static void forget_kept(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char path[STUDY_PATH_MAX];
    while ((e = readdir(d))) {
        size_t n = strlen(e->d_name);
        int kept = e->d_name[0] == '.' && ((n > 4 && !strcmp(e->d_name + n - 4, ".row")) ||
                                           (n > 5 && !strcmp(e->d_name + n - 5, ".done")) ||
                                           !strcmp(e->d_name, STATE_NAME));
        if (kept && study_out_path(path, dir, e->d_name, "") == CONSPH_OK) remove(path);
    }
    closedir(d);
}

static int write_small(const char *dir, const char *name, const char *text)
{
    char path[STUDY_PATH_MAX];
    consph_outfile of;
    int rc = study_out_path(path, dir, name, "");
    if (rc == CONSPH_OK) rc = consph_outfile_open(&of, path);
    if (rc) return rc;
    fputs(text, of.fp);
    return consph_outfile_commit(&of);
}

/* The first line where the kept state and this run's differ, named for the message. */
static int check_state(const char *dir, const char *want, const char *cmd_dir)
{
    char path[STUDY_PATH_MAX], have[512] = "";
    int rc = study_out_path(path, dir, STATE_NAME, "");
    if (rc) return rc;
    FILE *in = fopen(path, "r");
    if (!in)
        return consph_fail(CONSPH_EINVAL,
                           "--resume: nothing to resume in '%s' (no rows kept by an earlier run "
                           "of this study); run it without --resume",
                           cmd_dir);
    size_t got = fread(have, 1, sizeof have - 1, in);
    have[got] = '\0';
    fclose(in);
    if (!strcmp(have, want)) return CONSPH_OK;
    static const char *const what[] = {"the state file's version differs",
                                       "the study file's contents differ", "--quick differs",
                                       "the particle files (--particles) differ"};
    const char *a = have, *b = want;
    for (int line = 0; line < 4; ++line) {
        size_t la = strcspn(a, "\n"), lb = strcspn(b, "\n");
        if (la != lb || strncmp(a, b, la)) {
            if (line == 2)
                return consph_fail(CONSPH_EINVAL,
                                   "--resume: the rows in '%s' were made %s --quick, this run is "
                                   "%s it; resume with the same options, or run without --resume "
                                   "to start over",
                                   cmd_dir, strstr(a, "yes") == a + 6 ? "with" : "without",
                                   strstr(b, "yes") == b + 6 ? "with" : "without");
            return consph_fail(CONSPH_EINVAL,
                               "--resume: %s from the run that kept the rows in '%s'; resume "
                               "with the same study file and options, or run without --resume "
                               "to start over",
                               what[line], cmd_dir);
        }
        a += la + (a[la] == '\n');
        b += lb + (b[lb] == '\n');
    }
    return consph_fail(CONSPH_EINVAL, "--resume: the state kept in '%s' is not readable", cmd_dir);
}

static int figure_done_path(char *buf, const char *dir, const study_figure *f)
{
    char name[STUDY_NAME_MAX + 8];
    snprintf(name, sizeof name, ".%s", f->id);
    return study_out_path(buf, dir, name, ".done");
}

static int figure_rows(const consph_study *s, const study_figure *f, int quick,
                       const study_files *files, double *work)
{
    const study_kind *kind = study_kind_of(s, f);
    *work = 1.0;
    if (!kind->rows) return 1;
    *work = 0.0;
    return kind->rows(s, f, quick, files, work);
}

/* ---- a study spread over MPI ranks ---- */

static void rows_price_due(const consph_study *s, const consph_study_options *opt,
                           const study_files *files, const char *dir, study_rows *rows);

/* Whether this rank runs the next unit: units are dealt round-robin in the order every rank
 * meets them (the study's figures, series and rows), so no message decides who runs what. A
 * row is a unit, and so is a figure without rows. Worker processes
 * (--jobs) share memory instead: each meets the units in that same order and runs the ones it
 * claims first, so a worker that finished its unit takes the next one nobody has, and rows of
 * unequal cost (a scheme twice as dear as another) balance themselves. */
static int unit_mine(study_rows *r)
{
    r->share_units++;
    study_shared *sh = r->shared;
    if (!sh || r->share_units > sh->nunits)
        return (r->share_units - 1) % r->share_size == r->share_rank;
    if (__atomic_load_n(&sh->abandon, __ATOMIC_ACQUIRE)) return 0;
    return !__atomic_exchange_n(&sh->claim[r->share_units - 1], 1, __ATOMIC_ACQ_REL);
}

int study_row_elsewhere(const study_job *job)
{
    study_rows *r = job->rows;
    if (!r || r->share_size < 2) return CONSPH_OK;
    r->fig_met++;
    if (unit_mine(r)) return CONSPH_OK;
    return r->fig_met >= r->fig_rows ? STUDY_SHARED : STUDY_ELSEWHERE;
}

static int run_figures(const consph_study *s, const consph_study_options *opt,
                       const study_files *files, const char *dir, study_rows *rows)
{
    int rc = CONSPH_OK;
    layout_cache *cache = calloc(1, sizeof *cache);
    if (!cache) return consph_fail(CONSPH_ENOMEM, "out of memory");
    FILE *log = opt->log;
    /* On a terminal the log reaches opt->log between redraws of the live line. */
    if (rows->tty && log) {
        rows->out = log;
        rows->mem = open_memstream(&rows->membuf, &rows->memlen);
        if (rows->mem) log = rows->mem;
    }
    const int gpu_ok = opt->device == CONSPH_STUDY_DEVICE_AUTO && consph_gpu_available(NULL, 0);
    const study_job job = {s, opt->quick, dir, files, cache, log, rows, opt->device, gpu_ok};
    for (int k = 0; rc == CONSPH_OK && k < s->nfigs; ++k) {
        const study_figure *f = &s->figs[k];
        const study_kind *kind = study_kind_of(s, f);
        char done[STUDY_PATH_MAX];
        double work;
        const int nrows = figure_rows(s, f, opt->quick, files, &work);
        if ((rc = figure_done_path(done, dir, f))) break;
        /* Spread over ranks, a figure without rows is one unit, run whole by its rank. */
        if (rows->share_size > 1 && !kind->rows && !unit_mine(rows)) continue;
        rows->fig_rows = nrows;
        rows->fig_met = 0;
        if (opt->resume && access(done, F_OK) == 0) {
            /* Its outputs were committed before the mark: kept as they are. */
            if (log && rows->shared_report)
                fprintf(log, "[%s] %s\n  -> %s/%s.md (run %s)\n", f->id,
                        study_get_or(s, f, NULL, "title", ""), dir, f->id,
                        opt->jobs > 1 ? "by a worker process" : "on another rank");
            else if (log)
                fprintf(log, "[%s] kept from the earlier run\n", f->id);
            rows->done += nrows;
            rows->work_done += work;
            continue;
        }
        if (study_rows_stop(&job)) break;
        if (log) fprintf(log, "[%s] %s\n", f->id, study_get_or(s, f, NULL, "title", ""));
        double t0 = consph_wtime();
        if (!kind->rows) study_row_begin(&job, f, -1, "", 1.0);
        rc = kind->run(&job, f);
        if (rc == STUDY_SHARED) {
            /* its rows are kept; rank 0 writes its report from them */
            rc = CONSPH_OK;
            continue;
        }
        if (rc == STUDY_STOPPED) {
            rc = CONSPH_OK;
            study_rows_stop(&job);
            if (!rows->stopped) rows->stopped = SIGINT;
            break;
        }
        if (rc == CONSPH_OK && !kind->rows)
            rc = study_row_finish(&job, f, -1, 0, NULL, 0, NULL, 0, 0);
        if (rc == CONSPH_OK) rc = write_small(dir, strrchr(done, '/') + 1, "");
        if (log && rc == CONSPH_OK)
            fprintf(log, "  -> %s/%s.md (%.1f s)\n", dir, f->id, consph_wtime() - t0);
        study_rows_flush(rows);
    }
    if (rc == CONSPH_OK) study_rows_stop(&job);
    if (rows->mem) {
        study_rows_flush(rows);
        fclose(rows->mem);
        free(rows->membuf);
        rows->mem = NULL;
    }
    study_layout_cache_free(cache);
    free(cache);
    return rc;
}

/* README.md of a stopped study: the figures that finished, then the others as not run, with
 * the rows each kept for --resume, and the command that resumes. */
static int write_partial_readme(const consph_study *s, const consph_study_options *opt,
                                const study_files *files, const char *dir, const study_rows *rows)
{
    char path[STUDY_PATH_MAX];
    consph_outfile of;
    int rc = study_out_path(path, dir, "README", ".md");
    if (rc == CONSPH_OK) rc = consph_outfile_open(&of, path);
    if (rc) return rc;
    FILE *o = of.fp;
    fprintf(o, "# %s: %s\n\n", consph_study_name(s), consph_study_title(s));
    fprintf(o,
            "**Partial results**: stopped by %s after %d of %d rows. Resume with\n\n"
            "    %s\n\n",
            rows->stopped == SIGINT    ? "SIGINT"
            : rows->stopped == SIGTERM ? "SIGTERM"
                                       : "a signal",
            rows->done, rows->total,
            opt->resume_cmd ? opt->resume_cmd : "consph study NAME --resume");
    for (int k = 0; k < s->nfigs; ++k) {
        const study_figure *f = &s->figs[k];
        char md[STUDY_PATH_MAX], buf[4096];
        if (figure_done_path(path, dir, f) == CONSPH_OK && access(path, F_OK) == 0 &&
            study_out_path(md, dir, f->id, ".md") == CONSPH_OK) {
            FILE *in = fopen(md, "r");
            if (in) {
                size_t got;
                while ((got = fread(buf, 1, sizeof buf, in)) > 0) fwrite(buf, 1, got, o);
                fclose(in);
                continue;
            }
        }
        double work;
        const int nrows = figure_rows(s, f, opt->quick, files, &work);
        int kept = 0;
        char prefix[STUDY_NAME_MAX + 4];
        snprintf(prefix, sizeof prefix, ".%s.s", f->id);
        DIR *d = opendir(dir);
        struct dirent *e;
        while (d && (e = readdir(d))) {
            size_t n = strlen(e->d_name);
            kept += !strncmp(e->d_name, prefix, strlen(prefix)) && n > 4 &&
                    !strcmp(e->d_name + n - 4, ".row");
        }
        if (d) closedir(d);
        fprintf(o,
                "## %s: %s\n\n%s: %d of %d rows done and kept for --resume; the rest not "
                "run.\n\n",
                f->id, kept ? "partly run" : "not run", study_get_or(s, f, NULL, "title", f->id),
                kept, nrows);
    }
    return consph_outfile_commit(&of);
}

/* The checks made before anything is written; the study's directory and its state text. */
static int study_prepare(const consph_study *s, const consph_study_options *opt,
                         const study_files *files, char *dir, char *state, size_t state_size)
{
    int rc = study_validate(s, opt->quick, files);
    if (rc) return rc;
    if (files && (rc = validate_files(s, opt->quick, files))) return rc;
    if ((rc = study_out_path(dir, opt->out_dir, consph_study_name(s), ""))) return rc;
    if ((rc = state_text(s, opt->quick, files, state, state_size))) return rc;
    struct stat st;
    if (lstat(dir, &st) == 0 && S_ISLNK(st.st_mode))
        return consph_fail(CONSPH_EINVAL,
                           "'%s' is a symbolic link, which would take the results out of the "
                           "output directory; allowed: a directory, or nothing, at that name",
                           dir);
    if (opt->resume && (rc = check_state(dir, state, dir))) return rc;
    return CONSPH_OK;
}

static void rows_init(study_rows *rows, const consph_study *s, const consph_study_options *opt,
                      const study_files *files, const char *dir)
{
    memset(rows, 0, sizeof *rows);
    rows->dir = dir;
    rows->t0 = consph_wtime();
    rows->print = opt->progress;
    rows->signals = opt->stopped_by != NULL;
    rows->tty = opt->progress && isatty(STDERR_FILENO) == 1;
    rows->model_per_work = NAN;
    const char *hook = getenv("CONSPH_TEST_STOP_AFTER_ROWS");
    rows->stop_after = hook ? atoi(hook) : 0;
    for (int k = 0; k < s->nfigs; ++k) {
        double work;
        rows->total += figure_rows(s, &s->figs[k], opt->quick, files, &work);
        rows->work_total += work;
    }
}

/* After the units ran elsewhere (ranks, worker processes) and kept their rows on disk: the report
 * pass reads every row back (one missing is run here) and writes the serial report, or, when a
 * unit was stopped (`stopped`, `done` rows in all), the partial README. */
static int report_kept_rows(const consph_study *s, const consph_study_options *opt,
                            const study_files *files, const char *dir, study_rows *rows,
                            int stopped, long done)
{
    int rc;
    if (stopped) {
        rows->stopped = stopped;
        rows->done = (int)done;
        return write_partial_readme(s, opt, files, dir, rows);
    }
    consph_study_options report = *opt;
    report.resume = 1;
    rows->done = 0;
    rows->work_done = 0.0;
    rows->print = 0;
    rows->shared_report = 1;
    rc = run_figures(s, &report, files, dir, rows);
    if (rc == CONSPH_OK && rows->stopped)
        rc = write_partial_readme(s, opt, files, dir, rows);
    else if (rc == CONSPH_OK)
        rc = study_write_readme(s, opt->quick, files != NULL, dir);
    return rc;
}

/* A study on K > 1 ranks (docs/mpi.md): every rank runs its share of the rows into the row
 * store that --resume reads (a shared file system: the one --out names); then rank 0 runs the
 * study once more as a resume of the rows kept, so that every report is written by the code, in
 * the order and from the rows of a serial study. `rc`: this rank's result of study_prepare. */
static int study_run_shared(const consph_study *s, const consph_study_options *opt,
                            const study_files *files, const char *dir, const char *state, int rc)
{
    const int rank = consph_par_rank();
    if ((rc = consph_par_agree(rc))) return rc;
    study_rows rows;
    rows_init(&rows, s, opt, files, dir);
    /* rank 0's progress lines count the rows it runs; no live line between ranks' output */
    rows.tty = 0;
    /* no packing ahead here: the ETA prices the rows' packings apart */
    if (opt->progress) rows_price_due(s, opt, files, dir, &rows);
    size_t created = 0;
    if (rank == 0) {
        rc = study_mkdir_p(dir, &created);
        if (rc == CONSPH_OK) consph_made_dir_register(dir, created);
        if (rc == CONSPH_OK && !opt->resume) {
            forget_kept(dir);
            rc = write_small(dir, STATE_NAME, state);
        }
    }
    if ((rc = consph_par_agree(rc)) == CONSPH_OK) {
        consph_study_options share = *opt;
        share.log = NULL;
        rows.share_rank = rank;
        rows.share_size = consph_par_size();
        rc = run_figures(s, &share, files, dir, &rows);
        rows.share_size = 0;
    }
    rc = consph_par_agree(rc);
    const int stopped = consph_par_max_int(rc == CONSPH_OK ? rows.stopped : 0);
    const long done = consph_par_sum_long(rows.done);
    if (rank == 0 && rc == CONSPH_OK)
        rc = report_kept_rows(s, opt, files, dir, &rows, stopped, done);
    if (rank == 0) {
        if (rc) study_remove_created(dir, created);
        consph_made_dir_unregister();
    }
    rc = consph_par_agree(rc);
    const int stopped_by =
        consph_par_bcast_int(rc == CONSPH_OK ? (stopped ? stopped : rows.stopped) : 0);
    if (opt->stopped_by) *opt->stopped_by = stopped_by;
    free(rows.due);
    return rc;
}

/* The study's folder and state before its workers (processes or threads) start; `created`
 * counts the folders made, for study_remove_created. */
static int workers_begin(const consph_study_options *opt, const char *dir, const char *state,
                         size_t *created)
{
    int rc = study_mkdir_p(dir, created);
    if (rc == CONSPH_OK) consph_made_dir_register(dir, *created);
    if (rc == CONSPH_OK && !opt->resume) {
        forget_kept(dir);
        rc = write_small(dir, STATE_NAME, state);
    }
    return rc;
}

/* After the workers: the report as a resume of their kept rows (rc the workers' status,
 * stopped their stop signal, done their rows), or the folders made removed on a failure. */
static int workers_end(const consph_study *s, const consph_study_options *opt,
                       const study_files *files, const char *dir, study_rows *rows, int rc,
                       int stopped, long done, size_t created)
{
    if (rc == CONSPH_OK && !stopped) stopped = consph_stop_requested();
    if (rc == CONSPH_OK) rc = report_kept_rows(s, opt, files, dir, rows, stopped, done);
    if (rc) study_remove_created(dir, created);
    consph_made_dir_unregister();
    if (opt->stopped_by)
        *opt->stopped_by = rc == CONSPH_OK ? (stopped ? stopped : rows->stopped) : 0;
    return rc;
}

/* What a worker of study_run_jobs hands back through its pipe. */
typedef struct job_result {
    int rc, stopped, done;
    char msg[1024];
} job_result;

/* A study on `jobs` forked worker processes (docs/studies.md): the workers claim the units as
 * they meet them (unit_mine) and keep their rows, then this process writes the report as a
 * resume of them, as study_run_shared does. Processes rather than threads: every global of the
 * library stays private to one row. Workers are in their own process group, so a SIGINT of the
 * terminal reaches this process alone, which passes its stop request on once. */
static int study_run_jobs(const consph_study *s, const consph_study_options *opt,
                          const study_files *files, const char *dir, const char *state,
                          study_rows *prepared, int jobs)
{
    size_t created = 0;
    study_rows rows = *prepared;
    /* on a terminal worker 0 alone keeps the live line, counting every worker's rows */
    const int tty = rows.tty;
    rows.tty = 0;
    /* a unit holds at least one row: one claim per row is enough */
    const size_t shared_size = sizeof(study_shared) + (size_t)rows.total + 1;
    study_shared *sh =
        mmap(NULL, shared_size, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
    if (sh == MAP_FAILED)
        return consph_fail(CONSPH_ENOMEM, "--jobs: cannot map %zu bytes shared by the workers",
                           shared_size);
    memset(sh, 0, shared_size);
    sh->nunits = rows.total + 1;
    int rc = workers_begin(opt, dir, state, &created);
    pid_t pid[256];
    int fd[256], started = 0;
    const int threads = consph_num_threads() / jobs > 1 ? consph_num_threads() / jobs : 1;
    fflush(NULL);
    for (int k = 0; rc == CONSPH_OK && k < jobs; ++k) {
        int p[2];
        if (pipe(p) != 0) {
            rc = consph_fail(CONSPH_EIO, "--jobs: cannot make a pipe for worker %d", k);
            break;
        }
        pid[k] = fork();
        if (pid[k] < 0) {
            close(p[0]);
            close(p[1]);
            rc = consph_fail(CONSPH_EIO, "--jobs: cannot start worker %d of %d", k, jobs);
            break;
        }
        if (pid[k] == 0) {
            setpgid(0, 0);
            close(p[0]);
            consph_set_num_threads(threads);
            consph_study_options share = *opt;
            share.log = NULL;
            rows.share_rank = k;
            rows.share_size = jobs;
            rows.shared = sh;
            rows.tty = tty && k == 0;
            rows.print = opt->progress && (!tty || k == 0);
            job_result res;
            memset(&res, 0, sizeof res);
            res.rc = run_figures(s, &share, files, dir, &rows);
            if (rows.tty) fprintf(stderr, "\r\033[K");
            res.stopped = rows.stopped;
            res.done = rows.done;
            if (res.rc) snprintf(res.msg, sizeof res.msg, "%s", consph_last_error());
            fflush(NULL);
            const int sent = write(p[1], &res, sizeof res) == (ssize_t)sizeof res;
            _exit(sent && res.rc == CONSPH_OK ? 0 : 1);
        }
        close(p[1]);
        fd[k] = p[0];
        started++;
    }
    /* Polled rather than waited for, so that a stop request here reaches every worker, and a
     * worker that fails or is killed stops the others, as a serial study stops at its first
     * failure. */
    int alive = started, forwarded = 0, stopped = 0, failed = -1, worker_failed = 0;
    long done = 0;
    int status[256];
    for (int k = 0; k < started; ++k) status[k] = -1;
    while (alive > 0) {
        const int sig = consph_stop_requested();
        if ((sig || rc || worker_failed) && !forwarded) {
            forwarded = 1;
            for (int k = 0; k < started; ++k)
                if (status[k] == -1) kill(pid[k], sig ? sig : SIGTERM);
        }
        int any = 0;
        for (int k = 0; k < started; ++k) {
            if (status[k] != -1) continue;
            int st;
            if (waitpid(pid[k], &st, WNOHANG) != pid[k]) continue;
            status[k] = st;
            worker_failed |= !WIFEXITED(st) || WEXITSTATUS(st) != 0;
            any = 1;
            alive--;
        }
        if (!any) nanosleep(&(struct timespec){0, 20000000}, NULL);
    }
    for (int k = 0; k < started; ++k) {
        job_result res;
        memset(&res, 0, sizeof res);
        const int got = read(fd[k], &res, sizeof res) == (ssize_t)sizeof res;
        close(fd[k]);
        if (WIFSIGNALED(status[k]) && !got) {
            res.rc = CONSPH_EIO;
            snprintf(res.msg, sizeof res.msg,
                     "--jobs: worker %d of %d (pid %ld) ended by signal %d", k, jobs, (long)pid[k],
                     WTERMSIG(status[k]));
        } else if (!got) {
            res.rc = CONSPH_EIO;
            snprintf(res.msg, sizeof res.msg,
                     "--jobs: worker %d of %d (pid %ld) ended with status %d and no result", k,
                     jobs, (long)pid[k], WIFEXITED(status[k]) ? WEXITSTATUS(status[k]) : -1);
        }
        /* The first worker's failure is reported, as a serial study reports its first. */
        if (res.rc && failed < 0 && rc == CONSPH_OK) {
            failed = k;
            rc = consph_fail(res.rc, "%s", res.msg);
        }
        if (res.stopped > stopped) stopped = res.stopped;
        done += res.done;
    }
    munmap(sh, shared_size);
    return workers_end(s, opt, files, dir, &rows, rc, stopped, done, created);
}

/* A worker of study_run_threads: its rows, and what it hands back. */
typedef struct row_thread {
    const consph_study *s;
    const consph_study_options *opt;
    const study_files *files;
    const char *dir;
    study_rows rows;
    int threads;
    job_result res;
} row_thread;

static void *row_thread_main(void *arg)
{
    row_thread *w = arg;
    consph_set_num_threads(w->threads);
    consph_study_options share = *w->opt;
    share.log = NULL;
    w->res.rc = run_figures(w->s, &share, w->files, w->dir, &w->rows);
    w->res.stopped = w->rows.stopped;
    w->res.done = w->rows.done;
    if (w->res.rc) {
        snprintf(w->res.msg, sizeof w->res.msg, "%s", consph_last_error());
        /* as a failed worker process stops the others: no thread starts another unit */
        __atomic_store_n(&w->rows.shared->abandon, 1, __ATOMIC_RELEASE);
    }
    return NULL;
}

/* study_run_jobs on threads of this process: the rows of a study on the GPU, which worker
 * processes cannot share at once (a CUDA context is one process's, and kernels of different
 * processes do not run at the same time without NVIDIA's MPS daemon), while threads put their
 * rows' steps on streams of their own (src/gpu/cuda.cu) that the device runs side by side: the
 * small resolutions' rows each fill a fraction of it. Every row's run is its own solver, and
 * what the rows share of the library is atomic or per thread (its error text, the GPU
 * backend's, the outputs' temporary files, the passes' statistics counters). The threads claim
 * units as the processes do and keep their rows; this thread then writes the report as a resume of
 * them. A stop request reaches every thread's run (CONSPH_RUN_SIGNALS_WATCH: the handlers the
 * caller installed, watched, never reinstalled by a row); one thread's failure stops the others at
 * their next unit. Progress comes as a line per finished row, not a live line. */
static int study_run_threads(const consph_study *s, const consph_study_options *opt,
                             const study_files *files, const char *dir, const char *state,
                             study_rows *prepared, int jobs)
{
    size_t created = 0;
    study_rows rows = *prepared;
    rows.tty = 0;
    study_shared *sh = calloc(1, sizeof(study_shared) + (size_t)rows.total + 1);
    row_thread *w = calloc((size_t)jobs, sizeof *w);
    pthread_t *tid = calloc((size_t)jobs, sizeof *tid);
    if (!sh || !w || !tid) {
        free(sh);
        free(w);
        free(tid);
        return consph_fail(CONSPH_ENOMEM, "--jobs: out of memory");
    }
    sh->nunits = rows.total + 1;
    int rc = workers_begin(opt, dir, state, &created);
    const int threads = consph_num_threads() / jobs > 1 ? consph_num_threads() / jobs : 1;
    int started = 0;
    fflush(NULL);
    for (int k = 0; rc == CONSPH_OK && k < jobs; ++k) {
        w[k] = (row_thread){s, opt, files, dir, rows, threads, {0}};
        w[k].rows.share_rank = k;
        w[k].rows.share_size = jobs;
        w[k].rows.shared = sh;
        w[k].rows.print = opt->progress;
        if (rows.signals) w[k].rows.signals = CONSPH_RUN_SIGNALS_WATCH;
        /* the test hook's SIGINT once for the process: a second would end it (io/stop.c) */
        if (k > 0) w[k].rows.stop_after = 0;
        /* the layouts still to pack, which each thread marks as it finds them made */
        w[k].rows.due = NULL;
        if (rows.ndue > 0) {
            w[k].rows.due = malloc((size_t)rows.ndue * sizeof *rows.due);
            if (!w[k].rows.due) {
                rc = consph_fail(CONSPH_ENOMEM, "--jobs: out of memory");
                __atomic_store_n(&sh->abandon, 1, __ATOMIC_RELEASE);
                break;
            }
            memcpy(w[k].rows.due, rows.due, (size_t)rows.ndue * sizeof *rows.due);
        }
        if (pthread_create(&tid[k], NULL, row_thread_main, &w[k]) != 0) {
            rc = consph_fail(CONSPH_EIO, "--jobs: cannot start thread %d of %d", k, jobs);
            __atomic_store_n(&sh->abandon, 1, __ATOMIC_RELEASE);
            free(w[k].rows.due);
            break;
        }
        started++;
    }
    int stopped = 0, failed = -1;
    long done = 0;
    for (int k = 0; k < started; ++k) {
        pthread_join(tid[k], NULL);
        /* the first thread's failure is reported, as a serial study reports its first */
        if (w[k].res.rc && failed < 0 && rc == CONSPH_OK) {
            failed = k;
            rc = consph_fail(w[k].res.rc, "%s", w[k].res.msg);
        }
        if (w[k].res.stopped > stopped) stopped = w[k].res.stopped;
        done += w[k].res.done;
        free(w[k].rows.due);
    }
    free(sh);
    free(w);
    free(tid);
    return workers_end(s, opt, files, dir, &rows, rc, stopped, done, created);
}

/* ---- the device of the solver rows ---- */

const char *consph_study_device_name(int device)
{
    return device == CONSPH_STUDY_DEVICE_GPU    ? "gpu"
           : device == CONSPH_STUDY_DEVICE_AUTO ? "auto"
                                                : "cpu";
}

int consph_study_device_of(const consph_study *s, int asked)
{
    if (asked != CONSPH_STUDY_DEVICE_DEFAULT) return asked;
    const char *v = study_get(s, NULL, NULL, "device");
    if (!v) return CONSPH_STUDY_DEVICE_DEFAULT;
    return !strcmp(v, "gpu")    ? CONSPH_STUDY_DEVICE_GPU
           : !strcmp(v, "auto") ? CONSPH_STUDY_DEVICE_AUTO
                                : CONSPH_STUDY_DEVICE_CPU;
}

int consph_study_device_check(const consph_study *s, int quick, int device)
{
    if (device != CONSPH_STUDY_DEVICE_GPU) return CONSPH_OK;
    char why[256];
    if (!consph_gpu_available(why, sizeof why))
        return consph_fail(CONSPH_EINVAL, "--device gpu: %s", why);
    char rows[3000];
    size_t len = 0;
    int bad = 0;
    for (int k = 0; k < s->nfigs; ++k)
        if (study_kind_of(s, &s->figs[k]) == &study_kind_run)
            study_run_gpu_refusals(s, &s->figs[k], quick, rows, sizeof rows, &len, &bad);
    if (!bad) return CONSPH_OK;
    return consph_fail(CONSPH_EINVAL,
                       "--device gpu: %d series cannot run on the GPU (use --device auto to run "
                       "them on the CPU):%s",
                       bad, rows);
}

/* A GPU is one device: the ranks of MPI would each put their rows on it at once (--jobs runs
 * threads there, study_run_threads). */
static int device_sharing(const consph_study_options *opt)
{
    if (opt->device != CONSPH_STUDY_DEVICE_GPU && opt->device != CONSPH_STUDY_DEVICE_AUTO)
        return CONSPH_OK;
    if (consph_par_size() > 1)
        return consph_fail(CONSPH_EINVAL,
                           "--device %s runs the study on one process with one GPU: launched on "
                           "%d MPI ranks, run it without mpirun (or with -np 1)",
                           consph_study_device_name(opt->device), consph_par_size());
    return CONSPH_OK;
}

/* ---- the packed layouts, made before the workers start ---- */

/* A packed layout that the study's rows read and the cache does not hold yet, and its price by
 * the packing model (study_packing_seconds). */
typedef struct packing_entry {
    consph_layout_params lp;
    char key[512];
    char path[4352]; /* "" where the cache has no file name for it */
    double n, seconds;
} packing_entry;

typedef struct packing_list {
    packing_entry *e;
    int n, cap;
} packing_list;

static void packing_add(const consph_layout_params *lp, void *ctx)
{
    packing_list *l = ctx;
    if (lp->kind != CONSPH_LAYOUT_PACKED && lp->kind != CONSPH_LAYOUT_PACKED_POLISHED) return;
    char key[512], path[4352];
    if (consph_layout_cache_key(lp, key, sizeof key) != CONSPH_OK) return;
    for (int q = 0; q < l->n; ++q)
        if (!strcmp(l->e[q].key, key)) return;
    if (consph_layout_cache_path(lp, path, sizeof path) != CONSPH_OK)
        path[0] = '\0';
    else if (access(path, R_OK) == 0)
        return;
    if (l->n == l->cap) {
        const int cap = l->cap ? 2 * l->cap : 16;
        packing_entry *e = realloc(l->e, (size_t)cap * sizeof *e);
        /* out of memory: the rows pack what is not listed, as they would anyway */
        if (!e) return;
        l->e = e;
        l->cap = cap;
    }
    packing_entry *e = &l->e[l->n++];
    e->lp = *lp;
    snprintf(e->key, sizeof e->key, "%s", key);
    snprintf(e->path, sizeof e->path, "%s", path);
    e->n = 1.0;
    for (int a = 0; a < lp->dim; ++a) e->n *= (double)lp->nx[a];
    e->seconds = 0.0;
}

static int by_particles_descending(const void *a, const void *b)
{
    const packing_entry *x = a, *y = b;
    return x->n < y->n ? 1 : x->n > y->n ? -1 : strcmp(x->key, y->key);
}

/* The layouts every operator series reads (as study_estimate_plans counts them: at nx_fixed
 * across an hdx sweep) and every solver row reads (study_run_layouts). Particle files replace
 * the operator series' layouts. */
static void packing_figure(const consph_study *s, const study_figure *f, int quick,
                           const study_files *files, packing_list *l)
{
    const study_kind *kind = study_kind_of(s, f);
    if (kind == &study_kind_run) {
        study_run_layouts(s, f, quick, packing_add, l);
        return;
    }
    if (files ||
        (kind != &study_kind_approx && kind != &study_kind_m0 && kind != &study_kind_cauchy))
        return;
    for (int r = 0; r < f->nseries; ++r) {
        series_plan pl;
        if (study_plan_build(s, f, &f->series[r], quick, &pl) != CONSPH_OK) continue;
        for (int j = 0; j < pl.nvalues; ++j) {
            const consph_layout_params lp = study_plan_row_layout(&pl, j);
            packing_add(&lp, l);
        }
    }
}

/* The figures a resumed study keeps (their .done mark): 1 in skip[k]; none without --resume. */
static unsigned char *figures_kept(const consph_study *s, const consph_study_options *opt,
                                   const char *dir)
{
    unsigned char *skip = calloc((size_t)s->nfigs + 1, 1);
    for (int k = 0; skip && opt->resume && k < s->nfigs; ++k) {
        char done[STUDY_PATH_MAX];
        skip[k] = figure_done_path(done, dir, &s->figs[k]) == CONSPH_OK && access(done, F_OK) == 0;
    }
    return skip;
}

/* The packed layouts the rows will read that the cache lacks, largest first; priced by the
 * packing model when `priced`. */
static void packing_list_build(const consph_study *s, const consph_study_options *opt,
                               const study_files *files, const unsigned char *skip, int priced,
                               packing_list *l)
{
    for (int k = 0; k < s->nfigs; ++k)
        if (!skip || !skip[k]) packing_figure(s, &s->figs[k], opt->quick, files, l);
    if (l->n > 1) qsort(l->e, (size_t)l->n, sizeof *l->e, by_particles_descending);
    for (int q = 0; priced && q < l->n; ++q) l->e[q].seconds = study_packing_seconds(&l->e[q].lp);
}

/* The rows' seconds per unit of their work by the estimate's model, their packing left out (the
 * layouts are priced one by one): the ETA's rate before a row has given one. The figures a
 * resumed study keeps are left out too. NAN when the calibration fails. */
static double rows_model_rate(const consph_study *s, const consph_study_options *opt,
                              const study_files *files, const unsigned char *skip)
{
    double work = 0.0;
    for (int k = 0; k < s->nfigs; ++k) {
        double w;
        if (!skip || !skip[k]) {
            figure_rows(s, &s->figs[k], opt->quick, files, &w);
            work += w;
        }
    }
    /* Its calibration runs make their small layouts without the cache, which then holds the
     * rows' layouts alone, as it would without the model. */
    char cache[4096] = "";
    const char *c = consph_layout_cache_get();
    if (c) snprintf(cache, sizeof cache, "%s", c);
    consph_layout_cache_set(NULL);
    packing_priced_apart = 1;
    const double seconds = estimate_figures(s, opt->quick, files, skip);
    packing_priced_apart = 0;
    if (cache[0]) consph_layout_cache_set(cache);
    return work > 0.0 && seconds >= 0.0 ? seconds / work : NAN;
}

/* The layouts of the list whose files the cache still lacks become the rows' due packings: the
 * rows' ETA adds their price, and a row during which one is made is not a rate of its work. */
static void rows_take_due(study_rows *rows, const packing_list *l)
{
    int n = 0;
    for (int q = 0; q < l->n; ++q) n += l->e[q].path[0] && access(l->e[q].path, R_OK) != 0;
    if (n == 0 || !(rows->due = calloc((size_t)n, sizeof *rows->due))) return;
    /* a file removed since the count (the user clearing the cache) must not write past it */
    for (int q = 0; q < l->n && rows->ndue < n; ++q) {
        if (!l->e[q].path[0] || access(l->e[q].path, R_OK) == 0) continue;
        study_packing_due *d = &rows->due[rows->ndue++];
        snprintf(d->path, sizeof d->path, "%s", l->e[q].path);
        d->seconds = l->e[q].seconds;
    }
}

/* The rows' due packings where none is made ahead (MPI ranks), priced by the packing model. */
static void rows_price_due(const consph_study *s, const consph_study_options *opt,
                           const study_files *files, const char *dir, study_rows *rows)
{
    packing_list l = {NULL, 0, 0};
    unsigned char *skip = figures_kept(s, opt, dir);
    packing_list_build(s, opt, files, skip, 1, &l);
    /* rows that pack leave the rate; without the model's, every row of an nx sweep would
     * show no ETA at all */
    if (l.n > 0 && rows->print) rows->model_per_work = rows_model_rate(s, opt, files, skip);
    rows_take_due(rows, &l);
    free(skip);
    free(l.e);
}

/* The packing ahead's progress: layout q of the list, packing since q_t0. */
typedef struct packing_clock {
    pthread_mutex_t lock;
    pthread_cond_t wake;
    int stop;
    const packing_list *l;
    const study_rows *rows;
    int q;
    double q_t0;
    int threads; /* the packing's, read on the calling thread (OpenMP's count is per thread) */
} packing_clock;

/* What is left of a packing whose model price has run out: it is still running. */
#define PACKING_ETA_FLOOR 1.0
/* Seconds between redraws of the live line during a packing. */
#define PACKING_REDRAW 0.5

/* The whole study's seconds to go: the layouts after q at the model's price, layout q at its
 * price less the time it has run (at least PACKING_ETA_FLOOR), then the rows at the model's
 * rate (study_rows_eta, which adds a layout whose packing ahead failed). */
static double packing_eta(const packing_clock *c, double now)
{
    double left = study_rows_eta(c->rows);
    for (int q = c->q + 1; q < c->l->n; ++q) left += c->l->e[q].seconds;
    return left + fmax(c->l->e[c->q].seconds - (now - c->q_t0), PACKING_ETA_FLOOR);
}

static void packing_line(const packing_clock *c)
{
    const consph_layout_params *lp = &c->l->e[c->q].lp;
    const double now = consph_wtime();
    const int threads = c->threads;
    char el[32], eta[32];
    consph_study_duration_text(now - c->rows->t0, el, sizeof el);
    consph_study_duration_text(packing_eta(c, now), eta, sizeof eta);
    if (c->rows->tty)
        fprintf(stderr,
                "\rpacking %d/%d  %s, dim %d, nx=%zu, %d thread%s  elapsed %s  ETA %s\033[K",
                c->q + 1, c->l->n, consph_layout_name(lp->kind), lp->dim, lp->nx[0], threads,
                threads == 1 ? "" : "s", el, eta);
    else
        fprintf(stderr,
                "study: packing layout %s dim %d nx %zu (%d of %d, %d thread%s) before the rows "
                "start (elapsed %s, ETA %s)\n",
                consph_layout_name(lp->kind), lp->dim, lp->nx[0], c->q + 1, c->l->n, threads,
                threads == 1 ? "" : "s", el, eta);
    fflush(stderr);
}

/* The live line's redraws while a layout packs (consph_layout_generate reports no progress of
 * its own): a thread that wakes every PACKING_REDRAW seconds until told to stop. */
static void *packing_redraw(void *arg)
{
    packing_clock *c = arg;
    pthread_mutex_lock(&c->lock);
    while (!c->stop) {
        struct timespec until;
        clock_gettime(CLOCK_MONOTONIC, &until); /* a clock set back must not stop the redraws */
        until.tv_nsec += (long)(PACKING_REDRAW * 1e9);
        until.tv_sec += until.tv_nsec / 1000000000L;
        until.tv_nsec %= 1000000000L;
        pthread_cond_timedwait(&c->wake, &c->lock, &until);
        if (!c->stop) packing_line(c);
    }
    pthread_mutex_unlock(&c->lock);
    return NULL;
}

/* Before the rows (and the worker processes) start, this process packs every packed layout the
 * rows will read that the cache lacks, largest first, one after the other on all its threads,
 * through the cache (consph_layout_generate), so that the rows read the files it writes. Without
 * it the first row that needs a large layout packs it on its worker's one thread while the other
 * workers, whose rows need the same layout, wait on the cache's lock; and alone, the progress
 * line's ETA (remaining pairs at the rows' rate so far) would count a row's packing as the cost
 * of its pairs. The figures that --resume keeps need none. A layout that fails here is left to its
 * rows, which report the failure as they would have. A stop request ends the list after the layout
 * being packed (packing is not interruptible); the workers then stop at once and the partial report
 * is written. With progress, each layout's line (a live one on a terminal, redrawn by a thread)
 * has the whole study's ETA: the packings left by the packing model, then the rows by the
 * estimate's (rows_model_rate, calibrated here first). */
static void pack_ahead(const consph_study *s, const consph_study_options *opt,
                       const study_files *files, const char *dir, study_rows *rows)
{
    packing_list l = {NULL, 0, 0};
    unsigned char *skip = figures_kept(s, opt, dir);
    packing_list_build(s, opt, files, skip, 0, &l);
    if (opt->progress && l.n > 0) {
        rows->model_per_work = rows_model_rate(s, opt, files, skip);
        /* the calibration may have packed a small one; priced once it is left out */
        l.n = 0;
        packing_list_build(s, opt, files, skip, 1, &l);
    }
    free(skip);
    packing_clock c = {.l = &l, .rows = rows, .threads = consph_num_threads()};
    pthread_t redraw;
    int redrawing = 0;
    if (rows->tty && l.n > 0 && pthread_mutex_init(&c.lock, NULL) == 0) {
        pthread_condattr_t ca;
        int made = 0;
        if (pthread_condattr_init(&ca) == 0) {
            made = pthread_condattr_setclock(&ca, CLOCK_MONOTONIC) == 0 &&
                   pthread_cond_init(&c.wake, &ca) == 0;
            pthread_condattr_destroy(&ca);
        }
        if (made) {
            /* the stop requests are this thread's to take */
            sigset_t all, old;
            sigfillset(&all);
            pthread_sigmask(SIG_BLOCK, &all, &old);
            redrawing = pthread_create(&redraw, NULL, packing_redraw, &c) == 0;
            pthread_sigmask(SIG_SETMASK, &old, NULL);
            if (!redrawing) pthread_cond_destroy(&c.wake);
        }
        if (!redrawing) pthread_mutex_destroy(&c.lock);
    }
    const double t0 = consph_wtime();
    int q = 0;
    for (; q < l.n && !consph_stop_requested(); ++q) {
        if (redrawing) pthread_mutex_lock(&c.lock);
        c.q = q;
        c.q_t0 = consph_wtime();
        if (opt->progress) packing_line(&c);
        if (redrawing) pthread_mutex_unlock(&c.lock);
        consph_particles p;
        if (consph_layout_generate(&l.e[q].lp, &p, NULL) == CONSPH_OK) consph_particles_free(&p);
    }
    if (redrawing) {
        pthread_mutex_lock(&c.lock);
        c.stop = 1;
        pthread_cond_signal(&c.wake);
        pthread_mutex_unlock(&c.lock);
        pthread_join(redraw, NULL);
        pthread_cond_destroy(&c.wake);
        pthread_mutex_destroy(&c.lock);
    }
    if (opt->progress) rows_take_due(rows, &l);
    if (opt->progress && l.n > 0 && q == l.n && !consph_stop_requested()) {
        char took[32], el[32], eta[32];
        consph_study_duration_text(consph_wtime() - t0, took, sizeof took);
        consph_study_duration_text(consph_wtime() - rows->t0, el, sizeof el);
        consph_study_duration_text(study_rows_eta(rows), eta, sizeof eta);
        fprintf(stderr,
                "%sstudy: packed %d layout%s ahead in %s; the rows start (elapsed %s, ETA %s)\n",
                rows->tty ? "\r\033[K" : "", l.n, l.n == 1 ? "" : "s", took, el, eta);
        fflush(stderr);
    } else if (rows->tty && l.n > 0) {
        fprintf(stderr, "\r\033[K");
        fflush(stderr);
    }
    free(l.e);
}

static int study_run_with_cache(const consph_study *s, const consph_study_options *asked,
                                const study_files *files, int cached)
{
    char dir[STUDY_PATH_MAX], state[512];
    consph_study_options resolved = *asked;
    const consph_study_options *opt = &resolved;
    /* a bad key `device` is study_prepare's to report (study_validate) */
    resolved.device = consph_study_device_of(s, asked->device);
    int rc = device_sharing(opt);
    if (rc == CONSPH_OK) rc = consph_study_device_check(s, opt->quick, opt->device);
    if (rc == CONSPH_OK) rc = study_prepare(s, opt, files, dir, state, sizeof state);
    if (consph_par_size() > 1) return study_run_shared(s, opt, files, dir, state, rc);
    if (rc) return rc;
    size_t created = 0;
    study_rows rows;
    rows_init(&rows, s, opt, files, dir);
    /* no more workers than units (a unit holds at least one row); one runs here */
    const int jobs = opt->jobs < rows.total ? opt->jobs : rows.total;
    /* tests: the rows pack their own layouts, as on MPI ranks (the ETA prices them apart) */
    const char *no_ahead = getenv("CONSPH_TEST_NO_PACK_AHEAD");
    if (no_ahead && atoi(no_ahead) == 1) {
        if (opt->progress) rows_price_due(s, opt, files, dir, &rows);
    } else if (cached) {
        pack_ahead(s, opt, files, dir, &rows);
    }
    /* Stopped while packing: no workers (they would inherit the stop request and take the one
     * passed on as a second signal); the serial run below stops before its first row and writes
     * the partial report. */
    if (jobs > 1 && !consph_stop_requested()) {
        const int gpu =
            opt->device == CONSPH_STUDY_DEVICE_GPU || opt->device == CONSPH_STUDY_DEVICE_AUTO;
        rc = gpu ? study_run_threads(s, opt, files, dir, state, &rows, jobs)
                 : study_run_jobs(s, opt, files, dir, state, &rows, jobs);
        free(rows.due);
        return rc;
    }
    rc = study_mkdir_p(dir, &created);
    /* A signal removes what was made as a failure does (study_remove_created). */
    if (rc == CONSPH_OK) consph_made_dir_register(dir, created);
    if (rc == CONSPH_OK && !opt->resume) {
        forget_kept(dir);
        rc = write_small(dir, STATE_NAME, state);
    }
    if (rc == CONSPH_OK) rc = run_figures(s, opt, files, dir, &rows);
    if (rows.tty) {
        fprintf(stderr, "\r\033[K");
        consph_progress_prefix(NULL);
    }
    if (rc == CONSPH_OK && rows.stopped)
        rc = write_partial_readme(s, opt, files, dir, &rows);
    else if (rc == CONSPH_OK)
        rc = study_write_readme(s, opt->quick, files != NULL, dir);
    if (rc) study_remove_created(dir, created);
    free(rows.due);
    consph_made_dir_unregister();
    if (opt->stopped_by) *opt->stopped_by = rc == CONSPH_OK ? rows.stopped : 0;
    return rc;
}

/* Without a cache of packed layouts (--no-cache, or no cache directory) every solver row would
 * pack its own layout: 001-table9 --quick packs 20², 30² and 40² for four series, twelve
 * packings where three make the same positions. The study then keeps its packed layouts in a
 * cache of its own, a fresh temporary directory that it removes at the end, so that its rows and
 * worker processes (which inherit it) pack each layout once, and the user's cache is neither
 * read nor written. */
static void remove_private_cache(const char *dir)
{
    study_remove_files(dir);
    rmdir(dir);
}

static int study_run(const consph_study *s, const consph_study_options *asked,
                     const study_files *files)
{
    char priv[STUDY_PATH_MAX] = "";
    const int user_cache = consph_layout_cache_get() != NULL;
    if (!user_cache) {
        const char *tmp = getenv("TMPDIR");
        if (!tmp || tmp[0] != '/') tmp = "/tmp";
        /* where none can be made, the rows pack their own as before */
        if ((size_t)snprintf(priv, sizeof priv, "%s/consph-layouts-XXXXXX", tmp) >= sizeof priv ||
            !mkdtemp(priv))
            priv[0] = '\0';
        else if (consph_layout_cache_set(priv) != CONSPH_OK) {
            rmdir(priv);
            priv[0] = '\0';
        }
    }
    /* --no-cache: the rows share the private cache, and the layouts are packed ahead into it as
     * into the user's (pack_ahead); none where it could not be made */
    const int rc = study_run_with_cache(s, asked, files, user_cache || priv[0]);
    if (priv[0]) {
        consph_layout_cache_set(NULL);
        remove_private_cache(priv);
    }
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
