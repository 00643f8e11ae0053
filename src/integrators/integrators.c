/* The integrators' table and their steps (the state and the callbacks: integrators.h). */
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "consph/solver.h"
#include "integrators/integrators.h"

/* Per-particle loops run on the threads from this many particles on; each particle is written by
 * one iteration, so the bits do not depend on the thread count. */
#define INTEG_PARALLEL_MIN 4096

void integ_save_start(const integ_state *st)
{
    const size_t n = st->n, cap = st->cap;
    memcpy(st->q0, st->q, n * sizeof(double));
    for (int a = 0; a < st->dim; ++a) {
        memcpy(st->u0 + a * cap, st->u + a * cap, n * sizeof(double));
        if (st->x0) memcpy(st->x0 + a * cap, st->x[a], n * sizeof(double));
    }
}

/* The evolved fields are updated in blocks of this many particles, shared out among the threads,
 * one array at a time within a block: loops over restrict-qualified arrays that vectorise. */
#define INTEG_BLOCK 2048

/* y = y0 + c k over n values. */
static void update_block(double *restrict y, const double *restrict y0, const double *restrict k,
                         double c, size_t n)
{
    for (size_t i = 0; i < n; ++i) y[i] = y0[i] + c * k[i];
}

/* y0 = y, then y = y0 + c k over n values (one sweep: the value saved is the one updated). GCC
 * would split the copy out as a memmove, a second sweep reading y again. */
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-tree-loop-distribute-patterns")))
#endif
static void
save_update_block(double *restrict y, double *restrict y0, const double *restrict k, double c,
                  size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        const double v = y[i];
        y0[i] = v;
        y[i] = v + c * k[i];
    }
}

/* update_block and save_update_block with the rates of particle i at kp[i] of k (the last
 * rates, not moved by the re-sort: integ_state.kperm), the same values. */
static void update_block_perm(double *restrict y, const double *restrict y0,
                              const double *restrict k, const size_t *restrict kp, double c,
                              size_t n)
{
    for (size_t i = 0; i < n; ++i) y[i] = y0[i] + c * k[kp[i]];
}

#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-tree-loop-distribute-patterns")))
#endif
static void
save_update_block_perm(double *restrict y, double *restrict y0, const double *restrict k,
                       const size_t *restrict kp, double c, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        const double v = y[i];
        y0[i] = v;
        y[i] = v + c * k[kp[i]];
    }
}

/* One block's y = y0 + c k (save: y0 = y first), k read through kp where it is not NULL (kp,
 * y and y0 at the block's first particle, k at its component's). */
static void update_one(double *y, double *y0, const double *k, const size_t *kp, double c, size_t n,
                       int save)
{
    if (kp && save)
        save_update_block_perm(y, y0, k, kp, c, n);
    else if (kp)
        update_block_perm(y, y0, k, kp, c, n);
    else if (save)
        save_update_block(y, y0, k, c, n);
    else
        update_block(y, y0, k, c, n);
}

/* In blocks shared out among the threads: u = u0 + c ku and q = q0 + c kq where ku is given,
 * then x = x0 + c kx where kx is; save: from the unsaved start, u0, q0 (and x0) = u, q (and x)
 * in the same sweep (the same values: u0 is u); close: the block's closure (close_range) after
 * its q; kp: the rates read through it (integ_state.kperm), or NULL. Each value depends on its
 * own particle's alone, so one sweep of a block doing both is the two sweeps (one parallel
 * region, not two). */
static void update_blocks(const integ_state *st, double c, const double *ku, const double *kq,
                          const double *kx, int save, int close, const size_t *kp)
{
    const int d = st->dim;
    const size_t n = st->n, cap = st->cap;
    /* blocks of at most INTEG_BLOCK particles (a multiple of 8), as many as a multiple of the
     * threads: 5 blocks of 2048 shared by 2 threads would give one of them 3 */
    size_t nblocks = (n + INTEG_BLOCK - 1) / INTEG_BLOCK;
#ifdef _OPENMP
    const size_t threads = n >= INTEG_PARALLEL_MIN ? (size_t)omp_get_max_threads() : 1;
    nblocks = (nblocks + threads - 1) / threads * threads;
#endif
    size_t bs = nblocks ? (n + nblocks - 1) / nblocks : 1;
    bs = (bs + 7) / 8 * 8;
    nblocks = (n + bs - 1) / bs;
    double *u = st->u, *q = st->q, *u0 = st->u0, *q0 = st->q0;
#pragma omp parallel for schedule(static) if (n >= INTEG_PARALLEL_MIN)
    for (size_t b = 0; b < nblocks; ++b) {
        const size_t i0 = b * bs, m = n - i0 < bs ? n - i0 : bs;
        for (int a = ku ? -1 : d; a < d; ++a) {
            /* a = -1: q; then the components of u */
            const size_t o = a < 0 ? i0 : (size_t)a * cap + i0;
            double *y = a < 0 ? q : u, *y0 = a < 0 ? q0 : u0;
            const double *k = a < 0 ? kq : ku;
            if (kp)
                update_one(y + o, y0 + o, k + (o - i0), kp + i0, c, m, save);
            else
                update_one(y + o, y0 + o, k + o, NULL, c, m, save);
            if (a < 0 && close) st->close_range(st->ctx, i0, i0 + m);
        }
        for (int a = 0; kx && a < d; ++a) {
            double *x = st->x[a] + i0, *x0 = st->x0 + a * cap + i0;
            const double *k = kx + a * cap;
            update_one(x, x0, kp ? k : k + i0, kp ? kp + i0 : NULL, c, m, save);
        }
    }
}

/* u, q = u0, q0 + c (ku, kq), with the closure block by block where the state has one */
static void set_fields(const integ_state *st, double c, const double *ku, const double *kq)
{
    update_blocks(st, c, ku, kq, NULL, 0, st->close_range != NULL, NULL);
}

/* The closure after an update of q, unless the update ran it block by block. */
static void close_updated(const integ_state *st)
{
    if (!st->close_range) st->close(st->ctx);
}

/* x = x0 + c kx (with save: x0 = x first, in the same sweep), then wrapped and the search
 * rebuilt by the solver. */
static int drift(const integ_state *st, double c, const double *kx, int save)
{
    update_blocks(st, c, NULL, NULL, kx, save, 0, NULL);
    return st->moved(st->ctx);
}

/* y = y0 + c k for the evolved fields with the last rates, then the closure (in the update's
 * sweep where it has a close_range); save: the step's first update of an unsaved start, which
 * saves it on the way. Without a transport hook between the update and the drift, both in one
 * sweep. */
static int advance(const integ_state *st, double c, int save)
{
    const int fused = st->close_range != NULL;
    /* the first update of a step that starts from the last rates (save) is their reader */
    const size_t *kp = save ? st->kperm : NULL;
    if (st->x0 && !st->transport) {
        update_blocks(st, c, st->au, st->aq, st->ax, save, fused, kp);
        int rc = st->moved(st->ctx);
        if (rc != CONSPH_OK) return rc;
    } else {
        update_blocks(st, c, st->au, st->aq, NULL, save, fused, kp);
        if (st->x0) {
            if (st->transport) st->transport(st->ctx, c);
            int rc = drift(st, c, st->ax, save);
            if (rc != CONSPH_OK) return rc;
        }
    }
    close_updated(st);
    return CONSPH_OK;
}

/* Explicit midpoint (001 §5.2): y½ = y0 + Δt/2 F(y0), y1 = y0 + Δt F(y½). Under pec the F(y0)
 * is the previous step's F(y½), which makes PySPH's PECIntegrator. */
static int step_midpoint(const integ_state *st, double dt)
{
    int rc = advance(st, 0.5 * dt, st->unsaved);
    if (rc == CONSPH_OK) rc = st->rates(st->ctx);
    if (rc == CONSPH_OK) rc = advance(st, dt, 0);
    return rc;
}

static int step_euler(const integ_state *st, double dt)
{
    return advance(st, dt, st->unsaved);
}

/* Kick-drift-kick: the half kick moves u0 and q0 on, the drift uses the kicked velocity (with the
 * transport hook's correction), the second kick adds the rates at the drifted positions. */
static int step_kdk(const integ_state *st, double dt)
{
    const int d = st->dim;
    const size_t n = st->n, cap = st->cap;
    double *u0 = st->u0, *q0 = st->q0, *ax = st->ax, *u = st->u;
    const double *au = st->au, *aq = st->aq, *q = st->q;
    if (st->unsaved) {
        /* the start read from u, q and kicked into u0, q0 (the same values: u0 would be u) */
        const double h = 0.5 * dt;
#pragma omp parallel for schedule(static) if (n >= INTEG_PARALLEL_MIN)
        for (size_t i = 0; i < n; ++i) {
            q0[i] = q[i] + h * aq[i];
            for (int a = 0; a < d; ++a) {
                const double v = u[a * cap + i] + h * au[a * cap + i];
                u0[a * cap + i] = v;
                u[a * cap + i] = v;
            }
        }
    } else {
#pragma omp parallel for schedule(static) if (n >= INTEG_PARALLEL_MIN)
        for (size_t i = 0; i < n; ++i) {
            q0[i] += 0.5 * dt * aq[i];
            for (int a = 0; a < d; ++a) {
                u0[a * cap + i] += 0.5 * dt * au[a * cap + i];
                u[a * cap + i] = u0[a * cap + i];
            }
        }
    }
    int rc = CONSPH_OK;
    if (st->x0) {
        if (st->transport) {
            st->transport(st->ctx, 0.5 * dt);
        } else {
            /* rates evaluated at this step's start: dx/dt there plus the half kick */
#pragma omp parallel for schedule(static) if (n >= INTEG_PARALLEL_MIN)
            for (size_t i = 0; i < n; ++i)
                for (int a = 0; a < d; ++a) ax[a * cap + i] += 0.5 * dt * au[a * cap + i];
        }
        rc = drift(st, dt, ax, st->unsaved);
    }
    double *qd = st->q;
#pragma omp parallel for schedule(static) if (n >= INTEG_PARALLEL_MIN)
    for (size_t i = 0; i < n; ++i) qd[i] = q0[i];
    if (rc == CONSPH_OK) st->close(st->ctx);
    if (rc == CONSPH_OK) rc = st->rates(st->ctx);
    if (rc != CONSPH_OK) return rc;
    /* the second kick; the particles stay where the drift put them */
    set_fields(st, 0.5 * dt, au, aq);
    close_updated(st);
    return CONSPH_OK;
}

/* Shu & Osher's third-order strong-stability-preserving Runge-Kutta (SSP-RK3, 3 stages), in
 * increments from the step's start so that positions in a periodic box need no unwrapping:
 *   y1 = y0 + Δt k1,  y2 = y0 + Δt/4 (k1 + k2),  y3 = y0 + Δt/6 (k1 + k2 + 4 k3),
 * k_s the rates at y_{s-1} (the Shu-Osher convex combinations y2 = 3/4 y0 + 1/4 (y1 + Δt k2),
 * y3 = 1/3 y0 + 2/3 (y2 + Δt k3) expanded). The scratch holds Σ b_s k_s of u, q and the drift
 * velocity. The transport hook gets the time from the step's start to the stage's state (Δt,
 * Δt/2, Δt), as the midpoint rule's (Δt/2, Δt). */
static const integ_field ssprk3_scratch[] = {{"ssprk3_ku", INTEG_LIKE_U},
                                             {"ssprk3_kq", INTEG_LIKE_Q},
                                             {"ssprk3_kx", INTEG_LIKE_X},
                                             {NULL, INTEG_LIKE_U}};

/* k = k + w (au, aq), or k = (au, aq) when first. */
static void ssprk3_gather(const integ_state *st, double *ku, double *kq, double w, int first)
{
    const int d = st->dim;
    const size_t n = st->n, cap = st->cap;
    const double *au = st->au, *aq = st->aq;
#pragma omp parallel for schedule(static) if (n >= INTEG_PARALLEL_MIN)
    for (size_t i = 0; i < n; ++i) {
        kq[i] = first ? aq[i] : kq[i] + w * aq[i];
        for (int a = 0; a < d; ++a)
            ku[a * cap + i] = first ? au[a * cap + i] : ku[a * cap + i] + w * au[a * cap + i];
    }
}

/* One stage's end: u, q = u0, q0 + c (ku, kq); the drift velocity (after the transport hook with
 * time tc) gathered into kx with weight w, x = x0 + c kx; then the closure. */
static int ssprk3_stage(const integ_state *st, double c, double tc, double w, int first)
{
    double *ku = st->scratch[0], *kq = st->scratch[1], *kx = st->scratch[2];
    set_fields(st, c, ku, kq);
    if (st->x0) {
        if (st->transport) st->transport(st->ctx, tc);
        const size_t n = st->n, cap = st->cap;
        const int d = st->dim;
        const double *ax = st->ax;
#pragma omp parallel for schedule(static) if (n >= INTEG_PARALLEL_MIN)
        for (size_t i = 0; i < n; ++i)
            for (int a = 0; a < d; ++a) {
                const size_t j = a * cap + i;
                kx[j] = first ? ax[j] : kx[j] + w * ax[j];
            }
        int rc = drift(st, c, kx, 0);
        if (rc != CONSPH_OK) return rc;
    }
    close_updated(st);
    return CONSPH_OK;
}

static int step_ssprk3(const integ_state *st, double dt)
{
    if (st->unsaved) integ_save_start(st);
    double *ku = st->scratch[0], *kq = st->scratch[1];
    ssprk3_gather(st, ku, kq, 1.0, 1);
    int rc = ssprk3_stage(st, dt, dt, 1.0, 1);
    if (rc == CONSPH_OK) rc = st->rates(st->ctx);
    if (rc == CONSPH_OK) {
        ssprk3_gather(st, ku, kq, 1.0, 0);
        rc = ssprk3_stage(st, 0.25 * dt, 0.5 * dt, 1.0, 0);
    }
    if (rc == CONSPH_OK) rc = st->rates(st->ctx);
    if (rc == CONSPH_OK) {
        ssprk3_gather(st, ku, kq, 4.0, 0);
        rc = ssprk3_stage(st, dt / 6.0, dt, 4.0, 0);
    }
    return rc;
}

/* The table: a new integrator is a step function above and one row here. */
#define INTEGRATORS(X)                                                                             \
    X("rk2", "explicit midpoint Runge-Kutta, two evaluations per step (001 §5.2)", 2, 2,           \
      INTEG_REUSE_NEVER, NULL, step_midpoint)                                                      \
    X("euler", "forward Euler", 1, 1, INTEG_REUSE_NEVER, NULL, step_euler)                         \
    X("kdk",                                                                                       \
      "kick-drift-kick (Adami et al. 2013; PySPH TransportVelocityStep); one evaluation per "      \
      "step where the transport hook rebuilds the drift velocity from the reused rates",           \
      2, 2, INTEG_REUSE_WITH_TRANSPORT, NULL, step_kdk)                                            \
    X("pec",                                                                                       \
      "PySPH's PECIntegrator: the midpoint rule predicting with the previous step's rates, one "   \
      "evaluation per step",                                                                       \
      2, 2, INTEG_REUSE_ALWAYS, NULL, step_midpoint)                                               \
    X("ssprk3", "Shu & Osher's third-order strong-stability-preserving Runge-Kutta (SSP-RK3)", 3,  \
      3, INTEG_REUSE_NEVER, ssprk3_scratch, step_ssprk3)

#define INTEG_ROW(name, summary, order, stages, reuse, scratch, step)                              \
    {name, summary, order, stages, reuse, scratch, step},
static const integ_def integ_table[] = {INTEGRATORS(INTEG_ROW)};
#define INTEG_NAME(name, ...) "," name
static const char integ_names[] = INTEGRATORS(INTEG_NAME);

const char *consph_integrator_names(void)
{
    return integ_names + 1; /* past the first comma */
}

const integ_def *integ_find(const char *name)
{
    for (size_t k = 0; k < sizeof integ_table / sizeof integ_table[0]; ++k)
        if (strcmp(name, integ_table[k].name) == 0) return &integ_table[k];
    return NULL;
}

int integ_scratch_count(const integ_def *row)
{
    int k = 0;
    while (row->scratch && row->scratch[k].name) ++k;
    return k;
}
