/* The problems, as data: domain, exact (or initial) solution, defaults. */
#include <math.h>
#include <stdio.h>
#include <string.h>

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

/* clang-format off */
/* The rows; a field left out is 0 (the third axis of a 2D box is never read). */
static const problem_def problems[] = {
    {.name = "taylor-green",
     .summary = "001 eq. 25: Taylor-Green vortex, periodic unit square",
     .dim = 2, .lo = {0.0, 0.0}, .hi = {1.0, 1.0}, .periodic = {1, 1},
     .exact = taylor_green, .has_exact = 1,
     .tf = 0.5, .nu = -1.0, .c0 = 0.0, .layout = -1},
    {.name = "gresho-chan",
     .summary = "001 eq. 37: Gresho-Chan vortex, inviscid, periodic 1x1 centred at 0",
     .dim = 2, .lo = {-0.5, -0.5}, .hi = {0.5, 0.5}, .periodic = {1, 1},
     .exact = gresho_chan, .has_exact = 1,
     .tf = 3.0, .nu = 0.0, .c0 = 0.0, .layout = CONSPH_LAYOUT_LATTICE, .radial = 1},
    {.name = "shear-layer",
     .summary = "001 eqs. 38-39: double shear layer, rho 30, delta 0.05, nu 1e-4",
     .dim = 2, .lo = {0.0, 0.0}, .hi = {1.0, 1.0}, .periodic = {1, 1},
     .exact = shear_layer, .has_exact = 0,
     .tf = 1.0, .nu = 1e-4, .c0 = 0.0, .layout = CONSPH_LAYOUT_LATTICE, .vorticity_image = 1},
    {.name = "beltrami",
     .summary = "3D Arnold-Beltrami-Childress flow, A = B = C = U, k = 2 pi, periodic unit cube",
     .dim = 3, .lo = {0.0, 0.0, 0.0}, .hi = {1.0, 1.0, 1.0}, .periodic = {1, 1, 1},
     .exact = beltrami, .has_exact = 1,
     .tf = 0.5, .nu = -1.0, .c0 = 0.0, .layout = -1},
};
/* clang-format on */
enum { NPROBLEMS = sizeof problems / sizeof problems[0] };

const problem_def *problem_find(const char *name)
{
    for (size_t k = 0; k < NPROBLEMS; ++k)
        if (strcmp(problems[k].name, name) == 0) return &problems[k];
    return NULL;
}

const char *consph_problem_names(void)
{
    static char names[NPROBLEMS * 32];
    /* filled once, from the table; callers on several threads wait for the first */
#pragma omp critical(consph_problem_names)
    if (!names[0]) {
        size_t len = 0;
        for (size_t k = 0; k < NPROBLEMS; ++k)
            len += (size_t)snprintf(names + len, sizeof names - len, "%s%s", k ? "," : "",
                                    problems[k].name);
    }
    return names;
}

int consph_run_params_problem(consph_run_params *prm, const char *problem)
{
    const problem_def *pb = problem_find(problem);
    if (!pb || strlen(problem) >= sizeof prm->problem)
        return consph_fail(CONSPH_EINVAL, "problem '%.40s' is unknown (allowed: %s)", problem,
                           consph_problem_names());
    snprintf(prm->problem, sizeof prm->problem, "%s", pb->name);
    prm->tf = pb->tf;
    prm->nu = pb->nu;
    prm->c0 = pb->c0;
    prm->layout = pb->layout;
    return CONSPH_OK;
}
