/* The solver's fused derivative passes (src/schemes/negi/kit.c as L-IPST-C requests them: the
 * Bonet moment + ∇p + ∇u + ∇·u in one traversal, then the coupled Laplacian of u from G_j)
 * against the same quantities by separate consph_apply calls (asym_bc, f4 per component,
 * div_bc, coupled_bc per component).
 *
 * Cases: 2D 500² and 3D 100³ particles on a lattice perturbed by ε = 0.1 (the random layout) in
 * the periodic unit box, quintic kernel, h = 1.2Δs, volumes 1/Σ W. For each on 1 and 2 threads:
 * the pairs visited, the wall time, pairs/s/core (pairs visited / time / threads) and the
 * speed-up (separate time / fused time); and whether the two give identical numbers
 * (tests/test_kit_apply.c checks every output of the kit). The volumes, the search and the
 * context are built before timing and shared by both sides; the separate side starts from an
 * empty matrix cache, so it pays its own Bonet pass as the fused pass does.
 *
 * Usage: bench_pass [NX2 NX3] (particles per axis; default 500 100; a smoke run: 40 10). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/consph.h"
#include "solver/solver_internal.h"
#ifdef _OPENMP
#include <omp.h>
#endif

static void set_threads(int t)
{
#ifdef _OPENMP
    omp_set_num_threads(t);
#else
    (void)t;
#endif
}

/* The separate calls into sep (∇p/ρ d×n, G d²×n, ∇·u n, ∇²u d×n); adds the pairs to *pairs. */
static int separate(consph_op_ctx *ctx, int d, size_t n, const double *p, const double *u,
                    double *sep, size_t *pairs)
{
    consph_op_report rep;
    double *gradp = sep, *G = sep + (size_t)d * n, *divu = G + (size_t)d * d * n, *lapu = divu + n;
    int st = consph_apply(ctx, CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_CORR_BC, p, gradp, &rep);
    *pairs += st == CONSPH_OK ? rep.pairs : 0;
    for (int a = 0; a < d && st == CONSPH_OK; ++a) {
        st = consph_apply(ctx, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, u + a * n,
                          G + (size_t)a * d * n, &rep);
        *pairs += st == CONSPH_OK ? rep.pairs : 0;
    }
    if (st == CONSPH_OK) {
        st = consph_apply(ctx, CONSPH_OP_DIV, CONSPH_FORM_DIV, CONSPH_CORR_BC, u, divu, &rep);
        *pairs += st == CONSPH_OK ? rep.pairs : 0;
    }
    for (int a = 0; a < d && st == CONSPH_OK; ++a) {
        st = consph_apply(ctx, CONSPH_OP_LAPLACIAN, CONSPH_FORM_COUPLED, CONSPH_CORR_BC, u + a * n,
                          lapu + a * n, &rep);
        *pairs += st == CONSPH_OK ? rep.pairs : 0;
    }
    return st;
}

/* The kit's outputs in the layout of separate() (∇p divided by the context's ρ). */
static void kit_outputs(const consph_sys *sys, const consph_op_ctx *ctx, double *out)
{
    const consph_particles *p = sys->p;
    const int d = p->dim;
    const char *names[] = {SF_GRADP, SF_GRADU, SF_DIVU, SF_LAPU};
    const int comps[] = {d, d * d, 1, d};
    for (int k = 0; k < 4; ++k) {
        const consph_field *f = consph_particles_find(p, names[k]);
        for (int c = 0; c < comps[k]; ++c, out += p->n)
            for (size_t i = 0; i < p->n; ++i)
                out[i] = f ? f->data[(size_t)c * p->cap + i] / (k == 0 ? ctx->rho[i] : 1.0) : 0.0;
    }
}

static int run_case(int dim, size_t nx)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, dim, nx);
    lp.eps = 0.1;
    lp.seed = 1;
    consph_sys sys;
    consph_op_ctx ctx;
    consph_particles src;
    consph_kernel k;
    memset(&sys, 0, sizeof sys);
    memset(&ctx, 0, sizeof ctx);
    int st = consph_layout_generate(&lp, &src, NULL);
    if (st == CONSPH_OK) {
        st = consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, dim, 1.2 / (double)nx);
        if (st == CONSPH_OK) st = consph_sys_init(&sys, &src, &k, 0.0);
        consph_particles_free(&src);
    }
    if (st == CONSPH_OK) st = consph_op_ctx_init_sys(&ctx, &sys, CONSPH_VOLUME_NUMBER);
    const size_t n = sys.p ? sys.p->n : 0, cap = sys.p ? sys.p->cap : 0;
    const size_t nout = n * (size_t)(2 * dim + 1 + dim * dim);
    double *in = st == CONSPH_OK ? calloc(n * (size_t)(dim + 1), sizeof(double)) : NULL;
    double *m1 = in ? calloc(nout, sizeof(double)) : NULL;
    double *m2 = m1 ? calloc(nout, sizeof(double)) : NULL;
    double *fp = m2 ? consph_particles_field(sys.p, SF_P, 1) : NULL;
    double *fu = fp ? consph_particles_field(sys.p, SF_U, dim) : NULL;
    if (!fu) {
        fprintf(stderr, "bench_pass: %dD setup: %s\n", dim, consph_last_error());
        free(in);
        free(m1);
        free(m2);
        consph_op_ctx_free(&ctx);
        consph_sys_free(&sys);
        return 1;
    }
    for (size_t i = 0; i < n; ++i) {
        double x = sys.p->x[0][i], y = sys.p->x[1][i], z = dim > 2 ? sys.p->x[2][i] : 0.0;
        in[i] = fp[i] = x * y + z;
        for (int a = 0; a < dim; ++a)
            in[(size_t)(1 + a) * n + i] = fu[(size_t)a * cap + i] = x - y * (a + 1) + z * z;
    }
    /* L-IPST-C's request (src/schemes/negi/scheme.c) */
    const kit_req rq = {KIT_GRADP | KIT_LAPU | KIT_DIVU, KIT_LAP_COUPLED, SF_RHOF, ctx.cond_max, 0};
    size_t warm = 0;
    int warm_passes = 0;
    st = kit_derivatives(&sys, &rq, &warm, &warm_passes); /* creates the output fields */
    for (int threads = 1; threads <= 2 && st == CONSPH_OK; ++threads) {
        set_threads(threads);
        size_t pf = 0, ps = 0;
        int passes = 0;
        double t0 = consph_wtime();
        st = kit_derivatives(&sys, &rq, &pf, &passes);
        double tf = consph_wtime() - t0;
        if (st == CONSPH_OK) st = consph_op_ctx_refresh(&ctx);
        t0 = consph_wtime();
        if (st == CONSPH_OK) st = separate(&ctx, dim, n, in, in + n, m2, &ps);
        double ts = consph_wtime() - t0;
        if (st != CONSPH_OK) {
            fprintf(stderr, "bench_pass: %dD: %s\n", dim, consph_last_error());
            break;
        }
        kit_outputs(&sys, &ctx, m1);
        const int same = memcmp(m1, m2, nout * sizeof(double)) == 0;
        printf("%dD %zu^%d  threads %d  fused: %6.2e pairs %7.3f s %6.2e pairs/s/core  "
               "separate: %6.2e pairs %7.3f s %6.2e pairs/s/core  speed-up %.2f  identical %s\n",
               dim, nx, dim, threads, (double)pf, tf, (double)pf / tf / threads, (double)ps, ts,
               (double)ps / ts / threads, ts / tf, same ? "yes" : "NO");
        fflush(stdout);
    }
    free(in);
    free(m1);
    free(m2);
    consph_op_ctx_free(&ctx);
    consph_sys_free(&sys);
    return st == CONSPH_OK ? 0 : 1;
}

int main(int argc, char **argv)
{
    size_t nx2 = 500, nx3 = 100;
    if (argc == 3) {
        nx2 = strtoul(argv[1], NULL, 10);
        nx3 = strtoul(argv[2], NULL, 10);
    }
    if (argc == 2 || argc > 3 || nx2 < 8 || nx3 < 6 || nx2 > 100000 || nx3 > 2000) {
        fprintf(stderr, "usage: bench_pass [NX2 NX3] (particles per axis: NX2 >= 8, NX3 >= 6)\n");
        return 2;
    }
    printf("the kit's fused passes (L-IPST-C's request) vs separate consph_apply calls (quintic, h "
           "= 1.2 dx, "
           "perturbed lattice eps 0.1, periodic)\n");
    int rc = run_case(2, nx2);
    rc |= run_case(3, nx3);
    return rc;
}
