/* Two solvers' particles bit for bit, for the tests that run one path against another. */
#ifndef CONSPH_TESTS_SAME_STATE_H
#define CONSPH_TESTS_SAME_STATE_H

#include <string.h>

#include "check.h"
#include "consph/solver.h"

/* Positions and every field of a and b, bit for bit; the first difference is reported. */
static int same_state(const consph_solver *a, const consph_solver *b, const char *what)
{
    const consph_particles *p = consph_solver_particles(a), *q = consph_solver_particles(b);
    if (p->n != q->n || p->nfields != q->nfields) {
        CHECK(0, "%s: %zu/%zu particles, %d/%d fields", what, p->n, q->n, p->nfields, q->nfields);
        return 0;
    }
    for (int d = 0; d < p->dim; ++d)
        if (memcmp(p->x[d], q->x[d], p->n * sizeof(double)) != 0) {
            CHECK(0, "%s: positions (axis %d) differ", what, d);
            return 0;
        }
    for (int f = 0; f < p->nfields; ++f) {
        const consph_field *fa = &p->fields[f], *fb = consph_particles_find(q, fa->name);
        if (!fb || fb->ncomp != fa->ncomp) {
            CHECK(0, "%s: field %s missing", what, fa->name);
            return 0;
        }
        for (int c = 0; c < fa->ncomp; ++c)
            if (memcmp(fa->data + (size_t)c * p->cap, fb->data + (size_t)c * q->cap,
                       p->n * sizeof(double)) != 0) {
                CHECK(0, "%s: field %s (component %d) differs", what, fa->name, c);
                return 0;
            }
    }
    return 1;
}

#endif
