/* consph approx: accuracy of one operator on a manufactured field over a set of resolutions. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "commands.h"
#include "consph/io.h"
#include "consph/study.h"
#include "consph/transport.h"

#define OP_CHOICES "function,grad,div,laplacian,hessian"
#define FORMAT_CHOICES "table,csv,json"
/* --volume: the volume kinds of ops.h, then two names for particle files (box volume / N given
 * to every particle, and 1/ΣW as in 001 eq. 5). */
#define VOLUME_EXTRA ",lattice,shepard"

static const char *const norm_names[4] = {"l1", "l2", "linf", "mae"};

static void print_csv_header(void)
{
    printf("nx,n,h,nbr_mean,l1,l2,linf,mae,ft_over_fmax,seconds,fallbacks\n");
}

/* nx is printed as %.6g: an integer for layouts (nx <= 100000), N^(1/dim) for files. */
static void print_csv_row(const consph_approx_row *r, double nx)
{
    printf("%.6g,%zu,%.10g,%.6g,%.6e,%.6e,%.6e,%.6e,%.6e,%.6g,%zu\n", nx, r->n, r->h, r->nbr_mean,
           r->err.l1, r->err.l2, r->err.linf, r->err.mae, r->ft_over_fmax, r->seconds,
           r->fallbacks);
}

/* The verdict on every norm's order; a non-finite or degenerate row is reported once, on
 * stderr, naming the series and the resolution. Returns CLI_EXIT_NONFINITE for a non-finite row. */
static int fit_orders(const consph_approx_row *rows, const double *res, int nrows,
                      const char *series, const consph_particle_input *files, const char *pm,
                      consph_series_order fits[4])
{
    int rc = 0, warned = 0;
    if (consph_approx_sweep_fit(rows, res, nrows, pm, fits) == CONSPH_ENOMEM)
        for (int k = 0; k < 4; ++k) {
            fits[k].status = CONSPH_SERIES_NO_FIT;
            fits[k].row = -1;
            snprintf(fits[k].text, sizeof fits[k].text, "n/a (out of memory)");
        }
    for (int k = 0; k < 4; ++k) {
        const consph_series_order *so = &fits[k];
        if (warned || so->row < 0) continue;
        /* A file's row is named by the file: several files can share one nx. */
        const char *file = files ? files[so->row].path : NULL;
        if (so->status == CONSPH_SERIES_NONFINITE) {
            fprintf(stderr, "consph approx: error: %s%s%s: %s (exit status %d)\n", series,
                    file ? ", " : "", file ? file : "", so->why, CLI_EXIT_NONFINITE);
            rc = CLI_EXIT_NONFINITE;
            warned = 1;
        } else if (so->status == CONSPH_SERIES_DEGENERATE) {
            fprintf(stderr, "consph approx: warning: %s%s%s: %s\n", series, file ? ", " : "",
                    file ? file : "", so->why);
            warned = 1;
        }
    }
    return rc;
}

/* JSON has no NaN or infinity: a non-finite value is written as null. */
static void json_number(const char *fmt, double v)
{
    if (isfinite(v))
        printf(fmt, v);
    else
        printf("null");
}

static void json_string(const char *s)
{
    putchar('"');
    for (; *s; ++s) {
        if (*s == '"' || *s == '\\')
            printf("\\%c", *s);
        else if ((unsigned char)*s < 32)
            printf("\\u%04x", (unsigned char)*s);
        else
            putchar(*s);
    }
    putchar('"');
}

static void describe_file(FILE *o, const consph_particle_input *f, int periodic_given)
{
    const consph_particles *p = &f->p;
    static const char axis[] = "xyz";
    fprintf(o, "# %s: %zu particles (%s%s%s), box", f->path, p->n,
            f->rep.format == CONSPH_FORMAT_CSV ? "csv" : "vtu", f->rep.encoding[0] ? " " : "",
            f->rep.encoding);
    for (int a = 0; a < p->dim; ++a)
        fprintf(o, "%s[%g, %g]", a ? "x" : " ", p->box.lo[a], p->box.hi[a]);
    fprintf(o, " (%s), periodic ", f->rep.box_from_file ? "from the file" : "--box");
    int any = 0;
    for (int a = 0; a < p->dim; ++a)
        if (p->box.periodic[a]) fprintf(o, "%c", axis[a]), any = 1;
    fprintf(o, "%s (%s), spacing %g (%s), volumes %s", any ? "" : "none",
            f->rep.periodic_from_file ? "from the file"
            : periodic_given          ? "--periodic"
                                      : "none in the file",
            p->spacing, f->rep.spacing_from_file ? "from the file" : "(V/N)^(1/dim)",
            f->volume_text);
    if (f->rep.wrapped)
        fprintf(o, ", %zu particle%s wrapped into the periodic box", f->rep.wrapped,
                f->rep.wrapped == 1 ? "" : "s");
    fprintf(o, "\n");
}

/* Memory and time from the particle count and the neighbours the kernel's support holds at that
 * h, before any work: a size the machine cannot hold is refused naming --hdx and --nx (or the
 * file), one that may pass ten seconds is announced on stderr. */
static int check_cost(const cli_command *cmd, const consph_approx_sweep *sw, const char *kernel,
                      double hdx, long dim)
{
    const int threads = consph_num_threads();
    const consph_approx_sweep_cost c = consph_approx_sweep_estimate(sw, threads);
    const double seconds = c.seconds, worst = c.worst.bytes, worst_nbr = c.worst.neighbours;
    const int at = c.worst_row;
    double limit, cap, available;
    if (consph_memory_limit(&limit, &cap, &available))
        return cli_error(cmd, "%s", consph_last_error());
    char where[256];
    if (sw->files)
        snprintf(where, sizeof where, "%.200s", sw->files[at].path);
    else
        snprintf(where, sizeof where, "--nx %.0f", sw->nx[at]);
    if (worst > limit)
        return cli_error(cmd,
                         "option --hdx: %g with kernel %s in %ldD gives about %.3g neighbours per "
                         "particle at %s, which need about %.3g GB (72 bytes a neighbour on %d "
                         "threads); the limit is %.3g GB (the cap %.3g GB, CONSPH_MEMORY_LIMIT, "
                         "or the %.3g GB available, whichever is less); allowed: a smaller --hdx",
                         hdx, kernel, dim, worst_nbr, where, worst / 1e9, threads, limit / 1e9,
                         cap / 1e9, available / 1e9);
    if (seconds > 10.0)
        fprintf(stderr,
                "consph approx: estimate (rough): about %.0f s for %.3g neighbours per particle "
                "at %s (at %.0e neighbour pairs per second, measured on 2 cores); memory %.3g "
                "GB\n",
                seconds, worst_nbr, where, CONSPH_APPROX_PAIRS_PER_SECOND, worst / 1e9);
    return 0;
}

/* --volume on a file: the file's default (consph_particle_input_read) unless given; lattice
 * replaces its volumes by box volume / N, shepard is number. */
static int choose_volume(const cli_command *cmd, consph_particle_input *f, int volume_idx,
                         int given)
{
    if (!given) return 0;
    if (volume_idx == CONSPH_VOLUME_COUNT) { /* lattice */
        if (consph_particle_input_lattice_volumes(f) != CONSPH_OK)
            return cli_error(cmd, "%s", consph_last_error());
        snprintf(f->volume_text, sizeof f->volume_text, "given (--volume lattice: box volume / N)");
        return 0;
    }
    if (volume_idx == CONSPH_VOLUME_COUNT + 1) volume_idx = CONSPH_VOLUME_NUMBER; /* shepard */
    f->volume = (consph_volume_kind)volume_idx;
    snprintf(f->volume_text, sizeof f->volume_text, "%s (--volume%s%s)",
             consph_volume_name(f->volume), volume_idx == CONSPH_VOLUME_GIVEN ? ": " : "",
             volume_idx != CONSPH_VOLUME_GIVEN       ? ""
             : f->rep.volumes != CONSPH_VOLUMES_NONE ? consph_volume_origin_name(f->rep.volumes)
                                                     : "box volume / N, none in the file");
    return 0;
}

/* Reads the files of --particles (consph_particle_input_read) into in[], checking that they
 * share a dimension and applying --volume; a failure is one line on stderr. */
static int read_files(const cli_command *cmd, const char *particles, const consph_read_options *ro,
                      const char *periodic_text, int volume_idx, int volume_given,
                      consph_particle_input *in, int *nin)
{
    static char list[4096]; /* holds the file names, which the reports quote */
    if (strlen(particles) >= sizeof list || !cli_list_items_nonempty(particles))
        return cli_error(cmd, "option --particles: '%s' is not a comma-separated list of files",
                         particles);
    strcpy(list, particles);
    char *save = NULL;
    for (char *t = strtok_r(list, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        if (*nin == CLI_LIST_MAX)
            return cli_error(cmd, "option --particles: at most %d files", CLI_LIST_MAX);
        consph_particle_input *f = &in[*nin];
        consph_particle_format pf;
        if (consph_particle_format_from_path(t, &pf) != CONSPH_OK)
            return cli_error(cmd, "option --particles: %s", consph_last_error());
        if (consph_particle_input_read(t, ro, f) != CONSPH_OK) {
            fprintf(stderr, "consph approx: %s\n", consph_last_error());
            return CLI_EXIT_USAGE;
        }
        ++*nin;
        if (f->p.dim != in[0].p.dim)
            return cli_error(cmd, "option --particles: %s is %dD but %s is %dD", t, f->p.dim,
                             in[0].path, in[0].p.dim);
        if (periodic_text && cli_check_periodic_dim(cmd, periodic_text, f->p.dim))
            return CLI_EXIT_USAGE;
        if (choose_volume(cmd, f, volume_idx, volume_given)) return CLI_EXIT_USAGE;
    }
    return 0;
}

static void free_inputs(consph_particle_input *in, int n)
{
    for (int k = 0; k < n; ++k) consph_particle_input_free(&in[k]);
    free(in);
}

/* The writer of `consph approx`: the header, each row as it is measured (table or CSV, with
 * its packing warnings), the orders, or the whole sweep as JSON. */
typedef struct approx_writer {
    int fmt; /* 0 table, 1 csv, 2 json */
    const consph_approx_sweep *sw;
    const char *opname, *kernel, *field;
    double hdx, beta;
    int hpol;
    long dim;
    char pdesc[8]; /* the periodic axes */
    int periodic_given;
    double tol;
} approx_writer;

static void write_head(const approx_writer *w)
{
    const consph_approx_spec *s = &w->sw->spec;
    const consph_particle_input *in = w->sw->files;
    const int nin = in ? w->sw->nrows : 0;
    const long dim = w->dim;
    char hdesc[96];
    if (s->h_policy == CONSPH_H_ZHU || s->h_policy == CONSPH_H_BETA)
        snprintf(hdesc, sizeof hdesc, "h = hdx*dx at N = %.0f, then h ~ N^(-1/%g)", s->n_ref,
                 s->h_policy == CONSPH_H_ZHU ? 2.0 * (double)dim : w->beta);
    else
        snprintf(hdesc, sizeof hdesc, "%s", w->hpol ? "h = N^-1/6" : "h = hdx*dx");
    if (w->fmt == 0) {
        if (in)
            printf("# consph approx: op %s, form %s, corr %s, kernel %s, h/dx %g (%s), particles "
                   "from %d file%s, dim %ld, field %s\n",
                   w->opname, consph_form_name(s->op.form), consph_corr_name(s->op.corr), w->kernel,
                   w->hdx, hdesc, nin, nin == 1 ? "" : "s", dim, w->field);
        else
            printf("# consph approx: op %s, form %s, corr %s, kernel %s, h/dx %g (%s), layout %s, "
                   "dim %ld, periodic %s, field %s, volume %s\n",
                   w->opname, consph_form_name(s->op.form), consph_corr_name(s->op.corr), w->kernel,
                   w->hdx, hdesc, consph_layout_name(s->layout.kind), dim,
                   !w->pdesc[0]                      ? "no"
                   : strlen(w->pdesc) == (size_t)dim ? "yes"
                                                     : w->pdesc,
                   w->field, consph_volume_name(s->volume));
        for (int k = 0; k < nin; ++k) describe_file(stdout, &in[k], w->periodic_given);
        printf("%6s %10s %10s %8s %11s %11s %11s %11s %11s %9s %9s\n", "nx", "n", "h", "nbr", "l1",
               "l2", "linf", "mae", "ft/fmax", "seconds", "fallback");
    } else {
        /* CSV and JSON keep their columns; what was read from each file goes to stderr. */
        for (int k = 0; k < nin; ++k) describe_file(stderr, &in[k], w->periodic_given);
        if (w->fmt == 1) print_csv_header();
    }
}

static void write_json(const approx_writer *w, const consph_approx_row *rows, const double *res,
                       const consph_series_order fits[4])
{
    const consph_approx_spec *s = &w->sw->spec;
    const consph_particle_input *in = w->sw->files;
    const int nrows = w->sw->nrows;
    printf("{\n  \"op\": \"%s\", \"form\": \"%s\", \"corr\": \"%s\", \"kernel\": \"%s\", "
           "\"hdx\": %g, \"h_policy\": \"%s\", \"layout\": \"%s\", \"dim\": %ld, ",
           w->opname, consph_form_name(s->op.form), consph_corr_name(s->op.corr), w->kernel, w->hdx,
           consph_h_policy_name(s->h_policy), in ? "files" : consph_layout_name(s->layout.kind),
           w->dim);
    if (in)
        printf("\"field\": \"%s\",\n", w->field);
    else
        printf("\"periodic\": %s, \"field\": \"%s\", \"volume\": \"%s\",\n",
               w->pdesc[0] ? "true" : "false", w->field, consph_volume_name(s->volume));
    printf("  \"rows\": [\n");
    for (int r = 0; r < nrows; ++r) {
        const consph_approx_row *row = &rows[r];
        printf("    {");
        if (in) {
            printf("\"file\": ");
            json_string(in[r].path);
            printf(", \"volume\": \"%s\", \"volumes\": ", consph_volume_name(in[r].volume));
            json_string(in[r].volume_text);
            printf(", \"wrapped\": %zu, ", in[r].rep.wrapped);
        }
        printf("\"nx\": %.10g, \"n\": %zu, \"h\": %.10g, \"nbr_mean\": ", res[r], row->n, row->h);
        json_number("%.6g", row->nbr_mean);
        const double cols[] = {row->err.l1, row->err.l2, row->err.linf, row->err.mae,
                               row->ft_over_fmax};
        static const char *const names[] = {"l1", "l2", "linf", "mae", "ft_over_fmax"};
        for (int c = 0; c < 5; ++c) {
            printf(", \"%s\": ", names[c]);
            json_number("%.6e", cols[c]);
        }
        printf(", \"seconds\": ");
        json_number("%.6g", row->seconds);
        printf(", \"fallbacks\": %zu}%s\n", row->fallbacks, r + 1 < nrows ? "," : "");
    }
    printf("  ],\n  \"order\": {");
    for (int k = 0; k < 4; ++k) {
        const consph_order_fit *fit = &fits[k].fit;
        printf("%s\"%s\": ", k ? ", " : "", norm_names[k]);
        if (fits[k].status != CONSPH_SERIES_ORDER) {
            printf("null");
            continue;
        }
        printf("{\"order\": %.6f, \"stderr\": ", fit->order);
        json_number("%.6f", fit->order_stderr);
        printf("}");
    }
    printf("}\n}\n");
}

/* A row's line of the table or CSV as soon as it is measured, and its packing warnings. */
static void print_row(void *ctx, int r, const consph_approx_row *w, double res)
{
    const approx_writer *pr = ctx;
    const consph_approx_spec *s = &pr->sw->spec;
    if (!pr->sw->files && s->layout.kind == CONSPH_LAYOUT_PACKED_POLISHED &&
        w->layout_spread > pr->tol)
        fprintf(stderr,
                "consph approx: warning: nx = %.0f: packing stopped at --pack-iter %d "
                "with max|rho/rho0-1| = %.3g above --pack-tol %g; the particles are "
                "less uniform than asked\n",
                pr->sw->nx[r], s->layout.packing.max_iter, w->layout_spread, pr->tol);
    if (!pr->sw->files && s->layout.kind == CONSPH_LAYOUT_PACKED && !w->layout_converged)
        fprintf(stderr,
                "consph approx: warning: nx = %.0f: packing stopped at --pack-iter %d "
                "before the particles stopped moving (max|rho/rho0-1| = %.3g)\n",
                pr->sw->nx[r], s->layout.packing.max_iter, w->layout_spread);
    if (pr->fmt == 0)
        printf("%6.6g %10zu %10.4g %8.2f %11.4e %11.4e %11.4e %11.4e %11.3e %9.3g %9zu\n", res,
               w->n, w->h, w->nbr_mean, w->err.l1, w->err.l2, w->err.linf, w->err.mae,
               w->ft_over_fmax, w->seconds, w->fallbacks);
    else if (pr->fmt == 1)
        print_csv_row(w, res);
    fflush(stdout);
}

int cmd_approx(int argc, char **argv)
{
    int op_idx = 0, fmt = 0, hpol = 0, layout_idx = 0, mask_idx = 0, volume_idx = 1;
    const char *form = NULL, *corr = "none", *kernel = "quintic", *field = NULL;
    const char *particles = NULL, *box_text = NULL, *periodic_text = "yes";
    double hdx = 1.2, eps = 0.2, sigma = 0.1, tol = 1e-4, beta = 0.0;
    long dim = 2, seed = 1, max_iter = 0; /* 0: the layout kind's default */
    cli_list nx = {0, {0}};
    cli_cache cache = {NULL, 0};
    char volume_choices[128] = "";
    for (int v = 0; v < CONSPH_VOLUME_COUNT; ++v) {
        if (v) strcat(volume_choices, ",");
        strcat(volume_choices, consph_volume_name((consph_volume_kind)v));
    }
    strcat(volume_choices, VOLUME_EXTRA);
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
         "hdx: h = R dx; scaling: h = N^(-1/6) as in 003 section 6.2; zhu: h = R dx at the first "
         "row, then neighbours grow as N^(1/2) (Zhu et al., h ∝ N^(-1/(2 dim))); beta: h = R dx "
         "at the first row, then N ∝ h^(-B) as in 004 (neighbours ∝ N^(1 - dim/B))",
         "hdx,scaling,zhu,beta", 0, 0, 0},
        {"--layout", CLI_CHOICE, &layout_idx, "L", "particle layout (default lattice)",
         consph_layout_names(), 0, 0, 0},
        {"--dim", CLI_INT, &dim, "D",
         "dimension (default 2; with --particles: the files', checked when given)", NULL, 1, 3, 0},
        {"--nx", CLI_INT_LIST, &nx, "N,N,...", "particles per axis, one row each", NULL, 2, 100000,
         0},
        {"--particles", CLI_STRING, &particles, "FILE,FILE,...",
         "particle files (.csv or .vtu) instead of --layout/--nx, one row each in this order; nx "
         "is reported as N^(1/dim)",
         NULL, 0, 0, 0},
        {"--box", CLI_STRING, &box_text, "x0:x1,y0:y1[,z0:z1]",
         "with --particles: the domain (default: the box the file carries)", NULL, 0, 0, 0},
        {"--field", CLI_STRING, &field, "NAME",
         "manufactured field (default sin2pi, or tgv for div); allowed: see --help text", NULL, 0,
         0, 0},
        {"--periodic", CLI_STRING, &periodic_text, "yes|no|AXES",
         "periodic axes: yes (all, the default for layouts), no, or letters such as x or xy; with "
         "--particles the default is the file's; with no, only particles with full support are "
         "compared unless --mask all",
         NULL, 0, 0, 0},
        {"--mask", CLI_CHOICE, &mask_idx, "M", "particles compared on a non-periodic box",
         "interior,all", 0, 0, 0},
        {"--volume", CLI_CHOICE, &volume_idx, "V",
         "particle volumes: summation (m/rho), number (1/sum W, 001 eq. 5, default), given "
         "(layout or file volume), lattice (box volume / N), shepard (= number); with "
         "--particles the default is the file's volume (or m/rho) column, else shepard",
         volume_choices, 0, 0, 0},
        {"--eps", CLI_DOUBLE, &eps, "E", "random layout: perturbation factor (default 0.2)", NULL,
         0, 2, 0},
        {"--seed", CLI_INT, &seed, "S", "random/packed layout seed (default 1)", NULL, 0, 1e15, 0},
        {"--sigma", CLI_DOUBLE, &sigma, "S", "delta field: width (default 0.1)", NULL, 1e-6, 10, 0},
        {"--pack-tol", CLI_DOUBLE, &tol, "T",
         "packed-polished layout: density tolerance (default 1e-4)", NULL, 1e-12, 1, 0},
        {"--pack-iter", CLI_INT, &max_iter, "M",
         "packed layouts: iteration cap (default 40000 packed, 5000 packed-polished)", NULL, 1, 1e7,
         0},
        {"--format", CLI_CHOICE, &fmt, "F",
         "table (with fitted orders), csv (stable columns) or json (rows and orders)",
         FORMAT_CHOICES, 0, 0, 0},
        {"--beta", CLI_DOUBLE, &beta, "B", "the exponent of --h-policy beta, > dim", NULL, 0, 1e3,
         0},
        CLI_CACHE_OPTS(cache),
    };
    enum {
        O_OP = 0,
        O_DIM = 7,
        O_NX = 8,
        O_PARTICLES = 9,
        O_BOX = 10,
        O_PERIODIC = 12,
        O_VOLUME = 14,
        O_BETA = 21
    };
    char details[3072];
    snprintf(details, sizeof details,
             "CSV columns: nx,n,h,nbr_mean,l1,l2,linf,mae,ft_over_fmax,seconds,fallbacks\n"
             "  l1 = sum|g-g_o|/sum|g_o| (001 eq. 7, see docs/deviations.md), l2 and linf (002 "
             "eqs. 44-45),\n  mae = mean|g-g_o| (003 eq. 58), ft_over_fmax = sum F_x / max|F_x| "
             "(001 Tables 3, 5),\n  seconds = operator time, fallbacks = particles whose "
             "correction matrix was rejected.\n"
             "Orders: least-squares slope of log(error) against log(nx), with its standard "
             "error from three resolutions on (n/a with two); 'n/a (why)' where no order can be "
             "fitted, e.g. no neighbours within the support (a warning on stderr).\n"
             "Cost: before any work each resolution's neighbours per particle are estimated "
             "from h (--hdx, --h-policy), the kernel's support and the dimension (periodic "
             "images included); a run needing more than the memory limit (72 bytes a neighbour "
             "per thread; 4 GiB, CONSPH_MEMORY_LIMIT=BYTES[K|M|G], or the memory available) is "
             "refused (exit 2, naming --hdx and --nx), one estimated past 10 s (at 2e7 "
             "neighbour pairs per second, measured on 2 cores) is announced on stderr.\n"
             "Exit status: 0 done, 1 a run failed, 2 bad input, 3 an error is not finite (a "
             "wrong result; stderr names the operator and the resolution or file).\n"
             "Fields: %s.\n"
             "Particle files: CSV with a header row x,y[,z] (optional volume, m, rho columns) or "
             "VTK .vtu (ascii, binary, appended, zlib), as 'consph layout --out' writes them; "
             "the box and periodicity come from the file (CSV '# box'/'# periodic' comments, VTU "
             "FieldData) unless --box/--periodic are given; the spacing must lie in [1e-50, "
             "1e50]. A bad file gets one line naming the file, the line and the problem, and "
             "exit status 2. Packed layouts need --periodic yes.",
             consph_mfield_names());
    cli_command cmd = {"approx",
                       "Measure an operator's accuracy on a manufactured field at several "
                       "resolutions.",
                       "consph approx --op OP [--form FORM] [--corr CORR] (--nx N,N,... | "
                       "--particles FILE,FILE,...) [options]",
                       details,
                       opts,
                       (int)(sizeof opts / sizeof opts[0]),
                       0,
                       NULL};
    int rc = cli_parse(&cmd, argc, argv);
    if (rc) return rc == 1 ? 0 : rc;
    if ((rc = cli_cache_apply(&cmd, &cache))) return rc;
    if (!opts[O_OP].given) return cli_error(&cmd, "option --op is required; allowed: " OP_CHOICES);
    const int from_files = opts[O_PARTICLES].given;
    if (!from_files && !opts[O_NX].given)
        return cli_error(&cmd, "option --nx is required (e.g. --nx 50,100,200), or --particles "
                               "FILE,FILE,...");
    if (from_files) {
        static const char *const layout_only[] = {"--layout", "--nx",       "--eps",
                                                  "--seed",   "--pack-tol", "--pack-iter"};
        for (size_t k = 0; k < sizeof layout_only / sizeof layout_only[0]; ++k)
            for (int o = 0; o < cmd.nopts; ++o)
                if (opts[o].given && !strcmp(opts[o].name, layout_only[k]))
                    return cli_error(&cmd,
                                     "option %s: not with --particles (the files are the "
                                     "particles)",
                                     layout_only[k]);
    } else if (opts[O_BOX].given) {
        return cli_error(&cmd, "option --box: only with --particles (layouts fill the unit box)");
    }
    for (int r = 0; !from_files && r < nx.n; ++r)
        if ((rc = cli_check_nx(&cmd, (long)nx.v[r], dim))) return rc;
    int periodic[CONSPH_MAX_DIM];
    if (cli_parse_periodic(periodic_text, periodic) != 0)
        return cli_bad_periodic(&cmd, periodic_text);
    if (!from_files && (rc = cli_check_periodic_dim(&cmd, periodic_text, (int)dim))) return rc;
    /* The packing needs a periodic box (001's PP arrangement), as `consph layout` says. */
    const int packed =
        layout_idx == CONSPH_LAYOUT_PACKED || layout_idx == CONSPH_LAYOUT_PACKED_POLISHED;
    for (int a = 0; !from_files && packed && a < dim; ++a)
        if (!periodic[a])
            return cli_error(&cmd,
                             "option --periodic: --layout %s needs a periodic box; allowed: yes",
                             consph_layout_name((consph_layout_kind)layout_idx));
    consph_box given_box;
    if (box_text && cli_parse_box(box_text, &given_box) != 0) return cli_bad_box(&cmd, box_text);
    if (!from_files && volume_idx == CONSPH_VOLUME_COUNT) volume_idx = CONSPH_VOLUME_GIVEN;
    if (!from_files && volume_idx == CONSPH_VOLUME_COUNT + 1) volume_idx = CONSPH_VOLUME_NUMBER;

    /* Every file is read, and every bad one rejected, before anything is measured. */
    consph_particle_input *in = NULL;
    int nin = 0;
    if (from_files) {
        in = calloc(CLI_LIST_MAX, sizeof *in);
        if (!in) return cli_error(&cmd, "out of memory");
    }
    rc = CLI_EXIT_USAGE;
    if (from_files) {
        consph_read_options ro;
        memset(&ro, 0, sizeof ro);
        ro.dim = opts[O_DIM].given ? (int)dim : 0;
        if (box_text) {
            ro.have_box = 1;
            ro.box = given_box;
        }
        if (opts[O_PERIODIC].given) {
            ro.have_periodic = 1;
            for (int a = 0; a < CONSPH_MAX_DIM; ++a) ro.periodic[a] = periodic[a];
        }
        if (read_files(&cmd, particles, &ro, opts[O_PERIODIC].given ? periodic_text : NULL,
                       volume_idx, opts[O_VOLUME].given, in, &nin))
            goto out;
    }
    if (from_files) dim = in[0].p.dim;

    static const char *default_form[] = {"standard", "f4", "div", "coupled", "korzilius"};
    consph_approx_spec s = consph_approx_defaults((int)dim);
    char opname[32];
    cli_choice_name(OP_CHOICES, op_idx, opname, sizeof opname);
    if (!form) form = default_form[op_idx];
    if (consph_op_parse(opname, form, corr, (int)dim, &s.op) != CONSPH_OK) {
        consph_op_form unknown;
        consph_op op;
        char valid[1024];
        /* An unknown form name: the forms this op takes, with their corrections, rather than
         * every form of every op. */
        if (consph_form_lookup(form, &unknown) != CONSPH_OK &&
            consph_op_lookup(opname, &op) == CONSPH_OK)
            cli_error(&cmd, "option --form: unknown form '%s'; valid form[corrections] of %s: %s",
                      form, opname, consph_op_describe(op, valid, sizeof valid));
        else
            cli_error(&cmd, "%s", consph_last_error());
        goto out;
    }
    if (consph_kernel_lookup(kernel, &s.kernel) != CONSPH_OK) {
        cli_error(&cmd, "option --kernel: %s", consph_last_error());
        goto out;
    }
    if (consph_kernel_info_get(s.kernel)->tensor) {
        cli_error(&cmd, "option --kernel: '%s' is a remeshing kernel, not an SPH kernel", kernel);
        goto out;
    }
    if (!field) field = op_idx == 2 ? "tgv" : "sin2pi";
    if (consph_mfield_lookup(field, &s.field) != CONSPH_OK) {
        cli_error(&cmd, "option --field: %s", consph_last_error());
        goto out;
    }
    s.hdx = hdx;
    s.h_policy = (consph_h_policy)hpol;
    s.beta = beta;
    if (opts[O_BETA].given != (s.h_policy == CONSPH_H_BETA)) {
        cli_error(&cmd, "option --beta: give it with --h-policy beta, and only then");
        goto out;
    }
    if (s.h_policy == CONSPH_H_BETA && !(beta > dim)) {
        cli_error(&cmd,
                  "option --beta: must exceed the dimension %ld (004: N ∝ h^-β with β > n), "
                  "got %g",
                  dim, beta);
        goto out;
    }
    /* zhu and beta agree with hdx at the first row. */
    s.n_ref = from_files ? (double)in[0].p.n : pow(nx.v[0], (double)dim);
    s.layout = consph_layout_defaults((consph_layout_kind)layout_idx, (int)dim, 10);
    s.layout.seed = (uint64_t)seed;
    s.layout.eps = eps;
    s.layout.packing.tol = tol;
    if (max_iter > 0) s.layout.packing.max_iter = (int)max_iter;
    s.layout.box = consph_box_unit((int)dim, 0);
    for (int a = 0; a < dim; ++a) s.layout.box.periodic[a] = periodic[a];
    s.field_params.sigma = sigma;
    s.volume = (consph_volume_kind)volume_idx;
    s.interior_only = mask_idx == 0;
    const int nrows = from_files ? nin : nx.n;
    const consph_approx_sweep sw = {s, nrows, from_files ? NULL : nx.v, from_files ? in : NULL};
    if (consph_approx_sweep_check(&sw) != CONSPH_OK) {
        cli_error(&cmd, "%s", consph_last_error());
        goto out;
    }
    if (check_cost(&cmd, &sw, kernel, hdx, dim)) goto out;
    consph_approx_row rows[CLI_LIST_MAX];
    double res[CLI_LIST_MAX];
    /* After every check: a rejection stays the one line on stderr. */
    for (int k = 0; k < nin; ++k)
        cli_note_read_defaults(&cmd, in[k].path, &in[k].p, &in[k].rep, box_text != NULL,
                               opts[O_PERIODIC].given);
    approx_writer out = {
        fmt, &sw, opname, kernel, field, hdx, beta, hpol, dim, "", opts[O_PERIODIC].given, tol};
    for (int a = 0, k = 0; a < dim; ++a)
        if (periodic[a]) out.pdesc[k++] = "xyz"[a];
    write_head(&out);
    rc = 1;
    if (consph_approx_sweep_run(&sw, rows, res, print_row, &out) != CONSPH_OK) {
        fprintf(stderr, "consph approx: %s\n", consph_last_error());
        goto out;
    }
    char series[96];
    snprintf(series, sizeof series, "%s %s %s", opname, consph_form_name(s.op.form),
             consph_corr_name(s.op.corr));
    consph_series_order fits[4];
    const int fit_rc =
        fit_orders(rows, res, nrows, series, from_files ? in : NULL, fmt == 0 ? "+-" : "±", fits);
    if (fmt == 0) {
        for (int k = 0; k < 4; ++k) printf("order (%s): %s\n", norm_names[k], fits[k].text);
    } else if (fmt == 2) {
        write_json(&out, rows, res, fits);
    }
    if (fit_rc) {
        rc = fit_rc;
        goto out;
    }
    rc = 0;
out:
    if (in) free_inputs(in, nin);
    return rc;
}
