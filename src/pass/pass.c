/* The pass driver: every destination particle's neighbourhood with its kernel values, handed to
 * a visit (include/consph/pass.h), and the system it runs over.
 *
 * The pass walks the search's cells rather than querying particle by particle: the runs of
 * candidate slots are found once per cell (consph_nnps_cell_runs) and shared by its particles,
 * the hits come from the search's own test (consph_nnps_gather), and the kernel values come from
 * one vectorised batch per particle (consph_kernel_eval_batch). Each particle's neighbours are
 * those of consph_nnps_query_particle, in the same order and with the same separations and kernel
 * values bit for bit, so a visit sums exactly what it summed over a query. Particles are
 * independent and written only by their own visit, so results do not depend on how the cells
 * are shared out among threads. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "consph/pass.h"
#include "pass/group.h"
#include "pass/nbhd.h"
#include "pass/nlist.h"

#define PASS_CELLS_PER_CHUNK 16
/* at least this many chunks per thread */
#define PASS_CHUNKS_PER_THREAD 64

size_t pass_cells_per_chunk(size_t ncells)
{
#ifdef _OPENMP
    const size_t threads = (size_t)omp_get_max_threads();
#else
    const size_t threads = 1;
#endif
    const size_t c = ncells / (threads * PASS_CHUNKS_PER_THREAD);
    return c < 1 ? 1 : c > PASS_CELLS_PER_CHUNK ? PASS_CELLS_PER_CHUNK : c;
}

static int pass_fail(const consph_pass *pass, int status, const char *why)
{
    return consph_fail(status, "pass '%s': %s", pass->name ? pass->name : "unnamed", why);
}

int consph_pass_run_counted(const consph_sys *s, const consph_pass *pass, void *job, size_t *pairs)
{
    char why[256];
    if (!s || !s->p || !s->nnps || !pass || !pass->visit)
        return consph_fail(CONSPH_EINVAL, "pass: needs a system and a pass with a visit");
    if (s->split) {
        const int rc = pass_halo_refresh((consph_sys *)s);
        if (rc != CONSPH_OK) return rc;
        ((consph_sys *)s)->halo_fresh = 0; /* this pass reads it; the visits write fields */
    }
    const size_t n = s->p->n;
    const unsigned need = pass->need;
    const consph_kernel *kernel = &s->kernel;
    consph_nnps_slots v;
    if (n == 0) return CONSPH_OK;
    if (s->nlist && nlist_serves(s->nlist, n)) {
        const int rc = nlist_pass_run(s, pass, job, pairs);
        if (rc != NLIST_GATHER) return rc;
    }
    if (consph_nnps_slots_get(s->nnps, &v) != CONSPH_OK)
        return pass_fail(pass, CONSPH_EINVAL, consph_last_error());
    if (v.n != n) {
        snprintf(why, sizeof why,
                 "the neighbour search holds %zu particles, the system %zu; update the system", v.n,
                 n);
        return pass_fail(pass, CONSPH_EINVAL, why);
    }
    if (kernel->tensor && (need & (CONSPH_PASS_DW | CONSPH_PASS_D2W))) {
        snprintf(why, sizeof why,
                 "kernel '%s' is a tensor-product kernel, which has W only; this pass needs its "
                 "derivatives",
                 kernel->name);
        return pass_fail(pass, CONSPH_EINVAL, why);
    }
    /* A tensor-product kernel is a function of the separation vector, not of r. */
    const int tensor = kernel->tensor && (need & CONSPH_PASS_W);
    const int with_dx = !(need & CONSPH_PASS_NO_DX) || tensor;
    const unsigned char *dest = s->dest;
    int status = CONSPH_OK;
    size_t total = 0;
    /* consph_fail records per thread: a worker's message is copied out here. */
    why[0] = '\0';
    const size_t chunk = pass_cells_per_chunk(v.ncells);
    (void)chunk; /* read by the OpenMP schedule alone */
#pragma omp parallel if (n >= s->parallel_min)
    {
        consph_nnps_runs runs;
        memset(&runs, 0, sizeof runs);
        nbhd_scratch sc;
        memset(&sc, 0, sizeof sc);
        int my_status = CONSPH_OK;
        char my_why[256] = "";
        size_t my_pairs = 0;
#pragma omp for schedule(dynamic, chunk)
        for (size_t c = 0; c < v.ncells; ++c) {
            const size_t first = v.cell_start[c], last = v.cell_start[c + 1];
            if (first == last || my_status != CONSPH_OK) continue;
            if (dest) {
                size_t s_dest = first;
                while (s_dest < last && !dest[consph_nnps_slot_particle(&v, s_dest)]) ++s_dest;
                if (s_dest == last) continue;
            }
            if (consph_nnps_cell_runs(s->nnps, c, &runs) == (size_t)-1) {
                my_status = CONSPH_ENOMEM;
                snprintf(my_why, sizeof my_why, "runs of cell %zu: %s", c, consph_last_error());
                continue;
            }
            if (nbhd_scratch_reserve(&sc, runs.candidates + CONSPH_NNPS_GATHER_SLACK) !=
                CONSPH_OK) {
                my_status = CONSPH_ENOMEM;
                snprintf(my_why, sizeof my_why, "out of memory for %zu candidate neighbours",
                         runs.candidates);
                continue;
            }
            for (size_t sl = first; sl < last; ++sl) {
                if (dest && !dest[consph_nnps_slot_particle(&v, sl)]) continue;
                consph_nbhd nb;
                nbhd_gather(s, &v, &runs, sl, need, with_dx, &sc, &nb);
                pass->visit(job, &nb);
                my_pairs += nb.n;
            }
        }
#pragma omp critical(consph_pass_run)
        {
            total += my_pairs;
            /* Several threads may fail; keep the lowest status so the message is reproducible. */
            if (my_status != CONSPH_OK && (status == CONSPH_OK || my_status < status)) {
                status = my_status;
                memcpy(why, my_why, sizeof why);
            }
        }
        consph_nnps_runs_free(&runs);
        nbhd_scratch_free(&sc);
    }
    if (pairs) *pairs += total;
    if (status != CONSPH_OK) return pass_fail(pass, status, why);
    return CONSPH_OK;
}

int consph_pass_run(const consph_sys *s, const consph_pass *pass, void *job)
{
    return consph_pass_run_counted(s, pass, job, NULL);
}

/* ---- the system ---- */

/* A tensor-product kernel is non-zero on the cube |x_a| < radius, whose corners lie sqrt(dim)
 * times farther out than its radius: a search of its radius alone would drop the pairs in the
 * corners. */
double consph_sys_reach(const consph_kernel *kernel)
{
    return kernel->tensor ? kernel->radius * sqrt((double)kernel->dim) : kernel->radius;
}

int consph_sys_wrap(consph_sys *s, consph_particles *p, consph_nnps *nnps,
                    const consph_kernel *kernel)
{
    memset(s, 0, sizeof *s);
    if (!p || !nnps || !kernel)
        return consph_fail(CONSPH_EINVAL,
                           "system: needs particles, a neighbour search and a kernel");
    if (kernel->dim != p->dim)
        return consph_fail(CONSPH_EINVAL,
                           "system: the kernel is bound to %dD, the particles are %dD", kernel->dim,
                           p->dim);
    if (consph_nnps_radius(nnps) < consph_sys_reach(kernel) * (1.0 - 1e-12))
        return consph_fail(
            CONSPH_EINVAL,
            "system: neighbour search radius %g is below the kernel support radius %g",
            consph_nnps_radius(nnps), consph_sys_reach(kernel));
    s->p = p;
    s->nnps = nnps;
    s->kernel = *kernel;
    s->parallel_min = 2048;
    return CONSPH_OK;
}

int consph_sys_init(consph_sys *s, const consph_particles *src, const consph_kernel *kernel,
                    double radius)
{
    memset(s, 0, sizeof *s);
    if (!src || !kernel) return consph_fail(CONSPH_EINVAL, "system: needs particles and a kernel");
    if (kernel->dim != src->dim)
        return consph_fail(CONSPH_EINVAL,
                           "system: the kernel is bound to %dD, the particles are %dD", kernel->dim,
                           src->dim);
    consph_particles *p = consph_calloc(1, sizeof *p);
    size_t *origin = consph_calloc(src->n ? src->n : 1, sizeof(size_t));
    if (!p || !origin) {
        free(p);
        free(origin);
        return CONSPH_ENOMEM;
    }
    int rc = consph_particles_copy(p, src);
    if (rc) {
        free(p);
        free(origin);
        return rc;
    }
    s->p = p;
    s->origin = origin;
    s->owned = 1;
    s->kernel = *kernel;
    s->parallel_min = 2048;
    const double reach = consph_sys_reach(kernel);
    s->nnps = consph_nnps_create(&p->box, radius > reach ? radius : reach, 0);
    if (!s->nnps) {
        consph_sys_free(s);
        return CONSPH_ENOMEM;
    }
    for (size_t i = 0; i < p->n; ++i) origin[i] = i;
    rc = consph_sys_update(s, 1);
    if (rc) consph_sys_free(s);
    return rc;
}

int consph_sys_update(consph_sys *s, int resort)
{
    if (!s || !s->p || !s->nnps)
        return consph_fail(CONSPH_EINVAL, "system update: needs an initialised system");
    s->halo_fresh = 0;
    if (s->split) {
        int rc = s->split->refresh_positions ? s->split->refresh_positions(s, s->split->ctx)
                                             : s->split->refresh(s, s->split->ctx);
        if (rc != CONSPH_OK) return rc;
    }
    if (s->nlist) return nlist_update(s, resort);
    if (!resort) return consph_nnps_build(s->nnps, s->p);
    size_t *perm = sys_resort_buffer(s, s->p->n); /* every entry written by the sort */
    if (!perm) return CONSPH_ENOMEM;
    int rc = consph_nnps_sort(s->nnps, s->p, perm);
    if (rc == CONSPH_OK) rc = sys_carry_permutation(s, perm);
    return rc;
}

size_t *sys_resort_buffer(consph_sys *s, size_t n)
{
    const size_t need = 2 * n + n / sizeof(size_t) + 1;
    if (need > s->resort_cap) {
        free(s->resort_buf);
        s->resort_buf = malloc(need * sizeof(size_t));
        s->resort_cap = s->resort_buf ? need : 0;
        if (!s->resort_buf) {
            consph_fail(CONSPH_ENOMEM, "out of memory re-sorting %zu particles", n);
            return NULL;
        }
    }
    return s->resort_buf;
}

int sys_carry_permutation(consph_sys *s, const size_t *perm)
{
    const size_t n = s->p->n;
    if (!s->origin && !s->dest) return CONSPH_OK;
    /* Carry origin and mask through the same permutation, new[i] = old[perm[i]], by way of the
     * buffer past its first n (perm may be there). */
    size_t *buf = sys_resort_buffer(s, n);
    size_t *o2 = buf && s->origin ? buf + n : NULL;
    unsigned char *d2 = buf && s->dest ? (unsigned char *)(buf + 2 * n) : NULL;
    int rc = CONSPH_OK;
    if (!buf) {
        rc = CONSPH_ENOMEM;
    } else {
        /* on the threads from parallel_min on: a serial sweep here, every re-sort, is a part of
         * the step that no thread count shortens */
        size_t *origin = s->origin;
        unsigned char *dest = s->dest;
#pragma omp parallel if (n >= s->parallel_min)
        {
#pragma omp for schedule(static)
            for (size_t i = 0; i < n; ++i) {
                if (o2) o2[i] = origin[perm[i]];
                if (d2) d2[i] = dest[perm[i]];
            }
#pragma omp for schedule(static)
            for (size_t i = 0; i < n; ++i) {
                if (o2) origin[i] = o2[i];
                if (d2) dest[i] = d2[i];
            }
        }
    }
    return rc;
}

int consph_sys_set_dest(consph_sys *s, const unsigned char *dest)
{
    if (!s || !s->p)
        return consph_fail(CONSPH_EINVAL, "system destination mask: needs an initialised system");
    if (!dest) {
        free(s->dest);
        s->dest = NULL;
        return CONSPH_OK;
    }
    const size_t n = s->p->n;
    if (!s->dest) {
        s->dest = consph_calloc(n ? n : 1, 1);
        if (!s->dest) return CONSPH_ENOMEM;
    }
    memcpy(s->dest, dest, n);
    return CONSPH_OK;
}

int pass_halo_refresh(consph_sys *s)
{
    if (!s->split || s->halo_fresh) {
        s->reads_set = 0;
        return CONSPH_OK;
    }
    const int rc = s->split->refresh(s, s->split->ctx);
    /* a declaration serves the one pass it was made for: the next reads everything unless
     * declared again */
    s->reads_set = 0;
    if (rc == CONSPH_OK) s->halo_fresh = 1;
    return rc;
}

void consph_sys_next_reads(consph_sys *s, const consph_sys_reads *r)
{
    if (!s || !s->split) return;
    s->reads_set = r != NULL;
    if (r) s->reads = *r;
}

double *sys_pack_buffer(consph_sys *s, size_t count)
{
    if (count <= s->pack_cap) return s->pack_buf;
    free(s->pack_buf);
    s->pack_buf = malloc((count ? count : 1) * sizeof(double));
    s->pack_cap = s->pack_buf ? count : 0;
    if (!s->pack_buf) consph_fail(CONSPH_ENOMEM, "out of memory for %zu packed values", count);
    return s->pack_buf;
}

double *consph_sys_scratch(consph_sys *s, size_t count)
{
    s->scratch_asked = count;
    if (count <= s->scratch_cap) return s->scratch;
    double *q = realloc(s->scratch, count * sizeof(double));
    if (!q) {
        consph_fail(CONSPH_ENOMEM, "out of memory for %zu values of system scratch", count);
        return NULL;
    }
    s->scratch = q;
    s->scratch_cap = count;
    return q;
}

void consph_sys_free(consph_sys *s)
{
    if (!s) return;
    free(s->scratch);
    free(s->resort_buf);
    free(s->ipst_buf);
    free(s->pack_buf);
    nlist_free(s->nlist);
    if (s->owned) {
        consph_nnps_free(s->nnps);
        if (s->p) consph_particles_free(s->p);
        free(s->p);
        free(s->origin);
    }
    free(s->dest);
    memset(s, 0, sizeof *s);
}
