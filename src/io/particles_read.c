/* Particle input: the byte source and columns shared by the readers, the CSV reader, and the
 * checks every format gets (dimension, box, wrapping, duplicates, positive volumes). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "io/read_internal.h"

size_t consph_rd_chunk = 0;

/* ---- byte source ---- */

int consph_rd_open_file(rd_src *s, const char *path)
{
    memset(s, 0, sizeof *s);
    s->name = path;
    s->chunk = consph_rd_chunk ? consph_rd_chunk : RD_DEFAULT_CHUNK;
    s->fp = fopen(path, "rb");
    if (!s->fp) return consph_fail(CONSPH_EIO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fileno(s->fp), &st) == 0) {
        if (S_ISDIR(st.st_mode)) {
            fclose(s->fp);
            s->fp = NULL;
            return consph_fail(CONSPH_EIO, "%s: cannot read: it is a directory", path);
        }
        if (st.st_size > 0) s->size_hint = (size_t)st.st_size;
    }
    return CONSPH_OK;
}

void consph_rd_open_mem(rd_src *s, const char *name, const void *data, size_t size)
{
    memset(s, 0, sizeof *s);
    s->name = name;
    s->chunk = consph_rd_chunk ? consph_rd_chunk : RD_DEFAULT_CHUNK;
    s->mem = data;
    s->mem_len = data ? size : 0;
    s->size_hint = s->mem_len;
}

void consph_rd_close(rd_src *s)
{
    if (s->fp) fclose(s->fp);
    free(s->buf);
    memset(s, 0, sizeof *s);
}

static size_t src_read(rd_src *s, unsigned char *dst, size_t n)
{
    if (s->fp) {
        size_t got = fread(dst, 1, n, s->fp);
        if (got == 0 && ferror(s->fp)) {
            s->failed = 1;
            consph_fail(CONSPH_EIO, "%s: read error: %s", s->name, strerror(errno));
        }
        return got;
    }
    size_t left = s->mem_len - s->mem_pos;
    if (n > left) n = left;
    if (n) memcpy(dst, s->mem + s->mem_pos, n);
    s->mem_pos += n;
    return n;
}

int consph_rd_fill(rd_src *s, size_t need)
{
    if (s->failed) return CONSPH_EIO;
    if (s->len - s->pos >= need) return CONSPH_OK;
    if (s->pos > 0) {
        memmove(s->buf, s->buf + s->pos, s->len - s->pos);
        s->len -= s->pos;
        s->pos = 0;
    }
    size_t want = need > s->chunk ? need : s->chunk;
    if (want > s->cap) {
        size_t cap = s->cap * 2 > want ? s->cap * 2 : want;
        unsigned char *b = realloc(s->buf, cap + 1);
        if (!b) {
            s->failed = 1;
            return consph_fail(CONSPH_ENOMEM, "%s: out of memory (a %zu-byte buffer)", s->name,
                               cap);
        }
        s->buf = b;
        s->cap = cap;
    }
    while (s->len < need && !s->eof) {
        size_t room = s->cap - s->len;
        if (room > s->chunk) room = s->chunk;
        size_t got = src_read(s, s->buf + s->len, room);
        if (s->failed) return CONSPH_EIO;
        if (got == 0) s->eof = 1;
        s->len += got;
    }
    return CONSPH_OK;
}

int consph_rd_getc_slow(rd_src *s)
{
    if (consph_rd_fill(s, 1) != CONSPH_OK || s->pos == s->len) return -1;
    return s->buf[s->pos++];
}

/* Longer lines are not particle rows: refuse them before they exhaust memory. */
#define RD_MAX_LINE ((size_t)16 << 20)
/* The particle spacing a file may have: h^(dim+2) of any h/Δs up to 100 stays a normal double. */
#define READ_SPACING_MIN 1e-50
#define READ_SPACING_MAX 1e50

char *consph_rd_line(rd_src *s, size_t *len)
{
    size_t scanned = 0;
    for (;;) {
        unsigned char *start = s->buf ? s->buf + s->pos : NULL;
        size_t avail = s->len - s->pos;
        unsigned char *nl = avail > scanned ? memchr(start + scanned, '\n', avail - scanned) : NULL;
        if (nl) {
            size_t n = (size_t)(nl - start);
            *nl = '\0';
            s->pos += n + 1;
            if (n > 0 && start[n - 1] == '\r') start[--n] = '\0';
            *len = n;
            return (char *)start;
        }
        scanned = avail;
        if (s->eof) {
            if (avail == 0) return NULL;
            start[avail] = '\0'; /* buf has cap + 1 bytes */
            s->pos = s->len;
            if (avail > 0 && start[avail - 1] == '\r') start[--avail] = '\0';
            *len = avail;
            return (char *)start;
        }
        if (avail >= RD_MAX_LINE) {
            s->failed = 1;
            consph_fail(CONSPH_EFORMAT, "%s: a line longer than %zu bytes: not a particle file",
                        s->name, RD_MAX_LINE);
            return NULL;
        }
        if (consph_rd_fill(s, avail + 1) != CONSPH_OK) return NULL;
    }
}

/* ---- columns ---- */

int consph_rd_push(rd_column *c, double v)
{
    if (c->n == c->cap) {
        size_t cap = c->cap ? 2 * c->cap : 1024;
        double *nv = realloc(c->v, cap * sizeof(double));
        if (!nv) return consph_fail(CONSPH_ENOMEM, "out of memory (%zu values)", cap);
        c->v = nv;
        c->cap = cap;
    }
    c->v[c->n++] = v;
    return CONSPH_OK;
}

static void column_free(rd_column *c)
{
    free(c->v);
    memset(c, 0, sizeof *c);
}

void consph_rd_set_free(rd_set *set)
{
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) column_free(&set->x[a]);
    for (int f = 0; f < set->nfields; ++f)
        for (int c = 0; c < RD_MAX_COMP; ++c) column_free(&set->fields[f].col[c]);
    free(set->skipped);
    set->skipped = NULL;
    set->nfields = 0;
}

int consph_rd_streq_nocase(const char *a, const char *b)
{
    for (; *a && *b; ++a, ++b) {
        int ca = (unsigned char)*a, cb = (unsigned char)*b;
        if (ca >= 'A' && ca <= 'Z') ca += 'a' - 'A';
        if (cb >= 'A' && cb <= 'Z') cb += 'a' - 'A';
        if (ca != cb) return 0;
    }
    return *a == *b;
}

const char *consph_volume_origin_name(consph_volume_origin origin)
{
    switch (origin) {
    case CONSPH_VOLUMES_COLUMN:
        return "file column 'volume'";
    case CONSPH_VOLUMES_MASS_RHO:
        return "file columns m/rho";
    default:
        return "none in the file";
    }
}

/* ---- the checks common to every format ---- */

static const char axis_letter[CONSPH_MAX_DIM] = {'x', 'y', 'z'};

static size_t csv_line_of_row(const rd_set *set, size_t row)
{
    size_t line = set->first_row_line + row;
    for (size_t k = 0; k < set->nskipped; ++k) {
        if (set->skipped[k] > line) break;
        ++line;
    }
    return line;
}

/* "FILE:LINE" for a CSV row, "FILE:LINE: point i" for VTU (LINE: the data array's element). */
static void locate(const rd_set *set, size_t i, int field, char *buf, size_t size)
{
    if (set->format == CONSPH_FORMAT_CSV)
        snprintf(buf, size, "%s:%zu", set->name, csv_line_of_row(set, i));
    else
        snprintf(buf, size, "%s:%zu: point %zu", set->name,
                 field < 0 ? set->points_line : set->field_line[field], i);
}

/* How another particle is named in a message about a pair. */
static void name_other(const rd_set *set, size_t i, char *buf, size_t size)
{
    if (set->format == CONSPH_FORMAT_CSV)
        snprintf(buf, size, "the particle on line %zu", csv_line_of_row(set, i));
    else
        snprintf(buf, size, "point %zu", i);
}

static void position_text(double *const *x, int dim, size_t i, char *buf, size_t size)
{
    size_t used = 0;
    buf[0] = '\0';
    for (int a = 0; a < dim && used < size; ++a) {
        int w = snprintf(buf + used, size - used, "%s%c = %.17g", a ? ", " : "", axis_letter[a],
                         x[a][i]);
        if (w < 0) break;
        used += (size_t)w;
    }
}

static uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* Exact equality of positions through a hash table of particle indices (4 bytes per slot,
 * at most 3/4 full): O(N) time and memory. Returns 1 with the pair (first, second) when two
 * particles coincide, 0 when none do, or an error code < 0. */
static int find_duplicate(double *const *x, int dim, size_t n, size_t *first, size_t *second)
{
    size_t size = 1;
    while (size < n + n / 3 + 1) size <<= 1;
    uint32_t *slot = calloc(size, sizeof *slot);
    if (!slot) return -1;
    size_t mask = size - 1;
    int found = 0;
    for (size_t i = 0; i < n && !found; ++i) {
        uint64_t h = 0x9e3779b97f4a7c15ULL;
        for (int a = 0; a < dim; ++a) {
            double v = x[a][i] == 0.0 ? 0.0 : x[a][i]; /* -0 and +0 are the same place */
            uint64_t bits;
            memcpy(&bits, &v, sizeof bits);
            h = mix64(h ^ bits);
        }
        for (size_t k = (size_t)h & mask;; k = (k + 1) & mask) {
            if (slot[k] == 0) {
                slot[k] = (uint32_t)(i + 1);
                break;
            }
            size_t j = slot[k] - 1;
            int same = 1;
            for (int a = 0; a < dim && same; ++a) same = x[a][j] == x[a][i];
            if (same) {
                *first = j;
                *second = i;
                found = 1;
                break;
            }
        }
    }
    free(slot);
    return found;
}

static int find_field(const rd_set *set, const char *name)
{
    for (int f = 0; f < set->nfields; ++f)
        if (consph_rd_streq_nocase(set->fields[f].name, name)) return f;
    return -1;
}

/* Shrinks a column to exactly n values and takes its storage. */
static double *take_column(rd_column *c, size_t n)
{
    double *v = c->v;
    if (c->cap > n) {
        double *s = realloc(v, n * sizeof(double));
        if (s) v = s;
    }
    c->v = NULL;
    c->n = c->cap = 0;
    return v;
}

static int check_positive(const rd_set *set, int f, size_t n, const char *what)
{
    if (f < 0) return CONSPH_OK;
    const rd_field *fl = &set->fields[f];
    if (fl->ncomp != 1)
        return consph_fail(CONSPH_EFORMAT, "%s: '%s' has %d components; it must be a scalar",
                           set->name, fl->name, fl->ncomp);
    for (size_t i = 0; i < n; ++i)
        if (!(fl->col[0].v[i] > 0.0)) {
            char at[512];
            locate(set, i, f, at, sizeof at);
            return consph_fail(CONSPH_EFORMAT, "%s: %s = %.17g is not positive", at, what,
                               fl->col[0].v[i]);
        }
    return CONSPH_OK;
}

int consph_rd_finish(rd_set *set, const consph_read_options *opt, consph_particles *p,
                     consph_read_report *rep)
{
    memset(p, 0, sizeof *p);
    const char *name = set->name;
    size_t n = set->x[0].n;
    char at[512], other[256], pos[256];
    if (n == 0) return consph_fail(CONSPH_EFORMAT, "%s: no particles", name);
    if (n >= UINT32_MAX)
        return consph_fail(CONSPH_EINVAL, "%s: more than %u particles", name, UINT32_MAX - 1);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a)
        if (set->x[a].n != 0 && set->x[a].n != n)
            return consph_fail(CONSPH_EFORMAT, "%s: coordinate %c has %zu values, x has %zu", name,
                               axis_letter[a], set->x[a].n, n);

    /* Dimension: the file's structure, checked against the caller's. */
    int dim = set->dim;
    if (opt && opt->dim) {
        if (opt->dim < 1 || opt->dim > CONSPH_MAX_DIM)
            return consph_fail(CONSPH_EINVAL, "%s: dimension %d is not 1, 2 or 3", name, opt->dim);
        if (dim && dim != opt->dim)
            return consph_fail(CONSPH_EINVAL,
                               "%s:%zu: %s makes the particles %dD, but %dD particles were asked "
                               "for",
                               name, set->dim_line, set->dim_what, dim, opt->dim);
        dim = opt->dim;
    }
    if (!dim) {
        /* Points in VTU always have three coordinates: the last axis with one non-zero value
         * is the dimension. */
        dim = 1;
        for (int a = 1; a < CONSPH_MAX_DIM; ++a)
            for (size_t i = 0; i < set->x[a].n && dim <= a; ++i)
                if (set->x[a].v[i] != 0.0) dim = a + 1;
    }
    for (int a = 0; a < dim; ++a)
        if (set->x[a].n != n)
            return consph_fail(CONSPH_EFORMAT,
                               "%s: the particles are %dD but have no %c coordinate", name, dim,
                               axis_letter[a]);
    for (int a = dim; a < CONSPH_MAX_DIM; ++a)
        for (size_t i = 0; i < set->x[a].n; ++i)
            if (set->x[a].v[i] != 0.0) {
                locate(set, i, -1, at, sizeof at);
                return consph_fail(
                    CONSPH_EINVAL,
                    "%s: %c = %.17g, but the particles are %dD (%s), so it must be 0", at,
                    axis_letter[a], set->x[a].v[i], dim,
                    opt && opt->dim ? "as asked for" : "from the file's box");
            }

    /* Box and periodicity: the caller's, else the file's. */
    consph_box box;
    memset(&box, 0, sizeof box);
    box.dim = dim;
    int box_from_file = 0, periodic_from_file = 0;
    if (opt && opt->have_box) {
        if (opt->box.dim != dim)
            return consph_fail(CONSPH_EINVAL,
                               "%s: the given box has %d axes, the particles are %dD", name,
                               opt->box.dim, dim);
        for (int a = 0; a < dim; ++a) {
            box.lo[a] = opt->box.lo[a];
            box.hi[a] = opt->box.hi[a];
        }
    } else if (set->have_box) {
        if (set->box_dim != dim)
            return consph_fail(CONSPH_EINVAL,
                               "%s: the file's box has %d axes, the particles are %dD", name,
                               set->box_dim, dim);
        for (int a = 0; a < dim; ++a) {
            box.lo[a] = set->lo[a];
            box.hi[a] = set->hi[a];
        }
        box_from_file = 1;
    } else {
        return consph_fail(CONSPH_EINVAL,
                           "%s: the file has no box (a CSV '# box lo:hi ...' comment or a VTU "
                           "FieldData array 'box'); give the box explicitly",
                           name);
    }
    if (opt && opt->have_periodic) {
        for (int a = 0; a < dim; ++a) box.periodic[a] = opt->periodic[a] != 0;
    } else if (set->have_periodic) {
        if (set->periodic_dim != dim)
            return consph_fail(CONSPH_EINVAL,
                               "%s: the file's periodicity has %d axes, the particles are %dD",
                               name, set->periodic_dim, dim);
        for (int a = 0; a < dim; ++a) box.periodic[a] = set->periodic[a] != 0;
        periodic_from_file = 1;
    }
    if (consph_box_check(&box) != CONSPH_OK)
        return consph_fail(box_from_file ? CONSPH_EFORMAT : CONSPH_EINVAL, "%s: %s box: %s", name,
                           box_from_file ? "the file's" : "the given", consph_last_error());
    /* Lengths, volume and the spacing derived from them must be usable numbers. */
    double volume = consph_box_volume(&box);
    double spacing = set->have_spacing ? set->spacing : pow(volume / (double)n, 1.0 / dim);
    for (int a = 0; a < dim; ++a)
        if (!isfinite(consph_box_length(&box, a))) volume = INFINITY;
    /* Kernels divide by h^(dim+2) (Laplacians in 3D: h^5): a spacing far from 1 overflows them
     * after the work has begun, so it is refused here. */
    if (!(isfinite(volume) && volume > 0 && isfinite(spacing) && spacing >= READ_SPACING_MIN &&
          spacing <= READ_SPACING_MAX))
        return consph_fail(box_from_file ? CONSPH_EFORMAT : CONSPH_EINVAL,
                           "%s: %s box is too large or too small for double precision (volume "
                           "%g, spacing %g; allowed: spacing in [%g, %g])",
                           name, box_from_file ? "the file's" : "the given", volume, spacing,
                           READ_SPACING_MIN, READ_SPACING_MAX);

    /* Volumes, masses and densities, when present, must be positive scalars. */
    int fvol = find_field(set, "volume"), fm = find_field(set, "m"),
        fmass = find_field(set, "mass"), frho = find_field(set, "rho");
    if (fm >= 0 && fmass >= 0)
        return consph_fail(CONSPH_EFORMAT, "%s: both 'm' and 'mass' are given; keep one", name);
    if (fm < 0) fm = fmass;
    int rc;
    if ((rc = check_positive(set, fvol, n, "volume"))) return rc;
    if ((rc = check_positive(set, fm, n, "m"))) return rc;
    if ((rc = check_positive(set, frho, n, "rho"))) return rc;
    for (int f = 0; f < set->nfields; ++f)
        for (int c = 0; c < set->fields[f].ncomp; ++c)
            if (set->fields[f].col[c].n != n)
                return consph_fail(CONSPH_EFORMAT, "%s: '%s' has %zu values for %zu particles",
                                   name, set->fields[f].name, set->fields[f].col[c].n, n);

    /* Inside the box: an error across a wall, a wrap across a periodic boundary. Only values
     * outside [lo, hi) move, so particles already inside keep every bit. */
    size_t wrapped = 0;
    for (size_t i = 0; i < n; ++i) {
        int moved = 0;
        for (int a = 0; a < dim; ++a) {
            double v = set->x[a].v[i], lo = box.lo[a], hi = box.hi[a];
            if (box.periodic[a]) {
                if (v >= lo && v < hi) continue;
                double len = hi - lo, s = fmod(v - lo, len);
                if (s < 0.0) s += len;
                if (!(s < len)) s = 0.0;
                /* lo + s may round up to hi, which belongs to the next period */
                set->x[a].v[i] = lo + s < hi ? lo + s : lo;
                moved = 1;
            } else if (v < lo || v > hi) {
                locate(set, i, -1, at, sizeof at);
                return consph_fail(CONSPH_EFORMAT,
                                   "%s: particle outside the box: %c = %.17g is not in [%.17g, "
                                   "%.17g] and axis %c is not periodic",
                                   at, axis_letter[a], v, lo, hi, axis_letter[a]);
            }
        }
        wrapped += (size_t)moved;
    }

    double *xs[CONSPH_MAX_DIM] = {set->x[0].v, set->x[1].v, set->x[2].v};
    size_t first = 0, second = 0;
    int dup = find_duplicate(xs, dim, n, &first, &second);
    if (dup < 0) return consph_fail(CONSPH_ENOMEM, "%s: out of memory (duplicate check)", name);
    if (dup) {
        locate(set, second, -1, at, sizeof at);
        name_other(set, first, other, sizeof other);
        position_text(xs, dim, second, pos, sizeof pos);
        return consph_fail(CONSPH_EFORMAT, "%s: particle at the same position as %s (%s)%s", at,
                           other, pos, wrapped ? " after wrapping into the periodic box" : "");
    }

    /* Move the columns into the particle set. */
    int nout = set->nfields + (fvol < 0 && fm >= 0 && frho >= 0);
    if (nout > CONSPH_MAX_FIELDS)
        return consph_fail(CONSPH_EFORMAT, "%s: more than %d fields", name, CONSPH_MAX_FIELDS);
    p->dim = dim;
    p->n = n;
    p->cap = n;
    p->box = box;
    for (int a = 0; a < dim; ++a) p->x[a] = take_column(&set->x[a], n);
    for (int f = 0; f < set->nfields; ++f) {
        rd_field *fl = &set->fields[f];
        consph_field *out = &p->fields[p->nfields];
        snprintf(out->name, sizeof out->name, "%s", f == fm ? "mass" : fl->name);
        if (f == fvol) snprintf(out->name, sizeof out->name, "volume");
        if (f == frho) snprintf(out->name, sizeof out->name, "rho");
        out->ncomp = fl->ncomp;
        if (fl->ncomp == 1) {
            out->data = take_column(&fl->col[0], n);
        } else {
            out->data = malloc(n * (size_t)fl->ncomp * sizeof(double));
            if (!out->data) {
                consph_particles_free(p);
                return consph_fail(CONSPH_ENOMEM, "%s: out of memory", name);
            }
            for (int c = 0; c < fl->ncomp; ++c) {
                memcpy(out->data + (size_t)c * n, fl->col[c].v, n * sizeof(double));
                column_free(&fl->col[c]);
            }
        }
        p->nfields++;
    }
    consph_volume_origin origin = CONSPH_VOLUMES_NONE;
    if (fvol >= 0) {
        origin = CONSPH_VOLUMES_COLUMN;
    } else if (fm >= 0 && frho >= 0) {
        const double *m = consph_particles_find(p, "mass")->data;
        const double *rho = consph_particles_find(p, "rho")->data;
        double *vol = consph_particles_field(p, "volume", 1);
        if (!vol) {
            consph_particles_free(p);
            return consph_fail(CONSPH_ENOMEM, "%s: out of memory", name);
        }
        for (size_t i = 0; i < n; ++i) {
            vol[i] = m[i] / rho[i];
            if (!(vol[i] > 0 && isfinite(vol[i]))) {
                double mi = m[i], rhoi = rho[i];
                locate(set, i, fm, at, sizeof at);
                consph_particles_free(p);
                return consph_fail(CONSPH_EFORMAT,
                                   "%s: the volume m/rho = %g/%g is not a positive double", at, mi,
                                   rhoi);
            }
        }
        origin = CONSPH_VOLUMES_MASS_RHO;
    }
    p->spacing = spacing;
    if (rep) {
        rep->format = set->format;
        snprintf(rep->encoding, sizeof rep->encoding, "%s", set->encoding);
        rep->box_from_file = box_from_file;
        rep->periodic_from_file = periodic_from_file;
        rep->spacing_from_file = set->have_spacing;
        rep->wrapped = wrapped;
        rep->volumes = origin;
        rep->has_mass = fm >= 0;
        rep->has_time = set->have_time;
        rep->time = set->have_time ? set->time : 0.0;
        memset(&rep->file_box, 0, sizeof rep->file_box);
        rep->file_box.dim = dim;
        rep->file_has_box = set->have_box && set->box_dim == dim;
        rep->file_has_periodic = set->have_periodic && set->periodic_dim == dim;
        for (int a = 0; a < dim; ++a) {
            rep->file_box.lo[a] = rep->file_has_box ? set->lo[a] : 0.0;
            rep->file_box.hi[a] = rep->file_has_box ? set->hi[a] : 0.0;
            rep->file_box.periodic[a] = rep->file_has_periodic && set->periodic[a];
        }
    }
    return CONSPH_OK;
}

/* ---- CSV ---- */

#define CSV_MAX_COLUMNS 256

typedef struct csv_column {
    rd_column *dst;
    char label[40]; /* the header name, shortened for messages */
} csv_column;

static char *skip_blanks(char *t)
{
    while (*t == ' ' || *t == '\t') ++t;
    return t;
}

/* Trims blanks (and one pair of double quotes around a header name) in place. */
static char *trim(char *t, int unquote)
{
    t = skip_blanks(t);
    size_t n = strlen(t);
    while (n > 0 && (t[n - 1] == ' ' || t[n - 1] == '\t')) t[--n] = '\0';
    if (unquote && n >= 2 && t[0] == '"' && t[n - 1] == '"') {
        t[n - 1] = '\0';
        ++t;
    }
    return t;
}

/* Quotes at most 40 characters of untrusted text for a message. */
static const char *shown(const char *t, char *buf, size_t size)
{
    size_t n = 0;
    for (; t[n] && n + 4 < size && n < 40; ++n) buf[n] = (t[n] >= 32 && t[n] < 127) ? t[n] : '?';
    if (t[n] && n + 4 < size) {
        memcpy(buf + n, "...", 3);
        n += 3;
    }
    buf[n] = '\0';
    return buf;
}

static int parse_double(const char *t, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(t, &end);
    if (end == t || *end != '\0') return -1;
    if (!isfinite(v)) return -2;
    *out = v;
    return 0;
}

/* `# key values...` before the header row. Unknown keys are free text. */
static int csv_meta(rd_set *set, char *t, size_t ln, int *declared_dim)
{
    char *save = NULL, buf[64];
    char *key = strtok_r(t, " \t", &save);
    if (!key) return CONSPH_OK;
    if (strcmp(key, "dim") == 0 || strcmp(key, "n") == 0 || strcmp(key, "spacing") == 0) {
        char *v = strtok_r(NULL, " \t", &save);
        char *extra = v ? strtok_r(NULL, " \t", &save) : NULL;
        double d = 0;
        if (!v || extra || parse_double(v, &d) != 0 || d < 0)
            return consph_fail(CONSPH_EFORMAT,
                               "%s:%zu: comment header '# %s': expected one non-negative number, "
                               "got '%s'",
                               set->name, ln, key, v ? shown(v, buf, sizeof buf) : "");
        if (strcmp(key, "dim") == 0) {
            if (d != 1 && d != 2 && d != 3)
                return consph_fail(CONSPH_EFORMAT,
                                   "%s:%zu: comment header '# dim': %s is not 1, 2 or 3", set->name,
                                   ln, shown(v, buf, sizeof buf));
            *declared_dim = (int)d;
        } else if (strcmp(key, "n") == 0) {
            if (d != floor(d) || d > 1e15)
                return consph_fail(CONSPH_EFORMAT,
                                   "%s:%zu: comment header '# n': %s is not a particle count",
                                   set->name, ln, shown(v, buf, sizeof buf));
            set->have_declared_n = 1;
            set->declared_n = (size_t)d;
        } else if (d > 0) { /* consph writes spacing 0 when it is unknown */
            set->have_spacing = 1;
            set->spacing = d;
        }
        return CONSPH_OK;
    }
    if (strcmp(key, "box") == 0) {
        int k = 0;
        for (char *v = strtok_r(NULL, " \t", &save); v; v = strtok_r(NULL, " \t", &save), ++k) {
            char *colon = strchr(v, ':');
            double lo = 0, hi = 0;
            if (k == CONSPH_MAX_DIM || !colon)
                return consph_fail(CONSPH_EFORMAT,
                                   "%s:%zu: comment header '# box': expected lo:hi for each of at "
                                   "most 3 axes, got '%s'",
                                   set->name, ln, shown(v, buf, sizeof buf));
            *colon = '\0';
            if (parse_double(v, &lo) != 0 || parse_double(colon + 1, &hi) != 0 || !(lo < hi)) {
                *colon = ':';
                return consph_fail(CONSPH_EFORMAT,
                                   "%s:%zu: comment header '# box': '%s' is not lo:hi with finite "
                                   "lo < hi",
                                   set->name, ln, shown(v, buf, sizeof buf));
            }
            set->lo[k] = lo;
            set->hi[k] = hi;
        }
        if (k == 0)
            return consph_fail(CONSPH_EFORMAT, "%s:%zu: comment header '# box' has no axes",
                               set->name, ln);
        set->have_box = 1;
        set->box_dim = k;
        return CONSPH_OK;
    }
    if (strcmp(key, "periodic") == 0) {
        int k = 0;
        for (char *v = strtok_r(NULL, " \t", &save); v; v = strtok_r(NULL, " \t", &save), ++k) {
            if (k == CONSPH_MAX_DIM || (strcmp(v, "0") != 0 && strcmp(v, "1") != 0))
                return consph_fail(CONSPH_EFORMAT,
                                   "%s:%zu: comment header '# periodic': expected 0 or 1 for each "
                                   "of at most 3 axes, got '%s'",
                                   set->name, ln, shown(v, buf, sizeof buf));
            set->periodic[k] = v[0] == '1';
        }
        if (k == 0)
            return consph_fail(CONSPH_EFORMAT, "%s:%zu: comment header '# periodic' has no axes",
                               set->name, ln);
        set->have_periodic = 1;
        set->periodic_dim = k;
    }
    return CONSPH_OK;
}

static const char csv_expected[] =
    "expected a header row naming the columns x,y (2D) or x,y,z (3D) (x alone with '# dim 1'), "
    "optionally volume, m, rho and other fields";

/* Component k of a group name_0, name_1, ...: the length of `name` before "_k", or 0. */
static size_t component_base(const char *name, int k)
{
    char suffix[16];
    snprintf(suffix, sizeof suffix, "_%d", k);
    size_t n = strlen(name), s = strlen(suffix);
    if (n <= s || strcmp(name + n - s, suffix) != 0) return 0;
    return n - s;
}

static int csv_header(rd_set *set, const consph_read_options *opt, char *line, size_t ln,
                      int declared_dim, csv_column *cols, int *ncols_out)
{
    char *names[CSV_MAX_COLUMNS], buf[64], found[256];
    int ncols = 0;
    for (char *t = line;;) {
        char *comma = strchr(t, ',');
        if (comma) *comma = '\0';
        if (ncols == CSV_MAX_COLUMNS)
            return consph_fail(CONSPH_EFORMAT, "%s:%zu: more than %d columns", set->name, ln,
                               CSV_MAX_COLUMNS);
        names[ncols++] = trim(t, 1);
        if (!comma) break;
        t = comma + 1;
    }
    double probe;
    if (parse_double(names[0], &probe) == 0)
        return consph_fail(CONSPH_EFORMAT,
                           "%s:%zu: no header row: the first row starts with the "
                           "number %s; %s",
                           set->name, ln, shown(names[0], buf, sizeof buf), csv_expected);
    found[0] = '\0';
    for (int c = 0; c < ncols; ++c) {
        size_t used = strlen(found);
        snprintf(found + used, sizeof found - used, "%s%s", c ? "," : "",
                 shown(names[c], buf, sizeof buf));
    }
    int coord[CONSPH_MAX_DIM] = {-1, -1, -1};
    static const char *const coord_name[CONSPH_MAX_DIM] = {"x", "y", "z"};
    for (int c = 0; c < ncols; ++c) {
        if (names[c][0] == '\0')
            return consph_fail(CONSPH_EFORMAT,
                               "%s:%zu: column %d of the header row has no name; %s", set->name, ln,
                               c + 1, csv_expected);
        for (int d = 0; d < c; ++d)
            if (consph_rd_streq_nocase(names[c], names[d]))
                return consph_fail(CONSPH_EFORMAT,
                                   "%s:%zu: the header row names column '%s' twice (columns %d "
                                   "and %d)",
                                   set->name, ln, shown(names[c], buf, sizeof buf), d + 1, c + 1);
        for (int a = 0; a < CONSPH_MAX_DIM; ++a)
            if (consph_rd_streq_nocase(names[c], coord_name[a])) coord[a] = c;
    }
    /* The dimension is what the caller or the comment header says, else what the coordinate
     * columns give; a file without y is taken as a 2D file missing it (a misspelled header)
     * unless 1D is declared. */
    int present = coord[2] >= 0 ? 3 : coord[1] >= 0 ? 2 : 1;
    int dim = present == 1 ? 2 : present;
    char said[96] = "";
    int code = CONSPH_EFORMAT;
    if (opt && opt->dim) {
        dim = opt->dim;
        snprintf(said, sizeof said, "%dD particles were asked for", dim);
        code = CONSPH_EINVAL;
    } else if (declared_dim) {
        dim = declared_dim;
        snprintf(said, sizeof said, "the comment header says '# dim %d'", dim);
    } else if (set->have_box) {
        dim = set->box_dim;
        snprintf(said, sizeof said, "the comment header's '# box' has %d axes", dim);
    }
    if (present > dim)
        return consph_fail(code,
                           "%s:%zu: the header row has a '%s' column (found: %s): %dD particles, "
                           "but %s",
                           set->name, ln, coord_name[present - 1], found, present, said);
    for (int a = 0; a < dim; ++a)
        if (coord[a] < 0)
            return consph_fail(
                code, "%s:%zu: the header row has no column '%s' (found: %s)%s%s; %s", set->name,
                ln, coord_name[a], found, said[0] ? ", but " : "", said, csv_expected);
    set->dim = dim;
    set->dim_what = "the header row";
    set->dim_line = ln;

    for (int a = 0; a < dim; ++a) cols[coord[a]].dst = &set->x[a];
    for (int c = 0; c < ncols; ++c) {
        if (cols[c].dst) continue;
        /* name_0, name_1, ... in consecutive columns form one field with that many components,
         * as the CSV writer spells multi-component fields. */
        int m = 1;
        size_t base = component_base(names[c], 0);
        if (base > 0) {
            while (c + m < ncols && !cols[c + m].dst && m < RD_MAX_COMP &&
                   component_base(names[c + m], m) == base &&
                   strncmp(names[c + m], names[c], base) == 0)
                ++m;
        }
        if (m == 1) base = strlen(names[c]);
        if (base >= CONSPH_FIELD_NAME_MAX)
            return consph_fail(CONSPH_EFORMAT,
                               "%s:%zu: column name '%s' is longer than %d characters", set->name,
                               ln, shown(names[c], buf, sizeof buf), CONSPH_FIELD_NAME_MAX - 1);
        if (set->nfields == CONSPH_MAX_FIELDS - 1)
            return consph_fail(CONSPH_EFORMAT, "%s:%zu: more than %d fields", set->name, ln,
                               CONSPH_MAX_FIELDS - 1);
        rd_field *f = &set->fields[set->nfields++];
        memcpy(f->name, names[c], base);
        f->name[base] = '\0';
        f->ncomp = m;
        for (int k = 0; k < m; ++k) cols[c + k].dst = &f->col[k];
        c += m - 1;
    }
    for (int c = 0; c < ncols; ++c) shown(names[c], cols[c].label, sizeof cols[c].label);
    *ncols_out = ncols;
    return CONSPH_OK;
}

static int csv_row(rd_set *set, char *line, size_t ln, const csv_column *cols, int ncols)
{
    char buf[64];
    int nvalues = 1;
    for (const char *t = line; (t = strchr(t, ',')) != NULL; ++t) ++nvalues;
    if (nvalues != ncols)
        return consph_fail(CONSPH_EFORMAT,
                           "%s:%zu: %s: the row has %d value%s but the header row has %d columns",
                           set->name, ln, nvalues < ncols ? "short row" : "extra column", nvalues,
                           nvalues == 1 ? "" : "s", ncols);
    char *t = line;
    for (int c = 0; c < ncols; ++c) {
        char *comma = strchr(t, ',');
        if (comma) *comma = '\0';
        char *v = trim(t, 0);
        double d = 0;
        if (*v == '\0')
            return consph_fail(CONSPH_EFORMAT, "%s:%zu: column '%s' is empty", set->name, ln,
                               cols[c].label);
        int bad = parse_double(v, &d);
        if (bad == -1)
            return consph_fail(CONSPH_EFORMAT, "%s:%zu: column '%s': '%s' is not a number",
                               set->name, ln, cols[c].label, shown(v, buf, sizeof buf));
        if (bad == -2)
            return consph_fail(CONSPH_EFORMAT, "%s:%zu: column '%s': '%s' is not a finite number",
                               set->name, ln, cols[c].label, shown(v, buf, sizeof buf));
        int rc = consph_rd_push(cols[c].dst, d);
        if (rc) return rc;
        if (comma) t = comma + 1;
    }
    return CONSPH_OK;
}

static int remember_skipped(rd_set *set, size_t ln)
{
    if (set->nskipped == set->capskipped) {
        size_t cap = set->capskipped ? 2 * set->capskipped : 16;
        size_t *s = realloc(set->skipped, cap * sizeof *s);
        if (!s) return consph_fail(CONSPH_ENOMEM, "out of memory");
        set->skipped = s;
        set->capskipped = cap;
    }
    set->skipped[set->nskipped++] = ln;
    return CONSPH_OK;
}

int consph_rd_csv(rd_src *s, const consph_read_options *opt, rd_set *set)
{
    csv_column *cols = calloc(CSV_MAX_COLUMNS, sizeof *cols);
    if (!cols) return consph_fail(CONSPH_ENOMEM, "out of memory");
    int ncols = 0, header = 0, declared_dim = 0, rc = CONSPH_OK;
    size_t ln = 0, len, header_line = 0, rows = 0;
    char *line;
    while (rc == CONSPH_OK && (line = consph_rd_line(s, &len)) != NULL) {
        ++ln;
        if (ln == 1 && len >= 3 && memcmp(line, "\xEF\xBB\xBF", 3) == 0) {
            line += 3;
            len -= 3;
        }
        if (memchr(line, '\0', len)) {
            rc = consph_fail(CONSPH_EFORMAT,
                             "%s:%zu: binary data (a NUL byte): not a CSV text file", s->name, ln);
            break;
        }
        char *t = skip_blanks(line);
        if (!header) {
            if (*t == '\0') continue;
            if (*t == '#') {
                rc = csv_meta(set, t + 1, ln, &declared_dim);
                continue;
            }
            if (*t == '<') {
                rc = consph_fail(CONSPH_EFORMAT, "%s:%zu: this is XML (a .vtu file?), not CSV; %s",
                                 s->name, ln, csv_expected);
                break;
            }
            rc = csv_header(set, opt, line, ln, declared_dim, cols, &ncols);
            header = 1;
            header_line = ln;
            continue;
        }
        if (*t == '\0' || *t == '#') {
            if (rows > 0) rc = remember_skipped(set, ln);
            continue;
        }
        if (rows == 0) set->first_row_line = ln;
        rc = csv_row(set, line, ln, cols, ncols);
        ++rows;
    }
    free(cols);
    if (rc) return rc;
    if (s->failed) return CONSPH_EIO;
    if (!header) {
        if (ln == 0)
            return consph_fail(CONSPH_EFORMAT, "%s: empty file; %s", s->name, csv_expected);
        return consph_fail(CONSPH_EFORMAT, "%s:%zu: no header row, only comments; %s", s->name, ln,
                           csv_expected);
    }
    if (rows == 0)
        return consph_fail(CONSPH_EFORMAT, "%s:%zu: a header row but no particles", s->name,
                           header_line);
    if (set->have_declared_n && set->declared_n != rows)
        return consph_fail(CONSPH_EFORMAT,
                           "%s:%zu: the comment header says '# n %zu' but the file has %zu "
                           "particle rows (truncated?)",
                           s->name, ln, set->declared_n, rows);
    return CONSPH_OK;
}

/* ---- entry points ---- */

static int read_source(rd_src *s, consph_particle_format fmt, const consph_read_options *opt,
                       consph_particles *p, consph_read_report *rep)
{
    rd_set *set = calloc(1, sizeof *set);
    if (!set) return consph_fail(CONSPH_ENOMEM, "out of memory");
    set->name = s->name;
    set->format = fmt;
    int rc = fmt == CONSPH_FORMAT_CSV ? consph_rd_csv(s, opt, set) : consph_rd_vtu(s, opt, set);
    if (rc == CONSPH_OK) rc = consph_rd_finish(set, opt, p, rep);
    consph_rd_set_free(set);
    free(set);
    return rc;
}

int consph_read_particles(const char *path, const consph_read_options *opt, consph_particles *p,
                          consph_read_report *rep)
{
    memset(p, 0, sizeof *p);
    if (rep) memset(rep, 0, sizeof *rep);
    consph_particle_format fmt;
    int rc = consph_particle_format_from_path(path, &fmt);
    if (rc) return rc;
    rd_src s;
    if ((rc = consph_rd_open_file(&s, path))) return rc;
    rc = read_source(&s, fmt, opt, p, rep);
    consph_rd_close(&s);
    return rc;
}

int consph_read_particles_mem(const char *name, consph_particle_format fmt, const void *data,
                              size_t size, const consph_read_options *opt, consph_particles *p,
                              consph_read_report *rep)
{
    memset(p, 0, sizeof *p);
    if (rep) memset(rep, 0, sizeof *rep);
    if (fmt != CONSPH_FORMAT_CSV && fmt != CONSPH_FORMAT_VTU)
        return consph_fail(CONSPH_EINVAL, "%s: unknown particle format %d", name, (int)fmt);
    rd_src s;
    consph_rd_open_mem(&s, name, data, size);
    int rc = read_source(&s, fmt, opt, p, rep);
    consph_rd_close(&s);
    return rc;
}
