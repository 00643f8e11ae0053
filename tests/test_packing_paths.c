/* The packing's vector (AVX-512 where the processor has it, AVX2) and portable loops give the
 * same positions bit for bit, in 1D, 2D and 3D, for packed (fused quintic) and packed-polished
 * with another kernel (separate kernel evaluations), over enough steps that the neighbour list is
 * rebuilt. Where the processor lacks an instruction set the runs take the next loops down and
 * the test checks determinism only. */
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
    /* 0: the best loops the processor has, 1: portable, 2: AVX2 at most */
    consph_particles res[3];
    consph_packing_report rep[3];
    int ok = 1;
    for (int level = 0; level < 3; ++level) {
        layout_pack_set_portable(level);
        ok &= consph_layout_generate(&lp, &res[level], &rep[level]) == CONSPH_OK;
    }
    layout_pack_set_portable(0);
    CHECK(ok, "%s %dD generated", consph_layout_name(kind), dim);
    if (!ok) return;
    static const char *const names[3] = {"best", "portable", "AVX2"};
    for (int level = 1; level < 3; ++level) {
        int same = res[0].n == res[level].n && rep[0].iterations == rep[level].iterations &&
                   rep[0].rho_spread_final == rep[level].rho_spread_final;
        for (int a = 0; a < dim && same; ++a)
            same = memcmp(res[0].x[a], res[level].x[a], res[0].n * sizeof(double)) == 0;
        CHECK(same, "%s %dD nx %zu %s: %s and %s loops agree bit for bit (%d vs %d steps)",
              consph_layout_name(kind), dim, nx, kernel, names[0], names[level], rep[0].iterations,
              rep[level].iterations);
    }
    for (int level = 0; level < 3; ++level) {
        consph_particles_free(&res[level]);
        consph_packing_report_free(&rep[level]);
    }
}

/* The density and force walks run as a wavefront over chunks of particles, each thread over its
 * share of them, or one after the other: the same positions bit for bit, for 1, 2 and 3 threads
 * (enough particles for the parallel loops and several chunks per thread), with the wavefront's
 * rings of W'/r large enough and too small (chunks then placed at the ring's start, or left in
 * the list's array). */
static void compare_wavefront(int dim, size_t nx, int walls, int max_iter, int ring_chunks)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, dim, nx);
    lp.packing.max_iter = max_iter;
    lp.packing.history_every = 0;
    lp.packing.walls = walls;
    consph_particles ref, res;
    consph_packing_report rref, rres;
    layout_pack_set_wavefront(0, 0);
    check_set_threads(1);
    int ok = consph_layout_generate(&lp, &ref, &rref) == CONSPH_OK;
    layout_pack_set_wavefront(1, ring_chunks);
    CHECK(ok, "packed %dD nx %zu walls %d generated", dim, nx, walls);
    if (!ok) return;
    for (int threads = 1; threads <= 3; ++threads) {
        check_set_threads(threads);
        ok = consph_layout_generate(&lp, &res, &rres) == CONSPH_OK;
        int same = ok && res.n == ref.n && rres.iterations == rref.iterations &&
                   rres.rho_spread_final == rref.rho_spread_final;
        for (int a = 0; a < dim && same; ++a)
            same = memcmp(ref.x[a], res.x[a], ref.n * sizeof(double)) == 0;
        CHECK(
            same,
            "packed %dD nx %zu walls %d: the wavefront (rings of %d chunks) on %d threads and the "
            "separate walks agree bit for bit (%d vs %d steps)",
            dim, nx, walls, ring_chunks, threads, rres.iterations, rref.iterations);
        if (ok) {
            consph_particles_free(&res);
            consph_packing_report_free(&rres);
        }
    }
    check_set_threads(1);
    layout_pack_set_wavefront(1, 0);
    consph_particles_free(&ref);
    consph_packing_report_free(&rref);
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
    compare_wavefront(2, 64, 0, 300, 0);
    compare_wavefront(2, 64, 0, 300, 2); /* rings too small for a neighbourhood: the fallback */
    compare_wavefront(2, 48, 2, 200, 0);
    compare_wavefront(1, 3000, 0, 200, 3);
    return check_summary("test_packing_paths");
}
