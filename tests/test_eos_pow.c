/* Integer powers of the Tait EOS (src/solver/solver_internal.h, eos_ipow): a whole exponent n is
 * taken by multiplication, within n + 1 ulps of pow; any other exponent still goes through pow,
 * and the solver's p from ϱ follows eq. 18 with either. */
#include <math.h>
#include <string.h>

#include "check.h"
#include "consph/solver.h"
#include "solver/solver_internal.h"

static void test_ipow(void)
{
    CHECK(eos_int_exponent(7.0) == 7 && eos_int_exponent(0.0) == 0 && eos_int_exponent(20.0) == 20,
          "whole exponents not recognised");
    CHECK(eos_int_exponent(7.5) == -1 && eos_int_exponent(3.0000001) == -1 &&
              eos_int_exponent(-1.0) == -1 && eos_int_exponent(1e300) == -1 &&
              eos_int_exponent(NAN) == -1,
          "a fractional, negative, huge or NaN exponent taken as whole");
    double worst = 0.0;
    for (int n = 0; n <= 20; ++n)
        for (int k = 0; k <= 600; ++k) {
            const double x = 0.7 + 0.001 * k, p = pow(x, n), m = eos_ipow(x, n);
            const double ulps = fabs(m - p) / (nextafter(p, INFINITY) - p);
            if (ulps > worst) worst = ulps;
            /* each multiplication rounds once, and a squaring doubles the error before it */
            CHECK(ulps <= n + 1.0, "%.17g^%d: %.17g by multiplication, %.17g by pow (%g ulps)", x,
                  n, m, p, ulps);
        }
    CHECK(worst > 0.0, "multiplication agrees with pow bit for bit everywhere: is pow used?");
    CHECK(eos_ipow(2.0, 10) == 1024.0 && eos_ipow(-1.5, 3) == -3.375 && eos_ipow(3.0, 0) == 1.0,
          "exact cases");
}

/* wcsph (Tait, ϱ evolved): after set-up, p_i = ρ_o c_o²/γ ((ϱ_i/ρ_o)^γ - 1) with the power by
 * multiplication for γ = 7 and by pow for γ = 7.5. */
static void test_solver_eos(double gamma)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "wcsph");
    p.nx = 16;
    p.gamma = gamma;
    consph_solver *s = NULL;
    CHECK(consph_solver_create(&s, &p) == CONSPH_OK, "create: %s", consph_last_error());
    if (!s) return;
    CHECK(consph_solver_step(s) == CONSPH_OK, "step: %s", consph_last_error());
    const double *rf = sv_field(s, SF_RHOF, 1), *pr = sv_field(s, SF_P, 1);
    const double c2 = s->c0 * s->c0, r0 = p.rho0;
    const int ig = eos_int_exponent(gamma);
    size_t bad = 0, moved = 0;
    for (size_t i = 0; rf && pr && i < s->sys.p->n; ++i) {
        const double x = rf[i] / r0;
        const double want = r0 * c2 / gamma * ((ig >= 0 ? eos_ipow(x, ig) : pow(x, gamma)) - 1.0);
        bad += memcmp(&want, &pr[i], sizeof want) != 0;
        moved += x != 1.0;
    }
    CHECK(bad == 0 && moved > 0, "γ = %g: %zu pressures not eq. 18 (%zu densities moved)", gamma,
          bad, moved);
    consph_solver_free(s);
}

int main(void)
{
    test_ipow();
    test_solver_eos(7.0);
    test_solver_eos(7.5);
    return check_summary("test_eos_pow");
}
