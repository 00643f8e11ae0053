/* Particle regularisation: IPST (001 eqs. 19-21), the shifting of Sun et al. (δ+-SPH) and M4
 * remeshing (001 eqs. 32-33). Every pair sum is a pass; the choices and their sources are in
 * docs/schemes.md, section "Regularisation". */
#include "regularise/regularise.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "layout/layout_internal.h"
#include "nnps/nnps_internal.h"
#include "pass/group.h"
#include "pass/lanes4.h"
#include "pass/nbhd.h"
#include "pass/nlist.h"

/* ---- moving particles ---- */

/* Names particle i for a message: its index in the system and, when the system keeps it, the
 * index it had in the particles the system was made from. */
static int fail_particle(const consph_sys *s, size_t i, const char *what, int axis, double x)
{
    if (s->origin)
        return consph_fail(CONSPH_ENUMERIC,
                           "reg_move: particle %zu (input particle %zu): coordinate %d = %g %s", i,
                           s->origin[i], axis, x, what);
    return consph_fail(CONSPH_ENUMERIC, "reg_move: particle %zu: coordinate %d = %g %s", i, axis, x,
                       what);
}

int reg_move(consph_sys *s, const double *dr)
{
    if (!s || !s->p || !dr) return consph_fail(CONSPH_EINVAL, "reg_move: needs a system and dr");
    consph_particles *p = s->p;
    const size_t n = p->n, cap = p->cap;
    const consph_box *b = &p->box;
    /* A decomposed system moves its own particles: the update below brings the halo's
     * positions from their owners, and its dr is not theirs (a shift field that no pass reads
     * at the neighbours is not refreshed: consph_sys_next_reads). */
    const unsigned char *skip = s->split ? s->dest : NULL;
    /* Every new position is checked before any is written, so a refusal moves nothing. */
    for (int a = 0; a < p->dim; ++a)
        for (size_t i = 0; i < n; ++i) {
            if (skip && !skip[i]) continue;
            double x = p->x[a][i] + dr[(size_t)a * cap + i];
            if (!isfinite(x)) return fail_particle(s, i, "is not finite after the shift", a, x);
            if (!b->periodic[a] && (x < b->lo[a] || x > b->hi[a]))
                return fail_particle(s, i, "leaves the non-periodic box", a, x);
        }
    for (int a = 0; a < p->dim; ++a) {
        const double len = b->hi[a] - b->lo[a];
        for (size_t i = 0; i < n; ++i) {
            if (skip && !skip[i]) continue;
            double x = p->x[a][i] + dr[(size_t)a * cap + i];
            p->x[a][i] = b->periodic[a] ? layout_wrap(x, b->lo[a], len) : x;
        }
    }
    return consph_sys_update(s, 0);
}

/* ---- IPST ---- */

double reg_chi0(const consph_kernel *k, double ds)
{
    if (!k || !(ds > 0.0) || !isfinite(ds) || k->tensor) {
        consph_fail(CONSPH_EINVAL, "reg_chi0: needs a radial kernel and a spacing ds > 0");
        return NAN;
    }
    /* A periodic lattice a little wider than the support: the sum at any of its points is the
     * sum over the infinite lattice, computed by the same density pass IPST uses. */
    const int d = k->dim;
    const size_t m = (size_t)ceil(2.0 * consph_sys_reach(k) / ds) + 1;
    size_t n = 1;
    for (int a = 0; a < d; ++a) n *= m;
    consph_box box = consph_box_unit(d, 1);
    for (int a = 0; a < d; ++a) box.hi[a] = (double)m * ds;
    consph_particles p;
    if (consph_particles_init(&p, d, n, &box)) return NAN;
    for (size_t i = 0; i < n; ++i)
        for (size_t a = 0, r = i; a < (size_t)d; ++a, r /= m) p.x[a][i] = (double)(r % m) * ds;
    consph_sys sys;
    double chi = NAN;
    double *sumw = NULL;
    if (consph_sys_init(&sys, &p, k, 0.0) == CONSPH_OK) {
        if ((sumw = consph_calloc(n, sizeof(double))) &&
            consph_layout_density(&sys, 1.0, sumw, NULL) == CONSPH_OK)
            chi = pow(k->h, d) * sumw[0];
        consph_sys_free(&sys);
    }
    free(sumw);
    consph_particles_free(&p);
    return chi;
}

typedef struct ipst_job {
    double h;
    const double *vol;
    double *step; /* d × cap */
    size_t cap;
    int dim;
} ipst_job;

/* Eq. 19: δx_i = h Σ_j (x_ij/r_ij) W_ij ω_j. A neighbour at r = 0 (i itself, or a coincident
 * particle) has no direction and adds nothing. d known at compile time, so the sums stay in
 * registers (with d read at run time they went through memory at every pair).
 *
 * The factors W_ij ω_j / r_ij are independent of each other: they are computed for a chunk of
 * pairs first, four at a time, then added in the neighbours' order. A pair without direction
 * gets the factor 0 and the separation +0, whose product +0 leaves the sums as skipping it does
 * (a sum that starts at +0 is never -0), so the values are those of one loop over the pairs,
 * bit for bit. */
#define IPST_CHUNK 64
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
ipst_body(const ipst_job *a, const consph_nbhd *nb, const int D)
{
    const double *vol = a->vol;
    double acc[3] = {0.0, 0.0, 0.0};
    double f[IPST_CHUNK], x[3][IPST_CHUNK];
    for (size_t q0 = 0; q0 < nb->n; q0 += IPST_CHUNK) {
        const size_t m = nb->n - q0 < IPST_CHUNK ? nb->n - q0 : IPST_CHUNK;
        const double *rq = nb->r + q0, *wq = nb->w + q0;
        const size_t *jq = nb->j + q0;
        size_t k = 0;
#ifdef CONSPH_LANES4
        /* the division on every lane (by 1 where the pair has no direction), then the select */
        const lane4 zero = {0.0, 0.0, 0.0, 0.0}, one = {1.0, 1.0, 1.0, 1.0};
        for (; k + 4 <= m; k += 4) {
            const lane4 rk = *(const lane4u *)(rq + k), wk = *(const lane4u *)(wq + k);
            const lane4 vk = {vol[jq[k]], vol[jq[k + 1]], vol[jq[k + 2]], vol[jq[k + 3]]};
            const lane4i has = rk > zero;
            const lane4 ratio = wk * vk / LANE4_SEL(has, rk, one);
            *(lane4u *)(f + k) = LANE4_SEL(has, ratio, zero);
            for (int c = 0; c < D; ++c)
                *(lane4u *)(x[c] + k) = LANE4_SEL(has, *(const lane4u *)(nb->dx[c] + q0 + k), zero);
        }
#endif
        for (; k < m; ++k) {
            const int has = rq[k] > 0.0;
            f[k] = has ? wq[k] * vol[jq[k]] / rq[k] : 0.0;
            for (int c = 0; c < D; ++c) x[c][k] = has ? nb->dx[c][q0 + k] : 0.0;
        }
        for (k = 0; k < m; ++k)
            for (int c = 0; c < D; ++c) acc[c] += f[k] * x[c][k];
    }
    for (int c = 0; c < D; ++c) a->step[(size_t)c * a->cap + nb->i] = a->h * acc[c];
}

LANE4_CLONES static void ipst_visit_1(void *job, const consph_nbhd *nb)
{
    ipst_body(job, nb, 1);
}
LANE4_CLONES static void ipst_visit_2(void *job, const consph_nbhd *nb)
{
    ipst_body(job, nb, 2);
}
LANE4_CLONES static void ipst_visit_3(void *job, const consph_nbhd *nb)
{
    ipst_body(job, nb, 3);
}

/* max_i h^d Σ_j W_ij over the destinations (NaN when any sum is NaN), over every part of a
 * decomposed system. */
static double ipst_chi_max(const consph_sys *s, double h, const double *sumw)
{
    const double hd = pow(h, s->p->dim);
    double mx = -INFINITY;
    for (size_t i = 0; i < s->p->n; ++i) {
        if (s->dest && !s->dest[i]) continue; /* a halo particle: its part's maximum */
        double chi = hd * sumw[i];
        if (isnan(chi)) mx = NAN;
        if (chi > mx) mx = chi;
    }
    return s->split ? s->split->max(s->split->ctx, mx) : mx;
}

/* Writes ω = 1/Σ_j W_ij into vol and returns max_i h^d Σ_j W_ij (NaN when any sum is NaN). */
static int ipst_volumes(const consph_sys *s, double h, double *sumw, double *vol, double *chi_max)
{
    int rc = consph_layout_density(s, 1.0, sumw, NULL);
    if (rc) return rc;
    for (size_t i = 0; i < s->p->n; ++i) vol[i] = 1.0 / sumw[i];
    *chi_max = ipst_chi_max(s, h, sumw);
    return CONSPH_OK;
}

unsigned long reg_ipst_chains;

/* Σ_j W_ij and ω_i = 1/Σ_j W_ij of particle i: consph_layout_density's sum (mass 1) and
 * ipst_volumes' reciprocal, the same operations in the same order. */
typedef struct ipst_volume_job {
    double *sumw, *vol;
} ipst_volume_job;

static void ipst_volume_visit(void *job, const consph_nbhd *nb)
{
    const ipst_volume_job *v = job;
    double w = 0.0;
    for (size_t q = 0; q < nb->n; ++q) w += nb->w[q];
    const double sum = 1.0 * w;
    v->sumw[nb->i] = sum;
    v->vol[nb->i] = 1.0 / sum;
}

#ifdef CONSPH_LANES4
/* ---- the volumes and the shift over groups of four particles ----
 *
 * Each visit above sums one particle's neighbours in a chain of dependent additions (one per
 * axis for the shift), so the additions' latency, not the arithmetic, bounds it. The chained
 * iterations hand groups of four consecutive particles of a block of the pair cache
 * (src/pass/group.h) to the visits below instead: lane l of every vector is particle l's sum,
 * taken over its own neighbours in their order with the same operations as the per-particle
 * visit, so each result is that visit's bit for bit (tests/test_regularise.c). The cache's
 * arrays are not padded past a lane's n (PASS_GROUP_UNPADDED): the lanes that have run out are
 * masked, never read past their end. */

/* GCC builds a vector from scalars by inserting them into the destination's old value, and then
 * warns that the old value may be uninitialised (it is never read) */
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

/* The lanes' neighbour counts, the smallest and the largest. */
static inline void ipst_lane_counts(const consph_nbhd *nb, size_t n[PASS_GROUP], size_t *kmin,
                                    size_t *kmax)
{
    *kmin = *kmax = nb[0].n;
    for (int l = 0; l < PASS_GROUP; ++l) {
        n[l] = nb[l].n;
        if (n[l] < *kmin) *kmin = n[l];
        if (n[l] > *kmax) *kmax = n[l];
    }
}

/* ipst_volume_visit over a group */
LANE4_CLONES static void ipst_volume_group(void *job, const consph_nbhd *nb, int count)
{
    const ipst_volume_job *v = job;
    size_t n[PASS_GROUP], kmin, kmax;
    ipst_lane_counts(nb, n, &kmin, &kmax);
    lane4 w = {0.0, 0.0, 0.0, 0.0};
    size_t k = 0;
    for (; k + 4 <= kmin; k += 4) {
        lane4 f[4];
        const double *q[PASS_GROUP] = {nb[0].w, nb[1].w, nb[2].w, nb[3].w};
        lane4_transpose(q, k, f);
        w += f[0];
        w += f[1];
        w += f[2];
        w += f[3];
    }
    const lane4i nv = {(long long)n[0], (long long)n[1], (long long)n[2], (long long)n[3]};
    for (; k < kmax; ++k) {
        size_t e[PASS_GROUP];
        for (int l = 0; l < PASS_GROUP; ++l) e[l] = k < n[l] ? k : 0;
        const lane4 wk = {nb[0].w[e[0]], nb[1].w[e[1]], nb[2].w[e[2]], nb[3].w[e[3]]};
        const lane4i kv = {(long long)k, (long long)k, (long long)k, (long long)k};
        w = LANE4_SEL((lane4i)(kv < nv), w + wk, w);
    }
    for (int l = 0; l < count; ++l) {
        const double sum = 1.0 * w[l];
        v->sumw[nb[l].i] = sum;
        v->vol[nb[l].i] = 1.0 / sum;
    }
}

/* lane4_transpose of the four rows p + q, p + q + o1, p + q + o2, p + q + o3: rows of one array
 * at one offset per lane from lane 0's (the pair cache's blocks), formed here rather than held
 * as pointers per array and lane, which spilled. */
static inline __attribute__((always_inline)) void ipst_rows(const double *p, size_t q, size_t o1,
                                                            size_t o2, size_t o3, lane4 f[4])
{
    const double *const rows[PASS_GROUP] = {p + q, p + q + o1, p + q + o2, p + q + o3};
    lane4_transpose(rows, 0, f);
}

/* ipst_body over a group, the four particles side by side: lane l of every vector is particle
 * l's, its factor W ω / r and separations computed as ipst_body computes them and added in its
 * own neighbours' order, so that each lane's sums are ipst_body's bit for bit. While every lane
 * has four more pairs, their values come as rows of four and are transposed into columns (one
 * vector per pair index); then one pair index at a time, the lanes that have run out keeping
 * their sums. Before, each lane's factors were staged through a chunk
 * buffer and summed lane by lane in scalar code. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
ipst_group_body(const ipst_job *a, const consph_nbhd *nb, int count, const int D)
{
    const double *vol = a->vol;
    size_t n[PASS_GROUP], kmin, kmax;
    ipst_lane_counts(nb, n, &kmin, &kmax);
    const lane4 zero = {0.0, 0.0, 0.0, 0.0}, one = {1.0, 1.0, 1.0, 1.0};
    lane4 acc[3] = {zero, zero, zero};
    const double *rq[PASS_GROUP] = {nb[0].r, nb[1].r, nb[2].r, nb[3].r};
    const double *wq[PASS_GROUP] = {nb[0].w, nb[1].w, nb[2].w, nb[3].w};
    const double *xq[3][PASS_GROUP];
    for (int c = 0; c < D; ++c)
        for (int l = 0; l < PASS_GROUP; ++l) xq[c][l] = nb[l].dx[c];
    size_t k = 0;
    /* The rows of four are read where the lanes' entries lie at one offset per lane in every
     * array (the blocks of the neighbour list's pair cache, the only caller's: always), by that
     * offset from lane 0's pointers: 5 pointers and 3 offsets instead of 20 pointers, which
     * spilled (measured ~-1.5 % on L-IPST-C's quick row, within the noise). The loop after it,
     * one pair index at a time, does the rest (and all of any other layout). */
    size_t off[PASS_GROUP];
    int shared = 1;
    for (int l = 0; l < PASS_GROUP; ++l) {
        const uintptr_t d = (uintptr_t)nb[l].r - (uintptr_t)nb[0].r;
        off[l] = (size_t)(d / sizeof(double));
        shared &= d % sizeof(double) == 0 && (uintptr_t)nb[l].w == (uintptr_t)nb[0].w + d &&
                  (uintptr_t)nb[l].j == (uintptr_t)nb[0].j + off[l] * sizeof(size_t);
        for (int c = 0; c < D; ++c) shared &= (uintptr_t)nb[l].dx[c] == (uintptr_t)nb[0].dx[c] + d;
    }
    if (shared) {
        const double *r0 = nb[0].r, *w0 = nb[0].w, *x0[3] = {nb[0].dx[0], nb[0].dx[1], nb[0].dx[2]};
        const size_t *j0 = nb[0].j;
        const size_t o1 = off[1], o2 = off[2], o3 = off[3];
        for (; k + 4 <= kmin; k += 4) {
            lane4 r4[4], w4[4], x4[3][4];
            ipst_rows(r0, k, o1, o2, o3, r4);
            ipst_rows(w0, k, o1, o2, o3, w4);
            for (int c = 0; c < D; ++c) ipst_rows(x0[c], k, o1, o2, o3, x4[c]);
            for (int e = 0; e < 4; ++e) {
                const size_t q = k + (size_t)e;
                const lane4 vk = {vol[j0[q]], vol[j0[q + o1]], vol[j0[q + o2]], vol[j0[q + o3]]};
                const lane4i has = r4[e] > zero;
                const lane4 ratio = w4[e] * vk / LANE4_SEL(has, r4[e], one);
                const lane4 f = LANE4_SEL(has, ratio, zero);
                for (int c = 0; c < D; ++c) acc[c] += f * LANE4_SEL(has, x4[c][e], zero);
            }
        }
    }
    const lane4i nv = {(long long)n[0], (long long)n[1], (long long)n[2], (long long)n[3]};
    for (; k < kmax; ++k) {
        /* a lane that has run out (k >= its n, past the smallest count) reads its first pair (no
         * neighbour's volume) and keeps its sums */
        size_t e[PASS_GROUP];
        double v[PASS_GROUP];
        for (int l = 0; l < PASS_GROUP; ++l) {
            e[l] = k < n[l] ? k : 0;
            v[l] = k < n[l] ? vol[nb[l].j[k]] : 0.0;
        }
        const lane4 rk = {rq[0][e[0]], rq[1][e[1]], rq[2][e[2]], rq[3][e[3]]};
        const lane4 wk = {wq[0][e[0]], wq[1][e[1]], wq[2][e[2]], wq[3][e[3]]};
        const lane4 vk = {v[0], v[1], v[2], v[3]};
        const lane4i kv = {(long long)k, (long long)k, (long long)k, (long long)k};
        const lane4i live = kv < nv;
        const lane4i has = rk > zero;
        const lane4 ratio = wk * vk / LANE4_SEL(has, rk, one);
        const lane4 f = LANE4_SEL(has, ratio, zero);
        for (int c = 0; c < D; ++c) {
            const lane4 xk = {xq[c][0][e[0]], xq[c][1][e[1]], xq[c][2][e[2]], xq[c][3][e[3]]};
            acc[c] = LANE4_SEL(live, acc[c] + f * LANE4_SEL(has, xk, zero), acc[c]);
        }
    }
    const int L = count < PASS_GROUP ? count : PASS_GROUP;
    for (int l = 0; l < L; ++l)
        for (int c = 0; c < D; ++c) a->step[(size_t)c * a->cap + nb[l].i] = a->h * acc[c][l];
}

LANE4_CLONES static void ipst_group_1(void *job, const consph_nbhd *nb, int count)
{
    ipst_group_body(job, nb, count, 1);
}
LANE4_CLONES static void ipst_group_2(void *job, const consph_nbhd *nb, int count)
{
    ipst_group_body(job, nb, count, 2);
}
LANE4_CLONES static void ipst_group_3(void *job, const consph_nbhd *nb, int count)
{
    ipst_group_body(job, nb, count, 3);
}
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif
static const pass_group_fn ipst_groups[3] = {ipst_group_1, ipst_group_2, ipst_group_3};
#define IPST_VOLUME_GROUP ipst_volume_group
#else
static const pass_group_fn ipst_groups[3] = {NULL, NULL, NULL};
#define IPST_VOLUME_GROUP NULL
#endif

/* Whether the chained iterations run the group visits (1, the default) or the per-particle
 * ones: the same values; a switch for the tests that say so. */
int reg_ipst_groups = 1;

/* The volumes and the shift of one position state chained over the neighbour list's pair cache
 * (src/pass/nlist.h, nlist_chain_run): the shift of a block runs as soon as the volumes of its
 * neighbours are known, while the block's pairs are still in the processor's caches, instead of
 * a second sweep over the whole cache. The values of ipst_volumes then the shift's pass. *ran 0
 * where the list cannot chain them (no list, a mask, a decomposed system): nothing done. */
static int ipst_chained(consph_sys *s, const consph_pass *shift, ipst_job *job, double *sumw,
                        double *vol, int *ran)
{
    *ran = 0;
    if (!s->nlist || !nlist_serves(s->nlist, s->p->n) || s->dest || s->split) return CONSPH_OK;
    ipst_volume_job vj = {sumw, vol};
    const consph_pass volumes = {"IPST volumes 1/sum W", CONSPH_PASS_W | CONSPH_PASS_NO_DX,
                                 ipst_volume_visit};
    const int g = reg_ipst_groups;
    const block_visitor_in chain[2] = {
        {&volumes, g ? IPST_VOLUME_GROUP : NULL, &vj, 0, NULL, NULL},
        {shift, g ? ipst_groups[job->dim - 1] : NULL, job, 0, NULL, NULL}};
    size_t pairs = 0;
    const int rc = nlist_chain_run(s, chain, 2, &pairs, ran);
    if (rc == CONSPH_OK && *ran) __atomic_fetch_add(&reg_ipst_chains, 1, __ATOMIC_RELAXED);
    return rc;
}

/* What IPST's passes read at the neighbours (consph_sys_next_reads): the volumes' W alone, the
 * shift's ω_j (written on every particle from Σ W, the halo's from sums no pass made there: the
 * refresh brings the owners'). */
static const consph_sys_reads ipst_volume_reads = {0, 0, {NULL}, {0}};
static const consph_sys_reads ipst_shift_reads = {0, 0, {"volume"}, {0}};

int reg_ipst(consph_sys *s, const reg_ipst_params *prm, double *dr_total, reg_ipst_report *rep)
{
    if (!s || !s->p || !prm || !dr_total)
        return consph_fail(CONSPH_EINVAL, "IPST: needs a system, parameters and dr_total");
    if (!(prm->h > 0.0) || !isfinite(prm->h) || !(prm->chi0 > 0.0) || !isfinite(prm->chi0) ||
        !(prm->tol > 0.0) || prm->max_iter < 0)
        return consph_fail(CONSPH_EINVAL,
                           "IPST: needs h > 0, chi0 > 0, tol > 0 and max_iter >= 0 (got h = %g, "
                           "chi0 = %g, tol = %g, max_iter = %d)",
                           prm->h, prm->chi0, prm->tol, prm->max_iter);
    /* a decomposed system's halo is shifted by its own part (the shift of a particle outside
     * the mask stays 0 here) */
    if (s->dest && !s->split)
        return consph_fail(CONSPH_EINVAL,
                           "IPST: the system has a destination mask; IPST shifts every particle");
    consph_particles *p = s->p;
    const size_t n = p->n, cap = p->cap;
    const int d = p->dim;
    double *vol = consph_particles_field(p, "volume", 1);
    if (!vol) return CONSPH_EINVAL;
    /* The system keeps the three buffers between calls: allocated at each call, they came back
     * from the kernel as fresh pages where their size passes glibc's mmap threshold. Zeroed
     * here as the allocation did. */
    const size_t nsum = ((n ? n : 1) + 7) & ~(size_t)7, nstep = ((size_t)d * cap + 7) & ~(size_t)7,
                 need = nsum + 2 * nstep;
    if (need > s->ipst_cap) {
        free(s->ipst_buf);
        s->ipst_buf = malloc(need * sizeof(double));
        s->ipst_cap = s->ipst_buf ? need : 0;
    }
    int rc = s->ipst_buf ? CONSPH_OK : CONSPH_ENOMEM;
    double *sumw = s->ipst_buf, *step = sumw ? sumw + nsum : NULL,
           *total = step ? step + nstep : NULL;
    if (sumw) memset(sumw, 0, need * sizeof(double));
    ipst_job job = {prm->h, vol, step, cap, d};
    static const consph_visit_fn visits[3] = {ipst_visit_1, ipst_visit_2, ipst_visit_3};
    const consph_pass pass = {"IPST shift (001 eq. 19)", CONSPH_PASS_W, visits[d - 1]};
    int iterations = 0;
    double chi_max = NAN;
    while (rc == CONSPH_OK) {
        /* Each position state is read by the volumes' pass and, unless eq. 21 stops the
         * iteration, the shift's: one gather and one kernel batch for both where the system
         * keeps a neighbour list (its pair cache; the same values). */
        consph_sys_expect_passes(s, iterations < prm->max_iter ? 2 : 1, CONSPH_PASS_W);
        /* While another shift may follow, the shift is computed with the volumes (chained),
         * before eq. 21 is tested: where the test then stops the iteration, the shift is not
         * applied, so the positions and volumes returned are those of computing it only when
         * needed. */
        int shifted = 0;
        if (iterations < prm->max_iter && (rc = ipst_chained(s, &pass, &job, sumw, vol, &shifted)))
            break;
        /* The volumes are those of the current positions; the last refresh leaves "volume"
         * matching the positions the call returns. */
        if (!shifted) consph_sys_next_reads(s, &ipst_volume_reads);
        if (shifted)
            chi_max = ipst_chi_max(s, prm->h, sumw);
        else if ((rc = ipst_volumes(s, prm->h, sumw, vol, &chi_max)))
            break;
        if ((iterations >= prm->min_iter && fabs(chi_max - prm->chi0) < prm->tol) ||
            iterations >= prm->max_iter)
            break;
        if (!shifted) consph_sys_next_reads(s, &ipst_shift_reads);
        if (!shifted && (rc = consph_pass_run(s, &pass, &job))) break;
        if ((rc = reg_move(s, step))) break;
        for (size_t k = 0; k < (size_t)d * cap; ++k) total[k] += step[k];
        ++iterations;
    }
    if (rc == CONSPH_OK) {
        double mx = 0.0;
        for (size_t i = 0; i < n; ++i) {
            double r2 = 0.0;
            for (int a = 0; a < d; ++a) {
                double v = total[(size_t)a * cap + i];
                dr_total[(size_t)a * cap + i] += v;
                r2 += v * v;
            }
            if (r2 > mx) mx = r2;
        }
        if (rep) {
            rep->iterations = iterations;
            rep->chi_err = fabs(chi_max - prm->chi0);
            rep->max_shift = sqrt(mx) / prm->h;
            rep->chi_max = chi_max;
        }
    }
    return rc;
}

/* ---- shifting of Sun et al. ---- */

/* δr_i = -CFL·Ma·(2h)² Σ_j [1 + R (W_ij/W(Δs))^n] ∇W_ij V_j, capped in length. The self term
 * has ∇W = 0. n4: n is 4 (every caller's), the power taken as (t²)², which differs from pow()
 * at round-off and costs a fraction of it. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
pst_body(const reg_pst_job *a, const consph_nbhd *nb, const int n4, const int D)
{
    double acc[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
    for (size_t q = 0; q < nb->n; ++q) {
        const double t = nb->w[q] * a->inv_wds, t2 = t * t;
        const double f =
            (1.0 + a->R * (n4 ? t2 * t2 : pow(t, a->n))) * nb->dwr[q] * a->vol[nb->j[q]];
        for (int c = 0; c < D; ++c) acc[c] += f * nb->dx[c][q];
    }
    double len2 = 0.0;
    for (int c = 0; c < D; ++c) {
        acc[c] *= a->coef;
        len2 += acc[c] * acc[c];
    }
    const double len = sqrt(len2);
    const double scale = len > a->cap_len ? a->cap_len / len : 1.0;
    for (int c = 0; c < D; ++c) a->dr[(size_t)c * a->cap + nb->i] = scale * acc[c];
}

/* The dimension known at compile time: the sums stay in registers (with a run-time count they
 * went through the stack at every pair) */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
pst_by_dim(const reg_pst_job *a, const consph_nbhd *nb, const int n4)
{
    if (a->dim == 1)
        pst_body(a, nb, n4, 1);
    else if (a->dim == 2)
        pst_body(a, nb, n4, 2);
    else
        pst_body(a, nb, n4, 3);
}
static void pst_visit(void *job, const consph_nbhd *nb)
{
    pst_by_dim(job, nb, 0);
}
static void pst_visit_n4(void *job, const consph_nbhd *nb)
{
    pst_by_dim(job, nb, 1);
}

int reg_pst_pass(const consph_sys *s, const reg_pst_params *prm, double *dr, reg_pst_job *job,
                 consph_pass *pass)
{
    if (!s || !s->p || !prm || !dr)
        return consph_fail(CONSPH_EINVAL, "PST: needs a system, parameters and dr");
    if (!(prm->h > 0.0) || !(prm->ds > 0.0) || !isfinite(prm->h) || !isfinite(prm->ds) ||
        !(prm->cfl >= 0.0) || !(prm->mach >= 0.0) || !isfinite(prm->cfl) || !isfinite(prm->mach) ||
        !(prm->R >= 0.0) || !(prm->n > 0.0) || isnan(prm->max_shift))
        return consph_fail(CONSPH_EINVAL,
                           "PST: needs h > 0, ds > 0, cfl >= 0, mach >= 0, R >= 0 and n > 0 (got "
                           "h = %g, ds = %g, cfl = %g, mach = %g, R = %g, n = %g)",
                           prm->h, prm->ds, prm->cfl, prm->mach, prm->R, prm->n);
    const consph_field *fv = consph_particles_find(s->p, "volume");
    if (!fv || fv->ncomp != 1)
        return consph_fail(CONSPH_EINVAL, "PST: the particles have no one-component field "
                                          "\"volume\"");
    const double wds = consph_kernel_w(&s->kernel, prm->ds);
    if (!(wds > 0.0))
        return consph_fail(CONSPH_EINVAL,
                           "PST: the kernel '%s' is zero at ds = %g; W(ds) normalises the "
                           "anti-clumping term",
                           s->kernel.name, prm->ds);
    const size_t cap = s->p->cap;
    /* Particles outside a destination mask get no shift. */
    memset(dr, 0, (size_t)s->p->dim * cap * sizeof(double));
    const double twoh = 2.0 * prm->h;
    *job = (reg_pst_job){-prm->cfl * prm->mach * twoh * twoh,
                         1.0 / wds,
                         prm->R,
                         prm->n,
                         prm->max_shift > 0.0 ? prm->max_shift * prm->h : INFINITY,
                         fv->data,
                         dr,
                         cap,
                         s->p->dim};
    *pass = (consph_pass){"PST of Sun et al.", CONSPH_PASS_W | CONSPH_PASS_DW,
                          prm->n == 4.0 ? pst_visit_n4 : pst_visit};
    return CONSPH_OK;
}

int reg_pst_shift(const consph_sys *s, const reg_pst_params *prm, double *dr)
{
    reg_pst_job job;
    consph_pass pass;
    const int st = reg_pst_pass(s, prm, dr, &job, &pass);
    return st != CONSPH_OK ? st : consph_pass_run(s, &pass, &job);
}

/* ---- remeshing ---- */

/* src/kernels/kernels.c's m4_f (001 eq. 32's profile), the same operations, inlined: called
 * through the kernel's pointer it was a call per axis and pair. */
static inline double remesh_m4_f(double q)
{
    double inner = 1.0 - q * q * (2.5 - 1.5 * q);
    double t = 2.0 - q, outer = 0.5 * (1.0 - q) * t * t;
    return q < 1.0 ? inner : q < 2.0 ? outer : 0.0;
}

/* The remeshing's AVX-512 and AVX2 copies (src/pass/lanes4.h) */
#ifdef LANE4_CLONES
#define REMESH_CLONES LANE4_CLONES
#else
#define REMESH_CLONES
#endif

/* Components summed in registers or on the stack (the solver remeshes d + 1); more go through
 * out, with the same operations. */
#define REMESH_LOCAL_ROWS 16

typedef struct remesh_job {
    const consph_kernel *m4;
    size_t n;
    size_t rows;              /* components of all the fields */
    const double *const *src; /* row r: the particles' values of component r */
    double *out;              /* rows of n values, one per component */
    unsigned char *orphan;
} remesh_job;

/* Eq. 33 at lattice point k: Σ_j φ_j M4_kj / Σ_j M4_kj over its m neighbouring particles j[]
 * at separations dx (lattice point minus particle), in their order. The sums run in a local
 * array, written once: into out, which may alias the sources as far as the compiler knows,
 * every pair was a load and a store per component. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
remesh_point(const remesh_job *a, size_t k, size_t m, const size_t *j, double *const *dx,
             const int D)
{
    const size_t rows = a->rows;
    const double *const *src = a->src;
    double local[REMESH_LOCAL_ROWS];
    const int in_out = rows > REMESH_LOCAL_ROWS;
    double *acc = in_out ? a->out + k : local;
    const size_t stride = in_out ? a->n : 1;
    double wsum = 0.0;
    for (size_t r = 0; r < rows; ++r) acc[r * stride] = 0.0;
    const double norm = a->m4->norm, inv_h = a->m4->inv_h, support = a->m4->support;
    size_t q0 = 0;
#ifdef CONSPH_LANES4
    /* The weights of four candidates at once, every lane the loop's operations below, without
     * its branches: an axis at or past the support gives 0 and the later axes keep a zero a zero
     * (of either sign; a zero weight is skipped either way), so every weight that is not zero is
     * the loop's bit for bit. The candidates are then added in their order. Without the branches
     * on each candidate's axes and weight a remeshing takes about a third less time
     * (docs/pass.md). */
    const lane4 vnorm = {norm, norm, norm, norm}, vinv_h = {inv_h, inv_h, inv_h, inv_h};
    const lane4 vsupp = {support, support, support, support}, zero = {0.0, 0.0, 0.0, 0.0};
    const lane4 one = {1.0, 1.0, 1.0, 1.0}, two = {2.0, 2.0, 2.0, 2.0};
    const lane4 c25 = {2.5, 2.5, 2.5, 2.5}, c15 = {1.5, 1.5, 1.5, 1.5}, half = {0.5, 0.5, 0.5, 0.5};
    while (q0 + 4 <= m) {
        /* up to 64 candidates' weights, the ones not zero kept in order without a branch, then
         * added: a branch per candidate on its weight was mispredicted about as often as taken */
        double bw[64];
        size_t bj[64], nz = 0;
        const size_t left = (m - q0) & ~(size_t)3, qend = q0 + (left < 64 ? left : 64);
        for (; q0 < qend; q0 += 4) {
            lane4 w = vnorm;
            for (int c = 0; c < D; ++c) {
                const lane4 qa = LANE4_ABS(*(const lane4u *)(dx[c] + q0)) * vinv_h;
                const lane4 inner = one - qa * qa * (c25 - c15 * qa);
                const lane4 t = two - qa, outer = half * (one - qa) * t * t;
                const lane4 f = LANE4_SEL((lane4i)(qa < one), inner,
                                          LANE4_SEL((lane4i)(qa < two), outer, zero));
                w = LANE4_SEL((lane4i)(qa < vsupp), w * f, zero);
            }
            for (int e = 0; e < 4; ++e) {
                bw[nz] = w[e];
                bj[nz] = j[q0 + (size_t)e];
                nz += w[e] != 0.0;
            }
        }
        for (size_t t = 0; t < nz; ++t) {
            const double we = bw[t];
            const size_t jq = bj[t];
            wsum += we;
            for (size_t r = 0; r < rows; ++r) acc[r * stride] += we * src[r][jq];
        }
    }
#endif
    for (size_t q = q0; q < m; ++q) {
        /* M4 of the separation (consph_kernel_w_vec's product) */
        double w = norm;
        for (int c = 0; c < D && w != 0.0; ++c) {
            const double qa = fabs(dx[c][q]) * inv_h;
            w = qa < support ? w * remesh_m4_f(qa) : 0.0;
        }
        if (w == 0.0) continue;
        const size_t jq = j[q];
        wsum += w;
        for (size_t r = 0; r < rows; ++r) acc[r * stride] += w * src[r][jq];
    }
    a->orphan[k] = wsum == 0.0;
    if (wsum == 0.0) {
        /* out holds 0 for an orphan, as before */
        if (!in_out)
            for (size_t r = 0; r < rows; ++r) a->out[r * a->n + k] = 0.0;
        return;
    }
    for (size_t r = 0; r < rows; ++r) a->out[r * a->n + k] = acc[r * stride] / wsum;
}

REMESH_CLONES static void remesh_point_1(const remesh_job *a, size_t k, size_t m, const size_t *j,
                                         double *const *dx)
{
    remesh_point(a, k, m, j, dx, 1);
}
REMESH_CLONES static void remesh_point_2(const remesh_job *a, size_t k, size_t m, const size_t *j,
                                         double *const *dx)
{
    remesh_point(a, k, m, j, dx, 2);
}
REMESH_CLONES static void remesh_point_3(const remesh_job *a, size_t k, size_t m, const size_t *j,
                                         double *const *dx)
{
    remesh_point(a, k, m, j, dx, 3);
}

typedef void (*remesh_point_fn)(const remesh_job *a, size_t k, size_t m, const size_t *j,
                                double *const *dx);

/* Eq. 33 at every lattice point, over a search of the particles alone. The sums at a lattice
 * point were taken over a joint search of the lattice points and the particles (2n points), the
 * lattice points skipped: the neighbours of a lattice point were then the particles of the cells
 * its cell's walk visits, cell after cell in the walk's order and by particle index within a
 * cell (the sort is stable, and every lattice point came before every particle), those within
 * the search radius. A search of the particles alone on the grid that 2n points get
 * (nnps_fix_grid) has the same cells, the same walk and the same order within a cell, and the
 * same hit test from the same lattice coordinates: the same neighbours in the same order with
 * the same separations, hence the same sums bit for bit, without sorting 2n points and
 * gathering the lattice points only to skip them (tests/test_regularise.c compares it with the
 * joint search). The lattice points are binned into the same grid so that each cell's runs of
 * candidates are walked once for all of its lattice points. */
static int remesh_sums(const consph_sys *s, const double *lattice, const remesh_job *job)
{
    const consph_particles *p = s->p;
    const size_t n = p->n, cap = p->cap;
    const int d = p->dim;
    consph_nnps *g = consph_nnps_create(&p->box, consph_sys_reach(job->m4), 0);
    if (!g) return CONSPH_ENOMEM;
    nnps_fix_grid(g, 2 * n);
    int rc = consph_nnps_build(g, p);
    size_t *start = NULL, *order = NULL, *cell = NULL;
    size_t ncells = 0;
    if (rc == CONSPH_OK) {
        ncells = consph_nnps_cells(g);
        start = consph_calloc(ncells + 1, sizeof(size_t));
        order = consph_calloc(n ? n : 1, sizeof(size_t));
        cell = consph_calloc(n ? n : 1, sizeof(size_t));
        if (!start || !order || !cell) rc = CONSPH_ENOMEM;
    }
    consph_nnps_slots v;
    if (rc == CONSPH_OK) rc = consph_nnps_slots_get(g, &v);
    if (rc == CONSPH_OK) {
        /* the lattice points by cell (a stable counting sort, as a build's) */
        int64_t nc[CONSPH_MAX_DIM], reach[CONSPH_MAX_DIM];
        double edge[CONSPH_MAX_DIM];
        nnps_grid(g, nc, reach, edge);
        for (size_t k = 0; k < n; ++k) {
            size_t c = 0;
            for (int a = d - 1; a >= 0; --a)
                c = c * (size_t)nc[a] + (size_t)nnps_axis_cell(g, a, lattice[(size_t)a * cap + k]);
            cell[k] = c;
            ++start[c + 1];
        }
        for (size_t c = 0; c < ncells; ++c) start[c + 1] += start[c];
        for (size_t k = 0; k < n; ++k) order[start[cell[k]]++] = k;
        for (size_t c = ncells; c > 0; --c) start[c] = start[c - 1];
        start[0] = 0;
    }
    static const remesh_point_fn points[3] = {remesh_point_1, remesh_point_2, remesh_point_3};
    const remesh_point_fn point = points[d - 1];
    int status = rc;
    const size_t chunk = pass_cells_per_chunk(ncells);
    (void)chunk; /* read by the OpenMP schedule alone */
#pragma omp parallel if (rc == CONSPH_OK && n >= s->parallel_min)
    {
        consph_nnps_runs runs;
        memset(&runs, 0, sizeof runs);
        nbhd_scratch sc;
        memset(&sc, 0, sizeof sc);
        int my_status = CONSPH_OK;
#pragma omp for schedule(dynamic, chunk)
        for (size_t c = 0; c < ncells; ++c) {
            if (my_status != CONSPH_OK || start[c] == start[c + 1]) continue;
            if (consph_nnps_cell_runs(g, c, &runs) == (size_t)-1 ||
                nbhd_scratch_reserve(&sc, runs.candidates + CONSPH_NNPS_GATHER_SLACK)) {
                my_status = CONSPH_ENOMEM;
                continue;
            }
            for (size_t e = start[c]; e < start[c + 1]; ++e) {
                const size_t k = order[e];
                double xi[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
                for (int a = 0; a < d; ++a) xi[a] = lattice[(size_t)a * cap + k];
                const size_t m = consph_nnps_gather(&v, &runs, xi, sc.slot, sc.dx, sc.r);
                const size_t *j = sc.slot;
                if (v.particle) {
                    for (size_t q = 0; q < m; ++q) sc.j[q] = v.particle[sc.slot[q]];
                    j = sc.j;
                }
                point(job, k, m, j, sc.dx);
            }
        }
#pragma omp critical(regularise_remesh)
        if (my_status != CONSPH_OK) status = my_status;
        consph_nnps_runs_free(&runs);
        nbhd_scratch_free(&sc);
    }
    free(start);
    free(order);
    free(cell);
    consph_nnps_free(g);
    if (status == CONSPH_ENOMEM && rc == CONSPH_OK)
        return consph_fail(CONSPH_ENOMEM, "remesh: out of memory for the neighbours");
    return status;
}

static int remesh_check(const consph_sys *s, const double *lattice, double ds,
                        const char *const *fields, int nf, const consph_field **f, size_t *off,
                        size_t *rows)
{
    if (!s || !s->p || !lattice || (nf > 0 && !fields) || nf < 0 || nf > CONSPH_MAX_FIELDS)
        return consph_fail(CONSPH_EINVAL, "remesh: needs a system, the lattice and 0..%d fields",
                           CONSPH_MAX_FIELDS);
    if (!(ds > 0.0) || !isfinite(ds))
        return consph_fail(CONSPH_EINVAL, "remesh: spacing ds = %g must be positive", ds);
    if (s->dest)
        return consph_fail(CONSPH_EINVAL,
                           "remesh: the system has a destination mask; remeshing moves every "
                           "particle");
    const consph_particles *p = s->p;
    *rows = 0;
    for (int k = 0; k < nf; ++k) {
        f[k] = fields[k] ? consph_particles_find(p, fields[k]) : NULL;
        if (!f[k])
            return consph_fail(CONSPH_EINVAL, "remesh: the particles have no field '%s'",
                               fields[k] ? fields[k] : "(null)");
        off[k] = *rows;
        *rows += (size_t)f[k]->ncomp;
    }
    const consph_box *b = &p->box;
    for (int a = 0; a < p->dim; ++a)
        for (size_t i = 0; i < p->n; ++i) {
            double x = lattice[(size_t)a * p->cap + i];
            if (!isfinite(x) || (b->periodic[a] && (x < b->lo[a] || x >= b->hi[a])))
                return consph_fail(CONSPH_EINVAL,
                                   "remesh: lattice point %zu has coordinate %d = %g, outside "
                                   "[%g, %g) on a periodic axis or not finite",
                                   i, a, x, b->lo[a], b->hi[a]);
        }
    return CONSPH_OK;
}

int reg_remesh_m4(consph_sys *s, const double *lattice, double ds, const char *const *fields,
                  int nf, size_t *orphans)
{
    const consph_field *f[CONSPH_MAX_FIELDS];
    size_t off[CONSPH_MAX_FIELDS], rows = 0;
    int rc = remesh_check(s, lattice, ds, fields, nf, f, off, &rows);
    if (rc) return rc;
    consph_particles *p = s->p;
    const size_t n = p->n, cap = p->cap;
    const int d = p->dim;
    consph_kernel k;
    double *out = consph_calloc(rows * n + 1, sizeof(double));
    unsigned char *orphan = consph_calloc(n + 1, 1);
    /* the rows of out in field order, component by component */
    const double **src = malloc((rows ? rows : 1) * sizeof *src);
    if (!out || !orphan || !src) rc = CONSPH_ENOMEM;
    if (!rc) rc = consph_kernel_init(&k, CONSPH_KERNEL_M4, d, ds);
    if (!rc && n) {
        for (int q = 0; q < nf; ++q)
            for (int c = 0; c < f[q]->ncomp; ++c)
                src[off[q] + (size_t)c] = f[q]->data + (size_t)c * cap;
        const remesh_job job = {&k, n, rows, src, out, orphan};
        rc = remesh_sums(s, lattice, &job);
    }
    if (!rc) {
        size_t count = 0;
        for (size_t i = 0; i < n; ++i) count += orphan[i];
        for (int q = 0; q < nf; ++q)
            for (int c = 0; c < f[q]->ncomp; ++c) {
                double *dst = f[q]->data + (size_t)c * cap;
                const double *from = out + (off[q] + (size_t)c) * n;
                for (size_t i = 0; i < n; ++i)
                    if (!orphan[i]) dst[i] = from[i];
            }
        for (int a = 0; a < d; ++a) memcpy(p->x[a], lattice + (size_t)a * cap, n * sizeof(double));
        if (orphans) *orphans = count;
        rc = consph_sys_update(s, 0);
    }
    free(src);
    free(out);
    free(orphan);
    return rc;
}

/* The shift times period_dt + m T (T = every period_dt) at or before t, counted with a slack of
 * 1e-9 T so that a step landing on one by accumulated additions counts it once. */
static double ipst_times_upto(double t, double period_dt, double T)
{
    if (t < period_dt - 1e-9 * T) return 0.0;
    return floor((t - period_dt) / T + 1e-9) + 1.0;
}

int reg_ipst_due(long step, double t_prev, double t, int every, double period_dt)
{
    if (every <= 0 || step < 1) return 0;
    if (!(period_dt > 0.0)) return (step - 1) % every == 0;
    const double T = every * period_dt;
    return ipst_times_upto(t, period_dt, T) > ipst_times_upto(t_prev, period_dt, T);
}
