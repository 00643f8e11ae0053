/* Declared state: an undeclared field is refused (by name, with the scheme), never created; a
 * snapshot of every scheme holds exactly the arrays docs/solver-files.md lists, vectors as 3
 * and tensors as 9 components, with its time as TimeValue, the same arrays at every step and
 * the solver's values bit for bit; a checkpoint of a field nobody declares restores without it;
 * consph_write_vtu refuses a bad array list. */
#include <dirent.h>
#include <sys/stat.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "consph/io.h"
#include "consph/solver.h"
#include "solver/solver_internal.h"

static char dir[] = "/tmp/consph_state_XXXXXX";

/* docs/solver-files.md, "Snapshot arrays": name and components, in file order. */
typedef struct expect_array {
    const char *name;
    int ncomp;
} expect_array;

static const expect_array negi_arrays[] = {
    {"id", 1},        {"velocity", 3},       {"pressure", 1},
    {"density", 1},   {"volume", 1},         {"velocity_gradient", 9},
    {"vorticity", 1}, {"velocity_exact", 3}, {"pressure_exact", 1},
    {NULL, 0}};
static const expect_array wcsph_arrays[] = {{"id", 1},
                                            {"velocity", 3},
                                            {"pressure", 1},
                                            {"density", 1},
                                            {"velocity_gradient", 9},
                                            {"vorticity", 1},
                                            {"velocity_exact", 3},
                                            {"pressure_exact", 1},
                                            {NULL, 0}};
static const expect_array tv_arrays[] = {{"id", 1},
                                         {"velocity", 3},
                                         {"pressure", 1},
                                         {"summation_density", 1},
                                         {"velocity_gradient", 9},
                                         {"vorticity", 1},
                                         {"velocity_exact", 3},
                                         {"pressure_exact", 1},
                                         {NULL, 0}};
static const expect_array delta_arrays[] = {{"id", 1},
                                            {"velocity", 3},
                                            {"pressure", 1},
                                            {"density", 1},
                                            {"volume", 1},
                                            {"velocity_gradient", 9},
                                            {"vorticity", 1},
                                            {"velocity_exact", 3},
                                            {"pressure_exact", 1},
                                            {"mass", 1},
                                            {NULL, 0}};

static const struct {
    const char *scheme;
    const expect_array *arrays;
} cases[] = {
    {"l-ipst-c", negi_arrays},
    {"l-ipst-f", negi_arrays},
    {"l-ipst-k", negi_arrays},
    {"l-pst-c", negi_arrays},
    {"pe-ipst-c", negi_arrays},
    {"l-rr-c", negi_arrays},
    {"tv-c", negi_arrays},
    {"e-c", negi_arrays},
    {"ewcsph", negi_arrays},
    {"wcsph", wcsph_arrays},
    {"tvf", tv_arrays},
    {"edac", tv_arrays},
    {"delta-sph", delta_arrays},
    {"delta-plus-sph", delta_arrays},
    {"delta-plus-sph-d", delta_arrays},
};

static consph_solver *make(const char *scheme, int nx)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = nx;
    p.steps = 3;
    p.ipst_every = 2; /* a shift inside the run */
    consph_solver *s = NULL;
    int st = consph_solver_create(&s, &p);
    CHECK(st == CONSPH_OK, "create %s: %s", scheme, consph_last_error());
    return s;
}

static void clear_dir(const char *path)
{
    DIR *d = opendir(path);
    if (!d) return;
    struct dirent *e;
    char buf[512];
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.') continue;
        snprintf(buf, sizeof buf, "%s/%s", path, e->d_name);
        unlink(buf);
    }
    closedir(d);
}

/* The snapshot `file` of run `sub` holds exactly `want`, its time t and no other array. */
static void check_snapshot(const char *scheme, const char *path, const expect_array *want, double t,
                           consph_particles *q)
{
    consph_read_report rep;
    int st = consph_read_particles(path, NULL, q, &rep);
    CHECK(st == CONSPH_OK, "%s: read %s: %s", scheme, path, consph_last_error());
    if (st != CONSPH_OK) return;
    CHECK(rep.has_time && rep.time == t, "%s: %s: TimeValue %d %.17g, not %.17g", scheme, path,
          rep.has_time, rep.time, t);
    int k = 0;
    for (; want[k].name; ++k) {
        CHECK(k < q->nfields && !strcmp(q->fields[k].name, want[k].name) &&
                  q->fields[k].ncomp == want[k].ncomp,
              "%s: %s: array %d is '%s' (%d), not '%s' (%d)", scheme, path, k,
              k < q->nfields ? q->fields[k].name : "(none)",
              k < q->nfields ? q->fields[k].ncomp : 0, want[k].name, want[k].ncomp);
    }
    CHECK(q->nfields == k, "%s: %s: %d arrays, documented %d (the first extra: '%s')", scheme, path,
          q->nfields, k, q->nfields > k ? q->fields[k].name : "");
}

static void snapshots_of(const char *scheme, const expect_array *want)
{
    consph_solver *s = make(scheme, 8);
    if (!s) return;
    char sub[256], path[300];
    snprintf(sub, sizeof sub, "%s/%s", dir, scheme);
    mkdir(sub, 0777);
    consph_run_output out = {sub, 0, 0, 0, 0}; /* the first and the last */
    consph_run_summary sum;
    int stopped = 0;
    int st = consph_run(s, &out, &sum, &stopped);
    CHECK(st == CONSPH_OK, "%s: run: %s", scheme, consph_last_error());
    snprintf(path, sizeof path, "%s/run.pvd", sub);
    consph_pvd pvd;
    st = consph_pvd_load(&pvd, path);
    CHECK(st == CONSPH_OK && pvd.n == 2, "%s: index: %s (%zu entries)", scheme, consph_last_error(),
          st == CONSPH_OK ? pvd.n : 0);
    if (st != CONSPH_OK) {
        consph_solver_free(s);
        return;
    }
    for (size_t k = 0; k < pvd.n; ++k) {
        consph_particles q;
        snprintf(path, sizeof path, "%s/%s", sub, pvd.file[k]);
        check_snapshot(scheme, path, want, pvd.time[k], &q);
        if (k + 1 < pvd.n) {
            consph_particles_free(&q);
            continue;
        }
        /* the last one: the solver's state as it is now, bit for bit */
        const consph_particles *p = consph_solver_particles(s);
        const consph_field *u = consph_particles_find(p, SF_U),
                           *g = consph_particles_find(p, SF_GRADU);
        const consph_field *vu = consph_particles_find(&q, "velocity");
        const consph_field *vg = consph_particles_find(&q, "velocity_gradient");
        int same = u && g && vu && vg && q.n == p->n;
        for (size_t i = 0; same && i < p->n; ++i) {
            same = vu->data[i] == u->data[i] && vu->data[q.cap + i] == u->data[p->cap + i] &&
                   vu->data[2 * q.cap + i] == 0.0;
            for (int c = 0; c < 9 && same; ++c) {
                const int r = c / 3, col = c % 3;
                const double e =
                    r < 2 && col < 2 ? g->data[(size_t)(2 * r + col) * p->cap + i] : 0.0;
                same = memcmp(&vg->data[(size_t)c * q.cap + i], &e, sizeof e) == 0;
            }
        }
        CHECK(same, "%s: the last snapshot's velocity or velocity_gradient is not the solver's",
              scheme);
        consph_particles_free(&q);
    }
    consph_pvd_free(&pvd);
    consph_solver_free(s);
}

static void undeclared(void)
{
    consph_solver *s = make("tvf", 8);
    if (!s) return;
    const int nf = consph_solver_particles(s)->nfields;
    double *f = sv_field(s, "rhoff", 1);
    CHECK(f == NULL && strstr(consph_last_error(), "'rhoff'") &&
              strstr(consph_last_error(), "'tvf'"),
          "an undeclared name: %p, '%s'", (void *)f, consph_last_error());
    /* declared by another family only */
    f = sv_field(s, "gradrho_l", 2);
    CHECK(f == NULL && strstr(consph_last_error(), "'gradrho_l'"), "delta's field in tvf: %s",
          consph_last_error());
    f = sv_field(s, SF_U, 1);
    CHECK(f == NULL && strstr(consph_last_error(), "components"), "u with 1 component: %s",
          consph_last_error());
    CHECK(sv_field(s, SF_U, 2) != NULL, "u: %s", consph_last_error());
    CHECK(consph_solver_particles(s)->nfields == nf, "a refused name created a field");
    /* a field made behind sv_field's back is found at the next snapshot */
    CHECK(state_undeclared(s, 0) == CONSPH_OK, "%s", consph_last_error());
    consph_particles_field(s->sys.p, "stray", 1);
    CHECK(state_undeclared(s, 0) == CONSPH_EINVAL && strstr(consph_last_error(), "'stray'"),
          "a stray field: %s", consph_last_error());
    /* a checkpoint holding it restores without it, and steps on as the original does */
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    consph_solver *r = NULL;
    int st = consph_solver_checkpoint_meta(s, &meta, &hist, &nh);
    if (st == CONSPH_OK) st = consph_solver_restore(&r, meta, s->sys.p, hist, nh);
    CHECK(st == CONSPH_OK, "restore: %s", consph_last_error());
    if (r) {
        CHECK(!consph_particles_find(r->sys.p, "stray") && r->sys.p->nfields == nf,
              "the restored run keeps the undeclared field (%d fields, %d declared)",
              r->sys.p->nfields, nf);
        CHECK(consph_solver_step(r) == CONSPH_OK && consph_solver_step(s) == CONSPH_OK, "step: %s",
              consph_last_error());
        const consph_field *a = consph_particles_find(s->sys.p, SF_U);
        const consph_field *b = consph_particles_find(r->sys.p, SF_U);
        CHECK(a && b && !memcmp(a->data, b->data, s->sys.p->n * sizeof(double)),
              "the restored run steps differently");
    }
    free(meta);
    free(hist);
    consph_solver_free(r);
    consph_solver_free(s);
}

/* Every declared field exists from set-up on, in each scheme; scratch never names an output. */
static void declarations(void)
{
    const field_decl *lists[] = {solver_fields, integrator_fields};
    for (int l = 0; l < 2; ++l)
        for (const field_decl *f = lists[l]; f->name; ++f)
            CHECK(!(f->role == FIELD_SCRATCH && f->output), "scratch '%s' is written", f->name);
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        const scheme_def *sd = scheme_find(cases[k].scheme);
        CHECK(sd && sd->fields, "%s declares no fields", cases[k].scheme);
    }
    /* a scheme added to the registry without its expected arrays here would go unchecked */
    CHECK(sizeof cases / sizeof cases[0] == scheme_count(), "%zu cases for %zu schemes (%s)",
          sizeof cases / sizeof cases[0], scheme_count(), consph_scheme_names());
}

static void bad_arrays(void)
{
    consph_particles p;
    consph_box box = consph_box_unit(2, 1);
    CHECK(consph_particles_init(&p, 2, 4, &box) == CONSPH_OK, "%s", consph_last_error());
    for (size_t i = 0; i < 4; ++i) {
        p.x[0][i] = 0.25 * (double)i;
        p.x[1][i] = 0.5;
    }
    consph_particles_field(&p, "u", 2);
    consph_particles_field(&p, "G", 4);
    char path[300];
    snprintf(path, sizeof path, "%s/bad.vtu", dir);
    const struct {
        consph_vtu_array a[2];
        int n;
        const char *says;
    } bad[] = {
        {{{"velocity", "w", CONSPH_ARRAY_VECTOR}}, 1, "no field 'w'"},
        {{{"velocity", "u", CONSPH_ARRAY_TENSOR}}, 1, "'velocity': field 'u' has 2 components"},
        {{{"g", "G", CONSPH_ARRAY_VECTOR}}, 1, "a vector in 2D has 2"},
        {{{"a b", "u", CONSPH_ARRAY_VECTOR}}, 1, "name 'a b' not allowed"},
        {{{"v", "u", CONSPH_ARRAY_VECTOR}, {"v", "G", CONSPH_ARRAY_TENSOR}},
         2,
         "'v' is given twice"},
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        consph_vtu_content c = {bad[k].a, bad[k].n, 1, 0.5};
        int st = consph_write_vtu(path, &p, &c, CONSPH_VTU_ASCII);
        CHECK(st == CONSPH_EINVAL && strstr(consph_last_error(), bad[k].says), "case %zu: %d '%s'",
              k, st, consph_last_error());
        CHECK(access(path, F_OK) != 0, "case %zu: a file was written", k);
    }
    consph_vtu_array good[] = {{"velocity", "u", CONSPH_ARRAY_VECTOR},
                               {"gradient", "G", CONSPH_ARRAY_TENSOR}};
    consph_vtu_content c = {good, 2, 1, 0.125};
    CHECK(consph_write_vtu(path, &p, &c, CONSPH_VTU_ASCII) == CONSPH_OK, "%s", consph_last_error());
    consph_particles q;
    consph_read_report rep;
    CHECK(consph_read_particles(path, NULL, &q, &rep) == CONSPH_OK, "%s", consph_last_error());
    CHECK(rep.has_time && rep.time == 0.125 && q.nfields == 2 && q.fields[1].ncomp == 9,
          "read back: time %d %g, %d arrays", rep.has_time, rep.time, q.nfields);
    consph_particles_free(&q);
    unlink(path);
    consph_particles_free(&p);
}

int main(void)
{
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    declarations();
    undeclared();
    bad_arrays();
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k)
        snapshots_of(cases[k].scheme, cases[k].arrays);
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        char sub[256];
        snprintf(sub, sizeof sub, "%s/%s", dir, cases[k].scheme);
        clear_dir(sub);
        rmdir(sub);
    }
    rmdir(dir);
    return check_summary("test_state");
}
