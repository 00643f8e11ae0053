/* consph wasserstein: the Wasserstein distance between the particle measures of two files. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

/* Replaces the particle measure by its SPH density Σ m_b W(x − x_b, h) on a grid over the
 * particles' box, h = hdx × the file's spacing. */
static int smooth(const cli_command *cmd, const consph_kernel_id kid, double hdx, long cells,
                  input *in)
{
    consph_kernel k;
    if (consph_kernel_init(&k, kid, in->p.dim, hdx * in->p.spacing) != CONSPH_OK ||
        consph_grid_measure_sph(&in->p.box, (size_t)cells, &in->mu, &k, &in->grid) != CONSPH_OK)
        return cli_error(cmd, "%s: %s", in->path, consph_last_error());
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
        consph_ot_method method;
    } only[] = {{O_DIRECTIONS, CONSPH_OT_SLICED},
                {O_SEED, CONSPH_OT_SLICED},
                {O_EPS, CONSPH_OT_SINKHORN},
                {O_TOL, CONSPH_OT_SINKHORN},
                {O_MAX_ITER, CONSPH_OT_SINKHORN}};
    char here[16], needs[16];
    cli_choice_name(METHOD_CHOICES, (int)m, here, sizeof here);
    for (size_t k = 0; k < sizeof only / sizeof only[0]; ++k) {
        const cli_opt *o = &opts[only[k].opt];
        if (!o->given) continue;
        cli_choice_name(METHOD_CHOICES, (int)only[k].method, needs, sizeof needs);
        if (only[k].method != m)
            return cli_error(cmd,
                             "option %s: only with --method %s; the method here is %s%s, which "
                             "does not read it",
                             o->name, needs, here, method_given ? "" : " (the default)");
        /* 1D sliced is the exact distance: no direction is drawn. */
        if (m == CONSPH_OT_SLICED && dim == 1)
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
    if (!rc) rc = check_method_options(&cmd, opts, o.method, opts[O_METHOD].given, dim);
    for (int k = 0; k < 2 - uniform && !rc && smooth_name; ++k)
        rc = smooth(&cmd, kid, hdx, cells, &in[k]);
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
    o.p = (int)p;
    o.directions = (int)directions;
    o.seed = (uint64_t)seed;
    o.eps = eps;
    o.tol = tol;
    o.max_iter = max_iter;

    consph_ot_result res;
    double t0 = consph_wtime();
    rc = consph_wasserstein(&in[0].mu, &in[1].mu, &o, &res);
    double seconds = consph_wtime() - t0;
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
    if (fflush(stdout) != 0 || ferror(stdout)) {
        fprintf(stderr, "consph: writing to standard output failed\n");
        return 1;
    }
    return 0;
}
