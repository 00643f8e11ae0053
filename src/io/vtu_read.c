/* The .vtu reader: VTK XML UnstructuredGrid as consph and ParaView write it, streamed.
 *
 * The XML is read element by element; the data of an inline DataArray (ascii, or base64
 * "binary") is decoded while it is read, straight into growable columns. Arrays in appended
 * form are remembered with their offsets and read in offset order once <AppendedData> is
 * reached (raw bytes or base64), so no part of the file is held in memory beyond the particle
 * columns and one compressed block. Binary data is a header of UInt32 or UInt64 integers (the
 * byte count, or for vtkZLibDataCompressor: block count, block size, last block size and the
 * compressed size of each block) followed by the data; VTK encodes the header and the data in
 * one base64 run or in two, so the base64 decoder accepts padding between runs. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "io/read_internal.h"

#define XML_NAME_MAX 64
#define XML_VALUE_MAX 1024
#define XML_MAX_ATTR 32
#define XML_MAX_DEPTH 32
#define VTU_MAX_ARRAYS (CONSPH_MAX_FIELDS + 8)
/* A VTK block is 32 KiB by default; anything near this is not a block size. */
#define VTU_MAX_BLOCK ((uint64_t)1 << 31)

enum { TAG_START, TAG_END, TAG_EMPTY, TAG_EOF };
enum { ROLE_SKIP, ROLE_POINTS, ROLE_FIELD, ROLE_BOX, ROLE_PERIODIC, ROLE_SPACING, ROLE_TIME };
enum { FMT_ASCII, FMT_BINARY, FMT_APPENDED };
enum { PH_HEAD, PH_DATA, PH_CHEAD, PH_CSIZES, PH_BLOCK, PH_DONE };

typedef struct xml_tag {
    int kind;
    char name[XML_NAME_MAX];
    int nattr;
    char attr_name[XML_MAX_ATTR][XML_NAME_MAX];
    char attr_value[XML_MAX_ATTR][XML_VALUE_MAX];
    size_t line;
} xml_tag;

static const struct {
    const char *name;
    int size, is_float, is_signed;
} vt_types[] = {{"Int8", 1, 0, 1},    {"UInt8", 1, 0, 0},   {"Int16", 2, 0, 1}, {"UInt16", 2, 0, 0},
                {"Int32", 4, 0, 1},   {"UInt32", 4, 0, 0},  {"Int64", 8, 0, 1}, {"UInt64", 8, 0, 0},
                {"Float32", 4, 1, 1}, {"Float64", 8, 1, 1}, {"Char", 1, 0, 1},  {"UChar", 1, 0, 0},
                {"Short", 2, 0, 1},   {"UShort", 2, 0, 0},  {"Int", 4, 0, 1},   {"UInt", 4, 0, 0},
                {"Float", 4, 1, 1},   {"Double", 8, 1, 1}};
#define VT_NTYPES ((int)(sizeof vt_types / sizeof vt_types[0]))

typedef struct vtu_array {
    int role, type, ncomp, format;
    int field; /* ROLE_FIELD: index into set->fields */
    uint64_t offset;
    size_t line;
    char name[XML_NAME_MAX];
    size_t nvalues, expect; /* values received; expected (0: unknown) */
    double small[8];        /* FieldData values */
} vtu_array;

/* Decoding state of the binary data of one array. */
typedef struct vtu_stream {
    int phase;
    unsigned char hb[8];
    int hn, hcount;
    uint64_t data_left;
    uint64_t nblocks, blocksize, lastsize, block;
    uint64_t *csize;
    size_t ncsize, capcsize;
    unsigned char *cbuf, *obuf;
    size_t cn, ccap, ocap;
    unsigned char vb[8];
    int vn;
    char q[4]; /* base64 quad being assembled */
    int qn;
} vtu_stream;

typedef struct vtu_ctx {
    rd_src *s;
    rd_set *set;
    const consph_read_options *opt;
    size_t line;
    int big, hsize, zlib;
    int depth;
    char stack[XML_MAX_DEPTH][XML_NAME_MAX];
    size_t stack_line[XML_MAX_DEPTH];
    int seen_root, npieces, appended_read;
    int have_npoints;
    size_t npoints;
    int have_points, points_format, appended_base64;
    vtu_array pending[VTU_MAX_ARRAYS];
    int npending;
    xml_tag tag;
    vtu_stream st;
    char tok[96];
    int ntok;
} vtu_ctx;

/* ---- messages ---- */

static int fail_at(vtu_ctx *c, int code, size_t line, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
static int fail_at(vtu_ctx *c, int code, size_t line, const char *fmt, ...)
{
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return consph_fail(code, "%s:%zu: %s", c->set->name, line, msg);
}

static int fail_array(vtu_ctx *c, const vtu_array *a, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static int fail_array(vtu_ctx *c, const vtu_array *a, const char *fmt, ...)
{
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return consph_fail(CONSPH_EFORMAT, "%s:%zu: <DataArray Name=\"%s\">: %s", c->set->name, a->line,
                       a->name, msg);
}

static int fail_truncated(vtu_ctx *c)
{
    if (c->s->failed) return CONSPH_EIO;
    if (c->depth > 0)
        return fail_at(c, CONSPH_EFORMAT, c->line,
                       "truncated file: it ends inside <%s> (opened on line %zu)",
                       c->stack[c->depth - 1], c->stack_line[c->depth - 1]);
    return fail_at(c, CONSPH_EFORMAT, c->line, "truncated file: it ends inside a tag");
}

/* ---- XML ---- */

static int xgetc(vtu_ctx *c)
{
    int ch = rd_getc(c->s);
    if (ch == '\n') ++c->line;
    return ch;
}

static int is_space(int ch)
{
    return ch == ' ' || ch == '\t' || ch == '\n' || ch == '\r';
}

static int is_name_char(int ch)
{
    return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
           ch == '_' || ch == ':' || ch == '-' || ch == '.';
}

/* Skips up to and including `end` (e.g. "-->"). */
static int skip_until(vtu_ctx *c, const char *end)
{
    size_t n = strlen(end), matched = 0;
    for (;;) {
        int ch = xgetc(c);
        if (ch < 0) return fail_truncated(c);
        if (ch == end[matched]) {
            if (++matched == n) return CONSPH_OK;
        } else {
            matched = ch == end[0] ? 1 : 0;
        }
    }
}

/* Reads a name starting with `first`; *next receives the character after it. */
static int read_name(vtu_ctx *c, int first, char *name, int *next)
{
    int n = 0, ch = first;
    while (is_name_char(ch)) {
        if (n == XML_NAME_MAX - 1)
            return fail_at(c, CONSPH_EFORMAT, c->line,
                           "malformed XML: a name longer than %d characters", XML_NAME_MAX - 1);
        name[n++] = (char)ch;
        ch = xgetc(c);
    }
    name[n] = '\0';
    if (n == 0) {
        if (ch < 0) return fail_truncated(c);
        return fail_at(c, CONSPH_EFORMAT, c->line, "malformed XML: expected a name, found '%c'",
                       ch >= 32 && ch < 127 ? ch : '?');
    }
    *next = ch;
    return CONSPH_OK;
}

static int attr_value(vtu_ctx *c, char *value)
{
    int quote = xgetc(c);
    if (quote != '"' && quote != '\'') {
        if (quote < 0) return fail_truncated(c);
        return fail_at(c, CONSPH_EFORMAT, c->line,
                       "malformed XML: an attribute value must be "
                       "quoted");
    }
    int n = 0;
    for (;;) {
        int ch = xgetc(c);
        if (ch < 0) return fail_truncated(c);
        if (ch == quote) break;
        if (ch == '<')
            return fail_at(c, CONSPH_EFORMAT, c->line, "malformed XML: '<' in an attribute value");
        if (ch == '&') {
            char ent[8];
            int k = 0;
            while ((ch = xgetc(c)) >= 0 && ch != ';' && k < 7) ent[k++] = (char)ch;
            ent[k] = '\0';
            if (ch != ';')
                return fail_at(c, CONSPH_EFORMAT, c->line, "malformed XML: bad entity '&%s'", ent);
            ch = !strcmp(ent, "lt")     ? '<'
                 : !strcmp(ent, "gt")   ? '>'
                 : !strcmp(ent, "amp")  ? '&'
                 : !strcmp(ent, "quot") ? '"'
                 : !strcmp(ent, "apos") ? '\''
                                        : -1;
            if (ch < 0)
                return fail_at(c, CONSPH_EFORMAT, c->line, "unsupported XML entity '&%s;'", ent);
        }
        if (n == XML_VALUE_MAX - 1)
            return fail_at(c, CONSPH_EFORMAT, c->line,
                           "an attribute value longer than %d "
                           "characters",
                           XML_VALUE_MAX - 1);
        value[n++] = (char)ch;
    }
    value[n] = '\0';
    return CONSPH_OK;
}

/* Parses the markup after a '<' already consumed: a start, end or empty-element tag. Comments,
 * processing instructions and declarations are skipped (kind -1). */
static int parse_markup(vtu_ctx *c, xml_tag *t)
{
    t->line = c->line;
    t->nattr = 0;
    int ch = xgetc(c);
    if (ch < 0) return fail_truncated(c);
    if (ch == '?') {
        t->kind = -1;
        return skip_until(c, "?>");
    }
    if (ch == '!') {
        int a = xgetc(c), b = a == '-' ? xgetc(c) : 0;
        t->kind = -1;
        if (a == '-' && b == '-') return skip_until(c, "-->");
        if (a == '[')
            return fail_at(c, CONSPH_EFORMAT, c->line, "XML CDATA sections are not supported");
        if (a < 0) return fail_truncated(c);
        return skip_until(c, ">");
    }
    if (ch == '/') {
        int rc = read_name(c, xgetc(c), t->name, &ch);
        if (rc) return rc;
        while (is_space(ch)) ch = xgetc(c);
        if (ch != '>') {
            if (ch < 0) return fail_truncated(c);
            return fail_at(c, CONSPH_EFORMAT, c->line, "malformed XML end tag </%s", t->name);
        }
        t->kind = TAG_END;
        return CONSPH_OK;
    }
    int rc = read_name(c, ch, t->name, &ch);
    if (rc) return rc;
    for (;;) {
        while (is_space(ch)) ch = xgetc(c);
        if (ch == '>') {
            t->kind = TAG_START;
            return CONSPH_OK;
        }
        if (ch == '/') {
            if ((ch = xgetc(c)) != '>') {
                if (ch < 0) return fail_truncated(c);
                return fail_at(c, CONSPH_EFORMAT, c->line,
                               "malformed XML: '/' not followed by "
                               "'>' in <%s>",
                               t->name);
            }
            t->kind = TAG_EMPTY;
            return CONSPH_OK;
        }
        if (ch < 0) return fail_truncated(c);
        if (t->nattr == XML_MAX_ATTR)
            return fail_at(c, CONSPH_EFORMAT, c->line, "<%s> has more than %d attributes", t->name,
                           XML_MAX_ATTR);
        rc = read_name(c, ch, t->attr_name[t->nattr], &ch);
        if (rc) return rc;
        while (is_space(ch)) ch = xgetc(c);
        if (ch != '=') {
            if (ch < 0) return fail_truncated(c);
            return fail_at(c, CONSPH_EFORMAT, c->line,
                           "malformed XML: attribute '%s' of <%s> has "
                           "no value",
                           t->attr_name[t->nattr], t->name);
        }
        while (is_space(rd_peek(c->s))) xgetc(c);
        if ((rc = attr_value(c, t->attr_value[t->nattr]))) return rc;
        t->nattr++;
        ch = xgetc(c);
    }
}

/* The next tag, skipping text (which outside data arrays carries nothing we need). */
static int next_tag(vtu_ctx *c, xml_tag *t)
{
    for (;;) {
        int ch = xgetc(c);
        if (ch < 0) {
            if (c->s->failed) return CONSPH_EIO;
            t->kind = TAG_EOF;
            return CONSPH_OK;
        }
        if (ch != '<') continue;
        int rc = parse_markup(c, t);
        if (rc) return rc;
        if (t->kind >= 0) return CONSPH_OK;
    }
}

static const char *attr(const xml_tag *t, const char *name)
{
    for (int k = 0; k < t->nattr; ++k)
        if (strcmp(t->attr_name[k], name) == 0) return t->attr_value[k];
    return NULL;
}

/* A non-negative integer attribute, at most `max`; `def` when absent. */
static int attr_count(vtu_ctx *c, const xml_tag *t, const char *name, uint64_t def, uint64_t max,
                      uint64_t *out)
{
    const char *v = attr(t, name);
    if (!v) {
        *out = def;
        return CONSPH_OK;
    }
    const char *p = v;
    while (is_space((unsigned char)*p)) ++p;
    uint64_t n = 0;
    int digits = 0;
    for (; *p >= '0' && *p <= '9'; ++p, ++digits) {
        if (n > (max - (uint64_t)(*p - '0')) / 10)
            return fail_at(c, CONSPH_EFORMAT, t->line, "<%s %s=\"%.40s\">: more than %llu", t->name,
                           name, v, (unsigned long long)max);
        n = n * 10 + (uint64_t)(*p - '0');
    }
    while (is_space((unsigned char)*p)) ++p;
    if (!digits || *p)
        return fail_at(c, CONSPH_EFORMAT, t->line, "<%s %s=\"%.40s\">: not a non-negative integer",
                       t->name, name, v);
    *out = n;
    return CONSPH_OK;
}

/* ---- values ---- */

static uint64_t load_uint(const unsigned char *b, int size, int big)
{
    uint64_t u = 0;
    if (big)
        for (int k = 0; k < size; ++k) u = u << 8 | b[k];
    else
        for (int k = size - 1; k >= 0; --k) u = u << 8 | b[k];
    return u;
}

static double decode_value(const unsigned char *b, int type, int big)
{
    int size = vt_types[type].size;
    uint64_t u = load_uint(b, size, big);
    if (vt_types[type].is_float) {
        if (size == 4) {
            uint32_t w = (uint32_t)u;
            float f;
            memcpy(&f, &w, sizeof f);
            return (double)f;
        }
        double d;
        memcpy(&d, &u, sizeof d);
        return d;
    }
    if (!vt_types[type].is_signed) return (double)u;
    if (size < 8 && (u >> (8 * size - 1)) & 1u) u |= ~(uint64_t)0 << (8 * size); /* sign-extend */
    int64_t s;
    memcpy(&s, &u, sizeof s);
    return (double)s;
}

static const char axis_letter[3] = {'x', 'y', 'z'};

static int sink(vtu_ctx *c, vtu_array *a, double v)
{
    size_t k = a->nvalues;
    if (a->expect && k >= a->expect)
        return fail_array(c, a, "more values than NumberOfPoints x NumberOfComponents = %zu",
                          a->expect);
    a->nvalues++;
    switch (a->role) {
    case ROLE_POINTS:
        if (!isfinite(v))
            return fail_array(c, a, "point %zu: coordinate %c is not a finite number (%g)", k / 3,
                              axis_letter[k % 3], v);
        return consph_rd_push(&c->set->x[k % 3], v);
    case ROLE_FIELD: {
        rd_field *f = &c->set->fields[a->field];
        if (!isfinite(v))
            return fail_array(c, a, "point %zu: value %g is not a finite number",
                              k / (size_t)f->ncomp, v);
        return consph_rd_push(&f->col[k % (size_t)f->ncomp], v);
    }
    case ROLE_BOX:
    case ROLE_PERIODIC:
    case ROLE_SPACING:
    case ROLE_TIME:
        if (k >= 8) return fail_array(c, a, "too many values");
        if (!isfinite(v)) return fail_array(c, a, "value %g is not a finite number", v);
        a->small[k] = v;
        return CONSPH_OK;
    default:
        return CONSPH_OK;
    }
}

static int values_in(vtu_ctx *c, vtu_array *a, const unsigned char *b, size_t n)
{
    vtu_stream *st = &c->st;
    int size = vt_types[a->type].size;
    for (size_t k = 0; k < n; ++k) {
        st->vb[st->vn++] = b[k];
        if (st->vn == size) {
            st->vn = 0;
            int rc = sink(c, a, decode_value(st->vb, a->type, c->big));
            if (rc) return rc;
        }
    }
    return CONSPH_OK;
}

/* ---- binary data: header, blocks, inflation ---- */

static void stream_reset(vtu_ctx *c)
{
    vtu_stream *st = &c->st;
    st->phase = c->zlib ? PH_CHEAD : PH_HEAD;
    st->hn = st->hcount = st->vn = st->qn = 0;
    st->data_left = st->nblocks = st->blocksize = st->lastsize = st->block = 0;
    st->ncsize = 0;
    st->cn = 0;
}

static void stream_free(vtu_stream *st)
{
    free(st->csize);
    free(st->cbuf);
    free(st->obuf);
    memset(st, 0, sizeof *st);
}

/* Bytes the stream takes before its current phase ends; 0 once the array is complete. */
static uint64_t stream_want(const vtu_ctx *c)
{
    const vtu_stream *st = &c->st;
    switch (st->phase) {
    case PH_HEAD:
    case PH_CHEAD:
    case PH_CSIZES:
        return (uint64_t)(c->hsize - st->hn);
    case PH_DATA:
        return st->data_left;
    case PH_BLOCK:
        return st->csize[st->block] - st->cn;
    default:
        return 0;
    }
}

static uint64_t block_size(const vtu_stream *st, uint64_t b)
{
    return b + 1 == st->nblocks && st->lastsize ? st->lastsize : st->blocksize;
}

static int header_value(vtu_ctx *c, vtu_array *a, uint64_t v)
{
    vtu_stream *st = &c->st;
    uint64_t tsize = (uint64_t)vt_types[a->type].size;
    if (st->phase == PH_HEAD) {
        if (v % tsize)
            return fail_array(c, a, "the data size %llu is not a multiple of %s's %llu bytes",
                              (unsigned long long)v, vt_types[a->type].name,
                              (unsigned long long)tsize);
        if (a->expect && v / tsize != a->expect)
            return fail_array(c, a, "the header says %llu bytes, %zu values of %llu bytes expected",
                              (unsigned long long)v, a->expect, (unsigned long long)tsize);
        st->data_left = v;
        st->phase = v ? PH_DATA : PH_DONE;
        return CONSPH_OK;
    }
    if (st->phase == PH_CHEAD) {
        if (st->hcount == 0) st->nblocks = v;
        if (st->hcount == 1) st->blocksize = v;
        if (st->hcount == 2) st->lastsize = v;
        if (++st->hcount < 3) return CONSPH_OK;
        if (st->nblocks > 0 && (st->blocksize == 0 || st->blocksize > VTU_MAX_BLOCK ||
                                st->lastsize > st->blocksize || st->nblocks > ((uint64_t)1 << 40)))
            return fail_array(c, a, "bad compression header: %llu blocks of %llu bytes, last %llu",
                              (unsigned long long)st->nblocks, (unsigned long long)st->blocksize,
                              (unsigned long long)st->lastsize);
        uint64_t total =
            st->nblocks ? (st->nblocks - 1) * st->blocksize + block_size(st, st->nblocks - 1) : 0;
        if (total % tsize || (a->expect && total / tsize != a->expect))
            return fail_array(c, a,
                              "the compression header says %llu bytes, %zu values of %llu bytes "
                              "expected",
                              (unsigned long long)total, a->expect, (unsigned long long)tsize);
        st->phase = st->nblocks ? PH_CSIZES : PH_DONE;
        return CONSPH_OK;
    }
    /* PH_CSIZES */
    if (st->ncsize == st->capcsize) {
        size_t cap = st->capcsize ? 2 * st->capcsize : 16;
        uint64_t *p = realloc(st->csize, cap * sizeof *p);
        if (!p) return consph_fail(CONSPH_ENOMEM, "out of memory");
        st->csize = p;
        st->capcsize = cap;
    }
    if (v == 0) return fail_array(c, a, "block %zu has compressed size 0", st->ncsize);
    st->csize[st->ncsize++] = v;
    if (st->ncsize == st->nblocks) {
        st->phase = PH_BLOCK;
        st->block = 0;
        st->cn = 0;
    }
    return CONSPH_OK;
}

static int block_done(vtu_ctx *c, vtu_array *a)
{
    vtu_stream *st = &c->st;
    size_t outlen = 0;
    const char *why = "";
    uint64_t want = block_size(st, st->block);
    if (consph_rd_inflate(st->cbuf, st->cn, &st->obuf, &outlen, &st->ocap, (size_t)want, &why))
        return fail_array(c, a, "zlib block %llu of %llu: %s", (unsigned long long)st->block + 1,
                          (unsigned long long)st->nblocks, why);
    if (outlen != want)
        return fail_array(c, a, "zlib block %llu inflates to %zu bytes, the header says %llu",
                          (unsigned long long)st->block + 1, outlen, (unsigned long long)want);
    int rc = values_in(c, a, st->obuf, outlen);
    if (rc) return rc;
    st->cn = 0;
    if (++st->block == st->nblocks) st->phase = PH_DONE;
    return CONSPH_OK;
}

static int bytes_in(vtu_ctx *c, vtu_array *a, const unsigned char *b, size_t n)
{
    vtu_stream *st = &c->st;
    while (n > 0) {
        size_t take;
        int rc = CONSPH_OK;
        switch (st->phase) {
        case PH_HEAD:
        case PH_CHEAD:
        case PH_CSIZES:
            take = (size_t)(c->hsize - st->hn);
            if (take > n) take = n;
            memcpy(st->hb + st->hn, b, take);
            st->hn += (int)take;
            if (st->hn == c->hsize) {
                st->hn = 0;
                rc = header_value(c, a, load_uint(st->hb, c->hsize, c->big));
            }
            break;
        case PH_DATA:
            take = st->data_left < n ? (size_t)st->data_left : n;
            rc = values_in(c, a, b, take);
            st->data_left -= take;
            if (st->data_left == 0) st->phase = PH_DONE;
            break;
        case PH_BLOCK: {
            uint64_t left = st->csize[st->block] - st->cn;
            take = left < n ? (size_t)left : n;
            if (st->cn + take > st->ccap) {
                size_t cap = st->ccap ? st->ccap : 4096;
                while (cap < st->cn + take) cap *= 2;
                unsigned char *p = realloc(st->cbuf, cap);
                if (!p) return consph_fail(CONSPH_ENOMEM, "out of memory");
                st->cbuf = p;
                st->ccap = cap;
            }
            memcpy(st->cbuf + st->cn, b, take);
            st->cn += take;
            if (st->cn == st->csize[st->block]) rc = block_done(c, a);
            break;
        }
        default:
            return fail_array(c, a, "more data than its header announces");
        }
        if (rc) return rc;
        b += take;
        n -= take;
    }
    return CONSPH_OK;
}

/* ---- base64 ---- */

static int b64_value(int ch)
{
    if (ch >= 'A' && ch <= 'Z') return ch - 'A';
    if (ch >= 'a' && ch <= 'z') return ch - 'a' + 26;
    if (ch >= '0' && ch <= '9') return ch - '0' + 52;
    if (ch == '+') return 62;
    if (ch == '/') return 63;
    return -1;
}

/* Adds one base64 character; every complete quad goes to the array's byte stream. A padded
 * quad may be followed by more quads (VTK encodes header and data separately). */
static int b64_char(vtu_ctx *c, vtu_array *a, int ch)
{
    vtu_stream *st = &c->st;
    if (b64_value(ch) < 0 && ch != '=')
        return fail_array(c, a, "'%c' is not a base64 character", ch >= 32 && ch < 127 ? ch : '?');
    st->q[st->qn++] = (char)ch;
    if (st->qn < 4) return CONSPH_OK;
    st->qn = 0;
    int v[4], pad = 0;
    for (int k = 0; k < 4; ++k) {
        v[k] = b64_value(st->q[k]);
        if (st->q[k] == '=') {
            ++pad;
            v[k] = 0;
        } else if (pad) {
            return fail_array(c, a, "base64 padding in the middle of a quad");
        }
    }
    if (pad > 2) return fail_array(c, a, "bad base64 padding");
    unsigned char out[3] = {(unsigned char)(v[0] << 2 | v[1] >> 4),
                            (unsigned char)((v[1] & 15) << 4 | v[2] >> 2),
                            (unsigned char)((v[2] & 3) << 6 | v[3])};
    return bytes_in(c, a, out, (size_t)(3 - pad));
}

/* ---- arrays ---- */

static int ascii_token(vtu_ctx *c, vtu_array *a)
{
    c->tok[c->ntok] = '\0';
    c->ntok = 0;
    char *end;
    double v = strtod(c->tok, &end);
    if (end == c->tok || *end) return fail_array(c, a, "'%s' is not a number", c->tok);
    if (!isfinite(v)) return fail_array(c, a, "'%s' is not a finite number", c->tok);
    return sink(c, a, v);
}

static int array_done(vtu_ctx *c, vtu_array *a)
{
    rd_set *set = c->set;
    if (a->format != FMT_ASCII && c->st.phase != PH_DONE)
        return fail_array(c, a, "truncated: the data ends before the size its header gives");
    if (a->expect && a->nvalues != a->expect)
        return fail_array(c, a, "%zu values, NumberOfPoints x NumberOfComponents = %zu expected",
                          a->nvalues, a->expect);
    size_t n = a->nvalues;
    switch (a->role) {
    case ROLE_BOX:
        if (n < 2 || n > 6 || n % 2)
            return fail_array(c, a, "%zu values; expected lo hi for each of 1 to 3 axes", n);
        for (size_t k = 0; k < n; k += 2)
            if (!(a->small[k] < a->small[k + 1]))
                return fail_array(c, a, "axis %c: lo %g is not below hi %g", axis_letter[k / 2],
                                  a->small[k], a->small[k + 1]);
        set->have_box = 1;
        set->box_dim = (int)(n / 2);
        for (size_t k = 0; k < n; k += 2) {
            set->lo[k / 2] = a->small[k];
            set->hi[k / 2] = a->small[k + 1];
        }
        set->dim = set->box_dim;
        set->dim_what = "the FieldData array 'box'";
        set->dim_line = a->line;
        break;
    case ROLE_PERIODIC:
        if (n < 1 || n > 3)
            return fail_array(c, a, "%zu values; expected 1 to 3 (one per axis)", n);
        for (size_t k = 0; k < n; ++k) {
            if (a->small[k] != 0 && a->small[k] != 1)
                return fail_array(c, a, "value %g is not 0 or 1", a->small[k]);
            set->periodic[k] = a->small[k] != 0;
        }
        set->have_periodic = 1;
        set->periodic_dim = (int)n;
        break;
    case ROLE_SPACING:
        if (n != 1 || a->small[0] < 0) return fail_array(c, a, "expected one non-negative value");
        if (a->small[0] > 0) {
            set->have_spacing = 1;
            set->spacing = a->small[0];
        }
        break;
    case ROLE_TIME:
        if (n != 1) return fail_array(c, a, "%zu values; expected one time", n);
        set->have_time = 1;
        set->time = a->small[0];
        break;
    default:
        break;
    }
    return CONSPH_OK;
}

/* Skips an element's content through its end tag (for children of DataArray). */
static int skip_element(vtu_ctx *c)
{
    int depth = 1;
    xml_tag *t = &c->tag;
    while (depth > 0) {
        int rc = next_tag(c, t);
        if (rc) return rc;
        if (t->kind == TAG_EOF) return fail_truncated(c);
        if (t->kind == TAG_START) ++depth;
        if (t->kind == TAG_END) --depth;
    }
    return CONSPH_OK;
}

/* Reads the content of an inline <DataArray> up to and including its end tag; `a` NULL or an
 * appended array: the text is skipped. */
static int read_inline(vtu_ctx *c, vtu_array *a)
{
    int decode = a && a->format != FMT_APPENDED;
    if (decode) {
        stream_reset(c);
        c->ntok = 0;
    }
    for (;;) {
        int ch = xgetc(c);
        if (ch < 0) return fail_truncated(c);
        if (ch == '<') {
            if (decode && a->format == FMT_ASCII && c->ntok) {
                int rc = ascii_token(c, a);
                if (rc) return rc;
            }
            xml_tag *t = &c->tag;
            int rc = parse_markup(c, t);
            if (rc) return rc;
            if (t->kind == TAG_END) {
                if (strcmp(t->name, "DataArray") != 0)
                    return fail_at(c, CONSPH_EFORMAT, t->line,
                                   "malformed XML: </%s> inside <DataArray>", t->name);
                break;
            }
            if (t->kind == TAG_START && (rc = skip_element(c))) return rc;
            continue;
        }
        if (!decode) continue;
        if (a->format == FMT_ASCII) {
            if (is_space(ch)) {
                if (c->ntok) {
                    int rc = ascii_token(c, a);
                    if (rc) return rc;
                }
            } else {
                if (c->ntok == (int)sizeof c->tok - 1)
                    return fail_array(c, a, "a number longer than %d characters",
                                      (int)sizeof c->tok - 1);
                c->tok[c->ntok++] = (char)ch;
            }
        } else if (!is_space(ch)) {
            int rc = b64_char(c, a, ch);
            if (rc) return rc;
        }
    }
    if (!decode) return CONSPH_OK;
    if (a->format == FMT_BINARY && c->st.qn)
        return fail_array(c, a, "truncated base64 data (%d characters left over)", c->st.qn);
    return array_done(c, a);
}

/* Fills `a` from a <DataArray> tag found under `parent`. */
static int describe_array(vtu_ctx *c, const xml_tag *t, const char *parent, vtu_array *a)
{
    memset(a, 0, sizeof *a);
    a->line = t->line;
    const char *name = attr(t, "Name");
    snprintf(a->name, sizeof a->name, "%s", name ? name : "");
    if (!strcmp(parent, "Points")) {
        if (c->have_points)
            return fail_at(c, CONSPH_EFORMAT, t->line, "<Points> holds more than one DataArray");
        a->role = ROLE_POINTS;
        if (!name) snprintf(a->name, sizeof a->name, "Points");
    } else if (!strcmp(parent, "PointData") && name) {
        a->role = ROLE_FIELD;
    } else if (!strcmp(parent, "FieldData") && name) {
        a->role = !strcmp(name, "box")         ? ROLE_BOX
                  : !strcmp(name, "periodic")  ? ROLE_PERIODIC
                  : !strcmp(name, "spacing")   ? ROLE_SPACING
                  : !strcmp(name, "TimeValue") ? ROLE_TIME
                                               : ROLE_SKIP;
    } else {
        a->role = ROLE_SKIP;
    }
    const char *type = attr(t, "type");
    a->type = -1;
    for (int k = 0; type && k < VT_NTYPES; ++k)
        if (!strcmp(type, vt_types[k].name)) a->type = k;
    const char *format = attr(t, "format");
    a->format = !format                       ? -1
                : !strcmp(format, "ascii")    ? FMT_ASCII
                : !strcmp(format, "binary")   ? FMT_BINARY
                : !strcmp(format, "appended") ? FMT_APPENDED
                                              : -1;
    uint64_t ncomp = 1;
    int rc = attr_count(c, t, "NumberOfComponents", 1, 1u << 20, &ncomp);
    if (rc) return rc;
    if (ncomp == 0) return fail_array(c, a, "NumberOfComponents=\"0\"; it must be at least 1");
    a->ncomp = (int)ncomp;
    if (a->role == ROLE_SKIP) return CONSPH_OK;
    if (a->type < 0) {
        /* A field we cannot hold (a string array, ...) is left out, but coordinates must be
         * numbers. */
        if (a->role == ROLE_FIELD) {
            a->role = ROLE_SKIP;
            return CONSPH_OK;
        }
        return fail_array(c, a, "type=\"%.40s\" is not a numeric VTK type", type ? type : "");
    }
    if (a->format < 0)
        return fail_array(c, a, "format=\"%.40s\": expected ascii, binary or appended",
                          format ? format : "");
    if (a->format == FMT_APPENDED) {
        if ((rc = attr_count(c, t, "offset", 0, UINT64_MAX / 2, &a->offset))) return rc;
        if (!attr(t, "offset")) return fail_array(c, a, "format=\"appended\" without an offset");
    }
    if (a->role == ROLE_POINTS) {
        if (!c->have_npoints)
            return fail_array(c, a, "<Points> outside a <Piece> with NumberOfPoints");
        if (a->ncomp != 3)
            return fail_array(c, a, "NumberOfComponents=\"%d\"; points have 3", a->ncomp);
        a->expect = 3 * c->npoints;
        c->have_points = 1;
        c->points_format = a->format;
        c->set->points_line = t->line;
    } else if (a->role == ROLE_FIELD) {
        rd_set *set = c->set;
        if (!c->have_npoints)
            return fail_array(c, a, "<PointData> outside a <Piece> with NumberOfPoints");
        /* Arrays that cannot become fields are left out; they cannot change any result. */
        if (a->ncomp > RD_MAX_COMP || strlen(name) >= CONSPH_FIELD_NAME_MAX ||
            set->nfields >= CONSPH_MAX_FIELDS - 1) {
            a->role = ROLE_SKIP;
            return CONSPH_OK;
        }
        for (int f = 0; f < set->nfields; ++f)
            if (consph_rd_streq_nocase(set->fields[f].name, name))
                return fail_array(c, a, "a second PointData array of this name");
        a->field = set->nfields++;
        rd_field *f = &set->fields[a->field];
        snprintf(f->name, sizeof f->name, "%s", name);
        f->ncomp = a->ncomp;
        set->field_line[a->field] = t->line;
        a->expect = c->npoints * (size_t)a->ncomp;
    } else {
        uint64_t ntuples = 0;
        if ((rc = attr_count(c, t, "NumberOfTuples", 0, 8, &ntuples))) return rc;
        if (ntuples * ncomp > 8) return fail_array(c, a, "more values than expected");
        a->expect = (size_t)(ntuples * ncomp);
    }
    return CONSPH_OK;
}

/* ---- appended data ---- */

static int compare_offsets(const void *x, const void *y)
{
    const vtu_array *a = x, *b = y;
    return a->offset < b->offset ? -1 : a->offset > b->offset;
}

static int read_appended(vtu_ctx *c, const xml_tag *t)
{
    const char *enc = attr(t, "encoding");
    int b64 = enc && !strcmp(enc, "base64");
    if (!enc || (!b64 && strcmp(enc, "raw") != 0))
        return fail_at(c, CONSPH_EFORMAT, t->line,
                       "<AppendedData encoding=\"%.40s\">: expected raw or base64", enc ? enc : "");
    c->appended_base64 = b64;
    c->appended_read = 1;
    int ch;
    while ((ch = xgetc(c)) >= 0 && is_space(ch)) {
    }
    if (ch != '_') {
        if (ch < 0) return fail_truncated(c);
        return fail_at(c, CONSPH_EFORMAT, c->line,
                       "<AppendedData>: expected '_' before the data, found '%c'",
                       ch >= 32 && ch < 127 ? ch : '?');
    }
    qsort(c->pending, (size_t)c->npending, sizeof c->pending[0], compare_offsets);
    rd_src *s = c->s;
    uint64_t pos = 0; /* bytes (raw) or characters (base64) after the '_' */
    for (int k = 0; k < c->npending; ++k) {
        vtu_array *a = &c->pending[k];
        if (a->offset < pos)
            return fail_array(c, a,
                              "offset %llu overlaps the previous array's data (which ends "
                              "at %llu)",
                              (unsigned long long)a->offset, (unsigned long long)pos);
        while (pos < a->offset) {
            if (consph_rd_fill(s, 1) || s->pos == s->len)
                return s->failed ? CONSPH_EIO
                                 : fail_array(c, a,
                                              "truncated: the appended data ends before "
                                              "offset %llu",
                                              (unsigned long long)a->offset);
            uint64_t avail = s->len - s->pos, skip = a->offset - pos;
            if (skip > avail) skip = avail;
            s->pos += (size_t)skip;
            pos += skip;
        }
        stream_reset(c);
        uint64_t want;
        while ((want = stream_want(c)) > 0) {
            if (b64) {
                int rc = CONSPH_OK;
                for (int q = 0; q < 4 && rc == CONSPH_OK; ++q) {
                    int d = rd_getc(s);
                    if (d < 0)
                        return s->failed ? CONSPH_EIO
                                         : fail_array(c, a,
                                                      "truncated: the appended data ends "
                                                      "inside this array");
                    rc = b64_char(c, a, d);
                    ++pos;
                }
                if (rc) return rc;
            } else {
                if (consph_rd_fill(s, 1) || s->pos == s->len)
                    return s->failed ? CONSPH_EIO
                                     : fail_array(c, a,
                                                  "truncated: the appended data ends "
                                                  "inside this array");
                uint64_t avail = s->len - s->pos;
                size_t take = (size_t)(want < avail ? want : avail);
                int rc = bytes_in(c, a, s->buf + s->pos, take);
                if (rc) return rc;
                s->pos += take;
                pos += take;
            }
        }
        int rc = array_done(c, a);
        if (rc) return rc;
    }
    return CONSPH_OK;
}

/* ---- document ---- */

static int open_root(vtu_ctx *c, const xml_tag *t)
{
    if (strcmp(t->name, "VTKFile") != 0)
        return fail_at(c, CONSPH_EFORMAT, t->line,
                       "not a VTK XML file: the root element is <%s>, expected <VTKFile>", t->name);
    const char *type = attr(t, "type");
    if (!type || strcmp(type, "UnstructuredGrid") != 0)
        return fail_at(c, CONSPH_EFORMAT, t->line,
                       "<VTKFile type=\"%.40s\">: only UnstructuredGrid (.vtu) files are read",
                       type ? type : "");
    const char *order = attr(t, "byte_order");
    if (order && strcmp(order, "LittleEndian") != 0 && strcmp(order, "BigEndian") != 0)
        return fail_at(c, CONSPH_EFORMAT, t->line,
                       "<VTKFile byte_order=\"%.40s\">: expected LittleEndian or BigEndian", order);
    c->big = order && !strcmp(order, "BigEndian");
    const char *ht = attr(t, "header_type");
    if (ht && strcmp(ht, "UInt32") != 0 && strcmp(ht, "UInt64") != 0)
        return fail_at(c, CONSPH_EFORMAT, t->line,
                       "<VTKFile header_type=\"%.40s\">: expected UInt32 or UInt64", ht);
    c->hsize = ht && !strcmp(ht, "UInt64") ? 8 : 4;
    const char *comp = attr(t, "compressor");
    if (comp && *comp && strcmp(comp, "vtkZLibDataCompressor") != 0)
        return fail_at(c, CONSPH_EFORMAT, t->line,
                       "<VTKFile compressor=\"%.60s\">: not supported; save the file uncompressed "
                       "or with zlib compression",
                       comp);
    c->zlib = comp && *comp;
    c->seen_root = 1;
    return CONSPH_OK;
}

static int handle_start(vtu_ctx *c, xml_tag *t)
{
    const char *parent = c->depth ? c->stack[c->depth - 1] : "";
    int rc;
    if (c->depth == 0) {
        if (c->seen_root)
            return fail_at(c, CONSPH_EFORMAT, t->line, "a second root element <%s>", t->name);
        if ((rc = open_root(c, t))) return rc;
    } else if (!strcmp(t->name, "Piece")) {
        if (strcmp(parent, "UnstructuredGrid") != 0)
            return fail_at(c, CONSPH_EFORMAT, t->line, "<Piece> outside <UnstructuredGrid>");
        if (++c->npieces > 1)
            return fail_at(c, CONSPH_EFORMAT, t->line,
                           "a second <Piece>: files of several pieces are not read; merge them "
                           "into one (e.g. ParaView's Merge Blocks)");
        uint64_t np;
        if (!attr(t, "NumberOfPoints"))
            return fail_at(c, CONSPH_EFORMAT, t->line, "<Piece> without NumberOfPoints");
        if ((rc = attr_count(c, t, "NumberOfPoints", 0, (uint64_t)UINT32_MAX - 2, &np))) return rc;
        c->npoints = (size_t)np;
        c->have_npoints = 1;
    } else if (!strcmp(t->name, "DataArray")) {
        vtu_array a;
        if ((rc = describe_array(c, t, parent, &a))) return rc;
        int keep = a.role != ROLE_SKIP;
        if (keep && a.format == FMT_APPENDED) {
            if (c->npending == VTU_MAX_ARRAYS)
                return fail_at(c, CONSPH_EFORMAT, t->line, "more than %d data arrays",
                               VTU_MAX_ARRAYS);
            c->pending[c->npending++] = a;
        }
        if (t->kind == TAG_START)
            return read_inline(c, keep && a.format != FMT_APPENDED ? &a : NULL);
        if (keep && a.format != FMT_APPENDED) {
            /* <DataArray .../> holds no values: fine only where none are expected */
            stream_reset(c);
            c->st.phase = PH_DONE;
            return array_done(c, &a);
        }
        return CONSPH_OK;
    }
    if (t->kind == TAG_START) {
        if (c->depth == XML_MAX_DEPTH)
            return fail_at(c, CONSPH_EFORMAT, t->line, "XML nested deeper than %d elements",
                           XML_MAX_DEPTH);
        snprintf(c->stack[c->depth], XML_NAME_MAX, "%s", t->name);
        c->stack_line[c->depth++] = t->line;
    }
    return CONSPH_OK;
}

int consph_rd_vtu(rd_src *s, const consph_read_options *opt, rd_set *set)
{
    vtu_ctx *c = calloc(1, sizeof *c);
    if (!c) return consph_fail(CONSPH_ENOMEM, "out of memory");
    c->s = s;
    c->set = set;
    c->opt = opt;
    c->line = 1;
    c->hsize = 4;
    int rc = CONSPH_OK, ch;
    /* Content check: XML starts with '<' after an optional byte-order mark and blanks. */
    if (rd_peek(s) == 0xEF) {
        rd_getc(s);
        if (rd_getc(s) != 0xBB || rd_getc(s) != 0xBF)
            rc = fail_at(c, CONSPH_EFORMAT, 1, "not an XML file");
    }
    while (rc == CONSPH_OK && (ch = rd_peek(s)) >= 0 && is_space(ch)) xgetc(c);
    if (rc == CONSPH_OK) {
        ch = rd_peek(s);
        if (ch < 0)
            rc = s->failed ? CONSPH_EIO
                           : consph_fail(CONSPH_EFORMAT,
                                         "%s: empty file; expected a VTK XML "
                                         "UnstructuredGrid (.vtu)",
                                         set->name);
        else if (ch != '<')
            rc = fail_at(c, CONSPH_EFORMAT, c->line,
                         "not an XML file (a CSV file named .vtu?); expected a VTK XML "
                         "UnstructuredGrid starting with '<'");
    }
    int done = 0;
    while (rc == CONSPH_OK && !done) {
        xml_tag *t = &c->tag;
        if ((rc = next_tag(c, t))) break;
        switch (t->kind) {
        case TAG_EOF:
            if (c->depth > 0)
                rc = fail_truncated(c);
            else if (!c->seen_root)
                rc = fail_at(c, CONSPH_EFORMAT, c->line, "no <VTKFile> element: not a VTU file");
            done = 1;
            break;
        case TAG_START:
        case TAG_EMPTY:
            if (!strcmp(t->name, "AppendedData") && c->depth == 1) {
                rc = read_appended(c, t);
                done = 1;
                break;
            }
            rc = handle_start(c, t);
            if (c->depth == 0 && t->kind == TAG_EMPTY) done = 1;
            break;
        case TAG_END:
            if (c->depth == 0 || strcmp(t->name, c->stack[c->depth - 1]) != 0) {
                rc = c->depth
                         ? fail_at(c, CONSPH_EFORMAT, t->line,
                                   "malformed XML: </%s> closes <%s> (opened on line %zu)", t->name,
                                   c->stack[c->depth - 1], c->stack_line[c->depth - 1])
                         : fail_at(c, CONSPH_EFORMAT, t->line,
                                   "malformed XML: </%s> without an opening tag", t->name);
                break;
            }
            if (--c->depth == 0) done = 1;
            break;
        }
    }
    if (rc == CONSPH_OK && c->npending > 0 && !c->appended_read)
        rc = fail_at(c, CONSPH_EFORMAT, c->line,
                     "arrays in format=\"appended\" but no <AppendedData> section (truncated "
                     "file?)");
    if (rc == CONSPH_OK && !c->npieces)
        rc = fail_at(c, CONSPH_EFORMAT, c->line, "no <Piece> in the file");
    if (rc == CONSPH_OK && !c->have_points)
        rc = fail_at(c, CONSPH_EFORMAT, c->line, "no <Points> data array in the <Piece>");
    if (rc == CONSPH_OK && c->npoints == 0)
        rc = fail_at(c, CONSPH_EFORMAT, c->line, "<Piece NumberOfPoints=\"0\">: no particles");
    if (rc == CONSPH_OK) {
        const char *fmt = c->points_format == FMT_ASCII    ? "ascii"
                          : c->points_format == FMT_BINARY ? "binary"
                          : c->appended_base64             ? "appended base64"
                                                           : "appended raw";
        snprintf(set->encoding, sizeof set->encoding, "%s%s", fmt, c->zlib ? ", zlib" : "");
    }
    stream_free(&c->st);
    free(c);
    return rc;
}
