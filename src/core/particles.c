#include "consph/core.h"
#include "core/particles_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

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

/* The permutation runs on the threads from this many particles on (a solver re-sorts its whole
 * state, tens of arrays, every step). */
#define PERMUTE_PARALLEL_MIN 4096
/* The moved values are held at most this many bytes at a time (the arrays go through in groups
 * of about PERMUTE_HELD_BYTES / (8 moved)), so that they are read back from the core's cache,
 * not from memory: at nx 250 (0.5 MB an array, 42 % moved) a re-sort of wcsph's 12 arrays took
 * 0.57 ms in groups of 2 against 0.70 ms in groups of 8 (4 n / moved arrays' worth, the rule
 * before), arrays flushed from the caches first as a step leaves them. */
#define PERMUTE_HELD_BYTES ((size_t)512 * 1024)
/* Runs of at least this many slots are read by memcpy, shorter ones by a loop. */
#define PERMUTE_COPY_MIN 8

/* Only the slots with perm[s] != s move: a re-sort after a small step leaves most particles in
 * place (a third of them move in a Taylor-Green step), and the fixed ones are neither read nor
 * written. Every thread takes a slice of the slots and lists the runs of moved slots in it
 * (run[2k] <= s < run[2k + 1], runs cut at the slice's ends and wherever perm[s] is not
 * perm[s - 1] + 1, so that a run reads consecutive slots: a particle that changes cells shifts
 * the slots between its old and new place by one, long runs that are copied whole); then, a
 * group of arrays at a time, it reads the values its slots receive into tmp and, once every
 * thread has read (every value is read before any is written), writes them back run by run. Each
 * thread reads and writes only its own part of tmp, so a group's reads need not wait for the
 * previous group's writes: one barrier per group. The moves, not their order, make the result: the
 * same for any thread count. */
int consph_particles_permute(consph_particles *p, const size_t *perm)
{
    particles_permute_buf b = {0};
    const int st = particles_permute_buf_run(p, perm, &b);
    particles_permute_buf_free(&b);
    return st;
}

void particles_permute_buf_free(particles_permute_buf *b)
{
    free(b->run);
    free(b->tmp);
    memset(b, 0, sizeof *b);
}

/* *buf with room for at least `need` values of `size` bytes (its contents dropped) */
static int buf_reserve(void **buf, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap) return 1;
    free(*buf);
    *buf = malloc(need * size);
    *cap = *buf ? need : 0;
    return *buf != NULL;
}

int particles_permute_buf_run(consph_particles *p, const size_t *perm, particles_permute_buf *b)
{
    const size_t n = p->n;
    int narr = p->dim;
    for (int f = 0; f < p->nfields; ++f) narr += p->fields[f].ncomp;
#ifdef _OPENMP
    const int tmax = omp_get_max_threads();
#else
    const int tmax = 1;
#endif
    double **arr = consph_calloc((size_t)narr, sizeof(double *));
    /* per thread: moved slots, then runs, each as offsets from thread 0's (tmax + 1 each) */
    size_t *count = consph_calloc(2 * ((size_t)tmax + 1), sizeof(size_t));
    if (!arr || !count) {
        free(arr);
        free(count);
        return CONSPH_ENOMEM;
    }
    size_t *moved_at = count, *runs_at = count + tmax + 1;
    int k = 0;
    for (int a = 0; a < p->dim; ++a) arr[k++] = p->x[a];
    for (int f = 0; f < p->nfields; ++f)
        for (int c = 0; c < p->fields[f].ncomp; ++c)
            arr[k++] = p->fields[f].data + (size_t)c * p->cap;
    size_t moved = 0, *run = NULL;
    double *tmp = NULL;
    int group = narr, st = CONSPH_OK;
#pragma omp parallel if (n >= PERMUTE_PARALLEL_MIN)
    {
#ifdef _OPENMP
        const int nt = omp_get_num_threads(), t = omp_get_thread_num();
#else
        const int nt = 1, t = 0;
#endif
        const size_t s0 = n * (size_t)t / (size_t)nt, s1 = n * (size_t)(t + 1) / (size_t)nt;
        size_t mine = 0, myruns = 0;
        for (size_t s = s0; s < s1; ++s)
            if (perm[s] != s) {
                ++mine;
                myruns += s == s0 || perm[s - 1] == s - 1 || perm[s] != perm[s - 1] + 1;
            }
        moved_at[t + 1] = mine;
        runs_at[t + 1] = myruns;
#pragma omp barrier
#pragma omp single
        {
            for (int u = 0; u < nt; ++u) {
                moved_at[u + 1] += moved_at[u];
                runs_at[u + 1] += runs_at[u];
            }
            moved = moved_at[nt];
            if (moved) {
                const size_t held = PERMUTE_HELD_BYTES / (moved * sizeof *tmp);
                if (held < (size_t)group) group = held > 0 ? (int)held : 1;
                if (!buf_reserve((void **)&b->run, &b->run_cap, 2 * runs_at[nt], sizeof *run) ||
                    !buf_reserve((void **)&b->tmp, &b->tmp_cap, (size_t)group * moved, sizeof *tmp))
                    st = CONSPH_ENOMEM;
                run = b->run;
                tmp = b->tmp;
            }
        }
        if (moved && st == CONSPH_OK) {
            const size_t k0 = moved_at[t], r0 = runs_at[t], r1 = runs_at[t + 1];
            size_t r = r0;
            for (size_t s = s0; s < s1; ++s) {
                if (perm[s] == s) continue;
                if (s == s0 || perm[s - 1] == s - 1 || perm[s] != perm[s - 1] + 1) run[2 * r] = s;
                if (s + 1 == s1 || perm[s + 1] == s + 1 || perm[s + 1] != perm[s] + 1)
                    run[2 * r++ + 1] = s + 1;
            }
            for (int g0 = 0; g0 < narr; g0 += group) {
                const int gn = narr - g0 < group ? narr - g0 : group;
                for (int g = 0; g < gn; ++g) {
                    const double *a = arr[g0 + g];
                    double *held = tmp + (size_t)g * moved + k0;
                    size_t m = 0;
                    for (size_t q = r0; q < r1; ++q) {
                        const size_t len = run[2 * q + 1] - run[2 * q];
                        const double *from = a + perm[run[2 * q]];
                        if (len >= PERMUTE_COPY_MIN)
                            memcpy(held + m, from, len * sizeof *held);
                        else
                            for (size_t i = 0; i < len; ++i) held[m + i] = from[i];
                        m += len;
                    }
                }
#pragma omp barrier
                for (int g = 0; g < gn; ++g) {
                    double *a = arr[g0 + g];
                    const double *held = tmp + (size_t)g * moved + k0;
                    for (size_t q = r0; q < r1; ++q) {
                        const size_t len = run[2 * q + 1] - run[2 * q];
                        memcpy(a + run[2 * q], held, len * sizeof *held);
                        held += len;
                    }
                }
            }
        }
    }
    free(arr);
    free(count);
    if (st != CONSPH_OK)
        return consph_fail(st, "out of memory for the %zu moved values of a permutation", moved);
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
