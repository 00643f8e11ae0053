/* The files every run writes (runfiles.h). */
#include "solver/runfiles.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The names of the files a run writes, the problems' extras included. */
static const char *const run_file_names[] = {
    "run.pvd",     "log.csv",       "summary.json",  "checkpoint.ckpt", "run.id",
    "profile.csv", "vorticity.png", "vorticity.dat", "vorticity.gp",
};

static int all_digits(const char *s, size_t len)
{
    if (len == 0) return 0;
    for (size_t k = 0; k < len; ++k)
        if (s[k] < '0' || s[k] > '9') return 0;
    return 1;
}

/* A run's own name: one of the list, or snap_DIGITS.vtu. */
static int run_name(const char *name, size_t len)
{
    for (size_t k = 0; k < sizeof run_file_names / sizeof run_file_names[0]; ++k)
        if (strlen(run_file_names[k]) == len && !strncmp(name, run_file_names[k], len)) return 1;
    return len > 9 && !strncmp(name, "snap_", 5) && !strncmp(name + len - 4, ".vtu", 4) &&
           all_digits(name + 5, len - 9);
}

int runfiles_is_run_file(const char *name)
{
    size_t len = strlen(name);
    if (run_name(name, len)) return 1;
    /* the temporary files of consph_outfile (NAME.tmp.PID) and of the vorticity image */
    const char *tmp = strstr(name, ".tmp");
    if (!tmp || !run_name(name, (size_t)(tmp - name))) return 0;
    return tmp[4] == '\0' || (tmp[4] == '.' && all_digits(tmp + 5, strlen(tmp + 5)));
}

const char *runfiles_join(runfiles *f, const char *name)
{
    size_t need = strlen(f->dir) + strlen(name) + 2;
    if (need > f->cap) {
        char *p = realloc(f->path, need);
        if (!p) return NULL;
        f->path = p;
        f->cap = need;
    }
    snprintf(f->path, f->cap, "%s/%s", f->dir, name);
    return f->path;
}

int runfiles_pvd_init(runfiles *f)
{
    const char *pvd = runfiles_join(f, "run.pvd");
    if (!pvd) return consph_fail(CONSPH_ENOMEM, "out of memory");
    int st = consph_pvd_init(&f->pvd, pvd);
    f->have_pvd = st == CONSPH_OK;
    return st;
}

int runfiles_snapshot(runfiles *f, const consph_particles *p, long step, double t)
{
    const consph_vtu_content c = {NULL, 0, 1, t};
    return runfiles_snapshot_content(f, p, &c, step, NULL);
}

int runfiles_snapshot_content(runfiles *f, const consph_particles *p, const consph_vtu_content *c,
                              long step, const io_array_source *src)
{
    char name[64];
    snprintf(name, sizeof name, "snap_%06ld.vtu", step);
    const char *path = runfiles_join(f, name);
    if (!path) return consph_fail(CONSPH_ENOMEM, "out of memory");
    int st = io_write_vtu_source(path, p, c, CONSPH_VTU_DEFAULT, src);
    if (st == CONSPH_OK) st = consph_pvd_add(&f->pvd, c->time, name);
    return st;
}

int runfiles_csv(runfiles *f, const char *name, const char *header, const double *rows,
                 size_t nrows, int ncols)
{
    const char *path = runfiles_join(f, name);
    if (!path) return consph_fail(CONSPH_ENOMEM, "out of memory");
    consph_outfile of;
    int st = consph_outfile_open(&of, path);
    if (st != CONSPH_OK) return st;
    fprintf(of.fp, "%s\n", header);
    for (size_t r = 0; r < nrows; ++r) {
        const double *row = rows + r * (size_t)ncols;
        fprintf(of.fp, "%.0f", row[0]);
        for (int c = 1; c < ncols; ++c) fprintf(of.fp, ",%.10e", row[c]);
        fputc('\n', of.fp);
    }
    return consph_outfile_commit(&of);
}

int runfiles_text(runfiles *f, const char *name, void (*fn)(FILE *, const void *), const void *arg)
{
    const char *path = runfiles_join(f, name);
    if (!path) return consph_fail(CONSPH_ENOMEM, "out of memory");
    consph_outfile of;
    int st = consph_outfile_open(&of, path);
    if (st != CONSPH_OK) return st;
    fn(of.fp, arg);
    return consph_outfile_commit(&of);
}

void runfiles_free(runfiles *f)
{
    if (f->have_pvd) consph_pvd_free(&f->pvd);
    f->have_pvd = 0;
    free(f->path);
    f->path = NULL;
    f->cap = 0;
}

void runfiles_json_num(FILE *fp, const char *key, double v, int last)
{
    if (isfinite(v))
        fprintf(fp, "  \"%s\": %.17g%s\n", key, v, last ? "" : ",");
    else
        fprintf(fp, "  \"%s\": null%s\n", key, last ? "" : ",");
}

double runfiles_machine_memory(void)
{
    const long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    return pages > 0 && size > 0 ? (double)pages * (double)size : 0.0;
}

int runfiles_memory_check(int nx, int dim, double bytes_each, double memory)
{
    const double n = pow((double)nx, dim), need = n * bytes_each;
    if (memory > 0.0 && need > memory)
        return consph_fail(CONSPH_EINVAL,
                           "--nx %d: %.4g particles%s need about %.3g GiB (%.0f bytes each), more "
                           "than this machine's memory (%.3g GiB)",
                           nx, n, dim == 3 ? " (nx^3)" : "", need / 1073741824.0, bytes_each,
                           memory / 1073741824.0);
    return CONSPH_OK;
}
