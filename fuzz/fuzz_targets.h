/* The fuzz entry points of the particle readers, shared by the libFuzzer targets (fuzz_*.c,
 * built by `make fuzz`) and by tests/test_io_read.c, which replays the seed corpus and every
 * crash kept in fuzz/regressions/ through them in the normal (and sanitized) test build.
 *
 * Each entry point reads the input as a file of its format, twice: with no options (the file's
 * own box and dimension) and with a 2D unit box periodic in x given by the caller (the override
 * and wrapping paths). The refill size of the byte source is derived from the input length, so
 * that values, lines and base64 quads straddle refills at every offset. Whatever the input, a
 * read either fails with a message or yields particles that satisfy the reader's contract;
 * anything else aborts, which libFuzzer reports as a crash. */
#ifndef CONSPH_FUZZ_TARGETS_H
#define CONSPH_FUZZ_TARGETS_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/io.h"
#include "io/read_internal.h"

static inline void fuzz_require(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "fuzz invariant violated: %s\n", what);
        abort();
    }
}

/* The reader's contract for a successful read. */
static inline void fuzz_check_particles(const consph_particles *p, const consph_read_options *opt)
{
    fuzz_require(p->dim >= 1 && p->dim <= CONSPH_MAX_DIM, "dimension in 1..3");
    fuzz_require(!opt->dim || p->dim == opt->dim, "dimension as asked");
    fuzz_require(p->n > 0 && p->cap == p->n, "n > 0 and cap == n");
    fuzz_require(consph_box_check(&p->box) == CONSPH_OK, "a valid box");
    fuzz_require(p->spacing > 0 && isfinite(p->spacing), "a positive spacing");
    for (int a = 0; a < p->dim; ++a) {
        double lo = p->box.lo[a], hi = p->box.hi[a];
        for (size_t i = 0; i < p->n; ++i) {
            double x = p->x[a][i];
            fuzz_require(isfinite(x), "finite coordinates");
            fuzz_require(x >= lo && (p->box.periodic[a] ? x < hi : x <= hi), "inside the box");
        }
    }
    for (int f = 0; f < p->nfields; ++f) {
        const consph_field *fl = &p->fields[f];
        fuzz_require(fl->ncomp >= 1 && fl->data != NULL, "a field with data");
        for (size_t k = 0; k < p->n * (size_t)fl->ncomp; ++k)
            fuzz_require(isfinite(fl->data[k]), "finite field values");
    }
    const consph_field *vol = consph_particles_find(p, "volume");
    for (size_t i = 0; vol && i < p->n; ++i) fuzz_require(vol->data[i] > 0, "positive volumes");
    /* No two particles at the same place (quadratic, so only on small sets). */
    if (p->n <= 2000)
        for (size_t i = 0; i < p->n; ++i)
            for (size_t j = i + 1; j < p->n; ++j) {
                int same = 1;
                for (int a = 0; a < p->dim && same; ++a) same = p->x[a][i] == p->x[a][j];
                fuzz_require(!same, "no duplicate positions");
            }
}

static inline int consph_fuzz_read(consph_particle_format fmt, const uint8_t *data, size_t size)
{
    consph_rd_chunk = 1 + size % 17;
    for (int variant = 0; variant < 2; ++variant) {
        consph_read_options opt;
        memset(&opt, 0, sizeof opt);
        if (variant == 1) {
            opt.dim = 2;
            opt.have_box = 1;
            opt.box = consph_box_unit(2, 0);
            opt.have_periodic = 1;
            opt.periodic[0] = 1;
        }
        consph_particles p;
        consph_read_report rep;
        int rc = consph_read_particles_mem(fmt == CONSPH_FORMAT_CSV ? "fuzz.csv" : "fuzz.vtu", fmt,
                                           data, size, &opt, &p, &rep);
        if (rc == CONSPH_OK) {
            fuzz_check_particles(&p, &opt);
            consph_particles_free(&p);
        } else {
            fuzz_require(consph_last_error()[0] != '\0', "a failed read leaves a message");
            fuzz_require(p.n == 0 && p.x[0] == NULL, "a failed read leaves no particles");
        }
    }
    consph_rd_chunk = 0;
    return 0;
}

static inline int consph_fuzz_csv(const uint8_t *data, size_t size)
{
    return consph_fuzz_read(CONSPH_FORMAT_CSV, data, size);
}

static inline int consph_fuzz_vtu(const uint8_t *data, size_t size)
{
    return consph_fuzz_read(CONSPH_FORMAT_VTU, data, size);
}

/* The VTU reader's zlib wrapper on its own (output limit, buffer growth, error reasons):
 * arbitrary bytes as one compressed block. */
static inline int consph_fuzz_inflate(const uint8_t *data, size_t size)
{
    unsigned char *out = NULL;
    size_t outlen = 0, outcap = 0;
    const char *why = NULL;
    int rc = consph_rd_inflate(data, size, &out, &outlen, &outcap, (size_t)1 << 20, &why);
    fuzz_require(outlen <= ((size_t)1 << 20) && outlen <= outcap, "output within its bounds");
    fuzz_require(rc == 0 || (why && why[0]), "a failure has a reason");
    free(out);
    return 0;
}

#endif
