/* Study kind `run`: the solver over a sweep of resolutions (runstudy.c runs it; its report
 * and plots are written by run_report.c). */
#ifndef CONSPH_STUDY_KINDS_RUN_H
#define CONSPH_STUDY_KINDS_RUN_H

#include <stdio.h>

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
/* With exact = both a row also has its errors against the weakly-compressible reference, in the
 * measure of l1_u/l1_p: the report adds them, their orders and whether the row is on the floor. */
#define WC_BOTH(pl) ((pl)->prm.exact == CONSPH_EXACT_BOTH)
/* On the floor: L1(u) against the incompressible solution more than twice that against the
 * weakly-compressible reference (the model's O(Ma²) departure, not the discretisation, makes
 * most of it). */
#define WC_FLOOR_RATIO 2.0

typedef struct run_row {
    consph_run_summary sum;
    double eq26_u, eq26_p; /* 001 eq. 26 as the study reports it (key l1) */
    int status;            /* CONSPH_OK, or CONSPH_ENUMERIC for a run that diverged */
    int device;            /* the consph_device its steps ran on */
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
    [X_RADIUS] = {"profile", "r u_phi u_phi_exact", "r", "points ps 0.5", 3, 8},
    [X_TIME] = {"history", "t momentum_x momentum_y angular_momentum", "t", "linespoints lw 1.5", 4,
                12},
};

/* x = time: the quantities of `y`, one panel each, and their columns in the history. */
static const char *const y_names[] = {"momentum_x", "momentum_y", "angular_momentum", NULL};
static const char *const y_labels[] = {"M_x = Σ m u_x", "M_y = Σ m u_y", "L = Σ m (x u_y - y u_x)"};
#define MAX_PANELS 3

/* The panels of an x = time figure: `y`, one or more of y_names (default momentum_x). */
int run_y_panels(const consph_study *s, const study_figure *f, int x, int *ys, int *ny);
/* Whether the figure has points to plot. */
int run_plottable(const study_figure *f, const run_plan *plans, run_row (*rows)[MAX_SWEEP], int x);
/* The figure's title; a quick run's says what it ran. */
const char *run_title(const consph_study *s, const study_figure *f, int quick, const run_plan *pl,
                      char *buf, size_t size);
/* FIGURE.csv and FIGURE.md: the orders, the paper's values beside ours, every run; with
 * `devices` a line saying which device ran each row. */
int run_write_report(const consph_study *s, const study_figure *f, int quick, const char *dir,
                     const run_plan *plans, run_row (*rows)[MAX_SWEEP], int ref, int x,
                     const char *title, int devices);
/* FIGURE.dat, .gp and .svg (and FIGURE-profile/-history.dat for x = radius or time); the title
 * says what ran (t_f, resolutions, quick). */
int run_write_plot(const consph_study *s, const study_figure *f, const char *dir, int quick,
                   const run_plan *plans, run_row (*rows)[MAX_SWEEP], int x);

#endif
