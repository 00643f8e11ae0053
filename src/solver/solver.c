/* The solver: set-up from parameters, time stepping (a step of the integrator's row over the
 * state handed to it, src/integrators/), the equation of state, diagnostics, and the state a
 * checkpoint holds. */
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
#include "solver/solver_internal.h"

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
    if (dim == 2) return runfiles_memory_check(nx, RUN_BYTES_PER_PARTICLE, memory);
    if (memory > 0.0 && need > memory)
        return consph_fail(CONSPH_EINVAL,
                           "--nx %d: %.4g particles (nx^3) need about %.3g GiB (%.0f bytes each), "
                           "more than this machine's memory (%.3g GiB)",
                           nx, n, need / 1073741824.0, each, memory / 1073741824.0);
    return CONSPH_OK;
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

void solver_eos(consph_solver *s)
{
    if (s->scheme->closure) {
        s->scheme->closure(s);
        return;
    }
    consph_particles *p = s->sys.p;
    double *rhof = sv_field(s, SF_RHOF, 1), *pr = sv_field(s, SF_P, 1);
    const double c2 = s->c0 * s->c0, r0 = s->prm.rho0, g = s->prm.gamma;
    const size_t n = p->n;
    if (s->scheme->evolve_p) {
#pragma omp parallel for schedule(static) if (n >= SOLVER_PARALLEL_MIN)
        for (size_t i = 0; i < n; ++i) rhof[i] = pr[i] / c2 + r0; /* eq. 31 */
    } else if (s->eos == CONSPH_EOS_LINEAR) {
#pragma omp parallel for schedule(static) if (n >= SOLVER_PARALLEL_MIN)
        for (size_t i = 0; i < n; ++i) pr[i] = c2 * (rhof[i] - r0);
    } else {
#pragma omp parallel for schedule(static) if (n >= SOLVER_PARALLEL_MIN)
        for (size_t i = 0; i < n; ++i) pr[i] = r0 * c2 / g * (pow(rhof[i] / r0, g) - 1.0);
    }
}

void solver_taylor_update(consph_solver *s, const double *dr)
{
    consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    double *u = sv_field(s, SF_U, d), *q = sv_field(s, s->scheme->evolve_p ? SF_P : SF_RHOF, 1);
    const double *G = sv_field(s, SF_GRADU, d * d), *gq = sv_field(s, SF_GRADQ, d);
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
    s->ds = (s->prob->hi[0] - s->prob->lo[0]) / prm->nx;
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

static int hist_push(consph_solver *s, const consph_step_diag *g)
{
    if (s->nhist == s->caphist) {
        size_t cap = s->caphist ? 2 * s->caphist : 256;
        double *h = realloc(s->hist, cap * HIST_COLS * sizeof(double));
        if (!h) return consph_fail(CONSPH_ENOMEM, "out of memory for the run history");
        s->hist = h;
        s->caphist = cap;
    }
    double row[HIST_COLS] = {(double)g->step, g->t,       g->l1_u,     g->linf_u, g->l1_p,
                             g->linf_p,       g->ke,      g->mom[0],   g->mom[1], g->mom[2],
                             g->ang,          g->ft_fmax, g->max_divu, s->dt};
    memcpy(s->hist + s->nhist * HIST_COLS, row, sizeof row);
    ++s->nhist;
    return CONSPH_OK;
}

/* ---- the authors' error measure (consph_error_kind) ---- */

/* x of particle i as the problems take it: every coordinate of the run, 0 beyond. */
static void position_of(const consph_particles *p, size_t i, double x[3])
{
    for (int a = 0; a < 3; ++a) x[a] = a < p->dim ? p->x[a][i] : 0.0;
}

/* |u| over d components; in 2D hypot, as the 2D runs have always computed it. */
static double speed(const double u[3], int d)
{
    return d == 2 ? hypot(u[0], u[1]) : sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
}

static double max_abs(const double *a, size_t n)
{
    double m = 0.0;
    for (size_t i = 0; i < n; ++i) m = fmax(m, fabs(a[i]));
    return m;
}

/* Output time k with --tf; the last is t_f itself, not a rounding of it. */
static double auth_time(const consph_solver *s, int k)
{
    const int last = s->prm.error_times - 1;
    return k >= last ? s->tf : s->tf * (double)k / (double)last;
}

/* With --steps: the step whose end is output time k. */
static long auth_step(const consph_solver *s, int k)
{
    return lround((double)s->nsteps * (double)k / (double)(s->prm.error_times - 1));
}

/* Adds this instant's normalised errors of 001's post-processing to the sums. Runs right after
 * consph_solver_diag, whose buffer is large enough. */
static int auth_sample(consph_solver *s)
{
    const consph_particles *p = s->sys.p;
    const size_t n = p->n, cap = p->cap;
    const double *u = sv_field(s, SF_U, s->dim), *pr = sv_field(s, SF_P, 1);
    if (!u || !pr || s->diag_cap < 4 * n) return consph_fail(CONSPH_EINVAL, "solver state missing");
    double eu_n = NAN, ep_n = NAN;
    if (s->prob->has_exact || s->t == 0.0) {
        double *eu = s->diag_buf, *mu = eu + n, *ep = eu + 2 * n, *pe = eu + 3 * n;
#pragma omp parallel for schedule(static) if (n >= SOLVER_PARALLEL_MIN)
        for (size_t i = 0; i < n; ++i) {
            double x[3], ue[3];
            position_of(p, i, x);
            s->prob->exact(&s->prm, s->t, x, ue, &pe[i]);
            mu[i] = speed(ue, s->dim);
            const double ui[3] = {u[i], u[cap + i], s->dim == 3 ? u[2 * cap + i] : 0.0};
            eu[i] = fabs(speed(ui, s->dim) - mu[i]);
            ep[i] = fabs(pr[i] - pe[i]);
        }
        /* mean/mean for u, mean/max for p: taylor_green.py, post_process */
        eu_n = consph_sum(eu, n) / consph_sum(mu, n);
        ep_n = consph_sum(ep, n) / (double)n / max_abs(pe, n);
    }
    s->auth_u_acc += eu_n;
    s->auth_p_acc += ep_n;
    ++s->auth_n;
    return CONSPH_OK;
}

/* After a step: samples when it ended on the next output time. `landed`: a --tf run's step was
 * cut to end on it. */
static int auth_after_step(consph_solver *s, int landed)
{
    int hit = 0;
    if (s->nsteps == 0) {
        hit = landed;
        s->auth_next += hit;
    } else {
        /* several output times may round to one step: it is sampled once */
        while (s->auth_next < s->prm.error_times && auth_step(s, s->auth_next) <= s->step) {
            hit |= auth_step(s, s->auth_next) == s->step;
            ++s->auth_next;
        }
    }
    return hit ? auth_sample(s) : CONSPH_OK;
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

int consph_solver_create(consph_solver **out, const consph_run_params *prm)
{
    *out = NULL;
    int st = consph_run_params_check(prm);
    if (st != CONSPH_OK) return st;
    consph_solver *s = consph_calloc(1, sizeof *s);
    if (!s) return CONSPH_ENOMEM;
    s->prm = *prm;
    new_run_id(s->run_id);
    st = derive_solver(s);
    consph_layout_kind kind =
        prm->layout >= 0 ? (consph_layout_kind)prm->layout : s->scheme->layout;
    consph_layout_params lp = consph_layout_defaults(kind, s->dim, (size_t)prm->nx);
    lp.box = problem_box(s->prob);
    for (int a = 1; a < s->dim; ++a) /* the spacing Δs of axis 0 on every axis */
        lp.nx[a] = (size_t)lround((lp.box.hi[a] - lp.box.lo[a]) / s->ds);
    lp.seed = prm->seed;
    lp.packing.hdx = prm->hdx;
    consph_particles src = {0}, lat = {0};
    if (st == CONSPH_OK) st = consph_layout_generate(&lp, &src, NULL);
    consph_kernel k;
    if (st == CONSPH_OK) st = consph_kernel_init(&k, prm->kernel, s->dim, s->h);
    if (st == CONSPH_OK) st = consph_sys_init(&s->sys, &src, &k, 0.0);
    if (st == CONSPH_OK && s->scheme->needs_lattice) {
        consph_layout_params ll = lp;
        ll.kind = CONSPH_LAYOUT_LATTICE;
        st = consph_layout_generate(&ll, &lat, NULL);
    }
    if (st == CONSPH_OK) st = state_create(s);
    if (st == CONSPH_OK) {
        consph_particles *p = s->sys.p;
        const size_t n = p->n, cap = p->cap;
        double *id = sv_field(s, SF_ID, 1), *u = sv_field(s, SF_U, s->dim);
        double *pr = sv_field(s, SF_P, 1), *rhof = sv_field(s, SF_RHOF, 1);
        double *xl = lat.n ? sv_field(s, SF_LATTICE, s->dim) : NULL;
        if (!id || !u || !pr || !rhof || (lat.n && !xl)) st = CONSPH_ENOMEM;
        for (size_t i = 0; st == CONSPH_OK && i < n; ++i) {
            double x[3], ue[3], pe;
            position_of(p, i, x);
            s->prob->exact(prm, 0.0, x, ue, &pe);
            id[i] = (double)s->sys.origin[i];
            for (int a = 0; a < s->dim; ++a) u[a * cap + i] = ue[a];
            pr[i] = pe;
            rhof[i] = prm->rho_init == CONSPH_RHO_INIT_RHO0 ? prm->rho0 : exact_rho(s, pe);
            if (xl)
                for (int a = 0; a < s->dim; ++a) xl[a * cap + i] = lat.x[a][s->sys.origin[i]];
        }
    }
    consph_particles_free(&src);
    consph_particles_free(&lat);
    if (st == CONSPH_OK && prm->rho_init == CONSPH_RHO_INIT_RHO0) solver_eos(s);
    consph_step_diag g;
    if (st == CONSPH_OK) st = initial_rates(s);
    if (st == CONSPH_OK) st = state_undeclared(s, 0);
    if (st == CONSPH_OK) st = consph_solver_diag(s, &g);
    if (st == CONSPH_OK) st = hist_push(s, &g);
    if (st == CONSPH_OK && prm->error == CONSPH_ERROR_AUTHORS) {
        st = auth_sample(s); /* t = 0 is the first output time */
        s->auth_next = 1;
    }
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
    consph_sys_free(&s->sys);
    free(s->hist);
    free(s->diag_buf);
    free(s->integ_scratch);
    free(s);
}

/* ---- time stepping ---- */

static void wrap_positions(consph_solver *s)
{
    consph_particles *p = s->sys.p;
    for (int a = 0; a < s->dim; ++a) {
        if (!p->box.periodic[a]) continue;
        const double lo = p->box.lo[a], L = p->box.hi[a] - lo;
        double *x = p->x[a];
        for (size_t i = 0; i < p->n; ++i) {
            if (x[i] < lo || x[i] >= lo + L) {
                x[i] -= L * floor((x[i] - lo) / L);
                if (x[i] >= lo + L) x[i] = lo; /* rounding of a tiny negative offset */
            }
        }
    }
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

static void integ_transport(void *ctx, double c)
{
    consph_solver *s = ctx;
    s->scheme->transport(s, c);
}

static int integ_moved(void *ctx)
{
    consph_solver *s = ctx;
    wrap_positions(s);
    return consph_sys_update(&s->sys, 0);
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
    is->transport = s->scheme->transport ? integ_transport : NULL;
    is->moved = integ_moved;
    return CONSPH_OK;
}
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

/* Names the first non-finite value: the particle by its initial index, its position, the
 * quantity. */
static int check_finite(consph_solver *s)
{
    consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    static const char *const xs[3] = {"x", "y", "z"}, *const us[3] = {"u", "v", "w"};
    const double *u = sv_field(s, SF_U, d), *rf = sv_field(s, SF_RHOF, 1);
    const double *pr = sv_field(s, SF_P, 1);
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
 * every step once the values are known to be finite: the Mach number |u_i|/c_o, the compression
 * |ϱ_i/ρ_o − 1| (for pe-ipst-c, which evolves p, ϱ = p/c_o² + ρ_o by eq. 31: the same bound on
 * p/(ρ_o c_o²)), and the kinetic energy of the step's diagnostics g against the initial one (no
 * problem here has an energy source).
 * Maxima over the particles with ties to the smallest id: the verdict and the particle named do
 * not depend on the thread count or the particle order. */
static int check_valid(consph_solver *s, const consph_step_diag *g)
{
    const consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    const double *u = sv_field(s, SF_U, d), *rf = sv_field(s, SF_RHOF, 1);
    const double *pr = sv_field(s, SF_P, 1), *id = sv_field(s, SF_ID, 1);
    const double r0 = s->prm.rho0;
    /* edac evolves p on its own, with no EOS: its ϱ is a summation density that only weights
     * its sums, and a uniform drift of p moves nothing (its force takes p - p̄) */
    const int compressible = !(s->scheme->evolve_p && s->scheme->closure);
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
    const double ke0 = s->hist[6]; /* row 0: the initial state */
    if (g->ke > ke0 * (1.0 + CONSPH_VALID_KE_GROWTH)) {
        snprintf(what, sizeof what,
                 "is the fastest (|u| = %.4g) as the kinetic energy %.6g exceeds its initial "
                 "%.6g by %.4g, above the bound %g (the problem supplies no energy)",
                 sqrt(fast.v), g->ke, ke0, g->ke / ke0 - 1.0, CONSPH_VALID_KE_GROWTH);
        return stop_at(s, fast.i, what);
    }
    return CONSPH_OK;
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
    const double target = auth_tf ? auth_time(s, s->auth_next) : s->tf;
    int landed = 0;
    if (auth_tf && s->t + dt > target - 1e-9 * dt) {
        dt = target - s->t;
        landed = 1;
    } else if (s->nsteps == 0 && s->t + dt > s->tf) {
        dt = s->tf - s->t; /* land on tf */
    }
    const double full = s->dt;
    s->dt = dt;
    int st = CONSPH_OK;
    if (s->scheme->moves) st = consph_sys_update(&s->sys, 1);
    integ_state is;
    if (st == CONSPH_OK) st = integ_state_of(s, &is);
    if (st == CONSPH_OK) integ_save_start(&is);
    /* pec and kdk start from the rates the previous step left (the set-up's for the first) */
    if (st == CONSPH_OK && !s->reuse_rates) st = s->scheme->rhs(s);
    if (st == CONSPH_OK) st = s->integ->step(&is, dt);
    if (st == CONSPH_OK) {
        if (auth_tf)
            s->t = landed ? target : s->t + dt;
        else
            s->t = s->nsteps == 0 && dt < full ? s->tf : s->t + dt;
        ++s->step;
    }
    if (st == CONSPH_OK && s->scheme->regularise) st = s->scheme->regularise(s);
    if (st == CONSPH_OK) st = check_finite(s);
    consph_step_diag g;
    if (st == CONSPH_OK) st = consph_solver_diag(s, &g);
    if (st == CONSPH_OK) st = check_valid(s, &g);
    if (st == CONSPH_OK) {
        s->l1_u_acc += dt * g.l1_u;
        s->l1_p_acc += dt * g.l1_p;
        st = hist_push(s, &g);
    }
    if (st == CONSPH_OK && s->prm.error == CONSPH_ERROR_AUTHORS) st = auth_after_step(s, landed);
    s->dt = full;
    s->seconds += consph_wtime() - t0;
    return st;
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

/* ---- diagnostics ---- */

int consph_solver_diag(const consph_solver *cs, consph_step_diag *g)
{
    consph_solver *s = (consph_solver *)cs; /* fields are looked up, not created */
    const consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    memset(g, 0, sizeof *g);
    g->step = s->step;
    g->t = s->t;
    const consph_field *fu = consph_particles_find(p, SF_U), *fp = consph_particles_find(p, SF_P);
    const consph_field *fr = consph_particles_find(p, SF_RHOF);
    const consph_field *fa = consph_particles_find(p, SF_AU);
    const consph_field *fd = consph_particles_find(p, SF_DIVU);
    const consph_field *fm = consph_particles_find(p, SF_MASS);
    if (!fu || !fp || !fr || !fa || !fd) return consph_fail(CONSPH_EINVAL, "solver state missing");
    /* Without an exact solution after t = 0 the errors are not computed (they are n/a): the
     * exact() of such a problem is its initial state, evaluated for nothing. */
    const int errors = s->prob->has_exact || s->t == 0.0;
    /* kept between calls: a fresh allocation every step costs page faults on a hot path */
    const size_t cols = d == 3 ? 8 : 7; /* 3D: m u_z too */
    if (s->diag_cap < cols * n) {
        double *nw = realloc(s->diag_buf, cols * (n ? n : 1) * sizeof(double));
        if (!nw) return consph_fail(CONSPH_ENOMEM, "out of memory");
        s->diag_buf = nw;
        s->diag_cap = cols * n;
    }
    double *w = s->diag_buf;
    double *eu = w, *ep = w + n, *ke = w + 2 * n, *mx = w + 3 * n, *my = w + 4 * n, *an = w + 5 * n,
           *fx = w + 6 * n, *mz = d == 3 ? w + 7 * n : NULL;
    const double xc = 0.5 * (p->box.lo[0] + p->box.hi[0]), yc = 0.5 * (p->box.lo[1] + p->box.hi[1]);
#pragma omp parallel for schedule(static) if (n >= SOLVER_PARALLEL_MIN)
    for (size_t i = 0; i < n; ++i) {
        double x[3];
        position_of(p, i, x);
        const double ux = fu->data[i], uy = fu->data[cap + i];
        const double uz = d == 3 ? fu->data[2 * cap + i] : 0.0, ui[3] = {ux, uy, uz};
        if (errors) {
            double ue[3], pe;
            s->prob->exact(&s->prm, s->t, x, ue, &pe);
            eu[i] = fabs(speed(ui, d) - speed(ue, d));
            ep[i] = fabs(fp->data[i] - pe);
        }
        const double m = fm ? fm->data[i] : s->mass;
        ke[i] = 0.5 * m * (d == 3 ? ux * ux + uy * uy + uz * uz : ux * ux + uy * uy);
        mx[i] = m * ux;
        my[i] = m * uy;
        if (mz) mz[i] = m * uz;
        /* the z-component about the box centre's axis, in 3D as in 2D (a periodic box conserves
         * no angular momentum; the column tracks the rotation of the planar flows) */
        an[i] = m * ((x[0] - xc) * uy - (x[1] - yc) * ux);
        /* 001's authors sum m·a of the whole acceleration (taylor_green.py, post_process:
         * sum(m*au)); the maximum is of the acceleration itself (docs/schemes.md) */
        fx[i] = m * fa->data[i];
    }
    const double inv_n = n ? 1.0 / (double)n : 0.0;
    if (errors) {
        g->l1_u = consph_sum(eu, n) * inv_n;
        g->l1_p = consph_sum(ep, n) * inv_n;
        g->linf_u = max_abs(eu, n);
        g->linf_p = max_abs(ep, n);
    } else {
        /* no exact solution after t = 0: the errors are n/a, not a failure */
        g->l1_u = g->l1_p = g->linf_u = g->linf_p = NAN;
    }
    g->ke = consph_sum(ke, n);
    g->mom[0] = consph_sum(mx, n);
    g->mom[1] = consph_sum(my, n);
    if (mz) g->mom[2] = consph_sum(mz, n);
    g->ang = consph_sum(an, n);
    double fmax = max_abs(fa->data, n); /* component 0: a_x */
    g->ft_fmax = fmax > 0.0 ? consph_sum(fx, n) / fmax : 0.0;
    g->max_divu = max_abs(fd->data, n);
    return CONSPH_OK;
}

int consph_solver_summary(const consph_solver *s, consph_run_summary *sum)
{
    memset(sum, 0, sizeof *sum);
    snprintf(sum->scheme, sizeof sum->scheme, "%s", s->scheme->name);
    snprintf(sum->problem, sizeof sum->problem, "%s", s->prob->name);
    snprintf(sum->integrator, sizeof sum->integrator, "%s", s->integ->name);
    sum->n = s->sys.p->n;
    sum->dim = s->dim;
    sum->steps = s->step;
    sum->t = s->t;
    sum->dt = s->dt;
    sum->h = s->h;
    sum->c0 = s->c0;
    sum->l1_u = s->l1_u_acc;
    sum->l1_p = s->l1_p_acc;
    sum->error = s->prm.error;
    sum->error_samples = s->auth_n;
    sum->l1n_u = s->auth_n ? s->auth_u_acc / s->auth_n : NAN;
    sum->l1n_p = s->auth_n ? s->auth_p_acc / s->auth_n : NAN;
    consph_step_diag last;
    int st = consph_solver_history_row(s, s->nhist - 1, &last);
    if (st != CONSPH_OK) return st;
    sum->linf_u = last.linf_u;
    sum->linf_p = last.linf_p;
    sum->ke = last.ke;
    for (int a = 0; a < 3; ++a) sum->momentum[a] = last.mom[a];
    sum->angular_momentum = last.ang;
    sum->ft_fmax = last.ft_fmax;
    sum->max_divu = last.max_divu;
    sum->seconds = s->seconds;
    sum->pairs = s->pairs;
    sum->passes_per_stage = s->passes;
    sum->passes_min = s->scheme->passes_min;
    sum->regularisations = s->regs;
    return CONSPH_OK;
}

int consph_solver_output_fields(consph_solver *s)
{
    consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    double *ue = sv_field(s, SF_UEX, d), *pe = sv_field(s, SF_PEX, 1);
    double *w = sv_field(s, SF_VORT, d == 3 ? 3 : 1); /* a scalar in 2D, a vector in 3D */
    const double *G = sv_field(s, SF_GRADU, d * d);
    if (!ue || !pe || !w || !G) return CONSPH_ENOMEM;
#define GRAD(a, b) G[(size_t)((a)*d + (b)) * cap + i] /* ∂_b u_a */
    for (size_t i = 0; i < n; ++i) {
        double x[3], u[3];
        position_of(p, i, x);
        s->prob->exact(&s->prm, s->t, x, u, &pe[i]);
        for (int a = 0; a < d; ++a) ue[a * cap + i] = u[a];
        /* ∇×u from the last stage's G (Bonet-corrected); its z-component ∂v/∂x - ∂u/∂y is 2D's */
        if (d == 3) {
            w[i] = GRAD(2, 1) - GRAD(1, 2);
            w[cap + i] = GRAD(0, 2) - GRAD(2, 0);
            w[2 * cap + i] = GRAD(1, 0) - GRAD(0, 1);
        } else {
            w[i] = GRAD(1, 0) - GRAD(0, 1);
        }
    }
#undef GRAD
    return CONSPH_OK;
}

/* ---- the history (the columns of hist_push) ---- */

size_t consph_solver_history_size(const consph_solver *s)
{
    return s->nhist;
}

int consph_solver_history_row(const consph_solver *s, size_t k, consph_step_diag *d)
{
    if (k >= s->nhist) return consph_fail(CONSPH_EINVAL, "history row %zu of %zu", k, s->nhist);
    const double *h = s->hist + k * HIST_COLS;
    memset(d, 0, sizeof *d);
    d->step = (long)h[0];
    d->t = h[1];
    d->l1_u = h[2];
    d->linf_u = h[3];
    d->l1_p = h[4];
    d->linf_p = h[5];
    d->ke = h[6];
    for (int a = 0; a < 3; ++a) d->mom[a] = h[7 + a];
    d->ang = h[10];
    d->ft_fmax = h[11];
    d->max_divu = h[12];
    return CONSPH_OK;
}
