/* The report and plots of a `run` study figure (kinds/run.h): FIGURE.csv and FIGURE.md with the
 * fitted orders of L1(u) and L1(p) beside the paper's, and the gnuplot figure against nx, wall
 * time, radius or time, through the shared writer (writer.c). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/gpu.h"
#include "consph/io.h"
#include "study/kinds/kinds.h"
#include "study/kinds/run.h"

/* The panels of an x = time figure: `y`, one or more of y_names separated by commas (default
 * momentum_x), each once; *ys gets their indices. `y` with another x is an error. */
int run_y_panels(const consph_study *s, const study_figure *f, int x, int *ys, int *ny)
{
    const char *v = study_get(s, f, NULL, "y");
    *ny = 0;
    if (v && x != X_TIME) return study_key_error(s, f, NULL, "y", "only with x = time");
    if (!v) v = y_names[0];
    for (const char *c = v; *c;) {
        while (*c == ' ' || *c == '\t') ++c;
        size_t len = strcspn(c, ",");
        while (len && (c[len - 1] == ' ' || c[len - 1] == '\t')) --len;
        int k = 0;
        while (y_names[k] && !(strlen(y_names[k]) == len && strncmp(c, y_names[k], len) == 0)) ++k;
        if (!y_names[k])
            return study_key_error(s, f, NULL, "y",
                                   "unknown value '%.*s'; allowed: %s, %s, %s (comma-separated)",
                                   (int)len, c, y_names[0], y_names[1], y_names[2]);
        for (int j = 0; j < *ny; ++j)
            if (ys[j] == k) return study_key_error(s, f, NULL, "y", "'%s' named twice", y_names[k]);
        ys[(*ny)++] = k;
        c += strcspn(c, ",");
        if (*c) ++c;
    }
    return CONSPH_OK;
}

/* L1(u) (which = 0), L1(p) (1), or with exact = both the same against the weakly-compressible
 * reference (2, 3), in the row's measure. */
static double row_l1(const run_plan *pl, const run_row *w, int which)
{
    if (which == 0) return w->sum.l1_u;
    if (which == 1) return w->sum.l1_p;
    if (AUTHORS(pl)) return which == 2 ? w->sum.wc_l1n_u : w->sum.wc_l1n_p;
    return which == 2 ? w->sum.wc_l1_u : w->sum.wc_l1_p;
}

/* The order of row_l1(which) over the runs that finished, as text. */
static double fit_text(const run_plan *pl, const run_row *rows, int which, char *buf, size_t size)
{
    double xs[MAX_SWEEP], ys[MAX_SWEEP];
    int n = 0;
    for (int j = 0; j < pl->nnx; ++j) {
        if (rows[j].status != CONSPH_OK) continue;
        xs[n] = pl->nx[j];
        ys[n++] = row_l1(pl, &rows[j], which);
    }
    consph_order_fit fit;
    if (n < 2 && n < pl->nnx) {
        snprintf(buf, size, "n/a (%d of %d runs completed)", n, pl->nnx);
        return NAN;
    }
    if (consph_fit_order(xs, ys, n, &fit) != CONSPH_OK) {
        snprintf(buf, size, "n/a");
        return NAN;
    }
    consph_order_text(&fit, 2, "±", buf, size);
    return fit.order;
}

/* An order cell: ours, flagged when it differs from a numeric paper value by more than the
 * tolerance. */
static int order_cell(const consph_study *s, const study_figure *f, const study_series *r,
                      const char *key, double ours, const char *text, char *buf, size_t size)
{
    double paper;
    int off = isfinite(ours) && study_paper_number(s, f, r, key, &paper) &&
              fabs(ours - paper) > ORDER_TOLERANCE;
    snprintf(buf, size, "%s%s", text, off ? " ⚠" : "");
    return off;
}

/* Whether the figure has points: a history (x = time) always has its initial state; against
 * nx, a finished run's error, which a problem without an exact solution (the shear layer) has
 * not, and gnuplot refuses a plot without points. */
int run_plottable(const study_figure *f, const run_plan *plans, run_row (*rows)[MAX_SWEEP], int x)
{
    for (int k = 0; x == X_TIME && k < f->nseries; ++k)
        if (rows[k][plans[k].nnx - 1].ncurve) return 1;
    for (int k = 0; x != X_TIME && k < f->nseries; ++k)
        for (int j = 0; j < plans[k].nnx; ++j)
            if (rows[k][j].status == CONSPH_OK && isfinite(rows[k][j].sum.l1_u)) return 1;
    return 0;
}

/* Where 001 reports only whether a scheme completes (Gresho-Chan, the shear layer), a series'
 * `paper.outcome` asks for ours beside it: completed, or the resolutions that diverged and the
 * time the finest one reached. */
static void outcome_table(FILE *o, const consph_study *s, const study_figure *f,
                          const run_plan *plans, run_row (*rows)[MAX_SWEEP])
{
    int any = 0;
    for (int k = 0; k < f->nseries; ++k)
        any |= study_get(s, f, &f->series[k], "paper.outcome") != NULL;
    if (!any) return;
    fprintf(o, "\n| series | ours | paper |\n|---|---|---|\n");
    for (int k = 0; k < f->nseries; ++k) {
        const run_plan *pl = &plans[k];
        const run_row *last = &rows[k][pl->nnx - 1];
        fprintf(o, "| %s | ", f->series[k].label);
        int bad = 0;
        for (int j = 0; j < pl->nnx; ++j)
            if (rows[k][j].status != CONSPH_OK)
                fprintf(o, "%s%g", bad++ ? ", " : "diverged at nx ", pl->nx[j]);
        if (bad)
            fprintf(o, " (the finest at t = %.3g)", last->sum.t);
        else
            fprintf(o, "completed (t = %g)", last->sum.t);
        fprintf(o, " | %s |\n", study_get_or(s, f, &f->series[k], "paper.outcome", "—"));
    }
    fprintf(o, "\n");
}

/* x = time: per series the largest drift of M_x and of L from their initial values over the
 * finest run's steps (001 Figs. 15-17 plot both against time), beside paper.outcome. */
static void momentum_table(FILE *o, const consph_study *s, const study_figure *f,
                           const run_plan *plans, run_row (*rows)[MAX_SWEEP])
{
    fprintf(o, "Momentum drift over the steps of the finest run (to the last finite step of a "
               "diverged run); L about the box centre.\n\n| series | steps | t reached | max "
               "\\|M_x(t) − M_x(0)\\| | L(0) | max \\|L(t) − L(0)\\| | relative to \\|L(0)\\| | "
               "paper |\n|---|---|---|---|---|---|---|---|\n");
    for (int k = 0; k < f->nseries; ++k) {
        const run_row *w = &rows[k][plans[k].nnx - 1];
        if (w->ncurve == 0) continue;
        const double *c = w->curve, *end = c + 4 * (w->ncurve - 1);
        double dm = 0.0, dl = 0.0;
        for (const double *r = c; r <= end; r += 4) {
            dm = fmax(dm, fabs(r[1] - c[1]));
            dl = fmax(dl, fabs(r[3] - c[3]));
        }
        fprintf(o, "| %s | %zu | %.4g%s | %.3e | %.6g | %.3e | %.3e | %s |\n", f->series[k].label,
                w->ncurve - 1, end[0], w->status ? " (diverged)" : "", dm, c[3], dl,
                dl / fabs(c[3]), study_get_or(s, f, &f->series[k], "paper.outcome", "—"));
    }
    fprintf(o, "\n");
}

/* The figure's title; a quick run's says what it ran, since the title names the paper's final
 * time and its resolutions are not the paper's. */
const char *run_title(const consph_study *s, const study_figure *f, int quick, const run_plan *pl,
                      char *buf, size_t size)
{
    const char *title = study_get_or(s, f, NULL, "title", f->id);
    if (!quick) return title;
    size_t len = (size_t)snprintf(buf, size, "%s [quick run: ", title);
    if (len < size && pl->prm.steps > 0)
        len += (size_t)snprintf(buf + len, size - len, "%ld steps", pl->prm.steps);
    else if (len < size)
        len += (size_t)snprintf(buf + len, size - len, "to t = %g", pl->prm.tf);
    for (int j = 0; j < pl->nnx && len < size; ++j)
        len += (size_t)snprintf(buf + len, size - len, "%s%g", j ? ", " : ", nx ", pl->nx[j]);
    if (len < size) snprintf(buf + len, size - len, "]");
    return len < size ? buf : title;
}

/* "Device: ...": which device ran each row (consph study --device). */
static void device_line(FILE *o, const study_figure *f, const run_plan *plans,
                        run_row (*rows)[MAX_SWEEP])
{
    int count[2] = {0, 0}, total = 0;
    for (int k = 0; k < f->nseries; ++k)
        for (int j = 0; j < plans[k].nnx; ++j, ++total)
            count[rows[k][j].device == CONSPH_DEVICE_GPU]++;
    fprintf(o, "Device:");
    if (count[1] == total || count[0] == total)
        fprintf(o, " the %s ran every row.", count[1] ? "GPU" : "CPU");
    for (int d = 1; d >= 0 && count[0] && count[1]; --d) {
        fprintf(o, " the %s ran", d ? "GPU" : "CPU");
        int listed = 0;
        for (int k = 0; k < f->nseries; ++k) {
            int n = 0;
            for (int j = 0; j < plans[k].nnx; ++j) {
                if ((rows[k][j].device == CONSPH_DEVICE_GPU) != d) continue;
                if (!n) fprintf(o, "%s %s (nx ", listed++ ? "," : "", f->series[k].label);
                fprintf(o, "%s%g", n++ ? ", " : "", plans[k].nx[j]);
            }
            if (n) fprintf(o, ")");
        }
        fprintf(o, "%s", d ? ";" : ". T_r and the seconds compare wall times of both.");
    }
    fprintf(o, "\n\n");
}

int run_write_report(const consph_study *s, const study_figure *f, int quick, const char *dir,
                     const run_plan *plans, run_row (*rows)[MAX_SWEEP], int ref, int x,
                     const char *title, int devices)
{
    char label[128];
    consph_outfile of;
    int rc = study_open_output(&of, dir, f->id, ".csv");
    if (rc) return rc;
    int auth = 0, wcb = 0;
    for (int k = 0; k < f->nseries; ++k) auth |= AUTHORS(&plans[k]);
    for (int k = 0; k < f->nseries; ++k) wcb |= WC_BOTH(&plans[k]);
    fprintf(of.fp,
            "series,scheme,c0,nx,n,steps,t,dt,h,l1_u,l1_p,linf_u,linf_p,ft_over_fmax,"
            "seconds,pairs,regularisations,status%s%s\n",
            auth ? ",l1_u_eq26,l1_p_eq26" : "", wcb ? ",l1_u_wc,l1_p_wc" : "");
    for (int k = 0; k < f->nseries; ++k)
        for (int j = 0; j < plans[k].nnx; ++j) {
            const consph_run_summary *w = &rows[k][j].sum;
            fprintf(of.fp,
                    "%s,%s,%g,%g,%zu,%ld,%.10g,%.6e,%.10g,%.6e,%.6e,%.6e,%.6e,%.6e,%.6g,%zu,%ld,"
                    "%s",
                    study_csv_label(f->series[k].label, label, sizeof label), w->scheme, w->c0,
                    plans[k].nx[j], w->n, w->steps, w->t, w->dt, w->h, w->l1_u, w->l1_p, w->linf_u,
                    w->linf_p, w->ft_fmax, w->seconds, w->pairs, w->regularisations,
                    rows[k][j].status == CONSPH_OK ? "ok" : "diverged");
            if (auth) fprintf(of.fp, ",%.6e,%.6e", rows[k][j].eq26_u, rows[k][j].eq26_p);
            if (wcb)
                fprintf(of.fp, ",%.6e,%.6e", row_l1(&plans[k], &rows[k][j], 2),
                        row_l1(&plans[k], &rows[k][j], 3));
            fprintf(of.fp, "\n");
        }
    if ((rc = consph_outfile_commit(&of))) return rc;

    if ((rc = study_open_output(&of, dir, f->id, ".md"))) return rc;
    FILE *o = of.fp;
    study_report_head_as(o, s, f, title);
    const consph_run_params *p0 = &plans[0].prm;
    fprintf(o, "Run: %s resolutions (nx", quick ? "quick" : "full (paper)");
    for (int j = 0; j < plans[0].nnx; ++j) fprintf(o, "%s%g", j ? ", " : " ", plans[0].nx[j]);
    fprintf(o, "); problem `%s`, ", p0->problem);
    if (p0->nu >= 0)
        fprintf(o, "ν %g, ", p0->nu);
    else
        fprintf(o, "Re %g, ", p0->re);
    fprintf(o, "h/Δs %g, layout %s; ", p0->hdx,
            p0->layout < 0 ? "the scheme's own" : consph_layout_name(p0->layout));
    if (p0->steps > 0)
        fprintf(o, "%ld steps; ", p0->steps);
    else
        fprintf(o, "to t = %g; ", p0->tf);
    if (p0->dt > 0)
        fprintf(o, "Δt = %g fixed. ", p0->dt);
    else
        fprintf(o, "Δt = %g h/(U + c_o) with h %s. ", p0->cfl,
                plans[0].dt_finest ? "of the finest resolution of the sweep (as 001)"
                                   : "of each run");
    const char *eq26 = plans[0].l1_mean ? "001 eq. 26 divided by the time run (the "
                                          "time-averaged mean absolute error)"
                                        : "001 eq. 26 (integrated over time)";
    if (auth)
        fprintf(o,
                "L1 is the measure of 001's authors (their post-processing, docs/schemes.md): the "
                "mean over %d output times in [0, t_f], t = 0 included, of mean||u| - |u_e|| / "
                "mean|u_e| and mean|p - p_e| / max|p_e|; the steps land on those times. The "
                "orders are fitted to it; %s is given beside it.\n\n",
                p0->error_times, eq26);
    else
        fprintf(o, "L1 is %s.\n\n", eq26);
    if (wcb)
        fprintf(o,
                "Against wc: the same L1 with the exact solution replaced by a pseudo-spectral "
                "solution of the weakly-compressible equations each run discretises (its EOS, c_o, "
                "ν and initial state; docs/schemes.md, \"The weakly-compressible reference\"), so "
                "that its order is that of the discretisation alone. On the floor: L1(u) more than "
                "%g times L1(u) against wc, the model's O(Ma²) departure from the incompressible "
                "solution making most of it.\n\n",
                WC_FLOOR_RATIO);
    fprintf(o,
            "| series | scheme | c_o | L1(u) at finest | paper L1(u) | %sorder u | paper | "
            "L1(p) at finest | paper L1(p) | %sorder p | paper | F_T/F_max | paper | T_r | "
            "paper T_r |%s\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|%s%s\n",
            auth ? "eq. 26 L1(u) | " : "", auth ? "eq. 26 L1(p) | " : "",
            wcb ? " L1(u) against wc | order u against wc | on the floor |" : "",
            auth ? "---|---|" : "", wcb ? "---|---|---|" : "");
    const run_row *rref = &rows[ref][plans[ref].nnx - 1];
    int flagged = 0;
    for (int k = 0; k < f->nseries; ++k) {
        const study_series *r = &f->series[k];
        const run_row *last = &rows[k][plans[k].nnx - 1];
        char tu[64], tp[64], cu[80], cp[80];
        double ou = fit_text(&plans[k], rows[k], 0, tu, sizeof tu);
        double op = fit_text(&plans[k], rows[k], 1, tp, sizeof tp);
        flagged |= order_cell(s, f, r, "paper.order_u", ou, tu, cu, sizeof cu);
        flagged |= order_cell(s, f, r, "paper.order_p", op, tp, cp, sizeof cp);
        char e26u[32] = "", e26p[32] = "";
        if (auth) {
            snprintf(e26u, sizeof e26u, "%.3e | ", last->eq26_u);
            snprintf(e26p, sizeof e26p, "%.3e | ", last->eq26_p);
        }
        fprintf(o,
                "| %s | %s | %g | %.3e (nx=%g%s) | %s | %s%s | %s | %.3e | %s | %s%s | %s | %.2e | "
                "%s | %.2f | %s |",
                r->label, plans[k].prm.scheme, last->sum.c0, last->sum.l1_u,
                plans[k].nx[plans[k].nnx - 1], last->status ? ", diverged" : "",
                study_get_or(s, f, r, "paper.l1_u", "—"), e26u, cu,
                study_get_or(s, f, r, "paper.order_u", "—"), last->sum.l1_p,
                study_get_or(s, f, r, "paper.l1_p", "—"), e26p, cp,
                study_get_or(s, f, r, "paper.order_p", "—"), last->sum.ft_fmax,
                study_get_or(s, f, r, "paper.ft", "—"), last->sum.seconds / rref->sum.seconds,
                study_get_or(s, f, r, "paper.tr", "—"));
        if (wcb) {
            char tw[64];
            fit_text(&plans[k], rows[k], 2, tw, sizeof tw);
            const double wu = row_l1(&plans[k], last, 2);
            fprintf(o, " %.3e | %s | %s |", wu, tw,
                    !WC_BOTH(&plans[k]) || !isfinite(wu)   ? "—"
                    : last->sum.l1_u > WC_FLOOR_RATIO * wu ? "yes"
                                                           : "no");
        }
        fprintf(o, "\n");
    }
    fprintf(o, "\n");
    if (flagged)
        fprintf(o, "⚠ the fitted order differs from the paper's by more than %.1f%s.\n\n",
                ORDER_TOLERANCE,
                quick ? " (a quick run fits coarser resolutions and shorter times than the "
                        "paper's)"
                      : "");
    fprintf(o,
            "T_r: wall time of the time steps at the finest resolution relative to series '%s' "
            "(set-up and packing excluded).\n\n",
            f->series[ref].label);
    if (devices) device_line(o, f, plans, rows);
    for (int k = 0; k < f->nseries; ++k)
        for (int j = 0; j < plans[k].nnx; ++j)
            if (rows[k][j].status != CONSPH_OK)
                fprintf(o, "- %s, nx %g diverged, left out of the fit: %s\n", f->series[k].label,
                        plans[k].nx[j], rows[k][j].why);
    outcome_table(o, s, f, plans, rows);
    if (x == X_TIME) momentum_table(o, s, f, plans, rows);
    fprintf(o, "<details><summary>every run</summary>\n\n| series | nx | N | steps | Δt | h | "
               "L1(u) | L1(p) | L∞(u) | L∞(p) | F_T/F_max | seconds | regularisations "
               "|\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int k = 0; k < f->nseries; ++k)
        for (int j = 0; j < plans[k].nnx; ++j) {
            const consph_run_summary *w = &rows[k][j].sum;
            fprintf(o,
                    "| %s | %g | %zu | %ld | %.4g | %.4g | %.3e | %.3e | %.3e | %.3e | %.2e | "
                    "%.3g | %ld |\n",
                    f->series[k].label, plans[k].nx[j], w->n, w->steps, w->dt, w->h, w->l1_u,
                    w->l1_p, w->linf_u, w->linf_p, w->ft_fmax, w->seconds, w->regularisations);
        }
    fprintf(o, "\n</details>\n\n");
    study_published_values(s, f, o);
    if (!run_plottable(f, plans, rows, x))
        fprintf(o, "No figure: the problem has no exact solution, so no errors to plot.\n\n");
    else
        study_md_figure(o, f->id);
    return consph_outfile_commit(&of);
}

/* The line of a figure's title that says what ran: t_f (or the steps, and the time the first
 * series' finest run reached), the resolutions, and for a quick run the paper's beside them. */
static void ran_text(const consph_study *s, const study_figure *f, int quick, const run_plan *plans,
                     run_row (*rows)[MAX_SWEEP], char *buf, size_t size)
{
    const run_plan *pl = &plans[0];
    size_t len;
    if (pl->prm.steps > 0)
        len = (size_t)snprintf(buf, size, "ran: %ld step%s (t = %.4g at nx %g), ", pl->prm.steps,
                               pl->prm.steps == 1 ? "" : "s", rows[0][pl->nnx - 1].sum.t,
                               pl->nx[pl->nnx - 1]);
    else
        len = (size_t)snprintf(buf, size, "ran: t_f = %g, ", pl->prm.tf);
    study_list_text(buf, size, &len, "nx", pl->nx, pl->nnx);
    /* c_o, where every series ran at one (001 Table 8 sweeps it across series) */
    int one_c0 = 1;
    for (int k = 1; k < f->nseries; ++k) one_c0 = one_c0 && rows[k][0].sum.c0 == rows[0][0].sum.c0;
    if (len < size && one_c0)
        len += (size_t)snprintf(buf + len, size - len, ", c_o = %g", rows[0][0].sum.c0);
    if (len < size)
        len += (size_t)snprintf(buf + len, size - len, " (%s", quick ? "quick" : "full study");
    /* A quick run's full-study values beside it, where they differ. */
    double nxs[MAX_SWEEP], full_tf = pl->prm.tf;
    int n = 0, same = 1;
    const char *tf = study_get(s, f, &f->series[0], "tf");
    const char *steps = study_get(s, f, &f->series[0], "steps");
    if (study_get_list(s, f, &f->series[0], "nx", 4, 1e5, nxs, &n) != CONSPH_OK) n = 0;
    same = n == pl->nnx;
    for (int j = 0; same && j < n; ++j) same = nxs[j] == pl->nx[j];
    if (tf) full_tf = strtod(tf, NULL);
    if (steps)
        same = same && strtol(steps, NULL, 10) == pl->prm.steps;
    else
        same = same && full_tf == pl->prm.tf && pl->prm.steps <= 0;
    if (quick && !same && len < size) {
        len += (size_t)snprintf(buf + len, size - len, "; full study: ");
        if (steps)
            len += (size_t)snprintf(buf + len, size - len, "%s step%s, ", steps,
                                    strcmp(steps, "1") == 0 ? "" : "s");
        else if (tf)
            len += (size_t)snprintf(buf + len, size - len, "t_f = %s, ", tf);
        if (n) study_list_text(buf, size, &len, "nx", nxs, n);
    }
    if (len < size) snprintf(buf + len, size - len, ")");
}

/* One panel: column `col` of the data (2: L1(u), 3: L1(p)) against column `xcol`, cropped to the
 * points drawn, with the paper's value `paper_key` of each series at the paper's finest nx (the
 * open form of the series' marker, its own key entry) and, against nx, a slope -2 guide. */
static int gp_panel(FILE *o, const consph_study *s, const study_figure *f, const run_plan *plans,
                    run_row (*rows)[MAX_SWEEP], int xcol, int col, const char *paper_key,
                    const char *ylabel)
{
    int rc = CONSPH_OK;
    fprintf(o, "set ylabel '%s'\n", ylabel);
    double y0 = INFINITY, x0 = NAN;
    double paper_x[MAX_SERIES_POINTS];
    int paper_pt[MAX_SERIES_POINTS] = {0};
    study_extent ex, ey;
    study_extent_init(&ex);
    study_extent_init(&ey);
    for (int k = 0; k < f->nseries; ++k) {
        double y = col == 2 ? rows[k][0].sum.l1_u : rows[k][0].sum.l1_p;
        if (rows[k][0].status == CONSPH_OK && y > 0 && y < y0) {
            y0 = y;
            x0 = plans[k].nx[0];
        }
        for (int j = 0; j < plans[k].nnx; ++j) {
            const run_row *w = &rows[k][j];
            const double yj = col == 2 ? w->sum.l1_u : w->sum.l1_p;
            if (w->status != CONSPH_OK || !(yj > 0) || !isfinite(yj)) continue;
            study_extent_add(&ex, xcol == 1 ? plans[k].nx[j] : w->sum.seconds, 1);
            study_extent_add(&ey, yj, 1);
        }
        double nxs[MAX_SWEEP], py;
        int n = 0;
        if (k < MAX_SERIES_POINTS && xcol == 1 &&
            study_paper_number(s, f, &f->series[k], paper_key, &py) && py > 0 &&
            study_get_list(s, f, &f->series[k], "nx", 4, 1e5, nxs, &n) == CONSPH_OK && n) {
            fprintf(o, "$paper%d_%d << EOD\n%.10g %.10g\nEOD\n", col, k, nxs[n - 1], py);
            study_extent_add(&ex, nxs[n - 1], 1);
            study_extent_add(&ey, py, 1);
            paper_pt[k] = 1;
            paper_x[k] = nxs[n - 1];
        }
    }
    int guide = xcol == 1 && isfinite(y0);
    /* the guide's start stays in the frame */
    if (guide) study_extent_add(&ey, 0.5 * y0, 1);
    study_gp_range(o, "x", &ex, 1);
    study_gp_range(o, "y", &ey, 1);
    if (xcol == 1) {
        double tics[MAX_SWEEP + MAX_SERIES_POINTS];
        int nt = 0;
        for (int j = 0; j < plans[0].nnx; ++j) tics[nt++] = plans[0].nx[j];
        for (int k = 0; k < f->nseries && k < MAX_SERIES_POINTS; ++k)
            if (paper_pt[k]) tics[nt++] = paper_x[k];
        study_gp_tics(o, "x", tics, nt);
    }
    if (guide) fprintf(o, "ref(x) = %.10g*(x/%.10g)**(-2)\n", 0.5 * y0, x0);
    fprintf(o, "plot");
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
        fprintf(o, "%s '%s.dat' index %d using %d:%d with linespoints", k ? ", \\\n    " : " ",
                f->id, k, xcol, col);
        study_gp_style(o, k);
        fprintf(o, " title ");
        rc = study_gp_put(o, f->series[k].label);
    }
    for (int k = 0; rc == CONSPH_OK && k < f->nseries && k < MAX_SERIES_POINTS; ++k) {
        if (!paper_pt[k]) continue;
        char text[320];
        snprintf(text, sizeof text, "%s: paper (nx %g)", f->series[k].label, paper_x[k]);
        fprintf(o, ", \\\n    $paper%d_%d with points", col, k);
        study_gp_paper_style(o, k);
        fprintf(o, " title ");
        rc = study_gp_put(o, text);
    }
    if (guide)
        fprintf(o, ", \\\n    ref(x) with lines dashtype 2 lw 2 lc rgb 'gray40' title 'slope -2 "
                   "(second order)'");
    fprintf(o, "\n");
    return rc;
}

/* x = time: the y range of the series that completed, so that the last steps of a diverging
 * one, orders of magnitude off, do not flatten the others (its line leaves the frame). */
static void y_range(FILE *o, const study_figure *f, const run_plan *plans,
                    run_row (*rows)[MAX_SWEEP], int col)
{
    double lo = INFINITY, hi = -INFINITY;
    for (int k = 0; k < f->nseries; ++k) {
        const run_row *w = &rows[k][plans[k].nnx - 1];
        for (size_t i = 0; w->status == CONSPH_OK && i < w->ncurve; ++i) {
            lo = fmin(lo, w->curve[4 * i + (size_t)col - 1]);
            hi = fmax(hi, w->curve[4 * i + (size_t)col - 1]);
        }
    }
    if (!(lo <= hi)) {
        fprintf(o, "set autoscale y\n");
        return;
    }
    const double pad = hi > lo ? 0.05 * (hi - lo) : fmax(1e-12, 1e-6 * fabs(hi));
    fprintf(o, "set yrange [%.12g:%.12g]\n", lo - pad, hi + pad);
}

/* x = radius or time: FIGURE-SUFFIX.dat, per series with a curve a block of its rows, and
 * one panel per quantity: u_φ against r with the exact profile in black (x = radius), or each
 * quantity of `y` against t (x = time). */
static int write_curve_plot(const consph_study *s, const study_figure *f, const char *dir,
                            const char *title, const char *ran, const run_plan *plans,
                            run_row (*rows)[MAX_SWEEP], int x)
{
    const curve_kind *ck = &curve_kinds[x];
    int ys[MAX_PANELS], ny, rc = run_y_panels(s, f, x, ys, &ny);
    if (rc) return rc;
    char name[160];
    snprintf(name, sizeof name, "%s-%s", f->id, ck->suffix);
    consph_outfile of;
    if ((rc = study_open_output(&of, dir, name, ".dat"))) return rc;
    /* Only series with a curve get a block: gnuplot does not count a block without data. */
    for (int k = 0; k < f->nseries; ++k) {
        const run_row *w = &rows[k][plans[k].nnx - 1];
        if (w->ncurve == 0) continue;
        fprintf(of.fp, "# %s: %s\n", f->series[k].label, ck->columns);
        for (size_t i = 0; i < w->ncurve; ++i)
            for (int c = 0; c < ck->ncols; ++c)
                fprintf(of.fp, "%.*g%s", ck->digits, w->curve[(size_t)ck->ncols * i + (size_t)c],
                        c + 1 < ck->ncols ? " " : "\n");
        fprintf(of.fp, "\n\n");
    }
    if ((rc = consph_outfile_commit(&of))) return rc;
    if ((rc = study_open_output(&of, dir, f->id, ".gp"))) return rc;
    FILE *o = of.fp;
    rc = study_gp_head(o, f->id, title, ran);
    fprintf(o, "set xlabel '%s'\n%s", ck->xlabel,
            x == X_TIME ? "set autoscale xfix\nset format y '%.6g'\n" : "");
    if (ny > 1) {
        fprintf(o, "set multiplot layout %d,1 title ", ny);
        if (rc == CONSPH_OK) rc = study_gp_title(o, title, ran);
        /* Panels of one width whether or not they carry the key. */
        fprintf(
            o,
            " noenhanced\nunset title\nset lmargin at screen 0.14\nset rmargin at screen 0.72\n");
    }
    int n = 0;
    for (int panel = 0; rc == CONSPH_OK && panel < ny; ++panel) {
        /* x = radius draws u_φ (column 2); x = time the panel's quantity (y_names order). */
        const int col = x == X_TIME ? 2 + ys[panel] : 2;
        fprintf(o, "set ylabel '%s'\n%s", x == X_TIME ? y_labels[ys[panel]] : "u_φ",
                panel ? "unset key\n" : "");
        if (x == X_TIME) y_range(o, f, plans, rows, col);
        fprintf(o, "plot");
        n = 0;
        for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
            if (rows[k][plans[k].nnx - 1].ncurve == 0)
                continue; /* x = radius: a diverged run has none */
            fprintf(o, "%s '%s.dat' index %d using 1:%d with %s", n ? ", \\\n    " : " ", name, n,
                    col, ck->style);
            study_gp_style(o, k);
            /* a history has a row per step: a marker every tenth of it, the interval differing
             * per series so that the markers of curves on top of each other fall apart */
            const size_t nc = rows[k][plans[k].nnx - 1].ncurve;
            if (x == X_TIME) fprintf(o, " pi %zu", (nc > 10 ? nc / 10 : 1) + (size_t)k);
            fprintf(o, " title ");
            ++n;
            /* a history that ends early says why: the run diverged there */
            const run_row *w = &rows[k][plans[k].nnx - 1];
            char label[192];
            if (w->status != CONSPH_OK)
                snprintf(label, sizeof label, "%s (diverged, t = %.3g)", f->series[k].label,
                         w->curve[(size_t)ck->ncols * (w->ncurve - 1)]);
            else
                snprintf(label, sizeof label, "%s", f->series[k].label);
            rc = study_gp_put(o, label);
        }
        if (n && x == X_RADIUS)
            fprintf(o,
                    ", \\\n    '%s.dat' index 0 using 1:3 smooth unique with lines lw 2 lc rgb "
                    "'black' title 'exact'",
                    name);
        fprintf(o, "\n");
    }
    if (ny > 1) fprintf(o, "unset multiplot\n");
    if (rc || n == 0) {
        consph_outfile_abort(&of);
        return rc;
    }
    if ((rc = consph_outfile_commit(&of))) return rc;
    return study_render_figure(dir, f->id);
}

int run_write_plot(const consph_study *s, const study_figure *f, const char *dir, int quick,
                   const run_plan *plans, run_row (*rows)[MAX_SWEEP], int x)
{
    const char *title = study_get_or(s, f, NULL, "title", f->id);
    char ran[512];
    ran_text(s, f, quick, plans, rows, ran, sizeof ran);
    consph_outfile of;
    int rc = study_open_output(&of, dir, f->id, ".dat");
    if (rc) return rc;
    for (int k = 0; k < f->nseries; ++k) {
        fprintf(of.fp, "# %s: nx l1_u l1_p seconds\n", f->series[k].label);
        for (int j = 0; j < plans[k].nnx; ++j)
            if (rows[k][j].status == CONSPH_OK)
                fprintf(of.fp, "%g %.10g %.10g %.10g\n", plans[k].nx[j], rows[k][j].sum.l1_u,
                        rows[k][j].sum.l1_p, rows[k][j].sum.seconds);
        fprintf(of.fp, "\n\n");
    }
    if ((rc = consph_outfile_commit(&of))) return rc;
    if (x >= X_RADIUS) return write_curve_plot(s, f, dir, title, ran, plans, rows, x);
    if ((rc = study_open_output(&of, dir, f->id, ".gp"))) return rc;
    FILE *o = of.fp;
    rc = study_gp_head(o, f->id, title, ran);
    fprintf(o, "set logscale xy\nset format y '%%g'\n");
    if (x == X_SECONDS) {
        fprintf(o, "set xlabel 'wall time of the time steps (s)'\n");
        if (rc == CONSPH_OK)
            rc = gp_panel(o, s, f, plans, rows, 4, 2, "paper.l1_u",
                          AUTHORS(&plans[0]) ? "L1(u), the measure of 001 authors"
                                             : "L1(u), 001 eq. 26");
    } else {
        /* Two panels of one width and one key, right of them: a key entry for every series
         * and every paper point. */
        fprintf(o, "set terminal svg size 1300,640 dynamic\nset output outfile\n"
                   "set xlabel 'particles per axis'\nset multiplot title ");
        if (rc == CONSPH_OK) rc = study_gp_title(o, title, ran);
        fprintf(o, " noenhanced\nunset key\nset tmargin at screen 0.86\nset bmargin at screen 0.1\n"
                   "set lmargin at screen 0.07\nset rmargin at screen 0.37\n"
                   "set title 'velocity'\n");
        if (rc == CONSPH_OK)
            rc = gp_panel(o, s, f, plans, rows, 1, 2, "paper.l1_u",
                          AUTHORS(&plans[0]) ? "L1(u), the measure of 001 authors"
                                             : "L1(u), 001 eq. 26");
        fprintf(o, "set key at screen 0.77,0.86 top left noenhanced font ',9' spacing 1.1\n"
                   "set lmargin at screen 0.45\nset rmargin at screen 0.75\n"
                   "set title 'pressure'\n");
        if (rc == CONSPH_OK)
            rc = gp_panel(o, s, f, plans, rows, 1, 3, "paper.l1_p",
                          AUTHORS(&plans[0]) ? "L1(p), the measure of 001 authors"
                                             : "L1(p), 001 eq. 26");
        fprintf(o, "unset multiplot\n");
    }
    return study_gp_finish(&of, rc, dir, f->id);
}
