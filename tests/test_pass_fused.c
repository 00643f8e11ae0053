/* Fused passes built from the operators' terms (bench/fused_lipst.h) against consph_apply, and
 * correction tensors written by a pass and adopted by an operator context.
 *
 * - Pass 1 (Bonet moment + ∇p + ∇u + ∇·u) and pass 2 (coupled Laplacian from G_j) give, bit for
 *   bit, what the separate consph_apply calls give, on one thread and on two, in fewer pairs.
 * - A context made on the system keeps ω, m, ρ in the system's fields.
 * - "bonet" written by pass 1 and adopted gives the operators the results of the context's own
 *   B (fallbacks and condition estimates included) without the context's Bonet pass; adopting
 *   a different tensor changes the results (the identity turns f4 into f2). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../bench/fused_lipst.h"
#include "check.h"
#include "consph/consph.h"

static int same(const double *a, const double *b, size_t m)
{
    return memcmp(a, b, m * sizeof(double)) == 0;
}

/* Runs consph_apply on a fresh cache (or on the adopted tensor when adopt is set). */
static int apply_f(consph_op_ctx *ctx, const char *adopt, consph_op op, consph_op_form form,
                   consph_op_corr corr, const double *in, double *out, consph_op_report *rep)
{
    if (consph_op_ctx_refresh(ctx) != CONSPH_OK) return 0;
    if (adopt && consph_op_ctx_adopt(ctx, adopt) != CONSPH_OK) return 0;
    return consph_apply(ctx, op, form, corr, in, out, rep) == CONSPH_OK;
}

static void check_case(int dim, size_t nx, int periodic, int provoke_fallbacks)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, dim, nx);
    lp.eps = 0.3;
    lp.seed = 11;
    for (int a = 0; a < dim; ++a) lp.box.periodic[a] = periodic;
    consph_sys sys;
    consph_op_ctx ctx;
    int ok = fused_lipst_world(&lp, &sys, &ctx) == CONSPH_OK;
    CHECK(ok, "%dD setup: %s", dim, consph_last_error());
    if (!ok) {
        consph_sys_free(&sys);
        return;
    }
    const size_t n = sys.p->n;
    const int d = dim;
    const consph_field *fv = consph_particles_find(sys.p, "volume");
    const consph_field *fm = consph_particles_find(sys.p, "mass");
    const consph_field *fr = consph_particles_find(sys.p, "rho");
    CHECK(fv && fm && fr && fv->data == ctx.volume && fm->data == ctx.mass && fr->data == ctx.rho,
          "%dD: the context's volume, mass and rho are the system's fields", dim);

    consph_op_report rep;
    double *in = calloc(n * (size_t)(d + 1), sizeof(double));
    fused_lipst fused, sep, two;
    memset(&fused, 0, sizeof fused);
    ok = in && fused_lipst_bind(&fused, &sys, &ctx) == CONSPH_OK;
    CHECK(ok, "%dD bind: %s", dim, consph_last_error());
    if (!ok) {
        free(in);
        consph_op_ctx_free(&ctx);
        consph_sys_free(&sys);
        return;
    }
    for (size_t i = 0; i < n; ++i) {
        double x = sys.p->x[0][i], y = d > 1 ? sys.p->x[1][i] : 0.0,
               z = d > 2 ? sys.p->x[2][i] : 0.0;
        in[i] = sin(6.283185307179586 * x) * cos(6.283185307179586 * y) + z * z;
        for (int a = 0; a < d; ++a)
            in[(size_t)(1 + a) * n + i] = cos(6.283185307179586 * (x + 0.3 * a)) + x * y - 0.5 * z;
    }
    if (provoke_fallbacks) {
        /* Below the worst condition estimate, so that some particles fall back. */
        double *g = calloc((size_t)d * n, sizeof(double));
        ok =
            g && apply_f(&ctx, NULL, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, in, g, &rep);
        free(g);
        ctx.cond_max = 0.5 * rep.max_cond;
        fused.cond_max = ctx.cond_max;
        CHECK(ok, "%dD: %s", dim, consph_last_error());
    }
    fused.p = in;
    fused.u = in + n;
    sep = fused;
    two = fused;
    double *m1 = fused_lipst_outputs(&fused), *m2 = fused_lipst_outputs(&sep),
           *m3 = fused_lipst_outputs(&two);
    CHECK(m1 && m2 && m3, "out of memory");
    if (m1 && m2 && m3) {
        size_t pairs_fused = 0, pairs_two = 0, pairs_sep = 0, pairs_one = 0;
        fused_set_threads(1);
        ok = fused_lipst_run(&sys, &fused, &pairs_fused) == CONSPH_OK;
        ok = ok && consph_op_ctx_refresh(&ctx) == CONSPH_OK &&
             fused_lipst_separate(&ctx, &sep, &pairs_sep) == CONSPH_OK;
        fused_set_threads(2);
        ok = ok && fused_lipst_run(&sys, &two, &pairs_two) == CONSPH_OK;
        fused_set_threads(1);
        CHECK(ok, "%dD runs: %s", dim, consph_last_error());
        const size_t dn = (size_t)d * n;
        CHECK(same(fused.gradp, sep.gradp, dn), "%dD: fused asym_bc ∇p/ρ == consph_apply", dim);
        CHECK(same(fused.G, sep.G, dn * (size_t)d), "%dD: fused ∇u == f4 per component", dim);
        CHECK(same(fused.divu, sep.divu, n), "%dD: fused ∇·u == div bc", dim);
        CHECK(same(fused.lapu, sep.lapu, dn), "%dD: fused ∇²u == coupled bc per component", dim);
        CHECK(same(m1, m3, n * (size_t)(2 * d + 1 + d * d)), "%dD: fused, 1 vs 2 threads", dim);
        /* One traversal of every particle's neighbourhood, counted by the f2 gradient. */
        ok = apply_f(&ctx, NULL, CONSPH_OP_GRAD, CONSPH_FORM_F2, CONSPH_CORR_NONE, in, sep.gradp,
                     &rep);
        pairs_one = rep.pairs;
        CHECK(ok && pairs_fused == 2 * pairs_one && pairs_two == pairs_fused,
              "%dD: the fused pair is two traversals (%zu pairs, one is %zu)", dim, pairs_fused,
              pairs_one);
        CHECK(pairs_sep >= (size_t)(2 + 3 * d) * pairs_one,
              "%dD: separate calls visit %zu pairs, at least %d traversals", dim, pairs_sep,
              2 + 3 * d);

        /* Adoption: the same results as the context's own B, without its pass. */
        double *own = calloc(dn, sizeof(double)), *adopted = calloc(dn, sizeof(double));
        CHECK(own && adopted, "out of memory");
        if (own && adopted) {
            consph_op_report rown, radopt;
            ok = apply_f(&ctx, NULL, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, in, own,
                         &rown);
            ok = ok && apply_f(&ctx, "bonet", CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, in,
                               adopted, &radopt);
            CHECK(ok, "%dD adopt: %s", dim, consph_last_error());
            CHECK(same(own, adopted, dn), "%dD: f4 with the adopted B == with the context's", dim);
            CHECK(rown.fallbacks == radopt.fallbacks && rown.max_cond == radopt.max_cond,
                  "%dD: fallbacks %zu vs %zu, max cond %g vs %g", dim, rown.fallbacks,
                  radopt.fallbacks, rown.max_cond, radopt.max_cond);
            CHECK(!provoke_fallbacks || radopt.fallbacks > 0, "%dD: fallbacks provoked", dim);
            CHECK(rown.pairs == 2 * pairs_one && radopt.pairs == pairs_one,
                  "%dD: the adopted B spares the Bonet pass (%zu vs %zu pairs)", dim, radopt.pairs,
                  rown.pairs);
            /* Fatehi's B̂ is built on B: rebuilt on the adopted one, same result. */
            ok = apply_f(&ctx, NULL, CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI, CONSPH_CORR_FATEHI,
                         in, own, &rown);
            ok = ok && apply_f(&ctx, "bonet", CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI,
                               CONSPH_CORR_FATEHI, in, adopted, &radopt);
            CHECK(ok && same(own, adopted, n), "%dD: S4 on the adopted B == on the context's", dim);
            /* A tensor that differs from B gives other results: the identity makes f4 into f2. */
            for (int e = 0; e < d * d; ++e)
                for (size_t i = 0; i < n; ++i)
                    fused.bonet[(size_t)e * sys.p->cap + i] = e % (d + 1) == 0 ? 1.0 : 0.0;
            ok = apply_f(&ctx, NULL, CONSPH_OP_GRAD, CONSPH_FORM_F2, CONSPH_CORR_NONE, in, own,
                         &rown);
            ok = ok && apply_f(&ctx, "bonet", CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, in,
                               adopted, &radopt);
            CHECK(ok && same(own, adopted, dn), "%dD: f4 on an adopted identity == f2", dim);
            CHECK(!same(adopted, sep.G, dn), "%dD: ... and differs from f4 on B", dim);
        }
        free(own);
        free(adopted);
    }
    CHECK(consph_op_ctx_adopt(&ctx, "nope") == CONSPH_EINVAL, "unknown tensor name rejected");
    CHECK(consph_op_ctx_adopt(&ctx, "liu") == CONSPH_EINVAL, "adopting an absent field fails");
    free(m1);
    free(m2);
    free(m3);
    free(in);
    consph_op_ctx_free(&ctx);
    consph_sys_free(&sys);
}

int main(void)
{
    check_case(2, 24, 1, 0);
    check_case(2, 20, 0, 1);
    check_case(3, 9, 1, 0);
    check_case(1, 60, 0, 0);
    return check_summary("test_pass_fused");
}
