/* Particle arrangements: lattice, random (002 §6.2), quasi-random (Halton, 003 §6.2) and the
 * packed arrangement of 001 (the packing itself is in packing.c). */
#include "consph/layout.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "layout/layout_internal.h"

/* More particles than this is certainly a mistake (and would overflow size_t arithmetic in
 * field sizes long before memory runs out on 32-bit hosts). */
#define LAYOUT_MAX_PARTICLES ((size_t)1 << 34)

static const char *const kind_names[CONSPH_LAYOUT_COUNT] = {"lattice", "random", "quasi-random",
                                                            "packed", "packed-polished"};

const char *consph_layout_name(consph_layout_kind kind)
{
    if ((int)kind < 0 || kind >= CONSPH_LAYOUT_COUNT) return "unknown";
    return kind_names[kind];
}

/* Comma-separated without spaces, so the CLI can use it directly as its list of choices. */
const char *consph_layout_names(void)
{
    return "lattice,random,quasi-random,packed,packed-polished";
}

int consph_layout_uses_seed(consph_layout_kind kind)
{
    /* random perturbs the lattice, the packed kinds perturb it before packing; the lattice and
     * Halton's points are deterministic */
    return kind == CONSPH_LAYOUT_RANDOM || kind == CONSPH_LAYOUT_PACKED ||
           kind == CONSPH_LAYOUT_PACKED_POLISHED;
}

const char *consph_layout_seeded_names(char *buf, size_t size)
{
    size_t len = 0;
    if (size) buf[0] = '\0';
    for (int k = 0; k < CONSPH_LAYOUT_COUNT && len < size; ++k)
        if (consph_layout_uses_seed((consph_layout_kind)k))
            len += (size_t)snprintf(buf + len, size - len, "%s%s", len ? ", " : "", kind_names[k]);
    return buf;
}

int consph_layout_lookup(const char *name, consph_layout_kind *kind)
{
    if (name)
        for (int k = 0; k < CONSPH_LAYOUT_COUNT; ++k)
            if (strcmp(name, kind_names[k]) == 0) {
                *kind = (consph_layout_kind)k;
                return CONSPH_OK;
            }
    return consph_fail(CONSPH_EINVAL, "unknown layout kind '%s'; allowed: %s",
                       name ? name : "(null)", consph_layout_names());
}

consph_layout_params consph_layout_defaults(consph_layout_kind kind, int dim, size_t nx)
{
    consph_layout_params lp;
    memset(&lp, 0, sizeof lp);
    lp.kind = kind;
    lp.dim = dim;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) lp.nx[a] = a < dim ? nx : 1;
    /* An invalid dim is kept for consph_layout_generate to reject; the box must not be built
     * with it (consph_box_unit would index past its arrays). */
    if (dim >= 1 && dim <= CONSPH_MAX_DIM)
        lp.box = consph_box_unit(dim, 1);
    else
        lp.box.dim = dim;
    lp.seed = 1;
    lp.eps = 0.2;
    lp.packing.kernel = "quintic";
    lp.packing.hdx = 1.2;
    lp.packing.perturb = 0.5;
    /* packed: the step cap of [51]'s implementation; its stopping rule ends most runs well
     * before (2D nx = 50: about 5800 steps). */
    lp.packing.max_iter = kind == CONSPH_LAYOUT_PACKED ? 40000 : 5000;
    lp.packing.tol = 1e-4;
    lp.packing.move_tol = 1e-2;
    lp.packing.history_every = 50;
    lp.packing.walls = 0;
    return lp;
}

void consph_packing_report_free(consph_packing_report *r)
{
    if (!r) return;
    free(r->history_iter);
    free(r->history_spread);
    memset(r, 0, sizeof *r);
}

/* Validates what every kind needs and returns the particle count. For the lattice-based kinds
 * the spacing must be the same on every axis: p->spacing is one number and the mass
 * m = rho0 Δs^d of 001 assumes square cells. */
static int check_params(const consph_layout_params *lp, size_t *n_out, double *ds_out)
{
    if ((int)lp->kind < 0 || lp->kind >= CONSPH_LAYOUT_COUNT)
        return consph_fail(CONSPH_EINVAL, "layout kind %d is unknown; allowed: %s", (int)lp->kind,
                           consph_layout_names());
    if (lp->dim < 1 || lp->dim > CONSPH_MAX_DIM)
        return consph_fail(CONSPH_EINVAL, "layout dimension %d is not 1, 2 or 3", lp->dim);
    if (lp->box.dim != lp->dim)
        return consph_fail(CONSPH_EINVAL, "layout box has dimension %d but the layout %d",
                           lp->box.dim, lp->dim);
    int rc = consph_box_check(&lp->box);
    if (rc) return rc;
    size_t n = 1;
    for (int a = 0; a < lp->dim; ++a) {
        if (lp->nx[a] < 1)
            return consph_fail(CONSPH_EINVAL, "layout nx[%d] = %zu: need at least 1 particle", a,
                               lp->nx[a]);
        if (lp->nx[a] > LAYOUT_MAX_PARTICLES / n)
            return consph_fail(CONSPH_EINVAL, "layout: too many particles (more than %zu)",
                               LAYOUT_MAX_PARTICLES);
        n *= lp->nx[a];
    }
    double ds = consph_box_length(&lp->box, 0) / (double)lp->nx[0];
    if (lp->kind == CONSPH_LAYOUT_QUASI_RANDOM) {
        ds = pow(consph_box_volume(&lp->box) / (double)n, 1.0 / lp->dim);
    } else {
        for (int a = 1; a < lp->dim; ++a) {
            double dsa = consph_box_length(&lp->box, a) / (double)lp->nx[a];
            if (fabs(dsa - ds) > 1e-12 * ds)
                return consph_fail(CONSPH_EINVAL,
                                   "layout %s: spacing differs between axes (%.17g on axis 0, "
                                   "%.17g on axis %d); choose nx proportional to the box sides",
                                   consph_layout_name(lp->kind), ds, dsa, a);
        }
    }
    if (lp->kind == CONSPH_LAYOUT_RANDOM && !(lp->eps >= 0.0 && lp->eps <= 2.0))
        return consph_fail(CONSPH_EINVAL,
                           "layout random: eps = %g is outside [0, 2] (at 2 a particle may reach "
                           "the edge of its lattice cell)",
                           lp->eps);
    *n_out = n;
    *ds_out = ds;
    return CONSPH_OK;
}

/* Cell-centred lattice x = lo + (i + 1/2) Δs, axis 0 varying fastest:
 * particle index = i0 + nx0 (i1 + nx1 i2); p holds the particles first, first + 1, ... */
static void fill_lattice(const consph_layout_params *lp, consph_particles *p, size_t first)
{
    size_t idx[CONSPH_MAX_DIM] = {0, 0, 0}, rest = first;
    double ds[CONSPH_MAX_DIM];
    for (int a = 0; a < lp->dim; ++a) {
        ds[a] = consph_box_length(&lp->box, a) / (double)lp->nx[a];
        idx[a] = rest % lp->nx[a];
        rest /= lp->nx[a];
    }
    for (size_t i = 0; i < p->n; ++i) {
        for (int a = 0; a < lp->dim; ++a)
            p->x[a][i] = lp->box.lo[a] + ((double)idx[a] + 0.5) * ds[a];
        for (int a = 0; a < lp->dim; ++a) {
            if (++idx[a] < lp->nx[a]) break;
            idx[a] = 0;
        }
    }
}

/* Adds amplitude·Δs·(2U - 1), U uniform in [0, 1), to every coordinate in particle order, axis
 * by axis, and wraps on periodic axes. With amplitude = eps/4 this is 002's x + eps κ Δ with κ
 * uniform in [-0.25, 0.25]. */
static void perturb_positions(const consph_layout_params *lp, consph_particles *p, double ds,
                              double amplitude, size_t first)
{
    consph_rng rng;
    consph_rng_seed(&rng, lp->seed);
    /* particle i draws numbers i·dim to i·dim + dim - 1 of the sequence: those of the particles
     * before `first` are drawn and dropped (a few ns each, no memory) */
    for (size_t k = 0; k < first * (size_t)lp->dim; ++k) (void)consph_rng_next(&rng);
    for (size_t i = 0; i < p->n; ++i)
        for (int a = 0; a < lp->dim; ++a)
            p->x[a][i] += amplitude * ds * (2.0 * consph_rng_uniform(&rng) - 1.0);
    for (int a = 0; a < lp->dim; ++a) {
        const consph_box *b = &lp->box;
        double len = consph_box_length(b, a);
        for (size_t i = 0; i < p->n; ++i) {
            if (b->periodic[a])
                p->x[a][i] = layout_wrap(p->x[a][i], b->lo[a], len);
            else if (p->x[a][i] < b->lo[a])
                p->x[a][i] = b->lo[a];
            else if (p->x[a][i] > b->hi[a])
                p->x[a][i] = b->hi[a];
        }
    }
}

/* The radical inverse of k in `base`: the digits of k mirrored about the radix point. */
static double radical_inverse(uint64_t k, unsigned base)
{
    double inv = 1.0 / base, f = inv, r = 0.0;
    while (k) {
        r += (double)(k % base) * f;
        k /= base;
        f *= inv;
    }
    return r;
}

/* Halton points with bases 2, 3, 5 scaled to the box. Point i uses sequence index i + 1: index 0
 * is the origin in every base, which would put a particle on the box corner. */
static void fill_halton(const consph_layout_params *lp, consph_particles *p, size_t first)
{
    static const unsigned bases[CONSPH_MAX_DIM] = {2, 3, 5};
    for (int a = 0; a < lp->dim; ++a) {
        double lo = lp->box.lo[a], len = consph_box_length(&lp->box, a);
        for (size_t i = 0; i < p->n; ++i)
            p->x[a][i] = lo + len * radical_inverse((uint64_t)(first + i) + 1, bases[a]);
    }
}

/* The packed kinds, through the cache when it is on. */
static int generate_packed(const consph_layout_params *lp, consph_particles *p,
                           consph_packing_report *report)
{
    const int cached = layout_cache_enabled(lp);
    int lock = -1;
    if (cached) {
        char path[4352];
        const int absent =
            consph_layout_cache_path(lp, path, sizeof path) == CONSPH_OK && access(path, F_OK) != 0;
        /* A rejected file fills nothing the packing below does not overwrite. */
        if (layout_check_packing(lp) == CONSPH_OK && layout_cache_load(lp, p, report))
            return CONSPH_OK;
        /* another process may be packing it: wait for it, then read its file (a file rejected
         * above is packed again here) */
        lock = layout_cache_lock(lp);
        if (lock >= 0 && absent && layout_check_packing(lp) == CONSPH_OK &&
            layout_cache_load(lp, p, report)) {
            layout_cache_unlock(lock);
            return CONSPH_OK;
        }
        if (report) memset(report, 0, sizeof *report);
    }
    consph_packing_report own;
    consph_packing_report *rep = report;
    if (cached && !rep) {
        memset(&own, 0, sizeof own);
        rep = &own;
    }
    fill_lattice(lp, p, 0);
    int rc = consph_layout_pack(lp, p, rep);
    if (rc == CONSPH_OK && cached) layout_cache_store(lp, p, rep);
    layout_cache_unlock(lock);
    if (rep == &own) consph_packing_report_free(&own);
    return rc;
}

int consph_layout_by_index(consph_layout_kind kind)
{
    return kind == CONSPH_LAYOUT_LATTICE || kind == CONSPH_LAYOUT_RANDOM ||
           kind == CONSPH_LAYOUT_QUASI_RANDOM;
}

/* The particles [first, first + count) of the layout, or all of them (whole: the packed kinds
 * move every particle together). */
static int generate(const consph_layout_params *lp, consph_particles *p,
                    consph_packing_report *report, int whole, size_t first, size_t count)
{
    memset(p, 0, sizeof *p);
    if (report) memset(report, 0, sizeof *report);
    size_t n = 0;
    double ds = 0.0;
    int rc = check_params(lp, &n, &ds);
    if (rc) return rc;
    if (whole) {
        first = 0;
        count = n;
    } else if (!consph_layout_by_index(lp->kind) && !layout_cache_enabled(lp)) {
        return consph_fail(CONSPH_EINVAL,
                           "layout %s: its particles are packed together, not made one by one "
                           "from their index; generate the whole layout (or read a part from "
                           "the layout cache: consph_layout_cache_set)",
                           consph_layout_name(lp->kind));
    } else if (first > n || count > n - first) {
        return consph_fail(CONSPH_EINVAL,
                           "layout %s: particles [%zu, %zu) are not within its %zu particles",
                           consph_layout_name(lp->kind), first, first + count, n);
    }
    rc = consph_particles_init(p, lp->dim, count, &lp->box);
    if (rc) return rc;
    p->spacing = ds;
    switch (lp->kind) {
    case CONSPH_LAYOUT_LATTICE:
        fill_lattice(lp, p, first);
        break;
    case CONSPH_LAYOUT_RANDOM:
        fill_lattice(lp, p, first);
        perturb_positions(lp, p, ds, 0.25 * lp->eps, first);
        break;
    case CONSPH_LAYOUT_QUASI_RANDOM:
        fill_halton(lp, p, first);
        break;
    case CONSPH_LAYOUT_PACKED:
    case CONSPH_LAYOUT_PACKED_POLISHED:
        if (whole)
            rc = generate_packed(lp, p, report);
        else if ((rc = layout_check_packing(lp)) == CONSPH_OK &&
                 !layout_cache_load_range(lp, n, first, p))
            rc = consph_fail(CONSPH_EINVAL,
                             "layout %s: particles [%zu, %zu) are read from the layout cache "
                             "only, which holds no valid file of this layout; generate the "
                             "whole layout",
                             consph_layout_name(lp->kind), first, first + count);
        break;
    default:
        rc = consph_fail(CONSPH_EINVAL, "layout kind %d is unknown", (int)lp->kind);
    }
    if (rc == CONSPH_OK) {
        double *vol = consph_particles_field(p, "volume", 1);
        if (!vol) {
            rc = CONSPH_ENOMEM;
        } else {
            double v = consph_box_volume(&lp->box) / (double)n;
            for (size_t i = 0; i < count; ++i) vol[i] = v;
        }
    }
    if (rc) {
        consph_particles_free(p);
        if (report) consph_packing_report_free(report);
    }
    return rc;
}

int consph_layout_generate(const consph_layout_params *lp, consph_particles *p,
                           consph_packing_report *report)
{
    return generate(lp, p, report, 1, 0, 0);
}

int consph_layout_generate_range(const consph_layout_params *lp, size_t first, size_t count,
                                 consph_particles *p)
{
    return generate(lp, p, NULL, 0, first, count);
}

void consph_layout_perturb(const consph_layout_params *lp, consph_particles *p, double ds,
                           double amplitude)
{
    perturb_positions(lp, p, ds, amplitude, 0);
}
