/* The problems, as data: domain, exact (or initial) solution, defaults. */
#include <math.h>
#include <string.h>

#include "schemes/solver_internal.h"

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

static const problem_def problems[] = {
    {"taylor-green", "001 eq. 25: Taylor-Green vortex, periodic unit square", taylor_green, 1, 0.0,
     1.0},
};

const problem_def *problem_find(const char *name)
{
    for (size_t k = 0; k < sizeof problems / sizeof problems[0]; ++k)
        if (strcmp(problems[k].name, name) == 0) return &problems[k];
    return NULL;
}

const char *consph_problem_names(void)
{
    return "taylor-green";
}
