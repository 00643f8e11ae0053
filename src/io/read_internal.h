/* Shared by the particle readers of src/io; not part of the public API.
 *
 * A reader streams its input through an rd_src (a file or a memory buffer read in chunks, so
 * both take the same code path), appends every value to growable columns (rd_set), and hands
 * the columns to consph_rd_finish, which applies the checks common to every format (dimension,
 * box, wrapping, duplicates, positive volumes) and builds the particle set. */
#ifndef CONSPH_IO_READ_INTERNAL_H
#define CONSPH_IO_READ_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "consph/io.h"

/* ---- byte source ---- */

typedef struct rd_src {
    const char *name; /* for messages */
    FILE *fp;         /* NULL for a memory source */
    const unsigned char *mem;
    size_t mem_len, mem_pos;
    unsigned char *buf; /* cap + 1 bytes: room for a terminating NUL after a line */
    size_t cap, len, pos;
    size_t chunk;     /* bytes requested per read */
    size_t size_hint; /* total input size when known (0: unknown) */
    int eof;
    int failed; /* an error was recorded with consph_fail */
} rd_src;

/* Bytes per read when consph_rd_chunk is 0. The fuzz targets set consph_rd_chunk to a few bytes
 * so that every value and line straddles refills. */
#define RD_DEFAULT_CHUNK ((size_t)1 << 16)
extern size_t consph_rd_chunk;

int consph_rd_open_file(rd_src *s, const char *path);
void consph_rd_open_mem(rd_src *s, const char *name, const void *data, size_t size);
void consph_rd_close(rd_src *s);
/* Makes at least `need` unread bytes available at buf + pos unless the input ends first.
 * Returns CONSPH_OK, or an error recorded with consph_fail (s->failed set). */
int consph_rd_fill(rd_src *s, size_t need);
int consph_rd_getc_slow(rd_src *s);
/* The next byte, -1 at the end of the input or on an error (then s->failed is set). */
static inline int rd_getc(rd_src *s)
{
    if (s->pos < s->len) return s->buf[s->pos++];
    return consph_rd_getc_slow(s);
}
static inline int rd_peek(rd_src *s)
{
    if (s->pos < s->len) return s->buf[s->pos];
    if (consph_rd_fill(s, 1) != 0 || s->pos == s->len) return -1;
    return s->buf[s->pos];
}
/* The next line without its '\n' (and '\r'), NUL-terminated and writable until the next call;
 * NULL at the end of the input or on an error (s->failed). *len excludes the NUL. */
char *consph_rd_line(rd_src *s, size_t *len);

/* ---- columns ---- */

typedef struct rd_column {
    double *v;
    size_t n, cap;
} rd_column;

int consph_rd_push(rd_column *c, double v);

#define RD_MAX_COMP 16

typedef struct rd_field {
    char name[CONSPH_FIELD_NAME_MAX];
    int ncomp;
    rd_column col[RD_MAX_COMP];
} rd_field;

/* Everything a reader gathered, in the file's particle order. */
typedef struct rd_set {
    const char *name;
    consph_particle_format format;
    int dim;              /* from the file's structure (CSV columns, VTU box); 0 when unknown */
    const char *dim_what; /* what fixed dim, for messages ("the header row", ...) */
    size_t dim_line;      /* and where */
    rd_column x[CONSPH_MAX_DIM]; /* VTU stores all three; finish checks the unused are zero */
    int nfields;
    rd_field fields[CONSPH_MAX_FIELDS];
    int have_box, box_dim;
    double lo[CONSPH_MAX_DIM], hi[CONSPH_MAX_DIM];
    int have_periodic, periodic_dim;
    int periodic[CONSPH_MAX_DIM];
    int have_spacing;
    double spacing;
    int have_time; /* VTU: a FieldData TimeValue */
    double time;
    int have_declared_n; /* CSV `# n`: checked against the rows read */
    size_t declared_n;
    char encoding[48];
    /* Location of particle i (field < 0: its position, else field `field`): "FILE:LINE: ..." */
    void (*where)(const struct rd_set *set, size_t i, int field, char *buf, size_t size);
    /* CSV: line of the first data row and the blank or comment lines skipped after it */
    size_t first_row_line;
    size_t *skipped;
    size_t nskipped, capskipped;
    /* VTU: line of the Points array and of each field's array */
    size_t points_line;
    size_t field_line[CONSPH_MAX_FIELDS];
} rd_set;

void consph_rd_set_free(rd_set *set);
/* The common checks, then moves the columns into `p`. Frees nothing of `set` it did not move;
 * the caller frees the set either way. */
int consph_rd_finish(rd_set *set, const consph_read_options *opt, consph_particles *p,
                     consph_read_report *rep);

/* Case-insensitive ASCII comparison (the C library's strcasecmp is POSIX, not C11). */
int consph_rd_streq_nocase(const char *a, const char *b);

/* ---- format readers (called with an open source) ---- */

int consph_rd_csv(rd_src *s, const consph_read_options *opt, rd_set *set);
int consph_rd_vtu(rd_src *s, const consph_read_options *opt, rd_set *set);

/* ---- zlib (RFC 1950) streams, through the system zlib ---- */

/* Inflates the zlib stream in[0..inlen) into *out (grown with realloc as needed, capacity in
 * *outcap), appending at most `maxout` bytes; *outlen receives the count. Returns 0, or a
 * negative code with a short reason in `why`. */
int consph_rd_inflate(const unsigned char *in, size_t inlen, unsigned char **out, size_t *outlen,
                      size_t *outcap, size_t maxout, const char **why);

#endif
