/* Writers that take a particle set's arrays one at a time (not part of the public API): the
 * solver decomposed over MPI ranks writes its snapshots and checkpoints on rank 0 from the
 * arrays gathered one after the other (src/par/par_solver.c, par_stream), never holding the
 * whole set. The files are the bytes the writers make from a set holding every array. */
#ifndef CONSPH_IO_SOURCE_INTERNAL_H
#define CONSPH_IO_SOURCE_INTERNAL_H

#include "consph/io.h"

/* Before the writer reads the values of the positions (field -1) or of p->fields[field], it
 * calls load(arg, field), which makes p->x[0..dim) or that field's data point at the values
 * (p->n particles, component c from c·p->cap). The arrays loaded before may be left dangling:
 * the writer reads each array once, in the file's order. load returns a CONSPH_* status (the
 * writer stops at the first failure, the file not written). */
typedef struct io_array_source {
    int (*load)(void *arg, int field);
    void *arg;
} io_array_source;

/* consph_write_vtu (.vtu only) with the arrays from src (NULL: p holds them all). */
int io_write_vtu_source(const char *path, const consph_particles *p, const consph_vtu_content *c,
                        consph_vtu_encoding enc, const io_array_source *src);

/* consph_checkpoint_write with the arrays from src (NULL: p holds them all). */
int io_checkpoint_write_source(const char *path, const char *meta, const consph_particles *p,
                               const io_array_source *src, const double *history, size_t nhistory);

#endif
