/* The solver: set-up from parameters, time stepping (a step of the integrator's row over the
 * state handed to it, src/integrators/), the equation of state. Its diagnostics are in diag.c,
 * the validity checks after each step in validity.c, the declared fields in state.c, the
 * parameters in params.def/params.c, checkpoints in restore.c and the run with its files in
 * run.c. */
#include <ctype.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "solver/runfiles.h"
#include "regularise/regularise.h"
#include "integrators/integrators.h"
#include "problems/wcref.h"
#include "gpu/gpu_internal.h"
#include "solver/solver_internal.h"
#include "par/par_solver.h"
#include "nnps/nnps_internal.h"

/* Measured peak resident memory per particle (2D, one thread, --out, 160 000 particles): 600
 * bytes for l-rr-c (which keeps a lattice copy), 340-400 for the others, packing included; the
 * estimate leaves room for the threads' buffers and the snapshot writer. In 3D (tensors of 9
 * components; lattice, one thread, --out, 32 768 particles): 930 bytes for l-rr-c, 790 for
 * l-ipst-c, so RUN_BYTES_3D is again about twice the peak. */
#define RUN_BYTES_PER_PARTICLE 1024.0
#define RUN_BYTES_3D 2048.0

int run_nx_fits(int nx, int dim, double memory)
{
    const double each = dim == 3 ? RUN_BYTES_3D : RUN_BYTES_PER_PARTICLE;
    const double n = pow((double)nx, dim), need = n * each;
    const double nmax = (double)CONSPH_RUN_NX_MAX * CONSPH_RUN_NX_MAX;
    const int nx_max = dim == 3 ? (int)floor(cbrt(nmax) + 1e-9) : CONSPH_RUN_NX_MAX;
    if (nx < 4 || nx > nx_max)
        return consph_fail(CONSPH_EINVAL,
                           "--nx must be an integer in [4, %d] (at most %.0f particles in %dD), "
                           "not %d (%.4g particles, about %.3g GiB)",
                           nx_max, nmax, dim, nx, n, need / 1073741824.0);
    return runfiles_memory_check(nx, dim, each, memory);
}

int consph_run_nx_check(int nx, int dim)
{
    return run_nx_fits(nx, dim, runfiles_machine_memory());
}

int consph_problem_dim(const char *problem)
{
    const problem_def *pb = problem_find(problem);
    return pb ? pb->dim : 0;
}

int consph_run_params_layout(const consph_run_params *prm)
{
    const scheme_def *sd = scheme_find(prm->scheme);
    if (prm->layout >= 0) return prm->layout;
    return sd ? (int)sd->layout : -1;
}

/* The solver's EOS of particles [i0, i1): p from ϱ, or ϱ from p where p is evolved (eq. 31). */
static void eos_range(const consph_solver *s, double *restrict rhof, double *restrict pr, size_t i0,
                      size_t i1)
{
    const double c2 = s->c0 * s->c0, r0 = s->prm.rho0, g = s->prm.gamma;
    if (s->scheme->evolve_p) {
        for (size_t i = i0; i < i1; ++i) rhof[i] = pr[i] / c2 + r0; /* eq. 31 */
    } else if (s->eos == CONSPH_EOS_LINEAR) {
        for (size_t i = i0; i < i1; ++i) pr[i] = c2 * (rhof[i] - r0);
    } else {
        const int ig = eos_int_exponent(g); /* Tait's γ = 7: by multiplication */
        if (ig == 7) {
            /* the common case written out, the products in eos_ipow's order (the same bits), so
             * that the loop vectorises */
            for (size_t i = i0; i < i1; ++i) {
                const double x = rhof[i] / r0, x2 = x * x, x4 = x2 * x2;
                pr[i] = r0 * c2 / g * (x * x2 * x4 - 1.0);
            }
        } else {
            for (size_t i = i0; i < i1; ++i) {
                const double x = rhof[i] / r0;
                pr[i] = r0 * c2 / g * ((ig >= 0 ? eos_ipow(x, ig) : pow(x, g)) - 1.0);
            }
        }
    }
}

/* Every particle's EOS in blocks of this many, shared out among the threads. */
#define EOS_BLOCK 4096

void solver_eos(consph_solver *s)
{
    if (s->scheme->closure) {
        s->scheme->closure(s);
        return;
    }
    double *rhof = sv_field(s, SF_RHOF, 1), *pr = sv_field(s, SF_P, 1);
    const size_t n = s->sys.p->n, nb = (n + EOS_BLOCK - 1) / EOS_BLOCK;
#pragma omp parallel for schedule(static) if (n >= SOLVER_PARALLEL_MIN)
    for (size_t b = 0; b < nb; ++b)
        eos_range(s, rhof, pr, b * EOS_BLOCK, b + 1 < nb ? (b + 1) * EOS_BLOCK : n);
}

void solver_taylor_update(consph_solver *s, const double *dr)
{
    consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    double *u = sv_field(s, SF_U, d), *q = sv_field(s, s->scheme->evolve_p ? SF_P : SF_RHOF, 1);
    const double *G = sv_field(s, SF_GRADU, d * d), *gq = sv_field(s, SF_GRADQ, d);
#pragma omp parallel for schedule(static) if (n >= SOLVER_PARALLEL_MIN)
    for (size_t i = 0; i < n; ++i) {
        double dq = 0.0;
        for (int b = 0; b < d; ++b) dq += dr[b * cap + i] * gq[b * cap + i];
        q[i] += dq;
        for (int a = 0; a < d; ++a) {
            double v = 0.0;
            for (int b = 0; b < d; ++b) v += dr[b * cap + i] * G[(size_t)(a * d + b) * cap + i];
            u[a * cap + i] += v;
        }
    }
    solver_eos(s);
}

static double exact_rho(const consph_solver *s, double pr)
{
    const double c2 = s->c0 * s->c0, r0 = s->prm.rho0, g = s->prm.gamma;
    if (s->scheme->evolve_p || s->eos == CONSPH_EOS_LINEAR) return pr / c2 + r0;
    return r0 * pow(1.0 + g * pr / (r0 * c2), 1.0 / g); /* eq. 18 inverted */
}

/* The derived quantities, from the parameters (set-up and restore share them). */
int derive_solver(consph_solver *s)
{
    const consph_run_params *prm = &s->prm;
    s->scheme = scheme_find(prm->scheme);
    s->prob = problem_find(prm->problem);
    s->integ = integ_find(prm->integrator[0] ? prm->integrator : s->scheme->integrator);
    if (!s->integ) return consph_fail(CONSPH_EINVAL, "unknown integrator");
    s->dim = s->prob->dim;
    double volume = 1.0;
    for (int a = 0; a < s->dim; ++a) volume *= s->prob->hi[a] - s->prob->lo[a];
    /* n particles that are not nx^dim (a particle file): the spacing of their mean volume */
    s->ds = prm->n > 0 ? pow(volume / (double)prm->n, 1.0 / s->dim)
                       : (s->prob->hi[0] - s->prob->lo[0]) / prm->nx;
    s->h = prm->hdx * s->ds;
    s->c0 = prm->c0 > 0.0 ? prm->c0 : 10.0 * prm->U;
    s->nu = prm->nu >= 0.0 ? prm->nu : prm->U * (s->prob->hi[0] - s->prob->lo[0]) / prm->re;
    s->mass = prm->rho0 * pow(s->ds, s->dim);
    /* 001 eq. 27 prints δ h c_o², whose units are wrong: docs/deviations.md */
    s->D = prm->delta * s->h * s->c0;
    s->eos = prm->eos == CONSPH_EOS_DEFAULT ? s->scheme->eos : prm->eos;
    s->dt = prm->dt > 0.0 ? prm->dt
                          : prm->cfl * (prm->h_dt > 0.0 ? prm->h_dt : s->h) / (prm->U + s->c0);
    s->tf = prm->tf;
    s->nsteps = prm->steps;
    s->volumes_fixed = !s->scheme->moves;
    /* A regularisation changes the state after the last evaluation, so its rates are stale at
     * the next step's start: those schemes evaluate afresh (pec is then rk2). Kick-drift-kick
     * needs the drift velocity rebuilt from the reused rates, which the transport hook does. */
    s->reuse_rates =
        !s->scheme->regularise &&
        (s->integ->reuses_rates == INTEG_REUSE_ALWAYS ||
         (s->integ->reuses_rates == INTEG_REUSE_WITH_TRANSPORT && s->scheme->transport));
    consph_kernel k;
    int st = consph_kernel_init(&k, prm->kernel, s->dim, s->h);
    if (st != CONSPH_OK) return st;
    s->chi0 = reg_chi0(&k, s->ds);
    return CONSPH_OK;
}

static consph_box problem_box(const problem_def *pb)
{
    consph_box box = consph_box_unit(pb->dim, 1);
    for (int a = 0; a < pb->dim; ++a) {
        box.lo[a] = pb->lo[a];
        box.hi[a] = pb->hi[a];
        box.periodic[a] = pb->periodic[a];
    }
    return box;
}

int consph_run_layout_params(const consph_run_params *prm, consph_layout_params *lp)
{
    const problem_def *pb = problem_find(prm->problem);
    const int kind = consph_run_params_layout(prm);
    if (!pb || kind < 0)
        return consph_fail(CONSPH_EINVAL, "unknown problem '%s' or scheme '%s'", prm->problem,
                           prm->scheme);
    const double ds = (pb->hi[0] - pb->lo[0]) / prm->nx; /* as derive_solver */
    *lp = consph_layout_defaults((consph_layout_kind)kind, pb->dim, (size_t)prm->nx);
    lp->box = problem_box(pb);
    for (int a = 1; a < pb->dim; ++a) /* the spacing Δs of axis 0 on every axis */
        lp->nx[a] = (size_t)lround((lp->box.hi[a] - lp->box.lo[a]) / ds);
    lp->seed = prm->seed;
    lp->packing.hdx = prm->hdx;
    return CONSPH_OK;
}

static int initial_rates(consph_solver *s)
{
    if (s->volumes_fixed) {
        int st = kit_volumes(&s->sys, &s->pairs);
        if (st != CONSPH_OK) return st;
    }
    size_t pairs = s->pairs;
    int st = s->scheme->rhs(s);
    s->pairs = pairs; /* set-up, not time stepping */
    return st;
}

/* Random where /dev/urandom is readable, else from the clock and the process id: it has only to
 * differ between the runs that could share an output directory. */
static void new_run_id(char *id)
{
    uint64_t v = 0;
    FILE *fp = fopen("/dev/urandom", "rb");
    if (fp) {
        if (fread(&v, 1, sizeof v, fp) != sizeof v) v = 0;
        fclose(fp);
    }
    if (v == 0) {
        double w = consph_wtime();
        uint64_t bits;
        memcpy(&bits, &w, sizeof bits);
        v = (bits ^ ((uint64_t)getpid() << 32) ^ (uint64_t)time(NULL)) * 0x9E3779B97F4A7C15u;
    }
    snprintf(id, CONSPH_RUN_ID_LEN + 1, "%016" PRIx64, v);
}

const char *consph_solver_run_id(const consph_solver *s)
{
    return s->run_id;
}

/* The given particles as consph_layout_generate makes a layout: positions in the problem's box,
 * the run's spacing and the field "volume" = box volume / N; "u" and "p" are the caller's. With
 * a range, its particles only, `in` holding the n or the range's (*off: the first one's place
 * in `in`). */
static int given_particles(const consph_solver *s, const consph_particles *in,
                           const solver_range *range, consph_particles *p, size_t *off)
{
    const size_t n = s->prm.n > 0 ? (size_t)s->prm.n : (size_t)lround(pow(s->prm.nx, s->dim));
    const consph_box box = problem_box(s->prob);
    const size_t lo = range ? range->lo : 0, m = range ? range->hi - range->lo : n;
    *off = range && in->n == n ? lo : 0;
    if (in->dim != s->dim || (in->n != n && !(range && range->n == n && in->n == m)))
        return consph_fail(CONSPH_EINVAL,
                           "the given particles (%zu in %dD) are not the %zu in %dD of nx = %d, "
                           "n = %ld (consph_run_params_particles sets them)",
                           in->n, in->dim, n, s->dim, s->prm.nx, s->prm.n);
    for (int a = 0; a < s->dim; ++a)
        if (in->box.lo[a] != box.lo[a] || in->box.hi[a] != box.hi[a] ||
            !in->box.periodic[a] != !box.periodic[a])
            return consph_fail(CONSPH_EINVAL,
                               "the given particles' box or periodicity on axis %d is not that of "
                               "problem '%s'",
                               a, s->prob->name);
    for (int a = 0; a < s->dim; ++a)
        for (size_t i = *off; i < *off + m; ++i)
            if (!(in->x[a][i] >= box.lo[a] && in->x[a][i] < box.hi[a]))
                return consph_fail(CONSPH_EINVAL,
                                   "given particle %zu: coordinate %d = %.17g is not in [%.17g, "
                                   "%.17g) (the box of problem '%s')",
                                   i - *off + lo, a, in->x[a][i], box.lo[a], box.hi[a],
                                   s->prob->name);
    static const char *const named[2] = {"u", "p"};
    for (int k = 0; k < 2; ++k) {
        const consph_field *f = consph_particles_find(in, named[k]);
        if (f && f->ncomp != (k ? 1 : s->dim))
            return consph_fail(CONSPH_EINVAL, "the given field '%s' has %d components, not %d",
                               named[k], f->ncomp, k ? 1 : s->dim);
    }
    int st = consph_particles_init(p, s->dim, m, &box);
    if (st != CONSPH_OK) return st;
    p->spacing = s->ds;
    for (int a = 0; a < s->dim; ++a) memcpy(p->x[a], in->x[a] + *off, m * sizeof(double));
    double *vol = consph_particles_field(p, "volume", 1);
    if (!vol) return CONSPH_ENOMEM;
    const double v = consph_box_volume(&box) / (double)n;
    for (size_t i = 0; i < m; ++i) vol[i] = v;
    return CONSPH_OK;
}

/* The given field `name`'s data (components cap apart), NULL when there is none. */
static const double *given_field(const consph_particles *in, const char *name)
{
    const consph_field *f = in ? consph_particles_find(in, name) : NULL;
    return f ? f->data : NULL;
}

/* The diagnostics at t = 0 (over the whole set: solver_global, when the set-up was cut). */
static int first_sample(consph_solver *s, void *arg)
{
    (void)arg;
    int st = solver_sample(s);
    if (st == CONSPH_OK && s->prm.error == CONSPH_ERROR_AUTHORS)
        st = solver_auth_sample(s); /* t = 0 is the first output time */
    return st;
}

int consph_solver_create(consph_solver **out, const consph_run_params *prm)
{
    return consph_solver_create_from(out, prm, NULL);
}

int consph_solver_create_from(consph_solver **out, const consph_run_params *prm,
                              const consph_particles *given)
{
    return solver_create_cut(out, prm, given, NULL, NULL, NULL);
}

int solver_create_cut(consph_solver **out, const consph_run_params *prm,
                      const consph_particles *given, const solver_range *range,
                      int (*cut)(consph_solver *s, void *arg, int status), void *arg)
{
    *out = NULL;
    int st = consph_run_params_check(prm);
    if (st != CONSPH_OK) return st;
    if (prm->n > 0 && !given)
        return consph_fail(CONSPH_EINVAL,
                           "n = %ld: a run of n particles starts from given "
                           "particles, not from a layout",
                           prm->n);
    const int dim = consph_problem_dim(prm->problem);
    if (prm->n > 0 && prm->nx != lround(pow((double)prm->n, 1.0 / dim)))
        return consph_fail(CONSPH_EINVAL,
                           "n = %ld particles go with nx = %ld (n^(1/%d) rounded), not nx = %d",
                           prm->n, lround(pow((double)prm->n, 1.0 / dim)), dim, prm->nx);
    consph_solver *s = consph_calloc(1, sizeof *s);
    if (!s) return CONSPH_ENOMEM;
    s->prm = *prm;
    new_run_id(s->run_id);
    st = derive_solver(s);
    consph_layout_params lp;
    memset(&lp, 0, sizeof lp);
    if (st == CONSPH_OK) st = consph_run_layout_params(prm, &lp);
    consph_particles src = {0}, lat = {0};
    size_t goff = 0; /* the place of src's first particle in `given` */
    if (st == CONSPH_OK && given) {
        st = given_particles(s, given, range, &src, &goff);
    } else if (st == CONSPH_OK && range && range->made) {
        src = *range->made;
        memset(range->made, 0, sizeof *range->made);
    } else if (st == CONSPH_OK)
        st = range ? consph_layout_generate_range(&lp, range->lo, range->hi - range->lo, &src)
                   : consph_layout_generate(&lp, &src, NULL);
    consph_kernel k;
    if (st == CONSPH_OK) st = consph_kernel_init(&k, prm->kernel, s->dim, s->h);
    if (st == CONSPH_OK) st = consph_sys_init(&s->sys, &src, &k, 0.0);
    if (st == CONSPH_OK && s->scheme->needs_lattice) {
        consph_layout_params ll = lp;
        ll.kind = CONSPH_LAYOUT_LATTICE;
        st = consph_layout_generate(&ll, &lat, NULL);
    }
    if (st == CONSPH_OK) st = state_create(s);
    /* cut: the neighbour list and the initial rates are made on this rank's part only */
    if (st == CONSPH_OK && !cut) st = solver_nlist_start(s, 0);
    if (st == CONSPH_OK) {
        consph_particles *p = s->sys.p;
        const size_t n = p->n, cap = p->cap;
        double *id = sv_field(s, SF_ID, 1), *u = sv_field(s, SF_U, s->dim);
        double *pr = sv_field(s, SF_P, 1), *rhof = sv_field(s, SF_RHOF, 1);
        double *xl = lat.n ? sv_field(s, SF_LATTICE, s->dim) : NULL;
        const double *gu = given_field(given, "u"), *gp = given_field(given, "p");
        const size_t gcap = given ? given->cap : 0;
        if (!id || !u || !pr || !rhof || (lat.n && !xl)) st = CONSPH_ENOMEM;
        for (size_t i = 0; st == CONSPH_OK && i < n; ++i) {
            double x[3], ue[3], pe;
            solver_position_of(p, i, x);
            s->prob->exact(prm, 0.0, x, ue, &pe);
            const size_t o = s->sys.origin[i];
            id[i] = (double)(o + (range ? range->lo : 0));
            for (int a = 0; a < s->dim; ++a) u[a * cap + i] = gu ? gu[a * gcap + goff + o] : ue[a];
            if (gp) pe = gp[goff + o];
            pr[i] = pe;
            rhof[i] = prm->rho_init == CONSPH_RHO_INIT_RHO0 ? prm->rho0 : exact_rho(s, pe);
            if (xl)
                for (int a = 0; a < s->dim; ++a) xl[a * cap + i] = lat.x[a][(size_t)id[i]];
        }
    }
    consph_particles_free(&src);
    consph_particles_free(&lat);
    if (st == CONSPH_OK && prm->rho_init == CONSPH_RHO_INIT_RHO0) solver_eos(s);
    if (cut) st = cut(s, arg, st);
    if (st == CONSPH_OK && cut) st = solver_nlist_start(s, 0);
    s->step_dt = s->dt;
    if (st == CONSPH_OK) st = initial_rates(s);
    if (st == CONSPH_OK) st = state_undeclared(s, 0);
    if (st == CONSPH_OK)
        st = s->par ? par_global_some(s, first_sample, NULL, solver_sample_fields)
                    : first_sample(s, NULL);
    if (st == CONSPH_OK && s->par) st = par_share_history(s);
    if (prm->error == CONSPH_ERROR_AUTHORS) s->auth_next = 1;
    if (st != CONSPH_OK) {
        consph_solver_free(s);
        return st;
    }
    *out = s;
    return CONSPH_OK;
}

void consph_solver_free(consph_solver *s)
{
    if (!s) return;
    /* first: a sample on the host thread reads the particles and writes the history */
    solver_sampler_free(s);
    if (getenv("CONSPH_SAMPLE_SECONDS")) {
        const double *t = s->sample_seconds;
        fprintf(stderr,
                "consph: %ld log samples; all samples: copy back %.4f s, search %.4f s, checks "
                "%.4f s, diagnostics %.4f s, authors' measure %.4f s, reference steps %.4f s, "
                "reference evaluation %.4f s, reference rest %.4f s\n",
                s->sample_count, t[SAMPLE_COPY], t[SAMPLE_SEARCH], t[SAMPLE_CHECKS], t[SAMPLE_DIAG],
                t[SAMPLE_AUTH], t[SAMPLE_WC_STEPS], t[SAMPLE_WC_EVAL], t[SAMPLE_WC_REST]);
    }
    gpu_free(s->gpu);
    consph_sys_free(&s->sys);
    free(s->hist);
    free(s->diag_buf);
    free(s->integ_scratch);
    wcref_free(s->wc);
    free(s->wc_buf);
    par_solver_free(s->par);
    free(s->part);
    free(s);
}

/* ---- time stepping ---- */

/* Positions are wrapped in blocks of this many: a block with none to wrap (nearly all of them) is
 * one vectorised sweep of minima and maxima. */
#define WRAP_BLOCK 1024

/* Brings every coordinate on a periodic axis back into the box; 1 when each then lies in
 * [lo, hi) of the box (what the search's build would otherwise check again). A NaN is neither
 * wrapped nor counted: the build bins it to the same cell either way. */
static int wrap_positions(consph_solver *s)
{
    consph_particles *p = s->sys.p;
    const size_t n = p->n, nb = (n + WRAP_BLOCK - 1) / WRAP_BLOCK;
    int outside = 0;
    /* one parallel region for every axis */
#pragma omp parallel if (n >= SOLVER_PARALLEL_MIN) reduction(| : outside)
    for (int a = 0; a < s->dim; ++a) {
        if (!p->box.periodic[a]) continue;
        const double lo = p->box.lo[a], hi = p->box.hi[a], L = hi - lo;
        /* below both lo + L (where the wrap starts) and hi (where the box ends) */
        const double top = lo + L < hi ? lo + L : hi;
        double *x = p->x[a];
#pragma omp for schedule(static) nowait
        for (size_t b = 0; b < nb; ++b) {
            const size_t i0 = b * WRAP_BLOCK, i1 = i0 + WRAP_BLOCK < n ? i0 + WRAP_BLOCK : n;
            double mn = lo, mx = lo;
#pragma omp simd reduction(min : mn) reduction(max : mx)
            for (size_t i = i0; i < i1; ++i) {
                mn = x[i] < mn ? x[i] : mn;
                mx = x[i] > mx ? x[i] : mx;
            }
            if (mn >= lo && mx < top) continue;
            for (size_t i = i0; i < i1; ++i) {
                if (x[i] < lo || x[i] >= lo + L) {
                    x[i] -= L * floor((x[i] - lo) / L);
                    if (x[i] >= lo + L) x[i] = lo; /* rounding of a tiny negative offset */
                }
                outside |= x[i] < lo || x[i] >= hi;
            }
        }
    }
    return !outside;
}

/* The integrator's callbacks (integrators.h): the scheme's right-hand side, closure and
 * transport hook, and the drift's wrap and search rebuild. */
static int integ_rates(void *ctx)
{
    consph_solver *s = ctx;
    return s->scheme->rhs(s);
}

static void integ_close(void *ctx)
{
    solver_eos(ctx);
}

/* The solver's EOS of a block of particles, in the update's sweep (a scheme's own closure has no
 * such form). */
static void integ_close_range(void *ctx, size_t i0, size_t i1)
{
    const consph_solver *s = ctx;
    eos_range(s, s->eos_rhof, s->eos_p, i0, i1);
}

static void integ_transport(void *ctx, double c)
{
    consph_solver *s = ctx;
    s->scheme->transport(s, c);
}

/* Whether the search is made afresh from the positions at every move (no neighbour list with a
 * skin, not cut over ranks, not on a GPU): then the build after a step's last drift, or after
 * the regularisation's last move (it moves only through a rebuild, which takes back the word of
 * an earlier build), is the build its next step's re-sort would make. */
static int search_follows_drift(const consph_solver *s)
{
    return !s->par && !s->gpu && !(s->prm.skin > 0.0);
}

static int integ_moved(void *ctx)
{
    consph_solver *s = ctx;
    /* the word holds for the update's build, if it makes one (a list with a skin may keep its
     * last): taken back after it */
    const int inside = wrap_positions(s) && !s->sys.split;
    if (inside) nnps_positions_inside(s->sys.nnps, s->sys.p->box.lo, s->sys.p->box.hi);
    const int st = consph_sys_update(&s->sys, 0);
    if (inside) nnps_positions_inside(s->sys.nnps, NULL, NULL);
    if (st == CONSPH_OK && search_follows_drift(s)) nnps_build_is_current(s->sys.nnps);
    return st;
}

/* Whether the step's first update reads the last rates through the re-sort's permutation
 * (integ_state.kperm) instead of the re-sort moving them: a step that starts from them with no
 * transport hook (whose drift velocity would be rebuilt from other rates), after a re-sort that
 * always leaves its permutation in the system's buffer (no list with a skin). */
static int rates_by_perm(const consph_solver *s)
{
    return s->reuse_rates && !s->scheme->transport && search_follows_drift(s);
}

/* The re-sort into cell order at a step's start, carrying only the fields whose values the
 * step or the output can read before writing them (state_carried), and not the last rates
 * where the first update reads them through the permutation (rates_by_perm): the others are
 * hidden from the permutation and put back in their places after it. */
static int resort_carried(consph_solver *s)
{
    consph_particles *p = s->sys.p;
    consph_field all[CONSPH_MAX_FIELDS];
    const int nf = p->nfields, by_perm = rates_by_perm(s);
    memcpy(all, p->fields, (size_t)nf * sizeof all[0]);
    int k = 0;
    for (int f = 0; f < nf; ++f)
        if (state_carried(s, all[f].name) &&
            !(by_perm && (!strcmp(all[f].name, SF_AU) || !strcmp(all[f].name, SF_AQ) ||
                          !strcmp(all[f].name, SF_AX))))
            p->fields[k++] = all[f];
    p->nfields = k;
    const int st = consph_sys_update(&s->sys, 1);
    memcpy(p->fields, all, (size_t)nf * sizeof all[0]);
    p->nfields = nf;
    return st;
}

/* The integrator's view of the state. The start-of-step copies are created here on the first
 * step, in the order u0, q0, x0 (the order of the particles' fields is that of the snapshots'
 * arrays). The row's scratch lives outside the particles: it is dead between steps, so neither
 * the re-sorting nor a snapshot or checkpoint needs it. */
static int integ_state_of(consph_solver *s, integ_state *is)
{
    consph_particles *p = s->sys.p;
    const int d = s->dim, moves = s->scheme->moves;
    memset(is, 0, sizeof *is);
    is->dim = d;
    is->n = p->n;
    is->cap = p->cap;
    is->u = sv_field(s, SF_U, d);
    is->q = sv_field(s, s->scheme->evolve_p ? SF_P : SF_RHOF, 1);
    is->u0 = sv_field(s, SF_U0, d);
    is->q0 = sv_field(s, SF_Q0, 1);
    is->x0 = moves ? sv_field(s, SF_X0, d) : NULL;
    is->au = sv_field(s, SF_AU, d);
    is->aq = sv_field(s, SF_AQ, 1);
    is->ax = moves ? sv_field(s, SF_AX, d) : NULL;
    if (!is->u || !is->q || !is->u0 || !is->q0 || !is->au || !is->aq ||
        (moves && (!is->x0 || !is->ax)))
        return CONSPH_ENOMEM;
    for (int a = 0; a < d; ++a) is->x[a] = p->x[a];
    const int ns = integ_scratch_count(s->integ);
    if (ns > INTEG_SCRATCH_MAX)
        return consph_fail(CONSPH_EINVAL, "integrator %s: %d scratch arrays, at most %d",
                           s->integ->name, ns, INTEG_SCRATCH_MAX);
    size_t off[INTEG_SCRATCH_MAX], total = 0;
    for (int k = 0; k < ns; ++k) {
        const integ_shape like = s->integ->scratch[k].like;
        const int nc = like == INTEG_LIKE_Q ? 1 : (like == INTEG_LIKE_X && !moves) ? 0 : d;
        off[k] = nc ? total : (size_t)-1;
        total += (size_t)nc * p->cap;
    }
    if (total && !s->integ_scratch) {
        s->integ_scratch = malloc(total * sizeof(double));
        if (!s->integ_scratch) return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    for (int k = 0; k < ns; ++k)
        is->scratch[k] = off[k] == (size_t)-1 ? NULL : s->integ_scratch + off[k];
    is->ctx = s;
    is->rates = integ_rates;
    is->close = integ_close;
    s->eos_rhof = sv_field(s, SF_RHOF, 1);
    s->eos_p = sv_field(s, SF_P, 1);
    if (!s->eos_rhof || !s->eos_p) return CONSPH_ENOMEM;
    is->close_range = s->scheme->closure ? NULL : integ_close_range;
    is->transport = s->scheme->transport ? integ_transport : NULL;
    is->moved = integ_moved;
    /* the permutation of the re-sort just made (consph_sys_update leaves it there) */
    is->kperm = moves && !s->par && rates_by_perm(s) ? s->sys.resort_buf : NULL;
    return CONSPH_OK;
}

int solver_global(consph_solver *s, int (*fn)(consph_solver *s, void *arg), void *arg)
{
    return s->par ? par_global(s, fn, arg) : fn(s, arg);
}

/* What follows a step and reads every particle: the checks, the diagnostics' sample, the
 * authors' measure. */
typedef struct step_close_arg {
    int landed;
    int on_host; /* 0: a GPU step that left the particles on the device (nothing to check) */
    double dt;
} step_close_arg;

/* step_close's part after the checks: the diagnostics' sample when due and the authors'
 * measure (decomposed with solver_sample_owned, on every rank). */
static int step_sample(consph_solver *s, const step_close_arg *a)
{
    int st = CONSPH_OK;
    s->log_since += a->dt;
    s->step_dt = a->dt;
    if (s->step % s->prm.log_every == 0 || consph_solver_done(s)) st = solver_sample_overlapped(s);
    if (st == CONSPH_OK && s->prm.error == CONSPH_ERROR_AUTHORS)
        st = solver_auth_after_step(s, a->landed);
    return st;
}

static int step_close(consph_solver *s, void *arg)
{
    const step_close_arg *a = arg;
    int st = CONSPH_OK, on_host = a->on_host;
    /* a GPU run's state comes back for the authors' measure at its output times only, the
     * arrays the measure, the checks and the diagnostics read */
    if (!on_host && s->prm.error == CONSPH_ERROR_AUTHORS && solver_auth_due(s, a->landed)) {
        st = gpu_download_sample(s);
        on_host = 1;
    }
    if (st == CONSPH_OK && on_host) {
        const double t0 = consph_wtime();
        st = solver_check_valid(s);
        s->sample_seconds[SAMPLE_CHECKS] += consph_wtime() - t0;
    }
    return st == CONSPH_OK ? step_sample(s, a) : st;
}

int consph_solver_step(consph_solver *s)
{
    if (consph_solver_done(s)) return consph_fail(CONSPH_EINVAL, "the run is complete");
    double t0 = consph_wtime();
    double dt = s->dt;
    /* the authors' measure lands on its output times as PySPH's output_at_times does, with
     * its tolerance against a vanishing step just short of one */
    const int auth_tf =
        s->prm.error == CONSPH_ERROR_AUTHORS && s->nsteps == 0 && s->auth_next < s->prm.error_times;
    const double target = auth_tf ? solver_auth_time(s, s->auth_next) : s->tf;
    int landed = 0;
    if (auth_tf && s->t + dt > target - 1e-9 * dt) {
        dt = target - s->t;
        landed = 1;
    } else if (s->nsteps == 0 && s->t + dt > s->tf) {
        dt = s->tf - s->t; /* land on tf */
    }
    const double full = s->dt;
    s->dt = dt;
    const double t_next =
        auth_tf ? (landed ? target : s->t + dt) : (s->nsteps == 0 && dt < full ? s->tf : s->t + dt);
    const int last = s->nsteps > 0 ? s->step + 1 >= s->nsteps : t_next >= s->tf;
    s->grads_skip =
        s->grads_lazy && !last && !(s->grads_every > 0 && (s->step + 1) % s->grads_every == 0);
    int st = CONSPH_OK;
    /* on the GPU the host's particles are this step's only when the step copied them back */
    int on_host = 1;
    if (s->gpu) {
        st = gpu_step(s, dt, &on_host);
    } else {
        if (s->scheme->moves) st = s->par ? par_step_begin(s) : resort_carried(s);
        integ_state is;
        if (st == CONSPH_OK) st = integ_state_of(s, &is);
        /* pec and kdk start from the rates the previous step left (the set-up's for the first);
         * nothing then runs before the step, whose first update saves the start as it reads it.
         * The others evaluate the rates first, which leaves u, q and x as they are
         * (scheme_def.rhs) unless the scheme says its rates write q (rhs_writes_q: tvf's
         * summation density): the first update saves the start then too, instead of a copy
         * before the right-hand side. Decomposed, the passes' halo refresh writes the halo's u,
         * q and x: saved before. */
        is.unsaved = s->reuse_rates || (!s->par && !s->scheme->rhs_writes_q);
        if (st == CONSPH_OK && !is.unsaved) integ_save_start(&is);
        if (st == CONSPH_OK && !s->reuse_rates) st = s->scheme->rhs(s);
        if (st == CONSPH_OK) st = s->integ->step(&is, dt);
    }
    if (st == CONSPH_OK) {
        s->t = t_next;
        ++s->step;
    }
    if (st == CONSPH_OK && s->scheme->regularise)
        st = s->gpu ? gpu_regularise(s, &on_host) : s->scheme->regularise(s);
    if (st == CONSPH_OK && s->scheme->regularise && s->scheme->moves && search_follows_drift(s))
        nnps_build_is_current(s->sys.nnps);
    if (s->par) st = par_step_end(s, st);
    if (st == CONSPH_OK) {
        step_close_arg a = {landed, on_host, dt};
        /* decomposed, the checks' verdict is taken over the ranks, and then the sample (if
         * any) on every rank from its owned particles (solver_sample_owned); a failed check,
         * or a sample against --exact wc's reference, gathers what the checks and the sample
         * read (one list) to rank 0, for the serial message and the reference there */
        const int samples = s->step % s->prm.log_every == 0 || consph_solver_done(s) ||
                            s->prm.error == CONSPH_ERROR_AUTHORS;
        int clean = 0;
        if (s->par && (!samples || solver_sample_owned(s))) st = par_checks_clean(s, &clean);
        if (st == CONSPH_OK && clean) {
            st = step_sample(s, &a);
        } else if (st == CONSPH_OK) {
            /* a sample gathers what it reads; the files that follow stream every array */
            st = s->par ? par_global_some(s, step_close, &a, solver_sample_fields)
                        : solver_global(s, step_close, &a);
            /* the next output time, which the next step's length reads on every rank (the
             * gathered step_close moved it on rank 0 only) */
            if (st == CONSPH_OK && s->par && par_rank(s) != 0 &&
                s->prm.error == CONSPH_ERROR_AUTHORS)
                solver_auth_advance(s, landed);
        }
    }
    s->dt = full;
    s->grads_skip = 0;
    s->seconds += consph_wtime() - t0;
    return st;
}

int consph_solver_done(const consph_solver *s)
{
    return s->nsteps > 0 ? s->step >= s->nsteps : s->t >= s->tf;
}

long consph_solver_step_count(const consph_solver *s)
{
    return s->step;
}
double consph_solver_time(const consph_solver *s)
{
    return s->t;
}
double consph_solver_dt(const consph_solver *s)
{
    return s->dt;
}
const consph_run_params *consph_solver_params(const consph_solver *s)
{
    return &s->prm;
}
const consph_particles *consph_solver_particles(const consph_solver *s)
{
    return s->sys.p;
}
