/* Checkpoints of a run: one file that gives back, bit for bit, the metadata text, the particle
 * set and the history array a run needs to continue as if never interrupted.
 *
 * File layout (every integer an unsigned little-endian value; docs/solver-files.md):
 *
 *   offset  size  content
 *        0     8  magic "CONSPHCK"
 *        8     4  format version (1)
 *       12     4  CRC-32 (zlib's crc32, ISO-HDLC) of the uncompressed payload
 *       16     8  uncompressed payload size U
 *       24     8  compressed size C; the file is exactly 32 + C bytes
 *       32     C  the payload as one zlib (RFC 1950) stream
 *
 * Payload, all integers u64, all reals IEEE-754 binary64, both little-endian:
 *   meta length, meta bytes (no NUL)
 *   dim, n, then per axis lo, hi, periodic (0 or 1), then spacing
 *   nfields, then per field: name length, name bytes, ncomp
 *   positions: x[0][0..n), ..., x[dim-1][0..n)
 *   fields in stored order, each component-major: comp 0 of particles 0..n, comp 1, ...
 *   nhistory, history[0..nhistory)
 * and nothing after.
 *
 * Doubles travel as their 64-bit patterns (never through a floating-point register), so NaN
 * payloads and -0.0 come back as written. A reader trusts no size: each one is checked against
 * the bytes that remain in the payload before anything is allocated, and the payload itself is
 * inflated in growing steps, so a file that claims a huge size cannot make the reader allocate
 * more than its content really expands to. */
#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "consph/io.h"
#include "io/read_internal.h"
#include "io/source_internal.h"

#define CK_MAGIC "CONSPHCK"
#define CK_VERSION 1u
#define CK_HEADER 32
/* Payload bytes gathered before each deflate call: large enough that zlib's per-call cost is
 * nothing, small enough that the writer never holds a copy of the particle set. */
#define CK_CHUNK ((size_t)1 << 16)
/* The most a zlib stream can expand: 1032:1 for deflate (zlib's technical notes), plus room for
 * the stream's own header. A claimed size beyond this cannot be the file's content. */
#define CK_MAX_RATIO 1032u

static void put_u32(unsigned char *b, uint32_t v)
{
    for (int k = 0; k < 4; ++k) b[k] = (unsigned char)(v >> (8 * k));
}

static void put_u64(unsigned char *b, uint64_t v)
{
    for (int k = 0; k < 8; ++k) b[k] = (unsigned char)(v >> (8 * k));
}

static uint32_t get_u32(const unsigned char *b)
{
    uint32_t v = 0;
    for (int k = 3; k >= 0; --k) v = (v << 8) | b[k];
    return v;
}

static uint64_t get_u64(const unsigned char *b)
{
    uint64_t v = 0;
    for (int k = 7; k >= 0; --k) v = (v << 8) | b[k];
    return v;
}

/* ---- writing: the payload is built in chunks, each deflated and checksummed as it fills ---- */

typedef struct ck_writer {
    FILE *fp;
    z_stream z;
    unsigned char in[CK_CHUNK];
    unsigned char out[CK_CHUNK];
    size_t fill;
    uint64_t usize, csize;
    uint32_t crc;
    int failed;
    int load_st; /* the status of a source's load that failed (its message recorded) */
} ck_writer;

static void ck_deflate(ck_writer *w, int flush)
{
    w->crc = (uint32_t)crc32(w->crc, w->in, (uInt)w->fill);
    w->usize += w->fill;
    w->z.next_in = w->in;
    w->z.avail_in = (uInt)w->fill;
    int rc;
    do {
        w->z.next_out = w->out;
        w->z.avail_out = (uInt)sizeof w->out;
        rc = deflate(&w->z, flush);
        size_t got = sizeof w->out - w->z.avail_out;
        if (rc == Z_STREAM_ERROR || (got && fwrite(w->out, 1, got, w->fp) != got)) {
            w->failed = 1;
            return;
        }
        w->csize += got;
    } while (w->z.avail_out == 0 || (flush == Z_FINISH && rc != Z_STREAM_END));
    w->fill = 0;
}

static void ck_put(ck_writer *w, const void *data, size_t len)
{
    const unsigned char *b = data;
    while (len && !w->failed) {
        size_t take = CK_CHUNK - w->fill < len ? CK_CHUNK - w->fill : len;
        memcpy(w->in + w->fill, b, take);
        w->fill += take;
        b += take;
        len -= take;
        if (w->fill == CK_CHUNK) ck_deflate(w, Z_NO_FLUSH);
    }
}

static void ck_put_u64(ck_writer *w, uint64_t v)
{
    unsigned char b[8];
    put_u64(b, v);
    ck_put(w, b, 8);
}

static void ck_put_f64(ck_writer *w, double v)
{
    uint64_t bits;
    memcpy(&bits, &v, 8);
    ck_put_u64(w, bits);
}

static void ck_put_doubles(ck_writer *w, const double *v, size_t n)
{
    for (size_t i = 0; i < n && !w->failed; ++i) ck_put_f64(w, v[i]);
}

static int check_particles(const char *path, const consph_particles *p)
{
    if (p->dim < 1 || p->dim > CONSPH_MAX_DIM)
        return consph_fail(CONSPH_EINVAL, "checkpoint '%s': dimension %d is not 1, 2 or 3", path,
                           p->dim);
    if (p->n > p->cap)
        return consph_fail(CONSPH_EINVAL, "checkpoint '%s': %zu particles but room for %zu", path,
                           p->n, p->cap);
    if (p->nfields < 0 || p->nfields > CONSPH_MAX_FIELDS)
        return consph_fail(CONSPH_EINVAL, "checkpoint '%s': %d fields (at most %d)", path,
                           p->nfields, CONSPH_MAX_FIELDS);
    for (int f = 0; f < p->nfields; ++f) {
        const consph_field *fl = &p->fields[f];
        if (fl->ncomp < 1 || !memchr(fl->name, '\0', sizeof fl->name) || !fl->name[0])
            return consph_fail(CONSPH_EINVAL, "checkpoint '%s': field %d has no name or ncomp %d",
                               path, f, fl->ncomp);
    }
    return CONSPH_OK;
}

int consph_checkpoint_write(const char *path, const char *meta, const consph_particles *p,
                            const double *history, size_t nhistory)
{
    return io_checkpoint_write_source(path, meta, p, NULL, history, nhistory);
}

/* An array's values from the source, when the caller hands them one array at a time: the
 * payload is one deflate stream fed in order, so a column never needs the ones after it. */
static void ck_load(ck_writer *w, const io_array_source *src, int field)
{
    if (!src || w->failed) return;
    const int rc = src->load(src->arg, field);
    if (rc) {
        w->failed = 1;
        w->load_st = rc;
    }
}

int io_checkpoint_write_source(const char *path, const char *meta, const consph_particles *p,
                               const io_array_source *src, const double *history, size_t nhistory)
{
    if (!meta) meta = "";
    if (nhistory && !history)
        return consph_fail(CONSPH_EINVAL, "checkpoint '%s': %zu history values but no array", path,
                           nhistory);
    int rc = check_particles(path, p);
    if (rc) return rc;
    ck_writer *w = calloc(1, sizeof *w);
    if (!w) return consph_fail(CONSPH_ENOMEM, "out of memory");
    if (deflateInit(&w->z, Z_BEST_SPEED) != Z_OK) {
        free(w);
        return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    consph_outfile of;
    rc = consph_outfile_open(&of, path);
    if (rc) {
        deflateEnd(&w->z);
        free(w);
        return rc;
    }
    w->fp = of.fp;
    w->crc = (uint32_t)crc32(0L, Z_NULL, 0);
    unsigned char head[CK_HEADER] = {0};
    if (fwrite(head, 1, sizeof head, w->fp) != sizeof head) w->failed = 1;

    size_t mlen = strlen(meta);
    ck_put_u64(w, mlen);
    ck_put(w, meta, mlen);
    ck_put_u64(w, (uint64_t)p->dim);
    ck_put_u64(w, (uint64_t)p->n);
    for (int a = 0; a < p->dim; ++a) {
        ck_put_f64(w, p->box.lo[a]);
        ck_put_f64(w, p->box.hi[a]);
        ck_put_u64(w, p->box.periodic[a] ? 1 : 0);
    }
    ck_put_f64(w, p->spacing);
    ck_put_u64(w, (uint64_t)p->nfields);
    for (int f = 0; f < p->nfields; ++f) {
        size_t nlen = strlen(p->fields[f].name);
        ck_put_u64(w, nlen);
        ck_put(w, p->fields[f].name, nlen);
        ck_put_u64(w, (uint64_t)p->fields[f].ncomp);
    }
    ck_load(w, src, -1);
    for (int a = 0; a < p->dim; ++a) ck_put_doubles(w, p->x[a], p->n);
    /* after a failed load or write the view's arrays may be NULL: no offset from them */
    for (int f = 0; f < p->nfields && !w->failed; ++f) {
        ck_load(w, src, f);
        for (int c = 0; c < p->fields[f].ncomp && !w->failed; ++c)
            ck_put_doubles(w, p->fields[f].data + (size_t)c * p->cap, p->n);
    }
    ck_put_u64(w, nhistory);
    ck_put_doubles(w, history, nhistory);
    if (!w->failed) ck_deflate(w, Z_FINISH);
    deflateEnd(&w->z);

    /* The reader inflates through consph_rd_inflate, which takes at most 4 GiB of input: a
     * larger checkpoint could be written but never read, so it is refused now. */
    if (!w->failed && w->csize > UINT_MAX) {
        consph_outfile_abort(&of);
        rc = consph_fail(CONSPH_EINVAL, "checkpoint '%s': compressed size %llu exceeds 4 GiB", path,
                         (unsigned long long)w->csize);
        free(w);
        return rc;
    }
    memcpy(head, CK_MAGIC, 8);
    put_u32(head + 8, CK_VERSION);
    put_u32(head + 12, w->crc);
    put_u64(head + 16, w->usize);
    put_u64(head + 24, w->csize);
    if (!w->failed &&
        (fseek(w->fp, 0, SEEK_SET) != 0 || fwrite(head, 1, sizeof head, w->fp) != sizeof head))
        w->failed = 1;
    int failed = w->failed, load_st = w->load_st;
    free(w);
    if (failed) {
        /* Without a failed write, deflate or the rewind to the header failed. */
        rc = load_st ? load_st
             : ferror(of.fp)
                 ? consph_outfile_fail(&of, 0)
                 : consph_fail(CONSPH_EIO, "checkpoint '%s': compression or seek failed", path);
        consph_outfile_abort(&of);
        return rc;
    }
    return consph_outfile_commit(&of);
}

/* ---- reading ---- */

/* the file whose errors are named */
typedef struct ck_reader {
    const char *path;
} ck_reader;

static int bad(const ck_reader *r, const char *what)
{
    return consph_fail(CONSPH_EFORMAT, "checkpoint '%s': %s", r->path, what);
}

/* The payload's parse, over the whole payload in memory or inflated as a stream from the file;
 * a part keeps only a range of each column. */

typedef struct ck_stream {
    const char *path;
    FILE *fp;
    z_stream z;
    int zinit, zend;
    unsigned char in[CK_CHUNK];
    unsigned char skip[CK_CHUNK];
    uint64_t usize, consumed; /* the payload's size, the bytes handed out so far */
    uLong crc;
    int err; /* the first error of the parse (its status; the message recorded) */
    /* the whole payload already inflated and checked (consph_checkpoint_read), or NULL: the
     * stream is inflated from fp as it is taken */
    const unsigned char *mem;
} ck_stream;

static int cs_bad(ck_stream *s, const char *what)
{
    if (!s->err) s->err = consph_fail(CONSPH_EFORMAT, "checkpoint '%s': %s", s->path, what);
    return s->err;
}

static uint64_t cs_left(const ck_stream *s)
{
    return s->usize - s->consumed;
}

/* The next len bytes of the payload into dst (NULL: dropped), the CRC over them; a payload that
 * ends first is an error naming `what` (where: "before" or "inside"). */
static int cs_take(ck_stream *s, void *dst, size_t len, const char *where, const char *what)
{
    char msg[160];
    if (len > cs_left(s)) {
        snprintf(msg, sizeof msg, "payload ends %s the %s", where, what);
        return cs_bad(s, msg);
    }
    unsigned char *out = dst;
    if (s->mem) {
        if (out) memcpy(out, s->mem + s->consumed, len);
        s->consumed += len;
        return CONSPH_OK;
    }
    while (len > 0) {
        const size_t want = len < CK_CHUNK ? len : CK_CHUNK;
        unsigned char *to = out ? out : s->skip;
        s->z.next_out = to;
        s->z.avail_out = (uInt)want;
        while (s->z.avail_out > 0) {
            if (s->z.avail_in == 0 && !feof(s->fp)) {
                s->z.next_in = s->in;
                s->z.avail_in = (uInt)fread(s->in, 1, CK_CHUNK, s->fp);
            }
            const int zr = inflate(&s->z, Z_NO_FLUSH);
            if (zr == Z_STREAM_END) {
                s->zend = 1;
                break;
            }
            if (zr != Z_OK && !(zr == Z_BUF_ERROR && s->z.avail_in == 0 && !feof(s->fp)))
                return cs_bad(s, zr == Z_BUF_ERROR ? "payload shorter than the header says"
                                                   : "corrupt compressed payload");
        }
        const size_t got = want - s->z.avail_out;
        s->crc = crc32(s->crc, to, (uInt)got);
        s->consumed += got;
        if (got < want) return cs_bad(s, "payload shorter than the header says");
        if (out) out += got;
        len -= got;
    }
    return CONSPH_OK;
}

/* Whether the stream ends here, the payload's bytes all handed out. */
static int cs_end(ck_stream *s)
{
    unsigned char one;
    while (!s->zend) {
        if (s->z.avail_in == 0 && !feof(s->fp)) {
            s->z.next_in = s->in;
            s->z.avail_in = (uInt)fread(s->in, 1, CK_CHUNK, s->fp);
        }
        s->z.next_out = &one;
        s->z.avail_out = 1;
        const int zr = inflate(&s->z, Z_NO_FLUSH);
        if (s->z.avail_out == 0) return 0; /* a byte beyond the payload */
        if (zr == Z_STREAM_END)
            s->zend = 1;
        else if (zr != Z_OK && !(zr == Z_BUF_ERROR && s->z.avail_in == 0 && !feof(s->fp)))
            return 0;
    }
    return 1;
}

static int cs_u64(ck_stream *s, uint64_t *v, const char *what)
{
    unsigned char b[8];
    *v = 0;
    int rc = cs_take(s, b, 8, "before", what);
    if (!rc) *v = get_u64(b);
    return rc;
}

/* `count` doubles into v (NULL: dropped), as their bit patterns. */
static int cs_doubles(ck_stream *s, double *v, size_t count, const char *what)
{
    if (cs_left(s) / 8 < count) {
        char msg[128];
        snprintf(msg, sizeof msg, "payload ends inside the %s", what);
        return cs_bad(s, msg);
    }
    int rc = cs_take(s, v, 8 * count, "inside", what);
    for (size_t i = 0; v && !rc && i < count; ++i) {
        const uint64_t bits = get_u64((const unsigned char *)&v[i]);
        memcpy(&v[i], &bits, 8);
    }
    return rc;
}

/* The payload after the header: as parse_payload, keeping particles [first, first + count) of
 * the stored n; *total is n. */
static int cs_payload(ck_stream *s, int part, int parts, char **meta, consph_particles *p,
                      double **history, size_t *nhistory, size_t *first, size_t *total)
{
    uint64_t len;
    int rc = cs_u64(s, &len, "metadata");
    char msg[160];
    if (!rc && len > cs_left(s)) {
        snprintf(msg, sizeof msg, "metadata length %llu exceeds the payload",
                 (unsigned long long)len);
        rc = cs_bad(s, msg);
    }
    if (!rc && !(*meta = malloc((size_t)len + 1))) rc = consph_fail(CONSPH_ENOMEM, "out of memory");
    if (!rc) rc = cs_take(s, *meta, (size_t)len, "inside", "metadata");
    if (rc) return rc;
    (*meta)[len] = '\0';
    if (memchr(*meta, '\0', (size_t)len)) return cs_bad(s, "metadata holds a NUL byte");
    uint64_t dim, n, nfields, periodic[CONSPH_MAX_DIM];
    consph_box box;
    memset(&box, 0, sizeof box);
    double spacing;
    if ((rc = cs_u64(s, &dim, "dimension"))) return rc;
    if (dim < 1 || dim > CONSPH_MAX_DIM) return cs_bad(s, "dimension is not 1, 2 or 3");
    box.dim = (int)dim;
    if ((rc = cs_u64(s, &n, "particle count"))) return rc;
    for (int a = 0; a < box.dim; ++a) {
        uint64_t lo, hi;
        if ((rc = cs_u64(s, &lo, "box")) || (rc = cs_u64(s, &hi, "box")) ||
            (rc = cs_u64(s, &periodic[a], "box")))
            return rc;
        memcpy(&box.lo[a], &lo, 8);
        memcpy(&box.hi[a], &hi, 8);
        if (periodic[a] > 1) return cs_bad(s, "periodicity flag is not 0 or 1");
        box.periodic[a] = (int)periodic[a];
    }
    if (consph_box_check(&box)) return cs_bad(s, "invalid box");
    uint64_t sb;
    if ((rc = cs_u64(s, &sb, "spacing"))) return rc;
    memcpy(&spacing, &sb, 8);
    if ((rc = cs_u64(s, &nfields, "field count"))) return rc;
    if (nfields > CONSPH_MAX_FIELDS) return cs_bad(s, "more fields than consph allows");
    char names[CONSPH_MAX_FIELDS][CONSPH_FIELD_NAME_MAX];
    int ncomp[CONSPH_MAX_FIELDS];
    uint64_t columns = dim;
    for (uint64_t f = 0; f < nfields; ++f) {
        uint64_t nl;
        if ((rc = cs_u64(s, &nl, "field name"))) return rc;
        if (nl > CONSPH_FIELD_NAME_MAX - 1 || nl > cs_left(s)) {
            snprintf(msg, sizeof msg, "field name length %llu exceeds %s", (unsigned long long)nl,
                     nl > cs_left(s) ? "the payload" : "its limit");
            return cs_bad(s, msg);
        }
        if ((rc = cs_take(s, names[f], (size_t)nl, "inside", "field name"))) return rc;
        names[f][nl] = '\0';
        if (memchr(names[f], '\0', (size_t)nl)) return cs_bad(s, "field name holds a NUL byte");
        if (!names[f][0]) return cs_bad(s, "empty field name");
        for (uint64_t g = 0; g < f; ++g)
            if (strcmp(names[g], names[f]) == 0) return cs_bad(s, "two fields of the same name");
        uint64_t nc;
        if ((rc = cs_u64(s, &nc, "field components"))) return rc;
        if (nc < 1 || nc > INT_MAX || nc > cs_left(s))
            return cs_bad(s, "impossible field component count");
        ncomp[f] = (int)nc;
        columns += nc;
    }
    if (cs_left(s) < 8 || n > (cs_left(s) - 8) / 8 / columns)
        return cs_bad(s, "particle count larger than the payload holds");
    const size_t lo = (size_t)(n * (uint64_t)part / (uint64_t)parts),
                 hi = (size_t)(n * (uint64_t)(part + 1) / (uint64_t)parts), m = hi - lo;
    *first = lo;
    *total = (size_t)n;
    if ((rc = consph_particles_init(p, box.dim, m, &box))) return rc;
    p->spacing = spacing;
    /* every column: the particles before the range dropped, the range kept, the rest dropped */
    for (uint64_t c = 0; c < columns && !rc; ++c) {
        double *d = NULL;
        if (c < dim) {
            d = p->x[c];
        } else {
            uint64_t f = 0, k = c - dim;
            while (k >= (uint64_t)ncomp[f]) k -= (uint64_t)ncomp[f++];
            d = k == 0 ? consph_particles_field(p, names[f], ncomp[f])
                       : consph_particles_find(p, names[f])->data;
            if (!d) return CONSPH_ENOMEM;
            d += (size_t)k * p->cap;
        }
        const char *what = c < dim ? "positions" : "field data";
        rc = cs_doubles(s, NULL, lo, what);
        if (!rc) rc = cs_doubles(s, d, m, what);
        if (!rc) rc = cs_doubles(s, NULL, (size_t)n - hi, what);
    }
    if (rc) return rc;
    uint64_t nh;
    if ((rc = cs_u64(s, &nh, "history count"))) return rc;
    if (nh > cs_left(s) / 8) return cs_bad(s, "history count larger than the payload holds");
    if (nh) {
        *history = malloc((size_t)nh * sizeof(double));
        if (!*history) return consph_fail(CONSPH_ENOMEM, "out of memory");
        if ((rc = cs_doubles(s, *history, (size_t)nh, "history"))) return rc;
    }
    *nhistory = (size_t)nh;
    if (cs_left(s) != 0) return cs_bad(s, "bytes after the history");
    return CONSPH_OK;
}

/* The header of a checkpoint open in fp: magic, version, the compressed size against the file's
 * and the sizes' plausibility; fp is left at the compressed payload. */
static int ck_header(const ck_reader *r, FILE *fp, uint32_t *crc, uint64_t *usize, uint64_t *csize)
{
    unsigned char head[CK_HEADER];
    const size_t got = fread(head, 1, sizeof head, fp);
    char msg[160];
    if (got < 8 || memcmp(head, CK_MAGIC, 8) != 0)
        return bad(r, "not a consph checkpoint (bad magic)");
    if (got < sizeof head) return bad(r, "truncated header");
    const uint32_t version = get_u32(head + 8);
    *crc = get_u32(head + 12);
    *usize = get_u64(head + 16);
    *csize = get_u64(head + 24);
    if (version != CK_VERSION) {
        snprintf(msg, sizeof msg, "format version %lu, this build reads version %u",
                 (unsigned long)version, CK_VERSION);
        return bad(r, msg);
    }
    long fsize = -1;
    if (fseek(fp, 0, SEEK_END) != 0 || (fsize = ftell(fp)) < 0)
        return consph_fail(CONSPH_EIO, "cannot read checkpoint '%s'", r->path);
    if ((uint64_t)fsize - CK_HEADER != *csize) {
        snprintf(msg, sizeof msg, "%s: %llu bytes of compressed payload, the header says %llu",
                 (uint64_t)fsize - CK_HEADER < *csize ? "truncated" : "trailing bytes",
                 (unsigned long long)((uint64_t)fsize - CK_HEADER), (unsigned long long)*csize);
        return bad(r, msg);
    }
    if (*csize == 0 || *csize > UINT_MAX || *usize / CK_MAX_RATIO > *csize)
        return bad(r, "impossible payload sizes in the header");
    if (fseek(fp, CK_HEADER, SEEK_SET) != 0)
        return consph_fail(CONSPH_EIO, "cannot read checkpoint '%s'", r->path);
    return CONSPH_OK;
}

int consph_checkpoint_read(const char *path, char **meta, consph_particles *p, double **history,
                           size_t *nhistory)
{
    *meta = NULL;
    *history = NULL;
    *nhistory = 0;
    memset(p, 0, sizeof *p);
    ck_reader r = {path};
    FILE *fp = fopen(path, "rb");
    if (!fp) return consph_fail(CONSPH_EIO, "cannot open checkpoint '%s'", path);
    unsigned char *comp = NULL, *payload = NULL;
    uint32_t crc = 0;
    uint64_t usize = 0, csize = 0;
    int rc = ck_header(&r, fp, &crc, &usize, &csize);
    if (rc) goto done;
    comp = malloc((size_t)csize);
    if (!comp) {
        rc = consph_fail(CONSPH_ENOMEM, "out of memory");
        goto done;
    }
    if (fread(comp, 1, (size_t)csize, fp) != csize) {
        rc = consph_fail(CONSPH_EIO, "cannot read checkpoint '%s'", path);
        goto done;
    }
    size_t plen = 0, pcap = 0;
    const char *why;
    if (consph_rd_inflate(comp, (size_t)csize, &payload, &plen, &pcap, (size_t)usize, &why)) {
        rc = bad(&r, why);
        goto done;
    }
    if (plen != usize) {
        rc = bad(&r, "payload shorter than the header says");
        goto done;
    }
    uLong c = crc32(0L, Z_NULL, 0);
    for (size_t off = 0; off < plen; off += UINT_MAX)
        c = crc32(c, payload + off, (uInt)(plen - off < UINT_MAX ? plen - off : UINT_MAX));
    if ((uint32_t)c != crc) {
        rc = bad(&r, "CRC-32 mismatch (corrupt payload)");
        goto done;
    }
    ck_stream *s = consph_calloc(1, sizeof *s);
    if (!s) {
        rc = consph_fail(CONSPH_ENOMEM, "out of memory");
        goto done;
    }
    s->path = path;
    s->mem = payload;
    s->usize = plen;
    size_t first = 0, total = 0;
    rc = cs_payload(s, 0, 1, meta, p, history, nhistory, &first, &total);
    free(s);
    if (rc != CONSPH_OK) {
        free(*meta);
        *meta = NULL;
        free(*history);
        *history = NULL;
        *nhistory = 0;
        consph_particles_free(p);
    }
done:
    fclose(fp);
    free(comp);
    free(payload);
    return rc;
}

/* The first pass of a part's read: the whole compressed payload inflated as a stream into
 * scratch, with consph_checkpoint_read's checks and words (consph_rd_inflate's for the stream,
 * then its size and CRC), so that a bad file is refused as the whole read refuses it. */
static int ck_verify(ck_stream *s, const ck_reader *r, uint64_t csize, uint32_t crc)
{
    const char *why = "";
    z_stream z;
    memset(&z, 0, sizeof z);
    if (inflateInit(&z) != Z_OK) return bad(r, "out of memory");
    uint64_t read_in = 0, out = 0;
    const uint64_t limit = s->usize + 1;
    uLong c = crc32(0L, Z_NULL, 0);
    int rc = Z_OK;
    while (rc != Z_STREAM_END && out < limit) {
        if (z.avail_in == 0 && read_in < csize) {
            const size_t want = csize - read_in < CK_CHUNK ? (size_t)(csize - read_in) : CK_CHUNK;
            const size_t got = fread(s->in, 1, want, s->fp);
            if (got != want) {
                inflateEnd(&z);
                return consph_fail(CONSPH_EIO, "cannot read checkpoint '%s'", r->path);
            }
            read_in += got;
            z.next_in = s->in;
            z.avail_in = (uInt)got;
        }
        size_t room = CK_CHUNK;
        if (room > limit - out) room = (size_t)(limit - out);
        z.next_out = s->skip;
        z.avail_out = (uInt)room;
        rc = inflate(&z, Z_NO_FLUSH);
        const size_t got = room - z.avail_out;
        c = crc32(c, s->skip, (uInt)got);
        out += got;
        if (rc == Z_OK) continue;
        if (rc == Z_STREAM_END) break;
        if (rc == Z_BUF_ERROR && (z.avail_out == 0 || (z.avail_in == 0 && read_in < csize)))
            continue;
        if (rc == Z_BUF_ERROR)
            why = "truncated compressed data";
        else if (rc == Z_NEED_DICT)
            why = "needs a preset dictionary";
        else if (rc == Z_MEM_ERROR)
            why = "out of memory";
        else if (z.msg && strstr(z.msg, "incorrect data check"))
            why = "checksum mismatch";
        else if (z.msg && strstr(z.msg, "header"))
            why = "not a zlib stream (bad header)";
        else
            why = "corrupt compressed data";
        break;
    }
    inflateEnd(&z);
    if (out > s->usize) return bad(r, "more data than the block size in the header");
    if (rc != Z_STREAM_END) return bad(r, why[0] ? why : "truncated compressed data");
    if (z.avail_in != 0 || read_in < csize) return bad(r, "bytes after the end of the zlib stream");
    if (out != s->usize) return bad(r, "payload shorter than the header says");
    if ((uint32_t)c != crc) return bad(r, "CRC-32 mismatch (corrupt payload)");
    return CONSPH_OK;
}

int consph_checkpoint_read_part(const char *path, int part, int parts, char **meta,
                                consph_particles *p, double **history, size_t *nhistory,
                                size_t *first, size_t *total)
{
    *meta = NULL;
    *history = NULL;
    *nhistory = 0;
    *first = *total = 0;
    memset(p, 0, sizeof *p);
    if (parts < 1 || part < 0 || part >= parts)
        return consph_fail(CONSPH_EINVAL, "checkpoint '%s': part %d of %d", path, part, parts);
    ck_stream *s = consph_calloc(1, sizeof *s);
    if (!s) return consph_fail(CONSPH_ENOMEM, "out of memory");
    s->path = path;
    ck_reader r = {path};
    s->fp = fopen(path, "rb");
    if (!s->fp) {
        free(s);
        return consph_fail(CONSPH_EIO, "cannot open checkpoint '%s'", path);
    }
    /* the header's checks are consph_checkpoint_read's, then the whole stream's */
    uint32_t crc = 0;
    uint64_t csize = 0;
    int rc = ck_header(&r, s->fp, &crc, &s->usize, &csize);
    if (rc == CONSPH_OK && (rc = ck_verify(s, &r, csize, crc)) == CONSPH_OK &&
        fseek(s->fp, CK_HEADER, SEEK_SET) != 0)
        rc = consph_fail(CONSPH_EIO, "cannot read checkpoint '%s'", path);
    if (rc == CONSPH_OK) {
        if (inflateInit(&s->z) != Z_OK) {
            rc = consph_fail(CONSPH_ENOMEM, "out of memory");
        } else {
            s->zinit = 1;
            s->crc = crc32(0L, Z_NULL, 0);
            rc = cs_payload(s, part, parts, meta, p, history, nhistory, first, total);
            /* the stream was checked whole (ck_verify): what remains is the payload's content */
            if (rc == CONSPH_OK && !cs_end(s))
                rc = bad(&r, "inflate: the stream holds more than the header says");
        }
    }
    if (s->zinit) inflateEnd(&s->z);
    fclose(s->fp);
    free(s);
    if (rc != CONSPH_OK) {
        free(*meta);
        *meta = NULL;
        free(*history);
        *history = NULL;
        *nhistory = 0;
        if (p->x[0]) consph_particles_free(p);
    }
    return rc;
}
