/* The packing's vector (AVX2) and portable loops give the same positions bit for bit, in 1D, 2D
 * and 3D, for packed (fused quintic) and packed-polished with another kernel (separate kernel
 * evaluations), over enough steps that the neighbour list is rebuilt. Where the processor has
 * no AVX2 both runs take the portable loops and the test checks determinism only. */
#include <string.h>

#include "check.h"
#include "consph/layout.h"
#include "layout/layout_internal.h"

static void compare(consph_layout_kind kind, int dim, size_t nx, int max_iter, const char *kernel,
                    double hdx)
{
    consph_layout_params lp = consph_layout_defaults(kind, dim, nx);
    lp.packing.max_iter = max_iter;
    lp.packing.history_every = 0;
    lp.packing.kernel = kernel;
    lp.packing.hdx = hdx;
    if (kind == CONSPH_LAYOUT_PACKED_POLISHED) lp.packing.tol = 1e-6;
    consph_particles vec, port;
    consph_packing_report rv, rp;
    layout_pack_set_portable(0);
    int ok = consph_layout_generate(&lp, &vec, &rv) == CONSPH_OK;
    layout_pack_set_portable(1);
    ok &= consph_layout_generate(&lp, &port, &rp) == CONSPH_OK;
    layout_pack_set_portable(0);
    CHECK(ok, "%s %dD generated", consph_layout_name(kind), dim);
    if (!ok) return;
    int same = vec.n == port.n && rv.iterations == rp.iterations &&
               rv.rho_spread_final == rp.rho_spread_final;
    for (int a = 0; a < dim && same; ++a)
        same = memcmp(vec.x[a], port.x[a], vec.n * sizeof(double)) == 0;
    CHECK(same, "%s %dD nx %zu %s: vector and portable loops agree bit for bit (%d vs %d steps)",
          consph_layout_name(kind), dim, nx, kernel, rv.iterations, rp.iterations);
    consph_particles_free(&vec);
    consph_particles_free(&port);
    consph_packing_report_free(&rv);
    consph_packing_report_free(&rp);
}

int main(void)
{
    check_set_threads(1);
    compare(CONSPH_LAYOUT_PACKED, 2, 16, 400, "quintic", 1.2);
    compare(CONSPH_LAYOUT_PACKED, 1, 40, 400, "quintic", 1.2);
    compare(CONSPH_LAYOUT_PACKED, 3, 6, 100, "quintic", 1.2);
    compare(CONSPH_LAYOUT_PACKED, 2, 12, 200, "wendland-c4", 2.0);
    compare(CONSPH_LAYOUT_PACKED_POLISHED, 2, 12, 400, "wendland-c2", 1.5);
    compare(CONSPH_LAYOUT_PACKED_POLISHED, 3, 6, 200, "quintic", 1.2);
    return check_summary("test_packing_paths");
}
