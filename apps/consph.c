/* consph command-line tool: dispatch only; each subcommand parses its own options. */
#include <stdio.h>
#include <string.h>

#include "commands.h"
#include "consph/core.h"

typedef struct subcommand {
    const char *name;
    int (*run)(int argc, char **argv);
    const char *summary;
} subcommand;

static const subcommand subcommands[] = {
    {"kernels", cmd_kernels, "list every kernel with its support, edge smoothness and dimensions"},
    {"kernel", cmd_kernel, "tabulate one kernel: q, W, dW/dr, d2W/dr2"},
    {"layout", cmd_layout, "generate a particle arrangement and write it as .vtu or .csv"},
    {"approx", cmd_approx, "measure an operator's accuracy and order of convergence"},
    {"study", cmd_study, "run a convergence study that reproduces a paper's figure or table"},
    {"wasserstein", cmd_wasserstein, "Wasserstein distance between two particle files"},
};
#define NSUB (sizeof subcommands / sizeof subcommands[0])

static void usage(FILE *out)
{
    fprintf(out, "consph %s: consistent, convergent Smoothed Particle Hydrodynamics\n\n",
            CONSPH_VERSION);
    fprintf(out, "usage: consph COMMAND [options]   (consph COMMAND --help for its options)\n\n");
    fprintf(out, "commands:\n");
    for (size_t k = 0; k < NSUB; ++k)
        fprintf(out, "  %-10s %s\n", subcommands[k].name, subcommands[k].summary);
    fprintf(out, "\nexit status: 0 success, 1 failure while running, 2 bad usage or input\n");
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 ||
        strcmp(argv[1], "help") == 0) {
        usage(stdout);
        return 0;
    }
    if (strcmp(argv[1], "--version") == 0) {
        printf("consph %s\n", CONSPH_VERSION);
        return 0;
    }
    for (size_t k = 0; k < NSUB; ++k)
        if (strcmp(argv[1], subcommands[k].name) == 0)
            return subcommands[k].run(argc - 1, argv + 1);
    fprintf(stderr, "consph: unknown command '%s'; allowed:", argv[1]);
    for (size_t k = 0; k < NSUB; ++k) fprintf(stderr, " %s", subcommands[k].name);
    fprintf(stderr, "\n");
    return 2;
}
