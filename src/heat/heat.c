/* Heat conduction with Dirichlet walls, 002 §6 (include/consph/heat.h): a scalar forward-Euler
 * solver whose Laplacian is one pass over the interior particles (the walls are sources only),
 * made of the operator terms consph_apply runs. */
#include "consph/heat.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "consph/kernels.h"
#include "consph/ops.h"
#include "consph/pass.h"
#include "consph/solver.h"
#include "solver/runfiles.h"
#include "ops/terms.h"

#define HEAT_DIM 2
/* 002 eq. 43 is summed until the bound of the next term falls below this. */
#define HEAT_SERIES_TOL 1e-14
#define HEAT_SERIES_MAX 100000000L
/* log.csv: step t dt mean_T l2 linf ec */
#define HEAT_COLS 7

struct consph_heat {
    consph_heat_params prm;
    consph_sys sys;
    consph_op_ctx ctx;
    int have_ctx;
    double *T;          /* field "T" of the system's particles */
    const double *wall; /* field "wall": 1 on the boundary */
    double *lap;        /* ∇²T of the last step (destinations only are read) */
    const double *B;    /* S4: Bonet B_i (d² per particle) */
    const double *Bh;   /* S4: B̂_i of 002 eq. 40 */
    size_t n, n_interior, fallbacks, pairs;
    double delta, h, d_min, dt, dt_last, t, seconds, setup_seconds;
    long step, nsteps;
};

static const char *const lap_names[] = {"s3", "s4"};
static const char *const wall_names[] = {"sin", "linear"};

void consph_heat_params_default(consph_heat_params *prm)
{
    memset(prm, 0, sizeof *prm);
    prm->laplacian = CONSPH_HEAT_S4;
    prm->walls = CONSPH_HEAT_WALLS_SIN;
    prm->nx = 40;
    prm->eta = 2.0;
    prm->eps = 0.0;
    prm->seed = 1;
    prm->tf = 0.1;
    prm->steps = 0;
    prm->alpha = 1.0;
    prm->courant = 0.2;
}

const char *consph_heat_lap_name(consph_heat_lap lap)
{
    return lap == CONSPH_HEAT_S3 ? lap_names[0] : lap_names[1];
}

const char *consph_heat_walls_name(consph_heat_walls walls)
{
    return walls == CONSPH_HEAT_WALLS_SIN ? wall_names[0] : wall_names[1];
}

int consph_heat_lap_lookup(const char *name, consph_heat_lap *lap)
{
    for (int k = 0; k < 2; ++k)
        if (name && strcmp(name, lap_names[k]) == 0) {
            *lap = (consph_heat_lap)k;
            return CONSPH_OK;
        }
    return consph_fail(CONSPH_EINVAL, "option --laplacian: '%s' is unknown (allowed: s3, s4)",
                       name ? name : "");
}

int consph_heat_walls_lookup(const char *name, consph_heat_walls *walls)
{
    for (int k = 0; k < 2; ++k)
        if (name && strcmp(name, wall_names[k]) == 0) {
            *walls = (consph_heat_walls)k;
            return CONSPH_OK;
        }
    return consph_fail(CONSPH_EINVAL, "option --walls: '%s' is unknown (allowed: sin, linear)",
                       name ? name : "");
}

int consph_heat_params_check(const consph_heat_params *prm)
{
    if (prm->laplacian != CONSPH_HEAT_S3 && prm->laplacian != CONSPH_HEAT_S4)
        return consph_fail(CONSPH_EINVAL, "option --laplacian: unknown value (allowed: s3, s4)");
    if (prm->walls != CONSPH_HEAT_WALLS_SIN && prm->walls != CONSPH_HEAT_WALLS_LINEAR)
        return consph_fail(CONSPH_EINVAL, "option --walls: unknown value (allowed: sin, linear)");
    if (!(prm->nx >= 4 && prm->nx <= 20000))
        return consph_fail(CONSPH_EINVAL, "option --nx: %d is out of range (allowed: 4 to 20000)",
                           prm->nx);
    /* measured: 195 bytes per particle at nx = 400 */
    if (runfiles_memory_check(prm->nx, 2, 512.0, runfiles_machine_memory()) != CONSPH_OK)
        return consph_fail(CONSPH_EINVAL, "option %s", consph_last_error());
    if (!(prm->eta >= 1.0 && prm->eta <= 10.0))
        return consph_fail(CONSPH_EINVAL,
                           "option --eta: %g is out of range (allowed: h/Δ in [1, 10])", prm->eta);
    if (!(prm->eps >= 0.0 && prm->eps <= 1.0))
        return consph_fail(CONSPH_EINVAL, "option --eps: %g is out of range (allowed: 0 to 1)",
                           prm->eps);
    if (!(prm->tf > 0.0 && prm->tf <= 1e6))
        return consph_fail(CONSPH_EINVAL, "option --tf: %g is out of range (allowed: (0, 1e6])",
                           prm->tf);
    if (prm->steps < 0)
        return consph_fail(CONSPH_EINVAL, "option --steps: %ld is negative (allowed: >= 1)",
                           prm->steps);
    if (!(prm->alpha > 0.0 && isfinite(prm->alpha)))
        return consph_fail(CONSPH_EINVAL, "heat: alpha = %g must be positive", prm->alpha);
    if (!(prm->courant > 0.0 && prm->courant <= 1.0))
        return consph_fail(CONSPH_EINVAL, "heat: courant = %g is out of range (0, 1]",
                           prm->courant);
    return CONSPH_OK;
}

static double wall_value(consph_heat_walls walls, double x, double y)
{
    if (walls == CONSPH_HEAT_WALLS_LINEAR) return y;
    return y >= 1.0 ? sin(M_PI * x) : 0.0;
}

double consph_heat_exact(consph_heat_walls walls, double alpha, double x, double y, double t,
                         int *terms)
{
    if (terms) *terms = 0;
    if (walls == CONSPH_HEAT_WALLS_LINEAR) return y;
    /* The walls carry their data exactly; the truncated series would not, near t = 0. */
    if (x <= 0.0 || x >= 1.0 || y <= 0.0 || y >= 1.0) return wall_value(walls, x, y);
    if (t <= 0.0) return 0.0;
    double sum = sinh(M_PI * y) / sinh(M_PI);
    long m = 1;
    for (; m < HEAT_SERIES_MAX; ++m) {
        const double md = (double)m;
        const double bound =
            2.0 * md / (M_PI * (md * md + 1.0)) * exp(-alpha * M_PI * M_PI * (1.0 + md * md) * t);
        if (bound < HEAT_SERIES_TOL) break;
        sum += (m % 2 ? -bound : bound) * sin(md * M_PI * y);
    }
    if (terms) *terms = (int)(m - 1);
    return sum * sin(M_PI * x);
}

/* ---- passes ---- */

/* The distance to the nearest other particle. */
static void visit_nearest(void *vjob, const consph_nbhd *nb)
{
    double *dmin = vjob, best = INFINITY;
    for (size_t p = 0; p < nb->n; ++p)
        if (nb->r[p] > 0.0 && nb->r[p] < best) best = nb->r[p];
    dmin[nb->i] = best;
}

typedef struct heat_job {
    const consph_heat *h;
    const double *T;
    double *lap;
} heat_job;

/* S3: 002 eq. 13; S4: 002 eq. 41 with the F4 gradient and B̂ of eq. 40. */
static void visit_laplacian(void *vjob, const consph_nbhd *nb)
{
    const heat_job *job = vjob;
    const consph_heat *h = job->h;
    const int d = HEAT_DIM;
    const size_t i = nb->i, dd = (size_t)(d * d);
    if (h->prm.laplacian == CONSPH_HEAT_S3) {
        double c[3], M[9];
        term_grad_rule(d, CONSPH_CORR_NONE, NULL, 0, i, c, M);
        job->lap[i] = term_cleary(d, 0, CONSPH_CORR_NONE, c, M, nb, h->ctx.volume, job->T);
    } else {
        double G[3];
        term_f4_grad(d, nb, h->ctx.volume, job->T, h->B + i * dd, G);
        job->lap[i] = term_fatehi_lap(d, nb, h->ctx.volume, job->T, G, h->Bh + i * dd);
    }
}

/* ---- set-up ---- */

/* nx² particles on the grid vertices, particle i0 + nx i1; interior ones perturbed by ε κ Δ,
 * κ uniform in [-1/4, 1/4], drawn x then y per interior particle in that order. */
static int make_particles(const consph_heat_params *prm, double delta, consph_particles *p)
{
    const size_t nx = (size_t)prm->nx;
    consph_box box = consph_box_unit(HEAT_DIM, 0);
    int st = consph_particles_init(p, HEAT_DIM, nx * nx, &box);
    if (st != CONSPH_OK) return st;
    p->spacing = delta;
    double *wall = consph_particles_field(p, "wall", 1);
    double *vol = consph_particles_field(p, "volume", 1);
    double *T = consph_particles_field(p, "T", 1);
    if (!wall || !vol || !T) {
        consph_particles_free(p);
        return CONSPH_ENOMEM;
    }
    consph_rng rng;
    consph_rng_seed(&rng, (uint64_t)prm->seed);
    const double amp = 0.25 * prm->eps * delta;
    for (size_t j = 0; j < nx; ++j)
        for (size_t i = 0; i < nx; ++i) {
            const size_t k = i + nx * j;
            const int on_wall = i == 0 || j == 0 || i == nx - 1 || j == nx - 1;
            double x = i == nx - 1 ? 1.0 : (double)i * delta;
            double y = j == nx - 1 ? 1.0 : (double)j * delta;
            if (!on_wall && prm->eps > 0.0) {
                x += amp * (2.0 * consph_rng_uniform(&rng) - 1.0);
                y += amp * (2.0 * consph_rng_uniform(&rng) - 1.0);
            }
            p->x[0][k] = x;
            p->x[1][k] = y;
            wall[k] = on_wall;
            vol[k] = delta * delta;
            /* sin walls: 002's T = 0 inside at t = 0; linear walls: the steady state T = y. */
            T[k] = on_wall || prm->walls == CONSPH_HEAT_WALLS_LINEAR ? wall_value(prm->walls, x, y)
                                                                     : 0.0;
        }
    return CONSPH_OK;
}

/* Δt and the number of steps: full steps of Δt, then a shorter last one that lands on tf. */
static void plan_steps(consph_heat *h)
{
    const consph_heat_params *prm = &h->prm;
    h->dt = prm->courant * h->d_min * h->d_min / prm->alpha;
    if (prm->steps > 0) {
        h->nsteps = prm->steps;
        h->dt_last = h->dt;
        return;
    }
    long full = (long)floor(prm->tf / h->dt);
    double rest = prm->tf - (double)full * h->dt;
    /* a remainder at round-off level is no step of its own */
    if (rest <= 1e-9 * h->dt) {
        h->nsteps = full > 0 ? full : 1;
        h->dt_last = prm->tf - (double)(h->nsteps - 1) * h->dt;
    } else {
        h->nsteps = full + 1;
        h->dt_last = rest;
    }
}

static int heat_setup(consph_heat *h)
{
    const consph_heat_params *prm = &h->prm;
    h->delta = 1.0 / (double)(prm->nx - 1);
    h->h = prm->eta * h->delta;
    consph_kernel_id kid;
    consph_kernel kernel;
    int st = consph_kernel_lookup("wendland-c2:h", &kid);
    if (st == CONSPH_OK) st = consph_kernel_init(&kernel, kid, HEAT_DIM, h->h);
    if (st != CONSPH_OK) return st;
    consph_particles p;
    if ((st = make_particles(prm, h->delta, &p)) != CONSPH_OK) return st;
    st = consph_sys_init(&h->sys, &p, &kernel, 0.0);
    consph_particles_free(&p);
    if (st != CONSPH_OK) return st;
    h->n = h->sys.p->n;
    h->T = consph_particles_field(h->sys.p, "T", 1);
    const consph_field *wf = consph_particles_find(h->sys.p, "wall");
    h->lap = calloc(h->n, sizeof(double));
    unsigned char *dest = calloc(h->n, 1);
    double *dmin = calloc(h->n, sizeof(double));
    if (!h->T || !wf || !h->lap || !dest || !dmin) {
        free(dest);
        free(dmin);
        return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    h->wall = wf->data;
    for (size_t i = 0; i < h->n; ++i) {
        dest[i] = h->wall[i] == 0.0;
        h->n_interior += dest[i];
    }
    st = consph_sys_set_dest(&h->sys, dest);
    free(dest);
    /* d_min over every particle, walls included: the sum runs over all of them */
    if (st == CONSPH_OK) {
        consph_sys all = h->sys;
        all.dest = NULL;
        const consph_pass pass = {"nearest particle", 0, visit_nearest};
        st = consph_pass_run(&all, &pass, dmin);
    }
    if (st == CONSPH_OK) {
        h->d_min = INFINITY;
        for (size_t i = 0; i < h->n; ++i)
            if (dmin[i] < h->d_min) h->d_min = dmin[i];
        if (!isfinite(h->d_min))
            st = consph_fail(CONSPH_EINVAL, "option --eta: no particle has a neighbour within h");
    }
    free(dmin);
    if (st != CONSPH_OK) return st;
    if ((st = consph_op_ctx_init_sys(&h->ctx, &h->sys, CONSPH_VOLUME_GIVEN)) != CONSPH_OK)
        return st;
    h->have_ctx = 1;
    if (prm->laplacian == CONSPH_HEAT_S4) {
        const unsigned char *bad_b = NULL, *bad_f = NULL;
        h->B = consph_op_bonet(&h->ctx, &bad_b);
        h->Bh = h->B ? consph_op_fatehi(&h->ctx, &bad_f) : NULL;
        if (!h->B || !h->Bh) return CONSPH_ENOMEM;
        for (size_t i = 0; i < h->n; ++i)
            if (h->wall[i] == 0.0 && ((bad_b && bad_b[i]) || (bad_f && bad_f[i]))) ++h->fallbacks;
    }
    plan_steps(h);
    return CONSPH_OK;
}

int consph_heat_create(consph_heat **out, const consph_heat_params *prm)
{
    *out = NULL;
    int st = consph_heat_params_check(prm);
    if (st != CONSPH_OK) return st;
    consph_heat *h = calloc(1, sizeof *h);
    if (!h) return consph_fail(CONSPH_ENOMEM, "out of memory");
    h->prm = *prm;
    double t0 = consph_wtime();
    st = heat_setup(h);
    h->setup_seconds = consph_wtime() - t0;
    if (st != CONSPH_OK) {
        consph_heat_free(h);
        return st;
    }
    *out = h;
    return CONSPH_OK;
}

void consph_heat_free(consph_heat *h)
{
    if (!h) return;
    if (h->have_ctx) consph_op_ctx_free(&h->ctx);
    consph_sys_free(&h->sys);
    free(h->lap);
    free(h);
}

int consph_heat_step(consph_heat *h)
{
    if (consph_heat_done(h)) return CONSPH_OK;
    double t0 = consph_wtime();
    heat_job job = {h, h->T, h->lap};
    const consph_pass pass = {"heat laplacian", CONSPH_PASS_DW, visit_laplacian};
    int st = consph_pass_run_counted(&h->sys, &pass, &job, &h->pairs);
    if (st != CONSPH_OK) return st;
    const int last = h->step + 1 == h->nsteps;
    const double dt = last ? h->dt_last : h->dt, a = h->prm.alpha;
    size_t bad = h->n;
    for (size_t i = 0; i < h->n; ++i) {
        if (h->wall[i] != 0.0) continue;
        h->T[i] += dt * a * h->lap[i];
        if (!isfinite(h->T[i]) && bad == h->n) bad = i;
    }
    ++h->step;
    /* t from the step count, so that it does not drift; the last step lands on tf */
    h->t = last && h->prm.steps == 0 ? h->prm.tf : (double)h->step * h->dt;
    h->seconds += consph_wtime() - t0;
    if (bad < h->n)
        return consph_fail(CONSPH_ENUMERIC,
                           "heat: step %ld: T of particle %zu at (%.6g, %.6g) is not finite",
                           h->step, h->sys.origin ? h->sys.origin[bad] : bad, h->sys.p->x[0][bad],
                           h->sys.p->x[1][bad]);
    return CONSPH_OK;
}

int consph_heat_done(const consph_heat *h)
{
    return h->step >= h->nsteps;
}

long consph_heat_step_count(const consph_heat *h)
{
    return h->step;
}

double consph_heat_time(const consph_heat *h)
{
    return h->t;
}

const consph_particles *consph_heat_particles(const consph_heat *h)
{
    return h->sys.p;
}

int consph_heat_output_fields(consph_heat *h)
{
    double *ex = consph_particles_field(h->sys.p, "T_exact", 1);
    if (!ex) return CONSPH_ENOMEM;
    const consph_particles *p = h->sys.p;
    for (size_t i = 0; i < h->n; ++i)
        ex[i] = consph_heat_exact(h->prm.walls, h->prm.alpha, p->x[0][i], p->x[1][i], h->t, NULL);
    return CONSPH_OK;
}

int consph_heat_errors(const consph_heat *h, double *l2, double *linf, double *ec)
{
    double *e = malloc(h->n * sizeof(double)), *e2 = malloc(h->n * sizeof(double));
    if (!e || !e2) {
        free(e);
        free(e2);
        return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    const consph_particles *p = h->sys.p;
    double mx = 0.0;
    for (size_t i = 0; i < h->n; ++i) {
        e[i] = consph_heat_exact(h->prm.walls, h->prm.alpha, p->x[0][i], p->x[1][i], h->t, NULL) -
               h->T[i];
        e2[i] = e[i] * e[i];
        if (!(fabs(e[i]) <= mx)) mx = fabs(e[i]);
    }
    const double N = (double)h->n;
    if (l2) *l2 = sqrt(consph_sum(e2, h->n) / N);
    if (linf) *linf = mx;
    if (ec) *ec = fabs(consph_sum(e, h->n)) / N;
    free(e);
    free(e2);
    return CONSPH_OK;
}

int consph_heat_summary_get(const consph_heat *h, consph_heat_summary *sum)
{
    memset(sum, 0, sizeof *sum);
    snprintf(sum->laplacian, sizeof sum->laplacian, "%s", consph_heat_lap_name(h->prm.laplacian));
    snprintf(sum->walls, sizeof sum->walls, "%s", consph_heat_walls_name(h->prm.walls));
    sum->n = h->n;
    sum->n_interior = h->n_interior;
    sum->nx = h->prm.nx;
    sum->steps = h->step;
    sum->t = h->t;
    sum->dt = h->dt;
    sum->dt_last = h->dt_last;
    sum->delta = h->delta;
    sum->h = h->h;
    sum->eta = h->prm.eta;
    sum->eps = h->prm.eps;
    sum->d_min = h->d_min;
    sum->fallbacks = h->fallbacks;
    sum->seconds = h->seconds;
    sum->setup_seconds = h->setup_seconds;
    sum->pairs = h->pairs;
    return consph_heat_errors(h, &sum->l2, &sum->linf, &sum->ec);
}

void consph_heat_summary_json(FILE *fp, const consph_heat_summary *s)
{
    fprintf(fp,
            "{\n  \"problem\": \"heat\",\n  \"laplacian\": \"%s\",\n  \"walls\": \"%s\",\n"
            "  \"kernel\": \"wendland-c2:h\",\n  \"integrator\": \"euler\",\n",
            s->laplacian, s->walls);
    fprintf(fp, "  \"nx\": %d,\n  \"n\": %zu,\n  \"n_interior\": %zu,\n  \"steps\": %ld,\n", s->nx,
            s->n, s->n_interior, s->steps);
    runfiles_json_num(fp, "t", s->t, 0);
    runfiles_json_num(fp, "dt", s->dt, 0);
    runfiles_json_num(fp, "dt_last", s->dt_last, 0);
    runfiles_json_num(fp, "delta", s->delta, 0);
    runfiles_json_num(fp, "h", s->h, 0);
    runfiles_json_num(fp, "eta", s->eta, 0);
    runfiles_json_num(fp, "eps", s->eps, 0);
    runfiles_json_num(fp, "d_min", s->d_min, 0);
    runfiles_json_num(fp, "l2", s->l2, 0);
    runfiles_json_num(fp, "linf", s->linf, 0);
    runfiles_json_num(fp, "ec", s->ec, 0);
    runfiles_json_num(fp, "seconds", s->seconds, 0);
    runfiles_json_num(fp, "setup_seconds", s->setup_seconds, 0);
    fprintf(fp, "  \"pairs\": %zu,\n  \"fallbacks\": %zu\n}\n", s->pairs, s->fallbacks);
}

/* ---- a run with its files ---- */

typedef struct heat_log {
    double *rows;
    size_t n, cap;
} heat_log;

static int log_row(consph_heat *h, heat_log *lg, int with_errors)
{
    if (lg->n == lg->cap) {
        size_t cap = lg->cap ? 2 * lg->cap : 256;
        double *r = realloc(lg->rows, cap * HEAT_COLS * sizeof(double));
        if (!r) return consph_fail(CONSPH_ENOMEM, "out of memory");
        lg->rows = r;
        lg->cap = cap;
    }
    double *row = lg->rows + lg->n * HEAT_COLS;
    row[0] = (double)h->step;
    row[1] = h->t;
    row[2] = h->step == 0 ? 0.0 : h->step == h->nsteps ? h->dt_last : h->dt;
    row[3] = consph_sum(h->T, h->n) / (double)h->n;
    row[4] = row[5] = row[6] = NAN;
    ++lg->n;
    return with_errors ? consph_heat_errors(h, &row[4], &row[5], &row[6]) : CONSPH_OK;
}

static int heat_snapshot(consph_heat *h, runfiles *f, heat_log *lg)
{
    int st = consph_heat_output_fields(h);
    if (st == CONSPH_OK) st = runfiles_snapshot(f, h->sys.p, h->step, h->t);
    if (st == CONSPH_OK)
        st = runfiles_csv(f, "log.csv", "step,t,dt,mean_T,l2,linf,ec", lg->rows, lg->n, HEAT_COLS);
    return st;
}

static void summary_json(FILE *fp, const void *sum)
{
    consph_heat_summary_json(fp, sum);
}

int consph_heat_run(consph_heat *h, const char *dir, long snapshot_every, consph_heat_summary *sum)
{
    runfiles f = {.dir = dir};
    heat_log lg = {NULL, 0, 0};
    int st = CONSPH_OK;
    if (dir) {
        st = consph_run_dir_check(dir, NULL, 0);
        if (st == CONSPH_OK) st = runfiles_pvd_init(&f);
        if (st == CONSPH_OK) st = log_row(h, &lg, 1);
        if (st == CONSPH_OK) st = heat_snapshot(h, &f, &lg);
    }
    while (st == CONSPH_OK && !consph_heat_done(h)) {
        st = consph_heat_step(h);
        if (st != CONSPH_OK || !dir) continue;
        const int snap =
            consph_heat_done(h) || (snapshot_every > 0 && h->step % snapshot_every == 0);
        st = log_row(h, &lg, snap);
        if (st == CONSPH_OK && snap) st = heat_snapshot(h, &f, &lg);
    }
    int sst = consph_heat_summary_get(h, sum);
    if (st == CONSPH_OK) st = sst;
    if (dir && st == CONSPH_OK) st = runfiles_text(&f, "summary.json", summary_json, sum);
    if (dir && st == CONSPH_ENUMERIC) {
        /* keep the divergence's message; the log up to it still helps */
        char msg[512];
        snprintf(msg, sizeof msg, "%s", consph_last_error());
        runfiles_csv(&f, "log.csv", "step,t,dt,mean_T,l2,linf,ec", lg.rows, lg.n, HEAT_COLS);
        consph_fail(st, "%s", msg);
    }
    runfiles_free(&f);
    free(lg.rows);
    return st;
}
