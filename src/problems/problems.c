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

/* name, summary, exact, has_exact, lo, hi, tf, nu, c0, layout, radial, vorticity_image */
static const problem_def problems[] = {
    {"taylor-green", "001 eq. 25: Taylor-Green vortex, periodic unit square", taylor_green, 1, 0.0,
     1.0, 0.5, -1.0, 0.0, -1, 0, 0},
    {"gresho-chan", "001 eq. 37: Gresho-Chan vortex, inviscid, periodic 1x1 centred at 0",
     gresho_chan, 1, -0.5, 0.5, 3.0, 0.0, 0.0, CONSPH_LAYOUT_LATTICE, 1, 0},
    {"shear-layer", "001 eqs. 38-39: double shear layer, rho 30, delta 0.05, nu 1e-4", shear_layer,
     0, 0.0, 1.0, 1.0, 1e-4, 0.0, CONSPH_LAYOUT_LATTICE, 0, 1},
};

const problem_def *problem_find(const char *name)
{
    for (size_t k = 0; k < sizeof problems / sizeof problems[0]; ++k)
        if (strcmp(problems[k].name, name) == 0) return &problems[k];
    return NULL;
}

const char *consph_problem_names(void)
{
    return "taylor-green,gresho-chan,shear-layer";
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
