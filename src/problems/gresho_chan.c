/* The Gresho-Chan vortex (001 eq. 37): its exact (steady) solution and its row. */
#include <math.h>

#include "solver/solver_internal.h"

/* Gresho-Chan vortex, 001 eq. 37, centred at the origin: u_φ(r) and p(r), steady (the exact
 * solution at every t is the initial one). U and ρ_o are 1 in eq. 37 and are not scaled. */
static void gresho_chan_radial(double r, double *uphi, double *p)
{
    if (r < 0.2) {
        *uphi = 5.0 * r;
        *p = 12.5 * r * r + 5.0;
    } else if (r < 0.4) {
        *uphi = 2.0 - 5.0 * r;
        *p = 12.5 * r * r - 20.0 * r + 4.0 * log(5.0 * r) + 9.0;
    } else {
        *uphi = 0.0;
        *p = 3.0 + 4.0 * log(2.0);
    }
}

static void gresho_chan(const consph_run_params *prm, double t, const double x[3], double u[3],
                        double *p)
{
    (void)prm;
    (void)t;
    const double r = hypot(x[0], x[1]);
    double uphi;
    gresho_chan_radial(r, &uphi, p);
    /* e_φ = (-y, x)/r; at r = 0, u_φ = 0 */
    u[0] = r > 0.0 ? -uphi * x[1] / r : 0.0;
    u[1] = r > 0.0 ? uphi * x[0] / r : 0.0;
    u[2] = 0.0;
}

/* Its row of the table in src/problems/problems.c; a field left out is 0 (the third axis of a 2D
 * box is never read). */
/* clang-format off */
const problem_def problem_gresho_chan = {
    .name = "gresho-chan",
    .summary = "001 eq. 37: Gresho-Chan vortex, inviscid, periodic 1x1 centred at 0",
    .dim = 2, .lo = {-0.5, -0.5}, .hi = {0.5, 0.5}, .periodic = {1, 1},
    .exact = gresho_chan, .has_exact = 1,
    .tf = 3.0, .nu = 0.0, .c0 = 0.0, .layout = CONSPH_LAYOUT_LATTICE, .radial = 1
};
/* clang-format on */
