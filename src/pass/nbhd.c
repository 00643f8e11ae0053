/* The neighbourhood scratch of the pass layer (nbhd.h). */
#include "pass/nbhd.h"

#include <stdlib.h>
#include <string.h>

void nbhd_scratch_free(nbhd_scratch *sc)
{
    free(sc->slot);
    free(sc->j);
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) free(sc->dx[a]);
    free(sc->r);
    free(sc->w);
    free(sc->dwr);
    free(sc->d2w);
    memset(sc, 0, sizeof *sc);
}

/* A new array of count items on a 64-byte boundary; the old contents are not kept (every caller
 * reserves before it gathers). The gathers' vector stores then never straddle a cache line
 * wherever the heap happens to place the arrays: measured, serial wcsph nx 283, the AVX-512
 * gather of four particles (gather4) took 40-50 % more samples with the same arrays 16-byte
 * aligned after a 24-byte change of the solver's size had shifted the heap. */
static int grow(void **p, size_t count, size_t size)
{
    const size_t bytes = (count * size + 63) & ~(size_t)63;
    void *q = aligned_alloc(64, bytes);
    if (!q) return CONSPH_ENOMEM;
    free(*p);
    *p = q;
    return CONSPH_OK;
}

int nbhd_scratch_reserve(nbhd_scratch *sc, size_t need)
{
    if (need <= sc->cap) return CONSPH_OK;
    size_t cap = sc->cap ? sc->cap : 256;
    while (cap < need) cap *= 2;
    int st = grow((void **)&sc->slot, cap, sizeof(size_t));
    st = st ? st : grow((void **)&sc->j, cap, sizeof(size_t));
    for (int a = 0; a < CONSPH_MAX_DIM; ++a)
        st = st ? st : grow((void **)&sc->dx[a], cap, sizeof(double));
    st = st ? st : grow((void **)&sc->r, cap, sizeof(double));
    st = st ? st : grow((void **)&sc->w, cap, sizeof(double));
    st = st ? st : grow((void **)&sc->dwr, cap, sizeof(double));
    st = st ? st : grow((void **)&sc->d2w, cap, sizeof(double));
    if (st == CONSPH_OK) sc->cap = cap;
    return st;
}
