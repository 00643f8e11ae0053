/* consph command-line tool: dispatch only; each subcommand parses its own options. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "commands.h"
#include "consph/core.h"
#include "consph/par.h"
#include "consph/solver.h"

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
    {"run", cmd_run, "run a simulation: a weakly-compressible SPH problem, or 002's heat problem"},
};
#define NSUB (sizeof subcommands / sizeof subcommands[0])

/* `head` and a comma-separated list, one item after the other, wrapped at 80 columns. */
static void print_list(FILE *out, const char *head, const char *list)
{
    fprintf(out, "%s\n ", head);
    int col = 1;
    for (const char *c = list; *c;) {
        size_t len = strcspn(c, ",");
        if (col + 1 + (int)len > 80) {
            fprintf(out, "\n ");
            col = 1;
        }
        fprintf(out, " %.*s", (int)len, c);
        col += 1 + (int)len;
        c += len;
        if (*c) ++c;
    }
    fprintf(out, "\n");
}

static void usage(FILE *out)
{
    fprintf(out, "consph %s: consistent, convergent Smoothed Particle Hydrodynamics\n\n",
            CONSPH_VERSION);
    fprintf(out, "usage: consph COMMAND [options]   (consph COMMAND --help for its options)\n\n");
    fprintf(out, "commands:\n");
    for (size_t k = 0; k < NSUB; ++k)
        fprintf(out, "  %-12s %s\n", subcommands[k].name, subcommands[k].summary);
    /* From the registries, so that a new problem or scheme is listed without an edit here. */
    char problems[512];
    snprintf(problems, sizeof problems, "%s,heat", consph_problem_names());
    fprintf(out, "\n");
    print_list(out, "problems (consph run PROBLEM):", problems);
    print_list(out, "schemes (consph run --scheme):", consph_scheme_names());
    fprintf(out,
            "\nexit status: 0 success, 1 failure while running (a failed write included), 2 bad\n"
            "usage or input, 3 a non-finite result or a run that left its model's validity,\n"
            "130/143 stopped by SIGINT/SIGTERM\n");
}

/* libgomp's default spins 300 000 times (~7 ms here) at every barrier before sleeping: on a
 * machine whose cores are busy with other work the spinning threads take the time the working
 * ones need (2 threads on a loaded 2-core machine ran a quick study 4-5x as long as 1). Sleeping
 * at once (passive) costs a futex wake-up, tens of µs, at every fork and join instead: a step
 * of wcsph at nx 100 holds ~14 parallel regions in ~2 ms, and 2 threads were then only 1.23x one
 * thread. A short spin, CONSPH_SPINCOUNT (~50 µs at ~25 ns a pause), covers the gaps inside a
 * step and still yields soon on a loaded machine: 2 threads 1.91x (nx 100) and 1.93x (nx 250)
 * one on the idle 2-core machine, and faster than passive with two busy processes beside it
 * (bench/results/threads-s31.md). libgomp reads GOMP_SPINCOUNT when it is loaded, before main,
 * so unless the user chose a policy or a spin count the CLI runs itself again with it. */
#define CONSPH_SPINCOUNT "2000"
static void prefer_short_spin(char **argv)
{
    if (getenv("OMP_WAIT_POLICY") || getenv("GOMP_SPINCOUNT")) return;
    /* Under valgrind the new image would run outside it (or not at all). */
    const char *preload = getenv("LD_PRELOAD");
    if (preload && strstr(preload, "vgpreload")) return;
    if (setenv("GOMP_SPINCOUNT", CONSPH_SPINCOUNT, 1) != 0) return;
    execv("/proc/self/exe", argv);
    /* No /proc: run on with libgomp's default, and say so truthfully in --version. */
    unsetenv("GOMP_SPINCOUNT");
}

/* Under K > 1 MPI ranks, `study` spreads its rows over the ranks and `run` is the solver's
 * (apps/cmd_run.c decides); every other command is run by rank 0 alone while the others wait:
 * they make one file or one listing, which K copies would only write over each other. */
static int runs_on_every_rank(const char *name)
{
    return strcmp(name, "study") == 0 || strcmp(name, "run") == 0;
}

static int dispatch(int argc, char **argv)
{
    /* Every path that writes to stdout ends in cli_finish_stdout: output lost to a full disk or
     * a closed pipe must not exit 0. */
    cli_stdout_init();
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 ||
        strcmp(argv[1], "help") == 0) {
        usage(stdout);
        return cli_finish_stdout(NULL, 0);
    }
    if (strcmp(argv[1], "--version") == 0) {
        const char *policy = getenv("OMP_WAIT_POLICY"), *spin = getenv("GOMP_SPINCOUNT");
        printf("consph %s\n", CONSPH_VERSION);
#ifdef _OPENMP
        printf("threads %d, OMP_WAIT_POLICY %s", consph_num_threads(),
               policy ? policy : "unset (libgomp default)");
        if (spin) printf(", GOMP_SPINCOUNT %s", spin);
        printf("\n");
#else
        (void)policy, (void)spin;
        printf("threads 1 (built without OpenMP)\n");
#endif
        if (consph_par_available())
            printf("MPI ranks %d\n", consph_par_size());
        else
            printf("MPI not built in\n");
        return cli_finish_stdout(NULL, 0);
    }
    for (size_t k = 0; k < NSUB; ++k)
        if (strcmp(argv[1], subcommands[k].name) == 0) {
            if (consph_par_rank() != 0 && !runs_on_every_rank(subcommands[k].name)) return 0;
            return cli_finish_stdout(subcommands[k].name, subcommands[k].run(argc - 1, argv + 1));
        }
    fprintf(stderr, "consph: unknown command '%s'; allowed:", argv[1]);
    for (size_t k = 0; k < NSUB; ++k) fprintf(stderr, " %s", subcommands[k].name);
    fprintf(stderr, "\n");
    return 2;
}

int main(int argc, char **argv)
{
    prefer_short_spin(argv);
    /* MPI only under a launcher (include/consph/par.h): a serial run never initialises it. */
    const int par = consph_par_init(&argc, &argv);
    if (par != CONSPH_OK) {
        /* each rank of a build without MPI believes it is rank 0: all of them say it */
        fprintf(stderr, "consph: %s\n", consph_last_error());
        return par == CONSPH_EINVAL ? 2 : 1;
    }
    /* A message every rank would print (a bad option) is printed once, by rank 0; errors met on
     * one rank only reach rank 0 through consph_par_agree. */
    consph_par_quiet_others();
    int rc = dispatch(argc, argv);
    /* A rank that ended `study` (or `run`) before its run (a file that only it could not read)
     * joins the run's first agreement, so that the others end too instead of waiting for it. */
    const int study = argc > 1 && strcmp(argv[1], "study") == 0 && !cmd_study_started;
    const int run = argc > 1 && strcmp(argv[1], "run") == 0 && !cmd_run_started;
    if (consph_par_size() > 1 && (study || run))
        consph_par_agree(rc == 0 ? CONSPH_OK
                                 : consph_fail(CONSPH_EINVAL,
                                               "rank %d of %d stopped before the %s started "
                                               "(exit %d); only rank 0 prints its messages",
                                               consph_par_rank(), consph_par_size(),
                                               study ? "study" : "run", rc));
    /* Every rank exits with rank 0's status, the one whose messages were printed. */
    rc = consph_par_bcast_int(rc);
    consph_par_finalize();
    return rc;
}
