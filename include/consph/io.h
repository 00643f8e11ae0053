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

/* A buffered FILE on the descriptor `fd` that keeps in `err` the errno of its first failed write
 * or seek. glibc's own FILE discards the buffer of a failed write and lets later flushes succeed,
 * so by the time a caller checks ferror() the reason (a full disk, a closed pipe) is gone.
 * fclose leaves `fd` open. The struct must stay in place while its FILE is open. */
typedef struct consph_fdstream {
    int fd;
    int err;
} consph_fdstream;

/* The FILE (mode as fopen's, "w" or "wb"), or NULL with errno set. */
FILE *consph_fdstream_open(consph_fdstream *s, const char *mode);

/* An output file being written: write to `fp`, then commit (fsync, rename into place) or abort.
 * While one is open, SIGINT, SIGTERM and SIGHUP, where their action is still the default, remove
 * its temporary file before ending the process as they would have. A failed write makes commit
 * fail with a message naming the file and the reason. The struct must not be moved while open
 * (`fp` writes through `stream`). */
typedef struct consph_outfile {
    FILE *fp;
    char *path;
    char *tmp_path;
    consph_fdstream stream;
} consph_outfile;

int consph_outfile_open(consph_outfile *of, const char *path);
int consph_outfile_commit(consph_outfile *of);
void consph_outfile_abort(consph_outfile *of);
/* Sets the message "cannot write 'PATH': REASON" for a write into `of` that failed with errno
 * `err` (0: the reason its stream recorded) and returns CONSPH_EIO; for writers that detect the
 * failure before commit. Call before consph_outfile_abort, which forgets the path. */
int consph_outfile_fail(const consph_outfile *of, int err);

/* Checks that `path` could be created (its directory exists and is writable) without creating
 * anything; for validating options before long work. */
int consph_path_writable(const char *path);

typedef enum consph_particle_format { CONSPH_FORMAT_VTU, CONSPH_FORMAT_CSV } consph_particle_format;

/* Picks the format from the file extension (.vtu or .csv); CONSPH_EINVAL otherwise. */
int consph_particle_format_from_path(const char *path, consph_particle_format *fmt);

/* How a .vtu file stores its arrays. Every encoding reads back to the same bits. */
typedef enum consph_vtu_encoding {
    CONSPH_VTU_ASCII,  /* XML text (%.17g): readable; on 2000^2 particles 1.6 times the binary
                        * size and 4 to 50 times slower to write (bench_io 2000 all 2) */
    CONSPH_VTU_BINARY, /* raw bytes in an AppendedData element */
    CONSPH_VTU_ZLIB    /* raw bytes in zlib-compressed blocks (vtkZLibDataCompressor) */
} consph_vtu_encoding;
#define CONSPH_VTU_DEFAULT CONSPH_VTU_ZLIB

/* "ascii,binary,zlib": the encodings' names in enum order, for option parsers. */
const char *consph_vtu_encoding_names(void);
const char *consph_vtu_encoding_name(consph_vtu_encoding enc);

/* Writes positions and every field of `p`. CSV carries a comment header with the dimension, box
 * and periodicity, then a header row x,y[,z],<fields>. VTU is VTK XML (UnstructuredGrid, one
 * vertex cell per particle) with one PointData array per field and the box, periodicity and
 * spacing as ASCII FieldData; its arrays are in CONSPH_VTU_DEFAULT encoding. */
int consph_write_particles(const char *path, const consph_particles *p);
/* The same with the VTU encoding chosen (ignored for CSV). */
int consph_write_particles_enc(const char *path, const consph_particles *p,
                               consph_vtu_encoding enc);

/* What a .vtu holds beyond the positions, for a snapshot that a ParaView user reads: chosen
 * fields under names of their own, each written as the VTK kind of its values, and the time. */
typedef enum consph_array_kind {
    CONSPH_ARRAY_SCALAR, /* 1 component */
    CONSPH_ARRAY_VECTOR, /* dim components, written as 3 (z = 0 in 2D) */
    CONSPH_ARRAY_TENSOR  /* dim × dim, row-major (component a·dim + b is T_ab), written as 3 × 3
                          * with the rows and columns beyond dim zero */
} consph_array_kind;

typedef struct consph_vtu_array {
    const char *name;  /* the PointData array's name: letters, digits, '_', '-', '.' */
    const char *field; /* the field of the particle set it holds */
    consph_array_kind kind;
} consph_vtu_array;

typedef struct consph_vtu_content {
    const consph_vtu_array *arrays; /* NULL: every field under its own name */
    int narrays;
    int has_time; /* a FieldData array TimeValue holding `time` (how VTK's readers and
                   * ParaView see the time of a single file) */
    double time;
} consph_vtu_content;

/* A .vtu of `p` with the arrays and time of `c`, in encoding enc. A field missing from p, one
 * whose components do not match its kind (1, dim or dim²), a name not allowed or given twice is
 * CONSPH_EINVAL naming the array; `path` must end in .vtu. */
int consph_write_vtu(const char *path, const consph_particles *p, const consph_vtu_content *c,
                     consph_vtu_encoding enc);

/* ---- Reading particle files -------------------------------------------------------------- */

/* What the caller knows before reading. Zero-initialise, then set what is known; a known value
 * overrides (box, periodicity) or is checked against (dim) what the file says. */
typedef struct consph_read_options {
    int dim;           /* expected dimension 1..3; 0: the file's own */
    int have_box;      /* 1: use box.lo/box.hi instead of the file's box */
    consph_box box;    /* box.dim axes; its periodic flags are ignored (see have_periodic) */
    int have_periodic; /* 1: use periodic[] instead of the file's periodicity */
    int periodic[CONSPH_MAX_DIM];
} consph_read_options;

/* Where the "volume" field of read particles came from. */
typedef enum consph_volume_origin {
    CONSPH_VOLUMES_NONE,    /* the file has no volumes: the caller picks a rule */
    CONSPH_VOLUMES_COLUMN,  /* a `volume` column (CSV) or PointData array (VTU) */
    CONSPH_VOLUMES_MASS_RHO /* volume = m / rho from `m` and `rho` columns */
} consph_volume_origin;

/* What a read found, for the caller to report. */
typedef struct consph_read_report {
    consph_particle_format format;
    char encoding[48];      /* VTU: "ascii", "binary", "appended raw", ... (+ ", zlib"); CSV: "" */
    int box_from_file;      /* the box came from the file (else from the options) */
    int periodic_from_file; /* periodicity from the file (else options, or none) */
    int spacing_from_file;  /* p->spacing from the file (else (box volume / N)^(1/dim)) */
    size_t wrapped;         /* particles moved into the box along periodic axes */
    consph_volume_origin volumes;
    int has_mass; /* a "mass" field from an `m` (or `mass`) column */
    int has_time; /* VTU: a FieldData array TimeValue, whose value is `time` */
    double time;
    /* the box and periodicity the file itself states, also where the options replaced them
     * (for a caller that checks them against its own): file_box.lo/hi when file_has_box,
     * file_box.periodic when file_has_periodic */
    int file_has_box, file_has_periodic;
    consph_box file_box;
} consph_read_report;

/* Reads a particle file into `p` (initialised here), streaming it: memory is O(N). The format is
 * chosen by the extension (.csv or .vtu) and checked against the content.
 *
 * CSV: optional '#' comment lines first (consph writes `# dim D`, `# n N`, `# spacing S`,
 * `# box lo:hi lo:hi ...`, `# periodic 0|1 ...`; each is read when present), then a header row
 * naming the columns: x,y[,z] are required (their number is the dimension); `volume`, `m` (or
 * `mass`) and `rho` are used when present; other columns are kept as fields (a run name_0,
 * name_1, ... becomes one field with that many components). Then one row per particle.
 * VTU: VTK XML UnstructuredGrid, one Piece, with data arrays in ascii, binary (base64) or
 * appended (raw or base64) form, header_type UInt32 or UInt64, either byte order, uncompressed
 * or vtkZLibDataCompressor; FieldData arrays `box`, `periodic`, `spacing` and `TimeValue` as
 * consph writes them are read when present; PointData arrays become fields as CSV columns do.
 *
 * Then, for both: the dimension must match opt->dim when given; the box comes from the options
 * or the file (CONSPH_EINVAL when neither has one); a particle outside the box on a non-periodic
 * axis is an error, on a periodic axis it is wrapped (counted in rep->wrapped); two particles at
 * the same position are an error naming both; volume, m and rho must be positive; spacing
 * defaults to (V/N)^(1/dim). The result carries the field "volume" when the file has volumes
 * (a column, or m/rho) and "mass" when it has masses.
 *
 * Every rejection is one message naming the file and the line (VTU: the line of the element)
 * and the problem: CONSPH_EIO (cannot open or read), CONSPH_EFORMAT (content),
 * CONSPH_EINVAL (the content disagrees with the options, or no box), CONSPH_ENOMEM.
 * `rep` may be NULL. */
int consph_read_particles(const char *path, const consph_read_options *opt, consph_particles *p,
                          consph_read_report *rep);

/* The same from a buffer in memory; `name` is used in messages. */
int consph_read_particles_mem(const char *name, consph_particle_format fmt, const void *data,
                              size_t size, const consph_read_options *opt, consph_particles *p,
                              consph_read_report *rep);

/* "file column 'volume'", "m/rho columns" or "none": for reports. */
const char *consph_volume_origin_name(consph_volume_origin origin);

/* ---- key = value texts (study files, run parameter files) --------------------------------- */

/* Called for each line that is not blank or a comment: a section header `[...]` as key (the line,
 * trimmed) with value NULL, else the key and the value of `key = value`, both trimmed (the value
 * may be empty), writable until the next call. A status other than CONSPH_OK stops the
 * reading and is returned. */
typedef int (*consph_kv_fn)(void *ctx, int line, char *key, char *value);
/* Reads `size` bytes of text line by line: a '#' starts a comment that runs to the end of the
 * line. CONSPH_EFORMAT "PATH:LINE: ..." for a NUL byte, a line longer than line_max characters,
 * a control character other than tab, or a line that is neither a section header nor has an
 * '='. */
int consph_kv_parse(const char *path, const char *data, size_t size, size_t line_max,
                    consph_kv_fn each, void *ctx);

/* ---- Runs: checkpoints, ParaView time series, stop requests, progress ---------------------- */

/* A checkpoint holds everything a run needs to continue bit for bit: a text block of the run's
 * own metadata (key=value lines, written and parsed by the solver), a particle set (positions,
 * box, periodicity, spacing and every named field, in the stored order, as raw IEEE doubles)
 * and an array of doubles (the run's history). It is one zlib-compressed file with a magic,
 * a version and a CRC-32 of the content, written atomically (consph_outfile); the format is in
 * docs/solver-files.md. `meta` may be NULL (empty); `history` may be NULL when nhistory is 0. */
int consph_checkpoint_write(const char *path, const char *meta, const consph_particles *p,
                            const double *history, size_t nhistory);
/* Reads a checkpoint written by consph_checkpoint_write: *meta (NUL-terminated) and *history
 * are malloc'd (free them; *history is NULL when nhistory is 0), p is initialised here. A file
 * that is not a checkpoint, is truncated, fails its CRC or holds inconsistent sizes is
 * CONSPH_EFORMAT with a message naming the file and what is wrong; nothing is returned then.
 * Sizes in the file are checked against its length before any allocation. */
int consph_checkpoint_read(const char *path, char **meta, consph_particles *p, double **history,
                           size_t *nhistory);
/* The same for one of `parts` parts of the particles: those [N part / parts, N (part + 1) /
 * parts) of the stored N, in the stored order (*first, the first one's index; *total, N), every
 * field; meta and history whole. The payload is inflated as a stream (its CRC checked over the
 * whole of it), so memory is that of the part: an MPI rank's share of a restart
 * (consph_par_run_restart). */
int consph_checkpoint_read_part(const char *path, int part, int parts, char **meta,
                                consph_particles *p, double **history, size_t *nhistory,
                                size_t *first, size_t *total);

/* A ParaView .pvd index of snapshot files, rewritten atomically after each added entry so it
 * is always complete. Entry file names are written relative to the index's directory. */
typedef struct consph_pvd {
    char *path;
    size_t n, cap;
    double *time;
    char **file;
} consph_pvd;
/* Only records the path: nothing is written until the first add or truncate. */
int consph_pvd_init(consph_pvd *pvd, const char *path);
/* Adds (time, file) and rewrites the index. `file` must be a plain name in the index's directory
 * (no '/', '\\', quotes, '&', '<', '>' or control characters) and `time` finite and not before
 * the last entry's; a file already listed is CONSPH_EINVAL unless it is the last entry with the
 * same time (then the index is only rewritten). On failure the index is unchanged. */
int consph_pvd_add(consph_pvd *pvd, double time, const char *file);
/* Drops the entries with time > t (a restarted run rewrites what follows its checkpoint). */
int consph_pvd_truncate(consph_pvd *pvd, double t);
/* Loads an existing index written by consph_pvd_add (for a restarted run); pvd is initialised
 * here. Anything but the exact lines consph_pvd_add writes is CONSPH_EFORMAT (file and line). */
int consph_pvd_load(consph_pvd *pvd, const char *path);
void consph_pvd_free(consph_pvd *pvd);

/* Stop requests: installs handlers for SIGINT and SIGTERM that only record the signal, so a run
 * can finish its step, write a checkpoint and exit 128 + signal. A second signal of the same kind
 * ends the process at once (removing temporary files as consph_outfile does). Installing again
 * while installed only forgets the signals received. */
int consph_stop_install(void);
/* The signal received since consph_stop_install (0: none). */
int consph_stop_requested(void);
/* Restores the previous handlers. */
void consph_stop_uninstall(void);

/* A one-line progress display on stderr, `step N  t=T  R steps/s  ETA mm:ss`, redrawn with a
 * carriage return at most 4 times a second, and only when stderr is a terminal (nothing
 * otherwise, so logs and pipes stay clean). Fields are the display's own state. */
typedef struct consph_progress {
    int enabled;
    double t0, last; /* wall clock at start and at the last redraw */
    long step0;
    int have_first; /* the first update's step, simulated time and wall clock, for the ETA */
    long step_first;
    double t_first, wall_first;
} consph_progress;
void consph_progress_start(consph_progress *pr, long step0);
/* steps_end > 0: the run ends at that step (ETA from the step rate); else t_end > 0: it ends at
 * simulated time t_end (ETA from the rate of t since the first update); else no ETA. */
void consph_progress_update(consph_progress *pr, long step, double t, long steps_end, double t_end);
/* Clears the line. */
void consph_progress_end(consph_progress *pr);
/* Text every progress line starts with until changed (NULL or "": none), e.g. the study row a
 * run belongs to; copied (at most 255 bytes). */
void consph_progress_prefix(const char *text);

#ifdef __cplusplus
}
#endif
#endif
