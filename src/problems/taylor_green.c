/* The Taylor-Green vortex (001 eq. 25): its exact solution and its row. */
#include <math.h>

#include "solver/solver_internal.h"

/* Taylor-Green vortex, 001 eq. 25, on the periodic unit square: b = -8π²/Re. */
static void taylor_green(const consph_run_params *prm, double t, const double x[3], double u[3],
                         double *p)
{
    const double U = prm->U, b = -8.0 * M_PI * M_PI / prm->re, e = exp(b * t);
    const double cx = cos(2.0 * M_PI * x[0]), sx = sin(2.0 * M_PI * x[0]);
    const double cy = cos(2.0 * M_PI * x[1]), sy = sin(2.0 * M_PI * x[1]);
    u[0] = -U * e * cx * sy;
    u[1] = U * e * sx * cy;
    u[2] = 0.0;
    *p = -0.25 * U * U * e * e * (cos(4.0 * M_PI * x[0]) + cos(4.0 * M_PI * x[1]));
}

/* Its row of the table in src/problems/problems.c; a field left out is 0 (the third axis of a 2D
 * box is never read). */
/* clang-format off */
const problem_def problem_taylor_green = {
    .name = "taylor-green",
    .summary = "001 eq. 25: Taylor-Green vortex, periodic unit square",
    .dim = 2, .lo = {0.0, 0.0}, .hi = {1.0, 1.0}, .periodic = {1, 1},
    .exact = taylor_green, .has_exact = 1,
    .tf = 0.5, .nu = -1.0, .c0 = 0.0, .layout = -1, .wc_reference = 1
};
/* clang-format on */
