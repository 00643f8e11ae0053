/* Time integrators as a const table, one row per integrator, in the manner of GSL odeiv2's step
 * types: a row knows its name, order, stage count, whether it may start a step from the rates
 * the previous step left, and a step function over a state the solver hands it.
 *
 * The state is the evolved fields (velocity u, the evolved scalar q, the positions x when the
 * particles move), their rates (au, aq, and the drift velocity ax), the copies at the start of
 * the step (u0, q0, x0) and callbacks into the solver: evaluate the rates at the current state,
 * close it (the equation of state, or the scheme's own closure), the transport hook (the drift
 * velocity from the velocity just updated) and the drift (wrap the written positions into the
 * box and rebuild the neighbour search). A step sees nothing of the scheme beyond these: no name,
 * no flag. Per-particle arrays are component-major with stride cap, as consph_particles fields. */
#ifndef CONSPH_INTEGRATORS_INTEGRATORS_H
#define CONSPH_INTEGRATORS_INTEGRATORS_H

#include <stddef.h>

/* The per-particle scratch arrays a step may ask for, shaped like one evolved field. */
typedef enum integ_shape {
    INTEG_LIKE_U, /* dim components */
    INTEG_LIKE_Q, /* one component */
    INTEG_LIKE_X  /* dim components; only when the positions are evolved (else NULL) */
} integ_shape;

typedef struct integ_field {
    const char *name;
    integ_shape like;
} integ_field;

#define INTEG_SCRATCH_MAX 4

typedef struct integ_state {
    int dim;
    size_t n, cap;        /* particles, and the stride between components */
    double *u, *q;        /* evolved velocity (dim components) and scalar */
    double *x[3];         /* positions, one array per axis (when x0 is not NULL) */
    double *u0, *q0, *x0; /* the state at the step's start; x0 NULL: positions not evolved */
    /* 1: u0, q0, x0 are not written yet (integ_save_start not called): the step's first update
     * of each field copies it there as it reads it, one sweep instead of two */
    int unsaved;
    const double *au, *aq; /* rates at the last evaluation, rewritten in place by rates() */
    double *ax;            /* drift velocity (NULL when x0 is); rates() and transport() write it */
    /* NULL, or (a step that starts from the last rates, without a transport hook) the re-sort's
     * permutation that au, aq and ax were left out of: particle i's rates are at kperm[i] of
     * them, until rates() rewrites them; the step's first update reads them so, the only reader
     * before rates() (the re-sort need not move them, a sweep of five arrays) */
    const size_t *kperm;
    /* the row's scratch, in its order (integ_def.scratch); never part of the particles' state */
    double *scratch[INTEG_SCRATCH_MAX];
    void *ctx; /* passed to the callbacks */
    int (*rates)(void *ctx);
    void (*close)(void *ctx);
    /* The closure of particles [i0, i1) alone, where it reads and writes their own values only
     * and nothing between an update and its closure reads what it writes (NULL: none): an
     * update runs it on each block of particles just after the block's q, while the block is in
     * the cache, instead of close() sweeping every particle again. */
    void (*close_range)(void *ctx, size_t i0, size_t i1);
    /* The drift velocity ax from the velocity just updated, for a drift whose rates are weighted
     * by c; NULL: ax is the position rate the last evaluation left. */
    void (*transport)(void *ctx, double c);
    int (*moved)(void *ctx); /* positions written: wrap them, rebuild the search */
} integ_state;

/* Whether a step may start from the rates of the previous step instead of evaluating afresh
 * (the solver evaluates afresh anyway when a regularisation changed the state after them). */
typedef enum integ_reuse {
    INTEG_REUSE_NEVER,
    INTEG_REUSE_ALWAYS, /* its step reads the last rates through kperm where the state has one */
    /* only when the drift velocity can be rebuilt from the reused rates by the transport hook */
    INTEG_REUSE_WITH_TRANSPORT
} integ_reuse;

typedef struct integ_def {
    const char *name;
    const char *summary;
    int order;  /* in time, on smooth problems */
    int stages; /* rate evaluations per step, the first of them skipped when rates are reused */
    integ_reuse reuses_rates;
    const integ_field *scratch; /* NULL-name-terminated, or NULL: none */
    /* One step of dt from the state saved by integ_save_start (or, with unsaved, from the
     * current state, which it saves), whose rates are those at the step's start. */
    int (*step)(const integ_state *st, double dt);
} integ_def;

/* The row named `name`, or NULL. */
const integ_def *integ_find(const char *name);
/* The number of scratch arrays the row declares. */
int integ_scratch_count(const integ_def *row);
/* u0, q0 (and x0) = u, q (and x). */
void integ_save_start(const integ_state *st);

#endif
