/* The solver decomposed over MPI ranks (par_solver.c): the hooks consph_solver_step and the run
 * call when a solver has been cut by consph_par_solver_decompose (s->par != NULL). */
#ifndef CONSPH_PAR_PAR_SOLVER_H
#define CONSPH_PAR_PAR_SOLVER_H

#include "io/source_internal.h"
#include "solver/solver_internal.h"

typedef struct par_solver par_solver;

/* In place of the serial re-sort at a step's start: particles handed to the ranks that now own
 * their cells, re-sorted into the serial order, the boxes re-cut by each particle's work (the
 * pairs it visited, else its cell's candidates, else one), the halo rebuilt. */
int par_step_begin(consph_solver *s);
/* After the step's local work: `status` agreed over the ranks, and the guard that no particle
 * moved far enough in the step to have needed a halo it did not have. */
int par_step_end(consph_solver *s, int status);
/* solver_global's decomposed case. */
int par_global(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg);
/* The same with rank 0's particles holding their positions and only the fields named in
 * `only` (NULL-terminated; NULL: every field): what fn reads, for what runs at every step. */
int par_global_some(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg,
                    const char *const *only);
/* Rank 0 runs fn (a file's writer) with its own part in place and s->pairs the run's count,
 * while the other ranks serve the arrays it loads through par_stream_source, one at a time;
 * fn's status and message to every rank. Without par_stream_source nothing is gathered. */
int par_stream(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg);
/* In par_stream's fn on rank 0: *view gets the whole set's shape (its dimension, box, spacing,
 * fields, the particle count; no values) and src the loader that gathers one of its arrays in
 * the serial order into one buffer and points the view at it (io/source_internal.h), for
 * io_write_vtu_source and io_checkpoint_write_source. */
int par_stream_source(consph_solver *s, const consph_particles **view, io_array_source *src);
/* Whether the history lacks this step's row (rank 0's answer on every rank): a file written
 * now samples the diagnostics first. */
int par_sample_due(consph_solver *s);
/* The verdict of the checks after a step (solver_check_finite, solver_check_valid) without
 * gathering the particles: *clean when every owned value is finite and the state within the
 * CONSPH_VALID_* bounds, the kinetic energy summed as consph_sum over the serial order; the
 * same on every rank. When not clean, the serial checks on rank 0 name the particle. */
int par_checks_clean(consph_solver *s, int *clean);
/* This rank's owned particles (their local indices, ascending in the serial order: NULL for a
 * serial solver, whose particles are all its own) and how many the ranks own in all. */
const size_t *par_owned(const consph_solver *s, size_t *nown, size_t *nglobal);
/* consph_sum over the serial order of each of c columns, column k at w + k nown with one value
 * per owned particle in par_owned's order, into out[c], the same bits on every rank (one
 * gather of every column's partial sums, one broadcast). */
int par_owned_sums(consph_solver *s, const double *w, int c, double *out);
/* v[c] := the maximum of each over the ranks, on every rank (exact, in any order). */
int par_owned_max(consph_solver *s, double *v, int c);
/* Rank 0's history of the diagnostics and the sums of its samples to every rank: after a sample
 * made decomposed at the set-up (the checks read its first row, the initial state, on every
 * rank; the later samples are taken on every rank: solver_sample_owned). */
int par_share_history(consph_solver *s);
/* The particles this rank held when it was cut (its share of the set-up; a serial solver's
 * count): for the tests of the set-up's memory. */
size_t par_setup_made(const consph_solver *s);
/* This rank (0 for a serial solver). */
int par_rank(const consph_solver *s);
void par_solver_free(par_solver *ps);
/* For the tests: the next decompositions cut k[a] pieces along axis a (NULL: chosen for the
 * fewest halo cells); a launch whose rank count is not their product is refused. */
void par_force_boxes(const int *k);
/* What weighed the particles at the last cut: 0 their count, 1 the pairs each visited, 2 the
 * candidates of its cell's walk (0 for a serial solver). */
int par_cut_weights(const consph_solver *s);
/* The boxes of the cut (k[a] pieces along axis a), the search's cells along each axis and the
 * halo's width in cells (bench/bench_par prints them for the extrapolation in bench/mpi.sh);
 * returns the dimension, 0 for a serial solver (nothing written). */
int par_geometry(const consph_solver *s, int *k, long long *nc, long long *width);
/* For the tests: nonzero cuts the boxes by particle counts, as before the pairs weighed them. */
void par_force_count_cut(int on);
/* For the tests: the gathers to rank 0 in messages of at most `bytes` (0: 4 MiB), so that
 * small runs send a rank's part in several. */
void par_force_gather_bytes(size_t bytes);
/* For the tests: how many gathers of every field to rank 0 this process took part in. */
long par_whole_gathers(void);

#endif
