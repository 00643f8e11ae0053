/* Shared test fixture: particle layouts generated on one thread. The layout is input, not
 * under test, and the packing's many short parallel regions crawl when the machine is
 * oversubscribed (as under parallel CTest). */
#ifndef CONSPH_TESTS_LAYOUT_FIXTURE_H
#define CONSPH_TESTS_LAYOUT_FIXTURE_H

#ifdef _OPENMP
#include <omp.h>
#endif

#include "consph/layout.h"

static inline int generate_layout(const consph_layout_params *lp, consph_particles *p)
{
#ifdef _OPENMP
    int saved = omp_get_max_threads();
    omp_set_num_threads(1);
#endif
    int st = consph_layout_generate(lp, p, NULL);
#ifdef _OPENMP
    omp_set_num_threads(saved);
#endif
    return st;
}

#endif
