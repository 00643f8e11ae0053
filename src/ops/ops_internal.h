/* Shared machinery of the operators: the pass over the context's particles, the correction-matrix
 * cache and a small dense solver with a condition estimate. The pair sums are in terms.h. */
#ifndef CONSPH_OPS_INTERNAL_H
#define CONSPH_OPS_INTERNAL_H

#include <string.h>

#include "consph/ops.h"
#include "consph/pass.h"
#include "ops/terms.h"

/* d(d+1)/2 second-derivative components, at most 6; MSPH has 1 + d + d(d+1)/2 <= 10 unknowns. */
#define OPS_MAX_P 6
#define OPS_MAX_MSPH 10

/* What a pass needs evaluated per pair (include/consph/pass.h). */
enum {
    OPS_NEED_W = CONSPH_PASS_W,
    OPS_NEED_DW = CONSPH_PASS_DW,
    OPS_NEED_D2W = CONSPH_PASS_D2W,
    OPS_SKIP_DX = CONSPH_PASS_NO_DX
};

typedef consph_nbhd ops_nbhd;
typedef consph_visit_fn ops_visit_fn;

/* Runs `visit` over every particle of the context's system; adds the pairs visited to *pairs. */
int ops_run(const consph_op_ctx *ctx, unsigned need, ops_visit_fn visit, void *job, size_t *pairs);

/* Cached per-particle matrices. */
typedef enum ops_mat {
    OPS_MAT_BONET,    /* B_i = (Σ ω ∇W ⊗ x_ji)^{-1}, d×d */
    OPS_MAT_LIU,      /* L_i^{-1}, (d+1)² */
    OPS_MAT_FATEHI,   /* B̂_i, 002 eq. 40, d×d */
    OPS_MAT_FATEHI_C, /* B̂_i, 001 eq. 13, d×d */
    OPS_MAT_KORZ,     /* Γ̃_i^{-1}, P×P */
    OPS_MAT_CSPM2,    /* CSPM second-derivative matrix inverse, P×P */
    OPS_MAT_MSPH,     /* MSPH matrix inverse, (1+d+P)² */
    OPS_MAT_IAD,      /* IAD A_i^{-1}, d×d */
    OPS_MAT_COUNT
} ops_mat;

struct consph_ops_cache {
    double *mat[OPS_MAT_COUNT];
    unsigned char *bad[OPS_MAT_COUNT]; /* 1 where the particle fell back */
    size_t nbad[OPS_MAT_COUNT];
    double max_cond[OPS_MAT_COUNT]; /* over accepted matrices */
    double *ctilde;                 /* consistent-Shepard factors c̃ (NULL until needed) */
    double ctilde_lambda;           /* the last normalisation, -> the eigenvalue */
    int ctilde_iterations;
    /* Set by consph_op_ctx_init_sys: mass, rho and volume are fields of these particles, not
     * arrays of the context; mass_given records whether "mass" was there before the context
     * created it (otherwise it holds the default mass, recomputed on refresh). */
    consph_particles *fields_of;
    int mass_given;
};

/* Bookkeeping of one operator call: matrices used and pairs visited. */
typedef struct ops_call {
    unsigned used; /* bit m set: matrix m was used */
    size_t pairs;
} ops_call;

/* Frees matrix m of the cache (it is recomputed on next use). */
void ops_cache_drop(struct consph_ops_cache *c, ops_mat m);
/* Entries per particle of matrix m in `dim` dimensions. */
size_t ops_mat_size(ops_mat m, int dim);
/* The matrix, computing and caching it on first use (recording the pass's pairs in call). */
const double *ops_matrix(consph_op_ctx *ctx, ops_mat m, ops_call *call);
const unsigned char *ops_bad(const consph_op_ctx *ctx, ops_mat m);
/* Fills a report from a call. */
void ops_report_fill(const consph_op_ctx *ctx, const ops_call *call, double t0,
                     consph_op_report *rep);

/* Inverts the n×n row-major matrix a into ainv after row and column equilibration, so the
 * condition estimate (1-norm, of the equilibrated matrix) does not depend on units. Returns 1
 * and writes the estimate to *cond when it is finite and <= cond_max; returns 0 (ainv
 * untouched) for a singular, non-finite or ill-conditioned matrix. */
int ops_invert(int n, const double *a, double *ainv, double cond_max, double *cond);

/* Number of second-derivative components and the (l, k), l <= k, of component p. */
static inline int ops_npairs(int dim)
{
    return dim * (dim + 1) / 2;
}
void ops_pair_index(int dim, int p, int *l, int *k);

/* The F4 (Bonet-Lok) gradient of the scalar `in` at every particle, into g (component-major,
 * dim components); falls back to F2 where B fell back. */
int ops_grad_f4(consph_op_ctx *ctx, const double *in, double *g, ops_call *call);

/* The consistent-Shepard factors, computed with the context's defaults on first use. */
int ops_ctilde(consph_op_ctx *ctx, ops_call *call, const double **ctilde);

/* The consistent-Shepard gradient (000 eqs. 65-67, ops_cshepard.c). */
int ops_grad_cshepard(consph_op_ctx *ctx, const double *in, double *out, ops_call *call);

/* The operator families behind consph_apply (ops_first.c, ops_second.c). */
int ops_first(consph_op_ctx *ctx, consph_op op, consph_op_form form, consph_op_corr corr,
              const double *in, double *out, ops_call *call);
int ops_second(consph_op_ctx *ctx, consph_op op, consph_op_form form, consph_op_corr corr,
               const double *in, double *out, ops_call *call);

#endif
