/* consph kernels / consph kernel: list the kernels, tabulate one of them. */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "commands.h"
#include "consph/kernels.h"

enum { FORMAT_TABLE, FORMAT_CSV };
#define FORMAT_CHOICES "table,csv"

/* One CSV field, quoted when it holds a separator or a quote (RFC 4180). */
static void csv_text(const char *s)
{
    if (!strpbrk(s, ",\"\n")) {
        fputs(s, stdout);
        return;
    }
    putchar('"');
    for (; *s; ++s) {
        if (*s == '"') putchar('"');
        putchar(*s);
    }
    putchar('"');
}

static const char kernels_details[] =
    "columns:\n"
    "  support   support radius in units of h (W = 0 for r >= support*h)\n"
    "  beta_001  edge smoothness as 001 defines it: the order of the first derivative that is\n"
    "            nonzero at the edge of the support (0: the kernel itself is cut there)\n"
    "  beta_002  the same as 002 defines it (the largest order whose derivatives all vanish\n"
    "            at the edge) = beta_001 - 1; -1 for a kernel cut at the edge\n"
    "  dims      dimensions the kernel is normalised in\n"
    "The support-2h Wendland kernels use PySPH's own 1D polynomials, whose beta_001 in 1D is\n"
    "3, 5, 7; the columns give the 2D/3D values and the description the 1D one.\n"
    "W(r, h) = sigma_d / h^d f(r/h); m4 is the tensor product prod_a M4(|dx_a|/h) / h^d.\n"
    "\n"
    "exit status: 0 success, 1 failure while writing, 2 bad usage";

int cmd_kernels(int argc, char **argv)
{
    int format = FORMAT_TABLE;
    cli_opt opts[] = {
        {"--format", CLI_CHOICE, &format, "F", "output format (default table)", FORMAT_CHOICES, 0,
         0, 0},
    };
    cli_command cmd = {
        "kernels",
        "List every smoothing kernel: name, support, edge smoothness beta under both papers'\n"
        "definitions, dimensions, source paper and equation, and a description.",
        "consph kernels [--format table|csv]",
        kernels_details,
        opts,
        (int)(sizeof opts / sizeof opts[0]),
        0,
        NULL,
    };
    int rc = cli_parse(&cmd, argc, argv);
    if (rc == 1) return 0;
    if (rc) return rc;

    if (format == FORMAT_CSV)
        printf("name,support,beta_001,beta_002,dims,source,description\n");
    else
        printf("%-15s %7s %8s %8s %-5s  %-44s %s\n", "name", "support", "beta_001", "beta_002",
               "dims", "source", "description");
    for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id) {
        const consph_kernel_info *info = consph_kernel_info_get((consph_kernel_id)id);
        char dims[16] = "";
        for (int d = 1; d <= CONSPH_MAX_DIM; ++d)
            if (info->sigma[d - 1] > 0.0) {
                size_t len = strlen(dims);
                snprintf(dims + len, sizeof dims - len, "%s%d", len ? "," : "", d);
            }
        if (format == FORMAT_CSV) {
            printf("%s,%g,%d,%d,", info->name, info->support, info->beta_001, info->beta_001 - 1);
            csv_text(dims);
            putchar(',');
            csv_text(info->source);
            putchar(',');
            csv_text(info->description);
            putchar('\n');
        } else {
            printf("%-15s %5gh %8d %8d %-5s  %-44s %s\n", info->name, info->support, info->beta_001,
                   info->beta_001 - 1, dims, info->source, info->description);
        }
    }
    return 0;
}

static const char kernel_details[] =
    "Rows run from q = r/h = 0 to the support edge in --points equal steps:\n"
    "  q, W = sigma_d/h^d f(q), dW/dr = sigma_d/h^(d+1) f'(q), d2W/dr2 = sigma_d/h^(d+2) f''(q).\n"
    "The table is the command's only output, so --table may be given or left out.\n"
    "At the edge itself every kernel is 0 (the cut kernels gaussian and super-gaussian jump\n"
    "there). For m4, a tensor product, the values are along a coordinate axis, where\n"
    "W = M4(q)/h^d.\n"
    "--format table prints '#' comment lines (kernel, dimension, h, support, sigma_d) and aligned\n"
    "columns; --format csv prints the header row q,W,dW_dr,d2W_dr2 and the rows only.\n"
    "\n"
    "exit status: 0 success, 1 failure while writing, 2 bad usage";

int cmd_kernel(int argc, char **argv)
{
    int format = FORMAT_TABLE, table = 0;
    long dim = 0, points = 101;
    double h = 1.0;
    const char *positional[1] = {NULL};
    cli_opt opts[] = {
        {"--dim", CLI_INT, &dim, "D", "dimension (required)", NULL, 1, 3, 0},
        {"--table", CLI_FLAG, &table, NULL, "tabulate the kernel (the default and only output)",
         NULL, 0, 0, 0},
        {"--points", CLI_INT, &points, "N", "rows, q = 0 to the support edge (default 101)", NULL,
         2, 100000, 0},
        {"--h", CLI_DOUBLE, &h, "H", "smoothing length h (default 1)", NULL, 1e-12, 1e12, 0},
        {"--format", CLI_CHOICE, &format, "F", "output format (default table)", FORMAT_CHOICES, 0,
         0, 0},
    };
    cli_command cmd = {
        "kernel",
        "Tabulate one kernel: q, W, dW/dr and d2W/dr2 from q = 0 to the edge of its support.\n"
        "NAME is one of the names 'consph kernels' lists.",
        "consph kernel NAME --dim D [--table] [--points N] [--h H] [--format table|csv]",
        kernel_details,
        opts,
        (int)(sizeof opts / sizeof opts[0]),
        1,
        positional,
    };
    int rc = cli_parse(&cmd, argc, argv);
    if (rc == 1) return 0;
    if (rc) return rc;

    if (!positional[0])
        return cli_error(&cmd, "missing kernel NAME; allowed: %s", consph_kernel_names());
    consph_kernel_id id;
    if (consph_kernel_lookup(positional[0], &id) != CONSPH_OK)
        return cli_error(&cmd, "unknown kernel '%s'; allowed: %s", positional[0],
                         consph_kernel_names());
    if (!opts[0].given) return cli_error(&cmd, "option --dim is required; allowed: integer 1..3");
    consph_kernel k;
    if (consph_kernel_init(&k, id, (int)dim, h) != CONSPH_OK)
        return cli_error(&cmd, "option --h: %s", consph_last_error());

    if (format == FORMAT_CSV) {
        printf("q,W,dW_dr,d2W_dr2\n");
    } else {
        printf("# kernel %s, dimension %d, h = %.17g, support %g h, sigma_%d = %.17g\n", k.name,
               k.dim, k.h, k.support, k.dim, consph_kernel_info_get(id)->sigma[k.dim - 1]);
        printf("%24s %24s %24s %24s\n", "q", "W", "dW/dr", "d2W/dr2");
    }
    for (long i = 0; i < points; ++i) {
        /* From q directly, not r = q h: r / h could round to just below the edge. */
        double q = k.support * (double)i / (double)(points - 1);
        /* + 0.0 prints f'(0) = -0 as 0. */
        double w = k.norm * k.f(q), dw = k.norm * k.inv_h * k.df(q) + 0.0,
               d2w = k.norm * k.inv_h * k.inv_h * k.d2f(q);
        if (format == FORMAT_CSV)
            printf("%.17g,%.17g,%.17g,%.17g\n", q, w, dw, d2w);
        else
            printf("%24.16e %24.16e %24.16e %24.16e\n", q, w, dw, d2w);
    }
    return 0;
}
