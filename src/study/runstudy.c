/* Study kind `run`: the solver over a sweep of resolutions (001 Tables 8, 9, Fig. 20). Each
 * series is one scheme; each resolution one run of consph_run without files. The report gives
 * L1(u) and L1(p) (001 eq. 26, or with error = authors the measure of 001's authors and eq. 26
 * beside it) per nx, their fitted orders with standard errors, F_T/F_max at
 * the finest nx, T_r against a named series, and the paper's values beside ours. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/io.h"
#include "consph/solver.h"
#include "study/study_internal.h"

typedef struct run_plan {
    consph_run_params prm; /* nx and h_dt are set per run */
    int nnx;
    double nx[MAX_SWEEP];
    int dt_finest; /* 001: Δt from h of the finest resolution of the sweep, for every run */
    int l1_mean;   /* L1 divided by the time run: the mean error, which 001 Table 7 reports */
} run_plan;

/* With the authors' measure (key error = authors) a row's l1_u/l1_p are that measure, which the
 * fits, plots and tables use; eq. 26 is kept beside it. */
#define AUTHORS(pl) ((pl)->prm.error == CONSPH_ERROR_AUTHORS)

typedef struct run_row {
    consph_run_summary sum;
    double eq26_u, eq26_p; /* 001 eq. 26 as the study reports it (key l1) */
    int status;            /* CONSPH_OK, or CONSPH_ENUMERIC for a run that diverged */
    char why[256];
    char dt_warning[256]; /* Δt above its stability bound (consph_solver_dt_warning), or "" */
    /* The finest run's curve (curve_kinds[x]): x = radius, r, u_φ and the exact u_φ per particle
     * at the end; x = time, t, M_x, M_y and L per step. ncurve rows. */
    double *curve;
    size_t ncurve;
} run_row;

/* The abscissae of a figure (key x). */
enum { X_NX, X_SECONDS, X_RADIUS, X_TIME };

/* A figure of each series' finest run, one block of rows per series in FIGURE-SUFFIX.dat. */
typedef struct curve_kind {
    const char *suffix, *columns, *xlabel, *style;
    int ncols;
    int digits; /* a drift of L of 1e-6 relative must show in the history */
} curve_kind;

static const curve_kind curve_kinds[] = {
    [X_RADIUS] = {"profile", "r u_phi u_phi_exact", "r", "points pt 7 ps 0.4", 3, 8},
    [X_TIME] = {"history", "t momentum_x momentum_y angular_momentum", "t", "lines lw 1.5", 4, 12},
};

/* x = time: the quantities of `y`, one panel each, and their columns in the history. */
static const char *const y_names[] = {"momentum_x", "momentum_y", "angular_momentum", NULL};
static const char *const y_labels[] = {"M_x = Σ m u_x", "M_y = Σ m u_y", "L = Σ m (x u_y - y u_x)"};
#define MAX_PANELS 3

/* `quick.KEY` in a quick run when set, else KEY. */
static const char *quick_key(const consph_study *s, const study_figure *f, const study_series *r,
                             int quick, const char *key, char *buf, size_t size)
{
    snprintf(buf, size, "quick.%s", key);
    return quick && study_get(s, f, r, buf) ? buf : key;
}

/* The parameters of a run from the keys of the parameter table (consph_run_param_at: a key
 * sets its parameter through consph_run_param_set), then the keys of the study itself. */
static int plan_build(const consph_study *s, const study_figure *f, const study_series *r,
                      int quick, run_plan *pl)
{
    static const char *const rules[] = {"finest", "own", NULL};
    static const char *const l1s[] = {"integral", "mean", NULL};
    memset(pl, 0, sizeof *pl);
    consph_run_params *p = &pl->prm;
    consph_run_params_default(p);
    int rc, rule;
    char qk[32];
    /* The problem first: its own defaults (Gresho-Chan: inviscid, t = 3, lattice), which the
     * keys below override. */
    const char *v = study_get(s, f, r, "problem");
    if (v && consph_run_param_set(p, "problem", v) != CONSPH_OK)
        return study_key_error(s, f, r, "problem", "%s", consph_last_error());
    if ((rc = consph_run_params_problem(p, p->problem))) return rc;
    if (!study_get(s, f, r, "scheme"))
        return study_key_error(s, f, r, "scheme", "not given; allowed: %s", consph_scheme_names());
    for (int j = 0; j < consph_run_param_count(); ++j) {
        const consph_run_param *d = consph_run_param_at(j);
        if (!d->study_key || !strcmp(d->name, "problem") || (d->flags & CONSPH_PFLAG_NX)) continue;
        const char *k = d->flags & CONSPH_PFLAG_QUICK
                            ? quick_key(s, f, r, quick, d->study_key, qk, sizeof qk)
                            : d->study_key;
        if (!(v = study_get(s, f, r, k))) continue;
        /* "default": the problem's layout, else the scheme's */
        if (d->type == CONSPH_PTYPE_LAYOUT && !strcmp(v, "default")) continue;
        if (consph_run_param_set(p, d->name, v) != CONSPH_OK)
            return study_key_error(s, f, r, k, "%s", consph_last_error());
    }
    if (study_get(s, f, r, "re")) p->nu = -1.0; /* ν from the Re given, not the problem's */
    /* A step count replaces the final time: both given, one would be ignored. */
    char qt[16];
    const char *k = quick_key(s, f, r, quick, "steps", qk, sizeof qk);
    const char *tk = quick_key(s, f, r, quick, "tf", qt, sizeof qt);
    if (study_get(s, f, r, k) && study_get(s, f, r, tk))
        return study_key_error(s, f, r, k, "conflicts with '%s' (line %d); give one of them", tk,
                               study_line(s, f, r, tk));
    if ((rc = study_get_choice(s, f, r, "dt_rule", rules, 0, &rule))) return rc;
    pl->dt_finest = rule == 0;
    if ((rc = study_get_choice(s, f, r, "l1", l1s, 0, &pl->l1_mean))) return rc;
    k = quick_key(s, f, r, quick, "nx", qk, sizeof qk);
    if ((rc = study_get_list(s, f, r, k, 4, 1e5, pl->nx, &pl->nnx))) return rc;
    if (pl->nnx == 0) return study_key_error(s, f, r, "nx", "no resolutions given");
    for (int j = 0; j < pl->nnx; ++j)
        if (pl->nx[j] != floor(pl->nx[j]) || (j && !(pl->nx[j] > pl->nx[j - 1])))
            return study_key_error(s, f, r, k, "resolutions must be whole and increasing");
    p->nx = (int)pl->nx[pl->nnx - 1];
    if (consph_run_nx_check(p->nx, consph_problem_dim(p->problem)) != CONSPH_OK)
        return study_key_error(s, f, r, k, "%s", consph_last_error());
    if (consph_run_params_check(p) != CONSPH_OK)
        return study_key_error(s, f, r, "scheme", "%s", consph_last_error());
    /* as consph run's options: a series' key setting a parameter its scheme does not read would
     * do nothing; a figure's or the study's is a default for every series and stays allowed */
    char list[512];
    for (int j = 0; j < consph_run_param_count(); ++j) {
        const consph_run_param *d = consph_run_param_at(j);
        if (!d->reads || !d->study_key || !study_series_sets(s, f, r, d->study_key) ||
            (!strcmp(d->name, "eos") && p->eos == CONSPH_EOS_DEFAULT) ||
            consph_scheme_reads(p->scheme, d->reads))
            continue;
        return study_key_error(s, f, r, d->study_key,
                               "does nothing for the scheme %s (it acts on: %s)", p->scheme,
                               consph_scheme_readers(d->reads, list, sizeof list));
    }
    const int lk = consph_run_params_layout(p);
    if (study_series_sets(s, f, r, "seed") && !consph_layout_uses_seed((consph_layout_kind)lk))
        return study_key_error(s, f, r, "seed",
                               "does nothing for the layout %s, which draws no random numbers "
                               "(it acts on: %s)",
                               consph_layout_name((consph_layout_kind)lk),
                               consph_layout_seeded_names(list, sizeof list));
    return CONSPH_OK;
}

/* The series T_r is relative to: `tr_ref` names it (001 Table 9 is relative to EWCSPH), else
 * the first. */
static int tr_reference(const consph_study *s, const study_figure *f, int *ref)
{
    const char *v = study_get(s, f, NULL, "tr_ref");
    *ref = 0;
    if (!v) return CONSPH_OK;
    for (int k = 0; k < f->nseries; ++k)
        if (strcmp(f->series[k].label, v) == 0) {
            *ref = k;
            return CONSPH_OK;
        }
    return study_key_error(s, f, NULL, "tr_ref", "no series '%s' in this figure", v);
}

/* The abscissa of the figure: nx, the wall time (001 Fig. 20), the radius (u_φ(r) of a
 * centred vortex at the end of the finest run, 001 Figs. 15-16) or the time (the momentum
 * histories of the finest run, 001 Figs. 15-17). */
static int x_axis(const consph_study *s, const study_figure *f, int *x)
{
    static const char *const xs[] = {"nx", "seconds", "radius", "time", NULL};
    return study_get_choice(s, f, NULL, "x", xs, X_NX, x);
}

/* The panels of an x = time figure: `y`, one or more of y_names separated by commas (default
 * momentum_x), each once; *ys gets their indices. `y` with another x is an error. */
static int y_panels(const consph_study *s, const study_figure *f, int x, int *ys, int *ny)
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

int study_run_validate(const consph_study *s, const study_figure *f, int quick)
{
    int rc, dummy;
    for (int k = 0; k < f->nseries; ++k) {
        run_plan pl;
        if ((rc = plan_build(s, f, &f->series[k], quick, &pl))) return rc;
    }
    int x, ys[MAX_PANELS];
    if ((rc = tr_reference(s, f, &dummy))) return rc;
    if ((rc = x_axis(s, f, &x))) return rc;
    return y_panels(s, f, x, ys, &dummy);
}

/* Particles of a run at resolution nx: nx^d in the problem's dimension. */
static double particles_of(const run_plan *pl, double nx)
{
    return consph_problem_dim(pl->prm.problem) == 3 ? nx * nx * nx : nx * nx;
}

/* Steps of a run at resolution nx (an estimate: h = hdx/nx on a unit box). */
static double steps_of(const run_plan *pl, double nx)
{
    const consph_run_params *p = &pl->prm;
    if (p->steps > 0) return (double)p->steps;
    if (p->dt > 0) return ceil(p->tf / p->dt);
    double c0 = p->c0 > 0 ? p->c0 : 10.0 * p->U;
    double h = p->hdx / (pl->dt_finest ? pl->nx[pl->nnx - 1] : nx);
    return ceil(p->tf / (p->cfl * h / (p->U + c0)));
}

double study_run_estimate(const consph_study *s, const study_figure *f, int quick,
                          double *particle_steps)
{
    run_plan first, pl;
    double made = 0.0;
    *particle_steps = 0.0;
    for (int k = 0; k < f->nseries; ++k) {
        if (plan_build(s, f, &f->series[k], quick, &pl) != CONSPH_OK) return NAN;
        if (k == 0) first = pl;
        for (int j = 0; j < pl.nnx; ++j) {
            *particle_steps += particles_of(&pl, pl.nx[j]) * steps_of(&pl, pl.nx[j]);
            made += particles_of(&pl, pl.nx[j]);
        }
    }
    if (f->nseries == 0) return 0.0;
    /* Calibration: 16² (3D: 8³) particles, 20 steps of the first series, set-up (packing) timed
     * apart. */
    consph_run_params p = first.prm;
    p.nx = consph_problem_dim(p.problem) == 3 ? 8 : 16;
    const double ncal = particles_of(&first, p.nx);
    p.steps = 20;
    p.h_dt = 0.0;
    consph_solver *sv = NULL;
    consph_run_summary sum;
    int stopped;
    double t0 = consph_wtime();
    if (consph_solver_create(&sv, &p) != CONSPH_OK) return NAN;
    double per_made = (consph_wtime() - t0) / ncal;
    int rc = consph_run(sv, NULL, &sum, &stopped);
    consph_solver_free(sv);
    if (rc != CONSPH_OK || sum.steps <= 0) return NAN;
    return *particle_steps * sum.seconds / (ncal * (double)sum.steps) + made * per_made;
}

/* u_φ(r) about the centre of the box, with the exact u_φ, per particle at the end of a run. */
static int keep_profile(consph_solver *sv, run_row *row)
{
    int rc = consph_solver_output_fields(sv);
    if (rc) return rc;
    const consph_particles *p = consph_solver_particles(sv);
    const consph_field *fu = consph_particles_find(p, "u");
    const consph_field *fe = consph_particles_find(p, "u_exact");
    if (!fu || !fe || p->dim != 2)
        return consph_fail(CONSPH_EINVAL, "x = radius needs a 2D run with u and u_exact");
    row->curve = malloc(3 * p->n * sizeof *row->curve);
    if (!row->curve) return consph_fail(CONSPH_ENOMEM, "out of memory");
    row->ncurve = p->n;
    const size_t cap = p->cap;
    const double xc = 0.5 * (p->box.lo[0] + p->box.hi[0]), yc = 0.5 * (p->box.lo[1] + p->box.hi[1]);
    for (size_t i = 0; i < p->n; ++i) {
        const double x = p->x[0][i] - xc, y = p->x[1][i] - yc, r = hypot(x, y);
        const double *u = fu->data, *e = fe->data;
        row->curve[3 * i] = r;
        row->curve[3 * i + 1] = r > 0.0 ? (x * u[cap + i] - y * u[i]) / r : 0.0;
        row->curve[3 * i + 2] = r > 0.0 ? (x * e[cap + i] - y * e[i]) / r : 0.0;
    }
    return CONSPH_OK;
}

/* t, M_x, M_y and L of every step the run took (a diverged run's up to its last finite step). */
static int keep_history(const consph_solver *sv, run_row *row)
{
    const size_t n = consph_solver_history_size(sv);
    row->curve = malloc(4 * (n ? n : 1) * sizeof *row->curve);
    if (!row->curve) return consph_fail(CONSPH_ENOMEM, "out of memory");
    row->ncurve = n;
    for (size_t k = 0; k < n; ++k) {
        consph_step_diag d;
        int rc = consph_solver_history_row(sv, k, &d);
        if (rc) return rc;
        double *c = row->curve + 4 * k;
        c[0] = d.t;
        c[1] = d.mom[0];
        c[2] = d.mom[1];
        c[3] = d.ang;
    }
    return CONSPH_OK;
}

/* One run; `curve` (X_RADIUS, X_TIME, else none) keeps that curve of it. */
static int run_one(const run_plan *pl, int j, double h_dt, int curve, run_row *row)
{
    consph_run_params p = pl->prm;
    p.nx = (int)pl->nx[j];
    p.h_dt = h_dt;
    consph_solver *sv = NULL;
    int rc = consph_solver_create(&sv, &p);
    if (rc) return rc;
    if (!consph_solver_dt_warning(sv, row->dt_warning, sizeof row->dt_warning))
        row->dt_warning[0] = '\0';
    int stopped = 0;
    rc = consph_run(sv, NULL, &row->sum, &stopped);
    if (rc == CONSPH_OK && curve == X_RADIUS) rc = keep_profile(sv, row);
    /* A diverged run's history is kept too: it shows how it got there. */
    if ((rc == CONSPH_OK || rc == CONSPH_ENUMERIC) && curve == X_TIME) {
        int hr = keep_history(sv, row);
        if (hr) rc = hr;
    }
    consph_solver_free(sv);
    row->status = rc;
    if (pl->l1_mean && row->sum.t > 0) {
        row->sum.l1_u /= row->sum.t;
        row->sum.l1_p /= row->sum.t;
    }
    row->eq26_u = row->sum.l1_u;
    row->eq26_p = row->sum.l1_p;
    if (AUTHORS(pl)) {
        row->sum.l1_u = row->sum.l1n_u;
        row->sum.l1_p = row->sum.l1n_p;
    }
    /* A diverged run is a result of the study, reported, not the end of it. */
    if (rc == CONSPH_ENUMERIC) {
        snprintf(row->why, sizeof row->why, "%s", consph_last_error());
        return CONSPH_OK;
    }
    return rc;
}

/* The order of L1(u) (which = 0) or L1(p) over the runs that finished, as text. */
static double fit_text(const run_plan *pl, const run_row *rows, int which, char *buf, size_t size)
{
    double xs[MAX_SWEEP], ys[MAX_SWEEP];
    int n = 0;
    for (int j = 0; j < pl->nnx; ++j) {
        if (rows[j].status != CONSPH_OK) continue;
        xs[n] = pl->nx[j];
        ys[n++] = which ? rows[j].sum.l1_p : rows[j].sum.l1_u;
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
static int plottable(const study_figure *f, const run_plan *plans, run_row (*rows)[MAX_SWEEP],
                     int x)
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
static const char *run_title(const consph_study *s, const study_figure *f, int quick,
                             const run_plan *pl, char *buf, size_t size)
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

static int write_report(const consph_study *s, const study_figure *f, int quick, const char *dir,
                        const run_plan *plans, run_row (*rows)[MAX_SWEEP], int ref, int x,
                        const char *title)
{
    char label[128];
    consph_outfile of;
    int rc = study_open_output(&of, dir, f->id, ".csv");
    if (rc) return rc;
    int auth = 0;
    for (int k = 0; k < f->nseries; ++k) auth |= AUTHORS(&plans[k]);
    fprintf(of.fp,
            "series,scheme,c0,nx,n,steps,t,dt,h,l1_u,l1_p,linf_u,linf_p,ft_over_fmax,"
            "seconds,pairs,regularisations,status%s\n",
            auth ? ",l1_u_eq26,l1_p_eq26" : "");
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
    fprintf(o,
            "| series | scheme | c_o | L1(u) at finest | paper L1(u) | %sorder u | paper | "
            "L1(p) at finest | paper L1(p) | %sorder p | paper | F_T/F_max | paper | T_r | "
            "paper T_r |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|%s\n",
            auth ? "eq. 26 L1(u) | " : "", auth ? "eq. 26 L1(p) | " : "", auth ? "---|---|" : "");
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
                "%s | %.2f | %s |\n",
                r->label, plans[k].prm.scheme, last->sum.c0, last->sum.l1_u,
                plans[k].nx[plans[k].nnx - 1], last->status ? ", diverged" : "",
                study_get_or(s, f, r, "paper.l1_u", "—"), e26u, cu,
                study_get_or(s, f, r, "paper.order_u", "—"), last->sum.l1_p,
                study_get_or(s, f, r, "paper.l1_p", "—"), e26p, cp,
                study_get_or(s, f, r, "paper.order_p", "—"), last->sum.ft_fmax,
                study_get_or(s, f, r, "paper.ft", "—"), last->sum.seconds / rref->sum.seconds,
                study_get_or(s, f, r, "paper.tr", "—"));
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
    if (!plottable(f, plans, rows, x))
        fprintf(o, "No figure: the problem has no exact solution, so no errors to plot.\n\n");
    else if (study_have_gnuplot())
        fprintf(o, "![%s](%s.svg)\n\n", f->id, f->id);
    return consph_outfile_commit(&of);
}

/* One panel: column `col` of the data (2: L1(u), 3: L1(p)) against column `xcol`, with the
 * paper's value `paper_key` at the paper's finest nx and, against nx, a slope -2 guide. */
static int gp_panel(FILE *o, const consph_study *s, const study_figure *f, const run_plan *plans,
                    run_row (*rows)[MAX_SWEEP], int xcol, int col, const char *paper_key,
                    const char *ylabel)
{
    int rc = CONSPH_OK;
    fprintf(o, "set ylabel '%s'\n", ylabel);
    double y0 = INFINITY, x0 = NAN;
    for (int k = 0; k < f->nseries; ++k) {
        double y = col == 2 ? rows[k][0].sum.l1_u : rows[k][0].sum.l1_p;
        if (rows[k][0].status == CONSPH_OK && y > 0 && y < y0) {
            y0 = y;
            x0 = plans[k].nx[0];
        }
        double nxs[MAX_SWEEP], py;
        int n = 0;
        if (xcol == 1 && study_paper_number(s, f, &f->series[k], paper_key, &py) && py > 0 &&
            study_get_list(s, f, &f->series[k], "nx", 4, 1e5, nxs, &n) == CONSPH_OK && n)
            fprintf(o, "$paper%d_%d << EOD\n%.10g %.10g\nEOD\n", col, k, nxs[n - 1], py);
    }
    int guide = xcol == 1 && isfinite(y0);
    if (guide) fprintf(o, "ref(x) = %.10g*(x/%.10g)**(-2)\n", 0.5 * y0, x0);
    fprintf(o, "plot");
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
        fprintf(o, "%s '%s.dat' index %d using %d:%d with linespoints lc %d title ",
                k ? ", \\\n    " : " ", f->id, k, xcol, col, k + 1);
        rc = study_gp_put(o, f->series[k].label);
    }
    int keyed = 0;
    for (int k = 0; xcol == 1 && k < f->nseries; ++k) {
        double py;
        if (!study_paper_number(s, f, &f->series[k], paper_key, &py) || !(py > 0)) continue;
        fprintf(o, ", \\\n    $paper%d_%d with points pt 6 ps 2 lw 2 lc %d %s", col, k, k + 1,
                keyed ? "notitle" : "title 'paper (series colour)'");
        keyed = 1;
    }
    if (guide)
        fprintf(o, ", \\\n    ref(x) with lines dashtype 2 lw 2 lc rgb 'gray40' title 'slope -2'");
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
                            const char *title, const run_plan *plans, run_row (*rows)[MAX_SWEEP],
                            int x)
{
    const curve_kind *ck = &curve_kinds[x];
    int ys[MAX_PANELS], ny, rc = y_panels(s, f, x, ys, &ny);
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
    rc = study_gp_head(o, f->id, title);
    fprintf(o, "set xlabel '%s'\n%s", ck->xlabel,
            x == X_TIME ? "set autoscale xfix\nset format y '%.6g'\n" : "");
    if (ny > 1) {
        fprintf(o, "set multiplot layout %d,1 title ", ny);
        if (rc == CONSPH_OK) rc = study_gp_put(o, title);
        /* Panels of one width whether or not they carry the key. */
        fprintf(
            o, " noenhanced\nunset title\nset lmargin at screen 0.14\nset rmargin at screen 0.8\n");
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
            fprintf(o, "%s '%s.dat' index %d using 1:%d with %s lc %d ", n ? ", \\\n    " : " ",
                    name, n, col, ck->style, k + 1);
            /* gnuplot's colours repeat after 8: lines past them are dashed */
            if (x == X_TIME) fprintf(o, "dt %d ", 1 + k / 8);
            fprintf(o, "title ");
            ++n;
            rc = study_gp_put(o, f->series[k].label);
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

static int write_plot(const consph_study *s, const study_figure *f, const char *dir,
                      const char *title, const run_plan *plans, run_row (*rows)[MAX_SWEEP], int x)
{
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
    if (x >= X_RADIUS) return write_curve_plot(s, f, dir, title, plans, rows, x);
    if ((rc = study_open_output(&of, dir, f->id, ".gp"))) return rc;
    FILE *o = of.fp;
    rc = study_gp_head(o, f->id, title);
    fprintf(o, "set logscale xy\nset format y '%%g'\n");
    if (x == X_SECONDS) {
        fprintf(o, "set xlabel 'wall time of the time steps (s)'\n");
        if (rc == CONSPH_OK)
            rc = gp_panel(o, s, f, plans, rows, 4, 2, "paper.l1_u",
                          AUTHORS(&plans[0]) ? "L1(u), the measure of 001 authors"
                                             : "L1(u), 001 eq. 26");
    } else {
        fprintf(o, "set xlabel 'particles per axis'\nset multiplot layout 1,2 title ");
        if (rc == CONSPH_OK) rc = study_gp_put(o, title);
        /* One key, for both panels, where the falling curves leave room. */
        fprintf(o, " noenhanced\nset key inside bottom left noenhanced font ',10'\n"
                   "set title 'velocity'\n");
        if (rc == CONSPH_OK)
            rc = gp_panel(o, s, f, plans, rows, 1, 2, "paper.l1_u",
                          AUTHORS(&plans[0]) ? "L1(u), the measure of 001 authors"
                                             : "L1(u), 001 eq. 26");
        fprintf(o, "unset key\nset title 'pressure'\n");
        if (rc == CONSPH_OK)
            rc = gp_panel(o, s, f, plans, rows, 1, 3, "paper.l1_p",
                          AUTHORS(&plans[0]) ? "L1(p), the measure of 001 authors"
                                             : "L1(p), 001 eq. 26");
        fprintf(o, "unset multiplot\n");
    }
    if (rc) {
        consph_outfile_abort(&of);
        return rc;
    }
    if ((rc = consph_outfile_commit(&of))) return rc;
    return study_render_figure(dir, f->id);
}

int study_run_figure(const consph_study *s, const study_figure *f, int quick, const char *dir,
                     FILE *log)
{
    int ref, x, rc = study_run_validate(s, f, quick);
    if (rc == CONSPH_OK) rc = tr_reference(s, f, &ref);
    if (rc == CONSPH_OK) rc = x_axis(s, f, &x);
    if (rc) return rc;
    run_plan *plans = calloc((size_t)f->nseries, sizeof *plans);
    run_row(*rows)[MAX_SWEEP] = calloc((size_t)f->nseries, sizeof *rows);
    if (!plans || !rows) rc = consph_fail(CONSPH_ENOMEM, "out of memory");
    double particle_steps = 0.0;
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
        rc = plan_build(s, f, &f->series[k], quick, &plans[k]);
        for (int j = 0; rc == CONSPH_OK && j < plans[k].nnx; ++j)
            particle_steps +=
                particles_of(&plans[k], plans[k].nx[j]) * steps_of(&plans[k], plans[k].nx[j]);
    }
    if (log && rc == CONSPH_OK)
        fprintf(log, "  %d series, about %.2g particle-steps\n", f->nseries, particle_steps);
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
        const run_plan *pl = &plans[k];
        /* The finest first: its h sets Δt of the whole sweep (dt_rule = finest). */
        double h_dt = 0.0;
        for (int j = pl->nnx - 1; rc == CONSPH_OK && j >= 0; --j) {
            run_row *w = &rows[k][j];
            rc = run_one(pl, j, h_dt, j == pl->nnx - 1 ? x : X_NX, w);
            if (rc) {
                consph_fail(rc, "figure '%s', series '%s', nx %g: %s", f->id, f->series[k].label,
                            pl->nx[j], consph_last_error());
                break;
            }
            if (pl->dt_finest && j == pl->nnx - 1) h_dt = w->sum.h;
            if (log)
                fprintf(log,
                        "  %-24s nx=%-5g N=%-7zu steps=%-7ld L1(u)=%.3e L1(p)=%.3e (%.2fs)%s\n",
                        f->series[k].label, pl->nx[j], w->sum.n, w->sum.steps, w->sum.l1_u,
                        w->sum.l1_p, w->sum.seconds, w->status ? " diverged" : "");
            if (log && w->dt_warning[0]) fprintf(log, "  warning: %s\n", w->dt_warning);
        }
    }
    char tbuf[640];
    const char *title = rc == CONSPH_OK ? run_title(s, f, quick, &plans[0], tbuf, sizeof tbuf) : "";
    if (rc == CONSPH_OK) rc = write_report(s, f, quick, dir, plans, rows, ref, x, title);
    if (rc == CONSPH_OK && plottable(f, plans, rows, x))
        rc = write_plot(s, f, dir, title, plans, rows, x);
    for (int k = 0; rows && k < f->nseries; ++k)
        for (int j = 0; j < MAX_SWEEP; ++j) free(rows[k][j].curve);
    free(plans);
    free(rows);
    return rc;
}
