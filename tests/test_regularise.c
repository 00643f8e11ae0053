/* Particle regularisation (src/regularise/regularise.c): χ_o, IPST, the shifting of Sun et al.,
 * reg_move and M4 remeshing, each against a property it must have. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "check.h"
#include "consph/layout.h"
#include "layout/layout_internal.h"
#include "regularise/regularise.h"

static const double hdx = 1.2;

/* A 2D periodic unit-box layout of nx² particles in a system with the quintic at h = 1.2Δs and
 * the field "volume" = 1/Σ_j W_ij. */
/* A system with the quintic at h = 1.2Δs over a copy of p and the field "volume" = 1/Σ_j W_ij. */
static int sys_of(consph_sys *s, const consph_particles *p)
{
    consph_kernel k;
    if (consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, p->dim, hdx * p->spacing) != CONSPH_OK ||
        consph_sys_init(s, p, &k, 0.0) != CONSPH_OK)
        return 0;
    s->parallel_min = 0; /* small sets still take the parallel path in the thread tests */
    double *vol = consph_particles_field(s->p, "volume", 1);
    double *sumw = calloc(s->p->n, sizeof(double));
    int ok = vol && sumw && consph_layout_density(s, 1.0, sumw, NULL) == CONSPH_OK;
    for (size_t i = 0; ok && i < s->p->n; ++i) vol[i] = 1.0 / sumw[i];
    free(sumw);
    return ok;
}

/* A periodic unit-box layout of nx^dim particles (random: perturbed by eps Δs). */
static int make_layout(consph_particles *p, int dim, consph_layout_kind kind, size_t nx, double eps,
                       uint64_t seed)
{
    consph_layout_params lp = consph_layout_defaults(kind, dim, nx);
    lp.eps = eps;
    lp.seed = seed;
    return consph_layout_generate(&lp, p, NULL) == CONSPH_OK;
}

static int make_sys_dim(consph_sys *s, int dim, consph_layout_kind kind, size_t nx, double eps,
                        uint64_t seed)
{
    consph_particles p;
    if (!make_layout(&p, dim, kind, nx, eps, seed)) return 0;
    const int ok = sys_of(s, &p);
    consph_particles_free(&p);
    return ok;
}

static int make_sys(consph_sys *s, consph_layout_kind kind, size_t nx, double eps, uint64_t seed)
{
    return make_sys_dim(s, 2, kind, nx, eps, seed);
}

static size_t index_of(const consph_sys *s, size_t origin)
{
    for (size_t i = 0; i < s->p->n; ++i)
        if (s->origin[i] == origin) return i;
    return (size_t)-1;
}

/* max|χ_i - χ_o| and max_i Σ W - min_i Σ W over the particles. */
static void chi_stats(const consph_sys *s, double chi0, double *err, double *spread)
{
    const size_t n = s->p->n;
    double *sumw = calloc(n, sizeof(double));
    *err = *spread = NAN;
    if (!sumw || consph_layout_density(s, 1.0, sumw, NULL)) {
        free(sumw);
        return;
    }
    const double hd = pow(s->kernel.h, 2);
    double e = 0.0, lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n; ++i) {
        e = fmax(e, fabs(hd * sumw[i] - chi0));
        lo = fmin(lo, sumw[i]);
        hi = fmax(hi, sumw[i]);
    }
    *err = e;
    *spread = hi - lo;
    free(sumw);
}

/* Minimum-image difference on a periodic axis of length len. */
static double unwrap(double d, double len)
{
    return d - len * nearbyint(d / len);
}

static void test_chi0(void)
{
    consph_kernel k;
    const double ds = 1.0 / 50.0;
    CHECK(consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 2, hdx * ds) == CONSPH_OK, "kernel");
    CHECK_NEAR(reg_chi0(&k, ds), 1.4399190, 1e-6, "chi_o, docs/reference-values.md");
    CHECK(isnan(reg_chi0(&k, 0.0)), "ds = 0 is refused");
}

static reg_ipst_params ipst_params(const consph_sys *s)
{
    reg_ipst_params prm = {s->kernel.h, reg_chi0(&s->kernel, s->p->spacing), 1e-3, 10, 0};
    return prm;
}

/* Neither shifting moves the unperturbed lattice. */
static void test_lattice(void)
{
    consph_sys s;
    CHECK(make_sys(&s, CONSPH_LAYOUT_LATTICE, 20, 0.0, 1), "system: %s", consph_last_error());
    const size_t n = s.p->n, cap = s.p->cap;
    double *x0[2] = {malloc(n * sizeof(double)), malloc(n * sizeof(double))};
    double *dr = calloc(2 * cap, sizeof(double));
    for (int a = 0; a < 2; ++a) memcpy(x0[a], s.p->x[a], n * sizeof(double));
    /* Sun et al.: a shift of 1e-12 h is round-off; the crowded pair below moves by ~1e-3 h. */
    reg_pst_params pp = {s.kernel.h, s.p->spacing, 0.3, 0.1, 0.2, 4.0, 0.0};
    CHECK(reg_pst_shift(&s, &pp, dr) == CONSPH_OK, "PST: %s", consph_last_error());
    double big = 0.0;
    for (size_t i = 0; i < 2 * cap; ++i) big = fmax(big, fabs(dr[i]));
    CHECK(big <= 1e-12 * s.kernel.h, "PST moves a lattice by %g", big);
    memset(dr, 0, 2 * cap * sizeof(double));
    reg_ipst_params prm = ipst_params(&s);
    reg_ipst_report rep = {-1, NAN, NAN, NAN};
    CHECK(reg_ipst(&s, &prm, dr, &rep) == CONSPH_OK, "IPST: %s", consph_last_error());
    CHECK(rep.iterations == 0 || rep.iterations == 1, "iterations %d", rep.iterations);
    double moved = 0.0, shift = 0.0;
    for (int a = 0; a < 2; ++a)
        for (size_t i = 0; i < n; ++i) {
            moved = fmax(moved, fabs(unwrap(s.p->x[a][i] - x0[a][i], 1.0)));
            shift = fmax(shift, fabs(dr[a * cap + i]));
        }
    CHECK(moved <= 1e-12 && shift <= 1e-12, "lattice moved by %g (dr %g)", moved, shift);
    CHECK(rep.chi_err < prm.tol, "chi_err %g", rep.chi_err);
    free(x0[0]);
    free(x0[1]);
    free(dr);
    consph_sys_free(&s);
}

static void test_ipst_perturbed(void)
{
    consph_sys s;
    /* layout "random": every coordinate moved by up to ±0.1Δs (eps 0.4). */
    CHECK(make_sys(&s, CONSPH_LAYOUT_RANDOM, 20, 0.4, 7), "system: %s", consph_last_error());
    const size_t n = s.p->n, cap = s.p->cap;
    reg_ipst_params prm = ipst_params(&s);
    double err0, spread0, err1, spread1;
    chi_stats(&s, prm.chi0, &err0, &spread0);
    double *x0[2] = {malloc(n * sizeof(double)), malloc(n * sizeof(double))};
    for (int a = 0; a < 2; ++a) memcpy(x0[a], s.p->x[a], n * sizeof(double));
    double *dr = calloc(2 * cap, sizeof(double));
    reg_ipst_report rep = {-1, NAN, NAN, NAN};
    CHECK(reg_ipst(&s, &prm, dr, &rep) == CONSPH_OK, "IPST: %s", consph_last_error());
    chi_stats(&s, prm.chi0, &err1, &spread1);
    printf("IPST perturbed: %d iterations, max|chi - chi0| %.3e -> %.3e, spread of sum W %.3e -> "
           "%.3e, max shift %.3f h\n",
           rep.iterations, err0, err1, spread0, spread1, rep.max_shift);
    CHECK(rep.iterations >= 1 && rep.iterations <= prm.max_iter, "iterations %d", rep.iterations);
    CHECK(err1 < err0, "max|chi - chi0| not reduced: %g -> %g", err0, err1);
    CHECK(spread1 < spread0, "spread of sum W not reduced: %g -> %g", spread0, spread1);
    /* The displacement reported is the one the particles made. */
    double worst = 0.0, longest = 0.0;
    for (size_t i = 0; i < n; ++i) {
        double r2 = 0.0;
        for (int a = 0; a < 2; ++a) {
            double moved = unwrap(s.p->x[a][i] - x0[a][i], 1.0);
            worst = fmax(worst, fabs(moved - dr[a * cap + i]));
            r2 += dr[a * cap + i] * dr[a * cap + i];
        }
        longest = fmax(longest, sqrt(r2));
    }
    CHECK(worst <= 1e-13, "positions moved by %g more than dr_total says", worst);
    CHECK_NEAR(rep.max_shift, longest / prm.h, 1e-12, "max_shift is the largest |dr| / h");
    CHECK(longest > 1e-4 * prm.h, "IPST moved nothing (%g)", longest);
    /* "volume" matches the returned positions. */
    double *sumw = calloc(n, sizeof(double));
    const double *vol = consph_particles_find(s.p, "volume")->data;
    CHECK(consph_layout_density(&s, 1.0, sumw, NULL) == CONSPH_OK, "density");
    double vdiff = 0.0;
    for (size_t i = 0; i < n; ++i) vdiff = fmax(vdiff, fabs(vol[i] * sumw[i] - 1.0));
    CHECK(vdiff <= 1e-14, "volume is not 1/sum W at the new positions (%g)", vdiff);
    free(sumw);
    free(x0[0]);
    free(x0[1]);
    free(dr);
    consph_sys_free(&s);
}

/* A lattice whose particle `a` has been moved 0.3Δs towards its neighbour `b` along x. */
static int make_crowded(consph_sys *s, size_t *ia, size_t *ib)
{
    const size_t nx = 16;
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 2, nx);
    consph_particles p;
    if (consph_layout_generate(&lp, &p, NULL)) return 0;
    const size_t a = 8 * nx + 8, b = a + 1; /* lattice index = iy·nx + ix, b to the right */
    if (!(p.x[0][b] > p.x[0][a] && p.x[1][b] == p.x[1][a])) {
        consph_particles_free(&p);
        return 0;
    }
    p.x[0][a] += 0.3 * p.spacing;
    consph_kernel k;
    int ok = consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 2, hdx * p.spacing) == CONSPH_OK &&
             consph_sys_init(s, &p, &k, 0.0) == CONSPH_OK;
    consph_particles_free(&p);
    if (!ok) return 0;
    double *vol = consph_particles_field(s->p, "volume", 1);
    double *sumw = calloc(s->p->n, sizeof(double));
    ok = vol && sumw && consph_layout_density(s, 1.0, sumw, NULL) == CONSPH_OK;
    for (size_t i = 0; ok && i < s->p->n; ++i) vol[i] = 1.0 / sumw[i];
    free(sumw);
    *ia = index_of(s, a);
    *ib = index_of(s, b);
    return ok;
}

static double pair_gap(const consph_sys *s, size_t i, size_t j)
{
    double dx = unwrap(s->p->x[0][j] - s->p->x[0][i], 1.0);
    double dy = unwrap(s->p->x[1][j] - s->p->x[1][i], 1.0);
    return sqrt(dx * dx + dy * dy);
}

static void test_direction(void)
{
    consph_sys s;
    size_t a = 0, b = 0; /* CHECK goes on after a failed make_crowded */
    CHECK(make_crowded(&s, &a, &b), "system: %s", consph_last_error());
    const size_t cap = s.p->cap;
    const double gap0 = pair_gap(&s, a, b), ds = s.p->spacing;
    CHECK_NEAR(gap0, 0.7 * ds, 1e-12, "the crowded pair");
    /* Sun et al.: b lies at +x of a, so a must be pushed to -x and b to +x. */
    double *dr = calloc(2 * cap, sizeof(double));
    reg_pst_params pp = {s.kernel.h, ds, 0.3, 0.1, 0.2, 4.0, 0.0};
    CHECK(reg_pst_shift(&s, &pp, dr) == CONSPH_OK, "PST: %s", consph_last_error());
    CHECK(dr[a] < 0.0 && dr[b] > 0.0, "PST pushes the pair apart: dr_a %g, dr_b %g", dr[a], dr[b]);
    double big = 0.0;
    for (size_t i = 0; i < s.p->n; ++i) big = fmax(big, hypot(dr[i], dr[cap + i]));
    CHECK(big > 0.0 && fabs(dr[a]) >= 0.5 * big, "the crowded particle moves most (%g of %g)",
          fabs(dr[a]), big);
    /* The cap bounds |δr| to max_shift·h and keeps the direction. */
    pp.max_shift = 0.1 * big / s.kernel.h;
    double *capped = calloc(2 * cap, sizeof(double));
    CHECK(reg_pst_shift(&s, &pp, capped) == CONSPH_OK, "PST capped");
    CHECK_NEAR(hypot(capped[a], capped[cap + a]), 0.1 * big, 1e-15, "capped length");
    CHECK(fabs(capped[a] * dr[cap + a] - capped[cap + a] * dr[a]) <=
              1e-12 * hypot(capped[a], capped[cap + a]) * hypot(dr[a], dr[cap + a]),
          "the cap turned the shift");
    free(capped);
    /* IPST, eq. 19 with n_ij = x_ij/|x_ij|: the same pair moves apart. */
    memset(dr, 0, 2 * cap * sizeof(double));
    reg_ipst_params prm = ipst_params(&s);
    prm.max_iter = 1;
    reg_ipst_report rep;
    CHECK(reg_ipst(&s, &prm, dr, &rep) == CONSPH_OK && rep.iterations == 1, "IPST: %s",
          consph_last_error());
    CHECK(dr[a] < 0.0 && dr[b] > 0.0, "IPST pushes the pair apart: dr_a %g, dr_b %g", dr[a], dr[b]);
    CHECK(pair_gap(&s, a, b) > gap0, "gap %g -> %g", gap0, pair_gap(&s, a, b));
    free(dr);
    consph_sys_free(&s);
}

static void test_move(void)
{
    consph_sys s;
    CHECK(make_sys(&s, CONSPH_LAYOUT_LATTICE, 8, 0.0, 1), "system: %s", consph_last_error());
    const size_t n = s.p->n, cap = s.p->cap;
    double *dr = calloc(2 * cap, sizeof(double));
    /* Lattice points sit at (i + 1/2)/8; a shift of ±0.1 takes the edge ones across x = 0, 1. */
    size_t lo = n, hi = n;
    for (size_t i = 0; i < n; ++i) {
        if (s.p->x[0][i] < 0.1) lo = i;
        if (s.p->x[0][i] > 0.9) hi = i;
    }
    dr[lo] = -0.1;
    dr[hi] = 0.1;
    const double xlo = s.p->x[0][lo], xhi = s.p->x[0][hi];
    CHECK(reg_move(&s, dr) == CONSPH_OK, "move: %s", consph_last_error());
    CHECK_NEAR(s.p->x[0][lo], xlo - 0.1 + 1.0, 1e-15, "wrapped at 0");
    CHECK_NEAR(s.p->x[0][hi], xhi + 0.1 - 1.0, 1e-15, "wrapped at 1");
    /* A non-finite displacement is refused, naming the particle, and moves nothing. */
    double *x0 = malloc(n * sizeof(double));
    memcpy(x0, s.p->x[0], n * sizeof(double));
    dr[lo] = 0.01;
    dr[cap + 5] = NAN;
    CHECK(reg_move(&s, dr) == CONSPH_ENUMERIC, "NaN shift refused");
    char want[32];
    snprintf(want, sizeof want, "particle 5 ");
    CHECK(strstr(consph_last_error(), want) != NULL, "message names the particle: %s",
          consph_last_error());
    CHECK(!memcmp(x0, s.p->x[0], n * sizeof(double)), "a refused move moved particles");
    /* On a non-periodic axis a particle may not leave the box. */
    dr[cap + 5] = 0.0;
    s.p->box.periodic[0] = 0;
    dr[hi] = 1.0;
    CHECK(reg_move(&s, dr) == CONSPH_ENUMERIC, "leaving a non-periodic box is refused");
    CHECK(!memcmp(x0, s.p->x[0], n * sizeof(double)), "a refused move moved particles");
    s.p->box.periodic[0] = 1;
    /* Parameters outside their range name themselves. */
    reg_ipst_params bad = ipst_params(&s);
    bad.tol = 0.0;
    CHECK(reg_ipst(&s, &bad, dr, NULL) == CONSPH_EINVAL && strstr(consph_last_error(), "tol"),
          "tol = 0 refused: %s", consph_last_error());
    free(x0);
    free(dr);
    consph_sys_free(&s);
}

/* ---- remeshing ---- */

typedef struct remesh_case {
    consph_sys s;
    double *lattice; /* 2 × cap */
    double *x0[2];   /* particle positions before the remesh */
} remesh_case;

static double lin_f(double x, double y)
{
    return 1.0 + 3.0 * x - 2.0 * y;
}

/* Particles on the cell-centred lattice moved by (sx, sy)·Δs plus eps of the layout "random",
 * carrying "c" = 2.5, "lin" = lin_f and the two-component "u" = (x, x + y) at their positions;
 * the lattice is that of their slots. */
static int remesh_make(remesh_case *rc, size_t nx, double eps, double sx, double sy, int periodic)
{
    memset(rc, 0, sizeof *rc);
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 2, nx);
    lp.box = consph_box_unit(2, periodic);
    consph_particles lat, p;
    if (consph_layout_generate(&lp, &lat, NULL)) return 0;
    lp.kind = CONSPH_LAYOUT_RANDOM;
    lp.eps = eps;
    lp.seed = 11;
    if (consph_layout_generate(&lp, &p, NULL)) {
        consph_particles_free(&lat);
        return 0;
    }
    const size_t n = p.n, cap = p.cap;
    const double shift[2] = {sx * p.spacing, sy * p.spacing};
    for (int a = 0; a < 2; ++a)
        for (size_t i = 0; i < n; ++i) {
            double x = p.x[a][i] + shift[a];
            p.x[a][i] = periodic ? layout_wrap(x, 0.0, 1.0) : x;
        }
    double *c = consph_particles_field(&p, "c", 1), *l = consph_particles_field(&p, "lin", 1);
    double *u = consph_particles_field(&p, "u", 2);
    double *slot = consph_particles_field(&p, "slot", 1);
    for (size_t i = 0; i < n; ++i) {
        c[i] = 2.5;
        l[i] = lin_f(p.x[0][i], p.x[1][i]);
        u[i] = p.x[0][i];
        u[cap + i] = p.x[0][i] + p.x[1][i];
        slot[i] = (double)i;
    }
    consph_kernel k;
    int ok = consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 2, hdx * p.spacing) == CONSPH_OK &&
             consph_sys_init(&rc->s, &p, &k, 0.0) == CONSPH_OK;
    consph_particles_free(&p);
    if (ok) {
        rc->s.parallel_min = 0;
        const size_t sc = rc->s.p->cap;
        rc->lattice = calloc(2 * sc, sizeof(double));
        /* The system is in cell order: slot i gets the lattice point of the particle now at i. */
        for (int a = 0; a < 2; ++a) {
            rc->x0[a] = malloc(n * sizeof(double));
            memcpy(rc->x0[a], rc->s.p->x[a], n * sizeof(double));
            for (size_t i = 0; i < n; ++i) rc->lattice[a * sc + i] = lat.x[a][rc->s.origin[i]];
        }
    }
    consph_particles_free(&lat);
    return ok;
}

static void remesh_free(remesh_case *rc)
{
    free(rc->lattice);
    free(rc->x0[0]);
    free(rc->x0[1]);
    consph_sys_free(&rc->s);
}

static const char *const remesh_fields[] = {"c", "lin", "u"};

/* Largest errors after the remesh: of the constant everywhere, of the linear fields at lattice
 * points whose M4 support does not cross the periodic seam. */
static void remesh_errors(const remesh_case *rc, double *ec, double *el)
{
    const consph_particles *p = rc->s.p;
    const size_t cap = p->cap;
    const double *c = consph_particles_find(p, "c")->data;
    const double *l = consph_particles_find(p, "lin")->data;
    const double *u = consph_particles_find(p, "u")->data;
    const double margin = 3.0 * p->spacing;
    *ec = *el = 0.0;
    for (size_t i = 0; i < p->n; ++i) {
        const double x = p->x[0][i], y = p->x[1][i];
        *ec = fmax(*ec, fabs(c[i] - 2.5));
        if (x < margin || x > 1.0 - margin || y < margin || y > 1.0 - margin) continue;
        *el = fmax(*el, fabs(l[i] - lin_f(x, y)));
        *el = fmax(*el, fabs(u[i] - x));
        *el = fmax(*el, fabs(u[cap + i] - (x + y)));
    }
}

static void test_remesh_lattice_source(void)
{
    /* Particles on a lattice offset by (0.3, -0.2)Δs: M4 reproduces linear functions exactly on
     * a lattice source, so only round-off remains. */
    remesh_case rc;
    CHECK(remesh_make(&rc, 24, 0.0, 0.3, -0.2, 1), "setup: %s", consph_last_error());
    size_t orphans = 99;
    CHECK(reg_remesh_m4(&rc.s, rc.lattice, rc.s.p->spacing, remesh_fields, 3, &orphans) ==
              CONSPH_OK,
          "remesh: %s", consph_last_error());
    double ec, el;
    remesh_errors(&rc, &ec, &el);
    printf("remesh, offset lattice source: constant error %.2e, linear error %.2e\n", ec, el);
    CHECK(ec <= 1e-14, "constant: %g", ec);
    CHECK(el <= 1e-13, "linear on a lattice source: %g", el);
    CHECK(orphans == 0, "orphans %zu", orphans);
    const size_t cap = rc.s.p->cap;
    int on = 1;
    for (int a = 0; a < 2; ++a)
        on &= !memcmp(rc.s.p->x[a], rc.lattice + a * cap, rc.s.p->n * sizeof(double));
    CHECK(on, "particles are not exactly on the lattice points");
    remesh_free(&rc);
}

static void test_remesh_scattered(void)
{
    /* Scattered sources (layout "random", each coordinate moved by up to ±eps/4·Δs): the
     * normalised sum still gives constants to round-off; for a linear field the error is the
     * first moment of the displaced weights, first order in the displacement, so doubling the
     * same displacements doubles it. */
    double el[2];
    const double eps[2] = {0.2, 0.4};
    for (int e = 0; e < 2; ++e) {
        remesh_case rc;
        CHECK(remesh_make(&rc, 24, eps[e], 0.0, 0.0, 1), "setup: %s", consph_last_error());
        CHECK(reg_remesh_m4(&rc.s, rc.lattice, rc.s.p->spacing, remesh_fields, 3, NULL) ==
                  CONSPH_OK,
              "remesh: %s", consph_last_error());
        double ec;
        remesh_errors(&rc, &ec, &el[e]);
        const double ds = rc.s.p->spacing, amp = 0.25 * eps[e] * ds;
        printf("remesh, scattered (|dx| <= %.3f ds): constant error %.2e, linear error %.3e = "
               "%.3f * 3 * max|dx|\n",
               0.25 * eps[e], ec, el[e], el[e] / (3.0 * amp));
        CHECK(ec <= 1e-14, "constant: %g", ec);
        /* Measured: 2.45 |∇f|_max max|dx| at both amplitudes (|∇f| <= 3 on these fields). The
         * bound allows twice that; the order itself is checked by the ratio below. */
        CHECK(el[e] > 1e-10 && el[e] <= 5.0 * 3.0 * amp, "linear error %g vs 3 max|dx| %g", el[e],
              3.0 * amp);
        remesh_free(&rc);
    }
    CHECK(el[1] / el[0] > 1.8 && el[1] / el[0] < 2.2, "error ratio %.3f for twice the displacement",
          el[1] / el[0]);
}

static void test_remesh_orphans(void)
{
    /* A non-periodic box whose particles right of x = 0.6 have moved half a box to the left:
     * the lattice points 2Δs or more right of the last particle see none and keep the values
     * of their own slot. */
    remesh_case rc;
    CHECK(remesh_make(&rc, 16, 0.0, 0.3, -0.2, 0), "setup: %s", consph_last_error());
    consph_particles *p = rc.s.p;
    double *l = consph_particles_field(p, "lin", 1);
    double xmax = -INFINITY;
    for (size_t i = 0; i < p->n; ++i) {
        if (p->x[0][i] > 0.6) {
            p->x[0][i] -= 0.5;
            l[i] = lin_f(p->x[0][i], p->x[1][i]);
        }
        xmax = fmax(xmax, p->x[0][i]);
    }
    double *before = malloc(p->n * sizeof(double));
    memcpy(before, l, p->n * sizeof(double));
    CHECK(consph_sys_update(&rc.s, 0) == CONSPH_OK, "update");
    const double edge = xmax + 2.0 * p->spacing;
    size_t orphans = 0, expect = 0;
    for (size_t i = 0; i < p->n; ++i) expect += rc.lattice[i] >= edge;
    CHECK(reg_remesh_m4(&rc.s, rc.lattice, p->spacing, remesh_fields, 3, &orphans) == CONSPH_OK,
          "remesh: %s", consph_last_error());
    CHECK(orphans == expect && expect > 0, "orphans %zu, expected %zu", orphans, expect);
    int kept = 1, finite = 1;
    for (size_t i = 0; i < p->n; ++i) {
        if (p->x[0][i] >= edge) kept &= l[i] == before[i];
        finite &= isfinite(l[i]);
    }
    CHECK(kept, "an orphan lost its own value");
    CHECK(finite, "a remeshed value is not finite");
    free(before);
    remesh_free(&rc);
}

/* ---- remeshing against the joint search ----
 *
 * The sums of eq. 33 as reg_remesh_m4 took them before it searched the particles alone: one
 * system of the lattice points and the particles (2n points, the lattice points first), a pass
 * over the lattice points that skips the other lattice points among their neighbours and
 * evaluates M4 through the kernel's profile pointer. reg_remesh_m4 must give these values bit
 * for bit. */
typedef struct joint_job {
    const consph_kernel *m4;
    const size_t *origin;
    size_t n, rows;
    const double *const *src;
    double *out;
    unsigned char *orphan;
} joint_job;

static void joint_visit(void *job, const consph_nbhd *nb)
{
    const joint_job *a = job;
    const size_t k = a->origin[nb->i];
    double acc[64] = {0.0}, wsum = 0.0;
    for (size_t q = 0; q < nb->n; ++q) {
        const size_t o = a->origin[nb->j[q]];
        if (o < a->n) continue;
        double w = a->m4->norm;
        for (int c = 0; c < a->m4->dim && w != 0.0; ++c) {
            const double qa = fabs(nb->dx[c][q]) * a->m4->inv_h;
            w = qa < a->m4->support ? w * a->m4->f(qa) : 0.0;
        }
        if (w == 0.0) continue;
        wsum += w;
        for (size_t r = 0; r < a->rows; ++r) acc[r] += w * a->src[r][o - a->n];
    }
    a->orphan[k] = wsum == 0.0;
    for (size_t r = 0; r < a->rows; ++r) a->out[r * a->n + k] = wsum == 0.0 ? 0.0 : acc[r] / wsum;
}

/* The joint search's remeshed values of the fields (rows of n, component by component, field
 * by field) and orphans; 0 on failure. */
static int joint_remesh(const consph_particles *p, const double *lattice, double ds,
                        const char *const *fields, int nf, double *out, unsigned char *orphan)
{
    const size_t n = p->n, cap = p->cap;
    const int d = p->dim;
    const double *src[64];
    size_t rows = 0;
    for (int f = 0; f < nf; ++f) {
        const consph_field *fd = consph_particles_find(p, fields[f]);
        if (!fd) return 0;
        for (int c = 0; c < fd->ncomp && rows < 64; ++c) src[rows++] = fd->data + (size_t)c * cap;
    }
    consph_particles joint;
    if (consph_particles_init(&joint, d, 2 * n, &p->box)) return 0;
    for (int a = 0; a < d; ++a) {
        memcpy(joint.x[a], lattice + (size_t)a * cap, n * sizeof(double));
        memcpy(joint.x[a] + n, p->x[a], n * sizeof(double));
    }
    consph_kernel k;
    consph_sys sys;
    unsigned char *mask = calloc(2 * n, 1);
    int ok = mask && consph_kernel_init(&k, CONSPH_KERNEL_M4, d, ds) == CONSPH_OK &&
             consph_sys_init(&sys, &joint, &k, 0.0) == CONSPH_OK;
    if (ok) {
        for (size_t i = 0; i < 2 * n; ++i) mask[i] = sys.origin[i] < n;
        joint_job job = {&k, sys.origin, n, rows, src, out, orphan};
        const consph_pass pass = {"remesh, joint search", 0u, joint_visit};
        ok = consph_sys_set_dest(&sys, mask) == CONSPH_OK &&
             consph_pass_run(&sys, &pass, &job) == CONSPH_OK;
        consph_sys_free(&sys);
    }
    free(mask);
    consph_particles_free(&joint);
    return ok;
}

/* Remeshes a system of `kind` particles (dim, nx per axis, periodic or not) carrying random
 * fields "u" (dim components), "q" and, with wide, "wide" (20 components: the sums past the
 * local rows), to a lattice of their slots, and compares every value with the joint search's
 * bit for bit. The lattice point of slot i is the lattice site of the particle's input index,
 * shifted by (0.3, -0.2, 0.1)Δs: no lattice point coincides with a particle of the lattice
 * layouts. M4 has h = dscale Δs. Non-periodic, the particles right of the middle move a third of
 * the box left, so that some lattice points have no particle. */
static void remesh_vs_joint(int dim, consph_layout_kind kind, size_t nx, int periodic, int wide,
                            double dscale, const char *what)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, dim, nx);
    lp.box = consph_box_unit(dim, periodic);
    consph_particles lat, p;
    CHECK(consph_layout_generate(&lp, &lat, NULL) == CONSPH_OK, "%s: lattice", what);
    lp.kind = kind;
    lp.eps = 0.4;
    lp.seed = 5;
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "%s: layout: %s", what,
          consph_last_error());
    const size_t n = p.n;
    const double spacing = p.spacing, ds = dscale * spacing;
    if (!periodic)
        for (size_t i = 0; i < n; ++i)
            if (p.x[0][i] > 0.5) p.x[0][i] -= 1.0 / 3.0;
    uint64_t state = 77;
    const char *names[3] = {"u", "q", "wide"};
    const int ncomp[3] = {dim, 1, 20};
    const int nf = wide ? 3 : 2;
    for (int f = 0; f < nf; ++f) {
        double *v = consph_particles_field(&p, names[f], ncomp[f]);
        for (size_t e = 0; e < (size_t)ncomp[f] * p.cap; ++e) {
            state = state * 6364136223846793005ULL + 1442695040888963407ULL;
            v[e] = (double)(state >> 11) * 0x1.0p-53 - 0.5;
        }
    }
    consph_kernel k;
    consph_sys s;
    CHECK(consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, dim, hdx * spacing) == CONSPH_OK &&
              consph_sys_init(&s, &p, &k, 0.0) == CONSPH_OK,
          "%s: system", what);
    consph_particles_free(&p);
    s.parallel_min = 0;
    const size_t cap = s.p->cap;
    double *lattice = calloc((size_t)dim * cap, sizeof(double));
    const double off[3] = {0.3, -0.2, 0.1};
    for (int a = 0; a < dim; ++a)
        for (size_t i = 0; i < n; ++i) {
            const double x = lat.x[a][s.origin[i]] + off[a] * spacing;
            lattice[(size_t)a * cap + i] = periodic ? layout_wrap(x, 0.0, 1.0) : x;
        }
    consph_particles_free(&lat);
    const size_t rows = (size_t)dim + 1 + (wide ? 20 : 0);
    double *ref = calloc(rows * n, sizeof(double));
    unsigned char *orphan = calloc(n, 1);
    CHECK(joint_remesh(s.p, lattice, ds, names, nf, ref, orphan), "%s: joint search: %s", what,
          consph_last_error());
    /* an orphan keeps its own values */
    size_t r = 0, expect = 0;
    for (int f = 0; f < nf; ++f) {
        const double *v = consph_particles_find(s.p, names[f])->data;
        for (int c = 0; c < ncomp[f]; ++c, ++r)
            for (size_t i = 0; i < n; ++i)
                if (orphan[i]) ref[r * n + i] = v[(size_t)c * cap + i];
    }
    for (size_t i = 0; i < n; ++i) expect += orphan[i];
    size_t orphans = 0;
    CHECK(reg_remesh_m4(&s, lattice, ds, names, nf, &orphans) == CONSPH_OK, "%s: remesh: %s", what,
          consph_last_error());
    size_t differ = 0;
    r = 0;
    for (int f = 0; f < nf; ++f) {
        const double *v = consph_particles_find(s.p, names[f])->data;
        for (int c = 0; c < ncomp[f]; ++c, ++r)
            differ += memcmp(v + (size_t)c * cap, ref + r * n, n * sizeof(double)) != 0;
    }
    printf("remesh vs the joint search, %s: %zu particles, %zu orphans, %zu of %zu rows differ\n",
           what, n, orphans, differ, rows);
    CHECK(differ == 0, "%s: %zu rows differ from the joint search", what, differ);
    CHECK(orphans == expect && (periodic || expect > 0), "%s: orphans %zu, expected %zu", what,
          orphans, expect);
    free(ref);
    free(orphan);
    free(lattice);
    consph_sys_free(&s);
}

static void test_remesh_vs_joint(void)
{
#ifdef _OPENMP
    const int saved = omp_get_max_threads();
#endif
    for (int t = 1; t <= 2; ++t) {
#ifdef _OPENMP
        omp_set_num_threads(t);
#endif
        remesh_vs_joint(2, CONSPH_LAYOUT_RANDOM, 24, 1, t == 1, 1.0, "2D random");
        remesh_vs_joint(2, CONSPH_LAYOUT_RANDOM, 16, 0, 0, 1.0, "2D random, not periodic");
        remesh_vs_joint(3, CONSPH_LAYOUT_RANDOM, 9, 1, 0, 1.0, "3D random");
        remesh_vs_joint(3, CONSPH_LAYOUT_RANDOM, 7, 0, 0, 1.0, "3D random, not periodic");
    }
#ifdef _OPENMP
    omp_set_num_threads(1);
#endif
    remesh_vs_joint(2, CONSPH_LAYOUT_PACKED, 12, 1, 0, 1.0, "2D packed");
    remesh_vs_joint(3, CONSPH_LAYOUT_PACKED, 6, 1, 0, 1.0, "3D packed");
    /* M4 narrower than the spacing: the search of n particles would have had half the cells per
     * radius of the joint search of 2n points (another walk, another order) */
    remesh_vs_joint(3, CONSPH_LAYOUT_RANDOM, 9, 1, 0, 0.8, "3D random, ds 0.8 of the spacing");
#ifdef _OPENMP
    omp_set_num_threads(saved);
#endif
}

/* ---- 1 and 2 threads ---- */

static void test_threads(void)
{
    double *ipst_x[2], *pst_dr[2], *rem[2];
    size_t pst_len = 0;
    for (int t = 0; t < 2; ++t) {
#ifdef _OPENMP
        omp_set_num_threads(t + 1);
#endif
        consph_sys s;
        CHECK(make_sys(&s, CONSPH_LAYOUT_RANDOM, 24, 0.4, 3), "system");
        const size_t n = s.p->n, cap = s.p->cap;
        pst_dr[t] = calloc(2 * cap, sizeof(double));
        pst_len = 2 * cap;
        reg_pst_params pp = {s.kernel.h, s.p->spacing, 0.3, 0.1, 0.2, 4.0, 0.0};
        CHECK(reg_pst_shift(&s, &pp, pst_dr[t]) == CONSPH_OK, "PST");
        double *dr = calloc(2 * cap, sizeof(double));
        reg_ipst_params prm = ipst_params(&s);
        CHECK(reg_ipst(&s, &prm, dr, NULL) == CONSPH_OK, "IPST");
        ipst_x[t] = malloc(5 * n * sizeof(double));
        memcpy(ipst_x[t], s.p->x[0], n * sizeof(double));
        memcpy(ipst_x[t] + n, s.p->x[1], n * sizeof(double));
        memcpy(ipst_x[t] + 2 * n, dr, n * sizeof(double));
        memcpy(ipst_x[t] + 3 * n, dr + cap, n * sizeof(double));
        memcpy(ipst_x[t] + 4 * n, consph_particles_find(s.p, "volume")->data, n * sizeof(double));
        free(dr);
        consph_sys_free(&s);
        remesh_case rc;
        CHECK(remesh_make(&rc, 24, 0.4, 0.0, 0.0, 1), "remesh setup");
        CHECK(reg_remesh_m4(&rc.s, rc.lattice, rc.s.p->spacing, remesh_fields, 3, NULL) ==
                  CONSPH_OK,
              "remesh");
        const consph_particles *q = rc.s.p;
        rem[t] = malloc(4 * q->n * sizeof(double));
        memcpy(rem[t], consph_particles_find(q, "c")->data, q->n * sizeof(double));
        memcpy(rem[t] + q->n, consph_particles_find(q, "lin")->data, q->n * sizeof(double));
        memcpy(rem[t] + 2 * q->n, consph_particles_find(q, "u")->data, q->n * sizeof(double));
        memcpy(rem[t] + 3 * q->n, consph_particles_find(q, "u")->data + q->cap,
               q->n * sizeof(double));
        remesh_free(&rc);
    }
#ifdef _OPENMP
    omp_set_num_threads(1);
#endif
    const size_t n = 24 * 24;
    CHECK(!memcmp(ipst_x[0], ipst_x[1], 5 * n * sizeof(double)), "IPST differs with 2 threads");
    CHECK(!memcmp(pst_dr[0], pst_dr[1], pst_len * sizeof(double)), "PST differs with 2 threads");
    CHECK(!memcmp(rem[0], rem[1], 4 * n * sizeof(double)), "remesh differs with 2 threads");
    for (int t = 0; t < 2; ++t) {
        free(ipst_x[t]);
        free(pst_dr[t]);
        free(rem[t]);
    }
}

/* IPST on a system with a neighbour list (its volumes and shift chained on the pair cache, summed
 * four particles at a time by the group visits, or one at a time) moves the particles, and
 * leaves the volumes and the report, exactly as on a system without one, on 1 and 2 threads, in
 * 2D (random and packed layouts, neighbour counts differing from particle to particle, so the
 * lanes of a group run out at different pairs) and 3D; on the lattice (converged before any
 * shift) it moves nothing either. */
static void test_ipst_chained(void)
{
    const struct {
        int dim;
        consph_layout_kind kind;
        size_t nx;
        double eps;
    } cases[4] = {{2, CONSPH_LAYOUT_RANDOM, 40, 0.4},
                  {2, CONSPH_LAYOUT_LATTICE, 20, 0.0},
                  {2, CONSPH_LAYOUT_PACKED, 12, 0.0},
                  {3, CONSPH_LAYOUT_RANDOM, 9, 0.4}};
    enum { VARIANTS = 5 };
    for (int c = 0; c < 4; ++c) {
        const int d = cases[c].dim;
        double *out[VARIANTS] = {NULL};
        reg_ipst_report rep[VARIANTS];
        size_t n = 0;
        consph_particles layout;
        CHECK(make_layout(&layout, d, cases[c].kind, cases[c].nx, cases[c].eps, 3), "layout: %s",
              consph_last_error());
        /* 0: no list; 1, 2: the list, groups, 1 and 2 threads; 3, 4: one particle at a time */
        for (int v = 0; v < VARIANTS; ++v) {
#ifdef _OPENMP
            omp_set_num_threads(v == 2 || v == 4 ? 2 : 1);
#endif
            reg_ipst_groups = v < 3;
            consph_sys s;
            CHECK(sys_of(&s, &layout), "system: %s", consph_last_error());
            if (v > 0)
                CHECK(consph_sys_nlist(&s, 0.0, NULL, 0) == CONSPH_OK, "list: %s",
                      consph_last_error());
            n = s.p->n;
            const size_t cap = s.p->cap;
            double *dr = calloc((size_t)d * cap, sizeof(double));
            reg_ipst_params prm = ipst_params(&s);
            const unsigned long chains = reg_ipst_chains;
            CHECK(reg_ipst(&s, &prm, dr, &rep[v]) == CONSPH_OK, "IPST: %s", consph_last_error());
            if (v > 0) CHECK(reg_ipst_chains > chains, "case %d: no iteration ran chained", c);
            out[v] = malloc((size_t)(2 * d + 1) * n * sizeof(double));
            for (size_t i = 0; i < n; ++i) {
                /* in the order of the input particles: the systems sort alike, but say so */
                const size_t k = s.origin[i];
                for (int a = 0; a < d; ++a) {
                    out[v][(size_t)a * n + k] = s.p->x[a][i];
                    out[v][(size_t)(d + a) * n + k] = dr[(size_t)a * cap + i];
                }
                out[v][(size_t)(2 * d) * n + k] = consph_particles_find(s.p, "volume")->data[i];
            }
            free(dr);
            consph_sys_free(&s);
        }
        reg_ipst_groups = 1;
        consph_particles_free(&layout);
        CHECK(cases[c].kind == CONSPH_LAYOUT_LATTICE || rep[0].iterations > 1,
              "case %d: %d iterations", c, rep[0].iterations);
        for (int v = 1; v < VARIANTS; ++v) {
            CHECK(!memcmp(out[0], out[v], (size_t)(2 * d + 1) * n * sizeof(double)),
                  "case %d: positions, shifts or volumes differ with the list (variant %d)", c, v);
            CHECK(rep[v].iterations == rep[0].iterations &&
                      !memcmp(&rep[v].chi_max, &rep[0].chi_max, sizeof(double)) &&
                      !memcmp(&rep[v].max_shift, &rep[0].max_shift, sizeof(double)),
                  "case %d: report differs with the list (variant %d)", c, v);
        }
        for (int v = 0; v < VARIANTS; ++v) free(out[v]);
    }
#ifdef _OPENMP
    omp_set_num_threads(1);
#endif
}

int main(void)
{
    test_chi0();
    test_lattice();
    test_ipst_perturbed();
    test_direction();
    test_move();
    test_remesh_lattice_source();
    test_remesh_scattered();
    test_remesh_orphans();
    test_remesh_vs_joint();
    test_threads();
    test_ipst_chained();
    return check_summary("test_regularise");
}
