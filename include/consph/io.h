/* consph io: particle output as VTK XML unstructured grid (.vtu) and CSV, tables as CSV, and
 * the atomic-write discipline: every output goes to a temporary file in the target directory
 * and is renamed over the target only once complete, so no half-written file is ever left. */
#ifndef CONSPH_IO_H
#define CONSPH_IO_H

#include <stdio.h>

#include "consph/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* An output file being written: write to `fp`, then commit (rename into place) or abort. */
typedef struct consph_outfile {
    FILE *fp;
    char *path;
    char *tmp_path;
} consph_outfile;

int consph_outfile_open(consph_outfile *of, const char *path);
int consph_outfile_commit(consph_outfile *of);
void consph_outfile_abort(consph_outfile *of);

/* Checks that `path` could be created (its directory exists and is writable) without creating
 * anything; for validating options before long work. */
int consph_path_writable(const char *path);

typedef enum consph_particle_format { CONSPH_FORMAT_VTU, CONSPH_FORMAT_CSV } consph_particle_format;

/* Picks the format from the file extension (.vtu or .csv); CONSPH_EINVAL otherwise. */
int consph_particle_format_from_path(const char *path, consph_particle_format *fmt);

/* Writes positions and every field of `p`. CSV carries a comment header with the dimension, box
 * and periodicity, then a header row x,y[,z],<fields>. VTU is ASCII XML with one PointData
 * array per field and the box as FieldData. */
int consph_write_particles(const char *path, const consph_particles *p);

#ifdef __cplusplus
}
#endif
#endif
