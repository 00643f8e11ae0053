/* consph over MPI ranks.
 *
 * Section 1, the world (src/par/world.c): which process this is among the ranks of one launch.
 * consph_par_init calls MPI_Init only when the process was started by an MPI launcher (mpirun,
 * srun, mpiexec: OMPI_COMM_WORLD_SIZE, PMIX_RANK or PMI_SIZE in the environment); a process run
 * on its own never initialises MPI and is rank 0 of 1, as is every process of a build without
 * MPI (CONSPH_HAVE_MPI undefined). Every function below is then a no-op that returns what one
 * rank would, so callers need no #ifdef.
 *
 * The collective calls (barrier, agree, bcast, sum, max) must be made by every rank in the same
 * order; they go through a communicator of their own (a duplicate of MPI_COMM_WORLD), so they
 * never match messages of the solver's decomposition. */
#ifndef CONSPH_PAR_H
#define CONSPH_PAR_H

#include "consph/solver.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Initialises MPI iff launched by an MPI launcher; idempotent (a second call does nothing).
 * argc/argv may be NULL. Returns CONSPH_OK; CONSPH_EIO when MPI_Init fails; CONSPH_EINVAL in a
 * build without MPI started by a launcher on more than one rank (message set). */
int consph_par_init(int *argc, char ***argv);
/* This process's rank, 0 when MPI is not running. */
int consph_par_rank(void);
/* The number of ranks, 1 when MPI is not running. */
int consph_par_size(void);
/* 1 when this build has MPI (CONSPH_HAVE_MPI), else 0. */
int consph_par_available(void);
/* Finalises MPI if consph_par_init initialised it; idempotent. */
void consph_par_finalize(void);

/* Waits for every rank. */
void consph_par_barrier(void);
/* One status for all ranks: every rank passes its own; each gets back the status of the lowest
 * rank whose status is not CONSPH_OK (CONSPH_OK when none), with that rank's consph_last_error()
 * message set on every rank, so that rank 0 can report a failure that happened elsewhere. */
int consph_par_agree(int status);
/* Rank 0's value of v, on every rank (an exit status decided on rank 0). */
int consph_par_bcast_int(int v);
/* The sum and the maximum of v over the ranks, on every rank. */
long consph_par_sum_long(long v);
int consph_par_max_int(int v);
/* Sends the standard output and error of every rank but 0 to /dev/null, so that a message
 * every rank would print is printed once (the CLI's policy under MPI). */
void consph_par_quiet_others(void);

/* Section 2: */
/* ---- the solver decomposed over the ranks (src/par/par_solver.c) ----
 *
 * consph_par_solver_decompose cuts a solver that every rank of MPI_COMM_WORLD made the same
 * way (consph_solver_create with the same parameters, or consph_run_restart of the same
 * checkpoint) into boxes of the search's cells, one per rank (pieces along every axis, the
 * fewest halo cells; slabs along the last axis on a tie), each with a halo of the neighbouring
 * boxes' particles. From then on consph_solver_step and consph_run
 * run decomposed and give the serial run's snapshots, log, summary and checkpoints bit for bit
 * (timings aside); only rank 0 writes files and its summary is the run's (docs/mpi.md). MPI
 * must be initialised; on one rank, or built without MPI, it changes nothing (CONSPH_OK).
 * CONSPH_EINVAL (the same message on every rank: print it on rank 0) for a launch the
 * decomposition cannot serve: a rank count the cells cannot be cut into, a neighbour list with a
 * skin, remeshing (l-rr-c). */
int consph_par_solver_decompose(consph_solver *s);
/* consph_solver_create_from (given NULL: consph_solver_create) decomposed from the start, for
 * runs too large for every rank to hold the whole solver or the whole set: rank k of K makes
 * only the particles [N k/K, N (k+1)/K) of the layout's order (lattice, random, quasi-random)
 * or of `given` (which may hold all N or only that range) with their initial fields, the ranks
 * agree (consph_par_agree: a rank that failed before passes its status to the others, which
 * fail with it), the decomposition cuts them, and the neighbour list, the initial rates and the
 * first sample are made decomposed, so a rank's peak memory is its part's (a packed layout,
 * l-rr-c and more ranks than particles: every rank makes the whole set first, as before). *joined
 * (may be NULL) is set to 1 once this rank has joined the agreement. The run is the serial one bit
 * for bit, as after consph_par_solver_decompose. On one rank, or built without MPI:
 * consph_solver_create_from. */
int consph_par_solver_create(consph_solver **out, const consph_run_params *prm,
                             const consph_particles *given, int *joined);
/* Given particles read (and checked) on rank 0 only, shared for consph_par_solver_create:
 * collective; rank 0 passes the whole set in *given (positions and the optional fields "u",
 * "p"; prm already set by consph_run_params_particles), the others a zeroed set and the same
 * prm otherwise. Every rank ends with its range [N k/K, N (k+1)/K) of the particles in *given
 * (rank 0's whole set freed) and prm's particle count set as rank 0's; where the set-up makes
 * the whole set on every rank (more ranks than particles, l-rr-c) every rank gets the whole
 * set. On one rank, or built without MPI: nothing. */
int consph_par_given_share(consph_run_params *prm, consph_particles *given);

/* consph_run_restart for a decomposed run: each of K ranks reads only its part of the
 * checkpoint's particles (consph_checkpoint_read_part: 1/K of them in the stored order, every
 * field) and restores a solver of them, which consph_par_solver_decompose, called next as after
 * consph_run_restart (once the ranks agree), cuts as it cuts a whole one: the run is the same bit
 * for bit, for a checkpoint written on any number of ranks. Until then the solver holds a part
 * only: run nothing on it. On one rank, or built without MPI: consph_run_restart. */
int consph_par_run_restart(consph_solver **s, const char *checkpoint);

/* Communication of a decomposed solver so far, this rank: bytes sent (halo refresh, migration,
 * gathers to rank 0) and seconds spent in MPI calls. Zero for a serial solver. */
void consph_par_solver_comm(const consph_solver *s, double *bytes, double *seconds);

#ifdef __cplusplus
}
#endif

#endif
