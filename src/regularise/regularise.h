/* Particle regularisation of the Lagrangian schemes of 001: iterative particle shifting (IPST,
 * Huang et al., 001 eqs. 19-21), the non-iterative shifting of Sun et al. (δ+-SPH; 001's L-PST-C
 * and TV-C) and remeshing to the lattice with M4 (001 eqs. 32-33, L-RR-C).
 *
 * Every function runs on a system made by consph_sys_init whose particles carry the field
 * "volume" (the numerical volume ω used in the sums, refreshed by the caller before the call
 * unless the function says otherwise). Periodic axes wrap. None of them re-sorts the particles:
 * the caller re-sorts at the start of a time step only, so arrays it holds in particle order
 * (gradients for the Taylor update of 001 eq. 22) stay valid across the call. Results do not
 * depend on the thread count. */
#ifndef CONSPH_REGULARISE_H
#define CONSPH_REGULARISE_H

#include "consph/pass.h"
#include "consph/solver.h"

/* ---- moving particles ---- */

/* x_i += dr_i (dr component-major with stride p->cap, d components), wrapping periodic axes into
 * the box, then rebuilds the search (consph_sys_update(s, 0)). CONSPH_ENUMERIC naming the
 * particle when a position becomes non-finite or leaves a non-periodic box. */
int reg_move(consph_sys *s, const double *dr);

/* ---- IPST (001 eqs. 19-21) ---- */
typedef struct reg_ipst_params {
    double h;     /* smoothing length */
    double chi0;  /* χ_o: h^d Σ_j W_ij on the unperturbed lattice (reg_chi0) */
    double tol;   /* ε of eq. 21 */
    int max_iter; /* at most this many shifts (001: 10) */
    int min_iter; /* at least this many shifts before eq. 21 is tested (0: tested before the
                     first; 001's authors: 1, PySPH's iterated group with min_iterations=1) */
} reg_ipst_params;

typedef struct reg_ipst_report {
    int iterations;   /* shifts applied */
    double chi_err;   /* |max χ - χ_o| after the last shift */
    double max_shift; /* largest |total displacement| of a particle, in units of h */
    double chi_max;   /* max_i χ_i after the last shift */
} reg_ipst_report;

/* 1 when IPST runs after the step from t_prev to t (the step-th step, counted from 1), else 0.
 * period_dt <= 0: after steps 1, every + 1, 2 every + 1, ... (001's authors shift in PySPH's
 * post-step callback when its step counter, not yet incremented, is a multiple of every:
 * tsph_with_pst.py, post_step_ipst). period_dt > 0: the same schedule on a reference step
 * period_dt, in time: after each step whose interval (t_prev, t] holds one of the times
 * period_dt + m every period_dt (m = 0, 1, ...), so runs of any Δt shift at the same times
 * (once per step at most: a Δt above every period_dt shifts every step). every <= 0: never. */
int reg_ipst_due(long step, double t_prev, double t, int every, double period_dt);

/* χ_o for the kernel on the unperturbed lattice of spacing ds in the kernel's dimension:
 * h^d Σ_j W(|x_j|) over lattice points (1.4399190 for quintic, h = 1.2 ds, 2D:
 * docs/reference-values.md). */
double reg_chi0(const consph_kernel *k, double ds);

/* Shifts the particles by eq. 19 (away from crowded neighbours) until eq. 21 holds or max_iter
 * shifts were made, testing eq. 21 before each shift once min_iter shifts were made (with
 * min_iter 0 a set that meets it is not moved),
 * recomputing the volumes ω = 1/Σ_j W_ij (written into "volume") at every iteration, and adds
 * the total displacement of each particle to dr_total (d × cap, zeroed by the caller). Refuses a
 * system with a destination mask. */
int reg_ipst(consph_sys *s, const reg_ipst_params *prm, double *dr_total, reg_ipst_report *rep);
/* Iterations whose volumes and shift ran chained on the system's pair cache (a system with a
 * neighbour list, consph_sys_nlist: the same values as one pass after the other); for tests. */
extern unsigned long reg_ipst_chains;
/* 1 (the default): the chained iterations sum four particles' volumes and shifts at once, lane
 * by lane (the per-particle visits' values bit for bit); 0: the per-particle visits. For
 * tests. */
extern int reg_ipst_groups;

/* ---- non-iterative shifting of Sun et al. (δ+-SPH) ---- */
typedef struct reg_pst_params {
    double h, ds;     /* smoothing length and initial spacing Δs */
    double cfl;       /* CFL number of the run's time step rule */
    double mach;      /* U_max / c_o */
    double R, n;      /* the anti-clumping term (Sun et al.: 0.2 and 4) */
    double max_shift; /* cap on |δr| in units of h: a longer δr is shortened to it, keeping its
                         direction (<= 0: none; the paper's value is open, docs/schemes.md) */
} reg_pst_params;

/* δr_i = -cfl·mach·(2h)² Σ_j [1 + R (W_ij/W(ds))^n] ∇W_ij V_j of Sun et al. into dr (d × cap),
 * V_j from the field "volume"; 0 for particles outside a destination mask. Moves nothing. */
int reg_pst_shift(const consph_sys *s, const reg_pst_params *prm, double *dr);
/* reg_pst_shift's pass, for a caller that runs it itself (chained after the passes that make
 * the volumes: kit_volumes_derivatives_then): checks prm, zeroes dr and fills job and pass;
 * running pass with job then gives reg_pst_shift's dr. */
typedef struct reg_pst_job {
    double coef;    /* -CFL·Ma·(2h)² */
    double inv_wds; /* 1/W(Δs) */
    double R, n;
    double cap_len; /* largest |δr|, +inf for none */
    const double *vol;
    double *dr;
    size_t cap;
    int dim;
} reg_pst_job;
int reg_pst_pass(const consph_sys *s, const reg_pst_params *prm, double *dr, reg_pst_job *job,
                 consph_pass *pass);

/* The shifting velocity δu = δr/Δt of Sun et al. (δr of reg_pst_shift with R = 0.2, n = 4 and
 * CFL·Ma·(2h)² = 4ΔtUh, no cap; docs/schemes.md) into the solver's field SF_SHIFT at the current
 * positions and volumes; counts its pass in s->passes. In shift_velocity.c (δ+-SPH). */
int solver_shift_velocity(consph_solver *s, double **du);
/* The same for 001's TV-C as its authors compute it, δu = -2hU Σ_j (1 + 0.24 (W_ij/W(Δs))^4)
 * ∇W_ij V_j (no cap; docs/schemes.md, "Shifting constants"). */
int solver_shift_velocity_tvc(consph_solver *s, double **du);
/* solver_shift_velocity_tvc in two halves around its pass, for a caller that runs the pass
 * itself (TV-C's rates, chained after the kit's passes): the field *du and the pass; then, once
 * the pass has run, δr turned into δu (and the pass counted). */
int solver_shift_velocity_tvc_pass(consph_solver *s, double **du, reg_pst_job *job,
                                   consph_pass *pass);
void solver_shift_velocity_tvc_finish(consph_solver *s, double *du);

/* ---- remeshing (001 eqs. 32-33) ---- */

/* Remeshes in place: interpolates `nf` named fields of the particles of `s` (each with its own
 * number of components) at the lattice points `lattice` (d × cap, one point per particle slot,
 * spacing ds) with the normalised M4 sum of eq. 33, q per axis = |x_a|/ds (tensor product,
 * not 001's radial form: docs/deviations.md), then puts every particle on its lattice point with
 * the interpolated values and rebuilds the search. A lattice point whose M4 weights sum to 0 (no
 * particle within reach) keeps the values of the particle in its slot and is counted in *orphans
 * (may be NULL). Refuses a system with a destination mask, as reg_ipst does. */
int reg_remesh_m4(consph_sys *s, const double *lattice, double ds, const char *const *fields,
                  int nf, size_t *orphans);

#endif
