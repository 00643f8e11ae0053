/* Every scheme of the solver, one line each: the families' rows (src/schemes/<family>/scheme.c)
 * listed once here, and everything else that names schemes read from this list. Adding a scheme
 * is its row in its family's scheme.c and one line of SCHEMES below. */
#include <stdio.h>
#include <string.h>

#include "solver/solver_internal.h"

/* In the order consph_scheme_names lists; each line expands to the row's declaration and its
 * entry in the table. */
#define SCHEMES(X)                                                                                 \
    /* 001 §5.1 and §5.4 (negi/) */                                                              \
    X(scheme_l_ipst_c)                                                                             \
    X(scheme_l_ipst_f)                                                                             \
    X(scheme_l_ipst_k)                                                                             \
    X(scheme_l_pst_c)                                                                              \
    X(scheme_pe_ipst_c)                                                                            \
    X(scheme_l_rr_c)                                                                               \
    X(scheme_tv_c)                                                                                 \
    X(scheme_e_c)                                                                                  \
    X(scheme_ewcsph)                                                                               \
    /* the established weakly-compressible schemes (pysph/) */                                     \
    X(scheme_wcsph)                                                                                \
    X(scheme_tvf)                                                                                  \
    X(scheme_edac)                                                                                 \
    /* the δ-SPH family (delta/) */                                                               \
    X(scheme_delta_sph)                                                                            \
    X(scheme_delta_plus_sph)                                                                       \
    X(scheme_delta_plus_sph_d)

#define DECLARE_SCHEME(row) extern const scheme_def row;
SCHEMES(DECLARE_SCHEME)
#undef DECLARE_SCHEME

#define SCHEME_ENTRY(row) &row,
static const scheme_def *const schemes[] = {SCHEMES(SCHEME_ENTRY)};
#undef SCHEME_ENTRY

size_t scheme_count(void)
{
    return sizeof schemes / sizeof schemes[0];
}

const scheme_def *scheme_find(const char *name)
{
    for (size_t k = 0; name && k < scheme_count(); ++k)
        if (strcmp(schemes[k]->name, name) == 0) return schemes[k];
    return NULL;
}

/* Built from the table on the first call; the critical section orders that write before any
 * caller's read. */
const char *consph_scheme_names(void)
{
    static char names[1024];
#pragma omp critical(consph_scheme_names)
    if (!names[0]) {
        size_t len = 0;
        for (size_t k = 0; k < scheme_count() && len < sizeof names; ++k) {
            int w =
                snprintf(names + len, sizeof names - len, "%s%s", k ? "," : "", schemes[k]->name);
            if (w < 0) break;
            len += (size_t)w;
        }
    }
    return names;
}

int consph_scheme_uses_ipst(const char *name)
{
    return consph_scheme_reads(name, CONSPH_PARAM_IPST);
}

int consph_scheme_reads(const char *name, unsigned param)
{
    const scheme_def *sd = scheme_find(name);
    if (!sd) return 0;
    if (param == CONSPH_PARAM_EOS)
        /* solver_eos and the initial density are the only readers; a closure or an evolved p
         * replaces both */
        return !sd->evolve_p && !sd->closure;
    return (sd->reads & param) != 0;
}

const char *consph_scheme_readers(unsigned param, char *buf, size_t size)
{
    size_t len = 0;
    if (size) buf[0] = '\0';
    for (size_t k = 0; k < scheme_count() && len < size; ++k)
        if (consph_scheme_reads(schemes[k]->name, param)) {
            int w = snprintf(buf + len, size - len, "%s%s", len ? ", " : "", schemes[k]->name);
            if (w < 0) break;
            len += (size_t)w;
        }
    return buf;
}
