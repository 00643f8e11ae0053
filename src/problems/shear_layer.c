/* The double shear layer (001 eqs. 38-39): its initial state and its row. */
#include <math.h>

#include "solver/solver_internal.h"

/* Double shear layer, 001 eqs. 38-39 (Bell, Colella & Glaz 1989's thick layer): ρ = 30 (a shape
 * parameter), δ = 0.05, on the periodic unit square; p = 0 at t = 0, no exact solution later. */
static void shear_layer(const consph_run_params *prm, double t, const double x[3], double u[3],
                        double *p)
{
    (void)prm;
    (void)t;
    const double rho = 30.0, delta = 0.05, y = x[1];
    u[0] = y <= 0.5 ? tanh(rho * (y - 0.25)) : tanh(rho * (0.75 - y));
    u[1] = delta * sin(2.0 * M_PI * x[0]);
    u[2] = 0.0;
    *p = 0.0;
}

/* Its row of the table in src/problems/problems.c; a field left out is 0 (the third axis of a 2D
 * box is never read). */
/* clang-format off */
const problem_def problem_shear_layer = {
    .name = "shear-layer",
    .summary = "001 eqs. 38-39: double shear layer, rho 30, delta 0.05, nu 1e-4",
    .dim = 2, .lo = {0.0, 0.0}, .hi = {1.0, 1.0}, .periodic = {1, 1},
    .exact = shear_layer, .has_exact = 0,
    .tf = 1.0, .nu = 1e-4, .c0 = 0.0, .layout = CONSPH_LAYOUT_LATTICE, .vorticity_image = 1
};
/* clang-format on */
