/* The MPI world (include/consph/par.h, section 1): MPI only when a launcher started the process,
 * one rank otherwise; the collective helpers the CLI and the studies use. */
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "consph/core.h"
#include "consph/par.h"
#include "pass/nlist.h"

#ifdef CONSPH_HAVE_MPI
#include <mpi.h>

static int world_inited;    /* MPI_Init was called by consph_par_init */
static MPI_Comm world_comm; /* the helpers' own duplicate of MPI_COMM_WORLD */

/* A launcher (OpenMPI's mpirun, PMIx or PMI-1/2 ones such as srun and MPICH's mpiexec) leaves
 * these in the environment of every process it starts; MPI_Init in a process started by hand
 * would make it a singleton that still spawns OpenMPI's runtime, slow and needless. */
static int launched_by_mpi(void)
{
    static const char *const vars[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE"};
    for (size_t k = 0; k < sizeof vars / sizeof vars[0]; ++k)
        if (getenv(vars[k])) return 1;
    return 0;
}

static int running(void)
{
    int fin = 0;
    if (!world_inited) return 0;
    MPI_Finalized(&fin);
    return !fin;
}

/* Waits for a non-blocking collective asleep: OpenMPI's blocking collectives poll at full speed,
 * so a rank that waits (for the others' rows, for rank 0's report) would take a core from the
 * ranks still working when ranks share cores. Polls from 50 µs up to every 10 ms. */
static void wait_asleep(MPI_Request *req)
{
    long ns = 50000;
    for (;;) {
        int done = 0;
        MPI_Test(req, &done, MPI_STATUS_IGNORE);
        if (done) return;
        const struct timespec ts = {0, ns};
        nanosleep(&ts, NULL);
        if (ns < 10000000) ns *= 2;
    }
}

/* The ranks on this machine share its memory: the pair cache's default budget divides it. */
static void count_node_processes(void)
{
    MPI_Comm node;
    int count = 1;
    if (MPI_Comm_split_type(world_comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node) ==
        MPI_SUCCESS) {
        MPI_Comm_size(node, &count);
        MPI_Comm_free(&node);
    }
    nlist_node_processes(count);
}

int consph_par_init(int *argc, char ***argv)
{
    int already = 0, fin = 0;
    MPI_Finalized(&fin);
    if (fin) return CONSPH_OK; /* once finalised, MPI cannot start again: one rank from here */
    MPI_Initialized(&already);
    if (already || !launched_by_mpi()) {
        if (already && !world_inited) {
            /* An application that initialised MPI itself: join its world. */
            MPI_Comm_dup(MPI_COMM_WORLD, &world_comm);
            world_inited = 2;
            count_node_processes();
        }
        return CONSPH_OK;
    }
    int provided = 0;
    /* Only the main thread calls MPI; OpenMP threads compute between the calls. */
    if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
        return consph_fail(CONSPH_EIO, "MPI_Init failed");
    MPI_Comm_dup(MPI_COMM_WORLD, &world_comm);
    world_inited = 1;
    count_node_processes();
    return CONSPH_OK;
}

int consph_par_rank(void)
{
    int r = 0;
    if (running()) MPI_Comm_rank(world_comm, &r);
    return r;
}

int consph_par_size(void)
{
    int n = 1;
    if (running()) MPI_Comm_size(world_comm, &n);
    return n;
}

int consph_par_available(void)
{
    return 1;
}

void consph_par_finalize(void)
{
    if (!running()) return;
    MPI_Comm_free(&world_comm);
    /* MPI initialised by the application is finalised by it. */
    if (world_inited == 1) MPI_Finalize();
    world_inited = 0;
}

void consph_par_barrier(void)
{
    if (!running()) return;
    MPI_Request req;
    MPI_Ibarrier(world_comm, &req);
    wait_asleep(&req);
}

static void allreduce_int(int *in, int *out, MPI_Op op)
{
    MPI_Request req;
    MPI_Iallreduce(in, out, 1, MPI_INT, op, world_comm, &req);
    wait_asleep(&req);
}

static void bcast(void *buf, int count, MPI_Datatype type, int root)
{
    MPI_Request req;
    MPI_Ibcast(buf, count, type, root, world_comm, &req);
    wait_asleep(&req);
}

int consph_par_agree(int status)
{
    if (consph_par_size() < 2) return status;
    int rank = consph_par_rank(), size = consph_par_size();
    int mine = status != CONSPH_OK ? rank : size, first = size;
    allreduce_int(&mine, &first, MPI_MIN);
    if (first == size) return CONSPH_OK;
    char msg[1024];
    snprintf(msg, sizeof msg, "%s", rank == first ? consph_last_error() : "");
    bcast(&status, 1, MPI_INT, first);
    bcast(msg, (int)sizeof msg, MPI_CHAR, first);
    return consph_fail(status, "%s", msg);
}

int consph_par_bcast_int(int v)
{
    if (running()) bcast(&v, 1, MPI_INT, 0);
    return v;
}

long consph_par_sum_long(long v)
{
    long s = v;
    if (running()) {
        MPI_Request req;
        MPI_Iallreduce(&v, &s, 1, MPI_LONG, MPI_SUM, world_comm, &req);
        wait_asleep(&req);
    }
    return s;
}

int consph_par_max_int(int v)
{
    int m = v;
    if (running()) allreduce_int(&v, &m, MPI_MAX);
    return m;
}

#else /* one rank */

/* The value of the first of `vars` set in the environment, else -1. */
static long launcher_value(const char *const *vars, int n)
{
    for (int k = 0; k < n; ++k) {
        const char *v = getenv(vars[k]);
        if (v && *v) return strtol(v, NULL, 10);
    }
    return -1;
}

int consph_par_init(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    /* Started by mpirun on K > 1 ranks, a build without MPI would run K copies of one serial
     * command, writing the same files. */
    static const char *const size_vars[] = {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"};
    static const char *const rank_vars[] = {"OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK"};
    const long size = launcher_value(size_vars, 2), rank = launcher_value(rank_vars, 3);
    if (size > 1 || rank > 0)
        return consph_fail(CONSPH_EINVAL,
                           "launched by an MPI launcher on %ld ranks, but this consph was built "
                           "without MPI (CONSPH_MPI, docs/mpi.md); run it without mpirun",
                           size > 1 ? size : rank + 1);
    return CONSPH_OK;
}
int consph_par_rank(void)
{
    return 0;
}
int consph_par_size(void)
{
    return 1;
}
int consph_par_available(void)
{
    return 0;
}
void consph_par_finalize(void) {}
void consph_par_barrier(void) {}
int consph_par_agree(int status)
{
    return status;
}
int consph_par_bcast_int(int v)
{
    return v;
}
long consph_par_sum_long(long v)
{
    return v;
}
int consph_par_max_int(int v)
{
    return v;
}

#endif

void consph_par_quiet_others(void)
{
    if (consph_par_rank() == 0) return;
    fflush(stdout);
    fflush(stderr);
    int fd = open("/dev/null", O_WRONLY);
    if (fd < 0) return;
    dup2(fd, STDOUT_FILENO);
    dup2(fd, STDERR_FILENO);
    close(fd);
}
