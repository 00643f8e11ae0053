/* The solver's diagnostics: the values of the log (errors against the exact solution, kinetic
 * energy, momentum, F_T/F_max) in any dimension, sampled every log_every steps, at t = 0, the
 * last step and each snapshot (solver_sample), the history they are kept in, the authors' error
 * measure of 001's post-processing, the summary and the output fields. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "integrators/integrators.h"
#include "par/par_solver.h"
#include "problems/wcref.h"
#include "solver/solver_internal.h"

/* ---- the reference of the errors (consph_exact_kind) ---- */

/* The grid of --exact wc's reference: 32² keeps |k| <= 10 (2π/L) after dealiasing, and agrees
 * with 64² to < 1e-9 on Taylor-Green at c_o = 20 up to t = 0.1 (docs/schemes.md). */
enum { WCREF_GRID = 32 };

/* The reference starts from the run's own initial state (solver.c, consph_solver_create): u and
 * p exact, ϱ from p by the inverted EOS (or ρ_o with rho_init rho0); a scheme that evolves p
 * relates them linearly (001 eq. 31), as does the linear EOS. */
static int wcref_make(consph_solver *s)
{
    const problem_def *pb = s->prob;
    const int n = WCREF_GRID, linear = s->scheme->evolve_p || s->eos == CONSPH_EOS_LINEAR;
    const double c2 = s->c0 * s->c0, r0 = s->prm.rho0, g = s->prm.gamma;
    wcref_params wp = {.n = n,
                       .lo = {pb->lo[0], pb->lo[1]},
                       .len = {pb->hi[0] - pb->lo[0], pb->hi[1] - pb->lo[1]},
                       .c0 = s->c0,
                       .rho0 = r0,
                       .gamma = g,
                       .linear = linear,
                       .nu = s->nu};
    const size_t nn = (size_t)n * (size_t)n;
    double *r = malloc(3 * nn * sizeof(double));
    if (!r) return consph_fail(CONSPH_ENOMEM, "out of memory for the wc reference");
    double *u = r + nn, *v = r + 2 * nn;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const size_t q = (size_t)i + (size_t)n * (size_t)j;
            const double x[3] = {wp.lo[0] + wp.len[0] * i / n, wp.lo[1] + wp.len[1] * j / n, 0.0};
            double ue[3], pe;
            pb->exact(&s->prm, 0.0, x, ue, &pe);
            u[q] = ue[0];
            v[q] = ue[1];
            if (s->prm.rho_init == CONSPH_RHO_INIT_RHO0 && !s->scheme->evolve_p)
                r[q] = r0; /* p = EOS(ρ_o) = 0, under either EOS */
            else if (linear)
                r[q] = pe / c2 + r0;
            else
                r[q] = r0 * pow(1.0 + g * pe / (r0 * c2), 1.0 / g); /* eq. 18 inverted */
        }
    int st = wcref_create(&s->wc, &wp, r, u, v);
    free(r);
    return st;
}

int solver_exact_prepare(consph_solver *s)
{
    if (s->prm.exact == CONSPH_EXACT_INCOMPRESSIBLE) return CONSPH_OK;
    const double t0 = consph_wtime();
    int st = s->wc ? CONSPH_OK : wcref_make(s);
    if (st == CONSPH_OK) st = wcref_advance(s->wc, s->t);
    s->sample_seconds[SAMPLE_WC_STEPS] += consph_wtime() - t0;
    return st;
}

/* The reference's share of sample_seconds so far (to leave it out of its callers' parts). */
static double wc_seconds(const consph_solver *s)
{
    const double *t = s->sample_seconds;
    return t[SAMPLE_WC_STEPS] + t[SAMPLE_WC_EVAL] + t[SAMPLE_WC_REST];
}

static void wc_exact(const consph_solver *s, const double x[3], double u[3], double *p)
{
    double rho;
    wcref_eval(s->wc, x, u, &rho);
    u[2] = 0.0;
    *p = wcref_pressure(s->wc, rho);
}

void solver_exact(const consph_solver *s, const double x[3], double u[3], double *p)
{
    if (s->prm.exact == CONSPH_EXACT_WC)
        wc_exact(s, x, u, p);
    else
        s->prob->exact(&s->prm, s->t, x, u, p);
}

/* defined below, with the authors' measure */
static double speed(const double u[3], int d);
static double max_abs(const double *a, size_t n);

/* The normalisers of the authors' measure (mean |u_e|, max |p_e|) against the reference are the
 * incompressible solution's: the reference's own max |p| is 0 at t = 0 with rho_init rho0, and
 * with the same denominators the two errors differ in their numerators only. */
static void incompressible_scales(const consph_solver *s, const double x[3], double *mu, double *pe)
{
    double ue[3];
    s->prob->exact(&s->prm, s->t, x, ue, pe);
    *mu = speed(ue, s->dim);
}

/* A buffer of cols per-particle columns kept between calls (a fresh allocation every sample
 * costs page faults on a hot path); NULL with CONSPH_ENOMEM recorded. */
static double *columns_buffer(double **buf, size_t *cap, size_t n, size_t cols)
{
    if (*cap < cols * n) {
        double *nw = realloc(*buf, cols * (n ? n : 1) * sizeof(double));
        if (!nw) {
            consph_fail(CONSPH_ENOMEM, "out of memory");
            return NULL;
        }
        *buf = nw;
        *cap = cols * n;
    }
    return *buf;
}

/* --exact both: this instant's errors against the reference, as consph_solver_diag (mean |f -
 * f_o|, *eu and *ep) and solver_auth_sample (normalised, *nu and *np) take them against the
 * incompressible solution; nu and np NULL: not wanted, and the incompressible solution their
 * normalisers need is not evaluated (a log sample's eq. 26 sums read eu and ep only). Its own
 * buffer: the callers' are in use. */
int solver_wc_side(consph_solver *s, double *eu, double *ep, double *nu, double *np)
{
    const consph_particles *p = s->sys.p;
    const size_t n = p->n, cap = p->cap;
    const double *u = sv_field(s, SF_U, s->dim), *pr = sv_field(s, SF_P, 1);
    if (!u || !pr) return consph_fail(CONSPH_EINVAL, "solver state missing");
    int st = solver_exact_prepare(s);
    if (st != CONSPH_OK) return st;
    const double t0 = consph_wtime();
    double *a = columns_buffer(&s->wc_buf, &s->wc_cap, n, 7);
    if (!a) return CONSPH_ENOMEM;
    double *mu = a + n, *b = a + 2 * n, *pe = a + 3 * n;
    /* wc_exact at every particle (wcref_eval_many) */
    double *wu = a + 4 * n, *wv = a + 5 * n, *wrho = a + 6 * n;
    const double t1 = consph_wtime();
    st = wcref_eval_many(s->wc, n, p->x[0], p->x[1], wu, wv, wrho, n >= SOLVER_PARALLEL_MIN);
    const double t2 = consph_wtime();
    s->sample_seconds[SAMPLE_WC_EVAL] += t2 - t1;
    if (st != CONSPH_OK) return st;
    const int scales = nu || np;
#pragma omp parallel for schedule(static) if (n >= SOLVER_PARALLEL_MIN)
    for (size_t i = 0; i < n; ++i) {
        const double ue[3] = {wu[i], wv[i], 0.0};
        pe[i] = wcref_pressure(s->wc, wrho[i]);
        const double ui[3] = {u[i], u[cap + i], 0.0};
        a[i] = fabs(speed(ui, s->dim) - speed(ue, s->dim));
        b[i] = fabs(pr[i] - pe[i]);
        if (scales) {
            double x[3];
            solver_position_of(p, i, x);
            incompressible_scales(s, x, &mu[i], &pe[i]);
        }
    }
    const double su = consph_sum(a, n), sp = consph_sum(b, n);
    const double inv_n = n ? 1.0 / (double)n : 0.0; /* as consph_solver_diag */
    *eu = su * inv_n;
    *ep = sp * inv_n;
    if (nu) *nu = su / consph_sum(mu, n);
    if (np) *np = sp / (double)n / max_abs(pe, n);
    s->sample_seconds[SAMPLE_WC_REST] += (t1 - t0) + (consph_wtime() - t2);
    return CONSPH_OK;
}

int solver_hist_push(consph_solver *s, const consph_step_diag *g)
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
                             g->ang,          g->ft_fmax, g->max_divu, s->step_dt};
    memcpy(s->hist + s->nhist * HIST_COLS, row, sizeof row);
    ++s->nhist;
    return CONSPH_OK;
}

/* What solver_sample (consph_solver_diag), the authors' measure (solver_auth_sample,
 * solver_wc_side) and the checks after a step (solver_check_finite, solver_check_valid) read of
 * the particles besides their positions: decomposed over MPI ranks, a sample that writes no file
 * gathers only these to rank 0; on the GPU, a sample copies back only these (gpu.c, copy_back,
 * whose ids also give the origins). */
const char *const solver_sample_fields[] = {SF_U,    SF_RHOF, SF_P,    SF_ID,
                                            SF_MASS, SF_AU,   SF_DIVU, NULL};

static int diag_of(consph_solver *s, consph_step_diag *g, int owned);

int solver_sample(consph_solver *s)
{
    const int joined = solver_sample_join(s);
    if (joined != CONSPH_OK) return joined;
    if (solver_sampled_now(s)) return CONSPH_OK;
    consph_step_diag g;
    const double t0 = consph_wtime(), w0 = wc_seconds(s);
    int st = consph_solver_diag(s, &g);
    s->sample_seconds[SAMPLE_DIAG] += consph_wtime() - t0 - (wc_seconds(s) - w0);
    ++s->sample_count;
    if (st != CONSPH_OK) return st;
    if (s->nhist) {
        /* 001 eq. 26: Σ_j mean|f - f_o|(t_j) (t_j - t_{j-1}) over the samples t_j */
        s->l1_u_acc += s->log_since * g.l1_u;
        s->l1_p_acc += s->log_since * g.l1_p;
        if (s->prm.exact == CONSPH_EXACT_BOTH) {
            double eu, ep;
            st = solver_wc_side(s, &eu, &ep, NULL, NULL);
            if (st != CONSPH_OK) return st;
            s->wcs_u_acc += s->log_since * eu;
            s->wcs_p_acc += s->log_since * ep;
        }
    }
    s->log_since = 0.0;
    return solver_hist_push(s, &g);
}

int solver_sample_owned(const consph_solver *s)
{
    return s->par && s->prm.exact == CONSPH_EXACT_INCOMPRESSIBLE;
}

/* The per-particle buffer of the diagnostics, cols values per particle, kept between calls (a
 * fresh allocation at every sample costs page faults). */
static double *diag_buffer(consph_solver *s, size_t cols)
{
    return columns_buffer(&s->diag_buf, &s->diag_cap, s->sys.p->n, cols);
}

double *solver_ke_column(consph_solver *s)
{
    return diag_buffer(s, 1);
}

/* ---- the authors' error measure (consph_error_kind) ---- */

/* x of particle i as the problems take it: every coordinate of the run, 0 beyond. */
void solver_position_of(const consph_particles *p, size_t i, double x[3])
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

/* max_abs of a[idx[0..m)] (idx NULL: of a[0..m)). */
static double max_abs_at(const double *a, const size_t *idx, size_t m)
{
    if (!idx) return max_abs(a, m);
    double v = 0.0;
    for (size_t k = 0; k < m; ++k) v = fmax(v, fabs(a[idx[k]]));
    return v;
}

/* The particles a sample's terms are computed for: every one this process holds; `owned` (a
 * decomposed sample every rank takes: solver_sample_owned), this rank's owned ones (*idx, *m),
 * N of them over the ranks. */
static void sample_part(const consph_solver *s, int owned, const size_t **idx, size_t *m, size_t *N)
{
    if (owned) {
        *idx = par_owned(s, m, N);
    } else {
        *idx = NULL;
        *m = *N = s->sys.p->n;
    }
}

/* consph_sum of each of c columns of m terms at w into sum[c], and mx[nmx] (at most 4) made
 * the maxima over the whole set: as they are, unless `owned`: then over the ranks (the maxima
 * exact in any order, the sums over the serial order: par_owned_sums), with st, this rank's
 * status of the terms, taken over the ranks in the maxima's reduction, so that a rank that
 * failed alone does not leave the others waiting in the sums. */
static int sample_reduce(consph_solver *s, int owned, int st, const double *w, size_t m, int c,
                         double *sum, double *mx, int nmx)
{
    if (!owned) {
        for (int k = 0; st == CONSPH_OK && k < c; ++k) sum[k] = consph_sum(w + (size_t)k * m, m);
        return st;
    }
    double v[5];
    for (int k = 0; k < nmx; ++k) v[k] = st == CONSPH_OK ? mx[k] : 0.0;
    v[nmx] = st == CONSPH_OK ? 0.0 : 1.0;
    par_owned_max(s, v, nmx + 1);
    if (v[nmx] != 0.0)
        return st != CONSPH_OK ? st
                               : consph_fail(CONSPH_EINVAL, "a sample failed on another MPI rank");
    for (int k = 0; k < nmx; ++k) mx[k] = v[k];
    return par_owned_sums(s, w, c, sum);
}

/* Output time k with --tf; the last is t_f itself, not a rounding of it. */
double solver_auth_time(const consph_solver *s, int k)
{
    const int last = s->prm.error_times - 1;
    return k >= last ? s->tf : s->tf * (double)k / (double)last;
}

/* With --steps: the step whose end is output time k. */
static long auth_step(const consph_solver *s, int k)
{
    return lround((double)s->nsteps * (double)k / (double)(s->prm.error_times - 1));
}

/* Adds this instant's normalised errors of 001's post-processing to the sums. Decomposed (s->par:
 * every rank, solver_sample_owned), over the owned particles and then the ranks. */
int solver_auth_sample(consph_solver *s)
{
    const consph_particles *p = s->sys.p;
    const size_t cap = p->cap;
    const double *u = sv_field(s, SF_U, s->dim), *pr = sv_field(s, SF_P, 1);
    if (!u || !pr) return consph_fail(CONSPH_EINVAL, "solver state missing");
    double eu_n = NAN, ep_n = NAN;
    if (s->prob->has_exact || s->t == 0.0) {
        const size_t *idx;
        size_t m, N;
        const int owned = s->par != NULL;
        sample_part(s, owned, &idx, &m, &N);
        int st = solver_exact_prepare(s);
        double *eu = st == CONSPH_OK ? diag_buffer(s, 4) : NULL;
        if (st == CONSPH_OK && !eu) st = CONSPH_ENOMEM;
        double sum[3], pmax = 0.0;
        if (st == CONSPH_OK) {
            double *mu = eu + m, *ep = eu + 2 * m, *pe = eu + 3 * m;
#pragma omp parallel for schedule(static) if (m >= SOLVER_PARALLEL_MIN)
            for (size_t k = 0; k < m; ++k) {
                const size_t i = idx ? idx[k] : k;
                double x[3], ue[3];
                solver_position_of(p, i, x);
                solver_exact(s, x, ue, &pe[k]);
                mu[k] = speed(ue, s->dim);
                const double ui[3] = {u[i], u[cap + i], s->dim == 3 ? u[2 * cap + i] : 0.0};
                eu[k] = fabs(speed(ui, s->dim) - mu[k]);
                ep[k] = fabs(pr[i] - pe[k]);
                if (s->prm.exact == CONSPH_EXACT_WC) /* the scales: solver_wc_side */
                    incompressible_scales(s, x, &mu[k], &pe[k]);
            }
            pmax = max_abs(pe, m);
        }
        /* eu, mu, ep: the first three columns */
        st = sample_reduce(s, owned, st, eu, m, 3, sum, &pmax, 1);
        if (st != CONSPH_OK) return st;
        /* mean/mean for u, mean/max for p: taylor_green.py, post_process */
        eu_n = sum[0] / sum[1];
        ep_n = sum[2] / (double)N / pmax;
    }
    s->auth_u_acc += eu_n;
    s->auth_p_acc += ep_n;
    ++s->auth_n;
    if (s->prm.exact == CONSPH_EXACT_BOTH) {
        double eu, ep, nu, np;
        int st = solver_wc_side(s, &eu, &ep, &nu, &np);
        if (st != CONSPH_OK) return st;
        s->wcs_auth_u_acc += nu;
        s->wcs_auth_p_acc += np;
    }
    return CONSPH_OK;
}

/* Whether solver_auth_after_step(s, landed) samples after this step (s->step counts it): the
 * host's particles must then be this step's (a GPU run copies them back only then). */
int solver_auth_due(const consph_solver *s, int landed)
{
    if (s->nsteps == 0) return landed;
    for (int k = s->auth_next; k < s->prm.error_times && auth_step(s, k) <= s->step; ++k)
        if (auth_step(s, k) == s->step) return 1;
    return 0;
}

int solver_auth_advance(consph_solver *s, int landed)
{
    const int hit = solver_auth_due(s, landed);
    if (s->nsteps == 0) {
        s->auth_next += hit;
    } else {
        /* several output times may round to one step: it is sampled once */
        while (s->auth_next < s->prm.error_times && auth_step(s, s->auth_next) <= s->step)
            ++s->auth_next;
    }
    return hit;
}

/* After a step: samples when it ended on the next output time. `landed`: a --tf run's step was
 * cut to end on it. */
int solver_auth_after_step(consph_solver *s, int landed)
{
    if (!solver_auth_advance(s, landed)) return CONSPH_OK;
    /* the measure shares the reference and the buffers with a sample on the host thread */
    const int joined = solver_sample_join(s);
    if (joined != CONSPH_OK) return joined;
    const double t0 = consph_wtime(), w0 = wc_seconds(s);
    const int st = solver_auth_sample(s);
    s->sample_seconds[SAMPLE_AUTH] += consph_wtime() - t0 - (wc_seconds(s) - w0);
    return st;
}

/* ---- diagnostics ---- */

/* The columns of the diagnostics' per-particle terms (m u_z in 3D only). */
enum { DG_EU, DG_EP, DG_KE, DG_MX, DG_MY, DG_AN, DG_FX, DG_MZ };
/* Their maxima: of the errors, of a_x and of ∇·u. */
enum { DG_LINF_U, DG_LINF_P, DG_FMAX, DG_DIVU, DG_NMAX };

/* The diagnostics of this instant from the particles sample_part gives (`owned`: the same
 * values on every rank): each one's terms into the columns of diag_buffer (m values each),
 * summed and maximised over the whole set by sample_reduce (decomposed: over the ranks, each
 * rank's owned particles). */
static int diag_of(consph_solver *s, consph_step_diag *g, int owned)
{
    const consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t cap = p->cap;
    memset(g, 0, sizeof *g);
    g->step = s->step;
    g->t = s->t;
    const consph_field *fu = consph_particles_find(p, SF_U), *fp = consph_particles_find(p, SF_P);
    const consph_field *fr = consph_particles_find(p, SF_RHOF);
    const consph_field *fa = consph_particles_find(p, SF_AU);
    const consph_field *fd = consph_particles_find(p, SF_DIVU);
    const consph_field *fm = consph_particles_find(p, SF_MASS);
    if (!fu || !fp || !fr || !fa || !fd) return consph_fail(CONSPH_EINVAL, "solver state missing");
    const size_t *idx;
    size_t m, N;
    sample_part(s, owned, &idx, &m, &N);
    /* Without an exact solution after t = 0 the errors are not computed (they are n/a): the
     * exact() of such a problem is its initial state, evaluated for nothing. */
    const int errors = s->prob->has_exact || s->t == 0.0;
    int st = errors ? solver_exact_prepare(s) : CONSPH_OK;
    const int cols = d == 3 ? 8 : 7; /* 3D: m u_z too */
    double *w = st == CONSPH_OK ? diag_buffer(s, (size_t)cols) : NULL;
    if (st == CONSPH_OK && !w) st = CONSPH_ENOMEM;
    double mx[DG_NMAX] = {0.0, 0.0, 0.0, 0.0};
    if (st == CONSPH_OK) {
        double *eu = w + DG_EU * m, *ep = w + DG_EP * m, *ke = w + DG_KE * m, *mxc = w + DG_MX * m,
               *my = w + DG_MY * m, *an = w + DG_AN * m, *fx = w + DG_FX * m,
               *mz = d == 3 ? w + DG_MZ * m : NULL;
        const double xc = 0.5 * (p->box.lo[0] + p->box.hi[0]),
                     yc = 0.5 * (p->box.lo[1] + p->box.hi[1]);
#pragma omp parallel for schedule(static) if (m >= SOLVER_PARALLEL_MIN)
        for (size_t k = 0; k < m; ++k) {
            const size_t i = idx ? idx[k] : k;
            double x[3];
            solver_position_of(p, i, x);
            const double ux = fu->data[i], uy = fu->data[cap + i];
            const double uz = d == 3 ? fu->data[2 * cap + i] : 0.0, ui[3] = {ux, uy, uz};
            if (errors) {
                double ue[3], pe;
                solver_exact(s, x, ue, &pe);
                eu[k] = fabs(speed(ui, d) - speed(ue, d));
                ep[k] = fabs(fp->data[i] - pe);
            }
            const double mi = fm ? fm->data[i] : s->mass;
            ke[k] = kinetic_energy_of(mi, ux, uy, uz, d);
            mxc[k] = mi * ux;
            my[k] = mi * uy;
            if (mz) mz[k] = mi * uz;
            /* the z-component about the box centre's axis, in 3D as in 2D (a periodic box
             * conserves no angular momentum; the column tracks the rotation of the planar
             * flows) */
            an[k] = mi * ((x[0] - xc) * uy - (x[1] - yc) * ux);
            /* 001's authors sum m·a of the whole acceleration (taylor_green.py, post_process:
             * sum(m*au)); the maximum is of the acceleration itself (docs/schemes.md) */
            fx[k] = mi * fa->data[i];
        }
        if (errors) {
            mx[DG_LINF_U] = max_abs(eu, m);
            mx[DG_LINF_P] = max_abs(ep, m);
        }
        mx[DG_FMAX] = max_abs_at(fa->data, idx, m); /* component 0: a_x */
        mx[DG_DIVU] = max_abs_at(fd->data, idx, m);
    }
    /* without the errors, their columns hold nothing to sum */
    const int first = errors ? DG_EU : DG_KE;
    double sum[8] = {0.0};
    st = sample_reduce(s, owned, st, w ? w + (size_t)first * m : NULL, m, cols - first, sum + first,
                       mx, DG_NMAX);
    if (st != CONSPH_OK) return st;
    const double inv_n = N ? 1.0 / (double)N : 0.0;
    if (errors) {
        g->l1_u = sum[DG_EU] * inv_n;
        g->l1_p = sum[DG_EP] * inv_n;
        g->linf_u = mx[DG_LINF_U];
        g->linf_p = mx[DG_LINF_P];
    } else {
        /* no exact solution after t = 0: the errors are n/a, not a failure */
        g->l1_u = g->l1_p = g->linf_u = g->linf_p = NAN;
    }
    g->ke = sum[DG_KE];
    g->mom[0] = sum[DG_MX];
    g->mom[1] = sum[DG_MY];
    if (d == 3) g->mom[2] = sum[DG_MZ];
    g->ang = sum[DG_AN];
    g->ft_fmax = mx[DG_FMAX] > 0.0 ? sum[DG_FX] / mx[DG_FMAX] : 0.0;
    g->max_divu = mx[DG_DIVU];
    return CONSPH_OK;
}

/* Decomposed over MPI ranks, over every rank's owned particles (a collective: each rank holds a
 * halo too, which a sum over its particles would count twice). */
int consph_solver_diag(const consph_solver *cs, consph_step_diag *g)
{
    consph_solver *s = (consph_solver *)cs; /* fields are looked up, not created */
    const int joined = solver_sample_join(s);
    return joined != CONSPH_OK ? joined : diag_of(s, g, s->par != NULL);
}

int consph_solver_summary(const consph_solver *s, consph_run_summary *sum)
{
    memset(sum, 0, sizeof *sum);
    /* the sums of a sample on the host thread (the solver is the caller's to change) */
    const int joined = solver_sample_join((consph_solver *)s);
    if (joined != CONSPH_OK) return joined;
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
    solver_nlist_summary(s, sum);
    sum->passes_per_stage = s->passes;
    sum->passes_min = s->scheme->passes_min;
    sum->regularisations = s->regs;
    sum->exact = s->prm.exact;
    const int both = s->prm.exact == CONSPH_EXACT_BOTH;
    sum->wc_l1_u = both ? s->wcs_u_acc : NAN;
    sum->wc_l1_p = both ? s->wcs_p_acc : NAN;
    sum->wc_l1n_u = both && s->auth_n ? s->wcs_auth_u_acc / s->auth_n : NAN;
    sum->wc_l1n_p = both && s->auth_n ? s->wcs_auth_p_acc / s->auth_n : NAN;
    return CONSPH_OK;
}

int consph_solver_output_fields(consph_solver *s)
{
    const int joined = solver_sample_join(s);
    if (joined != CONSPH_OK) return joined;
    consph_particles *p = s->sys.p;
    const int d = s->dim;
    const size_t n = p->n, cap = p->cap;
    double *ue = sv_field(s, SF_UEX, d), *pe = sv_field(s, SF_PEX, 1);
    double *w = sv_field(s, SF_VORT, d == 3 ? 3 : 1); /* a scalar in 2D, a vector in 3D */
    const double *G = sv_field(s, SF_GRADU, d * d);
    if (!ue || !pe || !w || !G) return CONSPH_ENOMEM;
    /* the arrays u_exact, p_exact: what the errors are taken against */
    int st = solver_exact_prepare(s);
    if (st != CONSPH_OK) return st;
#define GRAD(a, b) G[(size_t)((a)*d + (b)) * cap + i] /* ∂_b u_a */
    for (size_t i = 0; i < n; ++i) {
        double x[3], u[3];
        solver_position_of(p, i, x);
        solver_exact(s, x, u, &pe[i]);
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

/* ---- the history (the columns of solver_hist_push) ---- */

size_t consph_solver_history_size(const consph_solver *s)
{
    /* a failed sample's status stays for the next join that returns one */
    (void)solver_sample_join((consph_solver *)s);
    return s->nhist;
}

int consph_solver_history_row(const consph_solver *s, size_t k, consph_step_diag *d)
{
    const int joined = solver_sample_join((consph_solver *)s);
    if (joined != CONSPH_OK) return joined;
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
