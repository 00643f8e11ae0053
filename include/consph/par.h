/* consph par: running over MPI ranks.
 *
 * (The MPI world, consph_par_init/rank/size/finalize, is declared in its own section.) */
#ifndef CONSPH_PAR_H
#define CONSPH_PAR_H

#include "consph/solver.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- the solver decomposed over the ranks (src/par/par_solver.c) ----
 *
 * consph_par_solver_decompose cuts a solver that every rank of MPI_COMM_WORLD made the same
 * way (consph_solver_create with the same parameters, or consph_run_restart of the same
 * checkpoint) into slabs of the search's cells along the last axis, one per rank, each with a
 * halo of the neighbouring slabs' particles. From then on consph_solver_step and consph_run
 * run decomposed and give the serial run's snapshots, log, summary and checkpoints bit for bit
 * (timings aside); only rank 0 writes files and its summary is the run's (docs/mpi.md). MPI
 * must be initialised; on one rank, or built without MPI, it changes nothing (CONSPH_OK).
 * CONSPH_EINVAL (the same message on every rank: print it on rank 0) for a launch the
 * decomposition cannot serve: more ranks than slabs of cells, a neighbour list with a skin,
 * remeshing (l-rr-c). */
int consph_par_solver_decompose(consph_solver *s);

/* Communication of a decomposed solver so far, this rank: bytes sent (halo refresh, migration,
 * gathers to rank 0) and seconds spent in MPI calls. Zero for a serial solver. */
void consph_par_solver_comm(const consph_solver *s, double *bytes, double *seconds);

#ifdef __cplusplus
}
#endif

#endif
