/* consph study: run a study declared in studies/NAME.study (docs/studies.md). */
#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "commands.h"
#include "consph/gpu.h"
#include "consph/io.h"
#include "consph/par.h"
#include "consph/study.h"

/* Longest --out accepted: DIR/STUDY/FIGURE.svg.tmp.PID must stay under PATH_MAX. */
#define OUT_DIR_MAX 3800

static int is_dir(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 && S_ISDIR(st.st_mode);
}

/* Where study files live, in order of precedence: $CONSPH_STUDIES, ./studies, the source
 * tree, the install tree. A directory only provides the studies it holds, so a local
 * ./studies with other files does not hide the built-in ones. */
static int study_dirs(const char **dirs)
{
    const char *cand[] = {getenv("CONSPH_STUDIES"), "studies", CONSPH_SOURCE_DIR "/studies",
                          CONSPH_DATA_DIR "/studies"};
    int n = 0;
    for (size_t k = 0; k < sizeof cand / sizeof cand[0]; ++k)
        if (cand[k] && *cand[k] && is_dir(cand[k])) dirs[n++] = cand[k];
    return n;
}

/* DIR/NAME.study from the first study directory that has it. */
static int find_study(const char *name, char *path, size_t size)
{
    const char *dirs[4];
    int n = study_dirs(dirs);
    for (int k = 0; k < n; ++k) {
        snprintf(path, size, "%s/%s.study", dirs[k], name);
        struct stat st;
        if (stat(path, &st) == 0 && S_ISREG(st.st_mode)) return 1;
    }
    return 0;
}

/* Whether `dir` exists as a writable directory or could be created (cli_dir_writable), and the
 * path leaves room for the study's own names. */
static int dir_creatable(const char *dir, char *why, size_t size)
{
    if (strlen(dir) > OUT_DIR_MAX) {
        snprintf(why, size, "longer than %d characters", OUT_DIR_MAX);
        return 0;
    }
    for (const char *c = dir; *c;) {
        size_t n = strcspn(c, "/");
        if (n > NAME_MAX) {
            snprintf(why, size, "a path component is longer than %d characters", NAME_MAX);
            return 0;
        }
        c += n + (c[n] == '/');
    }
    return cli_dir_writable(dir, why, size);
}

typedef struct study_entry {
    char *name, *file;
} study_entry;

static int compare_entries(const void *a, const void *b)
{
    return strcmp(((const study_entry *)a)->name, ((const study_entry *)b)->name);
}

static int list_studies(const cli_command *cmd)
{
    const char *dirs[4];
    int ndirs = study_dirs(dirs);
    if (!ndirs) return cli_error(cmd, "no studies directory found (set CONSPH_STUDIES)");
    /* Every study once, from the first directory that has it. */
    study_entry found[512];
    int n = 0;
    for (int k = 0; k < ndirs; ++k) {
        DIR *d = opendir(dirs[k]);
        if (!d) continue;
        struct dirent *e;
        while ((e = readdir(d)) && n < 512) {
            size_t len = strlen(e->d_name);
            if (len <= 6 || strcmp(e->d_name + len - 6, ".study") != 0) continue;
            int seen = 0;
            for (int q = 0; q < n && !seen; ++q)
                seen = strncmp(found[q].name, e->d_name, len - 6) == 0 &&
                       found[q].name[len - 6] == '\0';
            if (seen) continue;
            found[n].name = malloc(len - 5);
            found[n].file = malloc(strlen(dirs[k]) + len + 2);
            if (!found[n].name || !found[n].file) {
                free(found[n].name);
                free(found[n].file);
                break;
            }
            snprintf(found[n].name, len - 5, "%s", e->d_name);
            sprintf(found[n].file, "%s/%s", dirs[k], e->d_name);
            ++n;
        }
        closedir(d);
    }
    qsort(found, (size_t)n, sizeof found[0], compare_entries);
    int rc = 0;
    for (int k = 0; k < n; ++k) {
        consph_study *s;
        if (consph_study_load(found[k].file, &s) != CONSPH_OK) {
            fprintf(stderr, "consph study: %s\n", consph_last_error());
            rc = 1;
        } else {
            printf("%-16s %s\n", consph_study_name(s), consph_study_title(s));
            consph_study_free(s);
        }
        free(found[k].file);
        free(found[k].name);
    }
    return rc;
}

/* The particle files of --particles, read (and every bad one rejected) before the study runs. */
typedef struct study_inputs {
    int n;
    char *names[CLI_LIST_MAX];
    consph_particles sets[CLI_LIST_MAX];
} study_inputs;

static void free_inputs(study_inputs *in)
{
    for (int k = 0; k < in->n; ++k) {
        consph_particles_free(&in->sets[k]);
        free(in->names[k]);
    }
    in->n = 0;
}

/* Reads every file of `list` (consph_particle_input_read: a file without volumes gets box
 * volume / N, used by figures that ask for `volume = given`; the others compute their own). */
static int read_inputs(const cli_command *cmd, const char *list, const char *box_text,
                       const char *periodic_text, study_inputs *in)
{
    consph_read_options ro;
    memset(&ro, 0, sizeof ro);
    if (box_text) {
        if (cli_parse_box(box_text, &ro.box)) return cli_bad_box(cmd, box_text);
        ro.have_box = 1;
    }
    if (periodic_text) {
        if (cli_parse_periodic(periodic_text, ro.periodic))
            return cli_bad_periodic(cmd, periodic_text);
        ro.have_periodic = 1;
    }
    if (!cli_list_items_nonempty(list))
        return cli_error(cmd, "option --particles: '%s' is not a comma-separated list of files",
                         list);
    const char *t = list;
    while (*t) {
        const char *comma = strchr(t, ',');
        size_t n = comma ? (size_t)(comma - t) : strlen(t);
        if (in->n == CLI_LIST_MAX) {
            free_inputs(in);
            return cli_error(cmd, "option --particles: at most %d files", CLI_LIST_MAX);
        }
        char *name = malloc(n + 1);
        if (!name) {
            free_inputs(in);
            return cli_error(cmd, "out of memory");
        }
        memcpy(name, t, n);
        name[n] = '\0';
        in->names[in->n] = name;
        consph_particle_format pf;
        if (consph_particle_format_from_path(name, &pf) != CONSPH_OK) {
            cli_error(cmd, "option --particles: %s", consph_last_error());
            free(name);
            free_inputs(in);
            return CLI_EXIT_USAGE;
        }
        consph_particle_input file;
        if (consph_particle_input_read(name, &ro, &file) != CONSPH_OK) {
            fprintf(stderr, "consph study: %s\n", consph_last_error());
            free(name);
            free_inputs(in);
            return CLI_EXIT_USAGE;
        }
        /* The figures choose their volume kind (key `volume`); given volumes follow the rule
         * of consph_particle_input_read. */
        in->sets[in->n] = file.p;
        const consph_read_report rep = file.rep;
        consph_particles *p = &in->sets[in->n++];
        if (periodic_text && cli_check_periodic_dim(cmd, periodic_text, p->dim)) {
            free_inputs(in);
            return CLI_EXIT_USAGE;
        }
        cli_note_read_defaults(cmd, name, p, &rep, box_text != NULL, periodic_text != NULL);
        const char *vol = rep.volumes == CONSPH_VOLUMES_NONE
                              ? "none in the file: box volume / N where a figure asks for given "
                                "volumes"
                              : consph_volume_origin_name(rep.volumes);
        printf("particles %s: %zu, %dD, volumes %s", name, p->n, p->dim, vol);
        if (rep.wrapped) printf("; %zu wrapped into the periodic box", rep.wrapped);
        printf("\n");
        t += n + (comma ? 1 : 0);
    }
    return 0;
}

/* Exit status of a failed run: 2 bad input, 3 a non-finite result (as consph approx), else 1. */
static int run_status(int rc)
{
    return rc == CONSPH_EFORMAT || rc == CONSPH_EINVAL ? CLI_EXIT_USAGE
           : rc == CONSPH_ENUMERIC                     ? CLI_EXIT_NONFINITE
                                                       : 1;
}

/* The estimate in seconds, and in minutes, hours or days as its size asks; `jobs` workers
 * (threads where the rows share a GPU). */
static void print_estimate(double est, long jobs, int threads)
{
    if (!isfinite(est)) {
        printf("estimated run time: unknown (the calibration run failed)\n");
        return;
    }
    printf("estimated run time: %.0f s", est);
    if (est >= 2 * 86400.0)
        printf(" (%.1f days, %.1f hours)", est / 86400.0, est / 3600.0);
    else if (est >= 2 * 3600.0)
        printf(" (%.1f hours)", est / 3600.0);
    else
        printf(" (%.1f min)", est / 60.0);
    if (jobs > 1) printf(" on %ld worker %s", jobs, threads ? "threads" : "processes");
    printf("; from the work (particle-steps, neighbour pairs, packed particles) at the cost "
           "measured here on small runs\n");
}

/* A word as a shell reads it back: quoted unless made of safe characters only. */
static size_t shell_word(char *buf, size_t size, const char *w)
{
    int plain = *w != '\0';
    for (const char *c = w; *c && plain; ++c)
        plain = strchr("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-_./=,:+@",
                       *c) != NULL;
    if (plain) return (size_t)snprintf(buf, size, "%s", w);
    size_t n = 0;
    n += (size_t)snprintf(buf + n, n < size ? size - n : 0, "'");
    for (const char *c = w; *c; ++c)
        n += (size_t)snprintf(buf + n, n < size ? size - n : 0, *c == '\'' ? "'\\''" : "%c", *c);
    n += (size_t)snprintf(buf + n, n < size ? size - n : 0, "'");
    return n;
}

/* The command line that resumes this one: its own words, and --resume. */
static char *resume_command(int argc, char **argv, int resume)
{
    size_t size = 64;
    for (int a = 0; a < argc; ++a) size += 4 * strlen(argv[a]) + 3;
    char *buf = malloc(size);
    if (!buf) return NULL;
    size_t n = (size_t)snprintf(buf, size, "consph");
    for (int a = 0; a < argc; ++a) {
        buf[n++] = ' ';
        n += shell_word(buf + n, size - n, argv[a]);
    }
    if (!resume) snprintf(buf + n, size - n, " --resume");
    return buf;
}

/* The default of --jobs: a worker per core OpenMP would use (OMP_NUM_THREADS), each with one
 * thread: rows run whole on one core each beat every row spread over the cores (001-table9
 * --quick on 2 cores, docs/studies.md). */
static long jobs_default(void)
{
    const int cores = consph_num_threads();
    return cores < 1 ? 1 : cores > 256 ? 256 : cores;
}

int cmd_study_started;

int cmd_study(int argc, char **argv)
{
    int quick = 0, list = 0, estimate_only = 0, resume = 0;
    long jobs = 0;        /* 0: the default, jobs_default() */
    int device_index = 0; /* of "cpu,gpu,auto", when --device is given */
    const char *out = "out/studies";
    const char *name = NULL, *particles = NULL, *box_text = NULL, *periodic_text = NULL;
    cli_cache cache = {NULL, 0};
    cli_opt opts[] = {
        {"--list", CLI_FLAG, &list, NULL, "list the available studies and exit", NULL, 0, 0, 0},
        {"--quick", CLI_FLAG, &quick, NULL,
         "reduced resolutions (each study in under a minute on 2 cores)", NULL, 0, 0, 0},
        {"--out", CLI_STRING, &out, "DIR", "results go to DIR/NAME/ (default out/studies)", NULL, 0,
         0, 0},
        {"--estimate", CLI_FLAG, &estimate_only, NULL, "print the run-time estimate and exit", NULL,
         0, 0, 0},
        {"--resume", CLI_FLAG, &resume, NULL,
         "go on with a stopped study: the rows it finished (kept in DIR/NAME/) are read back, not "
         "run again; refused when the study file, --quick or --particles differ",
         NULL, 0, 0, 0},
        {"--particles", CLI_STRING, &particles, "FILE,FILE,...",
         "particle files (.csv or .vtu) in place of every figure's layout: one row per file, in "
         "order, at nx = N^(1/dim); an h/dx sweep runs on the last file",
         NULL, 0, 0, 0},
        {"--box", CLI_STRING, &box_text, "x0:x1,y0:y1[,z0:z1]",
         "with --particles: the domain (default: the box each file carries)", NULL, 0, 0, 0},
        {"--periodic", CLI_STRING, &periodic_text, "yes|no|AXES",
         "with --particles: periodic axes (default: each file's own)", NULL, 0, 0, 0},
        {"--jobs", CLI_INT, &jobs, "J",
         "run the rows on J worker processes, each with cores/J threads, and write the report a "
         "serial run writes (default: the cores, OMP_NUM_THREADS; 1: this process alone; with "
         "--device gpu or auto: J threads of this process, whose rows share the GPU, default 1)",
         NULL, 1, 256, 0},
        {"--device", CLI_CHOICE, &device_index, "D",
         "where the solver rows run: cpu, gpu (every row, else exit 2 naming those that cannot), "
         "auto (the GPU where it can; docs/gpu.md); default: the study file's key `device`, else "
         "cpu",
         "cpu,gpu,auto", 0, 0, 0},
        CLI_CACHE_OPTS(cache),
    };
    const char *positional[1] = {NULL};
    cli_command cmd = {
        "study",
        "Run a convergence study declared in studies/NAME.study: per figure or "
        "table a CSV, a markdown report with the paper's numbers beside ours, and "
        "a gnuplot figure.",
        "consph study NAME [--quick] [--out DIR] [--particles FILE,...] [--estimate] "
        "[--resume] [--jobs J] [--device cpu|gpu|auto] | consph study --list",
        "NAME is a study name (see --list) or a path to a .study file; NAME.study "
        "is taken from the first of $CONSPH_STUDIES, ./studies and the built-in "
        "studies that has it.\n"
        "Without --quick the paper's resolutions are used and a run-time "
        "estimate is printed first. File format: docs/studies.md.\n"
        "Progress goes to stderr: a live line on a terminal, else a line per "
        "finished row. SIGINT or SIGTERM ends the current row at its next step, "
        "writes the partial README.md and prints the command that resumes.\n"
        "Under mpirun -np K the rows are spread over the K ranks and rank 0 writes "
        "the same report (docs/mpi.md); --out must be seen by every rank; --jobs J "
        "does the same with J forked processes of this machine (docs/studies.md), or J threads "
        "with --device gpu or auto, whose rows share the GPU (docs/gpu.md).\n"
        "Exit status: 0 done, 1 a run failed, 2 bad input, 3 an error is not "
        "finite (stderr names the figure, series and resolution), 128 + signal "
        "stopped.",
        opts,
        (int)(sizeof opts / sizeof opts[0]),
        1,
        positional};
    int rc = cli_parse(&cmd, argc, argv);
    if (rc) return rc == 1 ? 0 : rc;
    if ((rc = cli_cache_apply(&cmd, &cache))) return rc;
    if (list) return list_studies(&cmd);
    const cli_opt *jobs_opt = opts;
    while (strcmp(jobs_opt->name, "--jobs")) jobs_opt++;
    if (jobs_opt->given && estimate_only)
        return cli_error(&cmd, "option --jobs: not with --estimate, which runs nothing");
    /* Under mpirun the ranks share the rows already; workers on every rank would oversubscribe. */
    if (jobs_opt->given && jobs > 1 && consph_par_size() > 1)
        return cli_error(&cmd,
                         "option --jobs: %ld workers under mpirun on %d ranks; allowed there: 1 "
                         "(the ranks share the rows, docs/mpi.md)",
                         jobs, consph_par_size());
    if (!jobs_opt->given) jobs = consph_par_size() > 1 ? 1 : jobs_default();
    char why[2200];
    if (!*out || !dir_creatable(out, why, sizeof why))
        return cli_error(&cmd, "option --out: cannot write results under '%.200s%s': %s", out,
                         strlen(out) > 200 ? "..." : "", *out ? why : "empty path");
    name = positional[0];
    if (!name) return cli_error(&cmd, "a study NAME is required; see 'consph study --list'");
    char path[2048];
    size_t len = strlen(name);
    if (len > 6 && strcmp(name + len - 6, ".study") == 0) {
        snprintf(path, sizeof path, "%s", name);
    } else if (!find_study(name, path, sizeof path)) {
        return cli_error(&cmd,
                         "unknown study '%s' (no %s.study in $CONSPH_STUDIES, ./studies or "
                         "the built-in studies); see 'consph study --list'",
                         name, name);
    }
    if (!particles && (box_text || periodic_text))
        return cli_error(&cmd, "option %s: only with --particles",
                         box_text ? "--box" : "--periodic");
    consph_study *s;
    if (consph_study_load(path, &s) != CONSPH_OK) return cli_error(&cmd, "%s", consph_last_error());
    if (consph_study_validate(s, quick) != CONSPH_OK) {
        consph_study_free(s);
        return cli_error(&cmd, "%s", consph_last_error());
    }
    /* The device before anything runs (the estimate's calibration included): a row the GPU
     * cannot run under --device gpu, or a GPU shared by processes, writes nothing. */
    const cli_opt *device_opt = opts;
    while (strcmp(device_opt->name, "--device")) device_opt++;
    const int device =
        consph_study_device_of(s, device_opt->given ? CONSPH_STUDY_DEVICE_CPU + device_index
                                                    : CONSPH_STUDY_DEVICE_DEFAULT);
    const int on_gpu = device == CONSPH_STUDY_DEVICE_GPU || device == CONSPH_STUDY_DEVICE_AUTO;
    /* one GPU: the default of one worker per core becomes one process */
    if (on_gpu && !jobs_opt->given) jobs = 1;
    rc = 0;
    if (on_gpu && consph_par_size() > 1)
        rc = cli_error(&cmd,
                       "option --device %s runs the study on one process with one GPU: launched "
                       "on %d MPI ranks, run it without mpirun (or with -np 1)",
                       consph_study_device_name(device), consph_par_size());
    else if (consph_study_device_check(s, quick, device) != CONSPH_OK)
        rc = cli_error(&cmd, "%s", consph_last_error());
    if (rc) {
        consph_study_free(s);
        return rc;
    }
    if (device == CONSPH_STUDY_DEVICE_AUTO && !consph_gpu_available(why, sizeof why))
        fprintf(stderr, "consph study: --device auto: %s; every row runs on the CPU\n", why);
    /* Files are read whole before the study starts: a bad one writes nothing. */
    static study_inputs in;
    if (particles) {
        rc = read_inputs(&cmd, particles, box_text, periodic_text, &in);
        if (rc) {
            consph_study_free(s);
            return rc;
        }
        printf("study %s: %s (on %d particle file%s)\n", consph_study_name(s),
               consph_study_title(s), in.n, in.n == 1 ? "" : "s");
    } else {
        printf("study %s: %s (%s resolutions)\n", consph_study_name(s), consph_study_title(s),
               quick ? "quick" : "paper");
    }
    /* Under MPI the estimate's calibration runs on rank 0 alone, which prints it. */
    if ((!quick || estimate_only) && consph_par_rank() == 0) {
        /* for the workers that will run: calibrated at a worker's threads, the work shared
         * evenly between them */
        const int cores = consph_num_threads();
        if (jobs > 1) consph_set_num_threads(cores / jobs > 1 ? (int)(cores / jobs) : 1);
        double est = particles ? consph_study_estimate_particles(s, quick, in.sets, in.n)
                               : consph_study_estimate(s, quick);
        if (jobs > 1) {
            consph_set_num_threads(cores);
            est /= (double)jobs;
        }
        print_estimate(est, jobs, on_gpu);
        fflush(stdout);
    }
    char *resume_cmd = resume_command(argc, argv, resume);
    int stopped_by = 0;
    consph_study_options o = {.quick = quick, .out_dir = out, .log = stdout};
    o.progress = 1;
    o.resume = resume;
    o.resume_cmd = resume_cmd;
    o.stopped_by = &stopped_by;
    o.jobs = (int)jobs;
    o.device = device;
    double t0 = consph_wtime();
    rc = CONSPH_OK;
    /* SIGINT/SIGTERM: the current row ends at its next step, the partial report is written. */
    if (!estimate_only) rc = consph_stop_install();
    if (rc == CONSPH_OK && !estimate_only) {
        /* its first collective call agrees the start with every rank (apps/consph.c) */
        cmd_study_started = 1;
        rc = particles
                 ? consph_study_run_particles(s, &o, in.sets, (const char *const *)in.names, in.n)
                 : consph_study_run(s, &o);
    }
    if (!estimate_only) consph_stop_uninstall();
    free_inputs(&in);
    if (rc == CONSPH_OK && stopped_by) {
        fprintf(stderr,
                "consph study: stopped by %s; partial report in %s/%s/README.md; the finished "
                "rows are kept: resume with\n  %s\n",
                stopped_by == SIGINT    ? "SIGINT"
                : stopped_by == SIGTERM ? "SIGTERM"
                                        : "a signal",
                out, consph_study_name(s), resume_cmd ? resume_cmd : "consph study NAME --resume");
        free(resume_cmd);
        consph_study_free(s);
        return 128 + stopped_by;
    }
    free(resume_cmd);
    if (rc != CONSPH_OK) {
        fprintf(stderr, "consph study: %s\n", consph_last_error());
        consph_study_free(s);
        return run_status(rc);
    }
    if (estimate_only) {
        consph_study_free(s);
        return 0;
    }
    printf("done in %.1f s: %s/%s/README.md\n", consph_wtime() - t0, out, consph_study_name(s));
    consph_study_free(s);
    return 0;
}
