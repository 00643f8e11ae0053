/* The neighbour list with a skin (consph_sys_nlist, src/pass/nlist.c): its neighbourhoods are
 * the brute-force sets after moves below and above the rebuild threshold (2D, 3D, a box
 * smaller than twice the radius); with skin 0 every pass sees what the gather gives, bit for
 * bit; and a solver run with a skin agrees with skin 0 to round-off, is the same for 1 and 2
 * threads and across a restart. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/nnps.h"
#include "consph/pass.h"
#include "consph/solver.h"
#include "solver/solver_internal.h"

/* ---- neighbourhoods against brute force ---- */

#define MAXNB 1024

typedef struct nb_record {
    size_t *count;
    size_t *j;     /* MAXNB per particle */
    double *dx[3]; /* MAXNB per particle */
} nb_record;

static void visit_record(void *job, const consph_nbhd *nb)
{
    nb_record *r = job;
    size_t m = nb->n < MAXNB ? nb->n : MAXNB;
    r->count[nb->i] = nb->n;
    for (size_t k = 0; k < m; ++k) {
        r->j[nb->i * MAXNB + k] = nb->j[k];
        for (int a = 0; a < 3; ++a) r->dx[a][nb->i * MAXNB + k] = nb->dx[a] ? nb->dx[a][k] : 0.0;
    }
}

static const consph_pass pass_record = {"record", CONSPH_PASS_W, visit_record};

typedef struct pair_key {
    size_t j;
    double d[3];
} pair_key;

static int key_cmp(const void *pa, const void *pb)
{
    const pair_key *a = pa, *b = pb;
    if (a->j != b->j) return a->j < b->j ? -1 : 1;
    for (int k = 0; k < 3; ++k)
        if (a->d[k] != b->d[k]) return a->d[k] < b->d[k] ? -1 : 1;
    return 0;
}

/* The list's neighbourhoods equal the brute-force sets (j and x_ij to round-off); returns the
 * number of pairs. */
static size_t check_brute(consph_sys *s, const char *what)
{
    const consph_particles *p = s->p;
    const size_t n = p->n;
    nb_record r;
    r.count = calloc(n, sizeof(size_t));
    r.j = malloc(n * MAXNB * sizeof(size_t));
    for (int a = 0; a < 3; ++a) r.dx[a] = malloc(n * MAXNB * sizeof(double));
    /* three times: from the second position state on, the first pass after a state that had
     * three fills the cache and the others read it (a state's passes otherwise stream) */
    for (int times = 0; times < 3; ++times)
        CHECK(consph_pass_run(s, &pass_record, &r) == CONSPH_OK, "%s: pass: %s", what,
              consph_last_error());
    consph_nbrs b = {0};
    pair_key *ka = malloc(MAXNB * sizeof *ka), *kb = malloc(MAXNB * sizeof *kb);
    size_t pairs = 0, bad = 0;
    for (size_t i = 0; i < n && bad < 5; ++i) {
        double x[3] = {0, 0, 0};
        for (int a = 0; a < p->dim; ++a) x[a] = p->x[a][i];
        size_t m = consph_nnps_brute(p, s->kernel.radius, x, &b);
        pairs += m;
        if (m != r.count[i] || m > MAXNB) {
            CHECK(0, "%s: particle %zu has %zu neighbours in the list, %zu by brute force", what, i,
                  r.count[i], m);
            ++bad;
            continue;
        }
        for (size_t k = 0; k < m; ++k) {
            ka[k].j = r.j[i * MAXNB + k];
            kb[k].j = b.j[k];
            for (int a = 0; a < 3; ++a) {
                ka[k].d[a] = r.dx[a][i * MAXNB + k];
                kb[k].d[a] = a < p->dim ? b.dx[a][k] : 0.0;
            }
        }
        qsort(ka, m, sizeof *ka, key_cmp);
        qsort(kb, m, sizeof *kb, key_cmp);
        for (size_t k = 0; k < m; ++k) {
            int same = ka[k].j == kb[k].j;
            for (int a = 0; a < 3; ++a) same = same && fabs(ka[k].d[a] - kb[k].d[a]) < 1e-12;
            if (!same) {
                CHECK(0, "%s: particle %zu, pair %zu: j %zu vs %zu, x_ij %g vs %g", what, i, k,
                      ka[k].j, kb[k].j, ka[k].d[0], kb[k].d[0]);
                ++bad;
                break;
            }
        }
    }
    consph_nbrs_free(&b);
    free(ka);
    free(kb);
    free(r.count);
    free(r.j);
    for (int a = 0; a < 3; ++a) free(r.dx[a]);
    return pairs;
}

/* Moves every particle by a random vector of length <= step (wrapped) and updates. */
static void move_all(consph_sys *s, consph_rng *rng, double step, int resort)
{
    consph_particles *p = s->p;
    for (size_t i = 0; i < p->n; ++i)
        for (int a = 0; a < p->dim; ++a) {
            double lo = p->box.lo[a], L = p->box.hi[a] - lo;
            double x = p->x[a][i] + step * (2.0 * consph_rng_uniform(rng) - 1.0) / sqrt(p->dim);
            x -= L * floor((x - lo) / L);
            if (x >= lo + L) x = lo;
            p->x[a][i] = x;
        }
    CHECK(consph_sys_update(s, resort) == CONSPH_OK, "update: %s", consph_last_error());
}

static void test_brute(int dim, size_t n, double len, double h, const char *what)
{
    consph_box box;
    memset(&box, 0, sizeof box);
    box.dim = dim;
    for (int a = 0; a < dim; ++a) {
        box.lo[a] = 0.0;
        box.hi[a] = len;
        box.periodic[a] = 1;
    }
    consph_particles src;
    CHECK(consph_particles_init(&src, dim, n, &box) == CONSPH_OK, "init");
    consph_rng rng;
    consph_rng_seed(&rng, 7 + (uint64_t)dim);
    for (size_t i = 0; i < n; ++i)
        for (int a = 0; a < dim; ++a) src.x[a][i] = len * consph_rng_uniform(&rng);
    consph_kernel k;
    CHECK(consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, dim, h) == CONSPH_OK, "kernel");
    consph_sys s;
    CHECK(consph_sys_init(&s, &src, &k, 0.0) == CONSPH_OK, "sys");
    const double skin = 0.3;
    CHECK(consph_sys_nlist(&s, skin, NULL, 0) == CONSPH_OK, "nlist: %s", consph_last_error());
    consph_nlist_info info;
    consph_sys_nlist_info(&s, &info);
    CHECK(info.on && info.builds == 1, "%s: list on (%d), %zu builds: %s", what, info.on,
          info.builds, info.note);
    CHECK(check_brute(&s, what) > n, "%s: no pairs", what);
    const double below = 0.5 * 0.2 * skin * k.radius; /* two moves: 0.2 of the threshold */
    for (int m = 0; m < 2; ++m) move_all(&s, &rng, below, m);
    consph_sys_nlist_info(&s, &info);
    CHECK(info.builds == 1, "%s: rebuilt after moves below the threshold (%zu builds)", what,
          info.builds);
    check_brute(&s, what);
    move_all(&s, &rng, 2.0 * skin * k.radius, 0); /* above: rebuilt without re-sorting */
    consph_sys_nlist_info(&s, &info);
    CHECK(info.builds == 2, "%s: %zu builds after a move above the threshold", what, info.builds);
    check_brute(&s, what);
    move_all(&s, &rng, below, 0);
    move_all(&s, &rng, 2.0 * skin * k.radius, 1); /* above, re-sorted */
    consph_sys_nlist_info(&s, &info);
    CHECK(info.builds == 3 && info.caches == 2, "%s: %zu builds, %zu caches", what, info.builds,
          info.caches);
    CHECK(info.bytes > 0.0 && info.candidates >= info.pairs, "%s: %g bytes, %g candidates", what,
          info.bytes, info.candidates);
    check_brute(&s, what);
    consph_sys_free(&s);
    consph_particles_free(&src);
}

/* ---- skin 0 is the gather, bit for bit ---- */

typedef struct moments {
    double *out; /* 6 per particle */
} moments;

static void visit_moments(void *job, const consph_nbhd *nb)
{
    moments *m = job;
    double s[6] = {0, 0, 0, 0, 0, 0};
    for (size_t k = 0; k < nb->n; ++k) {
        s[0] += nb->w[k];
        s[1] += nb->w[k] * nb->dx[0][k];
        s[2] += nb->dwr[k] * nb->dx[0][k] * nb->dx[1][k];
        s[3] += nb->d2w[k] * nb->r[k];
        s[4] += (double)nb->j[k] * nb->dx[1][k];
        s[5] += nb->dwr[k];
    }
    memcpy(m->out + 6 * nb->i, s, sizeof s);
}

static const consph_pass pass_moments = {
    "moments", CONSPH_PASS_W | CONSPH_PASS_DW | CONSPH_PASS_D2W, visit_moments};

static void visit_moments_w(void *job, const consph_nbhd *nb)
{
    moments *m = job;
    double s[6] = {0, 0, 0, 0, 0, 0};
    for (size_t k = 0; k < nb->n; ++k) {
        s[0] += nb->w[k];
        s[1] += nb->w[k] * nb->dx[0][k];
        s[2] += nb->w[k] * nb->dx[1][k];
        s[3] += nb->r[k];
        s[4] += (double)nb->j[k];
    }
    s[5] = (double)nb->n;
    memcpy(m->out + 6 * nb->i, s, sizeof s);
}

static void test_skin0_bits(void)
{
    const size_t nx = 40, n = nx * nx;
    consph_box box;
    memset(&box, 0, sizeof box);
    box.dim = 2;
    box.hi[0] = box.hi[1] = 1.0;
    box.periodic[0] = 1; /* periodic in x only */
    consph_particles src;
    CHECK(consph_particles_init(&src, 2, n, &box) == CONSPH_OK, "init");
    consph_rng rng;
    consph_rng_seed(&rng, 3);
    for (size_t i = 0; i < n; ++i) {
        src.x[0][i] = ((double)(i % nx) + 0.5 + 0.3 * consph_rng_uniform(&rng)) / (double)nx;
        src.x[1][i] = ((double)(i / nx) + 0.5 + 0.3 * consph_rng_uniform(&rng)) / (double)nx;
    }
    consph_kernel k;
    CHECK(consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 2, 1.3 / (double)nx) == CONSPH_OK, "k");
    consph_sys a, b, c;
    CHECK(consph_sys_init(&a, &src, &k, 0.0) == CONSPH_OK, "sys a");
    CHECK(consph_sys_init(&b, &src, &k, 0.0) == CONSPH_OK, "sys b");
    CHECK(consph_sys_init(&c, &src, &k, 0.0) == CONSPH_OK, "sys c");
    a.parallel_min = b.parallel_min = c.parallel_min = 1;
    CHECK(consph_sys_nlist(&b, 0.0, NULL, 0) == CONSPH_OK, "nlist b");
    CHECK(consph_sys_nlist(&c, 0.25, NULL, 0) == CONSPH_OK, "nlist c");
    moments ma = {malloc(6 * n * sizeof(double))}, mb = {malloc(6 * n * sizeof(double))};
    moments mc = {malloc(6 * n * sizeof(double))};
    consph_rng_seed(&rng, 4);
    for (int round = 0; round < 4; ++round) {
        size_t pa = 0, pb = 0;
        /* b three times: from round 1 on, the later passes read the cache the first filled */
        for (int times = 0; times < 3; ++times) {
            pb = 0;
            CHECK(consph_pass_run_counted(&b, &pass_moments, &mb, &pb) == CONSPH_OK, "pass b");
        }
        CHECK(consph_pass_run_counted(&a, &pass_moments, &ma, &pa) == CONSPH_OK, "pass a");
        CHECK(consph_pass_run(&c, &pass_moments, &mc) == CONSPH_OK, "pass c");
        CHECK(pa == pb && pa > n, "round %d: %zu pairs gathered, %zu from the list", round, pa, pb);
        CHECK(memcmp(a.p->x[0], b.p->x[0], n * sizeof(double)) == 0,
              "round %d: particle orders differ", round);
        CHECK(memcmp(ma.out, mb.out, 6 * n * sizeof(double)) == 0,
              "round %d: skin 0 differs from the gather", round);
        /* skin 0.25: another order and x_ij from displacements, round-off only (its particle
         * order differs: compare by position) */
        double worst = 0.0;
        for (size_t i = 0; i < n; ++i) {
            size_t ic = 0;
            while (ic < n && !(c.p->x[0][ic] == a.p->x[0][i] && c.p->x[1][ic] == a.p->x[1][i]))
                ++ic;
            if (ic == n) {
                worst = INFINITY;
                break;
            }
            for (int q = 0; q < 4; ++q) {
                double d = fabs(mc.out[6 * ic + q] - ma.out[6 * i + q]);
                double scale = fabs(ma.out[6 * i + 0]) + fabs(ma.out[6 * i + q]);
                if (d / scale > worst) worst = d / scale;
            }
        }
        CHECK(worst < 1e-12, "round %d: skin 0.25 differs from the gather by %g (relative)", round,
              worst);
        /* the same move on all three */
        for (size_t i = 0; i < n; ++i) {
            double d0 = 0.02 / (double)nx * (2.0 * consph_rng_uniform(&rng) - 1.0);
            double d1 = 0.02 / (double)nx * (2.0 * consph_rng_uniform(&rng) - 1.0);
            consph_sys *sys[3] = {&a, &b, &c};
            /* c holds the particles in another order: find i's */
            size_t ic = 0;
            while (ic < n && !(c.p->x[0][ic] == a.p->x[0][i] && c.p->x[1][ic] == a.p->x[1][i]))
                ++ic;
            CHECK(ic < n, "particle %zu not found in c", i);
            for (int q = 0; q < 3; ++q) {
                const size_t at = q == 2 ? ic : i;
                if (at == n) continue;
                double x = sys[q]->p->x[0][at] + d0;
                x -= floor(x);
                if (x >= 1.0) x = 0.0;
                sys[q]->p->x[0][at] = x;
                sys[q]->p->x[1][at] += d1;
            }
        }
        const int resort = round % 2;
        CHECK(consph_sys_update(&a, resort) == CONSPH_OK &&
                  consph_sys_update(&b, resort) == CONSPH_OK &&
                  consph_sys_update(&c, resort) == CONSPH_OK,
              "update");
    }
    consph_nlist_info info;
    consph_sys_nlist_info(&b, &info);
    CHECK(info.caches == 3, "skin 0: %zu caches in 3 rounds after the first", info.caches);
    free(ma.out);
    free(mb.out);
    free(mc.out);
    consph_sys_free(&a);
    consph_sys_free(&b);
    consph_sys_free(&c);
    consph_particles_free(&src);
}

/* A caller's hint (consph_sys_expect_passes) makes a two-pass state cache from its first pass,
 * also right after a state with one pass, with the values the hint names computed in one batch;
 * the neighbourhoods and values stay the gather's bit for bit. */
static void test_hint(void)
{
    const size_t nx = 30, n = nx * nx;
    consph_box box = consph_box_unit(2, 1);
    consph_particles src;
    CHECK(consph_particles_init(&src, 2, n, &box) == CONSPH_OK, "init");
    consph_rng rng;
    consph_rng_seed(&rng, 7);
    for (size_t i = 0; i < n; ++i) {
        src.x[0][i] = ((double)(i % nx) + 0.5 + 0.3 * consph_rng_uniform(&rng)) / (double)nx;
        src.x[1][i] = ((double)(i / nx) + 0.5 + 0.3 * consph_rng_uniform(&rng)) / (double)nx;
    }
    consph_kernel k;
    CHECK(consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 2, 1.2 / (double)nx) == CONSPH_OK, "k");
    consph_sys a, b;
    CHECK(consph_sys_init(&a, &src, &k, 0.0) == CONSPH_OK, "sys a");
    CHECK(consph_sys_init(&b, &src, &k, 0.0) == CONSPH_OK, "sys b");
    CHECK(consph_sys_nlist(&b, 0.0, NULL, 0) == CONSPH_OK, "nlist b");
    /* W alone first, so the second pass's W'/r and W'' come from the hint's batch */
    const consph_pass pass_w = {"w", CONSPH_PASS_W, visit_moments_w};
    moments ma = {malloc(6 * n * sizeof(double))}, mb = {malloc(6 * n * sizeof(double))};
    moments wa = {malloc(6 * n * sizeof(double))}, wb = {malloc(6 * n * sizeof(double))};
    size_t before = 0;
    for (int round = 0; round < 3; ++round) {
        consph_nlist_info info;
        consph_sys_nlist_info(&b, &info);
        before = info.caches;
        consph_sys_expect_passes(&b, 2, CONSPH_PASS_W | CONSPH_PASS_DW | CONSPH_PASS_D2W);
        CHECK(consph_pass_run(&b, &pass_w, &wb) == CONSPH_OK, "pass w b");
        CHECK(consph_pass_run(&b, &pass_moments, &mb) == CONSPH_OK, "pass b");
        CHECK(consph_pass_run(&a, &pass_w, &wa) == CONSPH_OK, "pass w a");
        CHECK(consph_pass_run(&a, &pass_moments, &ma) == CONSPH_OK, "pass a");
        consph_sys_nlist_info(&b, &info);
        CHECK(info.caches == before + 1, "round %d: the hinted state made %zu caches", round,
              info.caches - before);
        CHECK(memcmp(ma.out, mb.out, 6 * n * sizeof(double)) == 0 &&
                  memcmp(wa.out, wb.out, 6 * n * sizeof(double)) == 0,
              "round %d: the hinted cache differs from the gather", round);
        /* a state with one pass between: without the hint the next would gather */
        for (size_t i = 0; i < n; ++i) {
            const double d = 0.05 / (double)nx * (2.0 * consph_rng_uniform(&rng) - 1.0);
            double x = a.p->x[0][i] + d;
            x -= floor(x);
            a.p->x[0][i] = b.p->x[0][i] = x >= 1.0 ? 0.0 : x;
        }
        CHECK(consph_sys_update(&a, 0) == CONSPH_OK && consph_sys_update(&b, 0) == CONSPH_OK,
              "update");
        CHECK(consph_pass_run(&b, &pass_w, &wb) == CONSPH_OK, "pass w b");
        for (size_t i = 0; i < n; ++i) {
            double x = a.p->x[1][i] + 0.01 / (double)nx;
            x -= floor(x);
            a.p->x[1][i] = b.p->x[1][i] = x >= 1.0 ? 0.0 : x;
        }
        CHECK(consph_sys_update(&a, 1) == CONSPH_OK && consph_sys_update(&b, 1) == CONSPH_OK,
              "update");
    }
    /* no list: the hint does nothing */
    consph_sys_expect_passes(&a, 2, CONSPH_PASS_W);
    CHECK(consph_pass_run(&a, &pass_w, &wa) == CONSPH_OK, "pass a after a hint");
    free(ma.out);
    free(mb.out);
    free(wa.out);
    free(wb.out);
    consph_sys_free(&a);
    consph_sys_free(&b);
    consph_particles_free(&src);
}

/* ---- the solver ---- */

static consph_solver *make(const char *scheme, double skin, int nx)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = nx;
    p.skin = skin;
    p.steps = 20;
    p.tf = 0.0;
    p.ipst_every = 7;
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create %s: %s", scheme, consph_last_error());
    return s;
}

static int run_steps(consph_solver *s, long k)
{
    for (long i = 0; i < k; ++i) {
        int st = consph_solver_step(s);
        if (st != CONSPH_OK) return st;
    }
    return CONSPH_OK;
}

/* Largest relative difference of the velocities, particle by particle through their ids. */
static double velocity_gap(const consph_particles *a, const consph_particles *b)
{
    const consph_field *ia = consph_particles_find(a, SF_ID), *ib = consph_particles_find(b, SF_ID);
    const consph_field *ua = consph_particles_find(a, SF_U), *ub = consph_particles_find(b, SF_U);
    if (!ia || !ib || !ua || !ub || a->n != b->n) return INFINITY;
    size_t *at = malloc(a->n * sizeof(size_t));
    for (size_t i = 0; i < b->n; ++i) at[(size_t)ib->data[i]] = i;
    double worst = 0.0, umax = 0.0;
    for (size_t i = 0; i < a->n; ++i) {
        const size_t k = at[(size_t)ia->data[i]];
        for (int c = 0; c < a->dim; ++c) {
            const double va = ua->data[(size_t)c * a->cap + i],
                         vb = ub->data[(size_t)c * b->cap + k];
            worst = fmax(worst, fabs(va - vb));
            umax = fmax(umax, fabs(va));
        }
    }
    free(at);
    return worst / umax;
}

static int same_positions(const consph_particles *a, const consph_particles *b)
{
    if (a->n != b->n) return 0;
    for (int d = 0; d < a->dim; ++d)
        if (memcmp(a->x[d], b->x[d], a->n * sizeof(double))) return 0;
    const consph_field *ua = consph_particles_find(a, SF_U), *ub = consph_particles_find(b, SF_U);
    for (int c = 0; c < a->dim; ++c)
        if (memcmp(ua->data + (size_t)c * a->cap, ub->data + (size_t)c * b->cap,
                   a->n * sizeof(double)))
            return 0;
    return 1;
}

static void test_solver(const char *scheme)
{
    /* a small skin, so that the list is rebuilt several times in 20 steps */
    const double skin = 0.02;
    consph_solver *z = make(scheme, 0.0, 16), *s1 = make(scheme, skin, 16);
    if (!z || !s1) return;
    CHECK(run_steps(z, 20) == CONSPH_OK && run_steps(s1, 9) == CONSPH_OK, "%s: steps: %s", scheme,
          consph_last_error());
    /* a restart from the state after 9 steps */
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    consph_solver *r = NULL;
    int st = consph_solver_checkpoint_meta(s1, &meta, &hist, &nh);
    if (st == CONSPH_OK)
        st = consph_solver_restore(&r, meta, consph_solver_particles(s1), hist, nh);
    CHECK(st == CONSPH_OK, "%s: restore: %s", scheme, consph_last_error());
    free(meta);
    free(hist);
    CHECK(run_steps(s1, 11) == CONSPH_OK, "%s: steps: %s", scheme, consph_last_error());
    consph_nlist_info info;
    consph_sys_nlist_info(&s1->sys, &info);
    CHECK(info.on && info.builds >= 2, "%s: %zu list builds in 20 steps (on %d: %s)", scheme,
          info.builds, info.on, info.note);
    const double gap = velocity_gap(consph_solver_particles(z), consph_solver_particles(s1));
    CHECK(gap < 1e-10, "%s: skin %g and skin 0 differ by %g (relative) after 20 steps", scheme,
          skin, gap);
    if (r) {
        CHECK(run_steps(r, 11) == CONSPH_OK, "%s: restored steps: %s", scheme, consph_last_error());
        CHECK(same_positions(consph_solver_particles(s1), consph_solver_particles(r)),
              "%s: the restored run differs", scheme);
        consph_solver_free(r);
    }
    /* two threads */
    check_set_threads(2);
    consph_solver *s2 = make(scheme, skin, 16);
    if (s2) {
        s2->sys.parallel_min = 1;
        CHECK(run_steps(s2, 20) == CONSPH_OK, "%s: 2 threads: %s", scheme, consph_last_error());
        CHECK(same_positions(consph_solver_particles(s1), consph_solver_particles(s2)),
              "%s: 1 and 2 threads differ", scheme);
        consph_solver_free(s2);
    }
    check_set_threads(1);
    consph_solver_free(z);
    consph_solver_free(s1);
}

int main(void)
{
    check_set_threads(1);
    test_brute(2, 900, 1.0, 0.04, "2D");
    test_brute(3, 1000, 1.0, 0.07, "3D");
    /* radius 0.3 in a box of 0.5: every pair is seen through several images */
    test_brute(2, 60, 0.5, 0.1, "2D, box < 2 radius");
    test_brute(3, 40, 0.5, 0.1, "3D, box < 2 radius");
    test_skin0_bits();
    test_hint();
    const char *schemes[] = {"wcsph", "edac", "tvf", "l-ipst-c", "delta-plus-sph", "tv-c"};
    for (size_t k = 0; k < sizeof schemes / sizeof schemes[0]; ++k) test_solver(schemes[k]);
    return check_summary("test_nlist");
}
