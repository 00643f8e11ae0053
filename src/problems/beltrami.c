/* The 3D Arnold-Beltrami-Childress flow: its exact solution and its row. */
#include <math.h>

#include "solver/solver_internal.h"

/* The Arnold-Beltrami-Childress flow on the periodic unit cube, with A = B = C = U and k = 2π/L
 * (L = 1): u = (A sin kz + C cos ky, B sin kx + A cos kz, C sin ky + B cos kx) e^(-νk²t), a
 * Beltrami field (∇×u = k u), so u·∇u = ∇(|u|²/2) and p = -ρ_o |u|²/2 + const solves the
 * Navier-Stokes equations exactly (docs/schemes.md, "Problems"); the constant makes the mean of
 * p over the cube zero: the mean of |u|² is (A² + B² + C²) e^(-2νk²t). */
static void beltrami(const consph_run_params *prm, double t, const double x[3], double u[3],
                     double *p)
{
    const double A = prm->U, B = prm->U, C = prm->U, k = 2.0 * M_PI;
    const double nu = prm->nu >= 0.0 ? prm->nu : prm->U / prm->re; /* derive_solver's, L = 1 */
    const double e = exp(-nu * k * k * t);
    const double sx = sin(k * x[0]), cx = cos(k * x[0]), sy = sin(k * x[1]), cy = cos(k * x[1]);
    const double sz = sin(k * x[2]), cz = cos(k * x[2]);
    u[0] = (A * sz + C * cy) * e;
    u[1] = (B * sx + A * cz) * e;
    u[2] = (C * sy + B * cx) * e;
    const double u2 = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    *p = -0.5 * prm->rho0 * (u2 - (A * A + B * B + C * C) * e * e);
}

/* Its row of the table in src/problems/problems.c; a field left out is 0. */
/* clang-format off */
const problem_def problem_beltrami = {
    .name = "beltrami",
    .summary = "3D Arnold-Beltrami-Childress flow, A = B = C = U, k = 2 pi, periodic unit cube",
    .dim = 3, .lo = {0.0, 0.0, 0.0}, .hi = {1.0, 1.0, 1.0}, .periodic = {1, 1, 1},
    .exact = beltrami, .has_exact = 1,
    .tf = 0.5, .nu = -1.0, .c0 = 0.0, .layout = -1
};
/* clang-format on */
