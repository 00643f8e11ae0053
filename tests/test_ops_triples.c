/* Every valid (op, form, corr) triple in every dimension, enumerated from the library's own
 * table (consph_op_check), so that a new form is covered without touching this file: the call
 * succeeds and every output value is finite, on a periodic random layout, on a non-periodic
 * one (truncated support, fallbacks at the walls) and with h so small that a particle has no
 * neighbour but itself (every correction falls back).
 *
 * tests/memcheck.sh runs this program under valgrind with freshly allocated memory filled with
 * NaN bytes: an operator that reads a kernel value, a matrix or an output it never wrote then
 * prints a non-finite value here, or valgrind reports the read. Sizes are small for that. */
#include <math.h>
#include <stdlib.h>

#include "check.h"
#include "layout_fixture.h"
#include "consph/consph.h"
#include "consph/ops.h"

typedef struct world_case {
    const char *name;
    int periodic;
    double hdx; /* h/Δs; the kernel support is 3h */
} world_case;

static double input_value(const double *x, int d, int c)
{
    double v = sin(6.283185307179586 * (x[0] + 0.25 * c)) + 0.3 * x[0];
    if (d > 1) v *= cos(6.283185307179586 * x[1]) + 1.5;
    if (d > 2) v += x[2] * x[2] - 0.2 * c;
    return v;
}

static size_t run_case(int dim, size_t nx, const world_case *wc)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, dim, nx);
    lp.eps = 0.4;
    lp.seed = 7;
    for (int a = 0; a < dim; ++a) lp.box.periodic[a] = wc->periodic;
    world w;
    int ok = world_setup_params(&w, &lp, wc->hdx, CONSPH_VOLUME_NUMBER);
    CHECK(ok, "%dD %s: setup: %s", dim, wc->name, consph_last_error());
    size_t ran = 0;
    if (!ok) {
        world_free(&w);
        return ran;
    }
    const size_t n = w.p.n;
    for (int op = 0; op < CONSPH_OP_COUNT; ++op) {
        const int nin = consph_op_ncomp_in((consph_op)op, dim);
        const int nout = consph_op_ncomp_out((consph_op)op, dim);
        /* malloc, not calloc: under memcheck both arrays start as NaN bytes, so an output the
         * operator leaves unwritten is caught by the finiteness check. */
        double *in = malloc((size_t)nin * n * sizeof(double));
        double *out = malloc((size_t)nout * n * sizeof(double));
        CHECK(in && out, "out of memory");
        if (!in || !out) {
            free(in);
            free(out);
            continue;
        }
        for (size_t i = 0; i < n; ++i) {
            double x[3] = {0, 0, 0};
            for (int a = 0; a < dim; ++a) x[a] = w.p.x[a][i];
            for (int c = 0; c < nin; ++c) in[(size_t)c * n + i] = input_value(x, dim, c);
        }
        for (int form = 0; form < CONSPH_FORM_COUNT; ++form)
            for (int corr = 0; corr < CONSPH_CORR_COUNT; ++corr) {
                if (consph_op_check((consph_op)op, (consph_op_form)form, (consph_op_corr)corr,
                                    dim) != CONSPH_OK)
                    continue;
                /* Each triple starts from an empty cache, as a fresh run would. */
                ok = consph_op_ctx_refresh(&w.ctx) == CONSPH_OK;
                consph_op_report rep;
                ok = ok && consph_apply(&w.ctx, (consph_op)op, (consph_op_form)form,
                                        (consph_op_corr)corr, in, out, &rep) == CONSPH_OK;
                CHECK(ok, "%dD %s: %s %s %s: %s", dim, wc->name, consph_op_name((consph_op)op),
                      consph_form_name((consph_op_form)form),
                      consph_corr_name((consph_op_corr)corr), consph_last_error());
                if (!ok) continue;
                ++ran;
                size_t bad = 0, first = 0;
                for (size_t k = 0; k < (size_t)nout * n; ++k)
                    if (!isfinite(out[k]) && bad++ == 0) first = k;
                CHECK(bad == 0,
                      "%dD %s: %s %s %s: %zu of %zu outputs not finite (first: component %zu, "
                      "particle %zu = %g)",
                      dim, wc->name, consph_op_name((consph_op)op),
                      consph_form_name((consph_op_form)form),
                      consph_corr_name((consph_op_corr)corr), bad, (size_t)nout * n, first / n,
                      first % n, out[first]);
            }
        free(in);
        free(out);
    }
    world_free(&w);
    return ran;
}

int main(void)
{
    static const world_case cases[] = {
        {"periodic", 1, 1.2},
        {"non-periodic", 0, 1.2},
        {"no neighbours", 0, 0.3},
    };
    /* Smallest sets with a full support inside the box; 3D with a narrower kernel so that the
     * run stays short under memcheck. */
    static const size_t nx_of_dim[4] = {0, 16, 9, 6};
    static const double hdx_3d_scale = 0.6;
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k)
        for (int dim = 1; dim <= 3; ++dim) {
            world_case wc = cases[k];
            if (dim == 3 && wc.hdx > 1.0) wc.hdx *= hdx_3d_scale;
            size_t ran = run_case(dim, nx_of_dim[dim], &wc);
            /* Every dimension implements at least the standard function and the f2 gradient. */
            CHECK(ran >= 2, "%dD %s: only %zu triples ran", dim, wc.name, ran);
        }
    return check_summary("test_ops_triples");
}
