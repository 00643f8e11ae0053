/* The pass layer (consph/pass.h) against sums written out over the O(N^2) reference search:
 *  - a pass's W, ∇W and W'' sums and neighbour counts equal brute-force sums on perturbed
 *    lattices in 1D/2D/3D, periodic and not;
 *  - with a destination mask only masked particles are visited (once) and written, the others
 *    still appear as neighbours, and the pair count is the sum over the visited neighbourhoods;
 *  - results are bit-identical at 1 and 2 threads;
 *  - after the particles move, consph_sys_update keeps origin[], the mask and the named fields
 *    together, and passes see the new neighbourhoods;
 *  - a tensor-product kernel (M4) sums W over its whole square support, and a pass asking for its
 *    derivatives is refused with a message;
 *  - consph_sys_scratch hands out a buffer of the size asked for, grown on demand, with its
 *    contents kept while no larger one is asked for, and freed with the system;
 *  - bad arguments are refused. */
#include "check.h"
#include "consph/layout.h"
#include "consph/pass.h"

#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

/* Sums of the same terms in another order agree to round-off. */
#define SUM_TOL 1e-11

typedef struct sums {
    size_t n;
    int dim;
    const double *f; /* per particle, in system order */
    double *w;       /* Σ f_j W_ij */
    double *grad;    /* Σ f_j ∇W_ij, dim per particle */
    double *d2w;     /* Σ W''(r_ij) */
    size_t *count;   /* neighbours, i included */
    int *visits;
    size_t *masked_nbrs; /* neighbours outside the mask */
    const unsigned char *dest;
} sums;

static void visit_sums(void *job, const consph_nbhd *nb)
{
    sums *s = job;
    const size_t i = nb->i;
    double w = 0.0, g[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0}, d2 = 0.0;
    size_t outside = 0;
    for (size_t k = 0; k < nb->n; ++k) {
        const double fj = s->f[nb->j[k]];
        w += fj * nb->w[k];
        for (int a = 0; a < s->dim; ++a) g[a] += fj * nb->dwr[k] * nb->dx[a][k];
        d2 += nb->d2w[k];
        if (s->dest && !s->dest[nb->j[k]]) ++outside;
    }
    s->w[i] = w;
    for (int a = 0; a < s->dim; ++a) s->grad[(size_t)a * s->n + i] = g[a];
    s->d2w[i] = d2;
    s->count[i] = nb->n;
    s->masked_nbrs[i] = outside;
    ++s->visits[i];
}

static const consph_pass pass_sums = {"sums", CONSPH_PASS_W | CONSPH_PASS_D2W, visit_sums};

/* Never-written entries keep this value. */
#define UNTOUCHED -12345.0

static int sums_alloc(sums *s, size_t n, int dim, const double *f, const unsigned char *dest)
{
    memset(s, 0, sizeof *s);
    s->n = n;
    s->dim = dim;
    s->f = f;
    s->dest = dest;
    s->w = malloc(n * sizeof(double));
    s->grad = malloc((size_t)dim * n * sizeof(double));
    s->d2w = malloc(n * sizeof(double));
    s->count = calloc(n, sizeof(size_t));
    s->visits = calloc(n, sizeof(int));
    s->masked_nbrs = calloc(n, sizeof(size_t));
    if (!s->w || !s->grad || !s->d2w || !s->count || !s->visits || !s->masked_nbrs) return 0;
    for (size_t i = 0; i < n; ++i) s->w[i] = s->d2w[i] = UNTOUCHED;
    for (size_t i = 0; i < (size_t)dim * n; ++i) s->grad[i] = UNTOUCHED;
    return 1;
}

static void sums_free(sums *s)
{
    free(s->w);
    free(s->grad);
    free(s->d2w);
    free(s->count);
    free(s->visits);
    free(s->masked_nbrs);
    memset(s, 0, sizeof *s);
}

/* A lattice perturbed by up to 0.4 Δs, with a field "f" holding a smooth function and a field
 * "tag" holding each particle's index in the generated set. */
static int make_particles(consph_particles *p, int dim, size_t nx, int periodic, uint64_t seed)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, dim, nx);
    lp.box = consph_box_unit(dim, periodic);
    lp.eps = 0.4;
    lp.seed = seed;
    if (consph_layout_generate(&lp, p, NULL) != CONSPH_OK) return 0;
    double *f = consph_particles_field(p, "f", 1);
    double *tag = consph_particles_field(p, "tag", 1);
    if (!f || !tag) return 0;
    for (size_t i = 0; i < p->n; ++i) {
        double v = 1.0;
        for (int a = 0; a < dim; ++a) v += sin(2.0 * M_PI * p->x[a][i] + a);
        f[i] = v;
        tag[i] = (double)i;
    }
    return 1;
}

/* A system over make_particles' particles (left in *src) with kernel `id` at h = hdx Δs. */
static int make_sys(consph_sys *s, consph_particles *src, int dim, size_t nx, int periodic,
                    uint64_t seed, consph_kernel_id id, double hdx)
{
    consph_kernel k;
    if (!make_particles(src, dim, nx, periodic, seed) ||
        consph_kernel_init(&k, id, dim, hdx * src->spacing) != CONSPH_OK)
        return 0;
    return consph_sys_init(s, src, &k, 0.0) == CONSPH_OK;
}

static const double *field_of(const consph_particles *p, const char *name)
{
    const consph_field *fl = consph_particles_find(p, name);
    return fl ? fl->data : NULL;
}

/* The pass's sums at every visited particle against the brute-force search; returns the number
 * of pairs the reference found over the visited particles. */
static size_t check_against_brute(const consph_sys *s, const sums *got, const char *what)
{
    const consph_particles *p = s->p;
    const int dim = p->dim;
    const double *f = field_of(p, "f");
    consph_nbrs nb;
    memset(&nb, 0, sizeof nb);
    size_t bad = 0, pairs = 0;
    for (size_t i = 0; i < p->n; ++i) {
        if (s->dest && !s->dest[i]) continue;
        double x[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
        for (int a = 0; a < dim; ++a) x[a] = p->x[a][i];
        size_t m = consph_nnps_brute(p, s->kernel.radius, x, &nb);
        pairs += m;
        double w = 0.0, g[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0}, d2 = 0.0, scale = 0.0, d2scale = 0.0;
        for (size_t k = 0; k < m; ++k) {
            const double fj = f[nb.j[k]], r = nb.r[k];
            w += fj * consph_kernel_w(&s->kernel, r);
            scale += fabs(fj * consph_kernel_w(&s->kernel, r));
            if (r > 0.0)
                for (int a = 0; a < dim; ++a)
                    g[a] += fj * consph_kernel_dw(&s->kernel, r) / r * nb.dx[a][k];
            d2 += consph_kernel_d2w(&s->kernel, r);
            d2scale += fabs(consph_kernel_d2w(&s->kernel, r));
        }
        double gscale = 0.0;
        for (int a = 0; a < dim; ++a) gscale += fabs(g[a]);
        int ok = m == got->count[i] && fabs(w - got->w[i]) <= SUM_TOL * scale &&
                 fabs(d2 - got->d2w[i]) <= SUM_TOL * d2scale;
        for (int a = 0; a < dim; ++a)
            ok &= fabs(g[a] - got->grad[(size_t)a * p->n + i]) <=
                  SUM_TOL * (gscale + scale / s->kernel.h);
        if (!ok && bad++ == 0)
            fprintf(stderr, "%s: particle %zu: %zu vs %zu neighbours, W sum %.17g vs %.17g\n", what,
                    i, got->count[i], m, got->w[i], w);
    }
    consph_nbrs_free(&nb);
    CHECK(bad == 0, "%s: %zu particles differ from the brute-force sums", what, bad);
    return pairs;
}

static void test_brute(void)
{
    for (int dim = 1; dim <= 3; ++dim)
        for (int periodic = 0; periodic <= 1; ++periodic) {
            const size_t nx = dim == 1 ? 200 : dim == 2 ? 24 : 9;
            char what[64];
            snprintf(what, sizeof what, "%dD %s", dim, periodic ? "periodic" : "bounded");
            consph_particles src;
            consph_sys s;
            CHECK(make_sys(&s, &src, dim, nx, periodic, 7u + (unsigned)dim, CONSPH_KERNEL_QUINTIC,
                           1.2),
                  "%s: system: %s", what, consph_last_error());
            const size_t n = s.p->n;
            CHECK(n == src.n, "%s: %zu particles of %zu", what, n, src.n);
            /* origin[] is a permutation that maps every copied particle back to its source. */
            const double *tag = field_of(s.p, "tag");
            unsigned char *seen = calloc(n, 1);
            size_t bad_origin = 0;
            for (size_t i = 0; i < n; ++i) {
                size_t o = s.origin[i];
                int ok = o < n && !seen[o] && tag[i] == (double)o;
                for (int a = 0; ok && a < dim; ++a) ok = s.p->x[a][i] == src.x[a][o];
                if (o < n) seen[o] = 1;
                bad_origin += !ok;
            }
            free(seen);
            CHECK(bad_origin == 0, "%s: %zu particles do not match their origin", what, bad_origin);

            sums got;
            CHECK(sums_alloc(&got, n, dim, field_of(s.p, "f"), NULL), "alloc");
            size_t pairs = 0;
            CHECK(consph_pass_run_counted(&s, &pass_sums, &got, &pairs) == CONSPH_OK, "%s: run: %s",
                  what, consph_last_error());
            size_t visited_once = 0;
            for (size_t i = 0; i < n; ++i) visited_once += got.visits[i] == 1;
            CHECK(visited_once == n, "%s: %zu of %zu particles visited once", what, visited_once,
                  n);
            size_t ref_pairs = check_against_brute(&s, &got, what);
            CHECK(pairs == ref_pairs && pairs > 5 * n, "%s: %zu pairs, reference %zu", what, pairs,
                  ref_pairs);
            sums_free(&got);
            consph_sys_free(&s);
            consph_particles_free(&src);
        }
}

/* Sets the mask to every third particle (by source index): the rest are sources only. Returns a
 * copy of the mask (NULL when it could not be set). */
static unsigned char *mask_every_third(consph_sys *s)
{
    unsigned char *dest = malloc(s->p->n);
    for (size_t i = 0; dest && i < s->p->n; ++i) dest[i] = s->origin[i] % 3 == 0;
    if (dest && consph_sys_set_dest(s, dest) != CONSPH_OK) {
        free(dest);
        dest = NULL;
    }
    return dest;
}

static void test_mask(void)
{
    consph_particles src;
    consph_sys s;
    CHECK(make_sys(&s, &src, 2, 30, 0, 11u, CONSPH_KERNEL_WENDLAND_C4, 1.3), "system: %s",
          consph_last_error());
    const size_t n = s.p->n;
    unsigned char *dest = mask_every_third(&s);
    CHECK(dest != NULL, "set_dest: %s", consph_last_error());
    dest[0] ^= 1; /* the system keeps its own copy */
    CHECK(s.dest != dest && s.dest[0] != dest[0], "the mask is copied");
    dest[0] ^= 1;
    sums got;
    CHECK(sums_alloc(&got, n, 2, field_of(s.p, "f"), s.dest), "alloc");
    size_t pairs = 0;
    CHECK(consph_pass_run_counted(&s, &pass_sums, &got, &pairs) == CONSPH_OK, "run: %s",
          consph_last_error());
    size_t wrong_visits = 0, written_outside = 0, visited_pairs = 0, outside_nbrs = 0, ndest = 0;
    for (size_t i = 0; i < n; ++i) {
        wrong_visits += got.visits[i] != (dest[i] ? 1 : 0);
        if (dest[i]) {
            visited_pairs += got.count[i];
            outside_nbrs += got.masked_nbrs[i];
            ++ndest;
        } else {
            written_outside += got.w[i] != UNTOUCHED || got.d2w[i] != UNTOUCHED ||
                               got.grad[i] != UNTOUCHED || got.grad[n + i] != UNTOUCHED;
        }
    }
    CHECK(ndest > 0 && ndest < n, "a proper mask: %zu of %zu", ndest, n);
    CHECK(wrong_visits == 0, "%zu particles visited against the mask", wrong_visits);
    CHECK(written_outside == 0, "%zu particles outside the mask written", written_outside);
    CHECK(pairs == visited_pairs, "pair count %zu, Σ over visited %zu", pairs, visited_pairs);
    /* Two thirds of every neighbourhood lie outside the mask: sources are still neighbours. */
    CHECK(outside_nbrs > visited_pairs / 2, "%zu of %zu neighbours outside the mask", outside_nbrs,
          visited_pairs);
    CHECK(check_against_brute(&s, &got, "masked") == pairs, "masked pairs");
    sums_free(&got);

    /* Clearing the mask visits everyone again. */
    CHECK(consph_sys_set_dest(&s, NULL) == CONSPH_OK && s.dest == NULL, "mask cleared");
    CHECK(sums_alloc(&got, n, 2, field_of(s.p, "f"), NULL), "alloc");
    CHECK(consph_pass_run(&s, &pass_sums, &got) == CONSPH_OK, "run unmasked");
    size_t visited = 0;
    for (size_t i = 0; i < n; ++i) visited += got.visits[i] == 1;
    CHECK(visited == n, "%zu of %zu visited after clearing the mask", visited, n);
    sums_free(&got);
    free(dest);
    consph_sys_free(&s);
    consph_particles_free(&src);
}

/* The sums of one run, at a given thread count. */
static int run_threads(const consph_sys *s, int threads, sums *got)
{
#ifdef _OPENMP
    omp_set_num_threads(threads);
#else
    (void)threads;
#endif
    if (!sums_alloc(got, s->p->n, s->p->dim, field_of(s->p, "f"), s->dest)) return 0;
    return consph_pass_run(s, &pass_sums, got) == CONSPH_OK;
}

static void test_threads(void)
{
    for (int dim = 2; dim <= 3; ++dim) {
        consph_particles src;
        consph_sys s;
        CHECK(make_sys(&s, &src, dim, dim == 2 ? 60 : 16, 1, 3u, CONSPH_KERNEL_QUINTIC, 1.2),
              "system: %s", consph_last_error());
        s.parallel_min = 0;
        for (int masked = 0; masked <= 1; ++masked) {
            if (masked) free(mask_every_third(&s));
            sums one, two;
            CHECK(run_threads(&s, 1, &one) && run_threads(&s, 2, &two), "runs: %s",
                  consph_last_error());
            const size_t n = s.p->n;
            int same = !memcmp(one.w, two.w, n * sizeof(double)) &&
                       !memcmp(one.grad, two.grad, (size_t)dim * n * sizeof(double)) &&
                       !memcmp(one.d2w, two.d2w, n * sizeof(double)) &&
                       !memcmp(one.count, two.count, n * sizeof(size_t));
            CHECK(same, "%dD%s: results differ between 1 and 2 threads", dim,
                  masked ? " masked" : "");
            sums_free(&one);
            sums_free(&two);
        }
        consph_sys_free(&s);
        consph_particles_free(&src);
    }
#ifdef _OPENMP
    omp_set_num_threads(1);
#endif
}

static void test_update(void)
{
    consph_particles src;
    consph_sys s;
    CHECK(make_sys(&s, &src, 2, 30, 1, 5u, CONSPH_KERNEL_QUINTIC, 1.2), "system: %s",
          consph_last_error());
    const size_t n = s.p->n;
    free(mask_every_third(&s));
    /* Move every particle by a few spacings along a shear (wrapped into the periodic box), so
     * most change cell; remember where each source particle went. */
    double *moved[2] = {malloc(n * sizeof(double)), malloc(n * sizeof(double))};
    for (size_t i = 0; i < n; ++i) {
        double x = s.p->x[0][i], y = s.p->x[1][i];
        double nxp = x + 0.3 * sin(2.0 * M_PI * y), nyp = y + 0.2;
        nxp -= floor(nxp);
        nyp -= floor(nyp);
        s.p->x[0][i] = moved[0][s.origin[i]] = nxp;
        s.p->x[1][i] = moved[1][s.origin[i]] = nyp;
    }
    CHECK(consph_sys_update(&s, 1) == CONSPH_OK, "update: %s", consph_last_error());
    const double *tag = field_of(s.p, "tag");
    size_t bad = 0, resorted = 0;
    for (size_t i = 0; i < n; ++i) {
        size_t o = s.origin[i];
        bad += !(o < n && tag[i] == (double)o && s.p->x[0][i] == moved[0][o] &&
                 s.p->x[1][i] == moved[1][o] && (s.dest[i] != 0) == (o % 3 == 0));
        resorted += tag[i] != (double)i;
    }
    CHECK(bad == 0, "%zu particles whose origin, tag, position or mask disagree", bad);
    CHECK(resorted > n / 2, "the particles were re-sorted (%zu moved)", resorted);
    /* The mask holds as before: the pass visits exactly the masked particles, at their new
     * neighbourhoods. */
    sums got;
    CHECK(sums_alloc(&got, n, 2, field_of(s.p, "f"), s.dest), "alloc");
    size_t pairs = 0;
    CHECK(consph_pass_run_counted(&s, &pass_sums, &got, &pairs) == CONSPH_OK, "run after update");
    size_t wrong = 0;
    for (size_t i = 0; i < n; ++i) wrong += got.visits[i] != (s.dest[i] ? 1 : 0);
    CHECK(wrong == 0, "%zu particles visited against the mask after update", wrong);
    CHECK(check_against_brute(&s, &got, "after update") == pairs, "pairs after update");
    sums_free(&got);

    /* Without re-sorting, only the search is rebuilt: nothing is permuted. */
    for (size_t i = 0; i < n; ++i) s.p->x[1][i] = fmod(s.p->x[1][i] + 0.05, 1.0);
    size_t *before = malloc(n * sizeof(size_t));
    memcpy(before, s.origin, n * sizeof(size_t));
    CHECK(consph_sys_update(&s, 0) == CONSPH_OK, "rebuild");
    CHECK(!memcmp(before, s.origin, n * sizeof(size_t)), "update without resort keeps the order");
    CHECK(sums_alloc(&got, n, 2, field_of(s.p, "f"), s.dest), "alloc");
    CHECK(consph_pass_run_counted(&s, &pass_sums, &got, &pairs) == CONSPH_OK, "run after rebuild");
    check_against_brute(&s, &got, "after rebuild");
    sums_free(&got);
    free(before);
    free(moved[0]);
    free(moved[1]);
    consph_sys_free(&s);
    consph_particles_free(&src);
}

typedef struct wsum {
    double *w;
} wsum;

static void visit_w(void *job, const consph_nbhd *nb)
{
    double w = 0.0;
    for (size_t k = 0; k < nb->n; ++k) w += nb->w[k];
    ((wsum *)job)->w[nb->i] = w;
}

static void visit_nothing(void *job, const consph_nbhd *nb)
{
    (void)job;
    (void)nb;
}

/* The tensor-product M4 is not radial: its support is the square |x_a| < 2h, whose corners lie
 * beyond the radius 2h. Its W sum must reach them. */
static void test_tensor(void)
{
    for (int dim = 2; dim <= 3; ++dim) {
        consph_particles src;
        consph_sys s;
        CHECK(make_sys(&s, &src, dim, dim == 2 ? 20 : 8, 1, 9u, CONSPH_KERNEL_M4, 1.0),
              "system: %s", consph_last_error());
        const consph_kernel k = s.kernel;
        const size_t n = s.p->n;
        wsum got = {calloc(n, sizeof(double))};
        const consph_pass pw = {"m4 density", CONSPH_PASS_W, visit_w};
        CHECK(consph_pass_run(&s, &pw, &got) == CONSPH_OK, "W pass: %s", consph_last_error());
        /* Brute force over every pair (and periodic image, the box being wider than 4h). */
        size_t bad = 0;
        double worst = 0.0;
        for (size_t i = 0; i < n; ++i) {
            double w = 0.0;
            for (size_t j = 0; j < n; ++j) {
                double d[CONSPH_MAX_DIM] = {0.0, 0.0, 0.0};
                for (int a = 0; a < dim; ++a) {
                    d[a] = s.p->x[a][i] - s.p->x[a][j];
                    d[a] -= round(d[a]); /* unit periodic box: nearest image */
                }
                w += consph_kernel_w_vec(&k, d);
            }
            double e = fabs(w - got.w[i]) / w;
            if (e > worst) worst = e;
            bad += !(e <= 1e-12);
        }
        CHECK(bad == 0, "%dD M4: %zu particles miss part of the W sum (worst relative %.3g)", dim,
              bad, worst);
        free(got.w);
        const consph_pass pd = {"m4 gradient", CONSPH_PASS_W | CONSPH_PASS_DW, visit_nothing};
        consph_clear_error();
        CHECK(consph_pass_run(&s, &pd, NULL) == CONSPH_EINVAL, "a DW pass on M4 refused");
        CHECK(strstr(consph_last_error(), "m4 gradient") && strstr(consph_last_error(), "tensor"),
              "the message names the pass and the reason: '%s'", consph_last_error());
        const consph_pass p2 = {"m4 hessian", CONSPH_PASS_D2W, visit_nothing};
        CHECK(consph_pass_run(&s, &p2, NULL) == CONSPH_EINVAL, "a D2W pass on M4 refused");
        consph_sys_free(&s);
        consph_particles_free(&src);
    }
}

static void test_bad_arguments(void)
{
    consph_particles src;
    CHECK(make_particles(&src, 2, 10, 0, 1u), "particles");
    consph_kernel k2, k3;
    consph_kernel_init(&k2, CONSPH_KERNEL_CUBIC, 2, 1.2 * src.spacing);
    consph_kernel_init(&k3, CONSPH_KERNEL_CUBIC, 3, 1.2 * src.spacing);
    consph_sys s;
    CHECK(consph_sys_init(&s, &src, &k3, 0.0) == CONSPH_EINVAL, "3D kernel on 2D particles");
    CHECK(strstr(consph_last_error(), "3D") != NULL, "message: '%s'", consph_last_error());
    CHECK(s.p == NULL && s.nnps == NULL, "nothing left after a failed init");
    CHECK(consph_sys_init(&s, NULL, &k2, 0.0) == CONSPH_EINVAL, "no particles");
    CHECK(consph_sys_init(&s, &src, NULL, 0.0) == CONSPH_EINVAL, "no kernel");

    consph_nnps *small = consph_nnps_create(&src.box, 0.5 * k2.radius, 0);
    consph_nnps_build(small, &src);
    CHECK(consph_sys_wrap(&s, &src, small, &k2) == CONSPH_EINVAL, "search radius below support");
    CHECK(strstr(consph_last_error(), "radius") != NULL, "message: '%s'", consph_last_error());
    consph_nnps_free(small);

    consph_nnps *g = consph_nnps_create(&src.box, k2.radius, 0);
    consph_nnps_build(g, &src);
    CHECK(consph_sys_wrap(&s, &src, g, &k2) == CONSPH_OK, "wrap: %s", consph_last_error());
    CHECK(s.origin == NULL && !s.owned, "a wrapped system owns nothing");
    wsum got = {calloc(src.n, sizeof(double))};
    const consph_pass pw = {"w", CONSPH_PASS_W, visit_w};
    CHECK(consph_pass_run(&s, &pw, &got) == CONSPH_OK, "pass on a wrapped system");
    const consph_pass novisit = {"novisit", CONSPH_PASS_W, NULL};
    CHECK(consph_pass_run(&s, &novisit, NULL) == CONSPH_EINVAL, "a pass without a visit");
    CHECK(consph_pass_run(NULL, &pw, &got) == CONSPH_EINVAL, "no system");
    CHECK(consph_pass_run(&s, NULL, &got) == CONSPH_EINVAL, "no pass");
    /* Particles added after the search was built: the search no longer matches. */
    consph_particles more;
    CHECK(make_particles(&more, 2, 11, 0, 2u), "particles");
    consph_sys stale;
    CHECK(consph_sys_wrap(&stale, &more, g, &k2) == CONSPH_OK, "wrap");
    CHECK(consph_pass_run(&stale, &pw, &got) == CONSPH_EINVAL, "a stale search refused");
    CHECK(strstr(consph_last_error(), "update the system") != NULL, "message: '%s'",
          consph_last_error());
    consph_sys_free(&stale);
    consph_sys_free(&s);
    CHECK(src.x[0] != NULL, "freeing a wrapped system leaves the caller's particles");
    CHECK(consph_sys_update(NULL, 1) == CONSPH_EINVAL, "update of no system");
    CHECK(consph_sys_set_dest(NULL, NULL) == CONSPH_EINVAL, "mask of no system");
    consph_sys_free(NULL);
    free(got.w);
    consph_nnps_free(g);
    consph_particles_free(&more);
    consph_particles_free(&src);
}

static void test_scratch(void)
{
    consph_particles src;
    consph_sys s;
    const int ok = make_sys(&s, &src, 2, 8, 1, 3, CONSPH_KERNEL_QUINTIC, 1.2);
    CHECK(ok, "system for the scratch");
    if (!ok) return;
    double *a = consph_sys_scratch(&s, 10);
    CHECK(a != NULL, "scratch of 10 values");
    if (!a) return;
    for (int k = 0; k < 10; ++k) a[k] = k + 0.5;
    CHECK(consph_sys_scratch(&s, 4) == a, "a smaller request reuses the buffer");
    double *b = consph_sys_scratch(&s, 100000);
    CHECK(b != NULL, "scratch grown to 100000 values");
    if (!b) return;
    int kept = 1;
    for (int k = 0; k < 10; ++k) kept &= b[k] == k + 0.5;
    CHECK(kept, "growing keeps the values written");
    b[99999] = 1.0; /* the whole size is writable (the sanitizer build checks) */
    consph_sys_free(&s);
    CHECK(s.scratch == NULL && s.scratch_cap == 0, "consph_sys_free releases the scratch");
    consph_particles_free(&src);
}

/* Re-sorting moves every array of the particles through one permutation; above a few thousand
 * particles the arrays are shared out among the threads. Each must come out as a[perm[i]] for
 * 1 and 2 threads alike: for a scattering bijection, and for a re-sort's kind of permutation,
 * blocks of slots shifted by one (copied whole), short and long, one across the threads' halves,
 * one reversed, between fixed slots. */
static void test_permute_with(const size_t *perm, size_t n, const consph_box *box, int kind);

static void test_permute_threads(void)
{
    const size_t n = 6000;
    const consph_box box = consph_box_unit(2, 1);
    size_t *perm = malloc(n * sizeof *perm);
    for (int kind = 0; kind < 2; ++kind) {
        if (kind == 0)
            for (size_t i = 0; i < n; ++i)
                perm[i] = (i * 2654435761u + 17) % n; /* a bijection: 2654435761 is prime to n */
        else {
            for (size_t i = 0; i < n; ++i) perm[i] = i;
            static const size_t blocks[][2] = {{10, 13}, {20, 29}, {40, 140}, {2500, 3500}};
            for (int b = 0; b < 4; ++b) { /* [lo, hi) rotated: each slot takes its successor's */
                const size_t lo = blocks[b][0], hi = blocks[b][1];
                for (size_t i = lo; i + 1 < hi; ++i) perm[i] = i + 1;
                perm[hi - 1] = lo;
            }
            for (size_t i = 0; i < 30; ++i) perm[5000 + i] = 5029 - i;
            /* blocks moved by 7: slots [4000, 4100) take [4007, 4107), [4100, 4107) the rest */
            for (size_t i = 4000; i < 4100; ++i) perm[i] = i + 7;
            for (size_t i = 4100; i < 4107; ++i) perm[i] = i - 100;
        }
        test_permute_with(perm, n, &box, kind);
    }
    free(perm);
}

static void test_permute_with(const size_t *perm, size_t n, const consph_box *box, int kind)
{
    int ok = 1;
    for (int t = 1; t <= 2; ++t) {
        consph_particles p = {0};
        CHECK(consph_particles_init(&p, 2, n, box) == CONSPH_OK, "init");
        double *f1 = consph_particles_field(&p, "a", 1), *f3 = consph_particles_field(&p, "b", 3);
        for (size_t i = 0; i < n; ++i) {
            p.x[0][i] = (double)i;
            p.x[1][i] = -(double)i;
            f1[i] = 0.5 * (double)i;
            for (int c = 0; c < 3; ++c) f3[(size_t)c * p.cap + i] = (double)(c * n + i);
        }
        consph_set_num_threads(t);
        CHECK(consph_particles_permute(&p, perm) == CONSPH_OK, "permute");
        consph_set_num_threads(1);
        for (size_t i = 0; i < n; ++i) {
            const double j = (double)perm[i];
            ok &= p.x[0][i] == j && p.x[1][i] == -j && f1[i] == 0.5 * j;
            for (int c = 0; c < 3; ++c) ok &= f3[(size_t)c * p.cap + i] == (double)(c * n) + j;
        }
        CHECK(ok, "permutation %d, %d thread(s): an array was not permuted as a[perm[i]]", kind, t);
        consph_particles_free(&p);
    }
}

int main(void)
{
    test_brute();
    test_mask();
    test_threads();
    test_update();
    test_tensor();
    test_scratch();
    test_permute_threads();
    test_bad_arguments();
    return check_summary("test_pass");
}
