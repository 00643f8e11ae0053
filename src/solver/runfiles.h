/* The files of a run, shared by every solver (the WCSPH run of run.c, the heat run of
 * src/heat/heat.c): paths in the output directory, snapshots indexed by run.pvd, the per-step
 * log and the JSON summary, each written to a temporary name and renamed when complete. */
#ifndef CONSPH_SOLVER_RUNFILES_H
#define CONSPH_SOLVER_RUNFILES_H

#include <stdio.h>

#include "consph/io.h"
#include "io/source_internal.h"

typedef struct runfiles {
    const char *dir;
    char *path; /* scratch for joined paths */
    size_t cap;
    consph_pvd pvd;
    int have_pvd;
} runfiles;

/* DIR/name in the scratch buffer (valid until the next call), NULL when out of memory. */
const char *runfiles_join(runfiles *f, const char *name);
/* A new index DIR/run.pvd. */
int runfiles_pvd_init(runfiles *f);
/* DIR/snap_NNNNNN.vtu with every field of p and the TimeValue t, added to the index at t. */
int runfiles_snapshot(runfiles *f, const consph_particles *p, long step, double t);
/* The same with the arrays of c (which must have a time), taken from src when not NULL
 * (io/source_internal.h). */
int runfiles_snapshot_content(runfiles *f, const consph_particles *p, const consph_vtu_content *c,
                              long step, const io_array_source *src);
/* DIR/name as a CSV: the header line, then nrows rows of ncols doubles, the first printed as
 * an integer (the step). */
int runfiles_csv(runfiles *f, const char *name, const char *header, const double *rows,
                 size_t nrows, int ncols);
/* DIR/name written by fn(fp, arg). */
int runfiles_text(runfiles *f, const char *name, void (*fn)(FILE *, const void *), const void *arg);
void runfiles_free(runfiles *f);
/* 1 when `name` is a file a run writes (or its temporary file), so one that a new run in the
 * same directory would mix with its own, and that overwriting may remove. */
int runfiles_is_run_file(const char *name);

/* This machine's physical memory in bytes (0 when unknown). */
double runfiles_machine_memory(void);
/* CONSPH_OK when nx^dim particles of bytes_each fit in `memory` bytes (0: unknown, always);
 * else CONSPH_EINVAL naming --nx, the estimate and the memory. */
int runfiles_memory_check(int nx, int dim, double bytes_each, double memory);

/* "  \"key\": value," (null when not finite; no comma when last). */
void runfiles_json_num(FILE *fp, const char *key, double v, int last);

#endif
