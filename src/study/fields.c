#include <math.h>
#include <string.h>

#include "consph/study.h"

typedef struct mfield_info {
    const char *name;
    const char *description;
    int vector;
    int periodic_on_unit;
} mfield_info;

static const mfield_info mfields[CONSPH_MFIELD_COUNT] = {
    [CONSPH_MFIELD_SIN2PI] = {"sin2pi", "sin(2π(x+y+z)), 001 eq. 6 made periodic on [0,1)^d", 0, 1},
    [CONSPH_MFIELD_SINPI] = {"sinpi", "sin(π(x+y+z)), 001 eq. 6 as printed (anti-periodic)", 0, 0},
    [CONSPH_MFIELD_SINPROD] = {"sinprod", "Π sin(πx_a), 003 eqs. 53-54", 0, 0},
    [CONSPH_MFIELD_CONST] = {"const", "1", 0, 1},
    [CONSPH_MFIELD_LINEAR] = {"linear", "1 + 2x - 3y + z/2", 0, 0},
    [CONSPH_MFIELD_QUADRATIC] = {"quadratic", "x² + 3xy - 2y² + 2z² - yz", 0, 0},
    [CONSPH_MFIELD_CUBIC] = {"cubic", "x³ - 2xy² + y³ + xz²", 0, 0},
    [CONSPH_MFIELD_TGV] = {"tgv", "(-cos2πx sin2πy, sin2πx cos2πy), 001 eq. 12, divergence-free", 1,
                           1},
    [CONSPH_MFIELD_SIN2PI_VEC] = {"sin2pi-vec", "sin(2π(x+y+z)) in every component", 1, 1},
    [CONSPH_MFIELD_SINPI_VEC] = {"sinpi-vec", "sin(π(x+y+z)) in every component, 001 §4.2", 1, 0},
    [CONSPH_MFIELD_DELTA] = {"delta", "nascent Gaussian δ of width sigma at x0, 003 eq. 73", 0, 0},
};

const char *consph_mfield_name(consph_mfield_id id)
{
    return mfields[id].name;
}
const char *consph_mfield_description(consph_mfield_id id)
{
    return mfields[id].description;
}
int consph_mfield_is_vector(consph_mfield_id id)
{
    return mfields[id].vector;
}
int consph_mfield_periodic_on_unit(consph_mfield_id id)
{
    return mfields[id].periodic_on_unit;
}

const char *consph_mfield_names(void)
{
    static char names[512];
    if (!names[0]) {
        for (int k = 0; k < CONSPH_MFIELD_COUNT; ++k) {
            if (k) strcat(names, ",");
            strcat(names, mfields[k].name);
        }
    }
    return names;
}

int consph_mfield_lookup(const char *name, consph_mfield_id *id)
{
    for (int k = 0; k < CONSPH_MFIELD_COUNT; ++k)
        if (strcmp(name, mfields[k].name) == 0) {
            *id = (consph_mfield_id)k;
            return CONSPH_OK;
        }
    return consph_fail(CONSPH_EINVAL, "unknown field '%s'; allowed: %s", name,
                       consph_mfield_names());
}

consph_mfield_params consph_mfield_defaults(int dim)
{
    consph_mfield_params p;
    memset(&p, 0, sizeof p);
    p.sigma = 0.1;
    for (int a = 0; a < dim; ++a) p.x0[a] = 0.5;
    return p;
}

/* sin(k Σx) as a scalar, into component c of v. */
static void plane_wave(double k, int dim, const double *x, int c, consph_mfield_value *v)
{
    double s = 0.0;
    for (int a = 0; a < dim; ++a) s += x[a];
    double sn = sin(k * s), cs = cos(k * s);
    v->f[c] = sn;
    for (int a = 0; a < dim; ++a) {
        v->grad[c][a] = k * cs;
        if (c == 0)
            for (int b = 0; b < dim; ++b) v->hess[a][b] = -k * k * sn;
    }
    v->lap[c] = -dim * k * k * sn;
}

void consph_mfield_eval(consph_mfield_id id, int dim, const consph_mfield_params *prm,
                        const double *xin, consph_mfield_value *v)
{
    memset(v, 0, sizeof *v);
    double x[CONSPH_MAX_DIM] = {0, 0, 0};
    for (int a = 0; a < dim; ++a) x[a] = xin[a];
    v->ncomp = mfields[id].vector ? dim : 1;
    const double pi = M_PI;
    switch (id) {
    case CONSPH_MFIELD_SIN2PI:
        plane_wave(2 * pi, dim, x, 0, v);
        break;
    case CONSPH_MFIELD_SINPI:
        plane_wave(pi, dim, x, 0, v);
        break;
    case CONSPH_MFIELD_SIN2PI_VEC:
    case CONSPH_MFIELD_SINPI_VEC: {
        double k = id == CONSPH_MFIELD_SIN2PI_VEC ? 2 * pi : pi;
        for (int c = 0; c < dim; ++c) plane_wave(k, dim, x, c, v);
        for (int a = 0; a < dim; ++a) v->div += v->grad[a][a];
        break;
    }
    case CONSPH_MFIELD_SINPROD: {
        double sn[3], cs[3];
        for (int a = 0; a < dim; ++a) {
            sn[a] = sin(pi * x[a]);
            cs[a] = cos(pi * x[a]);
        }
        double f = 1.0;
        for (int a = 0; a < dim; ++a) f *= sn[a];
        v->f[0] = f;
        for (int a = 0; a < dim; ++a) {
            double g = pi * cs[a];
            for (int b = 0; b < dim; ++b)
                if (b != a) g *= sn[b];
            v->grad[0][a] = g;
            for (int b = 0; b < dim; ++b) {
                if (a == b) {
                    v->hess[a][a] = -pi * pi * f;
                } else {
                    double hh = pi * pi * cs[a] * cs[b];
                    for (int c = 0; c < dim; ++c)
                        if (c != a && c != b) hh *= sn[c];
                    v->hess[a][b] = hh;
                }
            }
        }
        v->lap[0] = -dim * pi * pi * f;
        break;
    }
    case CONSPH_MFIELD_CONST:
        v->f[0] = 1.0;
        break;
    case CONSPH_MFIELD_LINEAR: {
        static const double c[3] = {2.0, -3.0, 0.5};
        v->f[0] = 1.0;
        for (int a = 0; a < dim; ++a) {
            v->f[0] += c[a] * x[a];
            v->grad[0][a] = c[a];
        }
        break;
    }
    case CONSPH_MFIELD_QUADRATIC: {
        /* Axes past dim are zero, so the lower-dimensional forms follow by dropping terms. */
        double X = x[0], Y = x[1], Z = x[2];
        v->f[0] = X * X + 3 * X * Y - 2 * Y * Y + 2 * Z * Z - Y * Z;
        double g[3] = {2 * X + 3 * Y, 3 * X - 4 * Y - Z, 4 * Z - Y};
        double H[3][3] = {{2, 3, 0}, {3, -4, -1}, {0, -1, 4}};
        for (int a = 0; a < dim; ++a) {
            v->grad[0][a] = g[a];
            for (int b = 0; b < dim; ++b) v->hess[a][b] = H[a][b];
            v->lap[0] += H[a][a];
        }
        break;
    }
    case CONSPH_MFIELD_CUBIC: {
        double X = x[0], Y = x[1], Z = x[2];
        v->f[0] = X * X * X - 2 * X * Y * Y + Y * Y * Y + X * Z * Z;
        double g[3] = {3 * X * X - 2 * Y * Y + Z * Z, -4 * X * Y + 3 * Y * Y, 2 * X * Z};
        double H[3][3] = {{6 * X, -4 * Y, 2 * Z}, {-4 * Y, -4 * X + 6 * Y, 0}, {2 * Z, 0, 2 * X}};
        for (int a = 0; a < dim; ++a) {
            v->grad[0][a] = g[a];
            for (int b = 0; b < dim; ++b) v->hess[a][b] = H[a][b];
            v->lap[0] += H[a][a];
        }
        break;
    }
    case CONSPH_MFIELD_TGV: {
        /* Defined for dim >= 2; a third component, if any, is zero. */
        double k = 2 * pi;
        double sx = sin(k * x[0]), cx = cos(k * x[0]), sy = sin(k * x[1]), cy = cos(k * x[1]);
        v->f[0] = -cx * sy;
        v->f[1] = sx * cy;
        v->grad[0][0] = k * sx * sy;
        v->grad[0][1] = -k * cx * cy;
        v->grad[1][0] = k * cx * cy;
        v->grad[1][1] = -k * sx * sy;
        v->lap[0] = -2 * k * k * v->f[0];
        v->lap[1] = -2 * k * k * v->f[1];
        v->div = 0.0;
        break;
    }
    case CONSPH_MFIELD_DELTA: {
        double s2 = prm->sigma * prm->sigma, r2 = 0.0, d[3] = {0, 0, 0};
        for (int a = 0; a < dim; ++a) {
            d[a] = x[a] - prm->x0[a];
            r2 += d[a] * d[a];
        }
        double f = exp(-r2 / s2) / pow(sqrt(pi) * prm->sigma, dim);
        v->f[0] = f;
        for (int a = 0; a < dim; ++a) {
            v->grad[0][a] = -2.0 * d[a] / s2 * f;
            for (int b = 0; b < dim; ++b)
                v->hess[a][b] = f * (4.0 * d[a] * d[b] / (s2 * s2) - (a == b ? 2.0 / s2 : 0.0));
        }
        v->lap[0] = f * (4.0 * r2 / (s2 * s2) - 2.0 * dim / s2);
        break;
    }
    case CONSPH_MFIELD_COUNT:
        break;
    }
}
