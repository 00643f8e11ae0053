/* consph approx: accuracy of one operator on a manufactured field over a set of resolutions. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "commands.h"
#include "consph/study.h"

#define OP_CHOICES "function,grad,div,laplacian,hessian"
#define FORMAT_CHOICES "table,csv,json"

static const char *const norm_names[4] = {"l1", "l2", "linf", "mae"};

static double norm_of(const consph_approx_row *r, int k)
{
    switch (k) {
    case 0:
        return r->err.l1;
    case 1:
        return r->err.l2;
    case 2:
        return r->err.linf;
    default:
        return r->err.mae;
    }
}

static void print_csv_header(void)
{
    printf("nx,n,h,nbr_mean,l1,l2,linf,mae,ft_over_fmax,seconds,fallbacks\n");
}

static void print_csv_row(const consph_approx_row *r)
{
    printf("%zu,%zu,%.10g,%.6g,%.6e,%.6e,%.6e,%.6e,%.6e,%.6g,%zu\n", r->nx, r->n, r->h, r->nbr_mean,
           r->err.l1, r->err.l2, r->err.linf, r->err.mae, r->ft_over_fmax, r->seconds,
           r->fallbacks);
}

static void fit_norm(const consph_approx_row *rows, int nrows, int k, consph_order_fit *fit)
{
    double res[CLI_LIST_MAX], err[CLI_LIST_MAX];
    for (int r = 0; r < nrows; ++r) {
        res[r] = (double)rows[r].nx;
        err[r] = norm_of(&rows[r], k);
    }
    if (consph_fit_order(res, err, nrows, fit) != CONSPH_OK) fit->order = NAN;
}

int cmd_approx(int argc, char **argv)
{
    int op_idx = 0, fmt = 0, hpol = 0, layout_idx = 0, periodic_idx = 0, mask_idx = 0,
        volume_idx = 1;
    const char *form = NULL, *corr = "none", *kernel = "quintic", *field = NULL;
    double hdx = 1.2, eps = 0.2, sigma = 0.1, tol = 1e-4;
    long dim = 2, seed = 1, max_iter = 2000;
    cli_list nx = {0, {0}};
    char volume_choices[128] = "";
    for (int v = 0; v < CONSPH_VOLUME_COUNT; ++v) {
        if (v) strcat(volume_choices, ",");
        strcat(volume_choices, consph_volume_name((consph_volume_kind)v));
    }
    cli_opt opts[] = {
        {"--op", CLI_CHOICE, &op_idx, "OP", "operator", OP_CHOICES, 0, 0, 0},
        {"--form", CLI_STRING, &form, "FORM",
         "discretisation (default: standard for function, f4 for grad, div for div, coupled for "
         "laplacian, korzilius for hessian); an invalid op/form/corr triple lists the valid ones",
         NULL, 0, 0, 0},
        {"--corr", CLI_STRING, &corr, "CORR", "correction: none, bc, lc or fatehi (default none)",
         NULL, 0, 0, 0},
        {"--kernel", CLI_STRING, &kernel, "K",
         "kernel name, see 'consph kernels' (default quintic)", NULL, 0, 0, 0},
        {"--hdx", CLI_DOUBLE, &hdx, "R", "h/dx in the kernel's convention of h (default 1.2)", NULL,
         0.05, 100, 0},
        {"--h-policy", CLI_CHOICE, &hpol, "P",
         "hdx: h = R dx; scaling: h = N^(-1/6) as in 003 section 6.2", "hdx,scaling", 0, 0, 0},
        {"--layout", CLI_CHOICE, &layout_idx, "L", "particle layout (default lattice)",
         "lattice,random,quasi-random,packed", 0, 0, 0},
        {"--dim", CLI_INT, &dim, "D", "dimension (default 2)", NULL, 1, 3, 0},
        {"--nx", CLI_INT_LIST, &nx, "N,N,...", "particles per axis, one row each", NULL, 2, 100000,
         0},
        {"--field", CLI_STRING, &field, "NAME",
         "manufactured field (default sin2pi, or tgv for div); allowed: see --help text", NULL, 0,
         0, 0},
        {"--periodic", CLI_CHOICE, &periodic_idx, "yes|no",
         "periodic unit box (default yes); with no, only particles with full support are compared "
         "unless --mask all",
         "yes,no", 0, 0, 0},
        {"--mask", CLI_CHOICE, &mask_idx, "M", "particles compared on a non-periodic box",
         "interior,all", 0, 0, 0},
        {"--volume", CLI_CHOICE, &volume_idx, "V",
         "particle volumes: summation (m/rho), number (1/sum W, 001 eq. 5, default), given "
         "(layout volume)",
         volume_choices, 0, 0, 0},
        {"--eps", CLI_DOUBLE, &eps, "E", "random layout: perturbation factor (default 0.2)", NULL,
         0, 2, 0},
        {"--seed", CLI_INT, &seed, "S", "random/packed layout seed (default 1)", NULL, 0, 1e15, 0},
        {"--sigma", CLI_DOUBLE, &sigma, "S", "delta field: width (default 0.1)", NULL, 1e-6, 10, 0},
        {"--pack-tol", CLI_DOUBLE, &tol, "T", "packed layout: density tolerance (default 1e-4)",
         NULL, 1e-12, 1, 0},
        {"--pack-iter", CLI_INT, &max_iter, "M", "packed layout: iteration cap (default 2000)",
         NULL, 1, 1e7, 0},
        {"--format", CLI_CHOICE, &fmt, "F",
         "table (with fitted orders), csv (stable columns) or json (rows and orders)",
         FORMAT_CHOICES, 0, 0, 0},
    };
    char details[1024];
    snprintf(details, sizeof details,
             "CSV columns: nx,n,h,nbr_mean,l1,l2,linf,mae,ft_over_fmax,seconds,fallbacks\n"
             "  l1 = sum|g-g_o|/sum|g_o| (001 eq. 7, see docs/deviations.md), l2 and linf (002 "
             "eqs. 44-45),\n  mae = mean|g-g_o| (003 eq. 58), ft_over_fmax = sum F_x / max|F_x| "
             "(001 Tables 3, 5),\n  seconds = operator time, fallbacks = particles whose "
             "correction matrix was rejected.\n"
             "Orders: least-squares slope of log(error) against log(nx), with standard error.\n"
             "Fields: %s.",
             consph_mfield_names());
    cli_command cmd = {"approx",
                       "Measure an operator's accuracy on a manufactured field at several "
                       "resolutions.",
                       "consph approx --op OP [--form FORM] [--corr CORR] --nx N,N,... [options]",
                       details,
                       opts,
                       (int)(sizeof opts / sizeof opts[0]),
                       0,
                       NULL};
    int rc = cli_parse(&cmd, argc, argv);
    if (rc) return rc == 1 ? 0 : rc;
    if (!opts[0].given) return cli_error(&cmd, "option --op is required; allowed: " OP_CHOICES);
    if (!opts[8].given) return cli_error(&cmd, "option --nx is required (e.g. --nx 50,100,200)");

    static const char *default_form[] = {"standard", "f4", "div", "coupled", "korzilius"};
    consph_approx_spec s = consph_approx_defaults((int)dim);
    char opname[32];
    cli_choice_name(OP_CHOICES, op_idx, opname, sizeof opname);
    if (!form) form = default_form[op_idx];
    if (consph_op_parse(opname, form, corr, (int)dim, &s.op) != CONSPH_OK)
        return cli_error(&cmd, "%s", consph_last_error());
    if (consph_kernel_lookup(kernel, &s.kernel) != CONSPH_OK)
        return cli_error(&cmd, "option --kernel: %s", consph_last_error());
    if (consph_kernel_info_get(s.kernel)->tensor)
        return cli_error(&cmd, "option --kernel: '%s' is a remeshing kernel, not an SPH kernel",
                         kernel);
    if (!field) field = op_idx == 2 ? "tgv" : "sin2pi";
    if (consph_mfield_lookup(field, &s.field) != CONSPH_OK)
        return cli_error(&cmd, "option --field: %s", consph_last_error());
    s.hdx = hdx;
    s.h_policy = hpol ? CONSPH_H_SCALING : CONSPH_H_HDX;
    s.layout = consph_layout_defaults((consph_layout_kind)layout_idx, (int)dim, 10);
    s.layout.seed = (uint64_t)seed;
    s.layout.eps = eps;
    s.layout.packing.tol = tol;
    s.layout.packing.max_iter = (int)max_iter;
    s.layout.box = consph_box_unit((int)dim, periodic_idx == 0);
    s.field_params.sigma = sigma;
    s.volume = (consph_volume_kind)volume_idx;
    s.interior_only = mask_idx == 0;
    if (consph_approx_check(&s) != CONSPH_OK) return cli_error(&cmd, "%s", consph_last_error());

    consph_approx_row rows[CLI_LIST_MAX];
    const char *pnames[2] = {"yes", "no"};
    if (fmt == 0) {
        printf("# consph approx: op %s, form %s, corr %s, kernel %s, h/dx %g (%s), layout %s, "
               "dim %ld, periodic %s, field %s, volume %s\n",
               opname, consph_form_name(s.op.form), consph_corr_name(s.op.corr), kernel, hdx,
               hpol ? "h = N^-1/6" : "h = hdx*dx", consph_layout_name(s.layout.kind), dim,
               pnames[periodic_idx], field, consph_volume_name(s.volume));
        printf("%6s %10s %10s %8s %11s %11s %11s %11s %11s %9s %9s\n", "nx", "n", "h", "nbr", "l1",
               "l2", "linf", "mae", "ft/fmax", "seconds", "fallback");
    } else if (fmt == 1) {
        print_csv_header();
    }
    for (int r = 0; r < nx.n; ++r) {
        if (consph_approx_run(&s, (size_t)nx.v[r], &rows[r]) != CONSPH_OK) {
            fprintf(stderr, "consph approx: nx = %.0f: %s\n", nx.v[r], consph_last_error());
            return 1;
        }
        const consph_approx_row *w = &rows[r];
        if (fmt == 0)
            printf("%6zu %10zu %10.4g %8.2f %11.4e %11.4e %11.4e %11.4e %11.3e %9.3g %9zu\n", w->nx,
                   w->n, w->h, w->nbr_mean, w->err.l1, w->err.l2, w->err.linf, w->err.mae,
                   w->ft_over_fmax, w->seconds, w->fallbacks);
        else if (fmt == 1)
            print_csv_row(w);
        fflush(stdout);
    }
    if (fmt == 0) {
        for (int k = 0; k < 4; ++k) {
            consph_order_fit fit;
            fit_norm(rows, nx.n, k, &fit);
            if (isnan(fit.order))
                printf("order (%s): n/a\n", norm_names[k]);
            else
                printf("order (%s): %.3f +- %.3f\n", norm_names[k], fit.order, fit.order_stderr);
        }
    } else if (fmt == 2) {
        printf("{\n  \"op\": \"%s\", \"form\": \"%s\", \"corr\": \"%s\", \"kernel\": \"%s\", "
               "\"hdx\": %g, \"h_policy\": \"%s\", \"layout\": \"%s\", \"dim\": %ld, "
               "\"periodic\": %s, \"field\": \"%s\", \"volume\": \"%s\",\n  \"rows\": [\n",
               opname, consph_form_name(s.op.form), consph_corr_name(s.op.corr), kernel, hdx,
               hpol ? "scaling" : "hdx", consph_layout_name(s.layout.kind), dim,
               periodic_idx == 0 ? "true" : "false", field, consph_volume_name(s.volume));
        for (int r = 0; r < nx.n; ++r) {
            const consph_approx_row *w = &rows[r];
            printf("    {\"nx\": %zu, \"n\": %zu, \"h\": %.10g, \"nbr_mean\": %.6g, \"l1\": %.6e, "
                   "\"l2\": %.6e, \"linf\": %.6e, \"mae\": %.6e, \"ft_over_fmax\": %.6e, "
                   "\"seconds\": %.6g, \"fallbacks\": %zu}%s\n",
                   w->nx, w->n, w->h, w->nbr_mean, w->err.l1, w->err.l2, w->err.linf, w->err.mae,
                   w->ft_over_fmax, w->seconds, w->fallbacks, r + 1 < nx.n ? "," : "");
        }
        printf("  ],\n  \"order\": {");
        for (int k = 0; k < 4; ++k) {
            consph_order_fit fit;
            fit_norm(rows, nx.n, k, &fit);
            if (isnan(fit.order))
                printf("%s\"%s\": null", k ? ", " : "", norm_names[k]);
            else
                printf("%s\"%s\": {\"order\": %.6f, \"stderr\": %.6f}", k ? ", " : "",
                       norm_names[k], fit.order, fit.order_stderr);
        }
        printf("}\n}\n");
    }
    return 0;
}
