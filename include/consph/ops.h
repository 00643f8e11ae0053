/* consph ops: SPH particle operators (function, gradient, divergence, Laplacian and second
 * derivatives), their correction matrices and consistency diagnostics (000 §2-§4, 001 §2-§4
 * and App. A-C, 002 §2-§5, 003 §2).
 *
 * Conventions (001 App. C, 002 eq. 15): x_ij = x_i - x_j, r = |x_ij|, e_ij = x_ij / r,
 * ∇W_ij = ∇_i W(|x_i - x_j|) = W'(r) e_ij, ω_j the volume of particle j. Every operator is a
 * gather: particle i sums over the neighbours j returned by consph_nnps_query_particle (which
 * include i itself at r = 0) and writes only to i, so results do not depend on the number of
 * threads.
 *
 * Arrays are component-major: component c of particle i is a[c * n + i], n = ctx->n, for the
 * input (a scalar, or a dim-vector for the divergence) and for the output.
 *
 * What each form returns: the pressure-gradient forms asym, sym1, sym2 and sym_s1 approximate
 * ∇p/ρ as 001 Table 2 writes them (ϱ = ρ = m/ω); every other gradient form approximates ∇f.
 * "cspm" is Shepard for the function and F4 for the gradient (the same operators, 000 eqs.
 * 28-30 and 002 eqs. 5-6), and 000 eqs. 31-32 for the second derivatives, which take F' from F4 and
 * so are exact on quadratics only where the neighbourhood is point-symmetric. The correction
 * "fatehi" exists for the form "fatehi" only, where it gives the S4 scheme of 002 (exact on
 * quadratics); "fatehi_c" is 001's traced variant (exact only on the trace, e.g. ∇²|x|²).
 *
 * Correction matrices (Bonet-Lok B, Liu/FPM L, Fatehi B̂, Korzilius Γ̃, CSPM, MSPH, IAD) are
 * computed in a pass of their own on first use and cached in the context (O(N·d²) memory). A
 * matrix whose condition estimate exceeds ctx->cond_max (or that is singular or not finite) is
 * never inverted: that particle falls back to the uncorrected operator (the correction replaced
 * by the identity; for IAD the F2 gradient), and the report counts the particles that fell back.
 *
 * Named particle fields (a system's particles, include/consph/pass.h), so that a scheme computing
 * these in a pass it already runs hands them to the operators instead of paying a pass for each:
 *   "mass", "rho", "volume"  scalars. A context made by consph_op_ctx_init_sys keeps m, ρ and ω
 *                            in these fields of the system's particles (ctx->mass etc. point at
 *                            them; "mass" is read as given when present, else created and filled
 *                            with the default mass); passes read them there.
 *   "bonet"      B_i, d² components          "liu"       L_i^{-1}, (d+1)² components
 *   "fatehi"     B̂_i (002 eq. 40), d²        "fatehi_c"  B̂_i (001 eq. 13), d²
 *   "korzilius"  Γ̃_i^{-1}, P² (P = d(d+1)/2)
 *   "<name>_cond" (optional, 1 component): the condition estimate, 0 where the particle fell back.
 * A tensor's component a*k + b (k its row length) is its row-major entry (a, b), the layout of
 * consph_op_bonet & co; consph_op_ctx_adopt takes a tensor from its field into the context.
 *
 * A context is not safe for concurrent consph_apply calls from several threads (the cache is
 * filled lazily); each call is itself parallel. */
#ifndef CONSPH_OPS_H
#define CONSPH_OPS_H

#include <stddef.h>

#include "consph/core.h"
#include "consph/kernels.h"
#include "consph/nnps.h"
#include "consph/pass.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- names: operator, form and correction, with stable CLI names ---- */

typedef enum consph_op {
    CONSPH_OP_FUNCTION,  /* "function": f, 1 component */
    CONSPH_OP_GRAD,      /* "grad": ∇f, dim components */
    CONSPH_OP_DIV,       /* "div": ∇·u of a dim-vector u, 1 component */
    CONSPH_OP_LAPLACIAN, /* "laplacian": ∇²f, 1 component */
    CONSPH_OP_HESSIAN,   /* "hessian": ∂²f in the order xx, xy, xz, yy, yz, zz (d(d+1)/2) */
    CONSPH_OP_COUNT
} consph_op;

typedef enum consph_op_form {
    CONSPH_FORM_STANDARD,  /* "standard": Σ ω_j f_j W_ij */
    CONSPH_FORM_SHEPARD,   /* "shepard": Shepard/CSPM function, 000 eq. 28 */
    CONSPH_FORM_FPM,       /* "fpm": Liu-Liu FPM, 000 eqs. 33-36 = 001 eq. A.5 */
    CONSPH_FORM_MSPH,      /* "msph": Zhang-Batra MSPH, 000 §3.3 (f, ∇f, ∂²f together) */
    CONSPH_FORM_CSHEPARD,  /* "cshepard": consistent Shepard, 000 eqs. 59-64; gradient 000 eqs.
                              65-67 with ξ_a = Σ_b ω_b c̃_b ∇W̃_ab (eq. 68's ξ is dimensionally
                              inconsistent), so ∇(const) = 0 exactly */
    CONSPH_FORM_F1,        /* "f1": Σ ω_j u_j ∇W_ij, 002 eq. 2 */
    CONSPH_FORM_F2,        /* "f2": Σ ω_j (u_j - u_i) ∇W_ij, 002 eq. 3 */
    CONSPH_FORM_F3,        /* "f3": Σ ω_j (u_j + u_i) ∇W_ij, 002 eq. 4 */
    CONSPH_FORM_F4,        /* "f4": Bonet-Lok renormalised, 002 eqs. 5-6 = 001 eq. A.4 */
    CONSPH_FORM_ASYM,      /* "asym": Σ (p_j - p_i)/ρ_i ∇W_ij ω_j (∇p/ρ), 001 Table 2 */
    CONSPH_FORM_SYM1,      /* "sym1": Σ (p_j + p_i)/(ρ_i ρ_j) ∇W_ij m_j */
    CONSPH_FORM_SYM2,      /* "sym2": Σ m_j (p_j/ρ_j² + p_i/ρ_i²) ∇W_ij */
    CONSPH_FORM_SYM_S1,    /* "sym_s1": Dilts-symmetrised sym1 with Liu gradients, 001 eq. 10 */
    CONSPH_FORM_CSPM,      /* "cspm": CSPM, 000 eqs. 28-32 */
    CONSPH_FORM_IAD,       /* "iad": integral approach to derivatives, 000 eqs. 50-54 */
    CONSPH_FORM_DIV,       /* "div": Σ (u_j - u_i)·∇W_ij ω_j, 001 eq. 11 */
    CONSPH_FORM_S1,        /* "s1": Σ ω_j G_j·∇W_ij, G from f4, 002 eq. 7 */
    CONSPH_FORM_S1_DIFF,   /* "s1_diff": Σ ω_j (G_j - G_i)·∇W_ij, 002 eq. 8 */
    CONSPH_FORM_S1_SUM,    /* "s1_sum": Σ ω_j (G_j + G_i)·∇W_ij, 002 eq. 9 */
    CONSPH_FORM_S2,        /* "s2": Σ ω_j u_j ∇²W_ij, 002 eq. 10 */
    CONSPH_FORM_S2_DIFF,   /* "s2_diff": Σ ω_j (u_j - u_i) ∇²W_ij, 002 eq. 11 */
    CONSPH_FORM_S2_SUM,    /* "s2_sum": Σ ω_j (u_j + u_i) ∇²W_ij, 002 eq. 12 */
    CONSPH_FORM_CLEARY,    /* "cleary": Brookshaw/Cleary-Monaghan S3, 002 eq. 13, 001 Table 4 */
    CONSPH_FORM_TVF,       /* "tvf": Adami, 001 Table 4 */
    CONSPH_FORM_COUPLED,   /* "coupled": 001 Table 4 (= s1_diff with G from asym_bc) */
    CONSPH_FORM_FATEHI,    /* "fatehi": 001 eq. C.8; with corr fatehi it is S4, 002 eqs. 40-41 */
    CONSPH_FORM_FATEHI_C,  /* "fatehi_c": 001 eqs. 13/C.10 (traced B̂; not exact on quadratics) */
    CONSPH_FORM_KORZILIUS, /* "korzilius": 001 eqs. 14-15 with the fixes of docs/deviations.md */
    CONSPH_FORM_COUNT
} consph_op_form;

typedef enum consph_op_corr {
    CONSPH_CORR_NONE,   /* "none" */
    CONSPH_CORR_BC,     /* "bc": Bonet-Lok, ∇W_ij -> B_i ∇W_ij (001 eq. A.1) */
    CONSPH_CORR_LC,     /* "lc": Liu, ∇W_ij -> the gradient part of L_i^{-1}[W_ij, ∇W_ij] */
    CONSPH_CORR_FATEHI, /* "fatehi": Fatehi-Manzari B̂_i of 002 eq. 40 */
    CONSPH_CORR_COUNT
} consph_op_corr;

/* A validated (op, form, corr) triple. */
typedef struct consph_op_spec {
    consph_op op;
    consph_op_form form;
    consph_op_corr corr;
} consph_op_spec;

const char *consph_op_name(consph_op op);
const char *consph_form_name(consph_op_form form);
const char *consph_corr_name(consph_op_corr corr);
/* Name lookups; CONSPH_EINVAL listing the allowed names when unknown. */
int consph_op_lookup(const char *name, consph_op *op);
int consph_form_lookup(const char *name, consph_op_form *form);
int consph_corr_lookup(const char *name, consph_op_corr *corr);
/* CONSPH_OK when the triple is implemented in `dim` dimensions; otherwise CONSPH_EINVAL with a
 * message naming the valid forms of the op, or the valid corrections of the form. */
int consph_op_check(consph_op op, consph_op_form form, consph_op_corr corr, int dim);
/* Looks up all three names and checks the triple (corr may be NULL for "none"). */
int consph_op_parse(const char *op, const char *form, const char *corr, int dim,
                    consph_op_spec *spec);
/* Writes a description of every valid triple of `op` ("standard[none] shepard[none] ...",
 * one form per entry, corrections in brackets) into buf; returns buf. */
const char *consph_op_describe(consph_op op, char *buf, size_t size);
/* Components of the input and of the output of `op` in `dim` dimensions. */
int consph_op_ncomp_in(consph_op op, int dim);
int consph_op_ncomp_out(consph_op op, int dim);

/* ---- context ---- */

typedef enum consph_volume_kind {
    CONSPH_VOLUME_SUMMATION, /* ω = m/ρ with ρ_i = Σ_j m_j W_ij (001 eq. 4) */
    CONSPH_VOLUME_NUMBER,    /* ω_i = 1/Σ_j W_ij (001 eq. 5), ρ = m/ω */
    CONSPH_VOLUME_GIVEN,     /* ω from the field "volume", ρ = m/ω */
    CONSPH_VOLUME_COUNT
} consph_volume_kind;

const char *consph_volume_name(consph_volume_kind kind);
int consph_volume_lookup(const char *name, consph_volume_kind *kind);

struct consph_ops_cache; /* correction matrices, private to src/ops */

/* Everything an operator needs. Mass comes from the field "mass" when present, otherwise
 * m_i = ρ0 V_box / N with ρ0 = 1 (m = ρ0 Δs², which 001 leaves unstated); for CONSPH_VOLUME_GIVEN
 * without a "mass" field, m_i = ρ0 ω_i. `mass`, `rho` and `volume` are owned by the context. */
typedef struct consph_op_ctx {
    const consph_particles *p;
    const consph_nnps *nnps;
    consph_kernel kernel;
    consph_volume_kind volume_kind;
    int dim;
    size_t n;
    double *mass;
    double *rho;
    double *volume;
    double cond_max;     /* fallback threshold on the condition estimate (default 1e8); matrices
                            already cached keep the threshold they were built with until refresh */
    size_t parallel_min; /* passes over fewer particles run on one thread (default 2048): a
                            parallel region costs more than it saves on tiny sets */
    struct consph_ops_cache *cache;
} consph_op_ctx;

/* Binds particles, a neighbour search built on them (radius >= the kernel's support radius) and
 * a radial kernel, and computes the volumes. */
int consph_op_ctx_init(consph_op_ctx *ctx, const consph_particles *p, const consph_nnps *nnps,
                       const consph_kernel *kernel, consph_volume_kind volume_kind);
/* The same over a system's particles, search and kernel (the system must outlive the context);
 * mass, rho and volume become fields of the system's particles (header comment). */
int consph_op_ctx_init_sys(consph_op_ctx *ctx, const consph_sys *sys,
                           consph_volume_kind volume_kind);
/* Takes the correction tensor `name` ("bonet", "liu", "fatehi", "fatehi_c" or "korzilius") from
 * the particle field of that name, as a pass wrote it, instead of computing it: operators that
 * use it read the adopted values until the next refresh. With a field "<name>_cond", particles
 * where it is 0 count as fallbacks in reports and the largest value is the report's max_cond.
 * Adopting "bonet" drops the cached matrices built on it (fatehi, fatehi_c, korzilius). */
int consph_op_ctx_adopt(consph_op_ctx *ctx, const char *name);
/* B_i from its moment Σ_j -ω_j ∇W_ij ⊗ x_ij (d×d row-major, the sum of a pass) with the rule the
 * context uses: the inverse when its condition estimate is finite and <= cond_max (returns 1,
 * *cond the estimate), otherwise the identity (returns 0, *cond = 0). cond may be NULL. */
int consph_bonet_finalise(int d, const double *moment, double cond_max, double *B, double *cond);
void consph_op_ctx_free(consph_op_ctx *ctx);
/* Recomputes volumes and drops every cached matrix; call after the particles moved (and the
 * nnps was rebuilt). */
int consph_op_ctx_refresh(consph_op_ctx *ctx);

/* What an operator call did. */
typedef struct consph_op_report {
    size_t n;         /* particles evaluated */
    size_t pairs;     /* neighbour pairs visited, over every pass the call ran */
    size_t fallbacks; /* particles whose correction matrix was rejected (see header comment) */
    double max_cond;  /* largest condition estimate among the accepted correction matrices */
    double seconds;   /* wall time */
} consph_op_report;

/* The single entry point: evaluates `op` with `form` and `corr` on `in` (consph_op_ncomp_in
 * components) into `out` (consph_op_ncomp_out components). `rep` may be NULL. */
int consph_apply(consph_op_ctx *ctx, consph_op op, consph_op_form form, consph_op_corr corr,
                 const double *in, double *out, consph_op_report *rep);

/* ---- lower-level entry points ---- */

/* Function, gradient and second derivatives of MSPH in one solve; any output may be NULL.
 * f: 1 component, grad: dim, hess: d(d+1)/2 (order of CONSPH_OP_HESSIAN). */
int consph_op_msph(consph_op_ctx *ctx, const double *in, double *f, double *grad, double *hess,
                   consph_op_report *rep);
/* FPM function and gradient in one solve; either output may be NULL. */
int consph_op_fpm(consph_op_ctx *ctx, const double *in, double *f, double *grad,
                  consph_op_report *rep);
/* Korzilius second derivatives [u_xx, u_xy, ...] (hess) and/or their trace (lap). */
int consph_op_korzilius(consph_op_ctx *ctx, const double *in, double *hess, double *lap,
                        consph_op_report *rep);

/* Per-particle correction matrices, computing them if needed. Each returns a pointer into the
 * cache (valid until refresh/free) or NULL with an error; `bad` (may be NULL) receives a
 * pointer to n flags, non-zero where the particle fell back.
 * bonet: B_i, d×d row-major per particle (stride d²);
 * liu: L_i^{-1}, (d+1)×(d+1) per particle, unknown order [f, ∂_x f, ...];
 * fatehi: B̂_i of 002 eq. 40 (d×d, symmetric); fatehi_c: B̂_i of 001 eq. 13 (d×d). */
const double *consph_op_bonet(consph_op_ctx *ctx, const unsigned char **bad);
const double *consph_op_liu(consph_op_ctx *ctx, const unsigned char **bad);
const double *consph_op_fatehi(consph_op_ctx *ctx, const unsigned char **bad);
const double *consph_op_fatehi_c(consph_op_ctx *ctx, const unsigned char **bad);

/* Boundary-integral derivatives on an interval (000 §3.4, eqs. 45-46, 1D only). The particles
 * of ctx are the interior particles b != 1, N; the interval is [box.lo, box.hi] and fA, fB are
 * the values at its ends (particles 1 and N of the paper, which carry no volume). Eq. 45 with
 * the kernel derivative the printed sum lacks (dW_ab/dx_a, as eq. 43 implies) and
 * Γ_a = Σ_b ω_b W_ab. d1 or d2 may be NULL. */
int consph_op_boundary_1d(consph_op_ctx *ctx, const double *in, double fA, double fB, double *d1,
                          double *d2, consph_op_report *rep);

/* Consistent-Shepard factors c̃ (000 eqs. 62-63): the power iteration c̃ <- A c̃ / s with
 * (A c̃)_a = Σ_b ω_b c̃_b W_ab, from c̃ = 1, where s makes Σ_a ω_a c̃_a = Σ_a ω_a (the paper leaves
 * the norm open; s tends to the dominant eigenvalue of A, which is close to but not exactly 1).
 * Stops when max_a |Δc̃_a| < tol or after max_iter sweeps; writes n values to ctilde (may be
 * NULL) and the sweeps run. The function form "cshepard" uses tol 1e-10, max_iter 2000 and
 * caches the result. */
int consph_op_cshepard_factors(consph_op_ctx *ctx, double tol, int max_iter, double *ctilde,
                               int *iterations, double *lambda);

/* ---- consistency diagnostics (000 eqs. 15-16, 001 Tables 3, 5) ---- */

/* Per-particle discrete moments; any output may be NULL.
 * m0: Σ_j ω_j W_ij (1 comp); m1: Σ_j ω_j (x_j - x_i) W_ij (dim comps);
 * g0: Σ_j ω_j ∇W_ij (dim comps); g1: Σ_j ω_j (x_j - x_i) ⊗ ∇W_ij (dim² comps, component
 * a*dim + b = Σ ω (x_j - x_i)^a ∂^b W_ij; equals the identity in the continuum). */
int consph_op_moments(consph_op_ctx *ctx, double *m0, double *m1, double *g0, double *g1,
                      consph_op_report *rep);

/* Histogram of v[0..n) over [lo, hi) in nbins equal bins (003 Figs. 2-3); values outside go to
 * *below / *above (either may be NULL), NaN to neither. Also mean and standard deviation of
 * all finite values (either may be NULL), computed with consph_sum. */
int consph_histogram(const double *v, size_t n, double lo, double hi, int nbins, size_t *counts,
                     size_t *below, size_t *above, double *mean, double *stddev);

#ifdef __cplusplus
}
#endif
#endif
