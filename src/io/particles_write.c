#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <zlib.h>

#include "consph/io.h"
#include "io/source_internal.h"

static const char *axis_name[CONSPH_MAX_DIM] = {"x", "y", "z"};

int consph_particle_format_from_path(const char *path, consph_particle_format *fmt)
{
    const char *dot = strrchr(path, '.');
    if (dot && strcmp(dot, ".vtu") == 0) {
        *fmt = CONSPH_FORMAT_VTU;
        return CONSPH_OK;
    }
    if (dot && strcmp(dot, ".csv") == 0) {
        *fmt = CONSPH_FORMAT_CSV;
        return CONSPH_OK;
    }
    return consph_fail(CONSPH_EINVAL, "'%s': unknown particle file extension; allowed: .vtu, .csv",
                       path);
}

/* Component name of a multi-component field in CSV: name_0, name_1, ... */
static void write_csv(FILE *fp, const consph_particles *p)
{
    const consph_box *b = &p->box;
    fprintf(fp, "# consph particles\n# dim %d\n# n %zu\n# spacing %.17g\n# box", p->dim, p->n,
            p->spacing);
    for (int a = 0; a < p->dim; ++a) fprintf(fp, " %.17g:%.17g", b->lo[a], b->hi[a]);
    fprintf(fp, "\n# periodic");
    for (int a = 0; a < p->dim; ++a) fprintf(fp, " %d", b->periodic[a] ? 1 : 0);
    fprintf(fp, "\n");
    for (int a = 0; a < p->dim; ++a) fprintf(fp, "%s%s", a ? "," : "", axis_name[a]);
    for (int f = 0; f < p->nfields; ++f) {
        const consph_field *fl = &p->fields[f];
        if (fl->ncomp == 1)
            fprintf(fp, ",%s", fl->name);
        else
            for (int c = 0; c < fl->ncomp; ++c) fprintf(fp, ",%s_%d", fl->name, c);
    }
    fprintf(fp, "\n");
    for (size_t i = 0; i < p->n; ++i) {
        for (int a = 0; a < p->dim; ++a) fprintf(fp, "%s%.17g", a ? "," : "", p->x[a][i]);
        for (int f = 0; f < p->nfields; ++f) {
            const consph_field *fl = &p->fields[f];
            for (int c = 0; c < fl->ncomp; ++c)
                fprintf(fp, ",%.17g", fl->data[(size_t)c * p->cap + i]);
        }
        fprintf(fp, "\n");
    }
}

const char *consph_vtu_encoding_names(void)
{
    return "ascii,binary,zlib";
}

const char *consph_vtu_encoding_name(consph_vtu_encoding enc)
{
    static const char *const names[] = {"ascii", "binary", "zlib"};
    return (unsigned)enc < 3 ? names[enc] : "?";
}

/* Uncompressed bytes per zlib block: large enough that zlib's per-block set-up costs nothing,
 * small enough that a batch of blocks in memory stays a few MB. A multiple of 8, so no value
 * straddles two blocks. */
#define VTU_BLOCK ((size_t)1 << 18)
/* Blocks compressed at once (by several threads with OpenMP). A constant, so that the file is
 * the same for every thread count. */
#define VTU_BATCH 16
/* zlib's fastest level: on 2000^2 particles (lattice or random) level 6 made files 1% smaller
 * in 2.4 to 4 times the time (bench_io 2000 zlib 2 lattice|random). */
#define VTU_ZLIB_LEVEL Z_BEST_SPEED
/* Room for an appended array's offset, patched in once the data before it is written:
 * 20 digits, the closing quote and padding. */
#define VTU_OFFSET_WIDTH 21

typedef enum vtu_kind { VTU_POINTS, VTU_FIELD, VTU_CONNECTIVITY, VTU_OFFSETS, VTU_TYPES } vtu_kind;

/* One DataArray of the Piece. Points and 2-component fields are written with 3 components
 * (VTK's points are 3D; ParaView shows 3-vectors as vectors), the extra ones zero; a tensor of
 * a snapshot (consph_vtu_content) as 9. */
typedef struct vtu_array {
    vtu_kind kind;
    const consph_field *field;
    int ncomp;  /* components written */
    int mapped; /* written component c holds the field's component src[c] (-1: zero); else
                 * the field's component c, zero beyond its own */
    int src[9];
    size_t esize;   /* bytes per value */
    off_t tag_pos;  /* where the offset placeholder is (appended encodings) */
    uint64_t start; /* offset of the array's data in the appended block */
} vtu_array;

/* The array's values from the source, when the caller hands them one array at a time. */
static int load_array(const consph_particles *p, const vtu_array *a, const io_array_source *src)
{
    if (!src || !(a->kind == VTU_POINTS || a->kind == VTU_FIELD)) return CONSPH_OK;
    return src->load(src->arg, a->kind == VTU_POINTS ? -1 : (int)(a->field - p->fields));
}

static double float_value(const consph_particles *p, const vtu_array *a, size_t i, int c)
{
    if (a->kind == VTU_POINTS) return c < p->dim ? p->x[c][i] : 0.0;
    const int k = a->mapped ? a->src[c] : c < a->field->ncomp ? c : -1;
    return k >= 0 ? a->field->data[(size_t)k * p->cap + i] : 0.0;
}

/* Values first .. first+count-1 of the array (value k is component k % ncomp of particle
 * k / ncomp), in the machine's byte order. */
static void fill_values(const consph_particles *p, const vtu_array *a, uint64_t first, size_t count,
                        unsigned char *buf)
{
    for (size_t k = 0; k < count; ++k) {
        uint64_t v = first + k;
        if (a->kind == VTU_POINTS || a->kind == VTU_FIELD) {
            double d =
                float_value(p, a, (size_t)(v / (uint64_t)a->ncomp), (int)(v % (uint64_t)a->ncomp));
            memcpy(buf + 8 * k, &d, 8);
        } else if (a->kind == VTU_TYPES) {
            buf[k] = 1; /* VTK_VERTEX */
        } else {
            int64_t q = (int64_t)v + (a->kind == VTU_OFFSETS);
            memcpy(buf + 8 * k, &q, 8);
        }
    }
}

static void write_ascii_values(FILE *fp, const consph_particles *p, const vtu_array *a)
{
    for (size_t i = 0; i < p->n; ++i) {
        if (a->kind == VTU_POINTS || a->kind == VTU_FIELD) {
            for (int c = 0; c < a->ncomp; ++c)
                fprintf(fp, "%s%.17g", c ? " " : "", float_value(p, a, i, c));
            fputc('\n', fp);
        } else if (a->kind == VTU_TYPES) {
            fprintf(fp, "1\n");
        } else {
            fprintf(fp, "%zu\n", i + (a->kind == VTU_OFFSETS));
        }
    }
}

/* A DataArray element: ASCII values inline, or an empty element pointing into AppendedData. */
static int write_array_tag(FILE *fp, const consph_particles *p, vtu_array *a, const char *name,
                           consph_vtu_encoding enc, const io_array_source *src)
{
    static const char *const type[] = {"Float64", "Float64", "Int64", "Int64", "UInt8"};
    fprintf(fp, "<DataArray type=\"%s\"", type[a->kind]);
    if (name) fprintf(fp, " Name=\"%s\"", name);
    if (a->kind == VTU_POINTS || a->kind == VTU_FIELD)
        fprintf(fp, " NumberOfComponents=\"%d\"", a->ncomp);
    if (enc == CONSPH_VTU_ASCII) {
        fprintf(fp, " format=\"ascii\">\n");
        const int rc = load_array(p, a, src);
        if (rc) return rc;
        write_ascii_values(fp, p, a);
        fprintf(fp, "</DataArray>\n");
        return CONSPH_OK;
    }
    fprintf(fp, " format=\"appended\" offset=\"");
    a->tag_pos = ftello(fp);
    if (a->tag_pos < 0) return consph_fail(CONSPH_EIO, "write error: cannot tell the position");
    fprintf(fp, "%-*s/>\n", VTU_OFFSET_WIDTH, "0\"");
    return CONSPH_OK;
}

static int write_u64(FILE *fp, uint64_t v)
{
    return fwrite(&v, sizeof v, 1, fp) == 1 ? CONSPH_OK : consph_fail(CONSPH_EIO, "write error");
}

/* Appended data of one array: a UInt64 byte count, then the values. */
static int write_raw(FILE *fp, const consph_particles *p, const vtu_array *a, unsigned char *buf)
{
    uint64_t nvalues = (uint64_t)p->n * (uint64_t)a->ncomp, per = VTU_BLOCK / a->esize;
    int rc = write_u64(fp, nvalues * a->esize);
    for (uint64_t first = 0; !rc && first < nvalues; first += per) {
        size_t count = (size_t)(nvalues - first < per ? nvalues - first : per);
        fill_values(p, a, first, count, buf);
        if (fwrite(buf, a->esize, count, fp) != count) rc = consph_fail(CONSPH_EIO, "write error");
    }
    return rc;
}

/* Appended data of one array, as vtkZLibDataCompressor writes it: a header (number of blocks,
 * block size, size of a partial last block or 0, compressed size of every block), then the
 * blocks, each a zlib stream. The header is written once the sizes are known. */
static int write_zlib(FILE *fp, const consph_particles *p, const vtu_array *a, unsigned char *raw,
                      unsigned char *comp, size_t bound)
{
    uint64_t nbytes = (uint64_t)p->n * (uint64_t)a->ncomp * a->esize;
    uint64_t nblocks = (nbytes + VTU_BLOCK - 1) / VTU_BLOCK;
    /* zeroed: the block sizes are placeholders until rewritten below, and a placeholder of
     * heap garbage would still reach the file system (valgrind flags it) */
    uint64_t *head = calloc((size_t)(3 + nblocks), sizeof *head);
    if (!head) return consph_fail(CONSPH_ENOMEM, "out of memory");
    head[0] = nblocks;
    head[1] = VTU_BLOCK;
    head[2] = nbytes % VTU_BLOCK;
    int rc = CONSPH_OK;
    off_t head_pos = ftello(fp);
    if (head_pos < 0 || fwrite(head, sizeof *head, (size_t)(3 + nblocks), fp) != 3 + nblocks)
        rc = consph_fail(CONSPH_EIO, "write error");
    for (uint64_t b0 = 0; !rc && b0 < nblocks; b0 += VTU_BATCH) {
        int nb = (int)(nblocks - b0 < VTU_BATCH ? nblocks - b0 : VTU_BATCH);
        uLongf clen[VTU_BATCH];
        int zrc[VTU_BATCH];
#pragma omp parallel for schedule(dynamic, 1) if (nb > 1)
        for (int j = 0; j < nb; ++j) {
            uint64_t pos = (b0 + (uint64_t)j) * VTU_BLOCK;
            size_t len = (size_t)(nbytes - pos < VTU_BLOCK ? nbytes - pos : VTU_BLOCK);
            unsigned char *in = raw + (size_t)j * VTU_BLOCK;
            fill_values(p, a, pos / a->esize, len / a->esize, in);
            clen[j] = (uLongf)bound;
            zrc[j] = compress2(comp + (size_t)j * bound, &clen[j], in, (uLong)len, VTU_ZLIB_LEVEL);
        }
        for (int j = 0; j < nb && !rc; ++j) {
            if (zrc[j] != Z_OK)
                rc = zrc[j] == Z_MEM_ERROR ? consph_fail(CONSPH_ENOMEM, "out of memory (zlib)")
                                           : consph_fail(CONSPH_EIO, "zlib error %d", zrc[j]);
            else if (fwrite(comp + (size_t)j * bound, 1, clen[j], fp) != clen[j])
                rc = consph_fail(CONSPH_EIO, "write error");
            head[3 + b0 + (uint64_t)j] = clen[j];
        }
    }
    if (!rc && (fseeko(fp, head_pos, SEEK_SET) != 0 ||
                fwrite(head, sizeof *head, (size_t)(3 + nblocks), fp) != 3 + nblocks ||
                fseeko(fp, 0, SEEK_END) != 0))
        rc = consph_fail(CONSPH_EIO, "write error");
    free(head);
    return rc;
}

/* The AppendedData element with every array's data, then each array's offset patched in. */
static int write_appended(FILE *fp, const consph_particles *p, vtu_array *arr, int narr,
                          consph_vtu_encoding enc, const io_array_source *src)
{
    size_t bound = compressBound(VTU_BLOCK);
    size_t nbuf = enc == CONSPH_VTU_ZLIB ? VTU_BATCH : 1;
    unsigned char *raw = malloc(nbuf * VTU_BLOCK);
    unsigned char *comp = enc == CONSPH_VTU_ZLIB ? malloc(nbuf * bound) : NULL;
    if (!raw || (enc == CONSPH_VTU_ZLIB && !comp)) {
        free(raw);
        free(comp);
        return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    fprintf(fp, "<AppendedData encoding=\"raw\">\n_");
    int rc = CONSPH_OK;
    off_t base = ftello(fp);
    if (base < 0) rc = consph_fail(CONSPH_EIO, "write error: cannot tell the position");
    for (int k = 0; k < narr && !rc; ++k) {
        off_t at = ftello(fp);
        if (at < 0) {
            rc = consph_fail(CONSPH_EIO, "write error: cannot tell the position");
            break;
        }
        arr[k].start = (uint64_t)(at - base);
        rc = load_array(p, &arr[k], src);
        if (rc) break;
        rc = enc == CONSPH_VTU_ZLIB ? write_zlib(fp, p, &arr[k], raw, comp, bound)
                                    : write_raw(fp, p, &arr[k], raw);
    }
    free(raw);
    free(comp);
    if (rc) return rc;
    fprintf(fp, "\n</AppendedData>\n</VTKFile>\n");
    for (int k = 0; k < narr && !rc; ++k) {
        char num[32];
        snprintf(num, sizeof num, "%llu\"", (unsigned long long)arr[k].start);
        if (fseeko(fp, arr[k].tag_pos, SEEK_SET) != 0 ||
            fprintf(fp, "%-*s", VTU_OFFSET_WIDTH, num) != VTU_OFFSET_WIDTH)
            rc = consph_fail(CONSPH_EIO, "write error");
    }
    return rc;
}

/* A field array: every field's component as is (2 padded to 3), or as `kind`. */
static vtu_array field_array(const consph_particles *p, const consph_field *fl, int as_kind,
                             consph_array_kind kind)
{
    vtu_array a = {
        .kind = VTU_FIELD, .field = fl, .ncomp = fl->ncomp == 2 ? 3 : fl->ncomp, .esize = 8};
    if (!as_kind || kind == CONSPH_ARRAY_SCALAR) return a;
    const int d = p->dim;
    a.mapped = 1;
    a.ncomp = kind == CONSPH_ARRAY_VECTOR ? 3 : 9;
    for (int c = 0; c < a.ncomp; ++c) {
        if (kind == CONSPH_ARRAY_VECTOR) {
            a.src[c] = c < d ? c : -1;
        } else {
            const int row = c / 3, col = c % 3;
            a.src[c] = row < d && col < d ? row * d + col : -1;
        }
    }
    return a;
}

static int name_allowed(const char *name)
{
    if (!name[0]) return 0;
    for (const char *c = name; *c; ++c)
        if (!((*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') ||
              *c == '_' || *c == '-' || *c == '.'))
            return 0;
    return 1;
}

static int content_check(const consph_particles *p, const consph_vtu_content *c)
{
    static const char *const kinds[] = {"scalar", "vector", "tensor"};
    if (c->has_time && !isfinite(c->time))
        return consph_fail(CONSPH_EINVAL, "TimeValue %g is not a finite time", c->time);
    if (!c->arrays) return CONSPH_OK;
    if (c->narrays < 0 || c->narrays > CONSPH_MAX_FIELDS)
        return consph_fail(CONSPH_EINVAL, "%d arrays; allowed: 0 to %d", c->narrays,
                           CONSPH_MAX_FIELDS);
    for (int k = 0; k < c->narrays; ++k) {
        const consph_vtu_array *a = &c->arrays[k];
        if (!a->name || !name_allowed(a->name) || !strcmp(a->name, "TimeValue"))
            return consph_fail(CONSPH_EINVAL,
                               "array %d: name '%s' not allowed (letters, digits, '_', '-', "
                               "'.'; not TimeValue)",
                               k, a->name ? a->name : "(null)");
        for (int j = 0; j < k; ++j)
            if (!strcmp(c->arrays[j].name, a->name))
                return consph_fail(CONSPH_EINVAL, "array '%s' is given twice", a->name);
        if ((unsigned)a->kind > CONSPH_ARRAY_TENSOR)
            return consph_fail(CONSPH_EINVAL,
                               "array '%s': unknown kind %d; allowed: scalar, "
                               "vector, tensor",
                               a->name, (int)a->kind);
        const consph_field *fl = a->field ? consph_particles_find(p, a->field) : NULL;
        if (!fl)
            return consph_fail(CONSPH_EINVAL, "array '%s': the particles have no field '%s'",
                               a->name, a->field ? a->field : "(null)");
        const int want = a->kind == CONSPH_ARRAY_SCALAR   ? 1
                         : a->kind == CONSPH_ARRAY_VECTOR ? p->dim
                                                          : p->dim * p->dim;
        if (fl->ncomp != want)
            return consph_fail(CONSPH_EINVAL,
                               "array '%s': field '%s' has %d components, a %s in %dD has %d",
                               a->name, a->field, fl->ncomp, kinds[a->kind], p->dim, want);
    }
    return CONSPH_OK;
}

static int write_vtu(FILE *fp, const consph_particles *p, const consph_vtu_content *c,
                     consph_vtu_encoding enc, const io_array_source *src)
{
    const consph_box *b = &p->box;
    const uint16_t one = 1;
    int little = *(const unsigned char *)&one == 1;
    fprintf(fp,
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" "
            "byte_order=\"%s\" header_type=\"UInt64\"%s>\n<UnstructuredGrid>\n",
            little ? "LittleEndian" : "BigEndian",
            enc == CONSPH_VTU_ZLIB ? " compressor=\"vtkZLibDataCompressor\"" : "");
    /* The box is a handful of numbers: ASCII in every encoding, readable in the file. */
    fprintf(fp,
            "<FieldData>\n<DataArray type=\"Float64\" Name=\"box\" NumberOfTuples=\"1\" "
            "NumberOfComponents=\"%d\" format=\"ascii\">",
            2 * p->dim);
    for (int a = 0; a < p->dim; ++a) fprintf(fp, " %.17g %.17g", b->lo[a], b->hi[a]);
    fprintf(fp,
            "</DataArray>\n<DataArray type=\"Int32\" Name=\"periodic\" NumberOfTuples=\"1\" "
            "NumberOfComponents=\"%d\" format=\"ascii\">",
            p->dim);
    for (int a = 0; a < p->dim; ++a) fprintf(fp, " %d", b->periodic[a] ? 1 : 0);
    fprintf(fp,
            "</DataArray>\n<DataArray type=\"Float64\" Name=\"spacing\" NumberOfTuples=\"1\" "
            "format=\"ascii\"> %.17g</DataArray>\n",
            p->spacing);
    if (c && c->has_time)
        fprintf(fp,
                "<DataArray type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\" "
                "format=\"ascii\"> %.17g</DataArray>\n",
                c->time);
    fprintf(fp, "</FieldData>\n");
    fprintf(fp, "<Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\">\n", p->n, p->n);

    vtu_array arr[CONSPH_MAX_FIELDS + 4];
    int narr = 0, rc = CONSPH_OK;
    fprintf(fp, "<PointData>\n");
    if (c && c->arrays) {
        for (int k = 0; k < c->narrays && !rc; ++k) {
            const consph_vtu_array *a = &c->arrays[k];
            arr[narr] = field_array(p, consph_particles_find(p, a->field), 1, a->kind);
            rc = write_array_tag(fp, p, &arr[narr++], a->name, enc, src);
        }
    } else {
        for (int f = 0; f < p->nfields && !rc; ++f) {
            const consph_field *fl = &p->fields[f];
            arr[narr] = field_array(p, fl, 0, CONSPH_ARRAY_SCALAR);
            rc = write_array_tag(fp, p, &arr[narr++], fl->name, enc, src);
        }
    }
    fprintf(fp, "</PointData>\n<Points>\n");
    arr[narr] = (vtu_array){.kind = VTU_POINTS, .ncomp = 3, .esize = 8};
    if (!rc) rc = write_array_tag(fp, p, &arr[narr++], NULL, enc, src);
    fprintf(fp, "</Points>\n<Cells>\n");
    /* One VTK_VERTEX cell per particle, so readers show points without a glyph filter. */
    static const char *const cell_name[] = {"connectivity", "offsets", "types"};
    for (int k = 0; k < 3 && !rc; ++k) {
        arr[narr] = (vtu_array){
            .kind = (vtu_kind)(VTU_CONNECTIVITY + k), .ncomp = 1, .esize = k == 2 ? 1 : 8};
        rc = write_array_tag(fp, p, &arr[narr++], cell_name[k], enc, src);
    }
    fprintf(fp, "</Cells>\n</Piece>\n</UnstructuredGrid>\n");
    if (rc) return rc;
    if (enc == CONSPH_VTU_ASCII) {
        fprintf(fp, "</VTKFile>\n");
        return CONSPH_OK;
    }
    return write_appended(fp, p, arr, narr, enc, src);
}

static int write_particles(const char *path, const consph_particles *p, const consph_vtu_content *c,
                           consph_vtu_encoding enc, const io_array_source *src);

int consph_write_particles(const char *path, const consph_particles *p)
{
    return consph_write_particles_enc(path, p, CONSPH_VTU_DEFAULT);
}

int consph_write_particles_enc(const char *path, const consph_particles *p, consph_vtu_encoding enc)
{
    return write_particles(path, p, NULL, enc, NULL);
}

int consph_write_vtu(const char *path, const consph_particles *p, const consph_vtu_content *c,
                     consph_vtu_encoding enc)
{
    return io_write_vtu_source(path, p, c, enc, NULL);
}

int io_write_vtu_source(const char *path, const consph_particles *p, const consph_vtu_content *c,
                        consph_vtu_encoding enc, const io_array_source *src)
{
    consph_particle_format fmt;
    int rc = consph_particle_format_from_path(path, &fmt);
    if (rc) return rc;
    if (fmt != CONSPH_FORMAT_VTU)
        return consph_fail(CONSPH_EINVAL, "'%s': a snapshot with chosen arrays is a .vtu file",
                           path);
    rc = content_check(p, c);
    return rc ? rc : write_particles(path, p, c, enc, src);
}

static int write_particles(const char *path, const consph_particles *p, const consph_vtu_content *c,
                           consph_vtu_encoding enc, const io_array_source *src)
{
    if ((unsigned)enc > CONSPH_VTU_ZLIB)
        return consph_fail(CONSPH_EINVAL, "unknown VTU encoding %d; allowed: %s", (int)enc,
                           consph_vtu_encoding_names());
    consph_particle_format fmt;
    int rc = consph_particle_format_from_path(path, &fmt);
    if (rc) return rc;
    consph_outfile of;
    rc = consph_outfile_open(&of, path);
    if (rc) return rc;
    if (fmt == CONSPH_FORMAT_CSV)
        write_csv(of.fp, p);
    else
        rc = write_vtu(of.fp, p, c, enc, src);
    if (rc) {
        /* The writers' own "write error" lacks the file and the reason. */
        if (ferror(of.fp)) rc = consph_outfile_fail(&of, 0);
        consph_outfile_abort(&of);
        return rc;
    }
    return consph_outfile_commit(&of);
}
