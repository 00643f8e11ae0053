/* The solver's insides: its state, the scheme table, the derivative kit the schemes' right-hand
 * sides are made of, the problems and the integrators.
 *
 * State lives in named fields of the system's particles, so that re-sorting the particles into
 * cell order at the start of a step carries everything with them (and a checkpoint of the
 * particle set is the whole state). Field names are the SF_* macros below; every field is
 * declared (field_decl) by the solver, the integrator or the scheme, created at set-up, and a
 * name nobody declared is an error (sv_field), never a new field. */
#ifndef CONSPH_SOLVER_SOLVER_INTERNAL_H
#define CONSPH_SOLVER_SOLVER_INTERNAL_H

#include "consph/io.h"
#include "consph/pass.h"
#include "consph/solver.h"

/* Field names. */
#define SF_U "u"           /* velocity, d */
#define SF_RHOF "rhof"     /* fluid density ϱ */
#define SF_P "p"           /* pressure */
#define SF_VOL "volume"    /* ω = 1/Σ W */
#define SF_ID "id"         /* index in the initial particle set (as a double, exact) */
#define SF_MASS "mass"     /* per-particle mass of a scheme that has one (else ρ_o Δs^d) */
#define SF_LATTICE "x_lat" /* L-RR-C: the lattice point of the slot, d */
/* the integrator's state (src/integrators/): the start of the step and the rates */
/* the positions at the last neighbour-list build (src/pass/nlist.c), checkpoint only */
#define SF_XB "x_build"
#define SF_X0 "x0"
#define SF_U0 "u0"
#define SF_Q0 "q0"
#define SF_AX "ax" /* dx/dt, d */
#define SF_AU "au" /* du/dt, d */
#define SF_AQ "aq" /* rate of the evolved scalar (ϱ, or p for pressure evolution) */
/* derivatives (kit) */
#define SF_BONET "bonet" /* B_i, d² */
#define SF_GRADP "gradp" /* ∇p (asym, bc), d */
#define SF_GRADU "gradu" /* G[a d + b] = ∂_b u_a (asym, bc), d² */
#define SF_DIVU "divu"   /* ∇·u (div, bc) */
#define SF_GRADQ "gradq" /* ∇ of the diffused scalar (ϱ or p), d */
#define SF_LAPU "lapu"   /* ∇²u, d */
#define SF_LAPQ "lapq"   /* ∇² of the diffused scalar */
#define SF_SHIFT "shift" /* δr of a shifting step, d */
/* output */
#define SF_UEX "u_exact"
#define SF_PEX "p_exact"
#define SF_VORT "vorticity"

/* ---- declared state (src/solver/state.c) ---- */
typedef enum field_shape {
    FIELD_SCALAR, /* 1 component */
    FIELD_VECTOR, /* d */
    FIELD_TENSOR, /* d × d, row-major: component a d + b */
    FIELD_CURL    /* the curl of a velocity: 1 in 2D (its z component), 3 in 3D */
} field_shape;

typedef enum field_role {
    FIELD_STATE,   /* what the scheme evolves or carries from step to step */
    FIELD_DERIVED, /* derivatives and sums a right-hand side leaves (read by diagnostics, the
                    * output, or the next stage) */
    FIELD_SCRATCH, /* written within every step before anything reads it (the integrator's
                    * copies, a right-hand side's own sums): never written to snapshots, and not
                    * carried by the re-sort at a step's start */
    FIELD_OUTPUT,  /* written from the state before each snapshot (consph_solver_output_fields)
                    * and read only there: not carried by the re-sort either */
    FIELD_STEP,    /* a scheme's word on a field that another list may declare: every step writes
                    * it for every particle before anything reads it (a value of the step's own
                    * right-hand side, read after the step by the diagnostics and the output):
                    * not carried by the re-sort */
    FIELD_GRADS    /* as FIELD_STEP in a step whose right-hand sides write it (∇u, ∇p: unless
                    * grads_skip); carried into the others, whose snapshots and checkpoints keep
                    * the values of the last step that wrote it (as the GPU's step keeps them) */
} field_role;

/* One field: its name (an SF_* macro), components, role and, when a snapshot carries it, the
 * array name there (docs/solver-files.md lists them); NULL: not in snapshots. A field may be
 * declared by more than one list (the solver's and a scheme's) with the same shape; the one
 * that names an output names it (two different names are an error at set-up). Lists end with
 * FIELD_END. */
typedef struct field_decl {
    const char *name;
    field_shape shape;
    field_role role;
    const char *output;
} field_decl;
/* clang-format off */
#define FIELD_END {NULL, FIELD_SCALAR, FIELD_STATE, NULL}
/* clang-format on */

/* The solver's own fields (identity, velocity, pressure, density, what the diagnostics and the
 * output read) and the integrator's (state at the start of the step, rates). */
extern const field_decl solver_fields[], integrator_fields[];
/* Each family's, at the end of its file. */
extern const field_decl negi_fields[], negi_remesh_fields[], wcsph_fields[], tv_fields[],
    tvf_fields[], delta_fields[];

/* Components of a shape in d dimensions. */
int field_ncomp(field_shape shape, int d);
/* Creates every declared field (zero) that the particles lack; CONSPH_EINVAL when two
 * declarations of a name disagree. */
int state_create(consph_solver *s);
/* 0 when every declaration of field `name` is FIELD_SCRATCH or FIELD_OUTPUT, or one is
 * FIELD_STEP (FIELD_GRADS with grads_skip unset), or it is the pressure that the step's first
 * closure writes from the density (the EOS, under an integrator starting from the last rates): its
 * values between two steps are never read, so a step's re-sort need not carry them. */
int state_carried(const consph_solver *s, const char *name);
/* Gives the system its neighbour list (skin of a moving scheme; resume: from a checkpoint). */
int solver_nlist_start(consph_solver *s, int resume);
/* The list's memory, builds and note into the summary (skin > 0 only). */
void solver_nlist_summary(const consph_solver *s, consph_run_summary *sum);
/* CONSPH_EINVAL naming the first field of the particles that nobody declared (a field created
 * past sv_field); with `drop`, such fields are removed instead (a checkpoint of an older run). */
int state_undeclared(consph_solver *s, int drop);
/* The arrays of a snapshot, in declaration order, into arr (CONSPH_MAX_FIELDS entries). */
int state_snapshot_arrays(const consph_solver *s, consph_vtu_array *arr, int *narr);

/* ---- the derivative kit: fused passes over the system (src/schemes/negi/kit.c) ---- */
typedef enum kit_lap {
    KIT_LAP_COUPLED,   /* coupled_bc, 001 Table 4 with Bonet (= s1_diff from G) */
    KIT_LAP_FATEHI_C,  /* Fatehi_c, 001 eq. 13 */
    KIT_LAP_KORZILIUS, /* Korzilius, 001 eqs. 14-15 with the fixes of docs/deviations.md */
    KIT_LAP_CLEARY     /* Cleary's, Bonet-corrected, as 001's authors run EWCSPH (kit.c),
                          per unit mass density: the rates multiply by ν ρ_o */
} kit_lap;

enum {
    KIT_GRADP = 1u << 0, /* ∇p */
    KIT_GRADU = 1u << 1, /* G = ∇u */
    KIT_DIVU = 1u << 2,  /* ∇·u */
    KIT_GRADQ = 1u << 3, /* ∇q of the scalar field named by kit_req.q */
    KIT_LAPU = 1u << 4,  /* ∇²u with kit_req.lap (needs G) */
    KIT_LAPQ = 1u << 5   /* ∇²q, coupled_bc (needs ∇q) */
};

typedef struct kit_req {
    unsigned want; /* KIT_* */
    kit_lap lap;   /* the viscous Laplacian */
    const char *q; /* SF_RHOF or SF_P: the scalar of KIT_GRADQ/KIT_LAPQ */
    double cond_max;
    /* 1: the field SF_BONET holds B_i of these positions, volumes and cond_max (a fixed
     * geometry's, from an earlier evaluation): pass 1 may apply it instead of summing the moment
     * and inverting it again, the same values */
    int bonet_kept;
} kit_req;

/* ω_i = 1/Σ_j W_ij into SF_VOL (one pass); adds pairs to *pairs. */
int kit_volumes(consph_sys *s, size_t *pairs);
/* The requested derivatives in at most two passes (gradients and divergence in the first,
 * Laplacians in the second); adds pairs to *pairs, passes to *passes. */
int kit_derivatives(consph_sys *s, const kit_req *rq, size_t *pairs, int *passes);
/* kit_volumes then kit_derivatives, chained on the neighbour list's cache where it serves them
 * (the same values); adds pairs to *pairs, passes (the volumes' too) to *passes. */
int kit_volumes_derivatives(consph_sys *s, const kit_req *rq, size_t *pairs, int *passes);
/* kit_volumes_derivatives, then the pass `then` with then_job on the same positions, chained
 * after them where they chain (its block's pairs read while still cached, and the chain the
 * state's last reader where the caller announced its passes with it), else after them: a pass
 * that reads the volumes (SF_VOL) at the neighbours and nothing else the kit writes, and writes
 * nothing the kit reads. Its pairs are not counted (in *pairs) nor its pass (in *passes). */
int kit_volumes_derivatives_then(consph_sys *s, const kit_req *rq, const consph_pass *then,
                                 void *then_job, size_t *pairs, int *passes);

/* ---- schemes ---- */
typedef struct scheme_def {
    const char *name;
    const char *summary; /* paper and equations */
    int moves;           /* particles are advected (Lagrangian, TV) */
    int evolve_p;        /* the evolved scalar is p (ϱ from eq. 31) instead of ϱ */
    consph_layout_kind layout;
    consph_eos_kind eos;
    const char *integrator;
    /* the set-up keeps each slot's lattice point (SF_LATTICE, for remeshing) */
    int needs_lattice;
    int passes_min; /* passes per stage the equations need at least */
    /* CONSPH_PARAM_ALPHA, CONSPH_PARAM_DELTA and CONSPH_PARAM_IPST when its rates use α or δ
     * or it shifts by IPST (the EOS follows from evolve_p and closure: consph_scheme_reads) */
    unsigned reads;
    /* Rates into SF_AX (when moves), SF_AU and SF_AQ at the current state. It writes no
     * position, no velocity and no evolved scalar (the step's start is saved after it), unless
     * rhs_writes_q says it writes the evolved scalar. */
    int (*rhs)(consph_solver *s);
    /* 1 where rhs writes the evolved scalar (tvf: its summation density is its q): the step's
     * start is then saved before it (consph_solver_step). */
    int rhs_writes_q;
    /* What a family's shared rhs reads to tell its schemes apart (001's family: the scheme's
     * negi_terms); NULL where each scheme has an rhs of its own. */
    const void *terms;
    /* After a full step (NULL: none). Moves particles only through consph_sys_update(s, 0)
     * (reg_move, reg_remesh_m4), so that the search it leaves is built from the positions it
     * leaves (the next step's re-sort reuses it: search_follows_drift). */
    int (*regularise)(consph_solver *s);
    /* After every stage, in place of 001's closure (p from ϱ by the EOS, or ϱ from p by
     * eq. 31 for evolve_p): a scheme whose density is a summation, or whose pressure is
     * evolved with its own relation, sets its state here (NULL: 001's). */
    void (*closure)(consph_solver *s);
    /* The advection velocity SF_AX from the current velocity and the last rates, for a drift
     * whose rates are weighted by c (c Δt-scaled: Δt/2 or Δt), called by the integrator after
     * each velocity update of a moving scheme (NULL: SF_AX as the right-hand side left it). A
     * scheme whose drift velocity is u plus a lagged correction (a transport velocity) says so
     * here, which also lets kick-drift-kick reuse the rates of the previous step. */
    void (*transport)(consph_solver *s, double c);
    /* The fields its rates, closure and regularisation use beyond the solver's and the
     * integrator's (a list at the end of the family's file). */
    const field_decl *fields;
} scheme_def;

/* The table of every scheme (src/schemes/registry.c, which also declares the rows: a scheme is
 * found by name, never by its row's symbol). */
const scheme_def *scheme_find(const char *name);
size_t scheme_count(void);

/* ---- problems: data ---- */
/* A problem is a row in its own file, src/problems/<name>.c, listed once in src/problems/problems.c
 * (its names list is generated from that list). The run has the problem's dimension; nx particles
 * span axis 0 and the spacing Δs = (hi[0] - lo[0])/nx is the same on every axis (round(L_a/Δs)
 * particles along axis a). */
typedef struct problem_def {
    const char *name;
    const char *summary;
    int dim;             /* 2 or 3 */
    double lo[3], hi[3]; /* the box [lo, hi) per axis (the first dim are used) */
    int periodic[3];     /* per axis */
    /* exact (or initial, at t = 0) velocity and pressure at x (u[2] = 0 in 2D) */
    void (*exact)(const consph_run_params *prm, double t, const double x[3], double u[3],
                  double *p);
    int has_exact; /* the exact solution holds for t > 0 (else errors are NaN: n/a) */
    /* defaults that consph_run_params_problem sets: final time, ν (< 0: U L/Re, L = hi[0] -
     * lo[0]) and c_o (0: 10 U) */
    double tf, nu, c0;
    int layout;          /* consph_layout_kind, or -1: the scheme's */
    int radial;          /* a vortex centred in the box: the run writes profile.csv, u_φ(r) */
    int vorticity_image; /* the run draws the final vorticity (vorticity.png) */
    /* --exact wc may take it: 2D, periodic in both axes, an exact solution, and initial data
     * smooth enough for the reference's 32² Fourier series (src/problems/wcref.c) */
    int wc_reference;
} problem_def;

const problem_def *problem_find(const char *name);
/* The problem's files in dir at the final time (problem_out.c): profile.csv, vorticity.*. */
int problem_outputs(consph_solver *s, const char *dir);

/* ---- the solver ---- */
/* The parts of the samples' time (consph_solver.sample_seconds), disjoint: the GPU's copy back
 * and the host's search on it, the validity checks, the diagnostics and the authors' measure
 * (each without the reference), and the weakly-compressible reference's time steps, its
 * evaluation at the particles and the rest of its side (for every caller). */
enum {
    SAMPLE_COPY,
    SAMPLE_SEARCH,
    SAMPLE_CHECKS,
    SAMPLE_DIAG,
    SAMPLE_AUTH,
    SAMPLE_WC_STEPS,
    SAMPLE_WC_EVAL,
    SAMPLE_WC_REST,
    SAMPLE_PARTS
};

struct consph_solver {
    consph_run_params prm;
    const scheme_def *scheme;
    const problem_def *prob;
    const struct integ_def *integ; /* the integrator's row (src/integrators/integrators.h) */
    double *integ_scratch;         /* the row's scratch arrays, dead between steps */
    /* ϱ and p of the step in progress, for the EOS of a block of particles (integ_state_of) */
    double *eos_rhof, *eos_p;
    consph_sys sys;
    int dim;
    double h, ds, nu, c0, mass, D; /* D = δ h c_o */
    consph_eos_kind eos;
    double t, dt, tf;
    long step, nsteps; /* nsteps: the step count to reach (0: run to tf) */
    double l1_u_acc, l1_p_acc;
    /* the time since the last sample of the diagnostics (a sum of the steps' Δt, so that with
     * log_every 1 it is each step's Δt exactly), and the Δt of the last step */
    double log_since, step_dt;
    /* the authors' measure: sums of the normalised errors at the output times reached, their
     * count, and the index of the next output time */
    double auth_u_acc, auth_p_acc;
    int auth_n, auth_next;
    double seconds;
    size_t pairs;
    int passes; /* passes of the last stage */
    long regs;
    int volumes_fixed; /* particles never move: ω computed once */
    /* volumes_fixed: the field SF_BONET holds B_i of the rates' pass 1 (cond_max 1e8) on the
     * neighbour list's build bonet_builds (a build is a new geometry: a migration, a re-sort);
     * 0 until the first such pass on the CPU, and again after the GPU ran the steps */
    int bonet_kept;
    size_t bonet_builds;
    int reuse_rates; /* pec/kdk: the rates left by the previous step are this step's first */
    /* ∇u and ∇p are read by snapshots and the end-of-run outputs only: a right-hand side may
     * skip them while grads_skip is set, which consph_solver_step does for a step that ends
     * neither the run nor at a multiple of grads_every (consph_run sets grads_lazy and the
     * snapshot cadence; left 0, every right-hand side computes them) */
    int grads_lazy, grads_skip;
    long grads_every;
    double chi0;
    /* the history for the log: HIST_COLS doubles per sample (solver_sample) */
    double *hist;
    size_t nhist, caphist;
    double *diag_buf; /* the per-particle terms of consph_solver_diag, 8 per particle */
    size_t diag_cap;
    char run_id[CONSPH_RUN_ID_LEN + 1]; /* new at set-up, kept by checkpoints */
    struct wcref *wc; /* --exact wc: the reference (src/problems/wcref.h), made when first used */
    /* --exact both: the eq. 26 sums and the authors' sums against the reference */
    double wcs_u_acc, wcs_p_acc, wcs_auth_u_acc, wcs_auth_p_acc;
    double *wc_buf; /* solver_wc_side's per-particle terms */
    size_t wc_cap;
    /* where the samples' time goes (SAMPLE_*), printed at the end with CONSPH_SAMPLE_SECONDS=1:
     * a diagnostic hook for the GPU's log samples, whose host work bounds a study there */
    double sample_seconds[SAMPLE_PARTS];
    long sample_count;
    struct gpu_run *gpu; /* --device gpu: the steps run there (src/gpu/); NULL: on the CPU */
    /* the GPU's log samples beside its steps (sampler.c); NULL until the first one */
    struct solver_sampler *sampler;
    struct par_solver *par; /* decomposed over MPI ranks (src/par/par_solver.h); NULL: serial */
    /* a rank's part of a checkpoint, restored to be cut (range.n > 0: consph_par_run_restart) */
    struct solver_range *part;
};

/* fn(s, arg) over the whole state: at once in a serial run; decomposed, on rank 0 over the
 * particles gathered in the serial order (the other ranks take its status and message). For
 * what reads every particle: diagnostics, checks, files. */
int solver_global(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg);
/* A rank's share of a decomposed set-up: the particles [lo, hi) of the n in the layout's (or
 * the given particles') order. made: those particles already made from the layout (a packed
 * layout's part read from the cache), which solver_create_cut takes over (leaving it empty)
 * instead of making them again; NULL: it makes them. */
typedef struct solver_range {
    size_t lo, hi, n;
    consph_particles *made;
} solver_range;
/* consph_solver_create_from with cut(s, arg, status) (NULL: none) run on the particles and
 * their initial fields, before the neighbour list and the initial rates: the MPI
 * decomposition's set-up (src/par/par_solver.c), so that only the rank's part gets them. cut
 * is called whatever this rank's status so far (a collective: a rank that failed alone takes
 * the others out of it), and returns the status of the cut. With a range (NULL: the whole
 * set), only those particles are made (a layout made by index, or given: all n or only the
 * range's), each with "id" its index among the n. */
int solver_create_cut(consph_solver **out, const consph_run_params *prm,
                      const consph_particles *given, const solver_range *range,
                      int (*cut)(consph_solver *s, void *arg, int status), void *arg);
/* consph_solver_restore of the particles [range->lo, range->hi) of a checkpoint's range->n
 * (NULL: all of them), before its cut: no neighbour list yet (the cut starts it). */
int solver_restore_range(consph_solver **out, const char *meta, const consph_particles *particles,
                         const double *history, size_t nhistory, const solver_range *range);
/* solver_restore_range of what a checkpoint read gave (meta, particles, history: freed here),
 * its error prefixed with the checkpoint's name. */
int solver_restore_read(consph_solver **s, const char *checkpoint, char *meta, consph_particles *p,
                        double *hist, size_t nh, const solver_range *range);

/* consph_run_nx_check against `memory` bytes (0: unknown) instead of this machine's. */
int run_nx_fits(int nx, int dim, double memory);
/* Per-particle loops of the integrator and the diagnostics run on the threads from this many
 * particles on (each particle is written by one iteration, so the bits do not depend on the
 * thread count). */
#define SOLVER_PARALLEL_MIN 4096
#define HIST_COLS 14 /* step t l1_u linf_u l1_p linf_p ke mx my mz ang ft_fmax max_divu dt */
/* Whether the history's last row is this step's (a sample of this instant was taken). */
static inline int solver_sampled_now(const consph_solver *s)
{
    return s->nhist && (long)s->hist[(s->nhist - 1) * HIST_COLS] == s->step;
}

/* Diagnostics (diag.c): a row of the history; x of particle i as the problems take it (every
 * coordinate of the run, 0 beyond); the authors' measure: output time k of a --tf run, the sample
 * at this instant, and the sample after a step when it ended on the next output time (`landed`:
 * the step was cut to end on it). */
int solver_hist_push(consph_solver *s, const consph_step_diag *g);
/* The diagnostics of this instant into the history and the eq. 26 sums (each sample weighted by
 * the time since the previous one, log_since); nothing when the history's last row is this
 * step's already. Called at t = 0, every log_every steps, at the last step and before each
 * snapshot. */
int solver_sample(consph_solver *s);
/* solver_sample handed to a host thread where a GPU run's samples overlap its steps (sampler.c:
 * the same history and sums), else solver_sample itself. */
typedef struct solver_sampler solver_sampler;
int solver_sample_overlapped(consph_solver *s);
/* Waits for the sample on that thread, if any, and takes back what it wrote; its status. Called
 * before anything reads the host's particles again or what a sample writes (the history, the
 * sums, the buffers, the reference). */
int solver_sample_join(consph_solver *s);
/* Ends the thread (at consph_solver_free). */
void solver_sampler_free(consph_solver *s);
/* Whether a decomposed solver's samples are taken on every rank from its owned particles, the
 * sums over the serial order and the maxima over the ranks (solver_sample, solver_auth_sample,
 * called on every rank), rather than on rank 0 over the gathered set: with the problem's exact
 * solution (--exact wc's reference is kept on rank 0). */
int solver_sample_owned(const consph_solver *s);
extern const char *const solver_sample_fields[]; /* what it reads (diag.c) */
/* m |u|²/2 of one particle, the one expression of the diagnostics and the checks (so that their
 * kinetic energies are the same bits). */
static inline double kinetic_energy_of(double m, double ux, double uy, double uz, int d)
{
    return 0.5 * m * (d == 3 ? ux * ux + uy * uy + uz * uz : ux * ux + uy * uy);
}
/* The first particle of the solver's own (local index; n when it owns none): 0 serially, the
 * first in the destination mask of a decomposed system, whose halo holds other ranks'
 * particles. A once-only test of a field ("not set yet") reads it there, not at local particle
 * 0, which may be a halo particle whose column no declared refresh brings. */
static inline size_t solver_first_own(const consph_solver *s)
{
    const size_t n = s->sys.p->n;
    const unsigned char *dest = s->sys.dest;
    size_t i = 0;
    if (dest)
        while (i < n && !dest[i]) ++i;
    return i;
}
/* The column of the kinetic energy's terms, one per particle, for solver_check_valid to write in
 * its sweep of the state and sum with consph_sum as consph_solver_diag sums its own (diag.c's
 * buffer, kept between calls); NULL with CONSPH_ENOMEM recorded. */
double *solver_ke_column(consph_solver *s);
void solver_position_of(const consph_particles *p, size_t i, double x[3]);
double solver_auth_time(const consph_solver *s, int k);
int solver_auth_sample(consph_solver *s);
int solver_auth_after_step(consph_solver *s, int landed);
/* solver_auth_after_step's bookkeeping alone (the next output time, which a --tf run's steps
 * land on): whether this step is one to sample. */
int solver_auth_advance(consph_solver *s, int landed);
int solver_auth_due(const consph_solver *s, int landed);
/* The reference the errors are taken against (diag.c): solver_exact_prepare makes --exact wc's
 * reference on first use and brings it to s->t; solver_exact then gives u and p at x and s->t
 * (the problem's exact solution, or the reference), safe on several threads. */
int solver_exact_prepare(consph_solver *s);
void solver_exact(const consph_solver *s, const double x[3], double u[3], double *p);
int solver_wc_side(consph_solver *s, double *eu, double *ep, double *nu, double *np);
/* Validity (validity.c), after every step: CONSPH_ENUMERIC naming the first non-finite value, or
 * the first bound of the weakly-compressible model the state is beyond (from the state and its
 * kinetic energy only: no exact solution). solver_check_valid checks both (it calls
 * solver_check_finite to name a non-finite value). */
int solver_check_finite(consph_solver *s);
int solver_check_valid(consph_solver *s);

/* Shared by the schemes: the declared field `name` of ncomp components; NULL with CONSPH_EINVAL
 * naming it and the scheme when it is not declared or has other components. */
double *sv_field(consph_solver *s, const char *name, int ncomp);
void solver_eos(consph_solver *s); /* p from ϱ, or ϱ from p (evolve_p) */
/* The exponent g of a power as a whole number when it is one in [0, 64], else -1: the EOS then
 * takes x^g by multiplication (eos_ipow), which differs from pow's at round-off only. */
static inline int eos_int_exponent(double g)
{
    return g >= 0.0 && g <= 64.0 && g == (double)(int)g ? (int)g : -1;
}
static inline double eos_ipow(double x, int n)
{
    double r = 1.0;
    for (; n; n >>= 1, x *= x)
        if (n & 1) r *= x;
    return r;
}
/* Taylor update of 001 eq. 22/29 after a shift dr (SF_SHIFT): u, the evolved scalar, from the
 * gradients the kit left (SF_GRADU, SF_GRADQ), then the EOS. */
void solver_taylor_update(consph_solver *s, const double *dr);
/* The quantities derived from s->prm (scheme, problem, h, Δs, c_o, ν, Δt, ...). */
int derive_solver(consph_solver *s);

#endif
