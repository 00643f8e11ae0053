/* Four lanes of doubles for the group visits (src/pass/group.h: up to four particles of a cell,
 * each lane summing in its own neighbour order), with GCC's and clang's vector extensions;
 * CONSPH_LANES4 is defined where they exist, and other compilers run the per-particle visits. */
#ifndef CONSPH_PASS_LANES4_H
#define CONSPH_PASS_LANES4_H

#include <stddef.h>

#if defined(__GNUC__)
#define CONSPH_LANES4 1
typedef double lane4 __attribute__((vector_size(4 * sizeof(double))));
typedef long long lane4i __attribute__((vector_size(4 * sizeof(double))));
/* lane4 at an address aligned for a double only */
typedef double lane4u __attribute__((vector_size(4 * sizeof(double)), aligned(sizeof(double))));
/* m ? a : b per lane (m: all bits set or none); a macro, since a function returning a vector
 * would have a different ABI in a clone without AVX */
#define LANE4_SEL(m, a, b) ((lane4)(((m) & (lane4i)(a)) | (~(m) & (lane4i)(b))))
/* |x| per lane: the sign bit cleared, as fabs clears it */
#define LANE4_ABS(x)                                                                               \
    ((lane4)((lane4i)(x) & (lane4i){0x7fffffffffffffffLL, 0x7fffffffffffffffLL,                    \
                                    0x7fffffffffffffffLL, 0x7fffffffffffffffLL}))
/* a lane shuffle of two lane4 by constant indices (0-3 from a, 4-7 from b) */
#if defined(__clang__)
#define LANE4_SHUF(a, b, i0, i1, i2, i3) __builtin_shufflevector(a, b, i0, i1, i2, i3)
#else
#define LANE4_SHUF(a, b, i0, i1, i2, i3) __builtin_shuffle(a, b, (lane4i){i0, i1, i2, i3})
#endif
/* The 4×4 transpose of the rows a0..a3, vectors of type T (lane4, or lane4i for other 8-byte
 * words: a shuffle moves bits, whatever they mean), into the columns f[0..3]. */
#define LANE4_TRANSPOSE(T, a0, a1, a2, a3, f)                                                      \
    do {                                                                                           \
        const T t0_ = LANE4_SHUF(a0, a1, 0, 4, 2, 6), t1_ = LANE4_SHUF(a0, a1, 1, 5, 3, 7);        \
        const T t2_ = LANE4_SHUF(a2, a3, 0, 4, 2, 6), t3_ = LANE4_SHUF(a2, a3, 1, 5, 3, 7);        \
        (f)[0] = LANE4_SHUF(t0_, t2_, 0, 1, 4, 5);                                                 \
        (f)[1] = LANE4_SHUF(t1_, t3_, 0, 1, 4, 5);                                                 \
        (f)[2] = LANE4_SHUF(t0_, t2_, 2, 3, 6, 7);                                                 \
        (f)[3] = LANE4_SHUF(t1_, t3_, 2, 3, 6, 7);                                                 \
    } while (0)
/* Entries o..o+3 of the four rows q[l] as four vectors, f[c] = {q[0][o + c], ..., q[3][o + c]}. */
static inline __attribute__((always_inline)) void lane4_transpose(const double *const q[4],
                                                                  size_t o, lane4 f[4])
{
    const lane4 a0 = *(const lane4u *)(q[0] + o), a1 = *(const lane4u *)(q[1] + o);
    const lane4 a2 = *(const lane4u *)(q[2] + o), a3 = *(const lane4u *)(q[3] + o);
    LANE4_TRANSPOSE(lane4, a0, a1, a2, a3, f);
}

/* The group visits' copies in a generic x86-64 build, chosen at load time: AVX-512 (x86-64-v4:
 * 32 vector registers, where the four lanes' sums and values of a visit no longer spill to the
 * stack at every entry; the same 256-bit vectors), AVX2 and the default. The same operations in
 * the same order, hence the same bits: AVX-512 brings FMA, so that copy is made only in ISO C mode
 * (__STRICT_ANSI__: the build's -std=c11), where GCC contracts nothing, as KERNEL_CLONES in
 * src/kernels/kernels.c; arch=x86-64-v4 needs GCC 11. */
#if defined(__x86_64__) && !defined(__clang__) && defined(__GLIBC__) && !defined(__AVX2__)
#if defined(__STRICT_ANSI__) && __GNUC__ >= 11
#define LANE4_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#else
#define LANE4_CLONES __attribute__((target_clones("avx2", "default")))
#endif
#else
#define LANE4_CLONES
#endif
#endif

#endif
