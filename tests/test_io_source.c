/* The writers fed one array at a time (src/io/source_internal.h, what rank 0 writes a
 * decomposed run's snapshots and checkpoints with): a .vtu in every encoding (chosen arrays of
 * each kind, or every field) and a checkpoint are byte for byte the files written from a set
 * holding every array; each array is loaded once, and the writer reads no array it has not
 * loaded (the previous one is freed at each load, so a stale read shows under valgrind and as
 * other bytes); a failing load stops the writer with its status and leaves no file. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "consph/io.h"
#include "io/source_internal.h"

static char dir[] = "/tmp/consph_iosrc_XXXXXX";

/* The loader: copies the whole set's array into a fresh buffer (the last one filled with NaN
 * then freed, the view's pointers cleared). */
typedef struct loader {
    const consph_particles *full;
    consph_particles *view;
    double *buf;
    size_t len;
    int loads[CONSPH_MAX_FIELDS + 1]; /* per array (positions last): how many times */
    int fail_at;                      /* the load that fails (-1: none) */
    int count;
} loader;

static int load(void *arg, int field)
{
    loader *l = arg;
    if (l->count++ == l->fail_at) return consph_fail(CONSPH_EIO, "load %d refused", field);
    if (l->buf)
        for (size_t k = 0; k < l->len; ++k) l->buf[k] = NAN;
    free(l->buf);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) l->view->x[a] = NULL;
    for (int f = 0; f < l->view->nfields; ++f) l->view->fields[f].data = NULL;
    const consph_particles *p = l->full;
    const int nc = field < 0 ? p->dim : p->fields[field].ncomp;
    l->len = (size_t)nc * p->n;
    l->buf = malloc(l->len * sizeof(double));
    if (!l->buf) return consph_fail(CONSPH_ENOMEM, "out of memory");
    for (int c = 0; c < nc; ++c)
        memcpy(l->buf + (size_t)c * p->n,
               field < 0 ? p->x[c] : p->fields[field].data + (size_t)c * p->cap,
               p->n * sizeof(double));
    if (field < 0)
        for (int a = 0; a < p->dim; ++a) l->view->x[a] = l->buf + (size_t)a * p->n;
    else
        l->view->fields[field].data = l->buf;
    ++l->loads[field < 0 ? CONSPH_MAX_FIELDS : field];
    return CONSPH_OK;
}

/* The view: the set's shape, n particles at capacity n, no values. */
static void loader_init(loader *l, const consph_particles *full, consph_particles *view, int fail)
{
    memset(l, 0, sizeof *l);
    l->full = full;
    l->view = view;
    l->fail_at = fail;
    *view = *full;
    view->cap = full->n;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) view->x[a] = NULL;
    for (int f = 0; f < view->nfields; ++f) view->fields[f].data = NULL;
}

/* Values of every magnitude and sign (a NaN and -0.0 among them), in a set with room for
 * more particles than it holds (the columns start at c·cap). */
static void make_set(consph_particles *p, int dim, size_t n)
{
    consph_box box = consph_box_unit(dim, 1);
    consph_particles_init(p, dim, n + 5, &box);
    p->n = n;
    p->spacing = 0.02;
    consph_rng r;
    consph_rng_seed(&r, 7u + (unsigned)dim);
    for (int a = 0; a < dim; ++a)
        for (size_t i = 0; i < p->cap; ++i) p->x[a][i] = consph_rng_uniform(&r);
    const struct {
        const char *name;
        int ncomp;
    } fields[] = {{"rho", 1}, {"u", dim}, {"grad", dim * dim}, {"scratch", 4}, {"p", 1}};
    for (size_t f = 0; f < sizeof fields / sizeof fields[0]; ++f) {
        double *d = consph_particles_field(p, fields[f].name, fields[f].ncomp);
        for (size_t k = 0; k < p->cap * (size_t)fields[f].ncomp; ++k)
            d[k] = (consph_rng_uniform(&r) - 0.5) * pow(10.0, (double)(k % 40) - 20.0);
        d[0] = -0.0;
        d[1] = NAN;
    }
}

static void test_vtu(int dim, size_t n)
{
    consph_particles p, view;
    make_set(&p, dim, n);
    static const consph_vtu_array arrays[] = {{"velocity", "u", CONSPH_ARRAY_VECTOR},
                                              {"pressure", "p", CONSPH_ARRAY_SCALAR},
                                              {"velocity_gradient", "grad", CONSPH_ARRAY_TENSOR},
                                              {"density", "rho", CONSPH_ARRAY_SCALAR}};
    const consph_vtu_content chosen = {arrays, 4, 1, 0.125}, every = {NULL, 0, 0, 0.0};
    for (int enc = CONSPH_VTU_ASCII; enc <= CONSPH_VTU_ZLIB; ++enc)
        for (int which = 0; which < 2; ++which) {
            const consph_vtu_content *c = which ? &every : &chosen;
            char a[128], b[128];
            snprintf(a, sizeof a, "%s/whole_%d_%d.vtu", dir, enc, which);
            snprintf(b, sizeof b, "%s/source_%d_%d.vtu", dir, enc, which);
            CHECK(consph_write_vtu(a, &p, c, (consph_vtu_encoding)enc) == CONSPH_OK, "%s: %s", a,
                  consph_last_error());
            loader l;
            loader_init(&l, &p, &view, -1);
            const io_array_source src = {load, &l};
            CHECK(io_write_vtu_source(b, &view, c, (consph_vtu_encoding)enc, &src) == CONSPH_OK,
                  "%s: %s", b, consph_last_error());
            free(l.buf);
            CHECK(check_same_file(a, b), "%dD, encoding %s, %s: the file differs", dim,
                  consph_vtu_encoding_name((consph_vtu_encoding)enc),
                  which ? "every field" : "chosen arrays");
            CHECK(l.loads[CONSPH_MAX_FIELDS] == 1, "positions loaded %d times",
                  l.loads[CONSPH_MAX_FIELDS]);
            for (int f = 0; f < p.nfields; ++f) {
                int want = which;
                for (int k = 0; !which && k < chosen.narrays; ++k)
                    want |= !strcmp(arrays[k].field, p.fields[f].name);
                CHECK(l.loads[f] == want, "%s loaded %d times, not %d", p.fields[f].name,
                      l.loads[f], want);
            }
            unlink(a);
            unlink(b);
        }
    /* a failing load: its status, no file */
    for (int fail = 0; fail < 2; ++fail) {
        char b[128];
        snprintf(b, sizeof b, "%s/failed.vtu", dir);
        loader l;
        loader_init(&l, &p, &view, fail);
        const io_array_source src = {load, &l};
        const int st = io_write_vtu_source(b, &view, &chosen, CONSPH_VTU_ZLIB, &src);
        free(l.buf);
        CHECK(st == CONSPH_EIO && strstr(consph_last_error(), "refused"), "a failing load: %d %s",
              st, consph_last_error());
        CHECK(access(b, F_OK) != 0, "a failing load left %s", b);
    }
    consph_particles_free(&p);
}

static void test_checkpoint(int dim, size_t n)
{
    consph_particles p, view;
    make_set(&p, dim, n);
    const double hist[] = {1.0, -2.5, NAN, 0.0};
    char a[128], b[128];
    snprintf(a, sizeof a, "%s/whole.ckpt", dir);
    snprintf(b, sizeof b, "%s/source.ckpt", dir);
    CHECK(consph_checkpoint_write(a, "format=x\nkey=1\n", &p, hist, 4) == CONSPH_OK, "%s: %s", a,
          consph_last_error());
    loader l;
    loader_init(&l, &p, &view, -1);
    const io_array_source src = {load, &l};
    CHECK(io_checkpoint_write_source(b, "format=x\nkey=1\n", &view, &src, hist, 4) == CONSPH_OK,
          "%s: %s", b, consph_last_error());
    free(l.buf);
    CHECK(check_same_file(a, b), "%dD checkpoint: the file differs", dim);
    CHECK(l.loads[CONSPH_MAX_FIELDS] == 1, "positions loaded %d times", l.loads[CONSPH_MAX_FIELDS]);
    for (int f = 0; f < p.nfields; ++f)
        CHECK(l.loads[f] == 1, "%s loaded %d times", p.fields[f].name, l.loads[f]);
    unlink(a);
    unlink(b);
    loader_init(&l, &p, &view, 3);
    const int st = io_checkpoint_write_source(b, "", &view, &src, hist, 4);
    free(l.buf);
    CHECK(st == CONSPH_EIO && strstr(consph_last_error(), "refused"), "a failing load: %d %s", st,
          consph_last_error());
    CHECK(access(b, F_OK) != 0, "a failing load left %s", b);
    consph_particles_free(&p);
}

int main(void)
{
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    /* 3D at 12 000 particles: the tensor spans 4 zlib blocks of 2^18 bytes, the positions 2 */
    test_vtu(2, 1000);
    test_vtu(3, 12000);
    test_checkpoint(2, 1000);
    test_checkpoint(3, 12000);
    rmdir(dir);
    return check_summary("test_io_source");
}
