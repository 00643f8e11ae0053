#include "consph/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

consph_box consph_box_unit(int dim, int periodic)
{
    consph_box b;
    memset(&b, 0, sizeof b);
    b.dim = dim;
    /* An invalid dim is kept for consph_box_check to report; the arrays are never overrun. */
    for (int a = 0; a < dim && a < CONSPH_MAX_DIM; ++a) {
        b.lo[a] = 0.0;
        b.hi[a] = 1.0;
        b.periodic[a] = periodic != 0;
    }
    return b;
}

double consph_box_length(const consph_box *box, int axis)
{
    return box->hi[axis] - box->lo[axis];
}

double consph_box_volume(const consph_box *box)
{
    double v = 1.0;
    for (int a = 0; a < box->dim; ++a) v *= consph_box_length(box, a);
    return v;
}

int consph_box_check(const consph_box *box)
{
    if (box->dim < 1 || box->dim > CONSPH_MAX_DIM)
        return consph_fail(CONSPH_EINVAL, "box dimension %d is not 1, 2 or 3", box->dim);
    for (int a = 0; a < box->dim; ++a) {
        if (!isfinite(box->lo[a]) || !isfinite(box->hi[a]) || !(box->hi[a] > box->lo[a]))
            return consph_fail(CONSPH_EINVAL, "box axis %d: need finite lo < hi, got [%g, %g]", a,
                               box->lo[a], box->hi[a]);
    }
    return CONSPH_OK;
}

int consph_particles_init(consph_particles *p, int dim, size_t n, const consph_box *box)
{
    memset(p, 0, sizeof *p);
    if (dim < 1 || dim > CONSPH_MAX_DIM)
        return consph_fail(CONSPH_EINVAL, "dimension %d is not 1, 2 or 3", dim);
    p->dim = dim;
    p->n = n;
    p->cap = n;
    if (box) {
        p->box = *box;
    } else {
        p->box = consph_box_unit(dim, 0);
    }
    for (int a = 0; a < dim; ++a) {
        p->x[a] = consph_calloc(n, sizeof(double));
        if (!p->x[a]) {
            consph_particles_free(p);
            return CONSPH_ENOMEM;
        }
    }
    return CONSPH_OK;
}

void consph_particles_free(consph_particles *p)
{
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(p->x[a]);
    for (int f = 0; f < p->nfields; ++f) free(p->fields[f].data);
    memset(p, 0, sizeof *p);
}

const consph_field *consph_particles_find(const consph_particles *p, const char *name)
{
    for (int f = 0; f < p->nfields; ++f)
        if (strcmp(p->fields[f].name, name) == 0) return &p->fields[f];
    return NULL;
}

double *consph_particles_field(consph_particles *p, const char *name, int ncomp)
{
    const consph_field *found = consph_particles_find(p, name);
    if (found) {
        if (found->ncomp != ncomp) {
            consph_fail(CONSPH_EINVAL, "field '%s' exists with %d components, not %d", name,
                        found->ncomp, ncomp);
            return NULL;
        }
        return found->data;
    }
    if (p->nfields == CONSPH_MAX_FIELDS) {
        consph_fail(CONSPH_EINVAL, "too many fields (at most %d)", CONSPH_MAX_FIELDS);
        return NULL;
    }
    if (ncomp < 1 || strlen(name) >= CONSPH_FIELD_NAME_MAX) {
        consph_fail(CONSPH_EINVAL, "bad field '%s' (%d components)", name, ncomp);
        return NULL;
    }
    double *data = consph_calloc(p->cap * (size_t)ncomp, sizeof(double));
    if (!data) return NULL;
    consph_field *f = &p->fields[p->nfields++];
    strcpy(f->name, name);
    f->ncomp = ncomp;
    f->data = data;
    return data;
}

/* The arrays are independent copies, shared out among the threads from this many particles on
 * (a solver re-sorts its whole state, tens of arrays, every step). */
#define PERMUTE_PARALLEL_MIN 4096

/* a[s] = a[perm[s]] over the runs of slots that move, run[2k] <= s < run[2k + 1] (moved slots
 * in all): every value is read into tmp before any is written. */
static void permute_runs(double *a, const size_t *perm, const size_t *run, size_t nruns,
                         double *tmp)
{
    size_t k = 0;
    for (size_t r = 0; r < nruns; ++r)
        for (size_t s = run[2 * r]; s < run[2 * r + 1]; ++s) tmp[k++] = a[perm[s]];
    k = 0;
    for (size_t r = 0; r < nruns; ++r) {
        const size_t len = run[2 * r + 1] - run[2 * r];
        memcpy(a + run[2 * r], tmp + k, len * sizeof(double));
        k += len;
    }
}

/* Only the slots with perm[s] != s move: a re-sort after a small step leaves most particles in
 * place (a third of them move in a Taylor-Green step), and the fixed ones are neither read nor
 * written. */
int consph_particles_permute(consph_particles *p, const size_t *perm)
{
    const size_t n = p->n;
    size_t nruns = 0, moved = 0;
    for (size_t s = 0; s < n; ++s)
        if (perm[s] != s && (s == 0 || perm[s - 1] == s - 1)) ++nruns;
    if (nruns == 0) return CONSPH_OK;
    size_t *run = malloc(2 * nruns * sizeof(size_t));
    if (!run) return consph_fail(CONSPH_ENOMEM, "out of memory for %zu runs of moved slots", nruns);
    size_t r = 0;
    for (size_t s = 0; s < n; ++s) {
        if (perm[s] == s) continue;
        if (s == 0 || perm[s - 1] == s - 1) run[2 * r] = s;
        if (s + 1 == n || perm[s + 1] == s + 1) run[2 * r++ + 1] = s + 1;
        ++moved;
    }
    int narr = p->dim;
    for (int f = 0; f < p->nfields; ++f) narr += p->fields[f].ncomp;
    double **arr = consph_calloc((size_t)narr, sizeof(double *));
    if (!arr) {
        free(run);
        return CONSPH_ENOMEM;
    }
    int k = 0;
    for (int a = 0; a < p->dim; ++a) arr[k++] = p->x[a];
    for (int f = 0; f < p->nfields; ++f)
        for (int c = 0; c < p->fields[f].ncomp; ++c)
            arr[k++] = p->fields[f].data + (size_t)c * p->cap;
    int st = CONSPH_OK;
#pragma omp parallel if (moved >= PERMUTE_PARALLEL_MIN)
    {
        double *tmp = malloc(moved * sizeof(double));
        if (!tmp) {
#pragma omp atomic write
            st = CONSPH_ENOMEM;
        }
#pragma omp for schedule(dynamic, 1)
        for (int a = 0; a < narr; ++a)
            if (tmp) permute_runs(arr[a], perm, run, nruns, tmp);
        free(tmp);
    }
    free(arr);
    free(run);
    if (st != CONSPH_OK)
        return consph_fail(st, "out of memory for the %zu moved values of an array", moved);
    return CONSPH_OK;
}

int consph_particles_copy(consph_particles *dst, const consph_particles *src)
{
    int rc = consph_particles_init(dst, src->dim, src->n, &src->box);
    if (rc) return rc;
    dst->spacing = src->spacing;
    for (int a = 0; a < src->dim; ++a) memcpy(dst->x[a], src->x[a], src->n * sizeof(double));
    for (int f = 0; f < src->nfields; ++f) {
        const consph_field *sf = &src->fields[f];
        double *d = consph_particles_field(dst, sf->name, sf->ncomp);
        if (!d) {
            consph_particles_free(dst);
            return CONSPH_ENOMEM;
        }
        for (int c = 0; c < sf->ncomp; ++c)
            memcpy(d + (size_t)c * dst->cap, sf->data + (size_t)c * src->cap,
                   src->n * sizeof(double));
    }
    return CONSPH_OK;
}
