/* The terms of EWCSPH and PE-IPST-C that follow 001's authors' code (docs/schemes.md, "EWCSPH"
 * and "PE-IPST-C"), each against a value computed by hand here:
 *
 *   Cleary's Laplacian (kit.c, KIT_LAP_CLEARY): at every particle of a 2D periodic lattice with
 *     a varying ϱ, Σ_j 4 ω_j/(ϱ_i + ϱ_j) (x_ij·B_i∇W_ij)/r² (u_i - u_j) summed here over every
 *     particle by the minimum image, with the kit's own ω and B_i, to 1e-12 of max|∇²u|;
 *     and with ϱ = 1 it approximates ∇²u of u = sin 2πx (-4π² u) to 1 % at nx 32;
 *   PE-IPST-C's dp/dt (iact.h): -ρ_o c_o² ∇·u, not -ϱ c_o² ∇·u, with ϱ ≠ ρ_o;
 *   EWCSPH's rates: -∇p/ϱ_c with its frozen ϱ_c, -ϱ ∇·u in dϱ/dt, no -u·∇ϱ. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "consph/consph.h"
#include "schemes/negi/iact.h"
#include "solver/solver_internal.h"

#define TWO_PI 6.283185307179586

static double wrap(double x)
{
    return x - floor(x + 0.5); /* unit periodic box */
}

static void cleary_by_hand(void)
{
    enum { NX = 32 };
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 2, NX);
    consph_particles src;
    consph_kernel k;
    consph_sys sys;
    CHECK(consph_layout_generate(&lp, &src, NULL) == CONSPH_OK, "layout");
    CHECK(consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 2, 1.2 / NX) == CONSPH_OK, "kernel");
    CHECK(consph_sys_init(&sys, &src, &k, 0.0) == CONSPH_OK, "sys");
    consph_particles_free(&src);
    consph_particles *p = sys.p;
    const size_t n = p->n, cap = p->cap;
    double *u = consph_particles_field(p, SF_U, 2), *rho = consph_particles_field(p, SF_RHOF, 1);
    double *pr = consph_particles_field(p, SF_P, 1);
    CHECK(u && rho && pr, "fields");
    for (int pass = 0; pass < 2; ++pass) {
        /* pass 0: varying ϱ, against the sum by hand; pass 1: ϱ = 1, against ∇²u */
        for (size_t i = 0; i < n; ++i) {
            const double x = p->x[0][i], y = p->x[1][i];
            u[i] = sin(TWO_PI * x);
            u[cap + i] = pass ? 0.0 : cos(TWO_PI * y) * sin(TWO_PI * x);
            rho[i] = pass ? 1.0 : 1.0 + 0.05 * cos(TWO_PI * (x + 2.0 * y));
            pr[i] = 0.0;
        }
        size_t pairs = 0;
        int passes = 0;
        kit_req rq = {KIT_LAPU, KIT_LAP_CLEARY, SF_RHOF, 1e8, 0};
        CHECK(kit_volumes(&sys, &pairs) == CONSPH_OK, "volumes");
        CHECK(kit_derivatives(&sys, &rq, &pairs, &passes) == CONSPH_OK, "kit");
        const double *lap = consph_particles_find(p, SF_LAPU)->data;
        const double *vol = consph_particles_find(p, SF_VOL)->data;
        const double *B = consph_particles_find(p, SF_BONET)->data;
        double diff = 0.0, big = 0.0, err = 0.0, ex = 0.0;
        for (size_t i = 0; i < n; i += 7) {
            double acc[2] = {0.0, 0.0};
            for (size_t j = 0; j < n; ++j) {
                const double x[2] = {wrap(p->x[0][i] - p->x[0][j]), wrap(p->x[1][i] - p->x[1][j])};
                const double r = hypot(x[0], x[1]);
                if (!(r > 1e-14) || r >= k.radius) continue;
                const double dwr = consph_kernel_dw(&k, r) / r; /* ∇W_ij = dwr x_ij */
                double xBx = 0.0;
                for (int a = 0; a < 2; ++a)
                    for (int b = 0; b < 2; ++b)
                        xBx += x[a] * B[(size_t)(a * 2 + b) * cap + i] * x[b];
                const double c = 4.0 * vol[j] / (rho[i] + rho[j]) * dwr * xBx / (r * r);
                for (int a = 0; a < 2; ++a) acc[a] += c * (u[a * cap + i] - u[a * cap + j]);
            }
            for (int a = 0; a < 2; ++a) {
                diff = fmax(diff, fabs(lap[a * cap + i] - acc[a]));
                big = fmax(big, fabs(acc[a]));
            }
            const double exact = -TWO_PI * TWO_PI * u[i];
            err = fmax(err, fabs(lap[i] - exact));
            ex = fmax(ex, fabs(exact));
        }
        CHECK(big > 1.0, "Cleary's sum is not trivial (max %.3g)", big);
        CHECK(diff <= 1e-12 * big, "pass %d: kit's Cleary vs by hand: max diff %.3g of %.3g", pass,
              diff, big);
        if (pass) CHECK(err <= 0.01 * ex, "Cleary ∇²u of sin 2πx: max error %.3g of %.3g", err, ex);
    }
    consph_sys_free(&sys);
}

static void rates_by_hand(void)
{
    const negi_terms pe = {.lap = KIT_LAP_COUPLED, .diffuse_q = 1};
    const negi_terms ew = {.lap = KIT_LAP_CLEARY, .advect_u = 1};
    negi_derivs v;
    memset(&v, 0, sizeof v);
    v.rhof = 1.05;
    v.rhom = 1.05; /* ϱ: PE-IPST-C divides ∇p by its ϱ of eq. 31 */
    v.divu = 0.3;
    v.lapq = 2.0;
    v.u[0] = 0.5;
    v.u[1] = -0.25;
    v.gradp[0] = 4.0;
    v.gradp[1] = -2.0;
    v.gradq[0] = 7.0; /* read by neither scheme: EWCSPH drops -u·∇ϱ */
    v.gradq[1] = 3.0;
    v.lapu[0] = 1.5;
    v.lapu[1] = -0.5;
    v.G[0] = 1.0;
    v.G[1] = 2.0;
    v.G[2] = 3.0;
    v.G[3] = 4.0;
    double au[3], ax[3], aq;
    /* PE-IPST-C: dp/dt = -ρ_o c_o² ∇·u + D∇²p = -1·400·0.3 + 0.1·2 */
    negi_rates_i(&pe, 2, 0.01, 0.1, 400.0, 1.0, 1, &v, au, ax, &aq);
    CHECK(fabs(aq - (-120.0 + 0.2)) <= 1e-12, "PE-IPST-C dp/dt %.17g, by hand -119.8", aq);
    CHECK(fabs(au[0] - (-4.0 / 1.05 + 0.01 * 1.5)) <= 1e-14, "PE-IPST-C du/dt %.17g", au[0]);
    /* EWCSPH: dϱ/dt = -ϱ∇·u; du/dt = -∇p/ϱ_c + ν∇²u - (u·∇)u, ϱ_c = 1.02 the frozen one */
    v.rhom = 1.02;
    negi_rates_i(&ew, 2, 0.01, 0.0, 400.0, 1.0, 0, &v, au, ax, &aq);
    CHECK(fabs(aq - (-1.05 * 0.3)) <= 1e-15, "EWCSPH dϱ/dt %.17g, by hand -0.315", aq);
    const double au0 = -4.0 / 1.02 + 0.01 * 1.5 - (0.5 * 1.0 - 0.25 * 2.0);
    const double au1 = 2.0 / 1.02 - 0.01 * 0.5 - (0.5 * 3.0 - 0.25 * 4.0);
    CHECK(fabs(au[0] - au0) <= 1e-14 && fabs(au[1] - au1) <= 1e-14,
          "EWCSPH du/dt (%.17g, %.17g), by hand (%.17g, %.17g)", au[0], au[1], au0, au1);
}

int main(void)
{
    cleary_by_hand();
    rates_by_hand();
    return check_summary("test_negi_authors");
}
