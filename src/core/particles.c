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

static int permute_array(double *a, size_t n, const size_t *perm, double *tmp)
{
    for (size_t i = 0; i < n; ++i) tmp[i] = a[perm[i]];
    memcpy(a, tmp, n * sizeof(double));
    return CONSPH_OK;
}

/* The arrays are independent copies, shared out among the threads from this many particles on
 * (a solver re-sorts its whole state, tens of arrays, every step). */
#define PERMUTE_PARALLEL_MIN 4096

int consph_particles_permute(consph_particles *p, const size_t *perm)
{
    int narr = p->dim;
    for (int f = 0; f < p->nfields; ++f) narr += p->fields[f].ncomp;
    double **arr = consph_calloc((size_t)narr, sizeof(double *));
    if (!arr) return CONSPH_ENOMEM;
    int k = 0;
    for (int a = 0; a < p->dim; ++a) arr[k++] = p->x[a];
    for (int f = 0; f < p->nfields; ++f)
        for (int c = 0; c < p->fields[f].ncomp; ++c)
            arr[k++] = p->fields[f].data + (size_t)c * p->cap;
    int st = CONSPH_OK;
#pragma omp parallel if (p->n >= PERMUTE_PARALLEL_MIN)
    {
        double *tmp = consph_calloc(p->n ? p->n : 1, sizeof(double));
        if (!tmp) {
#pragma omp atomic write
            st = CONSPH_ENOMEM;
        }
#pragma omp for schedule(dynamic, 1)
        for (int a = 0; a < narr; ++a)
            if (tmp) permute_array(arr[a], p->n, perm, tmp);
        free(tmp);
    }
    free(arr);
    return st;
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
