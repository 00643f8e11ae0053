/* The particles' permutation with buffers its caller keeps between calls (a re-sort every step:
 * fresh buffers of hundreds of kB at each one come back from the kernel as zeroed pages). */
#ifndef CONSPH_CORE_PARTICLES_INTERNAL_H
#define CONSPH_CORE_PARTICLES_INTERNAL_H

#include "consph/core.h"

typedef struct particles_permute_buf {
    size_t *run; /* the runs of moved slots */
    size_t run_cap;
    double *tmp; /* the moved values of a group of arrays */
    size_t tmp_cap;
} particles_permute_buf;

/* consph_particles_permute, its buffers taken from b and grown there as needed. */
int particles_permute_buf_run(consph_particles *p, const size_t *perm, particles_permute_buf *b);
void particles_permute_buf_free(particles_permute_buf *b);

#endif
