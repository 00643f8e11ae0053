/* The validity of a run: after every step, every value finite and the state within the bounds of
 * the weakly-compressible model (docs/schemes.md, "Validity of a run"), the first breach named by
 * step, particle, position, quantity, value and bound; and the warning for a Δt above a stability
 * bound. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "solver/solver_internal.h"

/* "(x, y)" (or with z) of particle i: every coordinate of the run's dimension. */
static void position_text(const consph_solver *s, size_t i, char *buf, size_t size)
{
    const consph_particles *p = s->sys.p;
    int k = snprintf(buf, size, "(");
    for (int a = 0; a < s->dim && k > 0 && (size_t)k < size; ++a)
        k += snprintf(buf + k, size - (size_t)k, "%s%.6g", a ? ", " : "", p->x[a][i]);
    if (k > 0 && (size_t)k < size) snprintf(buf + k, size - (size_t)k, ")");
}

static int stop_at(const consph_solver *s, size_t i, const char *what)
{
    char pos[128];
    position_text(s, i, pos, sizeof pos);
    const double *id = sv_field((consph_solver *)s, SF_ID, 1);
    return consph_fail(CONSPH_ENUMERIC, "diverged at step %ld (t = %.6g): particle %.0f at %s %s",
                       s->step, s->t, id[i], pos, what);
}

/* 1 when every a[i] is finite: a - a is 0 for a finite value and NaN for any other, so the sum
 * is 0 exactly when all are (in any order: a branch-free loop the compiler may vectorise). */
static int all_finite(const double *a, size_t n)
{
    double acc = 0.0;
#pragma omp simd reduction(+ : acc)
    for (size_t i = 0; i < n; ++i) acc += a[i] - a[i];
    return acc == 0.0;
}

/* Names the first non-finite value: the particle by its initial index, its position, the
 * quantity. After every step, so the common case (all finite) is one cheap sweep per array and
 * the particle is looked for only when there is one. */
int solver_check_finite(consph_solver *s)
{
    consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    static const char *const xs[3] = {"x", "y", "z"}, *const us[3] = {"u", "v", "w"};
    const double *u = sv_field(s, SF_U, d), *rf = sv_field(s, SF_RHOF, 1);
    const double *pr = sv_field(s, SF_P, 1);
    int finite = all_finite(rf, n) && all_finite(pr, n);
    for (int a = 0; a < d && finite; ++a)
        finite = all_finite(p->x[a], n) && all_finite(u + a * cap, n);
    if (finite) return CONSPH_OK;
    for (size_t i = 0; i < n; ++i) {
        char what[64] = "";
        for (int a = 0; a < d && !what[0]; ++a)
            if (!isfinite(p->x[a][i]))
                snprintf(what, sizeof what, "has a non-finite %s", xs[a]);
            else if (!isfinite(u[a * cap + i]))
                snprintf(what, sizeof what, "has a non-finite velocity %s", us[a]);
        if (!what[0] && !isfinite(rf[i]))
            snprintf(what, sizeof what, "has a non-finite density rhof");
        if (!what[0] && !isfinite(pr[i]))
            snprintf(what, sizeof what, "has a non-finite pressure p");
        if (what[0]) return stop_at(s, i, what);
    }
    return CONSPH_OK;
}

/* The particle with the largest v[i] (the smallest id among equals, so that the choice does not
 * depend on the order the particles are in); v is per particle of the current order. */
typedef struct worst {
    size_t i;
    double v;
} worst;

static void worst_take(worst *w, size_t i, double v, const double *id)
{
    if (v > w->v || (v == w->v && id[i] < id[w->i])) {
        w->i = i;
        w->v = v;
    }
}

/* The weakly-compressible model's validity (docs/schemes.md, "Validity of a run"), checked after
 * every step: first that every value is finite (solver_check_finite names the first that is
 * not), then the Mach number |u_i|/c_o, the compression |ϱ_i/ρ_o − 1| (for pe-ipst-c, which
 * evolves p, ϱ = p/c_o² + ρ_o by eq. 31: the same bound on p/(ρ_o c_o²)), and the kinetic energy
 * against the initial one (no problem here has an energy source). Only these cheap quantities:
 * the diagnostics against the exact solution are sampled (solver_sample), this runs after every
 * step. The finiteness and the maxima come from one sweep of the arrays; the maxima are used
 * only once every value is known to be finite.
 * Maxima over the particles with ties to the smallest id: the verdict and the particle named do
 * not depend on the thread count or the particle order. */
int solver_check_valid(consph_solver *s)
{
    const consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    const double *u = sv_field(s, SF_U, d), *rf = sv_field(s, SF_RHOF, 1);
    const double *pr = sv_field(s, SF_P, 1), *id = sv_field(s, SF_ID, 1);
    if (!u || !rf || !pr || !id) return CONSPH_EINVAL;
    /* the kinetic energy's terms are written in the same sweep, which reads u already (with
     * the uniform mass; below with each particle's, where the scheme has them) */
    const consph_field *fm = consph_particles_find(p, SF_MASS);
    const double *mass = fm ? fm->data : NULL, m0 = s->mass;
    double *w = solver_ke_column(s);
    if (!w) return CONSPH_ENOMEM;
    const double r0 = s->prm.rho0;
    /* edac evolves p on its own, with no EOS: its ϱ is a summation density that only weights
     * its sums, and a uniform drift of p moves nothing (its force takes p - p̄) */
    const int compressible = !(s->scheme->evolve_p && s->scheme->closure);
    /* a - a is 0 for a finite a and NaN otherwise, so the sum is 0 exactly when every value is
     * finite, in any order (as all_finite); a maximum is the same in any order: on the threads,
     * the verdict does not depend on their count */
    double u2max = 0.0, cmax = 0.0, nonfinite = 0.0;
    if (d == 2) {
        /* (0 + u²) + v² of the loop below is u² + v²: the same value */
        const double *x0 = p->x[0], *x1 = p->x[1];
#pragma omp parallel for simd schedule(static) reduction(max : u2max, cmax)                       \
    reduction(+ : nonfinite) if (n >= SOLVER_PARALLEL_MIN)
        for (size_t i = 0; i < n; ++i) {
            const double ux = u[i], uy = u[cap + i];
            nonfinite += (x0[i] - x0[i]) + (x1[i] - x1[i]) + (ux - ux) + (uy - uy) +
                         (rf[i] - rf[i]) + (pr[i] - pr[i]);
            const double u2 = ux * ux + uy * uy;
            u2max = u2 > u2max ? u2 : u2max;
            w[i] = kinetic_energy_of(m0, ux, uy, 0.0, 2);
            /* for every particle, and dropped after the loop where it does not apply: a branch
             * here, with the store above, would keep the loop from vectorising */
            const double c = fabs(rf[i] / r0 - 1.0);
            cmax = c > cmax ? c : cmax;
        }
        if (!compressible) cmax = 0.0;
    } else {
#pragma omp parallel for schedule(static) reduction(max : u2max, cmax) reduction(+ : nonfinite) \
    if (n >= SOLVER_PARALLEL_MIN)
        for (size_t i = 0; i < n; ++i) {
            double u2 = 0.0;
            nonfinite += (rf[i] - rf[i]) + (pr[i] - pr[i]);
            for (int a = 0; a < d; ++a) {
                nonfinite += (p->x[a][i] - p->x[a][i]) + (u[a * cap + i] - u[a * cap + i]);
                u2 += u[a * cap + i] * u[a * cap + i];
            }
            u2max = u2 > u2max ? u2 : u2max;
            w[i] = kinetic_energy_of(m0, u[i], d > 1 ? u[cap + i] : 0.0,
                                     d == 3 ? u[2 * cap + i] : 0.0, d);
            if (compressible) {
                const double c = fabs(rf[i] / r0 - 1.0);
                cmax = c > cmax ? c : cmax;
            }
        }
    }
    /* a scheme with masses of its own: their terms in a sweep of their own, so that the loops
     * above stay branch-free (a load of mass[i] or not in the 2D one kept it from vectorising) */
    if (mass)
#pragma omp parallel for schedule(static) if (n >= SOLVER_PARALLEL_MIN)
        for (size_t i = 0; i < n; ++i)
            w[i] = kinetic_energy_of(mass[i], u[i], d > 1 ? u[cap + i] : 0.0,
                                     d == 3 ? u[2 * cap + i] : 0.0, d);
    if (nonfinite != 0.0) {
        const int st = solver_check_finite(s);
        if (st != CONSPH_OK) return st;
    }
    const double ke0 = s->hist[6]; /* row 0: the initial state */
    const double ke = consph_sum(w, n);
    /* the particle to name is looked for only when a bound is passed, by the same expressions */
    if (sqrt(u2max) / s->c0 <= CONSPH_VALID_MACH && cmax <= CONSPH_VALID_COMPRESSION &&
        !(ke > ke0 * (1.0 + CONSPH_VALID_KE_GROWTH)))
        return CONSPH_OK;
    worst fast = {0, -1.0}, comp = {0, -1.0};
    for (size_t i = 0; i < n; ++i) {
        double u2 = 0.0;
        for (int a = 0; a < d; ++a) u2 += u[a * cap + i] * u[a * cap + i];
        worst_take(&fast, i, u2, id);
        if (compressible) worst_take(&comp, i, fabs(rf[i] / r0 - 1.0), id);
    }
    if (n == 0) return CONSPH_OK;
    char what[192];
    const double mach = sqrt(fast.v) / s->c0;
    if (mach > CONSPH_VALID_MACH) {
        snprintf(what, sizeof what,
                 "moves at Mach number |u|/c_o = %.4g, above the bound %g (|u| = %.4g, c_o = %g)",
                 mach, CONSPH_VALID_MACH, sqrt(fast.v), s->c0);
        return stop_at(s, fast.i, what);
    }
    if (comp.v > CONSPH_VALID_COMPRESSION) {
        snprintf(what, sizeof what,
                 "has density |rhof/rho_o - 1| = %.4g, above the bound %g of the "
                 "weakly-compressible range (rhof = %.4g, p = %.4g)",
                 comp.v, CONSPH_VALID_COMPRESSION, rf[comp.i], pr[comp.i]);
        return stop_at(s, comp.i, what);
    }
    if (ke > ke0 * (1.0 + CONSPH_VALID_KE_GROWTH)) {
        snprintf(what, sizeof what,
                 "is the fastest (|u| = %.4g) as the kinetic energy %.6g exceeds its initial "
                 "%.6g by %.4g, above the bound %g (the problem supplies no energy)",
                 sqrt(fast.v), ke, ke0, ke / ke0 - 1.0, CONSPH_VALID_KE_GROWTH);
        return stop_at(s, fast.i, what);
    }
    return CONSPH_OK;
}

int consph_solver_dt_warning(const consph_solver *s, char *buf, size_t size)
{
    const double U = s->prm.U, acoustic = CONSPH_DT_ACOUSTIC * s->h / (U + s->c0);
    const double viscous = s->nu > 0.0 ? CONSPH_DT_VISCOUS * s->h * s->h / s->nu : INFINITY;
    /* a Δt equal to the bound but for the rounding of the default rule is not above it */
    const double slack = 1.0 + 1e-12;
    if (s->dt > acoustic * slack)
        snprintf(buf, size,
                 "dt = %.6g is above the acoustic stability bound %g h/(U + c_o) = %.6g (h = %.6g, "
                 "U = %g, c_o = %g)",
                 s->dt, CONSPH_DT_ACOUSTIC, acoustic, s->h, U, s->c0);
    else if (s->dt > viscous * slack)
        snprintf(buf, size,
                 "dt = %.6g is above the viscous stability bound %g h^2/nu = %.6g (h = %.6g, "
                 "nu = %g)",
                 s->dt, CONSPH_DT_VISCOUS, viscous, s->h, s->nu);
    else
        return 0;
    return 1;
}
