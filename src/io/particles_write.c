#include <string.h>

#include "consph/io.h"

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

static void write_vtu(FILE *fp, const consph_particles *p)
{
    const consph_box *b = &p->box;
    fprintf(fp, "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" "
                "byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n");
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
            "format=\"ascii\"> %.17g</DataArray>\n</FieldData>\n",
            p->spacing);
    fprintf(fp, "<Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\">\n", p->n, p->n);
    fprintf(fp, "<PointData>\n");
    for (int f = 0; f < p->nfields; ++f) {
        const consph_field *fl = &p->fields[f];
        int nc = fl->ncomp == 2 ? 3 : fl->ncomp; /* ParaView shows 3-vectors as vectors */
        fprintf(fp,
                "<DataArray type=\"Float64\" Name=\"%s\" NumberOfComponents=\"%d\" "
                "format=\"ascii\">\n",
                fl->name, nc);
        for (size_t i = 0; i < p->n; ++i) {
            for (int c = 0; c < nc; ++c)
                fprintf(fp, "%s%.17g", c ? " " : "",
                        c < fl->ncomp ? fl->data[(size_t)c * p->cap + i] : 0.0);
            fputc('\n', fp);
        }
        fprintf(fp, "</DataArray>\n");
    }
    fprintf(fp, "</PointData>\n<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" "
                "format=\"ascii\">\n");
    for (size_t i = 0; i < p->n; ++i) {
        for (int a = 0; a < 3; ++a)
            fprintf(fp, "%s%.17g", a ? " " : "", a < p->dim ? p->x[a][i] : 0.0);
        fputc('\n', fp);
    }
    fprintf(fp, "</DataArray>\n</Points>\n<Cells>\n");
    /* One VTK_VERTEX cell per particle, so readers show points without a glyph filter. */
    fprintf(fp, "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for (size_t i = 0; i < p->n; ++i) fprintf(fp, "%zu\n", i);
    fprintf(fp, "</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    for (size_t i = 0; i < p->n; ++i) fprintf(fp, "%zu\n", i + 1);
    fprintf(fp, "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
    for (size_t i = 0; i < p->n; ++i) fprintf(fp, "1\n");
    fprintf(fp, "</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
}

int consph_write_particles(const char *path, const consph_particles *p)
{
    consph_particle_format fmt;
    int rc = consph_particle_format_from_path(path, &fmt);
    if (rc) return rc;
    consph_outfile of;
    rc = consph_outfile_open(&of, path);
    if (rc) return rc;
    if (fmt == CONSPH_FORMAT_CSV)
        write_csv(of.fp, p);
    else
        write_vtu(of.fp, p);
    return consph_outfile_commit(&of);
}
