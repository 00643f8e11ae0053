/* Particle readers: bitwise round trips through the writers, the .vtu encodings VTK writes
 * (fixtures made by VTK 9.1's vtkXMLUnstructuredGridWriter in fuzz/corpus/vtu/), every bad-file
 * case with its message, the zlib decoder, and a replay of the fuzz corpus and of
 * every crash kept in fuzz/regressions/ through the fuzz entry points. */
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "../fuzz/fuzz_targets.h"
#include "check.h"
#include "consph/io.h"
#include "io/read_internal.h"

static char source_dir[1024];
static char tmp_dir[256];

/* The source tree, from this file's path (CMake compiles it by absolute path). */
static void find_source_dir(void)
{
    const char *env = getenv("CONSPH_SOURCE_DIR");
    if (env) {
        snprintf(source_dir, sizeof source_dir, "%s", env);
        return;
    }
    snprintf(source_dir, sizeof source_dir, "%s", __FILE__);
    char *slash = strrchr(source_dir, '/');
    if (slash) *slash = '\0';
    slash = strrchr(source_dir, '/');
    if (slash)
        *slash = '\0';
    else
        snprintf(source_dir, sizeof source_dir, "..");
}

static int same_particles(const consph_particles *a, const consph_particles *b, int vtu)
{
    if (a->dim != b->dim || a->n != b->n) return 0;
    for (int d = 0; d < a->dim; ++d)
        if (memcmp(a->x[d], b->x[d], a->n * sizeof(double))) return 0;
    for (int d = 0; d < a->dim; ++d)
        if (a->box.lo[d] != b->box.lo[d] || a->box.hi[d] != b->box.hi[d] ||
            a->box.periodic[d] != b->box.periodic[d])
            return 0;
    if (a->spacing != b->spacing) return 0;
    for (int f = 0; f < a->nfields; ++f) {
        const consph_field *fa = &a->fields[f], *fb = consph_particles_find(b, fa->name);
        if (!fb) return 0;
        /* VTU pads 2-vectors to 3 components. */
        int nc = fa->ncomp;
        if (fb->ncomp != nc && !(vtu && nc == 2 && fb->ncomp == 3)) return 0;
        for (int c = 0; c < nc; ++c)
            if (memcmp(fa->data + (size_t)c * a->cap, fb->data + (size_t)c * b->cap,
                       a->n * sizeof(double)))
                return 0;
    }
    return 1;
}

/* A particle set with awkward numbers: non-unit box, mixed periodicity, a 2-vector field. */
static void make_set(consph_particles *p, int dim, size_t n, unsigned seed)
{
    consph_box box = consph_box_unit(dim, 0);
    for (int a = 0; a < dim; ++a) {
        box.lo[a] = -0.3 * (a + 1);
        box.hi[a] = 1.0 / 3.0 + a;
        box.periodic[a] = a % 2 == 0;
    }
    consph_particles_init(p, dim, n, &box);
    consph_rng rng;
    consph_rng_seed(&rng, seed);
    for (int a = 0; a < dim; ++a)
        for (size_t i = 0; i < n; ++i)
            p->x[a][i] = box.lo[a] + consph_rng_uniform(&rng) * (box.hi[a] - box.lo[a]);
    p->x[0][0] = box.lo[0]; /* exactly on the walls: inside */
    if (dim > 1) p->x[1][1] = box.hi[1];
    p->spacing = 0.1 / 3.0;
    double *vol = consph_particles_field(p, "volume", 1);
    double *u = consph_particles_field(p, "u", 2);
    for (size_t i = 0; i < n; ++i) {
        vol[i] = 1e-3 * (1.0 + consph_rng_uniform(&rng));
        u[i] = sin((double)i) * 1e-300;
        u[p->cap + i] = -1.0 / (double)(i + 7);
    }
}

static void test_round_trip(void)
{
    for (int dim = 1; dim <= 3; ++dim)
        for (int vtu = 0; vtu <= 1; ++vtu) {
            consph_particles p, q, r;
            make_set(&p, dim, 257, (unsigned)(11 * dim + vtu));
            char path[512];
            snprintf(path, sizeof path, "%s/rt%d.%s", tmp_dir, dim, vtu ? "vtu" : "csv");
            CHECK(consph_write_particles(path, &p) == CONSPH_OK, "%s", consph_last_error());
            consph_read_report rep;
            int rc = consph_read_particles(path, NULL, &q, &rep);
            CHECK(rc == CONSPH_OK, "%s: %s", path, consph_last_error());
            if (rc == CONSPH_OK) {
                CHECK(same_particles(&p, &q, vtu), "%dD %s round trip not bitwise", dim,
                      vtu ? "vtu" : "csv");
                CHECK(rep.box_from_file && rep.periodic_from_file && rep.spacing_from_file,
                      "box, periodicity, spacing from the file");
                CHECK(rep.volumes == CONSPH_VOLUMES_COLUMN && rep.wrapped == 0, "volumes");
                /* The same with every refill splitting values and lines at odd places. */
                for (size_t chunk = 1; chunk <= 7; chunk += 3) {
                    consph_rd_chunk = chunk;
                    rc = consph_read_particles(path, NULL, &r, NULL);
                    consph_rd_chunk = 0;
                    CHECK(rc == CONSPH_OK && same_particles(&q, &r, 0),
                          "%s with %zu-byte reads: %s", path, chunk, consph_last_error());
                    if (rc == CONSPH_OK) consph_particles_free(&r);
                }
                consph_particles_free(&q);
            }
            consph_particles_free(&p);
        }
}

/* The bytes of a file written with `threads` OpenMP threads (NULL on failure). */
static unsigned char *write_with_threads(const char *path, const consph_particles *p,
                                         consph_vtu_encoding enc, int threads, size_t *size)
{
#ifdef _OPENMP
    int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
#else
    (void)threads;
#endif
    int rc = consph_write_particles_enc(path, p, enc);
#ifdef _OPENMP
    omp_set_num_threads(saved);
#endif
    CHECK(rc == CONSPH_OK, "%s: %s", path, consph_last_error());
    return rc == CONSPH_OK ? check_load_file(path, size) : NULL;
}

/* Every VTU encoding reads back bitwise, at sizes around the writer's zlib block of 2^18 bytes
 * (32768 doubles: one value, exactly one full block, a partial last block, more blocks than
 * one compression batch), and the file does not depend on the thread count. */
static void test_vtu_encodings(void)
{
    static const struct {
        int dim;
        size_t n;
    } sizes[] = {{1, 1}, {2, 32768}, {3, 12000}, {3, 200003}};
    static const char *const read_as[] = {"ascii", "appended raw", "appended raw, zlib"};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; ++k)
        for (int enc = CONSPH_VTU_ASCII; enc <= CONSPH_VTU_ZLIB; ++enc) {
            consph_particles p, q;
            make_set(&p, sizes[k].dim, sizes[k].n, (unsigned)(100 + k));
            char path[512];
            snprintf(path, sizeof path, "%s/enc_%s_%zu.vtu", tmp_dir,
                     consph_vtu_encoding_name((consph_vtu_encoding)enc), k);
            size_t size1 = 0, size2 = 0;
            unsigned char *two = NULL;
            if (enc != CONSPH_VTU_ASCII)
                two = write_with_threads(path, &p, (consph_vtu_encoding)enc, 2, &size2);
            unsigned char *one = write_with_threads(path, &p, (consph_vtu_encoding)enc, 1, &size1);
            if (two)
                CHECK(one && size1 == size2 && !memcmp(one, two, size1),
                      "%s: the file differs between 1 and 2 threads", path);
            free(one);
            free(two);
            consph_read_report rep;
            int rc = consph_read_particles(path, NULL, &q, &rep);
            CHECK(rc == CONSPH_OK, "%s: %s", path, consph_last_error());
            if (rc == CONSPH_OK) {
                CHECK(same_particles(&p, &q, 1), "%s: round trip not bitwise", path);
                CHECK(strcmp(rep.encoding, read_as[enc]) == 0, "%s read as '%s'", path,
                      rep.encoding);
                consph_particles_free(&q);
            }
            consph_particles_free(&p);
        }
    consph_particles p;
    make_set(&p, 2, 10, 1);
    char path[512];
    snprintf(path, sizeof path, "%s/bad_enc.vtu", tmp_dir);
    CHECK(consph_write_particles_enc(path, &p, (consph_vtu_encoding)7) == CONSPH_EINVAL &&
              strstr(consph_last_error(), "ascii,binary,zlib") && access(path, F_OK) != 0,
          "unknown encoding: %s", consph_last_error());
    consph_particles_free(&p);
}

/* The fixtures of fuzz/corpus/vtu written by VTK: 5 points, double coordinates, a Float64
 * 'volume', a Float32 2-vector 'u' = (i, -i), FieldData box [0,1]^2 and periodic (1, 0). */
static void test_vtk_fixtures(void)
{
    static const struct {
        const char *file, *encoding;
    } fx[] = {{"vtk_ascii.vtu", "ascii"},
              {"vtk_binary.vtu", "binary"},
              {"vtk_binary_u64_be.vtu", "binary"},
              {"vtk_appended_raw.vtu", "appended raw"},
              {"vtk_appended_b64_u64.vtu", "appended base64"},
              {"vtk_binary_zlib.vtu", "binary, zlib"},
              {"vtk_appended_raw_zlib_be.vtu", "appended raw, zlib"},
              {"vtk_appended_b64_zlib.vtu", "appended base64, zlib"}};
    static const double px[5] = {0.1, 0.3, 0.5, 0.7, 0.9}, py[5] = {0.3, 0.3, 0.7, 0.1, 0.9};
    for (size_t k = 0; k < sizeof fx / sizeof fx[0]; ++k) {
        char path[1200];
        snprintf(path, sizeof path, "%s/fuzz/corpus/vtu/%s", source_dir, fx[k].file);
        consph_particles p;
        consph_read_report rep;
        int rc = consph_read_particles(path, NULL, &p, &rep);
        CHECK(rc == CONSPH_OK, "%s", consph_last_error());
        if (rc) continue;
        CHECK(p.dim == 2 && p.n == 5, "%s: %dD, %zu points", fx[k].file, p.dim, p.n);
        CHECK(!strcmp(rep.encoding, fx[k].encoding), "%s: encoding '%s'", fx[k].file, rep.encoding);
        int ok = 1;
        for (size_t i = 0; i < 5 && p.n == 5; ++i) ok &= p.x[0][i] == px[i] && p.x[1][i] == py[i];
        CHECK(ok, "%s: coordinates", fx[k].file);
        const consph_field *vol = consph_particles_find(&p, "volume");
        const consph_field *u = consph_particles_find(&p, "u");
        CHECK(vol && u && u->ncomp == 2, "%s: fields", fx[k].file);
        for (size_t i = 0; vol && u && i < 5; ++i)
            CHECK(vol->data[i] == 0.2 && u->data[i] == (double)i &&
                      u->data[p.cap + i] == -(double)i,
                  "%s: point %zu fields", fx[k].file, i);
        CHECK(p.box.hi[0] == 1 && p.box.hi[1] == 1 && p.box.periodic[0] == 1 &&
                  p.box.periodic[1] == 0,
              "%s: box and periodicity", fx[k].file);
        CHECK_NEAR(p.spacing, sqrt(0.2), 1e-15, "%s: spacing (V/N)^(1/2)", fx[k].file);
        consph_particles_free(&p);
    }
}

/* Reads text as a file of the given kind; returns the status and leaves the message. */
static int read_text(const char *text, consph_particle_format fmt, const consph_read_options *opt,
                     consph_particles *p, consph_read_report *rep)
{
    consph_particles local;
    consph_read_report lrep;
    int rc = consph_read_particles_mem(fmt == CONSPH_FORMAT_CSV ? "t.csv" : "t.vtu", fmt, text,
                                       strlen(text), opt, p ? p : &local, rep ? rep : &lrep);
    if (!p && rc == CONSPH_OK) consph_particles_free(&local);
    return rc;
}

/* `text` is rejected with `code` and a message containing every one of `parts`. */
#define EXPECT_BAD(text, fmt, opt, code, ...)                                                      \
    do {                                                                                           \
        const char *parts_[] = {__VA_ARGS__, NULL};                                                \
        int rc_ = read_text(text, fmt, opt, NULL, NULL);                                           \
        const char *msg_ = consph_last_error();                                                    \
        int has_ = rc_ == (code);                                                                  \
        for (int k_ = 0; parts_[k_]; ++k_) has_ &= strstr(msg_, parts_[k_]) != NULL;               \
        CHECK(has_, "rc %d (want %d), message: %s", rc_, (int)(code), msg_);                       \
    } while (0)

#define BOX2 "# box 0:1 0:1\n"

static void test_bad_csv(void)
{
    const consph_particle_format C = CONSPH_FORMAT_CSV;
    EXPECT_BAD(BOX2 "x,yy,rho\n0.1,0.2,1\n", C, NULL, CONSPH_EFORMAT, "t.csv:2:", "no column 'y'",
               "found: x,yy,rho", "expected", "x,y,z");
    EXPECT_BAD("0.1,0.2\n0.3,0.4\n", C, NULL, CONSPH_EFORMAT, "t.csv:1:", "no header row");
    EXPECT_BAD(BOX2 "x,y\n0.1,0.2\n0.3\n", C, NULL, CONSPH_EFORMAT, "t.csv:4:", "short row",
               "1 value");
    EXPECT_BAD(BOX2 "x,y\n0.1,0.2,0.5\n", C, NULL, CONSPH_EFORMAT, "t.csv:3:", "extra column");
    EXPECT_BAD(BOX2 "x,y\n0.1,abc\n", C, NULL, CONSPH_EFORMAT, "t.csv:3:", "column 'y'",
               "'abc' is not a number");
    EXPECT_BAD(BOX2 "x,y\n0.1,0.2\n0.5,nan\n", C, NULL, CONSPH_EFORMAT,
               "t.csv:4:", "'nan' is not a finite number");
    EXPECT_BAD(BOX2 "x,y\n-inf,0.2\n", C, NULL, CONSPH_EFORMAT, "t.csv:3:", "column 'x'",
               "'-inf' is not a finite");
    EXPECT_BAD(BOX2 "x,y\n1e999,0.2\n", C, NULL, CONSPH_EFORMAT, "not a finite number");
    EXPECT_BAD(BOX2 "x,y\n0.1,\n", C, NULL, CONSPH_EFORMAT, "t.csv:3:", "column 'y' is empty");
    EXPECT_BAD("", C, NULL, CONSPH_EFORMAT, "t.csv: empty file");
    EXPECT_BAD("# only\n# comments\n", C, NULL, CONSPH_EFORMAT, "t.csv:2:", "no header row");
    EXPECT_BAD(BOX2 "x,y\n", C, NULL, CONSPH_EFORMAT, "t.csv:2:", "header row but no particles");
    /* Two particles at one place: both rows named, also across skipped lines. */
    EXPECT_BAD(BOX2 "x,y\n0.1,0.2\n0.5,0.5\n\n# note\n0.1,0.2\n", C, NULL, CONSPH_EFORMAT,
               "t.csv:7:", "same position as the particle on line 3");
    EXPECT_BAD(BOX2 "x,y\n0.1,-0\n0.1,0\n", C, NULL, CONSPH_EFORMAT, "t.csv:4:", "line 3");
    EXPECT_BAD(BOX2 "x,y\n0.1,0.2\n0.1,1.5\n", C, NULL, CONSPH_EFORMAT,
               "t.csv:4:", "outside the box", "y = 1.5", "not periodic");
    /* On a periodic axis, wrapping can make two particles coincide. */
    EXPECT_BAD(BOX2 "# periodic 1 0\nx,y\n0.25,0.2\n1.25,0.2\n", C, NULL, CONSPH_EFORMAT,
               "t.csv:5:", "line 4", "after wrapping");
    EXPECT_BAD(BOX2 "x,y,volume\n0.1,0.2,1\n0.3,0.2,-1\n", C, NULL, CONSPH_EFORMAT,
               "t.csv:4:", "volume = -1 is not positive");
    EXPECT_BAD(BOX2 "x,y,m,rho\n0.1,0.2,1,0\n", C, NULL, CONSPH_EFORMAT,
               "t.csv:3:", "rho = 0 is not positive");
    EXPECT_BAD(BOX2 "# n 3\nx,y\n0.1,0.2\n0.3,0.2\n", C, NULL, CONSPH_EFORMAT, "'# n 3'",
               "2 particle rows", "truncated");
    EXPECT_BAD(BOX2 "x,y,m,rho\n0.5,0.5,1e-300,1e300\n", C, NULL, CONSPH_EFORMAT,
               "t.csv:3:", "m/rho = 1e-300/1e+300 is not a positive double");
    EXPECT_BAD("# box -1e308:1e308 0:1\nx,y\n0.5,0.5\n", C, NULL, CONSPH_EFORMAT,
               "too large or too small");
    EXPECT_BAD("x,y\n0.1,0.2\n", C, NULL, CONSPH_EINVAL, "no box");
    EXPECT_BAD("# box 0:1\nx,y\n0.1,0.2\n", C, NULL, CONSPH_EFORMAT, "'# box' has 1 axes");
    EXPECT_BAD("# box 0:1 1:0\nx,y\n0.1,0.2\n", C, NULL, CONSPH_EFORMAT, "t.csv:1:", "'1:0'");
    EXPECT_BAD("# dim 3\nx,y\n0.1,0.2\n", C, NULL, CONSPH_EFORMAT, "no column 'z'", "'# dim 3'");
    EXPECT_BAD(BOX2 "x,y,x\n1,2,3\n", C, NULL, CONSPH_EFORMAT, "names column 'x' twice");
    EXPECT_BAD("<?xml version=\"1.0\"?>\n<VTKFile>", C, NULL, CONSPH_EFORMAT, "t.csv:1:", "XML");
    static const char nul[] = BOX2 "x,y\n0.1,0.2\0\n";
    consph_particles p;
    int rc = consph_read_particles_mem("t.csv", C, nul, sizeof nul - 1, NULL, &p, NULL);
    CHECK(rc == CONSPH_EFORMAT && strstr(consph_last_error(), "t.csv:3: binary data"), "%s",
          consph_last_error());

    consph_read_options o;
    memset(&o, 0, sizeof o);
    o.dim = 3;
    EXPECT_BAD(BOX2 "x,y\n0.1,0.2\n", C, &o, CONSPH_EINVAL, "t.csv:2:", "no column 'z'",
               "3D particles were asked for");
    o.dim = 2;
    EXPECT_BAD("# box 0:1 0:1 0:1\nx,y,z\n0.1,0.2,0.3\n", C, &o, CONSPH_EINVAL,
               "t.csv:2:", "'z' column", "2D particles were asked for");
    o.dim = 0;
    o.have_box = 1;
    o.box = consph_box_unit(3, 0);
    EXPECT_BAD(BOX2 "x,y\n0.1,0.2\n", C, &o, CONSPH_EINVAL, "given box has 3 axes");
}

static void test_good_csv(void)
{
    const consph_particle_format C = CONSPH_FORMAT_CSV;
    consph_particles p;
    consph_read_report rep;
    /* Foreign conventions: case, blanks, CRLF, quotes, m/rho, a vector, comment lines. */
    int rc = read_text("# box 0:2 0:1\r\n# periodic 1 0\r\n\"X\", Y ,m,rho,u_0,u_1\r\n"
                       "0.5,0.5,1,2,3,4\r\n1.5, 0.5 ,1,1,0,0\r\n\r\n# note\r\n"
                       "2.25,0.75,0.5,1,1e-3,-2.5e+2\r\n",
                       C, NULL, &p, &rep);
    CHECK(rc == CONSPH_OK, "%s", consph_last_error());
    if (rc == CONSPH_OK) {
        CHECK(p.dim == 2 && p.n == 3, "2D, 3 particles");
        CHECK(rep.volumes == CONSPH_VOLUMES_MASS_RHO && rep.has_mass, "volumes from m/rho");
        const consph_field *vol = consph_particles_find(&p, "volume"),
                           *m = consph_particles_find(&p, "mass"),
                           *u = consph_particles_find(&p, "u");
        CHECK(vol && m && u && u->ncomp == 2, "volume, mass and a 2-vector u");
        if (vol && m && u) {
            CHECK(vol->data[0] == 0.5 && vol->data[1] == 1.0 && vol->data[2] == 0.5, "m/rho");
            CHECK(u->data[2] == 1e-3 && u->data[p.cap + 2] == -250.0, "u of the last row");
        }
        CHECK(p.x[0][2] == 0.25 && rep.wrapped == 1, "x = 2.25 wrapped to 0.25 (%g), %zu wrapped",
              p.x[0][2], rep.wrapped);
        CHECK_NEAR(p.spacing, sqrt(2.0 / 3.0), 1e-15, "spacing (V/N)^(1/dim)");
        consph_particles_free(&p);
    }
    /* The caller's box and periodicity override the file's; x = hi wraps to lo. */
    consph_read_options o;
    memset(&o, 0, sizeof o);
    o.have_box = 1;
    o.box = consph_box_unit(2, 0);
    o.box.hi[0] = 2.0;
    o.have_periodic = 1;
    o.periodic[0] = 1;
    rc = read_text("x,y\n2,0.5\n1,1\n", C, &o, &p, &rep);
    CHECK(rc == CONSPH_OK && p.x[0][0] == 0.0 && p.x[1][1] == 1.0 && rep.wrapped == 1 &&
              !rep.box_from_file && rep.volumes == CONSPH_VOLUMES_NONE,
          "override: %s", consph_last_error());
    if (rc == CONSPH_OK) consph_particles_free(&p);
    /* 1D needs saying so. */
    rc = read_text("# dim 1\n# box 0:1\nx\n0.5\n0.25\n", C, NULL, &p, &rep);
    CHECK(rc == CONSPH_OK && p.dim == 1 && p.n == 2, "1D: %s", consph_last_error());
    if (rc == CONSPH_OK) consph_particles_free(&p);
}

static char *file_text(const char *name, size_t *size)
{
    char path[1200];
    snprintf(path, sizeof path, "%s/fuzz/corpus/vtu/%s", source_dir, name);
    char *t = (char *)check_load_file(path, size);
    if (t) t[*size] = '\0';
    return t;
}

static char *replace(const char *text, const char *from, const char *to)
{
    const char *at = strstr(text, from);
    if (!at) return NULL;
    size_t n = strlen(text) + strlen(to) + 1;
    char *out = malloc(n);
    snprintf(out, n, "%.*s%s%s", (int)(at - text), text, to, at + strlen(from));
    return out;
}

static void test_bad_vtu(void)
{
    const consph_particle_format V = CONSPH_FORMAT_VTU;
    size_t n;
    char *ascii = file_text("consph2d.vtu", &n);
    char *zlib = file_text("vtk_binary_zlib.vtu", &n);
    char *app = file_text("vtk_appended_raw.vtu", &n);
    CHECK(ascii && zlib && app, "fixtures in %s/fuzz/corpus/vtu", source_dir);
    if (!ascii || !zlib || !app) return;
    char *t = strdup(ascii);
    t[strlen(t) / 2] = '\0';
    EXPECT_BAD(t, V, NULL, CONSPH_EFORMAT, "t.vtu:", "truncated file");
    free(t);
    EXPECT_BAD("<html><body>hi</body></html>", V, NULL, CONSPH_EFORMAT,
               "t.vtu:1:", "not a VTK XML file", "<html>");
    EXPECT_BAD("x,y\n0.1,0.2\n", V, NULL, CONSPH_EFORMAT, "t.vtu:1:", "not an XML file");
    EXPECT_BAD("", V, NULL, CONSPH_EFORMAT, "t.vtu: empty file");
    EXPECT_BAD("<VTKFile type=\"PolyData\"></VTKFile>", V, NULL, CONSPH_EFORMAT,
               "only UnstructuredGrid");
    EXPECT_BAD("<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid></Piece>", V, NULL,
               CONSPH_EFORMAT, "</Piece> closes <UnstructuredGrid>");
    EXPECT_BAD("<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid></UnstructuredGrid></VTKFile>",
               V, NULL, CONSPH_EFORMAT, "no <Piece>");
    /* A value that does not parse, and one that is not finite, named with the array's line. */
    t = replace(
        ascii, "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n",
        "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\nnan ");
    CHECK(t != NULL, "ascii fixture layout");
    if (t) {
        EXPECT_BAD(t, V, NULL, CONSPH_EFORMAT, "<DataArray Name=\"Points\">",
                   "'nan' is not a finite");
        free(t);
    }
    t = replace(ascii, "NumberOfPoints=\"9\"", "NumberOfPoints=\"10\"");
    CHECK(t != NULL, "ascii fixture has 9 points");
    if (t) {
        EXPECT_BAD(t, V, NULL, CONSPH_EFORMAT,
                   "9 values, NumberOfPoints x NumberOfComponents = 10");
        free(t);
    }
    /* The dimension from the box disagrees with the caller's, or with a non-zero z. */
    consph_read_options o;
    memset(&o, 0, sizeof o);
    o.dim = 3;
    EXPECT_BAD(ascii, V, &o, CONSPH_EINVAL, "FieldData array 'box'", "3D particles were asked");
    t = replace(
        ascii,
        "Name=\"box\" NumberOfTuples=\"1\" NumberOfComponents=\"4\" format=\"ascii\"> 0 1 0 1",
        "Name=\"box\" NumberOfTuples=\"1\" NumberOfComponents=\"6\" format=\"ascii\"> 0 1 0 1 0 1");
    CHECK(t != NULL, "box in the ascii fixture");
    if (t) {
        consph_particles p;
        int rc = read_text(t, V, NULL, &p, NULL);
        CHECK(rc == CONSPH_EFORMAT || rc == CONSPH_EINVAL, "3D box, 2D data");
        free(t);
    }
    o.dim = 3;
    EXPECT_BAD(zlib, V, &o, CONSPH_EINVAL, "asked for");
    /* Compression: a corrupt block, an unsupported compressor. */
    t = replace(zlib, "eF5jYEAGH+xRuEA+ABdOAl8=", "eF5jYEAGH+xRuEA+ABdOAl9=");
    if (!t) t = replace(zlib, "eF5", "eF6");
    CHECK(t != NULL, "zlib fixture");
    if (t) {
        EXPECT_BAD(t, V, NULL, CONSPH_EFORMAT, "zlib block");
        free(t);
    }
    t = replace(zlib, "vtkZLibDataCompressor", "vtkLZ4DataCompressor");
    if (t) {
        EXPECT_BAD(t, V, NULL, CONSPH_EFORMAT, "vtkLZ4DataCompressor", "not supported");
        free(t);
    }
    /* Appended data cut short, or missing. */
    char *cut = strstr(app, "_");
    if (cut) {
        t = strdup(app);
        t[cut - app + 40] = '\0';
        EXPECT_BAD(t, V, NULL, CONSPH_EFORMAT, "truncated");
        t[cut - app - 40] = '\0';
        strcat(t, "</UnstructuredGrid></VTKFile>");
        consph_particles p;
        int rc = read_text(t, V, NULL, &p, NULL);
        CHECK(rc == CONSPH_EFORMAT, "appended arrays without data: %s", consph_last_error());
        free(t);
    }
    free(ascii);
    free(zlib);
    free(app);
}

static void test_files(void)
{
    consph_particles p;
    char path[512];
    snprintf(path, sizeof path, "%s/missing.csv", tmp_dir);
    CHECK(consph_read_particles(path, NULL, &p, NULL) == CONSPH_EIO &&
              strstr(consph_last_error(), "cannot open"),
          "%s", consph_last_error());
    snprintf(path, sizeof path, "%s/dir.csv", tmp_dir);
    mkdir(path, 0700);
    CHECK(consph_read_particles(path, NULL, &p, NULL) == CONSPH_EIO &&
              strstr(consph_last_error(), "directory"),
          "%s", consph_last_error());
    rmdir(path);
    CHECK(consph_read_particles("p.txt", NULL, &p, NULL) == CONSPH_EINVAL &&
              strstr(consph_last_error(), ".vtu, .csv"),
          "%s", consph_last_error());
}

static const char inflate_expect_unit[] = "0.1 0.2 0.3 ";

static void test_inflate(void)
{
    unsigned char want[40 * 12 + 256];
    for (int k = 0; k < 40; ++k) memcpy(want + 12 * k, inflate_expect_unit, 12);
    for (int k = 0; k < 256; ++k) want[480 + k] = (unsigned char)k;
    static const char *const names[] = {"stored.z", "fast.z", "best.z", "fixed.z", "empty.z"};
    for (int k = 0; k < 5; ++k) {
        char path[1200];
        size_t size;
        snprintf(path, sizeof path, "%s/fuzz/corpus/inflate/%s", source_dir, names[k]);
        unsigned char *z = check_load_file(path, &size);
        CHECK(z != NULL, "%s", path);
        if (!z) continue;
        unsigned char *out = NULL;
        size_t outlen = 0, outcap = 0;
        const char *why;
        size_t expect = k == 4 ? 0 : sizeof want;
        int rc = consph_rd_inflate(z, size, &out, &outlen, &outcap, 1 << 20, &why);
        CHECK(rc == 0 && outlen == expect && (!expect || !memcmp(out, want, expect)), "%s: %s",
              names[k], rc ? why : "wrong output");
        if (k < 4) {
            rc = consph_rd_inflate(z, size, &out, &outlen, &outcap, expect - 1, &why);
            CHECK(rc != 0 && strstr(why, "more data"), "%s: output limit", names[k]);
            z[size - 1] ^= 1;
            rc = consph_rd_inflate(z, size, &out, &outlen, &outcap, 1 << 20, &why);
            CHECK(rc != 0 && strstr(why, "checksum"), "%s: corrupt checksum", names[k]);
            rc = consph_rd_inflate(z, size / 2, &out, &outlen, &outcap, 1 << 20, &why);
            CHECK(rc != 0, "%s: truncated stream accepted", names[k]);
        }
        free(out);
        free(z);
    }
}

/* A stream that inflates to well past the output limit stops there with an error (it once
 * spun forever asking zlib for output with no room left). */
static void test_inflate_limit(void)
{
    char path[1200];
    size_t size;
    snprintf(path, sizeof path, "%s/fuzz/corpus/inflate/best.z", source_dir);
    unsigned char *z = check_load_file(path, &size);
    CHECK(z != NULL, "%s", path);
    if (!z) return;
    for (size_t maxout = 0; maxout < 40 * 12; maxout += 97) {
        unsigned char *out = NULL;
        size_t outlen = 0, outcap = 0;
        const char *why;
        int rc = consph_rd_inflate(z, size, &out, &outlen, &outcap, maxout, &why);
        CHECK(rc != 0 && strstr(why, "more data") && outlen <= maxout, "limit %zu: %s", maxout,
              rc ? why : "accepted");
        free(out);
    }
    free(z);
}

/* Every file of the seed corpora and of fuzz/regressions/<target>/ through the fuzz entry
 * points: a crash found once stays fixed. */
static void test_fuzz_replay(void)
{
    static const char *const targets[] = {"csv", "vtu", "inflate"};
    static const char *const roots[] = {"fuzz/corpus", "fuzz/regressions"};
    int replayed = 0;
    for (int r = 0; r < 2; ++r)
        for (int t = 0; t < 3; ++t) {
            char dir[1200];
            snprintf(dir, sizeof dir, "%s/%s/%s", source_dir, roots[r], targets[t]);
            DIR *d = opendir(dir);
            if (!d) {
                CHECK(r == 1, "seed corpus %s missing", dir);
                continue;
            }
            struct dirent *e;
            while ((e = readdir(d)) != NULL) {
                if (e->d_name[0] == '.') continue;
                char path[2400];
                snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
                size_t size;
                unsigned char *data = check_load_file(path, &size);
                if (!data) continue;
                if (t == 0) consph_fuzz_csv(data, size);
                if (t == 1) consph_fuzz_vtu(data, size);
                if (t == 2) consph_fuzz_inflate(data, size);
                free(data);
                ++replayed;
            }
            closedir(d);
        }
    CHECK(replayed >= 20, "replayed %d corpus files", replayed);
    printf("replayed %d fuzz corpus and regression files\n", replayed);
}

int main(void)
{
    find_source_dir();
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/consph_io_read_XXXXXX");
    if (!mkdtemp(tmp_dir)) {
        perror("mkdtemp");
        return 1;
    }
    test_round_trip();
    test_vtu_encodings();
    test_vtk_fixtures();
    test_bad_csv();
    test_good_csv();
    test_bad_vtu();
    test_files();
    test_inflate();
    test_inflate_limit();
    test_fuzz_replay();
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp_dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmp_dir);
    return check_summary("test_io_read");
}
