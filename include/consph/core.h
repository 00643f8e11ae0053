/* consph core: status codes and error messages, the simulation box, the particle set
 * (structure of arrays with named fields), deterministic reductions and timing. */
#ifndef CONSPH_CORE_H
#define CONSPH_CORE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define CONSPH_VERSION "0.1.0"
#define CONSPH_MAX_DIM 3

/* Every fallible library call returns one of these; the message is in consph_last_error(). */
typedef enum consph_status {
    CONSPH_OK = 0,
    CONSPH_EINVAL = 1,  /* a parameter is out of its allowed range or a name is unknown */
    CONSPH_ENOMEM = 2,  /* allocation failed */
    CONSPH_EIO = 3,     /* a file could not be read or written */
    CONSPH_EFORMAT = 4, /* a file's content is malformed */
    CONSPH_ENUMERIC = 5 /* a numerical failure: singular system, non-finite value */
} consph_status;

/* Records a printf-style message for the calling thread and returns `code`. */
int consph_fail(int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* The calling thread's last message ("" when none). */
const char *consph_last_error(void);
void consph_clear_error(void);

/* Allocation that never returns NULL for n > 0 without recording an error. Free with free(). */
void *consph_calloc(size_t count, size_t size);

/* An axis-aligned box [lo, hi) in `dim` dimensions; periodic[a] != 0 wraps axis a. */
typedef struct consph_box {
    int dim;
    double lo[CONSPH_MAX_DIM];
    double hi[CONSPH_MAX_DIM];
    int periodic[CONSPH_MAX_DIM];
} consph_box;

/* The unit box [0,1)^dim, periodic on every axis when `periodic` != 0. */
consph_box consph_box_unit(int dim, int periodic);
double consph_box_length(const consph_box *box, int axis);
double consph_box_volume(const consph_box *box);
int consph_box_check(const consph_box *box);

/* A named per-particle field of `ncomp` doubles per particle, stored component-major:
 * component c of particle i is data[c * cap + i]. */
#define CONSPH_FIELD_NAME_MAX 32
typedef struct consph_field {
    char name[CONSPH_FIELD_NAME_MAX];
    int ncomp;
    double *data;
} consph_field;

/* A particle set: positions as structure of arrays plus any number of named fields.
 * Positions live in x[0..dim-1]; axes past dim are NULL. */
#define CONSPH_MAX_FIELDS 64
typedef struct consph_particles {
    int dim;
    size_t n;
    size_t cap;
    double *x[CONSPH_MAX_DIM];
    consph_box box;
    double spacing; /* nominal inter-particle spacing Δs (0 when unknown) */
    int nfields;
    consph_field fields[CONSPH_MAX_FIELDS];
} consph_particles;

int consph_particles_init(consph_particles *p, int dim, size_t n, const consph_box *box);
void consph_particles_free(consph_particles *p);
/* Returns the field's data, creating it zero-filled if absent; NULL (with an error) on a
 * name clash with a different ncomp or when full. */
double *consph_particles_field(consph_particles *p, const char *name, int ncomp);
/* Returns the field or NULL when absent; never creates. */
const consph_field *consph_particles_find(const consph_particles *p, const char *name);
/* Deep copy of src into dst (initialised here). */
int consph_particles_copy(consph_particles *dst, const consph_particles *src);
/* Applies the permutation new[i] = old[perm[i]] to positions and every field. */
int consph_particles_permute(consph_particles *p, const size_t *perm);

/* Sum of a[0..n) that is independent of the number of threads: fixed-size blocks summed in
 * order, blocks combined pairwise in a fixed tree. */
double consph_sum(const double *a, size_t n);
/* The same with a stride (a[0], a[stride], ...). */
double consph_sum_strided(const double *a, size_t n, size_t stride);

/* Wall-clock seconds since an arbitrary origin. */
double consph_wtime(void);
/* Threads an OpenMP parallel region would use (1 without OpenMP).
 *
 * Thread count and a loaded machine: by default libgomp spins ~7 ms at every barrier before
 * sleeping, and when other processes keep the cores busy, the spinning threads take the time the
 * working ones need (2 threads on a loaded 2-core machine ran a study 4-5x slower than 1 thread);
 * sleeping at once (OMP_WAIT_POLICY=passive) makes every fork and join a futex wake-up, tens of
 * µs, which a solver step's many short regions feel (2 threads 1.23x one at nx 100). libgomp
 * reads OMP_WAIT_POLICY and GOMP_SPINCOUNT only when it is loaded, so a program cannot change
 * this once running: set GOMP_SPINCOUNT=2000 (~50 µs of spinning) in the environment that starts
 * it (the consph CLI and `import consph` do when neither variable is set), or use fewer
 * threads. */
int consph_num_threads(void);
/* Threads of the parallel regions that follow (n > 0; no effect without OpenMP). */
void consph_set_num_threads(int n);
/* Peak resident set size of this process in bytes (0 when unknown). */
size_t consph_peak_rss(void);

/* Deterministic 64-bit generator (splitmix64 seeding a xoshiro256**), same sequence on every
 * platform for a given seed. */
typedef struct consph_rng {
    uint64_t s[4];
} consph_rng;
void consph_rng_seed(consph_rng *r, uint64_t seed);
uint64_t consph_rng_next(consph_rng *r);
/* Uniform in [0, 1). */
double consph_rng_uniform(consph_rng *r);

#ifdef __cplusplus
}
#endif
#endif
