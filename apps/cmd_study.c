/* consph study: run a study declared in studies/NAME.study (docs/studies.md). */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "commands.h"
#include "consph/study.h"

static int is_dir(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 && S_ISDIR(st.st_mode);
}

/* Where study files live: $CONSPH_STUDIES, ./studies, the source tree, the install tree. */
static const char *studies_dir(void)
{
    const char *env = getenv("CONSPH_STUDIES");
    if (env && is_dir(env)) return env;
    if (is_dir("studies")) return "studies";
    if (is_dir(CONSPH_SOURCE_DIR "/studies")) return CONSPH_SOURCE_DIR "/studies";
    if (is_dir(CONSPH_DATA_DIR "/studies")) return CONSPH_DATA_DIR "/studies";
    return NULL;
}

static int compare_names(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

static int list_studies(const cli_command *cmd)
{
    const char *dir = studies_dir();
    if (!dir) return cli_error(cmd, "no studies directory found (set CONSPH_STUDIES)");
    DIR *d = opendir(dir);
    if (!d) return cli_error(cmd, "cannot read '%s'", dir);
    char *names[512];
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) && n < 512) {
        size_t len = strlen(e->d_name);
        if (len > 6 && strcmp(e->d_name + len - 6, ".study") == 0) {
            names[n] = malloc(strlen(dir) + len + 2);
            if (!names[n]) break;
            sprintf(names[n], "%s/%s", dir, e->d_name);
            ++n;
        }
    }
    closedir(d);
    qsort(names, (size_t)n, sizeof names[0], compare_names);
    int rc = 0;
    for (int k = 0; k < n; ++k) {
        consph_study *s;
        if (consph_study_load(names[k], &s) != CONSPH_OK) {
            fprintf(stderr, "consph study: %s\n", consph_last_error());
            rc = 1;
        } else {
            printf("%-16s %s\n", consph_study_name(s), consph_study_title(s));
            consph_study_free(s);
        }
        free(names[k]);
    }
    return rc;
}

int cmd_study(int argc, char **argv)
{
    int quick = 0, list = 0, estimate_only = 0;
    const char *out = "out/studies";
    const char *name = NULL;
    cli_opt opts[] = {
        {"--list", CLI_FLAG, &list, NULL, "list the available studies and exit", NULL, 0, 0, 0},
        {"--quick", CLI_FLAG, &quick, NULL,
         "reduced resolutions (each study in under a minute on 2 cores)", NULL, 0, 0, 0},
        {"--out", CLI_STRING, &out, "DIR", "results go to DIR/NAME/ (default out/studies)", NULL, 0,
         0, 0},
        {"--estimate", CLI_FLAG, &estimate_only, NULL, "print the run-time estimate and exit", NULL,
         0, 0, 0},
    };
    const char *positional[1] = {NULL};
    cli_command cmd = {"study",
                       "Run a convergence study declared in studies/NAME.study: per figure or "
                       "table a CSV, a markdown report with the paper's numbers beside ours, and "
                       "a gnuplot figure.",
                       "consph study NAME [--quick] [--out DIR] | consph study --list",
                       "NAME is a study name (see --list) or a path to a .study file; the study "
                       "directory is $CONSPH_STUDIES, ./studies or the source tree's studies/.\n"
                       "Without --quick the paper's resolutions are used and a run-time "
                       "estimate is printed first. File format: docs/studies.md.",
                       opts,
                       (int)(sizeof opts / sizeof opts[0]),
                       1,
                       positional};
    int rc = cli_parse(&cmd, argc, argv);
    if (rc) return rc == 1 ? 0 : rc;
    if (list) return list_studies(&cmd);
    name = positional[0];
    if (!name) return cli_error(&cmd, "a study NAME is required; see 'consph study --list'");
    char path[2048];
    size_t len = strlen(name);
    if (len > 6 && strcmp(name + len - 6, ".study") == 0) {
        snprintf(path, sizeof path, "%s", name);
    } else {
        const char *dir = studies_dir();
        if (!dir) return cli_error(&cmd, "no studies directory found (set CONSPH_STUDIES)");
        snprintf(path, sizeof path, "%s/%s.study", dir, name);
        FILE *probe = fopen(path, "r");
        if (!probe)
            return cli_error(&cmd, "unknown study '%s' (no %s); see 'consph study --list'", name,
                             path);
        fclose(probe);
    }
    consph_study *s;
    if (consph_study_load(path, &s) != CONSPH_OK) return cli_error(&cmd, "%s", consph_last_error());
    if (consph_study_validate(s, quick) != CONSPH_OK) {
        consph_study_free(s);
        return cli_error(&cmd, "%s", consph_last_error());
    }
    printf("study %s: %s (%s resolutions)\n", consph_study_name(s), consph_study_title(s),
           quick ? "quick" : "paper");
    if (!quick || estimate_only) {
        double est = consph_study_estimate(s, quick);
        printf("estimated run time: %.0f s (%.1f min; rough: neighbour pairs x measured cost per "
               "pair)\n",
               est, est / 60.0);
        fflush(stdout);
    }
    if (estimate_only) {
        consph_study_free(s);
        return 0;
    }
    consph_study_options o = {quick, out, stdout};
    double t0 = consph_wtime();
    rc = consph_study_run(s, &o);
    if (rc != CONSPH_OK) {
        fprintf(stderr, "consph study: %s\n", consph_last_error());
        consph_study_free(s);
        return rc == CONSPH_EFORMAT || rc == CONSPH_EINVAL ? 2 : 1;
    }
    printf("done in %.1f s: %s/%s/README.md\n", consph_wtime() - t0, out, consph_study_name(s));
    consph_study_free(s);
    return 0;
}
