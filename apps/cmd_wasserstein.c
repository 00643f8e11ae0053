/* consph wasserstein: the Wasserstein distance between the particle measures of two files. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "commands.h"
#include "consph/io.h"
#include "consph/transport.h"

#define METHOD_CHOICES "exact,sliced,sinkhorn"
#define FORMAT_CHOICES "table,json"
enum { FORMAT_TABLE, FORMAT_JSON };

static const char wasserstein_details[] =
    "Each file is a particle measure mu = sum_a m_a delta(x - x_a); the masses are the file's `m`\n"
    "column, else volume*rho (both columns), else equal, and each measure is normalised to total\n"
    "mass 1 (probability measures), so files of different N compare. The ground cost is |x-y|^p.\n"
    "\n"
    "methods (default: exact in 1D, sliced in 2D/3D):\n"
    "  exact     W_p from the sorted cumulative distributions; 1D only; O(N log N)\n"
    "  sliced    SW_p = (mean over K random directions of W_p^p of the projections)^(1/p),\n"
    "            directions from --seed; error = Monte Carlo standard error. SW_p <= W_p: a\n"
    "            different metric, not an estimate of W_p. O(K N log N)\n"
    "  sinkhorn  entropic transport in the log domain with eps-continuation down to\n"
    "            eps = --eps x C_max (C_max: the bounding-box diagonal to the p); reports\n"
    "            <pi,C>^(1/p) and a bound on its distance from W_p: the entropic bias\n"
    "            eps (min(H(r),H(b)) + KL(r|a)) plus C_max delta/2 for the marginal violation\n"
    "            delta, through the p-th root. O(N M) per iteration, O(N + M) memory\n"
    "\n"
    "B may be the word `uniform`: the uniform density on A's box, as the cell centres of a\n"
    "grid of --grid cells per axis. --smooth KERNEL replaces each particle measure by its SPH\n"
    "density sum_b m_b W(x - x_b, h), h = --hdx x the file's spacing, on the same kind of grid\n"
    "over the file's box (periodic axes wrap): the kernel-smoothed measure of 004. Comparing\n"
    "W(A, uniform) with and without --smooth separates the kernel limit (h) from the particle\n"
    "limit (N). Replacing a density by its grid moves no mass further than half a cell\n"
    "diagonal, so each gridded measure adds at most that to |W - W_exact|: reported apart as\n"
    "grid_error (the midpoint rule's error in the cell masses comes on top).\n"
    "\n"
    "A file without a box of its own (a CSV without the '# box' header) needs --box.\n"
    "Options of one method are refused with another, as they would do nothing: --directions\n"
    "and --seed are sliced's (in 2D/3D: 1D sliced is exact), --eps, --tol and --max-iter\n"
    "sinkhorn's; --grid needs --smooth or B = uniform, --hdx needs --smooth.\n"
    "\n"
    "Before any work the memory and time are estimated from the sizes: a comparison that\n"
    "needs more than 4 GiB (CONSPH_MEMORY_LIMIT=BYTES[K|M|G] sets this cap) or the memory the\n"
    "machine has available is refused (exit 2, naming --grid or the files, the estimate and\n"
    "the limit); one that may pass 10 s (Sinkhorn: 100 iterations) is announced on stderr,\n"
    "and on a terminal a progress line follows the smoothing and the Sinkhorn iterations.\n"
    "\n"
    "exit status: 0 success, 1 failure while running, 2 bad usage or input";

typedef struct input {
    const char *path;
    consph_particles p;
    consph_measure mu;
    double *scratch;
    consph_mass_origin origin;
    int loaded;
    consph_grid_measure grid; /* the smoothed or uniform measure that replaces mu, if any */
    int gridded;
} input;

static int load(const cli_command *cmd, const char *path, const consph_read_options *ro, input *in)
{
    in->path = path;
    consph_particle_format fmt;
    if (consph_particle_format_from_path(path, &fmt) != CONSPH_OK)
        return cli_error(cmd, "%s", consph_last_error());
    if (consph_read_particles(path, ro, &in->p, NULL) != CONSPH_OK) {
        fprintf(stderr, "consph wasserstein: %s\n", consph_last_error());
        return CLI_EXIT_USAGE;
    }
    in->loaded = 1;
    if (consph_measure_from_particles(&in->p, &in->mu, &in->scratch, &in->origin) != CONSPH_OK) {
        fprintf(stderr, "consph wasserstein: %s\n", consph_last_error());
        return 1;
    }
    return 0;
}

static void unload(input *in)
{
    if (in->loaded) consph_particles_free(&in->p);
    if (in->gridded) consph_grid_measure_free(&in->grid);
    free(in->scratch);
}

static const char *bytes_text(double b, char *buf, size_t size)
{
    if (b >= 1e9)
        snprintf(buf, size, "%.1f GB", b / 1e9);
    else if (b >= 1e6)
        snprintf(buf, size, "%.1f MB", b / 1e6);
    else
        snprintf(buf, size, "%.0f kB", b / 1e3);
    return buf;
}

/* A progress line on stderr, only on a terminal (as consph run's): logs see real messages. */
typedef struct progress {
    int enabled, shown;
    double t0, last;
    const char *what;
} progress;

static void progress_line(progress *pr, const char *fmt, double a, double b, double c)
{
    double now = consph_wtime();
    if (!pr->enabled || now - pr->last < 0.5) return;
    pr->last = now;
    pr->shown = 1;
    fprintf(stderr, "\r%s: ", pr->what);
    fprintf(stderr, fmt, a, b, c);
    fprintf(stderr, ", %.0f s\033[K", now - pr->t0);
    fflush(stderr);
}

static void grid_progress(void *ctx, double done, double total)
{
    progress *pr = ctx;
    double elapsed = consph_wtime() - pr->t0;
    progress_line(pr, "%.0f%% of %.3g cells, about %.0f s left", 100.0 * done / total, total,
                  done > 0 ? elapsed * (total - done) / done : NAN);
}

static void sinkhorn_progress(void *ctx, long iteration, double eps_abs, double marginal_error)
{
    progress_line(ctx, "iteration %.0f, eps %.3g, marginal violation %.2e", (double)iteration,
                  eps_abs, marginal_error);
}

static void progress_begin(progress *pr, const char *what)
{
    pr->enabled = isatty(STDERR_FILENO) == 1;
    pr->shown = 0;
    pr->t0 = consph_wtime();
    pr->last = pr->t0;
    pr->what = what;
}

static void progress_end(progress *pr)
{
    if (pr->shown) fprintf(stderr, "\r\033[K");
    pr->shown = 0;
}

/* Memory and time of the whole comparison, before any of it: what cannot fit is refused (naming
 * --grid when grids are involved, else the files), long work is announced. */
static int check_cost(const cli_command *cmd, const consph_ot_options *o, int dim, const input *in,
                      int uniform, int smoothing, long cells)
{
    const int threads = consph_num_threads();
    const double gridn = pow((double)cells, dim);
    double grid_bytes = 0.0, grid_seconds = 0.0, n[2];
    for (int k = 0; k < 2; ++k) {
        int gridded = k == 1 ? uniform || smoothing : smoothing;
        n[k] = gridded ? gridn : (double)in[k].mu.n;
        if (!gridded) continue;
        consph_ot_estimate g = consph_grid_measure_estimate(
            dim, (size_t)cells, k == 1 && uniform ? 0 : in[k].p.n, threads);
        grid_bytes += g.bytes;
        grid_seconds += g.seconds;
    }
    consph_ot_estimate t = consph_wasserstein_estimate(o, dim, n[0], n[1], threads);
    const double bytes = grid_bytes + t.bytes;
    double limit, cap, available;
    if (consph_memory_limit(&limit, &cap, &available))
        return cli_error(cmd, "%s", consph_last_error());
    char need[32], grids[32], trans[32], lim[32], capt[32], avail[32];
    bytes_text(bytes, need, sizeof need);
    bytes_text(grid_bytes, grids, sizeof grids);
    bytes_text(t.bytes, trans, sizeof trans);
    bytes_text(limit, lim, sizeof lim);
    bytes_text(cap, capt, sizeof capt);
    bytes_text(available, avail, sizeof avail);
    if (bytes > limit && grid_bytes > 0)
        return cli_error(cmd,
                         "option --grid: %ld cells per axis (%.3g cells in %dD) need about %s "
                         "(grids %s, transport %s on %d threads); the limit is %s (the cap %s, "
                         "CONSPH_MEMORY_LIMIT, or the %s available, whichever is less); allowed: "
                         "a smaller --grid",
                         cells, gridn, dim, need, grids, trans, threads, lim, capt, avail);
    if (bytes > limit)
        return cli_error(cmd,
                         "%s and %s: %.0f and %.0f points need about %s on %d threads; the limit "
                         "is %s (the cap %s, CONSPH_MEMORY_LIMIT, or the %s available, whichever "
                         "is less)",
                         in[0].path, in[1].path, n[0], n[1], need, threads, lim, capt, avail);
    /* Announced when it may pass ten seconds: Sinkhorn's iteration count is not known ahead
     * (W1 often takes thousands), so its estimate is per iteration with the cap's total. */
    const int sinkhorn = o->method == CONSPH_OT_SINKHORN;
    const double typical = grid_seconds + (sinkhorn ? 100.0 : 1.0) * t.seconds;
    if (typical >= 10.0) {
        fprintf(stderr, "consph wasserstein: estimate (rough, %d thread%s): memory %s", threads,
                threads == 1 ? "" : "s", need);
        if (grid_seconds > 0) fprintf(stderr, ", grids %.0f s", grid_seconds);
        if (sinkhorn)
            fprintf(stderr, ", %.3g s per Sinkhorn iteration (%.0f s at --max-iter %ld)", t.seconds,
                    t.seconds * (double)o->max_iter, o->max_iter);
        else
            fprintf(stderr, ", transport %.0f s", t.seconds);
        fprintf(stderr, "%s\n", isatty(STDERR_FILENO) ? "" : "; progress is shown on a terminal");
    }
    return 0;
}

/* Replaces the particle measure by its SPH density Σ m_b W(x − x_b, h) on a grid over the
 * particles' box, h = hdx × the file's spacing. */
static int smooth(const cli_command *cmd, const consph_kernel_id kid, double hdx, long cells,
                  input *in, progress *pr)
{
    consph_kernel k;
    int rc = consph_kernel_init(&k, kid, in->p.dim, hdx * in->p.spacing);
    progress_begin(pr, in->path);
    if (rc == CONSPH_OK)
        rc = consph_grid_measure_sph_progress(&in->p.box, (size_t)cells, &in->mu, &k, &in->grid,
                                              grid_progress, pr);
    progress_end(pr);
    if (rc != CONSPH_OK) return cli_error(cmd, "%s: %s", in->path, consph_last_error());
    in->gridded = 1;
    in->mu = in->grid.mu;
    return 0;
}

static const char *error_kind(consph_ot_method m)
{
    return m == CONSPH_OT_EXACT    ? "round-off only"
           : m == CONSPH_OT_SLICED ? "Monte Carlo standard error"
                                   : "bound: entropic bias + marginal violation";
}

/* The options, in the order of cmd_wasserstein's table. */
enum {
    O_METHOD,
    O_P,
    O_DIRECTIONS,
    O_SEED,
    O_EPS,
    O_TOL,
    O_MAX_ITER,
    O_BOX,
    O_SMOOTH,
    O_HDX,
    O_GRID,
    O_FORMAT
};

/* Options read by one method only: given with another, they would do nothing. */
static int check_method_options(const cli_command *cmd, const cli_opt *opts, consph_ot_method m,
                                int method_given, int dim)
{
    static const struct {
        int opt;
        consph_ot_param param;
    } only[] = {{O_DIRECTIONS, CONSPH_OT_PARAM_DIRECTIONS},
                {O_SEED, CONSPH_OT_PARAM_SEED},
                {O_EPS, CONSPH_OT_PARAM_EPS},
                {O_TOL, CONSPH_OT_PARAM_TOL},
                {O_MAX_ITER, CONSPH_OT_PARAM_MAX_ITER}};
    char here[16], needs[16];
    cli_choice_name(METHOD_CHOICES, (int)m, here, sizeof here);
    for (size_t k = 0; k < sizeof only / sizeof only[0]; ++k) {
        const cli_opt *o = &opts[only[k].opt];
        if (!o->given || consph_ot_param_read(m, dim, only[k].param)) continue;
        const consph_ot_method reader = consph_ot_param_method(only[k].param);
        cli_choice_name(METHOD_CHOICES, (int)reader, needs, sizeof needs);
        if (reader != m)
            return cli_error(cmd,
                             "option %s: only with --method %s; the method here is %s%s, which "
                             "does not read it",
                             o->name, needs, here, method_given ? "" : " (the default)");
        return cli_error(cmd,
                         "option %s: the particles are 1D, where every direction is +-1 and "
                         "the sliced distance is the exact one: it does nothing",
                         o->name);
    }
    return 0;
}

int cmd_wasserstein(int argc, char **argv)
{
    int method = 0, format = FORMAT_TABLE;
    long p = 1, directions = 64, seed = 1, max_iter = 20000;
    double eps = 1e-3, tol = 1e-6;
    const char *box_text = NULL, *smooth_name = NULL;
    long cells = 0;
    double hdx = 1.2;
    const char *positional[2] = {NULL, NULL};
    cli_opt opts[] = {
        {"--method", CLI_CHOICE, &method, "M",
         "exact (1D), sliced or sinkhorn (default exact in 1D, sliced otherwise)", METHOD_CHOICES,
         0, 0, 0},
        {"--p", CLI_INT, &p, "P", "order of the distance, cost |x-y|^p (default 1)", NULL, 1, 2, 0},
        {"--directions", CLI_INT, &directions, "K", "sliced: random directions (default 64)", NULL,
         2, 10000000, 0},
        {"--seed", CLI_INT, &seed, "S", "sliced: seed of the directions (default 1)", NULL, 0,
         9007199254740991.0, 0},
        {"--eps", CLI_DOUBLE, &eps, "E",
         "sinkhorn: final regularisation relative to C_max, 0 < E <= 1 (default 1e-3)", NULL, 1e-12,
         1.0, 0},
        {"--tol", CLI_DOUBLE, &tol, "T", "sinkhorn: stop at L1 marginal violation T (default 1e-6)",
         NULL, 1e-15, 0.5, 0},
        {"--max-iter", CLI_INT, &max_iter, "N", "sinkhorn: iteration cap (default 20000)", NULL, 1,
         100000000, 0},
        {"--box", CLI_STRING, &box_text, "BOX",
         "x0:x1[,y0:y1[,z0:z1]] for files without a box of their own", NULL, 0, 0, 0},
        {"--smooth", CLI_STRING, &smooth_name, "KERNEL",
         "compare the SPH densities with this kernel instead of the particles (needs --grid)", NULL,
         0, 0, 0},
        {"--hdx", CLI_DOUBLE, &hdx, "H", "--smooth: h / spacing (default 1.2)", NULL, 1e-3, 1e3, 0},
        {"--grid", CLI_INT, &cells, "G", "cells per axis of the grid for --smooth and uniform",
         NULL, 1, 100000000, 0},
        {"--format", CLI_CHOICE, &format, "F", "table or json (default table)", FORMAT_CHOICES, 0,
         0, 0},
    };
    cli_command cmd = {
        "wasserstein",
        "Wasserstein distance W_p between the particle measures of two files (CSV or .vtu):\n"
        "exact in 1D, sliced or entropic (Sinkhorn) in any dimension, each with its error.",
        "consph wasserstein A B [--method exact|sliced|sinkhorn] [--p 1|2] [--directions K]\n"
        "       [--seed S] [--eps E] [--tol T] [--max-iter N] [--box BOX]\n"
        "       [--smooth KERNEL [--hdx H]] [--grid G] [--format table|json]\n"
        "       consph wasserstein A uniform --grid G [...]",
        wasserstein_details,
        opts,
        (int)(sizeof opts / sizeof opts[0]),
        2,
        positional,
    };
    int rc = cli_parse(&cmd, argc, argv);
    if (rc == 1) return 0;
    if (rc) return rc;
    if (!positional[0] || !positional[1])
        return cli_error(&cmd, "two particle files A B are required (.csv or .vtu)");

    consph_read_options ro;
    memset(&ro, 0, sizeof ro);
    if (box_text) {
        if (cli_parse_box(box_text, &ro.box)) return cli_bad_box(&cmd, box_text);
        ro.have_box = 1;
    }
    int uniform = strcmp(positional[1], "uniform") == 0;
    if (opts[O_GRID].given && !smooth_name && !uniform)
        return cli_error(&cmd, "option --grid: only with --smooth KERNEL or B = uniform (the "
                               "particles themselves are compared)");
    consph_kernel_id kid = 0;
    if (smooth_name && consph_kernel_lookup(smooth_name, &kid) != CONSPH_OK)
        return cli_error(&cmd, "option --smooth: %s", consph_last_error());
    if ((smooth_name || uniform) && !opts[O_GRID].given)
        return cli_error(&cmd, "option --grid: needed with %s (cells per axis, 1 or more)",
                         smooth_name ? "--smooth" : "B = uniform");
    if (opts[O_HDX].given && !smooth_name)
        return cli_error(&cmd, "option --hdx: only with --smooth KERNEL");
    input in[2];
    memset(in, 0, sizeof in);
    rc = load(&cmd, positional[0], &ro, &in[0]);
    if (!rc && !uniform) rc = load(&cmd, positional[1], &ro, &in[1]);
    int dim = in[0].p.dim;
    if (!rc && !uniform && in[1].p.dim != dim)
        rc = cli_error(&cmd, "%s is %dD but %s is %dD (the measures must share a dimension)",
                       in[0].path, dim, in[1].path, in[1].p.dim);
    consph_ot_options o = consph_ot_defaults();
    o.method = opts[O_METHOD].given ? (consph_ot_method)method
                                    : (dim == 1 ? CONSPH_OT_EXACT : CONSPH_OT_SLICED);
    if (!rc && o.method == CONSPH_OT_EXACT && dim != 1)
        rc = cli_error(&cmd,
                       "option --method: exact is 1D only and the particles are %dD; "
                       "allowed here: sliced, sinkhorn",
                       dim);
    o.p = (int)p;
    o.directions = (int)directions;
    o.seed = (uint64_t)seed;
    o.eps = eps;
    o.tol = tol;
    o.max_iter = max_iter;
    if (!rc) rc = check_method_options(&cmd, opts, o.method, opts[O_METHOD].given, dim);
    if (!rc) rc = check_cost(&cmd, &o, dim, in, uniform, smooth_name != NULL, cells);
    progress pr;
    for (int k = 0; k < 2 - uniform && !rc && smooth_name; ++k)
        rc = smooth(&cmd, kid, hdx, cells, &in[k], &pr);
    if (!rc && uniform) {
        in[1].path = "uniform";
        in[1].p.dim = dim;
        in[1].origin = CONSPH_MASS_EQUAL;
        if (consph_grid_measure_density(&in[0].p.box, (size_t)cells, NULL, NULL, &in[1].grid))
            rc = cli_error(&cmd, "option --grid: %s", consph_last_error());
        else
            in[1].gridded = 1, in[1].mu = in[1].grid.mu;
    }
    double grid_error = (in[0].gridded ? in[0].grid.half_diagonal : 0.0) +
                        (in[1].gridded ? in[1].grid.half_diagonal : 0.0);
    if (rc) {
        unload(&in[0]);
        unload(&in[1]);
        return rc;
    }
    consph_ot_result res;
    if (o.method == CONSPH_OT_SINKHORN) {
        o.progress = sinkhorn_progress;
        o.progress_ctx = &pr;
    }
    progress_begin(&pr, "sinkhorn");
    double t0 = consph_wtime();
    rc = consph_wasserstein(&in[0].mu, &in[1].mu, &o, &res);
    double seconds = consph_wtime() - t0;
    progress_end(&pr);
    if (rc) {
        fprintf(stderr, "consph wasserstein: %s\n", consph_last_error());
        unload(&in[0]);
        unload(&in[1]);
        return 1;
    }
    char mname[16];
    cli_choice_name(METHOD_CHOICES, (int)o.method, mname, sizeof mname);
    if (format == FORMAT_JSON) {
        printf("{\"dim\": %d, \"n_a\": %zu, \"n_b\": %zu, \"masses_a\": \"%s\", \"masses_b\": "
               "\"%s\",\n",
               dim, in[0].mu.n, in[1].mu.n, consph_mass_origin_name(in[0].origin),
               consph_mass_origin_name(in[1].origin));
        printf(" \"method\": \"%s\", \"p\": %d, \"distance\": %.17g, \"error\": %.17g, "
               "\"error_kind\": \"%s\"",
               mname, o.p, res.distance, res.error, error_kind(o.method));
        if (o.method == CONSPH_OT_SLICED)
            printf(", \"directions\": %d, \"seed\": %llu", o.directions,
                   (unsigned long long)o.seed);
        if (o.method == CONSPH_OT_SINKHORN)
            printf(",\n \"eps\": %.17g, \"eps_abs\": %.17g, \"cost_max\": %.17g, "
                   "\"marginal_error\": %.17g, \"iterations\": %ld, \"converged\": %s",
                   o.eps, res.eps_abs, res.cost_max, res.marginal_error, res.iterations,
                   res.converged ? "true" : "false");
        if (smooth_name) printf(", \"smooth\": \"%s\", \"hdx\": %.17g", smooth_name, hdx);
        if (in[0].gridded || in[1].gridded)
            printf(", \"grid\": %ld, \"grid_error\": %.17g", cells, grid_error);
        printf(", \"seconds\": %.6f}\n", seconds);
    } else {
        for (int k = 0; k < 2; ++k)
            if (in[k].gridded)
                printf("%s: %s, %s on a grid of %zu cells (%dD)\n", k ? "B" : "A", in[k].path,
                       k && uniform ? "uniform density" : "SPH density", in[k].mu.n, dim);
            else
                printf("%s: %s, %zu particles, %dD, masses %s\n", k ? "B" : "A", in[k].path,
                       in[k].p.n, dim, consph_mass_origin_name(in[k].origin));
        if (smooth_name) printf("smoothed with %s, h = %g x spacing\n", smooth_name, hdx);
        printf("method %s, p %d", mname, o.p);
        if (o.method == CONSPH_OT_SLICED)
            printf(", %d directions, seed %llu", o.directions, (unsigned long long)o.seed);
        if (o.method == CONSPH_OT_SINKHORN)
            printf(", eps %g x C_max = %.6g (C_max %.6g), %ld iterations, marginal violation "
                   "%.3e%s",
                   o.eps, res.eps_abs, res.cost_max, res.iterations, res.marginal_error,
                   res.converged ? "" : " (NOT converged: --max-iter reached)");
        printf("\n%s %.10e +- %.3e (%s), %.3f s\n",
               o.method == CONSPH_OT_SLICED ? (o.p == 2 ? "SW_2" : "SW_1")
                                            : (o.p == 2 ? "W_2" : "W_1"),
               res.distance, res.error, error_kind(o.method), seconds);
        if (in[0].gridded || in[1].gridded)
            printf("grid discretisation adds at most %.3e (half the cell diagonal per grid)\n",
                   grid_error);
    }
    if (o.method == CONSPH_OT_SINKHORN && !res.converged)
        fprintf(stderr,
                "consph wasserstein: warning: Sinkhorn stopped at --max-iter %ld before "
                "its tolerance; the error bound accounts for the marginal violation\n",
                max_iter);
    unload(&in[0]);
    unload(&in[1]);
    return 0;
}
