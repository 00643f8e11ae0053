/* The series plan of the operator kinds (approx, m0, appc, cauchy): a series' keys parsed into
 * an approx spec and a sweep, the layouts they run on (cached: packed layouts are expensive and
 * shared between series), and the particle files that replace them. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "study/kinds/kinds.h"

/* N^(1/dim), exact when N is a perfect power, so that a file made by `consph layout --nx K`
 * reports nx = K. */
double study_resolution_of(const consph_particles *p)
{
    return consph_resolution_of(p->n, p->dim);
}

/* How h was chosen, for the reports. */
const char *study_h_policy_text(const consph_approx_spec *sp, char *buf, size_t size)
{
    const int d = sp->layout.dim;
    switch (sp->h_policy) {
    case CONSPH_H_SCALING:
        return "= N^(-1/6)";
    case CONSPH_H_ZHU:
        snprintf(buf, size, "= hdx·Δs at N = %.0f, then ∝ N^(-1/%d) (zhu: neighbours ∝ N^(1/2))",
                 sp->n_ref, 2 * d);
        return buf;
    case CONSPH_H_BETA:
        snprintf(buf, size,
                 "= hdx·Δs at N = %.0f, then ∝ N^(-1/%g) (004: N ∝ h^(-β), neighbours ∝ "
                 "N^%.3g)",
                 sp->n_ref, sp->beta, 1.0 - d / sp->beta);
        return buf;
    default:
        return "= hdx·Δs";
    }
}

int study_plan_build(const consph_study *s, const study_figure *f, const study_series *r, int quick,
                     series_plan *pl)
{
    static const char *const ops[] = {"function", "grad", "div", "laplacian", "hessian", NULL};
    static const char *const default_form[] = {"standard", "f4", "div", "coupled", "korzilius"};
    static const char *const policies[] = {"hdx", "scaling", "zhu", "beta", NULL};
    static const char *const layouts[] = {"lattice", "random",          "quasi-random",
                                          "packed",  "packed-polished", NULL};
    static const char *const yesno[] = {"yes", "no", NULL};
    static const char *const masks[] = {"interior", "all", NULL};
    static const char *const sweeps[] = {"nx", "hdx", NULL};
    static const char *const bounds[] = {"none", "interp", "delta", NULL};
    static const char *const norms[] = {"l1", "l2", "linf", "mae", NULL};
    static const char *const xs[] = {"nx", "nbr", "sqrtN", NULL};
    const char *volumes[CONSPH_VOLUME_COUNT + 1];
    for (int v = 0; v < CONSPH_VOLUME_COUNT; ++v)
        volumes[v] = consph_volume_name((consph_volume_kind)v);
    volumes[CONSPH_VOLUME_COUNT] = NULL;

    memset(pl, 0, sizeof *pl);
    int rc, kind_at, iop, ipol, ilay, iper, imask, isweep, ibound, ivol, dummy;
    double dim, hdx, match, eps, seed, sigma, tol, iters, beta;
    if ((rc = study_get_choice(s, f, r, "kind", study_kind_names, 0, &kind_at))) return rc;
    const study_kind *kind = study_kinds[kind_at];
    if ((rc = study_get_choice(s, f, r, "op", ops, 0, &iop))) return rc;
    if ((rc = study_get_choice(s, f, r, "h_policy", policies, 0, &ipol))) return rc;
    if ((rc = study_get_choice(s, f, r, "layout", layouts, 0, &ilay))) return rc;
    if ((rc = study_get_choice(s, f, r, "periodic", yesno, 0, &iper))) return rc;
    if ((rc = study_get_choice(s, f, r, "mask", masks, 0, &imask))) return rc;
    if ((rc = study_get_choice(s, f, r, "sweep", sweeps, 0, &isweep))) return rc;
    if ((rc = study_get_choice(s, f, r, "bound", bounds, 0, &ibound))) return rc;
    if ((rc = study_get_choice(s, f, r, "norm", norms, 0, &dummy))) return rc;
    if ((rc = study_get_choice(s, f, r, "x", xs, 0, &dummy))) return rc;
    if ((rc = study_get_choice(s, f, r, "volume", volumes, kind == &study_kind_m0 ? 2 : 1, &ivol)))
        return rc;
    if ((rc = study_get_double(s, f, r, "dim", kind == &study_kind_appc ? 1 : 2, 1, 3, &dim)))
        return rc;
    if (dim != floor(dim)) return study_key_error(s, f, r, "dim", "must be 1, 2 or 3");
    if ((rc = study_get_double(s, f, r, "hdx", 1.2, 0.01, 100, &hdx))) return rc;
    if ((rc = study_get_double(s, f, r, "match_support", 0, 0, 100, &match))) return rc;
    if ((rc = study_get_double(s, f, r, "beta", 0, 0, 1e3, &beta))) return rc;
    if (ipol == CONSPH_H_BETA && !(beta > dim))
        return study_key_error(s, f, r, "beta",
                               "h_policy = beta needs beta > dim = %g (004: β > n)", dim);
    if ((ilay == CONSPH_LAYOUT_PACKED || ilay == CONSPH_LAYOUT_PACKED_POLISHED) && iper != 0 &&
        kind != &study_kind_appc)
        return study_key_error(s, f, r, "periodic", "layout %s needs a periodic box; allowed: yes",
                               layouts[ilay]);
    if ((rc = study_get_double(s, f, r, "eps", 0.2, 0, 2, &eps))) return rc;
    if ((rc = study_get_double(s, f, r, "seed", 1, 0, 1e15, &seed))) return rc;
    if ((rc = study_get_double(s, f, r, "sigma", 0.1, 1e-9, 10, &sigma))) return rc;
    if ((rc = study_get_double(s, f, r, "pack_tol", 1e-4, 1e-12, 1, &tol))) return rc;
    const int iters_def = consph_layout_defaults((consph_layout_kind)ilay, 2, 10).packing.max_iter;
    if ((rc = study_get_double(s, f, r, "pack_iter", iters_def, 1, 1e7, &iters))) return rc;
    double walls;
    if ((rc = study_get_double(s, f, r, "pack_walls", 0, 0, 8, &walls))) return rc;
    if (walls != floor(walls))
        return study_key_error(s, f, r, "pack_walls", "a whole number of layers; allowed: 0..8");
    if (walls > 0 && ilay != CONSPH_LAYOUT_PACKED)
        return study_key_error(s, f, r, "pack_walls", "needs layout = packed");

    consph_approx_spec *sp = &pl->spec;
    *sp = consph_approx_defaults((int)dim);
    const char *form = study_get(s, f, r, "form");
    const char *corr = study_get(s, f, r, "corr");
    if (consph_op_parse(ops[iop], form ? form : default_form[iop], corr ? corr : "none", (int)dim,
                        &sp->op) != CONSPH_OK)
        return study_key_error(s, f, r, "form", "%s", consph_last_error());
    pl->kernel_name = study_get(s, f, r, "kernel");
    if (!pl->kernel_name) pl->kernel_name = "quintic";
    if (kind != &study_kind_appc && consph_kernel_lookup(pl->kernel_name, &sp->kernel) != CONSPH_OK)
        return study_key_error(s, f, r, "kernel", "%s", consph_last_error());
    if (match > 0) hdx *= match / consph_kernel_info_get(sp->kernel)->support;
    sp->hdx = hdx;
    sp->h_policy = (consph_h_policy)ipol;
    sp->beta = beta;
    sp->layout = consph_layout_defaults((consph_layout_kind)ilay, (int)dim, 10);
    sp->layout.eps = eps;
    sp->layout.seed = (uint64_t)seed;
    sp->layout.packing.tol = tol;
    sp->layout.packing.max_iter = (int)iters;
    sp->layout.packing.walls = (int)walls;
    sp->layout.box = consph_box_unit((int)dim, iper == 0);
    const char *field = study_get(s, f, r, "field");
    if (!field) field = iop == 2 ? "tgv" : "sin2pi";
    if (consph_mfield_lookup(field, &sp->field) != CONSPH_OK)
        return study_key_error(s, f, r, "field", "%s", consph_last_error());
    sp->field_params.sigma = sigma;
    sp->volume = (consph_volume_kind)ivol;
    sp->interior_only = imask == 0;
    pl->bound = ibound;
    if (kind == &study_kind_approx && consph_approx_check(sp) != CONSPH_OK)
        return study_key_error(s, f, r, "op", "%s", consph_last_error());

    double nxs[MAX_SWEEP];
    int nnx = 0;
    if (quick) {
        if ((rc = study_get_list(s, f, r, "quick.nx", 2, 1e5, nxs, &nnx))) return rc;
    }
    if (nnx == 0 && (rc = study_get_list(s, f, r, "nx", 2, 1e5, nxs, &nnx))) return rc;
    if (nnx == 0) return study_key_error(s, f, r, "nx", "no resolutions given");
    pl->sweep_hdx = isweep == 1 || kind == &study_kind_appc;
    if (pl->sweep_hdx) {
        const char *key = kind == &study_kind_appc ? "hdelta.values" : "hdx.values";
        char qkey[64];
        snprintf(qkey, sizeof qkey, "quick.%s", key);
        if (quick && (rc = study_get_list(s, f, r, qkey, 1e-3, 100, pl->values, &pl->nvalues)))
            return rc;
        if (pl->nvalues == 0 &&
            (rc = study_get_list(s, f, r, key, 1e-3, 100, pl->values, &pl->nvalues)))
            return rc;
        if (pl->nvalues == 0) return study_key_error(s, f, r, key, "no values given");
        pl->nx_fixed = (size_t)nxs[0];
    } else {
        memcpy(pl->values, nxs, sizeof(double) * (size_t)nnx);
        pl->nvalues = nnx;
    }
    /* zhu and beta agree with hdx at the first resolution. */
    sp->n_ref = pow(pl->sweep_hdx ? (double)pl->nx_fixed : pl->values[0], dim);
    return CONSPH_OK;
}

/* ---- layout cache: packed layouts are expensive and shared between series ---- */

static int same_layout(const consph_layout_params *a, const consph_layout_params *b)
{
    if (a->kind != b->kind || a->dim != b->dim || a->seed != b->seed) return 0;
    for (int d = 0; d < a->dim; ++d)
        if (a->nx[d] != b->nx[d] || a->box.periodic[d] != b->box.periodic[d]) return 0;
    if (a->kind == CONSPH_LAYOUT_RANDOM && a->eps != b->eps) return 0;
    if ((a->kind == CONSPH_LAYOUT_PACKED || a->kind == CONSPH_LAYOUT_PACKED_POLISHED) &&
        (a->packing.tol != b->packing.tol || a->packing.max_iter != b->packing.max_iter ||
         a->packing.move_tol != b->packing.move_tol || a->packing.hdx != b->packing.hdx ||
         a->packing.walls != b->packing.walls || strcmp(a->packing.kernel, b->packing.kernel)))
        return 0;
    return 1;
}

int study_layout_get(layout_cache *c, const consph_layout_params *lp, const consph_particles **p,
                     double *seconds, FILE *log)
{
    for (int k = 0; k < CACHE_SIZE; ++k)
        if (c->e[k].used && same_layout(&c->e[k].lp, lp)) {
            *p = &c->e[k].p;
            *seconds = 0.0;
            return CONSPH_OK;
        }
    cached_layout *e = &c->e[c->next];
    c->next = (c->next + 1) % CACHE_SIZE;
    if (e->used) consph_particles_free(&e->p);
    e->used = 0;
    double t0 = consph_wtime();
    consph_packing_report pack;
    memset(&pack, 0, sizeof pack);
    int rc = consph_layout_generate(lp, &e->p, &pack);
    if (rc == CONSPH_OK && lp->kind == CONSPH_LAYOUT_PACKED_POLISHED && log &&
        pack.rho_spread_final > lp->packing.tol)
        fprintf(log,
                "  warning: packing %zu^%d stopped at pack_iter %d with max|rho/rho0-1| = %.3g "
                "above pack_tol %g\n",
                lp->nx[0], lp->dim, lp->packing.max_iter, pack.rho_spread_final, lp->packing.tol);
    if (rc == CONSPH_OK && lp->kind == CONSPH_LAYOUT_PACKED && log && !pack.converged)
        fprintf(log,
                "  warning: packing %zu^%d stopped at pack_iter %d before the particles stopped "
                "moving (100 max|u| dt/h = %.3g above %g)\n",
                lp->nx[0], lp->dim, lp->packing.max_iter, pack.move_final, lp->packing.move_tol);
    consph_packing_report_free(&pack);
    if (rc) return rc;
    e->lp = *lp;
    e->used = 1;
    e->seconds = consph_wtime() - t0;
    *p = &e->p;
    *seconds = e->seconds;
    return CONSPH_OK;
}

void study_layout_cache_free(layout_cache *c)
{
    for (int k = 0; k < CACHE_SIZE; ++k)
        if (c->e[k].used) consph_particles_free(&c->e[k].p);
}

/* ---- output helpers ---- */

/* Particle files replace a plan's nx sweep, one resolution each; zhu and beta are anchored at
 * the first file. */
void study_plan_take_files(series_plan *pl, const study_files *files)
{
    pl->nvalues = files->n;
    for (int j = 0; j < files->n; ++j) pl->values[j] = study_resolution_of(&files->sets[j]);
    pl->spec.n_ref = (double)files->sets[0].n;
}

/* The particles of resolution j of an nx sweep, and their nx: file j, or the plan's layout at
 * nx = values[j] from the cache. */
int study_plan_particles(const series_plan *pl, int j, const study_files *files,
                         layout_cache *cache, FILE *log, const consph_particles **p, size_t *nx)
{
    if (files) {
        *p = &files->sets[j];
        *nx = (size_t)floor(study_resolution_of(*p) + 0.5);
        return CONSPH_OK;
    }
    *nx = (size_t)pl->values[j];
    consph_layout_params lp = pl->spec.layout;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) lp.nx[a] = a < lp.dim ? *nx : 1;
    double lsec;
    return study_layout_get(cache, &lp, p, &lsec, log);
}

/* Neighbour pairs of one run, from geometry (the support volume in particle spacings). */
double study_pairs_estimate(const series_plan *pl, double nx)
{
    double n = pow(nx, pl->spec.layout.dim);
    /* The unit box, Δs = 1/nx. */
    return n * (1.0 + consph_approx_neighbours(&pl->spec, (size_t)n, 1.0, 1.0 / nx));
}

consph_layout_params study_plan_row_layout(const series_plan *pl, int j)
{
    const size_t nx = pl->sweep_hdx ? pl->nx_fixed : (size_t)pl->values[j];
    consph_layout_params lp = pl->spec.layout;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) lp.nx[a] = a < lp.dim ? nx : 1;
    return lp;
}

/* The work of row j (neighbour pairs), the unit of the progress line's ETA. */
double study_plan_row_work(const series_plan *pl, int j)
{
    series_plan one = *pl;
    if (pl->sweep_hdx) one.spec.hdx = pl->values[j];
    return study_pairs_estimate(&one, pl->sweep_hdx ? (double)pl->nx_fixed : pl->values[j]);
}

/* The rows of an operator figure (one per series and resolution) and their neighbour pairs. */
int study_plan_rows(const consph_study *s, const study_figure *f, int quick,
                    const study_files *files, double *work)
{
    int n = 0;
    for (int k = 0; k < f->nseries; ++k) {
        series_plan pl;
        if (study_plan_build(s, f, &f->series[k], quick, &pl) != CONSPH_OK) continue;
        if (files && !pl.sweep_hdx) study_plan_take_files(&pl, files);
        if (files && pl.sweep_hdx)
            pl.nx_fixed = (size_t)floor(study_resolution_of(&files->sets[files->n - 1]) + 0.5);
        for (int j = 0; j < pl.nvalues; ++j) *work += study_plan_row_work(&pl, j);
        n += pl.nvalues;
    }
    return n;
}

/* Period-1 fields repeat on a periodic axis only when its length is a whole number. */
int study_check_field_period(const consph_approx_spec *sp, const consph_box *box)
{
    if (sp->field == CONSPH_MFIELD_CONST || !consph_mfield_periodic_on_unit(sp->field))
        return CONSPH_OK;
    for (int a = 0; a < box->dim; ++a) {
        double len = consph_box_length(box, a);
        if (box->periodic[a] && fabs(len - floor(len + 0.5)) > 1e-12 * fmax(1.0, len))
            return consph_fail(CONSPH_EINVAL,
                               "field '%s' has period 1 but the periodic axis %c has length %g",
                               consph_mfield_name(sp->field), "xyz"[a], len);
    }
    return CONSPH_OK;
}
