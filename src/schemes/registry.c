/* Every scheme of the solver, one row each: the families' rows (src/schemes/<family>/scheme.c)
 * listed once here, and everything else that names schemes read from this list. Adding a scheme
 * is its row in its family's scheme.c, its declaration in src/solver/solver_internal.h and one
 * line below. */
#include <stdio.h>
#include <string.h>

#include "solver/solver_internal.h"

/* In the order consph_scheme_names lists. */
static const scheme_def *const schemes[] = {
    /* 001 §5.1 and §5.4 (negi/) */
    &scheme_l_ipst_c,
    &scheme_l_ipst_f,
    &scheme_l_ipst_k,
    &scheme_l_pst_c,
    &scheme_pe_ipst_c,
    &scheme_l_rr_c,
    &scheme_tv_c,
    &scheme_e_c,
    &scheme_ewcsph,
    /* the established weakly-compressible schemes (pysph/) */
    &scheme_wcsph,
    &scheme_tvf,
    &scheme_edac,
    /* the δ-SPH family (delta/) */
    &scheme_delta_sph,
    &scheme_delta_plus_sph,
    &scheme_delta_plus_sph_d,
};

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
