/* Study kind `approx`: an operator's error on a manufactured field over resolutions or h/Δs,
 * one row per measurement, the fitted order beside the paper's (001 Tables 3 and 5, 003 Tables
 * 1-3), and the error against resolution with the paper's points and a slope -2 guide. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "study/kinds/kinds.h"

/* Timings behind T_r (the operator at a series' finest resolution) and their median. */
#define TR_TIMINGS 5

typedef struct series_result {
    consph_approx_row rows[MAX_SWEEP];
    double bound[MAX_SWEEP];
    double nx[MAX_SWEEP]; /* the resolution fitted: nx, or N^(1/dim) for particle files */
    int nrows;
} series_result;

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
            if (l == 0 && study_kv_has(&r->keys, key)) continue;
            snprintf(buf + strlen(buf), size - strlen(buf), "%s%s = %s", buf[0] ? "; " : "",
                     key + 6, study_get(s, f, r, key));
        }
}

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

/* The title's second line: what ran (the resolutions, the h/Δs sweep, the files), and for a
 * quick run the paper's resolutions beside them. */
static void ran_text(const consph_study *s, const study_figure *f, const series_plan *plans,
                     const series_result *res, int quick, const study_files *files, int dim,
                     char *buf, size_t size)
{
    size_t len = (size_t)snprintf(buf, size, "ran: ");
    if (files) {
        double n[MAX_SWEEP];
        for (int j = 0; j < files->n && j < MAX_SWEEP; ++j) n[j] = (double)files->sets[j].n;
        len += (size_t)snprintf(buf + len, size - len, "particle files, ");
        study_list_text(buf, size, &len, "N", n, files->n < MAX_SWEEP ? files->n : MAX_SWEEP);
    } else if (plans[0].sweep_hdx) {
        len += (size_t)snprintf(buf + len, size - len, "nx = %zu, ", plans[0].nx_fixed);
        study_list_text(buf, size, &len, "h/Δs", plans[0].values, plans[0].nvalues);
    } else {
        study_list_text(buf, size, &len, "nx", res[0].nx, res[0].nrows);
    }
    if (len < size)
        len += (size_t)snprintf(buf + len, size - len, " (%dD, %s", dim,
                                files   ? "the files'"
                                : quick ? "quick"
                                        : "full study");
    /* A quick run's full-study resolutions beside it, where they differ. */
    double full[MAX_SWEEP];
    int nfull = 0;
    if (quick && !files && !plans[0].sweep_hdx &&
        study_get_list(s, f, &f->series[0], "nx", 2, 1e5, full, &nfull) == CONSPH_OK && nfull) {
        int same = nfull == res[0].nrows;
        for (int j = 0; same && j < nfull; ++j) same = full[j] == res[0].nx[j];
        if (!same && len < size) {
            len += (size_t)snprintf(buf + len, size - len, "; full study: ");
            study_list_text(buf, size, &len, "nx", full, nfull);
        }
    }
    if (len < size) snprintf(buf + len, size - len, ")");
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
    const char *title = study_files_title(s, f, files != NULL, tbuf, sizeof tbuf);
    study_report_head_as(o, s, f, title);
    const consph_approx_spec *sp = &plans[0].spec;
    fprintf(o,
            "Run: %s resolutions; op `%s`, layout `%s`, dim %d, periodic %s, field `%s`, "
            "volumes `%s`, compared particles: %s. Norm fitted: `%s`.\n\n",
            study_resolutions_text(files != NULL, quick), consph_op_name(sp->op.op),
            files ? "particle files" : consph_layout_name(sp->layout.kind), dim,
            (files ? files->sets[0].box.periodic[0] : sp->layout.box.periodic[0]) ? "yes" : "no",
            consph_mfield_name(sp->field), consph_volume_name(sp->volume),
            sp->interior_only ? "interior (full support)" : "all", norm);
    if (sp->h_policy == CONSPH_H_ZHU || sp->h_policy == CONSPH_H_BETA) {
        char htext[160];
        fprintf(o, "Smoothing length: h %s.\n\n", study_h_policy_text(sp, htext, sizeof htext));
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
    study_md_figure(o, f->id);
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
    char ran[512];
    ran_text(s, f, plans, res, quick, files, dim, ran, sizeof ran);
    rc = study_gp_head(o, f->id, title, ran);
    fprintf(o, "set logscale xy\nset format y '%%g'\nset xlabel '%s'\nset ylabel '%s error'\n",
            strcmp(xname, "nbr") == 0 ? "neighbours" : "particles per axis", norm);
    /* The axes end at the data and the paper's points, the guide and the bound left out. */
    study_extent ex, ey;
    study_extent_init(&ex);
    study_extent_init(&ey);
    for (int k = 0; k < f->nseries; ++k)
        for (int j = 0; j < res[k].nrows; ++j) {
            double y = norm_value(&res[k].rows[j], norm);
            if (!(y > 0) || !isfinite(y)) continue;
            study_extent_add(&ex, x_value(&res[k].rows[j], res[k].nx[j], xname, dim), 1);
            study_extent_add(&ey, y, 1);
        }
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
    if (guide) {
        fprintf(o, "ref(x) = %.10g*(x/%.10g)**(-2)\n", 0.5 * y0,
                x_value(&res[0].rows[0], res[0].nx[0], xname, dim));
        study_extent_add(&ey, 0.5 * y0, 1); /* the guide's start stays in the frame */
    }
    /* The paper's value of each series as a marked point at the paper's finest resolution. */
    int paper_pt[MAX_SERIES_POINTS] = {0};
    double paper_x[MAX_SERIES_POINTS] = {0};
    for (int k = 0; k < f->nseries && k < MAX_SERIES_POINTS; ++k) {
        double px, py;
        if (sweep_hdx || !paper_point(s, f, &f->series[k], xname, norm, &px, &py)) continue;
        fprintf(o, "$paper%d << EOD\n%.10g %.10g\nEOD\n", k, px, py);
        study_extent_add(&ex, px, 1);
        study_extent_add(&ey, py, 1);
        paper_pt[k] = 1;
        paper_x[k] = px;
    }
    study_gp_range(o, "x", &ex, 1);
    study_gp_range(o, "y", &ey, 1);
    if (strcmp(xname, "nx") == 0) {
        double tics[2 * MAX_SWEEP + MAX_SERIES_POINTS];
        int nt = 0;
        for (int j = 0; j < res[0].nrows; ++j) tics[nt++] = res[0].nx[j];
        for (int k = 0; k < f->nseries && k < MAX_SERIES_POINTS; ++k)
            if (paper_pt[k]) tics[nt++] = paper_x[k];
        study_gp_tics(o, "x", tics, nt);
    }
    fprintf(o, "plot");
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
        fprintf(o, "%s '%s.dat' index %d using 1:2 with linespoints", k ? ", \\\n    " : " ", f->id,
                k);
        study_gp_style(o, k);
        fprintf(o, " title ");
        rc = study_gp_put(o, f->series[k].label);
    }
    /* Every paper point its own key entry, naming its series: the open form of the series'
     * marker. */
    for (int k = 0; rc == CONSPH_OK && k < f->nseries && k < MAX_SERIES_POINTS; ++k) {
        if (!paper_pt[k]) continue;
        char text[320];
        snprintf(text, sizeof text, "%s: paper (nx %g)", f->series[k].label, paper_x[k]);
        fprintf(o, ", \\\n    $paper%d with points", k);
        study_gp_paper_style(o, k);
        fprintf(o, " title ");
        rc = study_gp_put(o, text);
    }
    if (plans[0].bound)
        fprintf(o, ", \\\n    '%s.dat' index 0 using 1:3 with lines dashtype 2 title 'bound'",
                f->id);
    if (guide)
        fprintf(o, ", \\\n    ref(x) with lines dashtype 2 lw 2 lc rgb 'gray40' title 'slope -2 "
                   "(second order)'");
    fprintf(o, "\n");
    if ((rc = study_close_output(&of, rc))) return rc;
    /* before drawing: gnuplot may refuse the non-finite points, and its failure would then
     * hide this one, which names figure, series and resolution */
    if (failure[0]) return consph_fail(CONSPH_ENUMERIC, "%s", failure);
    return study_render_figure(dir, f->id);
}

static int run_approx_figure(const study_job *job, const study_figure *f)
{
    const consph_study *s = job->s;
    const int quick = job->quick;
    const study_files *files = job->files;
    layout_cache *cache = job->cache;
    FILE *log = job->log;
    int tr = reports_tr(s, f);
    series_plan *plans = calloc((size_t)f->nseries, sizeof *plans);
    series_result *res = calloc((size_t)f->nseries, sizeof *res);
    int rc = (!plans || !res) ? consph_fail(CONSPH_ENOMEM, "out of memory") : CONSPH_OK;
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k)
        rc = study_plan_build(s, f, &f->series[k], quick, &plans[k]);
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
        series_plan *pl = &plans[k];
        /* Files replace the nx sweep, one row each; an h/Δs sweep runs on the last file. */
        if (files && !pl->sweep_hdx) study_plan_take_files(pl, files);
        for (int j = 0; rc == CONSPH_OK && j < pl->nvalues; ++j) {
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
            consph_approx_spec sp = pl->spec;
            size_t nx = pl->sweep_hdx ? pl->nx_fixed : (size_t)pl->values[j];
            if (pl->sweep_hdx) sp.hdx = pl->values[j];
            /* T_r compares the finest resolutions: a median there, single timings elsewhere. */
            if (tr && !pl->sweep_hdx && j == pl->nvalues - 1) sp.timing_runs = TR_TIMINGS;
            char what[64];
            snprintf(what, sizeof what, "%s=%g", pl->sweep_hdx ? "h/dx" : "nx", pl->values[j]);
            study_row_begin(job, f, k, what, study_plan_row_work(pl, j));
            consph_approx_row *w = &res[k].rows[j];
            /* A row an earlier run kept is read back, its layout not made again. */
            const int stored = study_row_load(job, f, k, j, w, sizeof *w, NULL, NULL);
            const consph_particles *p = NULL;
            double lsec = 0.0;
            if (files) {
                p = &files->sets[pl->sweep_hdx ? files->n - 1 : j];
                res[k].nx[j] = study_resolution_of(p);
                nx = (size_t)floor(res[k].nx[j] + 0.5);
                sp.layout.box = p->box;
            } else if (!stored) {
                consph_layout_params lp = sp.layout;
                for (int a = 0; a < CONSPH_MAX_DIM; ++a) lp.nx[a] = a < lp.dim ? nx : 1;
                rc = study_layout_get(cache, &lp, &p, &lsec, log);
                if (rc) break;
                res[k].nx[j] = (double)nx;
            } else {
                res[k].nx[j] = (double)nx;
            }
            if (!stored) {
                rc = consph_approx_run_particles(&sp, p, nx, w);
                if (rc) {
                    consph_fail(rc, "figure '%s', series '%s', nx %zu: %s", f->id,
                                f->series[k].label, nx, consph_last_error());
                    break;
                }
                w->layout_seconds = lsec;
            }
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
            rc = study_row_finish(job, f, k, j, w, sizeof *w, NULL, 0, stored);
        }
    }
    if (rc == CONSPH_OK) rc = write_approx_outputs(s, f, plans, res, job->dir, quick, files, log);
    free(plans);
    free(res);
    return rc;
}

const study_kind study_kind_approx = {
    .name = "approx",
    .particles = STUDY_PARTICLES_USED,
    .checks_operator_on_files = 1,
    .validate = study_validate_plans,
    .estimate = study_estimate_plans,
    .rows = study_plan_rows,
    .run = run_approx_figure,
};
