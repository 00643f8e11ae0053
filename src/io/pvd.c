/* ParaView .pvd index of a run's snapshots (a VTK "Collection"): one DataSet element per
 * snapshot, with its time and its file name relative to the index.
 *
 * The index is rewritten whole, through consph_outfile, after every change, so a reader (or a
 * run killed at any moment) only ever sees a complete file. consph_pvd_load reads back exactly
 * the lines write_index produces and refuses anything else: it exists for a restarted run to
 * continue its own index, not to parse arbitrary ParaView files. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "consph/io.h"

static const char *const pvd_head[] = {
    "<?xml version=\"1.0\"?>",
    "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">",
    "  <Collection>",
};
static const char *const pvd_tail[] = {"  </Collection>", "</VTKFile>"};
#define PVD_NHEAD (sizeof pvd_head / sizeof pvd_head[0])
#define PVD_NTAIL (sizeof pvd_tail / sizeof pvd_tail[0])
#define PVD_ENTRY_PREFIX "    <DataSet timestep=\""
#define PVD_NAME_MAX 255 /* NAME_MAX of common file systems */
#define PVD_LINE_MAX 512 /* longer than any entry line write_index produces */

/* A name that lies in the index's directory and needs no XML escaping: no '/', no quote, '&',
 * '<', '>', control byte, not "." or "..". */
static int plain_name(const char *file)
{
    size_t len = strlen(file);
    if (len == 0 || len > PVD_NAME_MAX || strcmp(file, ".") == 0 || strcmp(file, "..") == 0)
        return 0;
    for (const unsigned char *c = (const unsigned char *)file; *c; ++c)
        if (*c < 0x20 || *c == 0x7f || strchr("/\\\"'&<>", *c)) return 0;
    return 1;
}

static int write_index(const consph_pvd *pvd)
{
    consph_outfile of;
    int rc = consph_outfile_open(&of, pvd->path);
    if (rc) return rc;
    for (size_t k = 0; k < PVD_NHEAD; ++k) fprintf(of.fp, "%s\n", pvd_head[k]);
    for (size_t i = 0; i < pvd->n; ++i)
        fprintf(of.fp, PVD_ENTRY_PREFIX "%.17g\" file=\"%s\"/>\n", pvd->time[i], pvd->file[i]);
    for (size_t k = 0; k < PVD_NTAIL; ++k) fprintf(of.fp, "%s\n", pvd_tail[k]);
    return consph_outfile_commit(&of);
}

int consph_pvd_init(consph_pvd *pvd, const char *path)
{
    memset(pvd, 0, sizeof *pvd);
    if (!path || !*path) return consph_fail(CONSPH_EINVAL, "empty .pvd path");
    pvd->path = malloc(strlen(path) + 1);
    if (!pvd->path) return consph_fail(CONSPH_ENOMEM, "out of memory");
    strcpy(pvd->path, path);
    return CONSPH_OK;
}

void consph_pvd_free(consph_pvd *pvd)
{
    for (size_t i = 0; i < pvd->n; ++i) free(pvd->file[i]);
    free(pvd->file);
    free(pvd->time);
    free(pvd->path);
    memset(pvd, 0, sizeof *pvd);
}

/* Appends in memory only; the caller rewrites the index. */
static int append(consph_pvd *pvd, double time, const char *file)
{
    if (pvd->n == pvd->cap) {
        size_t cap = pvd->cap ? 2 * pvd->cap : 16;
        double *t = realloc(pvd->time, cap * sizeof *t);
        if (!t) return consph_fail(CONSPH_ENOMEM, "out of memory");
        pvd->time = t;
        char **f = realloc(pvd->file, cap * sizeof *f);
        if (!f) return consph_fail(CONSPH_ENOMEM, "out of memory");
        pvd->file = f;
        pvd->cap = cap;
    }
    char *copy = malloc(strlen(file) + 1);
    if (!copy) return consph_fail(CONSPH_ENOMEM, "out of memory");
    strcpy(copy, file);
    pvd->time[pvd->n] = time;
    pvd->file[pvd->n] = copy;
    ++pvd->n;
    return CONSPH_OK;
}

/* Times never decrease and a file appears once: what a run's snapshots are. The same entry
 * added again (a restarted run rewriting the snapshot of its checkpoint's step) is a rewrite. */
static int check_entry(const consph_pvd *pvd, double time, const char *file, int *same_as_last)
{
    *same_as_last = 0;
    if (!file || !plain_name(file))
        return consph_fail(CONSPH_EINVAL,
                           "'%s': .pvd entry must be a plain file name (1 to %d bytes; no '/', "
                           "'\\', quotes, '&', '<', '>' or control characters)",
                           file ? file : "(null)", PVD_NAME_MAX);
    if (!isfinite(time))
        return consph_fail(CONSPH_EINVAL, "'%s': .pvd time must be finite, got %g", file, time);
    if (pvd->n && time < pvd->time[pvd->n - 1])
        return consph_fail(CONSPH_EINVAL, "'%s': .pvd time %.17g is before the last entry's %.17g",
                           file, time, pvd->time[pvd->n - 1]);
    for (size_t i = 0; i < pvd->n; ++i)
        if (strcmp(pvd->file[i], file) == 0) {
            if (i == pvd->n - 1 && pvd->time[i] == time) {
                *same_as_last = 1;
                return CONSPH_OK;
            }
            return consph_fail(CONSPH_EINVAL, "'%s' is already in the .pvd index at t = %.17g",
                               file, pvd->time[i]);
        }
    return CONSPH_OK;
}

int consph_pvd_add(consph_pvd *pvd, double time, const char *file)
{
    int same;
    int rc = check_entry(pvd, time, file, &same);
    if (rc) return rc;
    if (!same && (rc = append(pvd, time, file))) return rc;
    rc = write_index(pvd);
    if (rc && !same) {
        /* The file on disk does not have it: neither does the index in memory. */
        free(pvd->file[--pvd->n]);
    }
    return rc;
}

int consph_pvd_truncate(consph_pvd *pvd, double t)
{
    size_t keep = 0;
    for (size_t i = 0; i < pvd->n; ++i) {
        if (pvd->time[i] > t) {
            free(pvd->file[i]);
            continue;
        }
        pvd->time[keep] = pvd->time[i];
        pvd->file[keep] = pvd->file[i];
        ++keep;
    }
    pvd->n = keep;
    return write_index(pvd);
}

/* The line without its '\n'; 0 at the end of the file, -1 when longer than the buffer. */
static int read_line(FILE *fp, char *buf, size_t size)
{
    if (!fgets(buf, (int)size, fp)) return 0;
    size_t len = strlen(buf);
    if (len == 0 || buf[len - 1] != '\n') return -1;
    buf[len - 1] = '\0';
    return 1;
}

/* One entry line as write_index writes it, into pvd; -1 when the line is not an entry. */
static int parse_entry(consph_pvd *pvd, const char *path, size_t lineno, char *line)
{
    const size_t plen = strlen(PVD_ENTRY_PREFIX);
    if (strncmp(line, PVD_ENTRY_PREFIX, plen) != 0) return -1;
    char *end;
    double time = strtod(line + plen, &end);
    if (end == line + plen || strncmp(end, "\" file=\"", 8) != 0)
        return consph_fail(CONSPH_EFORMAT, "%s:%zu: bad timestep attribute", path, lineno);
    char *file = end + 8;
    char *close = strchr(file, '"');
    if (!close || strcmp(close, "\"/>") != 0)
        return consph_fail(CONSPH_EFORMAT, "%s:%zu: bad DataSet element", path, lineno);
    *close = '\0';
    int same;
    if (check_entry(pvd, time, file, &same) || same)
        return consph_fail(CONSPH_EFORMAT, "%s:%zu: %s", path, lineno,
                           same ? "entry repeated" : consph_last_error());
    return append(pvd, time, file);
}

int consph_pvd_load(consph_pvd *pvd, const char *path)
{
    int rc = consph_pvd_init(pvd, path);
    if (rc) return rc;
    FILE *fp = fopen(path, "r");
    if (!fp) {
        consph_pvd_free(pvd);
        return consph_fail(CONSPH_EIO, "cannot open .pvd index '%s'", path);
    }
    char line[PVD_LINE_MAX];
    size_t lineno = 0, head = 0, tail = 0;
    int got;
    while ((got = read_line(fp, line, sizeof line)) != 0) {
        ++lineno;
        if (got < 0) {
            rc = consph_fail(CONSPH_EFORMAT, "%s:%zu: line too long or not ended", path, lineno);
            break;
        }
        if (head < PVD_NHEAD) {
            if (strcmp(line, pvd_head[head]) != 0) {
                rc = consph_fail(CONSPH_EFORMAT, "%s:%zu: expected '%s' (not a consph .pvd index)",
                                 path, lineno, pvd_head[head]);
                break;
            }
            ++head;
            continue;
        }
        if (tail == 0) {
            rc = parse_entry(pvd, path, lineno, line);
            if (rc == 0) continue;
            if (rc != -1) break;
            rc = 0;
        }
        if (tail == PVD_NTAIL || strcmp(line, pvd_tail[tail]) != 0) {
            rc = consph_fail(CONSPH_EFORMAT, "%s:%zu: unexpected line", path, lineno);
            break;
        }
        ++tail;
    }
    if (!rc && tail < PVD_NTAIL)
        rc = consph_fail(CONSPH_EFORMAT, "%s: truncated (no closing '%s')", path,
                         pvd_tail[PVD_NTAIL - 1]);
    fclose(fp);
    if (rc) consph_pvd_free(pvd);
    return rc;
}
