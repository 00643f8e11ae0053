/* Study figures of kind `heat` (docs/studies.md, docs/heat.md): 002's heat-conduction runs
 * (include/consph/heat.h), one series per (Laplacian, η), an nx sweep each. Errors are reported
 * against Δ = 1/(nx - 1) with the fitted order in Δ of L2, L∞ and EC; a figure with
 * `report = time` instead compares the run times of its series with the first one (002 §6.3). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "consph/heat.h"
#include "consph/io.h"
#include "study/kinds/kinds.h"

typedef struct heat_plan {
    consph_heat_params prm;
    int nvalues;
    double nx[STUDY_MAX_SWEEP];
} heat_plan;

typedef struct heat_row {
    consph_heat_summary sum;
    double total; /* set-up plus time steps, the best of the timed repeats */
} heat_row;

static int heat_plan_build(const consph_study *s, const study_figure *f, const study_series *r,
                           int quick, heat_plan *pl)
{
    memset(pl, 0, sizeof *pl);
    consph_heat_params_default(&pl->prm);
    const char *lap = study_get(s, f, r, "laplacian"), *walls = study_get(s, f, r, "walls");
    if (lap && consph_heat_lap_lookup(lap, &pl->prm.laplacian) != CONSPH_OK)
        return study_key_error(s, f, r, "laplacian", "unknown value; allowed: s3, s4");
    if (walls && consph_heat_walls_lookup(walls, &pl->prm.walls) != CONSPH_OK)
        return study_key_error(s, f, r, "walls", "unknown value; allowed: sin, linear");
    double seed;
    int rc;
    if ((rc = study_get_double(s, f, r, "hdx", 2.0, 1.0, 10.0, &pl->prm.eta))) return rc;
    if ((rc = study_get_double(s, f, r, "eps", 0.0, 0.0, 1.0, &pl->prm.eps))) return rc;
    if ((rc = study_get_double(s, f, r, "seed", 1, 0, 1e15, &seed))) return rc;
    if ((rc = study_get_double(s, f, r, "tf", 0.1, 1e-9, 1e3, &pl->prm.tf))) return rc;
    pl->prm.seed = (unsigned long)seed;
    if (study_series_sets(s, f, r, "seed") && !(pl->prm.eps > 0.0))
        return study_key_error(s, f, r, "seed",
                               "does nothing without eps > 0 (it draws only the perturbation)");
    if (quick && (rc = study_get_list(s, f, r, "quick.nx", 4, 20000, pl->nx, &pl->nvalues)))
        return rc;
    if (pl->nvalues == 0 && (rc = study_get_list(s, f, r, "nx", 4, 20000, pl->nx, &pl->nvalues)))
        return rc;
    if (pl->nvalues == 0) return study_key_error(s, f, r, "nx", "no resolutions given");
    return CONSPH_OK;
}

/* DIR/ID.EXT opened for an atomic write. */
static int run_one(const heat_plan *pl, int j, int repeats, heat_row *row)
{
    consph_heat_params prm = pl->prm;
    prm.nx = (int)pl->nx[j];
    row->total = INFINITY;
    for (int k = 0; k < repeats; ++k) {
        consph_heat *h = NULL;
        consph_heat_summary sum;
        int st = consph_heat_create(&h, &prm);
        if (st == CONSPH_OK) st = consph_heat_run(h, NULL, 0, &sum);
        consph_heat_free(h);
        if (st != CONSPH_OK) return st;
        /* the repeats differ in their times only: keep the fastest */
        if (sum.seconds + sum.setup_seconds < row->total) {
            row->sum = sum;
            row->total = sum.seconds + sum.setup_seconds;
        }
    }
    return CONSPH_OK;
}

/* Every paper.* key of a series, "key = value; ..." */
static void paper_text(const study_figure *f, const study_series *r, char *buf, size_t size)
{
    buf[0] = '\0';
    const study_kvlist *lists[2] = {&f->keys, &r->keys};
    for (int l = 0; l < 2; ++l)
        for (int k = 0; k < lists[l]->n; ++k) {
            const study_kv *kv = &lists[l]->items[k];
            if (strncmp(kv->key, "paper.", 6) != 0) continue;
            size_t len = strlen(buf);
            snprintf(buf + len, size - len, "%s%s", len ? "; " : "", kv->value);
        }
}

static int write_csv(const study_figure *f, const heat_plan *plans,
                     heat_row (*rows)[STUDY_MAX_SWEEP], const char *dir)
{
    char label[256];
    consph_outfile of;
    int rc = study_open_output(&of, dir, f->id, ".csv");
    if (rc) return rc;
    fprintf(of.fp, "series,laplacian,walls,eta,eps,seed,nx,n,delta,h,d_min,steps,dt,t,l2,linf,ec,"
                   "seconds,setup_seconds,fallbacks\n");
    for (int k = 0; k < f->nseries; ++k)
        for (int j = 0; j < plans[k].nvalues; ++j) {
            const consph_heat_summary *w = &rows[k][j].sum;
            fprintf(of.fp,
                    "%s,%s,%s,%g,%g,%lu,%d,%zu,%.10g,%.10g,%.10g,%ld,%.10g,%.10g,%.6e,%.6e,%.6e,"
                    "%.6g,%.6g,%zu\n",
                    study_csv_label(f->series[k].label, label, sizeof label), w->laplacian,
                    w->walls, w->eta, w->eps, plans[k].prm.seed, w->nx, w->n, w->delta, w->h,
                    w->d_min, w->steps, w->dt, w->t, w->l2, w->linf, w->ec, w->seconds,
                    w->setup_seconds, w->fallbacks);
        }
    return consph_outfile_commit(&of);
}

/* Three panels (L2, L∞, EC against Δ), one line per series; data in ID.dat, one block each. */
static int write_plot(const consph_study *s, const study_figure *f, const heat_plan *plans,
                      heat_row (*rows)[STUDY_MAX_SWEEP], int quick, const char *dir)
{
    consph_outfile of;
    int rc = study_open_output(&of, dir, f->id, ".dat");
    if (rc) return rc;
    for (int k = 0; k < f->nseries; ++k) {
        fprintf(of.fp, "# %s: delta l2 linf ec\n", f->series[k].label);
        for (int j = 0; j < plans[k].nvalues; ++j) {
            const consph_heat_summary *w = &rows[k][j].sum;
            fprintf(of.fp, "%.10g %.6e %.6e %.6e\n", w->delta, w->l2, w->linf, w->ec);
        }
        fprintf(of.fp, "\n\n");
    }
    if ((rc = consph_outfile_commit(&of))) return rc;
    if ((rc = study_open_output(&of, dir, f->id, ".gp"))) return rc;
    FILE *o = of.fp;
    const char *title = study_get(s, f, NULL, "title");
    char ran[512];
    size_t len = (size_t)snprintf(ran, sizeof ran, "ran: t_f = %g, ", plans[0].prm.tf);
    study_list_text(ran, sizeof ran, &len, "nx", plans[0].nx, plans[0].nvalues);
    double full[STUDY_MAX_SWEEP];
    int nfull = 0;
    if (len < sizeof ran)
        len +=
            (size_t)snprintf(ran + len, sizeof ran - len, " (%s", quick ? "quick" : "full study");
    int same = 0;
    if (quick && study_get_list(s, f, &f->series[0], "nx", 4, 20000, full, &nfull) == CONSPH_OK) {
        same = nfull == plans[0].nvalues;
        for (int j = 0; same && j < nfull; ++j) same = full[j] == plans[0].nx[j];
    }
    if (quick && nfull && !same && len < sizeof ran) {
        len += (size_t)snprintf(ran + len, sizeof ran - len, "; full study: ");
        study_list_text(ran, sizeof ran, &len, "nx", full, nfull);
    }
    if (len < sizeof ran) snprintf(ran + len, sizeof ran - len, ")");
    rc = study_gp_head(o, f->id, title ? title : f->id, ran);
    static const char *const names[3] = {"L2 (002 eq. 44)", "Linf (eq. 45)", "EC (eq. 46)"};
    /* Three panels of one width, the key right of the last. */
    fprintf(o, "set terminal svg size 1600,600 dynamic\nset output outfile\nunset title\n"
               "set multiplot title ");
    if (rc == CONSPH_OK) rc = study_gp_title(o, title ? title : f->id, ran);
    fprintf(o, " noenhanced\nset logscale xy\nset format y '%%.0e'\nset xlabel 'Δ = 1/(nx-1)'\n"
               "unset key\nset tmargin at screen 0.88\nset bmargin at screen 0.11\n");
    study_extent ex;
    study_extent_init(&ex);
    for (int k = 0; k < f->nseries; ++k)
        for (int j = 0; j < plans[k].nvalues; ++j) study_extent_add(&ex, rows[k][j].sum.delta, 1);
    study_gp_range(o, "x", &ex, 1);
    /* tics at the resolutions that ran, as 1/(nx - 1) */
    fprintf(o, "set xtics (");
    for (int j = 0; j < plans[0].nvalues; ++j)
        fprintf(o, "%s'1/%g' %.10g", j ? ", " : "", plans[0].nx[j] - 1.0,
                1.0 / (plans[0].nx[j] - 1.0));
    fprintf(o, ")\n");
    for (int c = 0; rc == CONSPH_OK && c < 3; ++c) {
        /* 002 describes S3 as first order and S4 as near second order: a slope-1 guide above
         * the errors at the coarsest Δ and a slope-2 guide below them, so that neither hides a
         * series. */
        study_extent ey;
        study_extent_init(&ey);
        double x0 = ex.hi, top = -INFINITY, bottom = INFINITY;
        for (int k = 0; k < f->nseries; ++k)
            for (int j = 0; j < plans[k].nvalues; ++j) {
                const consph_heat_summary *w = &rows[k][j].sum;
                const double e = c == 0 ? w->l2 : c == 1 ? w->linf : w->ec;
                study_extent_add(&ey, e, 1);
                if (w->delta == x0 && e > 0 && isfinite(e)) {
                    top = fmax(top, e);
                    bottom = fmin(bottom, e);
                }
            }
        if (isfinite(top) && isfinite(bottom)) {
            /* the guides start in the frame */
            study_extent_add(&ey, 2.0 * top, 1);
            study_extent_add(&ey, 0.5 * bottom, 1);
        }
        study_gp_range(o, "y", &ey, 1);
        fprintf(o, "set ylabel '%s'\nset lmargin at screen %.3f\nset rmargin at screen %.3f\n",
                names[c], 0.05 + 0.27 * c, 0.26 + 0.27 * c);
        if (c == 2) fprintf(o, "set key at screen 0.82,0.88 top left noenhanced font ',9'\n");
        const int guides = isfinite(top) && isfinite(bottom) && isfinite(x0);
        if (guides)
            fprintf(o, "slope1(x) = %.10g*(x/%.10g)\nslope2(x) = %.10g*(x/%.10g)**2\n", 2.0 * top,
                    x0, 0.5 * bottom, x0);
        fprintf(o, "plot");
        for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
            /* each series its colour and marker; S3 dashed, S4 solid */
            fprintf(o, "%s '%s.dat' index %d using 1:%d with linespoints", k ? ", \\\n    " : " ",
                    f->id, k, c + 2);
            study_gp_style(o, k);
            fprintf(o, " dt %d title ", plans[k].prm.laplacian == CONSPH_HEAT_S3 ? 2 : 1);
            rc = study_gp_put(o, f->series[k].label);
        }
        if (guides)
            fprintf(o, ", \\\n    slope1(x) with lines dt 3 lw 2 lc rgb 'gray40' title 'slope 1 "
                       "(first order)', \\\n    slope2(x) with lines dt 4 lw 2 lc rgb 'gray20' "
                       "title 'slope 2 (second order)'");
        fprintf(o, "\n");
    }
    fprintf(o, "unset multiplot\n");
    return study_gp_finish(&of, rc, dir, f->id);
}

static void order_of(const heat_plan *pl, const heat_row *rows, int norm, char *buf, size_t size)
{
    double res[STUDY_MAX_SWEEP], err[STUDY_MAX_SWEEP];
    for (int j = 0; j < pl->nvalues; ++j) {
        res[j] = 1.0 / rows[j].sum.delta;
        err[j] = norm == 0 ? rows[j].sum.l2 : norm == 1 ? rows[j].sum.linf : rows[j].sum.ec;
    }
    consph_order_fit fit;
    if (consph_fit_order(res, err, pl->nvalues, &fit) != CONSPH_OK) {
        snprintf(buf, size, "n/a");
        return;
    }
    consph_order_text(&fit, 2, "±", buf, size);
}

static int write_report(const consph_study *s, const study_figure *f, const heat_plan *plans,
                        heat_row (*rows)[STUDY_MAX_SWEEP], int timing, int quick, const char *dir)
{
    char paper[1024];
    consph_outfile of;
    int rc = study_open_output(&of, dir, f->id, ".md");
    if (rc) return rc;
    FILE *o = of.fp;
    const char *title = study_get(s, f, NULL, "title");
    fprintf(o, "## %s: %s\n\n", f->id, title ? title : f->id);
    const char *note = study_figure_note(f);
    if (note) fprintf(o, "%s\n\n", note);
    fprintf(o,
            "Run: %s resolutions. 002's heat problem (docs/heat.md): nx × nx particles on the grid "
            "vertices, walls included (Δ = 1/(nx − 1)), walls as source-only particles, "
            "`wendland-c2:h` with h = η Δ, forward Euler with Δt = 0.2 d_min² to t = %g. Orders "
            "are least-squares slopes in 1/Δ (positive: the error falls).\n\n",
            quick ? "quick" : "full", plans[0].prm.tf);
    if (!timing) study_md_figure(o, f->id);
    if (timing) {
        fprintf(o,
                "| series | nx | N | steps | time (s) | relative to %s | steps (s) | set-up (s) "
                "| L2 | paper |\n|---|---|---|---|---|---|---|---|---|---|\n",
                f->series[0].label);
        const double ref = rows[0][plans[0].nvalues - 1].total;
        for (int k = 0; k < f->nseries; ++k) {
            const heat_row *w = &rows[k][plans[k].nvalues - 1];
            paper_text(f, &f->series[k], paper, sizeof paper);
            fprintf(o, "| %s | %d | %zu | %ld | %.3f | %.2f | %.3f | %.3f | %.3e | %s |\n",
                    f->series[k].label, w->sum.nx, w->sum.n, w->sum.steps, w->total, w->total / ref,
                    w->sum.seconds, w->sum.setup_seconds, w->sum.l2, paper);
        }
        fprintf(o,
                "\nTimes: wall clock of %s (set-up and time steps, no files), relative to the "
                "first series. 002 ran on one core of a 3 GHz Core 2 E8400; only the ratios "
                "compare.\n\n",
                quick ? "the fastest of 3 runs" : "one run");
        return consph_outfile_commit(&of);
    }
    fprintf(o, "| series | order L2 | order L∞ | order EC | L2 at the finest Δ | paper |\n"
               "|---|---|---|---|---|---|\n");
    for (int k = 0; k < f->nseries; ++k) {
        char ol2[64], oli[64], oec[64];
        order_of(&plans[k], rows[k], 0, ol2, sizeof ol2);
        order_of(&plans[k], rows[k], 1, oli, sizeof oli);
        order_of(&plans[k], rows[k], 2, oec, sizeof oec);
        paper_text(f, &f->series[k], paper, sizeof paper);
        fprintf(o, "| %s | %s | %s | %s | %.3e | %s |\n", f->series[k].label, ol2, oli, oec,
                rows[k][plans[k].nvalues - 1].sum.l2, paper);
    }
    fprintf(o, "\n| series | nx | Δ | N | steps | L2 | L∞ | EC | s |\n"
               "|---|---|---|---|---|---|---|---|---|\n");
    for (int k = 0; k < f->nseries; ++k)
        for (int j = 0; j < plans[k].nvalues; ++j) {
            const consph_heat_summary *w = &rows[k][j].sum;
            fprintf(o, "| %s | %d | %.4g | %zu | %ld | %.3e | %.3e | %.3e | %.2f |\n",
                    f->series[k].label, w->nx, w->delta, w->n, w->steps, w->l2, w->linf, w->ec,
                    rows[k][j].total);
        }
    fprintf(o, "\n");
    return consph_outfile_commit(&of);
}

/* The work model of one run (time steps × pairs), the unit of the progress line's ETA. */
static double heat_row_work(const heat_plan *pl, int j)
{
    double nx = pl->nx[j], d = 1.0 / (nx - 1.0);
    double steps = pl->prm.tf / (pl->prm.courant * d * d) + 1.0;
    return steps * nx * nx * (1.0 + M_PI * pl->prm.eta * pl->prm.eta);
}

static int heat_rows(const consph_study *s, const study_figure *f, int quick,
                     const study_files *files, double *work)
{
    (void)files;
    const char *report = study_get(s, f, NULL, "report");
    const int timing = report && strcmp(report, "time") == 0;
    int n = 0;
    for (int k = 0; k < f->nseries; ++k) {
        heat_plan pl;
        if (heat_plan_build(s, f, &f->series[k], quick, &pl) != CONSPH_OK) continue;
        for (int j = timing ? pl.nvalues - 1 : 0; j < pl.nvalues; ++j, ++n)
            *work += heat_row_work(&pl, j);
    }
    return n;
}

static int heat_figure(const study_job *job, const study_figure *f)
{
    const consph_study *s = job->s;
    const int quick = job->quick;
    const char *dir = job->dir;
    FILE *log = job->log;
    if (f->nseries < 1) return study_key_error(s, f, NULL, "kind", "a heat figure needs series");
    const char *report = study_get(s, f, NULL, "report");
    const int timing = report && strcmp(report, "time") == 0;
    if (report && !timing)
        return study_key_error(s, f, NULL, "report", "unknown value; allowed: time");
    heat_plan *plans = calloc((size_t)f->nseries, sizeof *plans);
    heat_row(*rows)[STUDY_MAX_SWEEP] = calloc((size_t)f->nseries, sizeof *rows);
    int rc = plans && rows ? CONSPH_OK : consph_fail(CONSPH_ENOMEM, "out of memory");
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k)
        rc = heat_plan_build(s, f, &f->series[k], quick, &plans[k]);
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k)
        for (int j = 0; rc == CONSPH_OK && j < plans[k].nvalues; ++j) {
            /* a time comparison runs only the finest resolution, best of 3 when it is cheap */
            if (timing && j < plans[k].nvalues - 1) continue;
            if (study_rows_stop(job)) {
                rc = STUDY_STOPPED;
                break;
            }
            rc = study_row_elsewhere(job);
            if (rc == STUDY_ELSEWHERE) {
                rc = CONSPH_OK;
                continue;
            }
            if (rc) break;
            char what[32];
            snprintf(what, sizeof what, "nx=%g", plans[k].nx[j]);
            study_row_begin(job, f, k, what, heat_row_work(&plans[k], j));
            /* A row an earlier run kept is read back, not run again. */
            const int stored =
                study_row_load(job, f, k, j, &rows[k][j], sizeof rows[k][j], NULL, NULL);
            if (!stored) rc = run_one(&plans[k], j, timing && quick ? 3 : 1, &rows[k][j]);
            const consph_heat_summary *w = &rows[k][j].sum;
            if (rc == CONSPH_OK && !(isfinite(w->l2) && isfinite(w->linf) && isfinite(w->ec)))
                rc = consph_fail(CONSPH_ENUMERIC, "error not finite");
            if (rc != CONSPH_OK) {
                char msg[512];
                snprintf(msg, sizeof msg, "%s", consph_last_error());
                rc = consph_fail(rc, "figure '%s', series '%s', nx %g: %s", f->id,
                                 f->series[k].label, plans[k].nx[j], msg);
            } else if (log) {
                fprintf(log, "  %s nx %d: L2 %.3e  (%.2f s)\n", f->series[k].label, w->nx, w->l2,
                        rows[k][j].total);
            }
            if (rc == CONSPH_OK)
                rc =
                    study_row_finish(job, f, k, j, &rows[k][j], sizeof rows[k][j], NULL, 0, stored);
        }
    if (timing)
        for (int k = 0; k < f->nseries; ++k) {
            /* the report reads the finest row only */
            rows[k][0] = rows[k][plans[k].nvalues - 1];
            plans[k].nx[0] = plans[k].nx[plans[k].nvalues - 1];
            plans[k].nvalues = 1;
        }
    if (rc == CONSPH_OK) rc = write_csv(f, plans, rows, dir);
    if (rc == CONSPH_OK && !timing) rc = write_plot(s, f, plans, rows, quick, dir);
    if (rc == CONSPH_OK) rc = write_report(s, f, plans, rows, timing, quick, dir);
    free(plans);
    free(rows);
    return rc;
}

/* Pair evaluations per step scale as N (1 + π η²); S3 costs about 0.8 of S4 per pair (measured
 * at 80², η = 3.5); calibrated on one small S4 run. */
double study_heat_seconds(const consph_study *s, const study_figure *f, int quick)
{
    static double per_pair_step = 0.0;
    if (per_pair_step == 0.0) {
        consph_heat_params prm;
        consph_heat_params_default(&prm);
        /* S4 at the figures' largest η, long enough to dwarf the set-up */
        prm.nx = 40;
        prm.eta = 3.5;
        prm.steps = 200;
        consph_heat *h = NULL;
        consph_heat_summary sum;
        if (consph_heat_create(&h, &prm) != CONSPH_OK) return NAN;
        consph_heat_run(h, NULL, 0, &sum);
        consph_heat_free(h);
        per_pair_step = sum.seconds / (double)sum.pairs;
    }
    const char *report = study_get(s, f, NULL, "report");
    const int timing = report && strcmp(report, "time") == 0;
    double total = 0.0;
    for (int k = 0; k < f->nseries; ++k) {
        heat_plan pl;
        if (heat_plan_build(s, f, &f->series[k], quick, &pl) != CONSPH_OK) return NAN;
        for (int j = timing ? pl.nvalues - 1 : 0; j < pl.nvalues; ++j) {
            double nx = pl.nx[j], d = 1.0 / (nx - 1.0);
            double steps = pl.prm.tf / (pl.prm.courant * d * d) + 1.0;
            double pairs = nx * nx * (1.0 + M_PI * pl.prm.eta * pl.prm.eta);
            total += (timing && quick ? 3.0 : 1.0) * steps * pairs * per_pair_step *
                     (pl.prm.laplacian == CONSPH_HEAT_S4 ? 1.0 : 0.8);
        }
    }
    return total;
}

static int heat_estimate(const consph_study *s, const study_figure *f, int quick,
                         const study_files *files, study_estimate *e)
{
    (void)files;
    e->seconds += study_heat_seconds(s, f, quick);
    return CONSPH_OK;
}

const study_kind study_kind_heat = {
    .name = "heat",
    .particles = STUDY_PARTICLES_IGNORED,
    .validate = study_validate_plans,
    .estimate = heat_estimate,
    .rows = heat_rows,
    .run = heat_figure,
};
