/* An L-IPST-C-like right-hand side as two fused passes (issue 13, "The pass layer"), and the same
 * quantities by separate consph_apply calls, for bench_pass.c and tests/test_pass_fused.c.
 *
 * Pass 1 sums, in one visit of each particle, the Bonet moment, ∇p (asym with bc), ∇u (f4, the
 * d×d gradient G) and ∇·u (div with bc), and finalises them with the inverted matrix; it writes
 * B into the particle field "bonet" (and "bonet_cond"), which an operator context can adopt.
 * Pass 2 sums the coupled Laplacian of each component of u from G_j (coupled with bc).
 *
 * Both sides run the terms of src/ops/terms.h in the same order, so every quantity equals its
 * consph_apply counterpart bit for bit. The divergence needs B_i at every pair, so it runs over
 * the neighbourhood after the moment has been inverted: a second sweep of the same visit, over
 * pair geometry and kernel values the traversal evaluated once. */
#ifndef CONSPH_BENCH_FUSED_LIPST_H
#define CONSPH_BENCH_FUSED_LIPST_H

#include <stdlib.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "consph/layout.h"
#include "consph/ops.h"
#include "consph/pass.h"
#include "ops/terms.h"

typedef struct fused_lipst {
    int d;
    size_t n, cap;           /* particles; the fields' stride */
    const double *vol, *rho; /* the context's ω and ρ (fields of the system) */
    const double *p;         /* pressure, n */
    const double *u;         /* velocity, d × n */
    double cond_max;
    double *bonet, *bonet_cond; /* fields "bonet" (d² × cap) and "bonet_cond" (cap) */
    double *gradp;              /* ∇p/ρ, d × n */
    double *divu;               /* n */
    double *G;                  /* G[(a d + b) n + i] = ∂_b u_a, d² × n */
    double *lapu;               /* ∇²u_a, d × n */
} fused_lipst;

/* Threads of the next parallel regions (the passes' and consph_apply's). */
static inline void fused_set_threads(int t)
{
#ifdef _OPENMP
    omp_set_num_threads(t);
#else
    (void)t;
#endif
}

static inline void fused_lipst_visit1(void *vjob, const consph_nbhd *nb)
{
    fused_lipst *job = vjob;
    const int d = job->d;
    const size_t i = nb->i, n = job->n;
    const double zero[3] = {0.0, 0.0, 0.0};
    double moment[9], B[9], cond, sg[3], sw, out[3], ui[3];
    term_bonet_moment_any(d, nb, job->vol, moment);
    consph_bonet_finalise(d, moment, job->cond_max, B, &cond);
    for (int e = 0; e < d * d; ++e) job->bonet[(size_t)e * job->cap + i] = B[e];
    job->bonet_cond[i] = cond;
    term_grad_sums_any(d, TERM_GRAD_DIFF, 0, nb, job->vol, NULL, NULL, job->p, job->p[i], sg, &sw);
    term_apply_rule(d, zero, B, sg, sw, out);
    for (int a = 0; a < d; ++a) job->gradp[a * n + i] = out[a] / job->rho[i];
    for (int a = 0; a < d; ++a) {
        const double *ua = job->u + a * n;
        ui[a] = ua[i];
        term_grad_sums_any(d, TERM_GRAD_DIFF, 0, nb, job->vol, NULL, NULL, ua, ui[a], sg, &sw);
        term_apply_rule(d, zero, B, sg, sw, out);
        for (int b = 0; b < d; ++b) job->G[(size_t)(a * d + b) * n + i] = out[b];
    }
    job->divu[i] = term_corrected_div_any(d, CONSPH_CORR_BC, zero, B, nb, job->vol, job->u, n, ui);
}

static inline void fused_lipst_visit2(void *vjob, const consph_nbhd *nb)
{
    fused_lipst *job = vjob;
    const int d = job->d;
    const size_t i = nb->i, n = job->n;
    const double zero[3] = {0.0, 0.0, 0.0};
    double B[9], Gi[3];
    for (int e = 0; e < d * d; ++e) B[e] = job->bonet[(size_t)e * job->cap + i];
    for (int a = 0; a < d; ++a) {
        const double *Ga = job->G + (size_t)a * d * n;
        for (int b = 0; b < d; ++b) Gi[b] = Ga[b * n + i];
        job->lapu[a * n + i] =
            term_corrected_div_any(d, CONSPH_CORR_BC, zero, B, nb, job->vol, Ga, n, Gi);
    }
}

/* The system on the particles of lp (quintic kernel, h = 1.2 Δs with Δs = 1/nx[0]) and an
 * operator context on it with volumes 1/Σ W. */
static inline int fused_lipst_world(const consph_layout_params *lp, consph_sys *sys,
                                    consph_op_ctx *ctx)
{
    consph_particles src;
    consph_kernel k;
    memset(sys, 0, sizeof *sys);
    memset(ctx, 0, sizeof *ctx);
    int st = consph_layout_generate(lp, &src, NULL);
    if (st != CONSPH_OK) return st;
    st = consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, lp->dim, 1.2 / (double)lp->nx[0]);
    if (st == CONSPH_OK) st = consph_sys_init(sys, &src, &k, 0.0);
    consph_particles_free(&src);
    if (st == CONSPH_OK) st = consph_op_ctx_init_sys(ctx, sys, CONSPH_VOLUME_NUMBER);
    return st;
}

/* Binds the job to the system and its context (made by consph_op_ctx_init_sys), creating the
 * fields "bonet" and "bonet_cond"; the caller sets p, u and the outputs. */
static inline int fused_lipst_bind(fused_lipst *job, const consph_sys *sys,
                                   const consph_op_ctx *ctx)
{
    const int d = sys->p->dim;
    job->d = d;
    job->n = sys->p->n;
    job->cap = sys->p->cap;
    job->vol = ctx->volume;
    job->rho = ctx->rho;
    job->cond_max = ctx->cond_max;
    job->bonet = consph_particles_field(sys->p, "bonet", d * d);
    job->bonet_cond = job->bonet ? consph_particles_field(sys->p, "bonet_cond", 1) : NULL;
    return job->bonet_cond ? CONSPH_OK : CONSPH_EINVAL;
}

/* Allocates the job's outputs in one block (n (2d + 1 + d²) values, zero); free() it. */
static inline double *fused_lipst_outputs(fused_lipst *job)
{
    const size_t n = job->n, d = (size_t)job->d;
    double *mem = calloc(n * (2 * d + 1 + d * d), sizeof(double));
    if (!mem) return NULL;
    job->gradp = mem;
    job->divu = mem + d * n;
    job->G = job->divu + n;
    job->lapu = job->G + d * d * n;
    return mem;
}

/* The two fused passes; adds the pairs visited to *pairs. */
static inline int fused_lipst_run(const consph_sys *sys, fused_lipst *job, size_t *pairs)
{
    const consph_pass p1 = {"lipst: bonet + grad p + grad u + div u", CONSPH_PASS_DW,
                            fused_lipst_visit1};
    const consph_pass p2 = {"lipst: coupled laplacian of u", CONSPH_PASS_DW, fused_lipst_visit2};
    int st = consph_pass_run_counted(sys, &p1, job, pairs);
    return st == CONSPH_OK ? consph_pass_run_counted(sys, &p2, job, pairs) : st;
}

/* The same quantities by separate consph_apply calls into job's outputs (G from f4, one
 * component at a time); adds the pairs visited to *pairs. */
static inline int fused_lipst_separate(consph_op_ctx *ctx, fused_lipst *job, size_t *pairs)
{
    const int d = job->d;
    const size_t n = job->n;
    consph_op_report rep;
    int st = consph_apply(ctx, CONSPH_OP_GRAD, CONSPH_FORM_ASYM, CONSPH_CORR_BC, job->p, job->gradp,
                          &rep);
    *pairs += st == CONSPH_OK ? rep.pairs : 0;
    for (int a = 0; a < d && st == CONSPH_OK; ++a) {
        st = consph_apply(ctx, CONSPH_OP_GRAD, CONSPH_FORM_F4, CONSPH_CORR_NONE, job->u + a * n,
                          job->G + (size_t)a * d * n, &rep);
        *pairs += st == CONSPH_OK ? rep.pairs : 0;
    }
    if (st == CONSPH_OK) {
        st = consph_apply(ctx, CONSPH_OP_DIV, CONSPH_FORM_DIV, CONSPH_CORR_BC, job->u, job->divu,
                          &rep);
        *pairs += st == CONSPH_OK ? rep.pairs : 0;
    }
    for (int a = 0; a < d && st == CONSPH_OK; ++a) {
        st = consph_apply(ctx, CONSPH_OP_LAPLACIAN, CONSPH_FORM_COUPLED, CONSPH_CORR_BC,
                          job->u + a * n, job->lapu + a * n, &rep);
        *pairs += st == CONSPH_OK ? rep.pairs : 0;
    }
    return st;
}

#endif
