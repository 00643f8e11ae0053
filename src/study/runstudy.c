/* Study kind `run`: the solver over a sweep of resolutions (001 Tables 8, 9, Fig. 20). Each
 * series is one scheme; each resolution one run of consph_run without files. The report gives
 * L1(u) and L1(p) (001 eq. 26, or with error = authors the measure of 001's authors and eq. 26
 * beside it) per nx, their fitted orders with standard errors, F_T/F_max at
 * the finest nx, T_r against a named series, and the paper's values beside ours. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/gpu.h"
#include "consph/io.h"
#include "consph/solver.h"
#include "study/kinds/kinds.h"
#include "study/kinds/run.h"

/* `quick.KEY` in a quick run when set, else KEY. */
static const char *quick_key(const consph_study *s, const study_figure *f, const study_series *r,
                             int quick, const char *key, char *buf, size_t size)
{
    snprintf(buf, size, "quick.%s", key);
    return quick && study_get(s, f, r, buf) ? buf : key;
}

/* The parameters of a run from the keys of the parameter table (consph_run_param_at: a key
 * sets its parameter through consph_run_param_set), then the keys of the study itself. */
static int plan_build(const consph_study *s, const study_figure *f, const study_series *r,
                      int quick, run_plan *pl)
{
    static const char *const rules[] = {"finest", "own", NULL};
    static const char *const l1s[] = {"integral", "mean", NULL};
    memset(pl, 0, sizeof *pl);
    consph_run_params *p = &pl->prm;
    consph_run_params_default(p);
    int rc, rule;
    char qk[32];
    /* The problem first: its own defaults (Gresho-Chan: inviscid, t = 3, lattice), which the
     * keys below override. */
    const char *v = study_get(s, f, r, "problem");
    if (v && consph_run_param_set(p, "problem", v) != CONSPH_OK)
        return study_key_error(s, f, r, "problem", "%s", consph_last_error());
    if ((rc = consph_run_params_problem(p, p->problem))) return rc;
    if (!study_get(s, f, r, "scheme"))
        return study_key_error(s, f, r, "scheme", "not given; allowed: %s", consph_scheme_names());
    for (int j = 0; j < consph_run_param_count(); ++j) {
        const consph_run_param *d = consph_run_param_at(j);
        if (!d->study_key || !strcmp(d->name, "problem") || (d->flags & CONSPH_PFLAG_NX)) continue;
        const char *k = d->flags & CONSPH_PFLAG_QUICK
                            ? quick_key(s, f, r, quick, d->study_key, qk, sizeof qk)
                            : d->study_key;
        if (!(v = study_get(s, f, r, k))) continue;
        /* "default": the problem's layout, else the scheme's */
        if (d->type == CONSPH_PTYPE_LAYOUT && !strcmp(v, "default")) continue;
        if (consph_run_param_set(p, d->name, v) != CONSPH_OK)
            return study_key_error(s, f, r, k, "%s", consph_last_error());
    }
    if (study_get(s, f, r, "re")) p->nu = -1.0; /* ν from the Re given, not the problem's */
    /* A step count replaces the final time: both given, one would be ignored. */
    char qt[16];
    const char *k = quick_key(s, f, r, quick, "steps", qk, sizeof qk);
    const char *tk = quick_key(s, f, r, quick, "tf", qt, sizeof qt);
    if (study_get(s, f, r, k) && study_get(s, f, r, tk))
        return study_key_error(s, f, r, k, "conflicts with '%s' (line %d); give one of them", tk,
                               study_line(s, f, r, tk));
    if ((rc = study_get_choice(s, f, r, "dt_rule", rules, 0, &rule))) return rc;
    pl->dt_finest = rule == 0;
    if ((rc = study_get_choice(s, f, r, "l1", l1s, 0, &pl->l1_mean))) return rc;
    k = quick_key(s, f, r, quick, "nx", qk, sizeof qk);
    if ((rc = study_get_list(s, f, r, k, 4, 1e5, pl->nx, &pl->nnx))) return rc;
    if (pl->nnx == 0) return study_key_error(s, f, r, "nx", "no resolutions given");
    for (int j = 0; j < pl->nnx; ++j)
        if (pl->nx[j] != floor(pl->nx[j]) || (j && !(pl->nx[j] > pl->nx[j - 1])))
            return study_key_error(s, f, r, k, "resolutions must be whole and increasing");
    p->nx = (int)pl->nx[pl->nnx - 1];
    if (consph_run_nx_check(p->nx, consph_problem_dim(p->problem)) != CONSPH_OK)
        return study_key_error(s, f, r, k, "%s", consph_last_error());
    if (consph_run_params_check(p) != CONSPH_OK)
        return study_key_error(s, f, r, "scheme", "%s", consph_last_error());
    /* as consph run's options: a series' key setting a parameter its scheme does not read would
     * do nothing; a figure's or the study's is a default for every series and stays allowed */
    char list[512];
    for (int j = 0; j < consph_run_param_count(); ++j) {
        const consph_run_param *d = consph_run_param_at(j);
        if (!d->reads || !d->study_key || !study_series_sets(s, f, r, d->study_key) ||
            (!strcmp(d->name, "eos") && p->eos == CONSPH_EOS_DEFAULT) ||
            consph_scheme_reads(p->scheme, d->reads))
            continue;
        return study_key_error(s, f, r, d->study_key,
                               "does nothing for the scheme %s (it acts on: %s)", p->scheme,
                               consph_scheme_readers(d->reads, list, sizeof list));
    }
    const int lk = consph_run_params_layout(p);
    if (study_series_sets(s, f, r, "seed") && !consph_layout_uses_seed((consph_layout_kind)lk))
        return study_key_error(s, f, r, "seed",
                               "does nothing for the layout %s, which draws no random numbers "
                               "(it acts on: %s)",
                               consph_layout_name((consph_layout_kind)lk),
                               consph_layout_seeded_names(list, sizeof list));
    return CONSPH_OK;
}

/* The series T_r is relative to: `tr_ref` names it (001 Table 9 is relative to EWCSPH), else
 * the first. */
static int tr_reference(const consph_study *s, const study_figure *f, int *ref)
{
    const char *v = study_get(s, f, NULL, "tr_ref");
    *ref = 0;
    if (!v) return CONSPH_OK;
    for (int k = 0; k < f->nseries; ++k)
        if (strcmp(f->series[k].label, v) == 0) {
            *ref = k;
            return CONSPH_OK;
        }
    return study_key_error(s, f, NULL, "tr_ref", "no series '%s' in this figure", v);
}

/* The abscissa of the figure: nx, the wall time (001 Fig. 20), the radius (u_φ(r) of a
 * centred vortex at the end of the finest run, 001 Figs. 15-16) or the time (the momentum
 * histories of the finest run, 001 Figs. 15-17). */
static int x_axis(const consph_study *s, const study_figure *f, int *x)
{
    static const char *const xs[] = {"nx", "seconds", "radius", "time", NULL};
    return study_get_choice(s, f, NULL, "x", xs, X_NX, x);
}

int study_run_validate(const consph_study *s, const study_figure *f, int quick)
{
    static const char *const devices[] = {"cpu", "gpu", "auto", NULL};
    int rc, dummy;
    if ((rc = study_get_choice(s, f, NULL, "device", devices, 0, &dummy))) return rc;
    for (int k = 0; k < f->nseries; ++k) {
        run_plan pl;
        if ((rc = plan_build(s, f, &f->series[k], quick, &pl))) return rc;
    }
    int x, ys[MAX_PANELS];
    if ((rc = tr_reference(s, f, &dummy))) return rc;
    if ((rc = x_axis(s, f, &x))) return rc;
    return run_y_panels(s, f, x, ys, &dummy);
}

/* Particles of a run at resolution nx: nx^d in the problem's dimension. */
static double particles_of(const run_plan *pl, double nx)
{
    return consph_problem_dim(pl->prm.problem) == 3 ? nx * nx * nx : nx * nx;
}

/* Steps of a run at resolution nx (an estimate: h = hdx/nx on a unit box). */
static double steps_of(const run_plan *pl, double nx)
{
    const consph_run_params *p = &pl->prm;
    if (p->steps > 0) return (double)p->steps;
    if (p->dt > 0) return ceil(p->tf / p->dt);
    double c0 = p->c0 > 0 ? p->c0 : 10.0 * p->U;
    double h = p->hdx / (pl->dt_finest ? pl->nx[pl->nnx - 1] : nx);
    return ceil(p->tf / (p->cfl * h / (p->U + c0)));
}

/* The seconds to pack the layout of one run, 0 when the cache holds it or when an earlier row
 * of this estimate packs the same one and the cache keeps it for the others (keys: `seen`). */
static double run_packing_seconds(const consph_run_params *prm, char (*seen)[512], int *nseen)
{
    consph_layout_params lp;
    if (consph_run_layout_params(prm, &lp) != CONSPH_OK) return 0.0;
    char key[512];
    if (consph_layout_cache_get() && consph_layout_cache_key(&lp, key, sizeof key) == CONSPH_OK) {
        for (int q = 0; q < *nseen; ++q)
            if (!strcmp(seen[q], key)) return 0.0;
        if (*nseen < 64) snprintf(seen[(*nseen)++], sizeof seen[0], "%s", key);
    }
    return study_packing_seconds(&lp);
}

int study_run_layouts(const consph_study *s, const study_figure *f, int quick,
                      void (*add)(const consph_layout_params *lp, void *ctx), void *ctx)
{
    for (int k = 0; k < f->nseries; ++k) {
        run_plan pl;
        int rc = plan_build(s, f, &f->series[k], quick, &pl);
        if (rc) return rc;
        for (int j = 0; j < pl.nnx; ++j) {
            consph_run_params row = pl.prm;
            row.nx = (int)pl.nx[j];
            consph_layout_params lp;
            if (consph_run_layout_params(&row, &lp) == CONSPH_OK) add(&lp, ctx);
        }
    }
    return CONSPH_OK;
}

static double finest_h(const run_plan *pl);

/* One calibration run of a series at nx per side, on its own layout (a packed one is packed once
 * and cached like a row's; IPST's iterations depend on the arrangement: a lattice meets eq. 21
 * at once where a packed layout takes all ten) or on the lattice: its first step untimed (it
 * touches every array for the first time and makes IPST's first, one-iteration shift), then
 * `steps` steps timed. At the series' Δt where its rows share one (dt_rule = finest), so that
 * IPST's steps per shift are the rows'; else at its own, IPST keeping the series' steps per
 * shift. Errors by eq. 26 (the authors' 50 samples would fall at every step of a calibration,
 * where a row spreads them over thousands) against the incompressible solution unless `exact`
 * (then the series' own: with the weakly-compressible reference, its evaluation at the particles
 * at the log cadence). The timed steps run as `blocks` blocks of `steps`, the diagnostics sampled
 * every `steps` steps (once in each block): seconds per particle-step of the fastest block (other
 * work on the machine, and a virtual machine's stolen time, only add to a block), and per particle
 * of the set-up without packing (packing: study_packing_seconds). */
static int calibrate(const run_plan *pl, int nx, int lattice, int exact, long steps, int blocks,
                     double *per_step, double *per_made)
{
    consph_run_params p = pl->prm;
    p.nx = nx;
    if (lattice) p.layout = CONSPH_LAYOUT_LATTICE;
    p.error = CONSPH_ERROR_EQ26;
    if (!exact) p.exact = CONSPH_EXACT_INCOMPRESSIBLE;
    p.h_dt = 0.0;
    if (pl->dt_finest)
        p.h_dt = finest_h(pl);
    else if (p.ipst_h_dt > 0.0)
        /* IPST on a time schedule shifts once per ipst_every steps of a Δt at h = ipst_h_dt: keep
         * the series' steps per shift, which the calibration's larger Δt would otherwise turn
         * into a shift at every step */
        p.ipst_h_dt *= (p.hdx / p.nx) / (p.hdx / pl->nx[0]);
    const double n = particles_of(pl, nx);
    p.steps = (long)blocks * steps + 1;
    /* each block samples the diagnostics once, as a row does every log_every steps */
    p.log_every = (int)steps;
    consph_solver *sv = NULL;
    double t0 = study_cpu_seconds();
    int rc = consph_solver_create(&sv, &p);
    if (rc) return rc;
    *per_made = (study_cpu_seconds() - t0) / n;
    rc = consph_solver_step(sv);
    double fastest = INFINITY;
    for (int b = 0; rc == CONSPH_OK && b < blocks; ++b) {
        t0 = study_cpu_seconds();
        for (long k = 0; rc == CONSPH_OK && k < steps; ++k) rc = consph_solver_step(sv);
        fastest = fmin(fastest, study_cpu_seconds() - t0);
    }
    *per_step = fastest / (n * (double)steps);
    consph_solver_free(sv);
    return rc;
}

/* Calibration sizes. Small: a few hundred particles, every series (their costs per particle-step
 * differ by 2-3 times: IPST's iterations, the remeshing, the passes per stage). Large: one run
 * whose pair cache (about 2 kB per particle in 2D, 10 kB in 3D) is larger than a processor's
 * last-level cache (tens of MB), so that it pays the memory traffic of a study's large rows,
 * which a run whose data stay in the caches does not show (1.1-1.2 times the small run's cost
 * per particle-step at 128² on this machine; docs/studies.md compares the estimate with rows at
 * nx 500). */
#define CAL_NX_SMALL_2D 16
#define CAL_NX_SMALL_3D 8
#define CAL_NX_LARGE_2D 128
#define CAL_NX_LARGE_3D 20
/* Timed steps of a small calibration: blocks of 10 steps, each holding one shift of IPST every 10
 * steps (after steps 1, 11, 21 and 31) and one sample of the diagnostics, as a row's steps do; the
 * fastest of three. The size factor compares blocks of 4 steps, one sample each, at the small size
 * (the fastest of five: steps 2-5, 6-9 and 14-17 shift nothing) with the fastest of two at the
 * large one (steps 2-5 and 6-9), and the weakly-compressible reference's evaluation is timed in
 * such blocks too. Timed once, 20 steps of the small calibration gave 0.57-0.84 us per
 * particle-step for one series in four estimates run back to back on the shared 2-core machine,
 * and the size factor 1.0-1.54: the estimate of 001-table9 30-56 hours. */
#define CAL_STEPS_SMALL 10
#define CAL_BLOCKS_SMALL 3
#define CAL_STEPS_LARGE 4
#define CAL_BLOCKS_RATIO 5
#define CAL_BLOCKS_LARGE 2
/* The calibrations of a figure stop calibrating series one by one past this many seconds (the
 * rest take the mean rate of those done), so that an estimate stays within about 2 s. */
#define CAL_BUDGET_SECONDS 1.0

/* The size factor at N particles: 1 up to the small calibration's n0, the large one's ratio from
 * its n1 on, log-linear between. */
static double size_factor(double n, double n0, double n1, double ratio)
{
    if (!(n1 > n0) || n <= n0) return 1.0;
    if (n >= n1) return ratio;
    return 1.0 + (ratio - 1.0) * log(n / n0) / log(n1 / n0);
}

double study_run_estimate(const consph_study *s, const study_figure *f, int quick,
                          double *particle_steps)
{
    *particle_steps = 0.0;
    if (f->nseries == 0) return 0.0;
    run_plan *plans = calloc((size_t)f->nseries, sizeof *plans);
    double *rate = calloc((size_t)f->nseries, sizeof *rate);
    if (!plans || !rate) {
        free(plans);
        free(rate);
        return NAN;
    }
    double packing = 0.0, made = 0.0, max_nx = 0.0;
    char seen[64][512];
    int nseen = 0;
    for (int k = 0; k < f->nseries; ++k) {
        run_plan *pl = &plans[k];
        if (plan_build(s, f, &f->series[k], quick, pl) != CONSPH_OK) {
            free(plans);
            free(rate);
            return NAN;
        }
        for (int j = 0; j < pl->nnx; ++j) {
            *particle_steps += particles_of(pl, pl->nx[j]) * steps_of(pl, pl->nx[j]);
            made += particles_of(pl, pl->nx[j]);
            if (pl->nx[j] > max_nx) max_nx = pl->nx[j];
            consph_run_params row = pl->prm;
            row.nx = (int)pl->nx[j];
            packing += run_packing_seconds(&row, seen, &nseen);
        }
    }
    const int dim3 = consph_problem_dim(plans[0].prm.problem) == 3;
    const int nx0 = dim3 ? CAL_NX_SMALL_3D : CAL_NX_SMALL_2D;
    /* no larger than the study's largest row */
    const int nx1 = (int)fmin(dim3 ? CAL_NX_LARGE_3D : CAL_NX_LARGE_2D, max_nx);
    /* every series at the small size on its own layout; the dearest (by its rows' work) again
     * on the lattice at both sizes */
    double per_made = 0.0, sum_rate = 0.0, dearest = -1.0;
    int calibrated = 0, big = 0;
    const double t0 = consph_wtime();
    for (int k = 0; k < f->nseries; ++k) {
        if (calibrated > 0 && consph_wtime() - t0 > CAL_BUDGET_SECONDS) {
            rate[k] = -1.0;
            continue;
        }
        double unused;
        if (calibrate(&plans[k], nx0, 0, 0, CAL_STEPS_SMALL, CAL_BLOCKS_SMALL, &rate[k], &unused) !=
            CONSPH_OK) {
            free(plans);
            free(rate);
            return NAN;
        }
        sum_rate += rate[k];
        ++calibrated;
        double work = 0.0;
        for (int j = 0; j < plans[k].nnx; ++j)
            work += particles_of(&plans[k], plans[k].nx[j]) * steps_of(&plans[k], plans[k].nx[j]);
        if (rate[k] * work > dearest) {
            dearest = rate[k] * work;
            big = k;
        }
    }
    for (int k = 0; k < f->nseries; ++k)
        if (rate[k] < 0.0) rate[k] = sum_rate / calibrated;
    /* the size factor, on the lattice at both sizes; at the large size the weakly-compressible
     * reference's evaluation too, per particle and sample, where the series has it (its solve, a
     * cost per row whatever the particles, is left out) */
    double ratio = 1.0, wc_side = 0.0, small_steps = 0.0, large_steps = 0.0, unused;
    const double n0 = particles_of(&plans[big], nx0), n1 = particles_of(&plans[big], nx1);
    int rc = calibrate(&plans[big], nx0, 1, 0, CAL_STEPS_LARGE, CAL_BLOCKS_RATIO, &small_steps,
                       &per_made);
    if (rc == CONSPH_OK && nx1 > nx0) {
        rc = calibrate(&plans[big], nx1, 1, 0, CAL_STEPS_LARGE, CAL_BLOCKS_LARGE, &large_steps,
                       &per_made);
        /* the memory traffic makes a run dearer, never cheaper: a faster large run is noise */
        if (rc == CONSPH_OK) ratio = fmax(1.0, large_steps / small_steps);
    }
    if (rc == CONSPH_OK && plans[big].prm.exact != CONSPH_EXACT_INCOMPRESSIBLE) {
        double with_wc;
        const int nx_wc = nx1 > nx0 ? nx1 : nx0;
        rc = calibrate(&plans[big], nx_wc, 1, 1, CAL_STEPS_LARGE, CAL_BLOCKS_LARGE, &with_wc,
                       &unused);
        /* per particle and sample: the calibration sampled once in CAL_STEPS_LARGE steps */
        if (rc == CONSPH_OK)
            wc_side =
                CAL_STEPS_LARGE * fmax(0.0, with_wc - (nx1 > nx0 ? large_steps : small_steps));
    }
    if (rc) {
        free(plans);
        free(rate);
        return NAN;
    }
    double seconds = made * per_made + packing;
    for (int k = 0; k < f->nseries; ++k)
        for (int j = 0; j < plans[k].nnx; ++j) {
            const double n = particles_of(&plans[k], plans[k].nx[j]);
            /* a row evaluates the reference at each sample, every log_every steps */
            const double wc = plans[k].prm.exact != CONSPH_EXACT_INCOMPRESSIBLE
                                  ? wc_side / fmax(1.0, plans[k].prm.log_every)
                                  : 0.0;
            seconds += n * steps_of(&plans[k], plans[k].nx[j]) *
                       (rate[k] * size_factor(n, n0, n1, ratio) + wc);
        }
    free(plans);
    free(rate);
    return seconds;
}

/* h of the sweep's finest run as the solver derives it (derive_solver: hdx times the box's
 * length over nx), bit for bit. */
static double finest_h(const run_plan *pl)
{
    consph_run_params p = pl->prm;
    p.nx = (int)pl->nx[pl->nnx - 1];
    consph_layout_params lp;
    if (consph_run_layout_params(&p, &lp) != CONSPH_OK) return 0.0;
    return p.hdx * ((lp.box.hi[0] - lp.box.lo[0]) / p.nx);
}

/* u_φ(r) about the centre of the box, with the exact u_φ, per particle at the end of a run. */
static int keep_profile(consph_solver *sv, run_row *row)
{
    int rc = consph_solver_output_fields(sv);
    if (rc) return rc;
    const consph_particles *p = consph_solver_particles(sv);
    const consph_field *fu = consph_particles_find(p, "u");
    const consph_field *fe = consph_particles_find(p, "u_exact");
    if (!fu || !fe || p->dim != 2)
        return consph_fail(CONSPH_EINVAL, "x = radius needs a 2D run with u and u_exact");
    row->curve = malloc(3 * p->n * sizeof *row->curve);
    if (!row->curve) return consph_fail(CONSPH_ENOMEM, "out of memory");
    row->ncurve = p->n;
    const size_t cap = p->cap;
    const double xc = 0.5 * (p->box.lo[0] + p->box.hi[0]), yc = 0.5 * (p->box.lo[1] + p->box.hi[1]);
    for (size_t i = 0; i < p->n; ++i) {
        const double x = p->x[0][i] - xc, y = p->x[1][i] - yc, r = hypot(x, y);
        const double *u = fu->data, *e = fe->data;
        row->curve[3 * i] = r;
        row->curve[3 * i + 1] = r > 0.0 ? (x * u[cap + i] - y * u[i]) / r : 0.0;
        row->curve[3 * i + 2] = r > 0.0 ? (x * e[cap + i] - y * e[i]) / r : 0.0;
    }
    return CONSPH_OK;
}

/* t, M_x, M_y and L of every step the run took (a diverged run's up to its last finite step). */
static int keep_history(const consph_solver *sv, run_row *row)
{
    const size_t n = consph_solver_history_size(sv);
    row->curve = malloc(4 * (n ? n : 1) * sizeof *row->curve);
    if (!row->curve) return consph_fail(CONSPH_ENOMEM, "out of memory");
    row->ncurve = n;
    for (size_t k = 0; k < n; ++k) {
        consph_step_diag d;
        int rc = consph_solver_history_row(sv, k, &d);
        if (rc) return rc;
        double *c = row->curve + 4 * k;
        c[0] = d.t;
        c[1] = d.mom[0];
        c[2] = d.mom[1];
        c[3] = d.ang;
    }
    return CONSPH_OK;
}

void study_run_gpu_refusals(const consph_study *s, const study_figure *f, int quick, char *buf,
                            size_t size, size_t *len, int *bad)
{
    for (int k = 0; k < f->nseries; ++k) {
        run_plan pl;
        if (plan_build(s, f, &f->series[k], quick, &pl) != CONSPH_OK) continue;
        for (int j = 0; j < pl.nnx; ++j) {
            consph_run_params p = pl.prm;
            p.nx = (int)pl.nx[j];
            if (consph_gpu_check(&p) == CONSPH_OK) continue;
            /* the rows of a series differ in nx alone, which no GPU check reads: one line each */
            const char *why = consph_last_error();
            if (!strncmp(why, "--device gpu: ", 14)) why += 14;
            if (*len < size)
                *len +=
                    (size_t)snprintf(buf + *len, size - *len, "\n  figure '%s', series '%s' (nx",
                                     f->id, f->series[k].label);
            for (int q = 0; q < pl.nnx && *len < size; ++q)
                *len += (size_t)snprintf(buf + *len, size - *len, "%s%g", q ? ", " : " ", pl.nx[q]);
            if (*len < size) *len += (size_t)snprintf(buf + *len, size - *len, "): %s", why);
            ++*bad;
            break;
        }
    }
}

/* Whether the rows of a series run on the GPU: every one under DEVICE_GPU (checked before the
 * study started, consph_study_device_check), those consph_gpu_check passes under DEVICE_AUTO. */
static int series_on_gpu(const study_job *job, const run_plan *pl)
{
    if (job->device == CONSPH_STUDY_DEVICE_GPU) return 1;
    return job->device == CONSPH_STUDY_DEVICE_AUTO && job->gpu_ok &&
           consph_gpu_check(&pl->prm) == CONSPH_OK;
}

/* One run; `curve` (X_RADIUS, X_TIME, else none) keeps that curve of it. With `rows`, a stop
 * request ends it at its next step: STUDY_STOPPED, the row not done. `gpu`: its steps on the GPU
 * (a failure to move there is the row's under DEVICE_GPU; under DEVICE_AUTO the row stays on the
 * CPU, whose state the failed move left as it was), row->device says where it ran. */
static int run_one(const run_plan *pl, int j, double h_dt, int curve, run_row *row,
                   study_rows *rows, int gpu, int device)
{
    consph_run_params p = pl->prm;
    p.nx = (int)pl->nx[j];
    p.h_dt = h_dt;
    consph_solver *sv = NULL;
    int rc = consph_solver_create(&sv, &p);
    if (rc) return rc;
    row->device = CONSPH_DEVICE_CPU;
    if (gpu) {
        rc = consph_solver_set_device(sv, CONSPH_DEVICE_GPU);
        if (rc == CONSPH_OK) row->device = CONSPH_DEVICE_GPU;
        if (rc != CONSPH_OK && device == CONSPH_STUDY_DEVICE_GPU) {
            consph_solver_free(sv);
            return rc;
        }
    }
    if (!consph_solver_dt_warning(sv, row->dt_warning, sizeof row->dt_warning))
        row->dt_warning[0] = '\0';
    int stopped = 0;
    /* On a terminal the run's own step line shows (after the row, consph_progress_prefix). */
    const consph_run_output watch = {.signals = rows ? rows->signals : 0,
                                     .progress = rows && rows->tty};
    rc = consph_run(sv, rows && rows->signals ? &watch : NULL, &row->sum, &stopped);
    if (rows && rows->signals) {
        if (stopped && !rows->stopped) rows->stopped = stopped;
    }
    if (rows && rows->signals == 1) {
        /* consph_run gave back the handlers it found; the study keeps watching. */
        int irc = consph_stop_install();
        if (rc == CONSPH_OK) rc = irc;
    }
    if (rc == CONSPH_OK && stopped) {
        consph_solver_free(sv);
        return STUDY_STOPPED;
    }
    if (rc == CONSPH_OK && curve == X_RADIUS) rc = keep_profile(sv, row);
    /* A diverged run's history is kept too: it shows how it got there. */
    if ((rc == CONSPH_OK || rc == CONSPH_ENUMERIC) && curve == X_TIME) {
        int hr = keep_history(sv, row);
        if (hr) rc = hr;
    }
    consph_solver_free(sv);
    row->status = rc;
    if (pl->l1_mean && row->sum.t > 0) {
        row->sum.l1_u /= row->sum.t;
        row->sum.l1_p /= row->sum.t;
        row->sum.wc_l1_u /= row->sum.t;
        row->sum.wc_l1_p /= row->sum.t;
    }
    row->eq26_u = row->sum.l1_u;
    row->eq26_p = row->sum.l1_p;
    if (AUTHORS(pl)) {
        row->sum.l1_u = row->sum.l1n_u;
        row->sum.l1_p = row->sum.l1n_p;
    }
    /* A diverged run is a result of the study, reported, not the end of it. */
    if (rc == CONSPH_ENUMERIC) {
        snprintf(row->why, sizeof row->why, "%s", consph_last_error());
        return CONSPH_OK;
    }
    return rc;
}

/* The rows of a run figure (one run per series and resolution) and their particle-steps. */
int study_run_rows(const consph_study *s, const study_figure *f, int quick, double *work)
{
    int n = 0;
    for (int k = 0; k < f->nseries; ++k) {
        run_plan pl;
        if (plan_build(s, f, &f->series[k], quick, &pl) != CONSPH_OK) continue;
        for (int j = 0; j < pl.nnx; ++j)
            *work += particles_of(&pl, pl.nx[j]) * steps_of(&pl, pl.nx[j]);
        n += pl.nnx;
    }
    return n;
}

int study_run_figure(const study_job *job, const study_figure *f)
{
    const consph_study *s = job->s;
    const int quick = job->quick;
    const char *dir = job->dir;
    FILE *log = job->log;
    int ref, x, rc = study_run_validate(s, f, quick);
    if (rc == CONSPH_OK) rc = tr_reference(s, f, &ref);
    if (rc == CONSPH_OK) rc = x_axis(s, f, &x);
    if (rc) return rc;
    run_plan *plans = calloc((size_t)f->nseries, sizeof *plans);
    run_row(*rows)[MAX_SWEEP] = calloc((size_t)f->nseries, sizeof *rows);
    if (!plans || !rows) rc = consph_fail(CONSPH_ENOMEM, "out of memory");
    double particle_steps = 0.0;
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
        rc = plan_build(s, f, &f->series[k], quick, &plans[k]);
        for (int j = 0; rc == CONSPH_OK && j < plans[k].nnx; ++j)
            particle_steps +=
                particles_of(&plans[k], plans[k].nx[j]) * steps_of(&plans[k], plans[k].nx[j]);
    }
    if (log && rc == CONSPH_OK)
        fprintf(log, "  %d series, about %.2g particle-steps\n", f->nseries, particle_steps);
    for (int k = 0; rc == CONSPH_OK && k < f->nseries; ++k) {
        const run_plan *pl = &plans[k];
        const int gpu = series_on_gpu(job, pl);
        /* The finest first; its h sets Δt of the whole sweep (dt_rule = finest), known before it
         * runs, so that every row is a unit of its own for --jobs and MPI ranks. */
        const double h_finest = pl->dt_finest ? finest_h(pl) : 0.0;
        for (int j = pl->nnx - 1; rc == CONSPH_OK && j >= 0; --j) {
            if (study_rows_stop(job)) {
                rc = STUDY_STOPPED;
                break;
            }
            rc = study_row_elsewhere(job);
            if (rc == STUDY_ELSEWHERE) {
                rc = CONSPH_OK;
                continue;
            }
            if (rc) break;
            run_row *w = &rows[k][j];
            char what[32];
            snprintf(what, sizeof what, "nx=%g", pl->nx[j]);
            study_row_begin(job, f, k, what, particles_of(pl, pl->nx[j]) * steps_of(pl, pl->nx[j]));
            /* A row an earlier run kept is read back with its curve, not run again. */
            double *curve = NULL;
            size_t ncurve_values = 0;
            const int stored = study_row_load(job, f, k, j, w, sizeof *w, &curve, &ncurve_values);
            if (stored) {
                w->curve = curve;
                rc = CONSPH_OK;
            } else {
                rc = run_one(pl, j, j == pl->nnx - 1 ? 0.0 : h_finest, j == pl->nnx - 1 ? x : X_NX,
                             w, job->rows, gpu, job->device);
            }
            if (rc == STUDY_STOPPED) break;
            if (rc) {
                consph_fail(rc, "figure '%s', series '%s', nx %g: %s", f->id, f->series[k].label,
                            pl->nx[j], consph_last_error());
                break;
            }
            if (pl->dt_finest && j == pl->nnx - 1 && w->status == CONSPH_OK && w->sum.h != h_finest)
                rc = consph_fail(CONSPH_EINVAL,
                                 "figure '%s', series '%s': the finest run's h %.17g is not the "
                                 "h %.17g its sweep's time step was given",
                                 f->id, f->series[k].label, w->sum.h, h_finest);
            if (rc) break;
            if (log)
                fprintf(log,
                        "  %-24s nx=%-5g N=%-7zu steps=%-7ld L1(u)=%.3e L1(p)=%.3e (%.2fs%s)%s\n",
                        f->series[k].label, pl->nx[j], w->sum.n, w->sum.steps, w->sum.l1_u,
                        w->sum.l1_p, w->sum.seconds,
                        job->device == CONSPH_STUDY_DEVICE_DEFAULT ? ""
                        : w->device == CONSPH_DEVICE_GPU           ? " on the GPU"
                                                                   : " on the CPU",
                        w->status ? " diverged" : "");
            if (log && w->dt_warning[0]) fprintf(log, "  warning: %s\n", w->dt_warning);
            const size_t cols =
                j == pl->nnx - 1 && x >= X_RADIUS ? (size_t)curve_kinds[x].ncols : 0;
            rc = study_row_finish(job, f, k, j, w, sizeof *w, w->curve,
                                  w->curve ? cols * w->ncurve : 0, stored);
        }
    }
    char tbuf[640];
    const char *title = rc == CONSPH_OK ? run_title(s, f, quick, &plans[0], tbuf, sizeof tbuf) : "";
    if (rc == CONSPH_OK)
        rc = run_write_report(s, f, quick, dir, plans, rows, ref, x, title,
                              job->device != CONSPH_STUDY_DEVICE_DEFAULT);
    if (rc == CONSPH_OK && run_plottable(f, plans, rows, x))
        rc = run_write_plot(s, f, dir, quick, plans, rows, x);
    for (int k = 0; rows && k < f->nseries; ++k)
        for (int j = 0; j < MAX_SWEEP; ++j) free(rows[k][j].curve);
    free(plans);
    free(rows);
    return rc;
}
