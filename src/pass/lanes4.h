/* Four lanes of doubles for the group visits (src/pass/group.h: up to four particles of a cell,
 * each lane summing in its own neighbour order), with GCC's and clang's vector extensions;
 * CONSPH_LANES4 is defined where they exist, and other compilers run the per-particle visits. */
#ifndef CONSPH_PASS_LANES4_H
#define CONSPH_PASS_LANES4_H

#if defined(__GNUC__)
#define CONSPH_LANES4 1
typedef double lane4 __attribute__((vector_size(4 * sizeof(double))));
typedef long long lane4i __attribute__((vector_size(4 * sizeof(double))));
/* lane4 at an address aligned for a double only */
typedef double lane4u __attribute__((vector_size(4 * sizeof(double)), aligned(sizeof(double))));
/* m ? a : b per lane (m: all bits set or none); a macro, since a function returning a vector
 * would have a different ABI in a clone without AVX */
#define LANE4_SEL(m, a, b) ((lane4)(((m) & (lane4i)(a)) | (~(m) & (lane4i)(b))))
#endif

#endif
