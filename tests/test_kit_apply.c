/* The solver runs what the studies measure: the kit's fused passes (src/schemes/negi/kit.c, the
 * derivatives of 001's schemes) against consph_apply of the same operator, form and correction
 * (include/consph/ops.h), on perturbed and packed particle sets, periodic or not, in 2D and 3D.
 *
 *   kit_volumes                  ω = 1/Σ W     == the context's number volumes   bit for bit
 *   KIT_GRADP  ∇p / ρ            == grad asym bc                                  bit for bit
 *   KIT_GRADU  ∂_b u_a           == grad f4 none, per component                   bit for bit
 *   KIT_DIVU   ∇·u               == div div bc                          to 1e-13 max|∇·u|
 *                                == the trace of the kit's G                      bit for bit
 *   KIT_GRADQ  ∇q                == grad f4 none                                  bit for bit
 *   KIT_LAPU   coupled           == laplacian coupled bc, per component           bit for bit
 *              Fatehi_c          == laplacian fatehi_c none                       bit for bit
 *              Korzilius         == laplacian korzilius none             to 1e-14 max|∇²u|
 *   KIT_LAPQ   coupled           == laplacian coupled bc                          bit for bit
 *   "bonet"    B_i               == consph_op_bonet (fallbacks to the identity)   bit for bit
 *
 * Both sides sum the terms of src/ops/terms.h in the same order, except ∇·u (the kit applies B_i
 * to the sums of G once, div bc applies it per pair) and the last step of Korzilius' Laplacian
 * (the reason at its check). The fused passes also give the same bits on
 * one thread and on two, visit every pair once per pass (pairs = passes x one traversal), and
 * the same requests with a matrix condition cap low enough that some particles fall back still
 * agree. The tensor B_i the kit leaves in "bonet", adopted by an operator context, gives the
 * operators the results of the context's own B without its pass. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/consph.h"
#include "solver/solver_internal.h"

#define TWO_PI 6.283185307179586

/* Component a of field `name` (stride cap) into n contiguous values. */
static void gather(const consph_particles *p, const char *name, int a, double *out)
{
    const consph_field *f = consph_particles_find(p, name);
    for (size_t i = 0; i < p->n; ++i) out[i] = f ? f->data[(size_t)a * p->cap + i] : NAN;
}

static size_t count_diff(const double *a, const double *b, size_t n)
{
    size_t k = 0;
    for (size_t i = 0; i < n; ++i) k += memcmp(&a[i], &b[i], sizeof(double)) != 0;
    return k;
}

typedef struct world {
    consph_sys sys;
    consph_op_ctx ctx;
    int d;
    size_t n;
    double *p, *u, *q; /* the inputs, contiguous (u: d × n) */
    double *a, *b;     /* scratch, d² × n each */
} world;

/* The particles of lp with smooth p, u and q (fields "p", "u", "rhof"), an operator context with
 * number volumes, quintic kernel, h = 1.2 Δs. */
static int world_make(world *w, const consph_layout_params *lp)
{
    consph_particles src;
    consph_kernel k;
    memset(w, 0, sizeof *w);
    int st = consph_layout_generate(lp, &src, NULL);
    if (st != CONSPH_OK) return st;
    st = consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, lp->dim, 1.2 / (double)lp->nx[0]);
    if (st == CONSPH_OK) st = consph_sys_init(&w->sys, &src, &k, 0.0);
    consph_particles_free(&src);
    if (st == CONSPH_OK) st = consph_op_ctx_init_sys(&w->ctx, &w->sys, CONSPH_VOLUME_NUMBER);
    if (st != CONSPH_OK) return st;
    consph_particles *p = w->sys.p;
    const int d = w->d = lp->dim;
    const size_t n = w->n = p->n, cap = p->cap;
    double *fp = consph_particles_field(p, SF_P, 1), *fu = consph_particles_field(p, SF_U, d);
    double *fq = consph_particles_field(p, SF_RHOF, 1);
    w->p = malloc(n * sizeof(double));
    w->u = malloc((size_t)d * n * sizeof(double));
    w->q = malloc(n * sizeof(double));
    w->a = malloc((size_t)d * d * n * sizeof(double));
    w->b = malloc((size_t)d * d * n * sizeof(double));
    if (!fp || !fu || !fq || !w->p || !w->u || !w->q || !w->a || !w->b) return CONSPH_ENOMEM;
    for (size_t i = 0; i < n; ++i) {
        const double x = p->x[0][i], y = d > 1 ? p->x[1][i] : 0.0, z = d > 2 ? p->x[2][i] : 0.0;
        w->p[i] = fp[i] = sin(TWO_PI * x) * cos(TWO_PI * y) + z * z;
        w->q[i] = fq[i] = 1.0 + 0.1 * cos(TWO_PI * (x + 2.0 * y)) + 0.05 * x * z;
        for (int a = 0; a < d; ++a)
            w->u[(size_t)a * n + i] = fu[(size_t)a * cap + i] =
                cos(TWO_PI * (x + 0.3 * a)) + x * y - 0.5 * z;
    }
    return CONSPH_OK;
}

static void world_free(world *w)
{
    free(w->p);
    free(w->u);
    free(w->q);
    free(w->a);
    free(w->b);
    consph_op_ctx_free(&w->ctx);
    consph_sys_free(&w->sys);
}

/* consph_apply on a fresh cache; the pairs it visited into *pairs. */
static int apply(world *w, consph_op op, consph_op_form form, consph_op_corr corr, const double *in,
                 double *out, size_t *pairs)
{
    consph_op_report rep;
    if (consph_op_ctx_refresh(&w->ctx) != CONSPH_OK) return 0;
    int ok = consph_apply(&w->ctx, op, form, corr, in, out, &rep) == CONSPH_OK;
    if (pairs) *pairs = rep.pairs;
    return ok;
}

/* Field `name` (ncomp components) against ref (ncomp × n contiguous); with `by_rho` the field
 * divided by the context's ρ first. tol = 0: bit for bit; else |kit - ref| <= tol max|ref|. */
static void expect_same(world *w, const char *what, const char *name, int ncomp, const double *ref,
                        int by_rho, double tol)
{
    const size_t n = w->n;
    size_t bad = 0;
    double diff = 0.0, big = 0.0;
    for (int c = 0; c < ncomp; ++c) {
        double *got = w->a + (size_t)c * n;
        const double *r = ref + (size_t)c * n;
        gather(w->sys.p, name, c, got);
        if (by_rho)
            for (size_t i = 0; i < n; ++i) got[i] /= w->ctx.rho[i];
        bad += count_diff(got, r, n);
        for (size_t i = 0; i < n; ++i) {
            diff = fmax(diff, fabs(got[i] - r[i]));
            big = fmax(big, fabs(r[i]));
        }
    }
    if (tol == 0.0)
        CHECK(bad == 0, "%dD %s: %zu of %zu values differ from consph_apply (max %.3g)", w->d, what,
              bad, (size_t)ncomp * n, diff);
    else
        CHECK(diff <= tol * big, "%dD %s: max |kit - consph_apply| %.3g > %.1g max|ref| (%.3g)",
              w->d, what, diff, tol, big);
}

/* Every kit output of one request against consph_apply. */
static void compare(world *w, kit_lap lap, const char *label)
{
    const int d = w->d;
    const size_t n = w->n;
    const char *lapname[] = {"coupled", "Fatehi_c", "Korzilius"};
    double *ref = w->b;
    char what[96];
    int ok = apply(w, CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_CORR_BC, w->p, ref, NULL);
    snprintf(what, sizeof what, "%s gradp/rho (asym bc)", label);
    if (ok) expect_same(w, what, SF_GRADP, d, ref, 1, 0.0);
    for (int a = 0; a < d && ok; ++a)
        ok = apply(w, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, w->u + (size_t)a * n,
                   ref + (size_t)a * d * n, NULL);
    /* the kit's G[a d + b] is component a's gradient b: the same layout */
    snprintf(what, sizeof what, "%s grad u (f4)", label);
    if (ok) expect_same(w, what, SF_GRADU, d * d, ref, 0, 0.0);
    ok = ok && apply(w, CONSPH_OP_DIV, CONSPH_FORM_DIV, CONSPH_CORR_BC, w->u, ref, NULL);
    snprintf(what, sizeof what, "%s div u (div bc)", label);
    if (ok) expect_same(w, what, SF_DIVU, 1, ref, 0, 1e-13);
    if (ok) {
        /* ∇·u = Σ_a ∂_a u_a of the kit's own G, summed from a = 0 up */
        for (size_t i = 0; i < n; ++i) ref[i] = 0.0;
        for (int a = 0; a < d; ++a) {
            gather(w->sys.p, SF_GRADU, a * d + a, w->a);
            for (size_t i = 0; i < n; ++i) ref[i] += w->a[i];
        }
        snprintf(what, sizeof what, "%s div u (trace of the kit's G)", label);
        expect_same(w, what, SF_DIVU, 1, ref, 0, 0.0);
    }
    ok = ok && apply(w, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, w->q, ref, NULL);
    snprintf(what, sizeof what, "%s grad q (f4)", label);
    if (ok) expect_same(w, what, SF_GRADQ, d, ref, 0, 0.0);
    const consph_op_form lapform[] = {CONSPH_FORM_COUPLED, CONSPH_FORM_FATEHI_C,
                                      CONSPH_FORM_KORZILIUS};
    const consph_op_corr lapcorr[] = {CONSPH_CORR_BC, CONSPH_CORR_NONE, CONSPH_CORR_NONE};
    for (int a = 0; a < d && ok; ++a)
        ok = apply(w, CONSPH_OP_LAPLACIAN, lapform[lap], lapcorr[lap], w->u + (size_t)a * n,
                   ref + (size_t)a * n, NULL);
    snprintf(what, sizeof what, "%s lap u (%s)", label, lapname[lap]);
    /* Korzilius: the operator forms each diagonal entry of the Hessian, Σ_c Γ̃^{-1}_rc b_c, and
     * then sums them; the kit sums every product of the diagonal rows into one accumulator
     * (src/schemes/negi/kit.c), which rounds differently: measured ≤ 6e-16 max|∇²u| in 2D and
     * 3D. Every other Laplacian sums the same terms in the same order. */
    if (ok) expect_same(w, what, SF_LAPU, d, ref, 0, lap == KIT_LAP_KORZILIUS ? 1e-14 : 0.0);
    ok = ok && apply(w, CONSPH_OP_LAPLACIAN, CONSPH_FORM_COUPLED, CONSPH_CORR_BC, w->q, ref, NULL);
    snprintf(what, sizeof what, "%s lap q (coupled bc)", label);
    if (ok) expect_same(w, what, SF_LAPQ, 1, ref, 0, 0.0);
    if (ok && consph_op_ctx_refresh(&w->ctx) == CONSPH_OK) {
        const unsigned char *bad = NULL;
        const double *B = consph_op_bonet(&w->ctx, &bad);
        ok = B != NULL;
        if (ok)
            for (int e = 0; e < d * d; ++e)
                for (size_t i = 0; i < n; ++i) ref[(size_t)e * n + i] = B[i * (size_t)(d * d) + e];
        snprintf(what, sizeof what, "%s bonet", label);
        if (ok) expect_same(w, what, SF_BONET, d * d, ref, 0, 0.0);
    }
    CHECK(ok, "%dD %s: consph_apply: %s", d, label, consph_last_error());
}

/* The outputs of the kit as one block (to compare runs). */
static double *snapshot(world *w)
{
    const char *names[] = {SF_BONET, SF_GRADP, SF_GRADU, SF_DIVU, SF_GRADQ, SF_LAPU, SF_LAPQ};
    const int d = w->d, comps[] = {d * d, d, d * d, 1, d, d, 1};
    double *s = malloc((size_t)(2 * d * d + 3 * d + 2) * w->n * sizeof(double)), *o = s;
    for (int k = 0; s && k < 7; ++k)
        for (int c = 0; c < comps[k]; ++c, o += w->n) gather(w->sys.p, names[k], c, o);
    return s;
}

/* The B_i the kit left in "bonet", handed to the operators (consph_op_ctx_adopt): the results of
 * the context's own B without its pass; another tensor in its place changes them. */
static void check_adopt(world *w, const char *label, size_t one)
{
    const int d = w->d;
    const size_t n = w->n, dn = (size_t)d * n;
    consph_particles *p = w->sys.p;
    const consph_field *fv = consph_particles_find(p, "volume");
    const consph_field *fm = consph_particles_find(p, "mass");
    const consph_field *fr = consph_particles_find(p, "rho");
    CHECK(fv && fm && fr && fv->data == w->ctx.volume && fm->data == w->ctx.mass &&
              fr->data == w->ctx.rho,
          "%dD %s: the context's volume, mass and rho are the system's fields", d, label);
    double *own = w->a, *adopted = w->b;
    consph_op_report rown, radopt;
    int ok = consph_op_ctx_refresh(&w->ctx) == CONSPH_OK &&
             consph_apply(&w->ctx, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, w->p, own,
                          &rown) == CONSPH_OK;
    ok = ok && consph_op_ctx_refresh(&w->ctx) == CONSPH_OK &&
         consph_op_ctx_adopt(&w->ctx, "bonet") == CONSPH_OK &&
         consph_apply(&w->ctx, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, w->p, adopted,
                      &radopt) == CONSPH_OK;
    CHECK(ok, "%dD %s adopt: %s", d, label, consph_last_error());
    if (!ok) return;
    CHECK(count_diff(own, adopted, dn) == 0, "%dD %s: f4 on the kit's B == on the context's", d,
          label);
    CHECK(rown.pairs == 2 * one && radopt.pairs == one,
          "%dD %s: the adopted B spares the Bonet pass (%zu vs %zu pairs)", d, label, radopt.pairs,
          rown.pairs);
    /* Fatehi's B̂ is built on B: rebuilt on the adopted one, the same S4 */
    ok = consph_op_ctx_refresh(&w->ctx) == CONSPH_OK &&
         consph_apply(&w->ctx, CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI, CONSPH_CORR_FATEHI, w->p,
                      own, NULL) == CONSPH_OK;
    ok = ok && consph_op_ctx_refresh(&w->ctx) == CONSPH_OK &&
         consph_op_ctx_adopt(&w->ctx, "bonet") == CONSPH_OK &&
         consph_apply(&w->ctx, CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI, CONSPH_CORR_FATEHI, w->p,
                      adopted, NULL) == CONSPH_OK;
    CHECK(ok && count_diff(own, adopted, n) == 0, "%dD %s: S4 on the kit's B == on the context's",
          d, label);
    /* the identity in its place makes f4 into f2 */
    double *B = consph_particles_field(p, SF_BONET, d * d);
    for (int e = 0; B && e < d * d; ++e)
        for (size_t i = 0; i < n; ++i) B[(size_t)e * p->cap + i] = e % (d + 1) == 0 ? 1.0 : 0.0;
    ok = B && apply(w, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, w->p, own, NULL);
    ok = ok && apply(w, CONSPH_OP_GRAD, CONSPH_FORM_F2, CONSPH_CORR_NONE, w->p, w->a + dn, NULL);
    ok = ok && consph_op_ctx_refresh(&w->ctx) == CONSPH_OK &&
         consph_op_ctx_adopt(&w->ctx, "bonet") == CONSPH_OK &&
         consph_apply(&w->ctx, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, w->p, adopted,
                      NULL) == CONSPH_OK;
    CHECK(ok && count_diff(w->a + dn, adopted, dn) == 0 && count_diff(own, adopted, dn) != 0,
          "%dD %s: f4 on an adopted identity == f2, != f4 on B", d, label);
    CHECK(consph_op_ctx_adopt(&w->ctx, "nope") == CONSPH_EINVAL, "unknown tensor name rejected");
    CHECK(consph_op_ctx_adopt(&w->ctx, "liu") == CONSPH_EINVAL, "adopting an absent field fails");
}

static void check_case(consph_layout_kind kind, int dim, size_t nx, int periodic, int provoke)
{
    consph_layout_params lp = consph_layout_defaults(kind, dim, nx);
    lp.eps = 0.3;
    lp.seed = 7;
    lp.packing.max_iter = 200; /* a disordered set is all that is needed, not a converged one */
    for (int a = 0; a < dim; ++a) lp.box.periodic[a] = periodic;
    world w;
    int ok = world_make(&w, &lp) == CONSPH_OK;
    char label[64];
    snprintf(label, sizeof label, "%s%s", consph_layout_name(kind),
             periodic ? " periodic" : " bounded");
    CHECK(ok, "%dD %s: setup: %s", dim, label, consph_last_error());
    if (!ok) {
        world_free(&w);
        return;
    }
    const size_t n = w.n;
    double cond_max = 1e8;
    if (provoke) {
        /* half the worst condition estimate of B: some particles fall back to the identity */
        consph_op_report rep;
        ok = consph_apply(&w.ctx, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, w.p, w.a,
                          &rep) == CONSPH_OK;
        cond_max = 0.5 * rep.max_cond;
    }
    w.ctx.cond_max = cond_max;
    gather(w.sys.p, SF_VOL, 0, w.b); /* the context's volumes */
    size_t pairs = 0, one = 0;
    ok = kit_volumes(&w.sys, &pairs) == CONSPH_OK;
    gather(w.sys.p, SF_VOL, 0, w.a);
    CHECK(ok && count_diff(w.a, w.b, n) == 0, "%dD %s: kit volumes == the context's number volumes",
          dim, label);
    apply(&w, CONSPH_OP_GRAD, CONSPH_FORM_F2, CONSPH_CORR_NONE, w.p, w.a, &one);
    const unsigned all = KIT_GRADP | KIT_GRADU | KIT_DIVU | KIT_GRADQ | KIT_LAPU | KIT_LAPQ;
    for (int lap = KIT_LAP_COUPLED; lap <= KIT_LAP_KORZILIUS; ++lap) {
        kit_req rq = {all, (kit_lap)lap, SF_RHOF, cond_max, 0};
        int passes = 0;
        pairs = 0;
        check_set_threads(1);
        ok = kit_derivatives(&w.sys, &rq, &pairs, &passes) == CONSPH_OK;
        CHECK(ok, "%dD %s: kit: %s", dim, label, consph_last_error());
        if (!ok) break;
        CHECK(passes == 2 && pairs == 2 * one,
              "%dD %s: two passes of one traversal each (%d passes, %zu pairs, one is %zu)", dim,
              label, passes, pairs, one);
        double *s1 = snapshot(&w);
        compare(&w, (kit_lap)lap, label);
        /* two threads on every pass, however small the set */
        const size_t pmin = w.sys.parallel_min;
        w.sys.parallel_min = 0;
        check_set_threads(2);
        ok = kit_derivatives(&w.sys, &rq, &pairs, &passes) == CONSPH_OK;
        check_set_threads(1);
        w.sys.parallel_min = pmin;
        double *s2 = snapshot(&w);
        CHECK(ok && s1 && s2 && count_diff(s1, s2, (size_t)(2 * dim * dim + 3 * dim + 2) * n) == 0,
              "%dD %s lap %d: the same bits on one thread and on two", dim, label, lap);
        free(s1);
        free(s2);
    }
    if (ok && provoke && consph_op_ctx_refresh(&w.ctx) == CONSPH_OK) {
        const unsigned char *bad = NULL;
        size_t fallbacks = 0;
        if (consph_op_bonet(&w.ctx, &bad) && bad)
            for (size_t i = 0; i < n; ++i) fallbacks += bad[i] != 0;
        CHECK(fallbacks > 0 && fallbacks < n, "%dD %s: cond_max %g: %zu of %zu fall back", dim,
              label, cond_max, fallbacks, n);
    }
    /* A request for the gradients alone runs one pass and leaves them as the full one does. */
    if (ok) {
        kit_req rq = {KIT_GRADU | KIT_GRADQ, KIT_LAP_COUPLED, SF_RHOF, cond_max, 0};
        int passes = 0;
        gather(w.sys.p, SF_GRADQ, 0, w.b);
        ok = kit_derivatives(&w.sys, &rq, &pairs, &passes) == CONSPH_OK;
        gather(w.sys.p, SF_GRADQ, 0, w.a);
        CHECK(ok && passes == 1 && count_diff(w.a, w.b, n) == 0,
              "%dD %s: gradients alone: one pass, the same values", dim, label);
    }
    if (ok) check_adopt(&w, label, one);
    world_free(&w);
}

int main(void)
{
    check_case(CONSPH_LAYOUT_RANDOM, 2, 20, 1, 0);
    check_case(CONSPH_LAYOUT_PACKED, 2, 16, 1, 0);
    check_case(CONSPH_LAYOUT_RANDOM, 2, 16, 0, 0);
    check_case(CONSPH_LAYOUT_RANDOM, 2, 16, 0, 1); /* with fallbacks */
    check_case(CONSPH_LAYOUT_RANDOM, 3, 8, 1, 0);
    check_case(CONSPH_LAYOUT_RANDOM, 3, 6, 0, 1); /* with fallbacks */
    return check_summary("test_kit_apply");
}
