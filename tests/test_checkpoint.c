/* Run infrastructure of io.h: checkpoints (bit-exact round trip, refusal of every corruption
 * without allocating what a hostile header claims, atomic writes), the .pvd index, stop
 * requests (and their interplay with consph_outfile's temp-file cleanup), progress output. */
/* posix_openpt and friends, for the progress check on a pseudo-terminal. */
#define _XOPEN_SOURCE 700
#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include "check.h"
#include "consph/io.h"

static char dir[] = "/tmp/consph_ckpt_XXXXXX";

static void path_in(char *buf, size_t size, const char *name)
{
    snprintf(buf, size, "%s/%s", dir, name);
}

static int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static void spill(const char *path, const void *data, size_t size)
{
    FILE *fp = fopen(path, "wb");
    if (size) fwrite(data, 1, size, fp);
    fclose(fp);
}

/* Every 64-bit pattern is a double the round trip must keep: random bits give NaNs with
 * payloads, infinities and subnormals; a few special values are placed by hand. */
static double random_bits(consph_rng *r)
{
    uint64_t b = consph_rng_next(r);
    double d;
    memcpy(&d, &b, 8);
    return d;
}

static void fill(double *v, size_t n, consph_rng *r)
{
    for (size_t i = 0; i < n; ++i) v[i] = random_bits(r);
    if (n > 0) v[0] = -0.0;
    if (n > 1) {
        uint64_t qnan_payload = 0x7ff8000000012345ull;
        memcpy(&v[1], &qnan_payload, 8);
    }
    if (n > 2) {
        uint64_t snan = 0x7ff0000000000001ull;
        memcpy(&v[2], &snan, 8);
    }
}

/* Particles with room for n + 3 but only n in use, so the write must take the first n of each
 * component-major column, not the whole allocation. */
static void make_particles(consph_particles *p, int dim, size_t n, consph_rng *r)
{
    consph_box box = consph_box_unit(dim, 0);
    for (int a = 0; a < dim; ++a) {
        box.lo[a] = -0.5 * (a + 1);
        box.hi[a] = 1.25 + a;
        box.periodic[a] = a % 2 == 0;
    }
    consph_particles_init(p, dim, n + 3, &box);
    p->n = n;
    p->spacing = 0.1 / 3.0;
    for (int a = 0; a < dim; ++a) fill(p->x[a], p->cap, r);
    static const struct {
        const char *name;
        int ncomp;
    } fields[] = {{"rho", 1}, {"u", 3}, {"tensor_field_w", 5}, {"p", 1}};
    for (size_t f = 0; f < sizeof fields / sizeof fields[0]; ++f) {
        double *d = consph_particles_field(p, fields[f].name, fields[f].ncomp);
        fill(d, p->cap * (size_t)fields[f].ncomp, r);
    }
}

static int same_bits(const double *a, const double *b, size_t n)
{
    return n == 0 || memcmp(a, b, n * sizeof(double)) == 0;
}

static void check_same_particles(const consph_particles *a, const consph_particles *b,
                                 const char *what)
{
    CHECK(a->dim == b->dim && a->n == b->n, "%s: dim %d/%d n %zu/%zu", what, a->dim, b->dim, a->n,
          b->n);
    CHECK(b->cap == b->n, "%s: read particles have cap %zu for n %zu", what, b->cap, b->n);
    CHECK(memcmp(&a->spacing, &b->spacing, 8) == 0, "%s: spacing", what);
    CHECK(a->box.dim == b->box.dim, "%s: box dim", what);
    for (int d = 0; d < a->dim && d < b->dim; ++d) {
        CHECK(memcmp(&a->box.lo[d], &b->box.lo[d], 8) == 0 &&
                  memcmp(&a->box.hi[d], &b->box.hi[d], 8) == 0 &&
                  a->box.periodic[d] == b->box.periodic[d],
              "%s: box axis %d", what, d);
        CHECK(same_bits(a->x[d], b->x[d], a->n), "%s: positions axis %d", what, d);
    }
    CHECK(a->nfields == b->nfields, "%s: %d fields, read %d", what, a->nfields, b->nfields);
    for (int f = 0; f < a->nfields && f < b->nfields; ++f) {
        const consph_field *fa = &a->fields[f], *fb = &b->fields[f];
        CHECK(strcmp(fa->name, fb->name) == 0 && fa->ncomp == fb->ncomp,
              "%s: field %d is %s/%d, read %s/%d", what, f, fa->name, fa->ncomp, fb->name,
              fb->ncomp);
        if (fa->ncomp != fb->ncomp) continue;
        for (int c = 0; c < fa->ncomp; ++c)
            CHECK(same_bits(fa->data + (size_t)c * a->cap, fb->data + (size_t)c * b->cap, a->n),
                  "%s: field %s component %d", what, fa->name, c);
    }
}

static void test_round_trip(void)
{
    consph_rng r;
    consph_rng_seed(&r, 14);
    char path[256];
    path_in(path, sizeof path, "rt.ckpt");
    const size_t sizes[] = {0, 1, 2, 3, 257};
    for (int dim = 1; dim <= 3; ++dim)
        for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; ++k)
            for (int variant = 0; variant < 2; ++variant) {
                consph_particles p, q;
                make_particles(&p, dim, sizes[k], &r);
                const char *meta = variant ? "scheme=l-ipst-c\nstep=120\nt=0.25\n" : "";
                double hist[7];
                fill(hist, 7, &r);
                size_t nh = variant ? 7 : 0;
                char what[64];
                snprintf(what, sizeof what, "dim %d n %zu variant %d", dim, sizes[k], variant);
                int rc = consph_checkpoint_write(path, meta, &p, variant ? hist : NULL, nh);
                CHECK(rc == CONSPH_OK, "%s: write: %s", what, consph_last_error());
                char *meta2 = NULL;
                double *hist2 = NULL;
                size_t nh2 = 99;
                rc = consph_checkpoint_read(path, &meta2, &q, &hist2, &nh2);
                CHECK(rc == CONSPH_OK, "%s: read: %s", what, consph_last_error());
                if (rc == CONSPH_OK) {
                    CHECK(strcmp(meta, meta2) == 0, "%s: meta '%s'", what, meta2);
                    CHECK(nh2 == nh, "%s: %zu history values", what, nh2);
                    CHECK(nh ? same_bits(hist, hist2, nh) : hist2 == NULL, "%s: history", what);
                    check_same_particles(&p, &q, what);
                    consph_particles_free(&q);
                }
                /* the parts a decomposed restart reads: together, the whole set bit for bit */
                for (int parts = 1; parts <= 3; ++parts) {
                    int same = 1;
                    for (int part = 0; part < parts; ++part) {
                        char *m3 = NULL;
                        double *h3 = NULL;
                        size_t n3 = 0, first = 0, total = 0;
                        consph_particles r3;
                        rc = consph_checkpoint_read_part(path, part, parts, &m3, &r3, &h3, &n3,
                                                         &first, &total);
                        CHECK(rc == CONSPH_OK, "%s: part %d of %d: %s", what, part, parts,
                              consph_last_error());
                        if (rc != CONSPH_OK) continue;
                        const size_t lo = p.n * (size_t)part / (size_t)parts;
                        same = same && total == p.n && first == lo && !strcmp(m3, meta) &&
                               n3 == nh && (!nh || same_bits(h3, hist, nh)) && r3.dim == p.dim &&
                               r3.n == p.n * (size_t)(part + 1) / (size_t)parts - lo &&
                               r3.nfields == p.nfields && r3.spacing == p.spacing;
                        for (int a = 0; same && a < dim; ++a)
                            same = same_bits(r3.x[a], p.x[a] + lo, r3.n) &&
                                   r3.box.lo[a] == p.box.lo[a] && r3.box.hi[a] == p.box.hi[a] &&
                                   r3.box.periodic[a] == p.box.periodic[a];
                        for (int f = 0; same && f < p.nfields; ++f) {
                            same = !strcmp(r3.fields[f].name, p.fields[f].name) &&
                                   r3.fields[f].ncomp == p.fields[f].ncomp;
                            for (int c = 0; same && c < p.fields[f].ncomp; ++c)
                                same = same_bits(r3.fields[f].data + (size_t)c * r3.cap,
                                                 p.fields[f].data + (size_t)c * p.cap + lo, r3.n);
                        }
                        free(m3);
                        free(h3);
                        consph_particles_free(&r3);
                    }
                    CHECK(same, "%s: %d parts are not the whole set", what, parts);
                }
                free(meta2);
                free(hist2);
                consph_particles_free(&p);
            }
    /* A NULL meta is the empty text. */
    consph_particles p, q;
    make_particles(&p, 2, 4, &r);
    CHECK(consph_checkpoint_write(path, NULL, &p, NULL, 0) == CONSPH_OK, "%s", consph_last_error());
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    CHECK(consph_checkpoint_read(path, &meta, &q, &hist, &nh) == CONSPH_OK, "%s",
          consph_last_error());
    CHECK(meta && meta[0] == '\0', "NULL meta reads back as empty");
    free(meta);
    consph_particles_free(&q);
    consph_particles_free(&p);
}

/* Reading `bytes` as a checkpoint must fail with CONSPH_EFORMAT and a message naming the file,
 * and return nothing. */
static void expect_refused(const char *path, const void *bytes, size_t size, const char *what)
{
    spill(path, bytes, size);
    char *meta = (char *)1;
    double *hist = (double *)1;
    size_t nh = 99;
    consph_particles p;
    consph_clear_error();
    int rc = consph_checkpoint_read(path, &meta, &p, &hist, &nh);
    CHECK(rc == CONSPH_EFORMAT, "%s: rc %d (%s)", what, rc, consph_last_error());
    CHECK(strstr(consph_last_error(), path) != NULL, "%s: message '%s' does not name the file",
          what, consph_last_error());
    CHECK(meta == NULL && hist == NULL && nh == 0 && p.n == 0 && p.x[0] == NULL && p.nfields == 0,
          "%s: something was returned", what);
    if (rc == CONSPH_OK) {
        free(meta);
        free(hist);
        consph_particles_free(&p);
    }
    /* a part of it: refused as well, with the whole read's message */
    char whole[512];
    snprintf(whole, sizeof whole, "%s", consph_last_error());
    for (int part = 0; part < 2; ++part) {
        meta = (char *)1;
        hist = (double *)1;
        nh = 99;
        size_t first = 9, total = 9;
        consph_clear_error();
        rc = consph_checkpoint_read_part(path, part, 2, &meta, &p, &hist, &nh, &first, &total);
        CHECK(rc == CONSPH_EFORMAT && !strcmp(consph_last_error(), whole),
              "%s: part %d: rc %d (%s), the whole read's: %s", what, part, rc, consph_last_error(),
              whole);
        CHECK(meta == NULL && hist == NULL && nh == 0 && p.n == 0 && p.x[0] == NULL,
              "%s: part %d: something was returned", what, part);
        if (rc == CONSPH_OK) {
            free(meta);
            free(hist);
            consph_particles_free(&p);
        }
    }
}

static void test_corruption(void)
{
    consph_rng r;
    consph_rng_seed(&r, 7);
    char good[256], bad_path[256];
    path_in(good, sizeof good, "good.ckpt");
    path_in(bad_path, sizeof bad_path, "bad.ckpt");
    consph_particles p;
    make_particles(&p, 2, 40, &r);
    double hist[3] = {1, 2, 3};
    CHECK(consph_checkpoint_write(good, "k=v\n", &p, hist, 3) == CONSPH_OK, "%s",
          consph_last_error());
    consph_particles_free(&p);
    size_t size = 0;
    unsigned char *b = check_load_file(good, &size);
    CHECK(b && size > 64, "checkpoint of %zu bytes", size);
    if (!b || size <= 64) return;
    unsigned char *c = malloc(size + 1);

    const size_t cuts[] = {0, 1, 7, 8, 12, 31, 32, 33, 40, size / 2, size - 1};
    for (size_t k = 0; k < sizeof cuts / sizeof cuts[0]; ++k) {
        char what[64];
        snprintf(what, sizeof what, "truncated to %zu bytes", cuts[k]);
        expect_refused(bad_path, b, cuts[k], what);
    }
    memcpy(c, b, size);
    c[size] = 0;
    expect_refused(bad_path, c, size + 1, "one byte appended");

    /* Every header byte: magic, version, CRC, both sizes. */
    for (size_t k = 0; k < 32; ++k) {
        memcpy(c, b, size);
        c[k] ^= 0x20;
        char what[64];
        snprintf(what, sizeof what, "header byte %zu flipped", k);
        expect_refused(bad_path, c, size, what);
    }
    /* Payload bytes: zlib's own check or the CRC-32 catches each. */
    const size_t at[] = {32, 33, 34, 40, 64, size / 2, size - 5, size - 1};
    for (size_t k = 0; k < sizeof at / sizeof at[0]; ++k) {
        memcpy(c, b, size);
        c[at[k]] ^= 0x01;
        char what[64];
        snprintf(what, sizeof what, "payload byte %zu flipped", at[k]);
        expect_refused(bad_path, c, size, what);
    }
    memcpy(c, b, size);
    memcpy(c, "CONSPHCX", 8);
    expect_refused(bad_path, c, size, "wrong magic");
    memcpy(c, b, size);
    c[8] = 2;
    expect_refused(bad_path, c, size, "version 2");
    /* A claimed uncompressed size of 2^50 bytes: refused before inflating. */
    memcpy(c, b, size);
    c[22] = 0x04;
    expect_refused(bad_path, c, size, "uncompressed size 2^50");
    free(c);
    free(b);
}

/* ---- hand-built payloads: a valid zlib stream and CRC around inconsistent content ---- */

typedef struct buf {
    unsigned char b[4096];
    size_t n;
} buf;

static void put64(buf *o, uint64_t v)
{
    for (int k = 0; k < 8; ++k) o->b[o->n++] = (unsigned char)(v >> (8 * k));
}

static void putf(buf *o, double d)
{
    uint64_t v;
    memcpy(&v, &d, 8);
    put64(o, v);
}

static void put_bytes(buf *o, const char *s)
{
    put64(o, strlen(s));
    memcpy(o->b + o->n, s, strlen(s));
    o->n += strlen(s);
}

/* The 1D header: meta "", dim 1, n, box [0,1) non-periodic, spacing 0.5. */
static void put_head_1d(buf *o, uint64_t n)
{
    put64(o, 0);
    put64(o, 1);
    put64(o, n);
    putf(o, 0.0);
    putf(o, 1.0);
    put64(o, 0);
    putf(o, 0.5);
}

/* Wraps a payload into a checkpoint file; extra_usize is added to the declared size. */
static void wrap(const char *path, const buf *payload, uint64_t extra_usize)
{
    static unsigned char file[8192];
    uLongf clen = sizeof file - 32;
    compress2(file + 32, &clen, payload->b, (uLong)payload->n, 6);
    uint32_t crc = (uint32_t)crc32(crc32(0L, Z_NULL, 0), payload->b, (uInt)payload->n);
    uint64_t usize = payload->n + extra_usize;
    memcpy(file, "CONSPHCK", 8);
    uint64_t fields[3] = {1u | (uint64_t)crc << 32, usize, clen};
    for (int f = 0; f < 3; ++f)
        for (int k = 0; k < 8; ++k) file[8 + 8 * f + k] = (unsigned char)(fields[f] >> (8 * k));
    spill(path, file, 32 + clen);
}

static void expect_payload_refused(const char *path, const buf *payload, const char *what)
{
    wrap(path, payload, 0);
    size_t size;
    unsigned char *b = check_load_file(path, &size);
    expect_refused(path, b, size, what);
    free(b);
}

/* No particles, fields of one component named a (and b when not NULL), no history. */
static void field_payload(buf *o, const char *a, const char *b)
{
    memset(o, 0, sizeof *o);
    put_head_1d(o, 0);
    put64(o, b ? 2 : 1);
    put_bytes(o, a);
    put64(o, 1);
    if (b) {
        put_bytes(o, b);
        put64(o, 1);
    }
    put64(o, 0);
}

static void test_hostile_payloads(void)
{
    char path[256];
    path_in(path, sizeof path, "hostile.ckpt");
    buf o;

    /* First the valid one the others depart from: two particles, field "f", one history value. */
    memset(&o, 0, sizeof o);
    put_head_1d(&o, 2);
    put64(&o, 1);
    put_bytes(&o, "f");
    put64(&o, 1);
    putf(&o, 0.25);
    putf(&o, 0.75);
    putf(&o, -1.0);
    putf(&o, -2.0);
    put64(&o, 1);
    putf(&o, 42.0);
    wrap(path, &o, 0);
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    consph_particles p;
    int rc = consph_checkpoint_read(path, &meta, &p, &hist, &nh);
    CHECK(rc == CONSPH_OK, "hand-built checkpoint: %s", consph_last_error());
    if (rc == CONSPH_OK) {
        CHECK(p.n == 2 && p.x[0][1] == 0.75 && p.nfields == 1 && p.fields[0].data[1] == -2.0 &&
                  nh == 1 && hist[0] == 42.0 && p.spacing == 0.5,
              "hand-built checkpoint read wrong");
        free(meta);
        free(hist);
        consph_particles_free(&p);
    }
    /* The same stream declaring a larger uncompressed size. */
    wrap(path, &o, 100);
    size_t size;
    unsigned char *b = check_load_file(path, &size);
    expect_refused(path, b, size, "declared size larger than the stream");
    free(b);
    buf keep = o;
    o.b[o.n++] = 0;
    expect_payload_refused(path, &o, "a byte after the history");
    o = keep;
    o.n -= 4;
    expect_payload_refused(path, &o, "payload ends inside the history");

    /* Huge counts: each must be refused without trying to allocate it (ASan would report). */
    const uint64_t huge[] = {(uint64_t)1 << 40, (uint64_t)1 << 61, UINT64_MAX};
    for (size_t k = 0; k < 3; ++k) {
        memset(&o, 0, sizeof o);
        put_head_1d(&o, huge[k]);
        put64(&o, 0);
        putf(&o, 0.5);
        put64(&o, 0);
        expect_payload_refused(path, &o, "huge particle count");

        memset(&o, 0, sizeof o);
        put64(&o, huge[k]);
        expect_payload_refused(path, &o, "huge meta length");

        memset(&o, 0, sizeof o);
        put_head_1d(&o, 1);
        put64(&o, 1);
        put_bytes(&o, "f");
        put64(&o, huge[k]);
        putf(&o, 0.5);
        putf(&o, 0.5);
        put64(&o, 0);
        expect_payload_refused(path, &o, "huge component count");

        memset(&o, 0, sizeof o);
        put_head_1d(&o, 1);
        put64(&o, 0);
        putf(&o, 0.5);
        put64(&o, huge[k]);
        putf(&o, 1.0);
        expect_payload_refused(path, &o, "huge history count");

        memset(&o, 0, sizeof o);
        put_head_1d(&o, 1);
        put64(&o, huge[k]);
        expect_payload_refused(path, &o, "huge field count");

        memset(&o, 0, sizeof o);
        put_head_1d(&o, 1);
        put64(&o, 1);
        put64(&o, huge[k]);
        expect_payload_refused(path, &o, "huge field name length");
    }
    /* Content that cannot be a particle set. */
    memset(&o, 0, sizeof o);
    put64(&o, 0);
    put64(&o, 4);
    expect_payload_refused(path, &o, "dimension 4");
    memset(&o, 0, sizeof o);
    put_head_1d(&o, 1);
    o.n -= 16;
    put64(&o, 2);
    putf(&o, 0.5);
    expect_payload_refused(path, &o, "periodic flag 2");
    field_payload(&o, "f", "f");
    expect_payload_refused(path, &o, "two fields named f");
    field_payload(&o, "", NULL);
    expect_payload_refused(path, &o, "empty field name");
    field_payload(&o, "a_name_of_thirty_two_characters_", NULL);
    expect_payload_refused(path, &o, "field name too long");
}

/* No file and no temporary file when a write fails. */
static void test_atomic(void)
{
    consph_rng r;
    consph_rng_seed(&r, 3);
    consph_particles p;
    make_particles(&p, 3, 10, &r);
    char missing[300];
    path_in(missing, sizeof missing, "no_such_dir/c.ckpt");
    int rc = consph_checkpoint_write(missing, "", &p, NULL, 0);
    CHECK(rc == CONSPH_EIO, "write into a missing directory: rc %d", rc);
    CHECK(!file_exists(missing), "file created in a missing directory");
    /* Invalid particles: refused before anything is written, the old checkpoint kept. */
    char path[256];
    path_in(path, sizeof path, "keep.ckpt");
    CHECK(consph_checkpoint_write(path, "old", &p, NULL, 0) == CONSPH_OK, "%s",
          consph_last_error());
    size_t before_size, after_size;
    unsigned char *before = check_load_file(path, &before_size);
    p.n = p.cap + 1;
    rc = consph_checkpoint_write(path, "new", &p, NULL, 0);
    CHECK(rc == CONSPH_EINVAL, "n > cap: rc %d", rc);
    p.n = 10;
    unsigned char *after = check_load_file(path, &after_size);
    CHECK(after && before_size == after_size && memcmp(before, after, after_size) == 0,
          "failed write changed the existing checkpoint");
    free(before);
    free(after);
    consph_particles_free(&p);
}

/* No "*.tmp.*" left in the test directory. */
static void check_no_temp_files(void)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    while (d && (e = readdir(d)))
        CHECK(strstr(e->d_name, ".tmp.") == NULL, "temporary file '%s' left", e->d_name);
    if (d) closedir(d);
}

/* ---- .pvd ---- */

static void check_same_index(const consph_pvd *a, const consph_pvd *b, const char *what)
{
    CHECK(a->n == b->n, "%s: %zu entries, loaded %zu", what, a->n, b->n);
    for (size_t i = 0; i < a->n && i < b->n; ++i)
        CHECK(memcmp(&a->time[i], &b->time[i], 8) == 0 && strcmp(a->file[i], b->file[i]) == 0,
              "%s: entry %zu is %.17g %s, loaded %.17g %s", what, i, a->time[i], a->file[i],
              b->time[i], b->file[i]);
}

static void expect_pvd_refused(const char *path, const char *text, const char *what)
{
    spill(path, text, strlen(text));
    consph_pvd q;
    int rc = consph_pvd_load(&q, path);
    CHECK(rc == CONSPH_EFORMAT, "%s: rc %d (%s)", what, rc, consph_last_error());
    CHECK(strstr(consph_last_error(), path) != NULL, "%s: message '%s' does not name the file",
          what, consph_last_error());
    if (rc == CONSPH_OK) consph_pvd_free(&q);
}

static void test_pvd(void)
{
    char path[256];
    path_in(path, sizeof path, "run.pvd");
    consph_pvd pvd, q;
    CHECK(consph_pvd_init(&pvd, path) == CONSPH_OK, "init");
    CHECK(!file_exists(path), "init wrote the index");
    const double t[] = {0.0, 0.1 + 0.2, 0.5, 2.0 / 3.0, 2.0};
    const char *names[] = {"snap_000000.vtu", "snap_000010.vtu", "snap-20.vtu", "s 30.vtu",
                           "snap_000040.vtu"};
    for (int k = 0; k < 5; ++k)
        CHECK(consph_pvd_add(&pvd, t[k], names[k]) == CONSPH_OK, "add %s: %s", names[k],
              consph_last_error());
    size_t size;
    char *text = (char *)check_load_file(path, &size);
    CHECK(strstr(text, "<VTKFile type=\"Collection\"") != NULL, "no Collection VTKFile:\n%s", text);
    CHECK(strstr(text, "<DataSet timestep=\"0.5\" file=\"snap-20.vtu\"/>") != NULL,
          "no DataSet entry:\n%s", text);
    free(text);
    CHECK(consph_pvd_load(&q, path) == CONSPH_OK, "load: %s", consph_last_error());
    check_same_index(&pvd, &q, "after adds");
    consph_pvd_free(&q);

    /* Refusals leave the index, in memory and on disk, as it was. */
    unsigned char *before = check_load_file(path, &size);
    const char *bad[] = {"a/b.vtu", "../x.vtu", "x\"y.vtu",  "a&b.vtu", "<x>.vtu",
                         "",        "..",       "tab\t.vtu", "q'.vtu",  "back\\slash"};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k)
        CHECK(consph_pvd_add(&pvd, 3.0, bad[k]) == CONSPH_EINVAL, "name '%s' accepted", bad[k]);
    CHECK(consph_pvd_add(&pvd, 1.0, "late.vtu") == CONSPH_EINVAL, "time going back accepted");
    CHECK(consph_pvd_add(&pvd, 3.0, names[1]) == CONSPH_EINVAL, "file listed twice accepted");
    CHECK(consph_pvd_add(&pvd, NAN, "nan.vtu") == CONSPH_EINVAL, "NaN time accepted");
    CHECK(pvd.n == 5, "refusals changed the index: %zu entries", pvd.n);
    size_t size2;
    unsigned char *after = check_load_file(path, &size2);
    CHECK(size == size2 && memcmp(before, after, size) == 0, "refusals changed the file");
    free(before);
    free(after);
    /* The last entry again is a rewrite, not a second entry. */
    CHECK(consph_pvd_add(&pvd, t[4], names[4]) == CONSPH_OK && pvd.n == 5, "last entry again");

    CHECK(consph_pvd_truncate(&pvd, 0.5) == CONSPH_OK && pvd.n == 3, "truncate: %zu", pvd.n);
    CHECK(consph_pvd_load(&q, path) == CONSPH_OK, "load: %s", consph_last_error());
    check_same_index(&pvd, &q, "after truncate");
    /* A restarted run continues the loaded index. */
    CHECK(consph_pvd_add(&q, 0.75, "snap_000030.vtu") == CONSPH_OK, "%s", consph_last_error());
    consph_pvd_free(&q);
    CHECK(consph_pvd_load(&q, path) == CONSPH_OK && q.n == 4 && q.time[3] == 0.75, "restart add");
    consph_pvd_free(&q);
    CHECK(consph_pvd_truncate(&pvd, -1.0) == CONSPH_OK && pvd.n == 0, "truncate all");
    CHECK(consph_pvd_load(&q, path) == CONSPH_OK && q.n == 0, "empty index loads");
    consph_pvd_free(&q);
    consph_pvd_free(&pvd);

    char missing[300];
    path_in(missing, sizeof missing, "nodir/run.pvd");
    CHECK(consph_pvd_init(&pvd, missing) == CONSPH_OK, "init");
    CHECK(consph_pvd_add(&pvd, 0.0, "a.vtu") == CONSPH_EIO && pvd.n == 0,
          "add into a missing directory");
    consph_pvd_free(&pvd);
    CHECK(consph_pvd_load(&q, missing) == CONSPH_EIO, "load of a missing file");

    const char *head = "<?xml version=\"1.0\"?>\n"
                       "<VTKFile type=\"Collection\" version=\"0.1\" "
                       "byte_order=\"LittleEndian\">\n  <Collection>\n";
    const char *tail = "  </Collection>\n</VTKFile>\n";
    char doc[1024];
#define PVD_CASE(entries, tl, what)                                                                \
    do {                                                                                           \
        snprintf(doc, sizeof doc, "%s%s%s", head, entries, tl);                                    \
        expect_pvd_refused(path, doc, what);                                                       \
    } while (0)
    PVD_CASE("    <DataSet timestep=\"0\" file=\"a/b.vtu\"/>\n", tail, "slash in a loaded name");
    PVD_CASE("    <DataSet timestep=\"x\" file=\"a.vtu\"/>\n", tail, "bad time");
    PVD_CASE("    <DataSet timestep=\"nan\" file=\"a.vtu\"/>\n", tail, "NaN time");
    PVD_CASE("    <DataSet timestep=\"0\" group=\"\" file=\"a.vtu\"/>\n", tail, "extra attribute");
    PVD_CASE("    <DataSet timestep=\"0\" file=\"a.vtu\"/> \n", tail, "trailing space");
    PVD_CASE("    <DataSet timestep=\"1\" file=\"a.vtu\"/>\n"
             "    <DataSet timestep=\"0\" file=\"b.vtu\"/>\n",
             tail, "times going back");
    PVD_CASE("    <DataSet timestep=\"0\" file=\"a.vtu\"/>\n", "  </Collection>\n",
             "missing closing tag");
    PVD_CASE("", "  </Collection>\n</VTKFile>\nextra\n", "line after the end");
    PVD_CASE("", "  </Collection>\n</VTKFile>", "last line not ended");
    expect_pvd_refused(path, "<VTKFile type=\"UnstructuredGrid\">\n", "not a collection");
    expect_pvd_refused(path, "", "empty file");
#undef PVD_CASE
}

/* ---- stop requests ---- */

static volatile sig_atomic_t app_handler_calls;
static void app_handler(int sig)
{
    (void)sig;
    ++app_handler_calls;
}

static void test_stop_in_process(void)
{
    struct sigaction app, now;
    memset(&app, 0, sizeof app);
    app.sa_handler = app_handler;
    sigemptyset(&app.sa_mask);
    sigaction(SIGTERM, &app, NULL);
    signal(SIGINT, SIG_DFL);

    CHECK(consph_stop_install() == CONSPH_OK, "%s", consph_last_error());
    CHECK(consph_stop_requested() == 0, "a stop before any signal");
    raise(SIGTERM);
    CHECK(consph_stop_requested() == SIGTERM, "after SIGTERM: %d", consph_stop_requested());
    CHECK(app_handler_calls == 0, "the application's handler ran while stop was installed");
    raise(SIGINT); /* a first SIGINT: recorded, not fatal; the first signal stays the answer */
    CHECK(consph_stop_requested() == SIGTERM, "after SIGINT: %d", consph_stop_requested());
    CHECK(consph_stop_install() == CONSPH_OK && consph_stop_requested() == 0,
          "installing again forgets the signals");
    consph_stop_uninstall();

    sigaction(SIGTERM, NULL, &now);
    CHECK(now.sa_handler == app_handler, "SIGTERM handler not restored");
    sigaction(SIGINT, NULL, &now);
    CHECK(now.sa_handler == SIG_DFL, "SIGINT action not restored");
    raise(SIGTERM);
    CHECK(app_handler_calls == 1, "restored handler called %d times", (int)app_handler_calls);
    consph_stop_uninstall(); /* not installed: nothing to do */
    signal(SIGTERM, SIG_DFL);
}

/* In a child: the order of events `scenario` names, then a second signal that must end it.
 * The child reports a failure before the end by its exit status. */
enum { OUTFILE_AFTER_INSTALL, OUTFILE_BEFORE_INSTALL, OUTFILE_AFTER_UNINSTALL };

static void child_run(int scenario, int sig, const char *target)
{
    signal(SIGINT, SIG_DFL);
    signal(SIGTERM, SIG_DFL);
    consph_outfile of, first;
    if (scenario == OUTFILE_BEFORE_INSTALL && consph_outfile_open(&of, target)) _exit(10);
    if (consph_stop_install()) _exit(11);
    if (scenario == OUTFILE_AFTER_INSTALL && consph_outfile_open(&of, target)) _exit(10);
    if (scenario == OUTFILE_AFTER_UNINSTALL) {
        /* A file opened and committed while stop is installed, then a new one after it is gone:
         * the default action is back, and so must be the temp-file cleanup. */
        char other[300];
        snprintf(other, sizeof other, "%s.first", target);
        if (consph_outfile_open(&first, other) || consph_outfile_commit(&first)) _exit(12);
        consph_stop_uninstall();
        if (consph_outfile_open(&of, target)) _exit(10);
        fputs("partial", of.fp);
        fflush(of.fp);
        if (access(of.tmp_path, F_OK) != 0) _exit(13);
        raise(sig);
        _exit(14);
    }
    fputs("partial", of.fp);
    fflush(of.fp);
    if (access(of.tmp_path, F_OK) != 0) _exit(13);
    raise(sig);
    if (consph_stop_requested() != sig) _exit(15);
    if (access(of.tmp_path, F_OK) != 0) _exit(16); /* the first signal removes nothing */
    raise(sig);
    _exit(14); /* still alive after the second signal */
}

static void test_stop_second_signal(void)
{
    const char *names[] = {"outfile opened after install", "outfile opened before install",
                           "outfile opened after uninstall"};
    const int sigs[] = {SIGINT, SIGTERM};
    for (int scenario = 0; scenario < 3; ++scenario)
        for (int s = 0; s < 2; ++s) {
            char target[256], tmp[300];
            path_in(target, sizeof target, "interrupted.vtu");
            fflush(NULL);
            pid_t pid = fork();
            if (pid == 0) child_run(scenario, sigs[s], target);
            int status = 0;
            waitpid(pid, &status, 0);
            CHECK(WIFSIGNALED(status) && WTERMSIG(status) == sigs[s], "%s, signal %d: child %s %d",
                  names[scenario], sigs[s],
                  WIFSIGNALED(status) ? "killed by signal" : "exited with",
                  WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status));
            snprintf(tmp, sizeof tmp, "%s.tmp.%ld", target, (long)pid);
            CHECK(!file_exists(tmp), "%s, signal %d: temporary file left", names[scenario],
                  sigs[s]);
            CHECK(!file_exists(target), "%s: target created", names[scenario]);
            unlink(tmp);
            snprintf(tmp, sizeof tmp, "%s.first", target);
            unlink(tmp);
        }
}

/* ---- progress ---- */

static void test_progress_not_a_terminal(void)
{
    char path[256];
    path_in(path, sizeof path, "stderr.txt");
    fflush(stderr);
    int saved = dup(STDERR_FILENO);
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    dup2(fd, STDERR_FILENO);
    close(fd);
    consph_progress pr;
    consph_progress_start(&pr, 0);
    for (long s = 1; s <= 1000; ++s) consph_progress_update(&pr, s, 0.001 * s, 1000, 1.0);
    consph_progress_end(&pr);
    fflush(stderr);
    dup2(saved, STDERR_FILENO);
    close(saved);
    struct stat st;
    CHECK(stat(path, &st) == 0 && st.st_size == 0, "progress wrote %ld bytes to a file",
          (long)st.st_size);
    CHECK(pr.enabled == 0, "progress enabled on a file");
    unlink(path);
}

/* On a pseudo-terminal the line is drawn; skipped where no pty can be had. */
static void test_progress_terminal(void)
{
    int master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || grantpt(master) || unlockpt(master)) {
        printf("progress on a terminal: no pseudo-terminal, not checked\n");
        if (master >= 0) close(master);
        return;
    }
    int slave = open(ptsname(master), O_RDWR | O_NOCTTY);
    if (slave < 0) {
        close(master);
        printf("progress on a terminal: cannot open the pty, not checked\n");
        return;
    }
    fflush(stderr);
    int saved = dup(STDERR_FILENO);
    dup2(slave, STDERR_FILENO);
    consph_progress pr;
    consph_progress_start(&pr, 0);
    int enabled = pr.enabled;
    consph_progress_update(&pr, 10, 0.125, 100, 0.0);
    consph_progress_update(&pr, 11, 0.25, 100, 0.0); /* within 0.25 s: not drawn */
    consph_progress_end(&pr);
    fflush(stderr);
    dup2(saved, STDERR_FILENO);
    close(saved);
    char out[512] = {0};
    size_t len = 0;
    struct pollfd pfd = {master, POLLIN, 0};
    while (len < sizeof out - 1 && poll(&pfd, 1, 200) > 0) {
        ssize_t got = read(master, out + len, sizeof out - 1 - len);
        if (got <= 0) break;
        len += (size_t)got;
    }
    close(slave);
    close(master);
    CHECK(enabled, "progress not enabled on a terminal");
    CHECK(strncmp(out, "\rstep 10  t=0.125  ", 19) == 0 && strstr(out, "steps/s  ETA ") != NULL,
          "progress line '%s'", out);
    CHECK(strstr(out, "step 11") == NULL, "redrawn within the period: '%s'", out);
    CHECK(len >= 4 && memcmp(out + len - 4, "\r\033[K", 4) == 0, "end does not clear the line");
}

int main(void)
{
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    test_round_trip();
    test_corruption();
    test_hostile_payloads();
    test_atomic();
    test_pvd();
    test_stop_in_process();
    test_stop_second_signal();
    test_progress_not_a_terminal();
    test_progress_terminal();
    check_no_temp_files();
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", dir);
    return check_summary("test_checkpoint");
}
