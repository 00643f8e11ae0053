/* wcsph, tvf and edac compute ∇u and ∇p only in the steps whose end a snapshot or the end of the
 * run reads (consph_run sets grads_lazy, consph_solver_step grads_skip): every snapshot's
 * velocity_gradient equals, bit for bit, that of a run stepped by hand that computes them in
 * every step, and so does the velocity (nothing the solution depends on is skipped); a skipped
 * step leaves the gradient as it was. */
#include <sys/stat.h>
#include <dirent.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "consph/io.h"
#include "consph/solver.h"
#include "solver/solver_internal.h"

static char dir[] = "/tmp/consph_lazy_grads_XXXXXX";

enum { STEPS = 7, EVERY = 3 };

static consph_solver *make(const char *scheme)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = 10;
    p.steps = STEPS;
    consph_solver *s = NULL;
    int st = consph_solver_create(&s, &p);
    CHECK(st == CONSPH_OK, "create %s: %s", scheme, consph_last_error());
    return s;
}

/* The snapshot at `path` holds the velocity and velocity_gradient of s bit for bit. */
static int same_as_snapshot(const consph_solver *s, const char *path)
{
    consph_particles q;
    consph_read_report rep;
    if (consph_read_particles(path, NULL, &q, &rep) != CONSPH_OK) {
        CHECK(0, "read %s: %s", path, consph_last_error());
        return 0;
    }
    const consph_particles *p = consph_solver_particles(s);
    const consph_field *u = consph_particles_find(p, SF_U), *g = consph_particles_find(p, SF_GRADU);
    const consph_field *vu = consph_particles_find(&q, "velocity");
    const consph_field *vg = consph_particles_find(&q, "velocity_gradient");
    int same = u && g && vu && vg && q.n == p->n;
    for (size_t i = 0; same && i < p->n; ++i) {
        for (int a = 0; a < 2 && same; ++a)
            same = memcmp(&vu->data[(size_t)a * q.cap + i], &u->data[(size_t)a * p->cap + i],
                          sizeof(double)) == 0;
        for (int r = 0; r < 2 && same; ++r)
            for (int c = 0; c < 2 && same; ++c)
                same = memcmp(&vg->data[(size_t)(3 * r + c) * q.cap + i],
                              &g->data[(size_t)(2 * r + c) * p->cap + i], sizeof(double)) == 0;
    }
    consph_particles_free(&q);
    return same;
}

static void remove_dir(const char *path)
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
    rmdir(path);
}

static void scheme_case(const char *scheme)
{
    char sub[256], path[400];
    snprintf(sub, sizeof sub, "%s/%s", dir, scheme);
    mkdir(sub, 0777);
    consph_solver *lazy = make(scheme), *full = make(scheme);
    if (!lazy || !full) {
        consph_solver_free(lazy);
        consph_solver_free(full);
        return;
    }
    consph_run_output out = {sub, EVERY, 0, 0, 0};
    consph_run_summary sum;
    int stopped = 0;
    CHECK(consph_run(lazy, &out, &sum, &stopped) == CONSPH_OK, "%s: run: %s", scheme,
          consph_last_error());
    snprintf(path, sizeof path, "%s/run.pvd", sub);
    consph_pvd pvd;
    if (consph_pvd_load(&pvd, path) != CONSPH_OK) {
        CHECK(0, "%s: index: %s", scheme, consph_last_error());
        consph_solver_free(lazy);
        consph_solver_free(full);
        return;
    }
    /* snapshots at steps 0, 3, 6 and 7 */
    CHECK(pvd.n == 4, "%s: %zu snapshots, not 4", scheme, pvd.n);
    size_t k = 0;
    snprintf(path, sizeof path, "%s/%s", sub, pvd.file[k++]);
    CHECK(same_as_snapshot(full, path), "%s: snapshot of step 0", scheme);
    while (!consph_solver_done(full) && k < pvd.n) {
        CHECK(consph_solver_step(full) == CONSPH_OK, "%s: step: %s", scheme, consph_last_error());
        const long n = consph_solver_step_count(full);
        if (n % EVERY && n != STEPS) continue;
        snprintf(path, sizeof path, "%s/%s", sub, pvd.file[k++]);
        CHECK(same_as_snapshot(full, path),
              "%s: the snapshot of step %ld differs from a run that computes ∇u every step", scheme,
              n);
    }
    consph_pvd_free(&pvd);

    /* a skipped step keeps the last gradient; a step that is not skipped replaces it */
    consph_solver *s = make(scheme);
    if (s) {
        const consph_field *g = consph_particles_find(consph_solver_particles(s), SF_GRADU);
        const size_t bytes = 4 * consph_solver_particles(s)->cap * sizeof(double);
        double *g0 = malloc(bytes);
        memcpy(g0, g->data, bytes);
        s->grads_lazy = 1;
        s->grads_every = 2;
        CHECK(consph_solver_step(s) == CONSPH_OK, "%s: step 1", scheme);
        CHECK(memcmp(g0, g->data, bytes) == 0, "%s: step 1 of 7 (every 2) computed ∇u", scheme);
        CHECK(consph_solver_step(s) == CONSPH_OK, "%s: step 2", scheme);
        CHECK(memcmp(g0, g->data, bytes) != 0, "%s: step 2 of 7 (every 2) kept ∇u", scheme);
        free(g0);
        consph_solver_free(s);
    }
    consph_solver_free(lazy);
    consph_solver_free(full);
    remove_dir(sub);
}

int main(void)
{
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    scheme_case("wcsph");
    scheme_case("tvf");
    scheme_case("edac");
    rmdir(dir);
    return check_summary("test_lazy_grads");
}
