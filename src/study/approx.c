/* One operator-accuracy measurement: generate particles, evaluate an operator on a manufactured
 * field, compare with the exact answer. Shared by `consph approx` and the static studies. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "consph/study.h"

consph_approx_spec consph_approx_defaults(int dim)
{
    consph_approx_spec s;
    memset(&s, 0, sizeof s);
    s.op.op = CONSPH_OP_FUNCTION;
    s.op.form = CONSPH_FORM_STANDARD;
    s.op.corr = CONSPH_CORR_NONE;
    s.kernel = CONSPH_KERNEL_QUINTIC;
    s.hdx = 1.2;
    s.h_policy = CONSPH_H_HDX;
    s.layout = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, dim, 10);
    s.field = CONSPH_MFIELD_SIN2PI;
    s.field_params = consph_mfield_defaults(dim);
    s.volume = CONSPH_VOLUME_NUMBER;
    s.interior_only = 1;
    s.timing_runs = 1;
    return s;
}

static const char *const h_policy_names[CONSPH_H_COUNT] = {"hdx", "scaling", "zhu", "beta"};

const char *consph_h_policy_name(consph_h_policy policy)
{
    return (int)policy >= 0 && policy < CONSPH_H_COUNT ? h_policy_names[policy] : "?";
}

int consph_h_policy_lookup(const char *name, consph_h_policy *policy)
{
    for (int k = 0; k < CONSPH_H_COUNT; ++k)
        if (name && strcmp(name, h_policy_names[k]) == 0) {
            *policy = (consph_h_policy)k;
            return CONSPH_OK;
        }
    return consph_fail(CONSPH_EINVAL, "unknown h policy '%s' (allowed: hdx, scaling, zhu, beta)",
                       name ? name : "");
}

/* The exponent β of N ∝ h^(-β). */
static double policy_beta(const consph_approx_spec *s, int dim)
{
    return s->h_policy == CONSPH_H_ZHU ? 2.0 * dim : s->beta;
}

double consph_approx_h(const consph_approx_spec *s, size_t n, double box_volume, double spacing)
{
    const int dim = s->layout.dim;
    switch (s->h_policy) {
    case CONSPH_H_SCALING:
        /* 003 states h = N^(-1/6) for the unit box; scale with the box for other sizes. */
        return consph_scaling_h((double)n) * pow(box_volume, 1.0 / dim);
    case CONSPH_H_ZHU:
    case CONSPH_H_BETA: {
        const double nref = s->n_ref > 0 ? s->n_ref : (double)n;
        const double ds_ref = pow(box_volume / nref, 1.0 / dim);
        return s->hdx * ds_ref * pow((double)n / nref, -1.0 / policy_beta(s, dim));
    }
    default:
        return s->hdx * spacing;
    }
}

double consph_approx_neighbours(const consph_approx_spec *s, size_t n, double box_volume,
                                double spacing)
{
    const int d = s->layout.dim;
    const double unit_ball = d == 1 ? 2.0 : d == 2 ? M_PI : 4.0 * M_PI / 3.0;
    const double radius =
        consph_kernel_info_get(s->kernel)->support * consph_approx_h(s, n, box_volume, spacing);
    return unit_ball * pow(radius / spacing, d);
}

consph_approx_cost consph_approx_estimate(const consph_approx_spec *s, size_t n, double box_volume,
                                          double spacing, int threads)
{
    consph_approx_cost c;
    c.neighbours = consph_approx_neighbours(s, n, box_volume, spacing);
    c.bytes = 72.0 * (c.neighbours + 1.0) * (threads > 0 ? threads : 1);
    c.seconds = (double)n * (c.neighbours + 1.0) / CONSPH_APPROX_PAIRS_PER_SECOND;
    return c;
}

/* The forms of 001 Table 2 approximate ∇p/ϱ with ϱ = ρ, not ∇p. */
static int divides_by_rho(consph_op_form form)
{
    return form == CONSPH_FORM_ASYM || form == CONSPH_FORM_SYM1 || form == CONSPH_FORM_SYM2 ||
           form == CONSPH_FORM_SYM_S1;
}

int consph_approx_check(const consph_approx_spec *s)
{
    int dim = s->layout.dim;
    int rc = consph_op_check(s->op.op, s->op.form, s->op.corr, dim);
    if (rc) return rc;
    int vector_in = s->op.op == CONSPH_OP_DIV;
    if (vector_in != consph_mfield_is_vector(s->field))
        return consph_fail(CONSPH_EINVAL, "field '%s' is a %s field but op '%s' takes a %s",
                           consph_mfield_name(s->field),
                           consph_mfield_is_vector(s->field) ? "vector" : "scalar",
                           consph_op_name(s->op.op), vector_in ? "vector" : "scalar");
    if (s->field == CONSPH_MFIELD_TGV && dim < 2)
        return consph_fail(CONSPH_EINVAL, "field 'tgv' needs dimension 2 or 3");
    int any_periodic = 0;
    for (int a = 0; a < dim; ++a) any_periodic |= s->layout.box.periodic[a];
    if (any_periodic && !consph_mfield_periodic_on_unit(s->field))
        return consph_fail(CONSPH_EINVAL,
                           "field '%s' is not periodic on the unit box; use a non-periodic box "
                           "or a periodic field (sin2pi, const, tgv, sin2pi-vec)",
                           consph_mfield_name(s->field));
    if (!(s->hdx > 0) || !isfinite(s->hdx))
        return consph_fail(CONSPH_EINVAL, "h/dx must be positive, got %g", s->hdx);
    if ((int)s->h_policy < 0 || s->h_policy >= CONSPH_H_COUNT)
        return consph_fail(CONSPH_EINVAL, "unknown h policy %d", (int)s->h_policy);
    /* 004: N ∝ h^(-β) with β > n, so that 𝒩 ∝ N^(1 - n/β) grows while 𝒩/N -> 0. */
    if (s->h_policy == CONSPH_H_BETA && !(s->beta > dim && isfinite(s->beta)))
        return consph_fail(CONSPH_EINVAL, "h policy 'beta' needs beta > dim = %d, got %g", dim,
                           s->beta);
    if (!(s->n_ref >= 0) || !isfinite(s->n_ref))
        return consph_fail(CONSPH_EINVAL, "reference particle count must be >= 0, got %g",
                           s->n_ref);
    return consph_box_check(&s->layout.box);
}

void consph_approx_exact(const consph_approx_spec *s, const double *x, double rho_i, double *out)
{
    int dim = s->layout.dim;
    consph_mfield_value v;
    consph_mfield_eval(s->field, dim, &s->field_params, x, &v);
    switch (s->op.op) {
    case CONSPH_OP_FUNCTION:
        out[0] = v.f[0];
        break;
    case CONSPH_OP_GRAD:
        for (int a = 0; a < dim; ++a)
            out[a] = divides_by_rho(s->op.form) ? v.grad[0][a] / rho_i : v.grad[0][a];
        break;
    case CONSPH_OP_DIV:
        out[0] = v.div;
        break;
    case CONSPH_OP_LAPLACIAN:
        out[0] = v.lap[0];
        break;
    case CONSPH_OP_HESSIAN: {
        int k = 0;
        for (int a = 0; a < dim; ++a)
            for (int b = a; b < dim; ++b) out[k++] = v.hess[a][b];
        break;
    }
    case CONSPH_OP_COUNT:
        break;
    }
}

static void visit_none(void *job, const consph_nbhd *nb)
{
    (void)job;
    (void)nb;
}

/* The mean neighbour count, self excluded: a pass that only counts its pairs. */
static double mean_neighbours(const consph_sys *sys)
{
    const consph_pass count = {"neighbour count", CONSPH_PASS_NO_DX, visit_none};
    const size_t n = sys->p->n;
    size_t pairs = 0;
    if (consph_pass_run_counted(sys, &count, NULL, &pairs) != CONSPH_OK) return NAN;
    return n ? (double)(pairs - n) / (double)n : 0.0;
}

static int compare_doubles(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The median time of spec->timing_runs applications, the first (already timed, in *seconds)
 * included. The correction cache is cleared before each so every run pays for its matrices. */
static int time_operator(const consph_approx_spec *s, consph_op_ctx *ctx, const double *in,
                         double *out, double *seconds)
{
    double t[CONSPH_APPROX_MAX_TIMINGS];
    int runs =
        s->timing_runs < CONSPH_APPROX_MAX_TIMINGS ? s->timing_runs : CONSPH_APPROX_MAX_TIMINGS;
    t[0] = *seconds;
    for (int k = 1; k < runs; ++k) {
        consph_op_report rep;
        int rc = consph_op_ctx_refresh(ctx);
        if (rc == CONSPH_OK)
            rc = consph_apply(ctx, s->op.op, s->op.form, s->op.corr, in, out, &rep);
        if (rc) return rc;
        t[k] = rep.seconds;
    }
    qsort(t, (size_t)runs, sizeof t[0], compare_doubles);
    *seconds = runs % 2 ? t[runs / 2] : 0.5 * (t[runs / 2 - 1] + t[runs / 2]);
    return CONSPH_OK;
}

int consph_approx_run(const consph_approx_spec *s, size_t nx, consph_approx_row *row)
{
    memset(row, 0, sizeof *row);
    int rc = consph_approx_check(s);
    if (rc) return rc;
    consph_layout_params lp = s->layout;
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) lp.nx[a] = a < lp.dim ? nx : 1;
    consph_particles p;
    double t0 = consph_wtime();
    consph_packing_report pack;
    memset(&pack, 0, sizeof pack);
    rc = consph_layout_generate(&lp, &p, &pack);
    double spread = lp.kind == CONSPH_LAYOUT_PACKED || lp.kind == CONSPH_LAYOUT_PACKED_POLISHED
                        ? pack.rho_spread_final
                        : NAN;
    const int converged = pack.converged;
    consph_packing_report_free(&pack);
    if (rc) return rc;
    double layout_seconds = consph_wtime() - t0;
    rc = consph_approx_run_particles(s, &p, nx, row);
    row->layout_seconds = layout_seconds;
    row->layout_spread = spread;
    row->layout_converged = converged;
    consph_particles_free(&p);
    return rc;
}

int consph_approx_run_particles(const consph_approx_spec *s, const consph_particles *src, size_t nx,
                                consph_approx_row *row)
{
    memset(row, 0, sizeof *row);
    int rc = consph_approx_check(s);
    if (rc) return rc;
    const int dim = s->layout.dim;
    if (src->dim != dim)
        return consph_fail(CONSPH_EINVAL, "particles have dimension %d, the study %d", src->dim,
                           dim);
    consph_sys sys;
    int have_sys = 0;
    consph_op_ctx ctx;
    int have_ctx = 0;
    double *in = NULL, *out = NULL, *exact = NULL;
    unsigned char *mask = NULL;
    const size_t n = src->n;
    row->nx = nx;
    row->n = n;
    row->layout_spread = NAN;

    const double h = consph_approx_h(s, n, consph_box_volume(&src->box), src->spacing);
    row->h = h;
    consph_kernel k;
    rc = consph_kernel_init(&k, s->kernel, dim, h);
    if (rc) goto done;
    /* The system works on a copy in cell order. */
    rc = consph_sys_init(&sys, src, &k, 0.0);
    if (rc) goto done;
    have_sys = 1;
    const consph_particles *p = sys.p;
    rc = consph_op_ctx_init_sys(&ctx, &sys, s->volume);
    if (rc) goto done;
    have_ctx = 1;

    int nin = consph_op_ncomp_in(s->op.op, dim), nout = consph_op_ncomp_out(s->op.op, dim);
    in = consph_calloc(n * (size_t)nin, sizeof(double));
    out = consph_calloc(n * (size_t)nout, sizeof(double));
    exact = consph_calloc(n * (size_t)nout, sizeof(double));
    mask = consph_calloc(n, 1);
    if (!in || !out || !exact || !mask) {
        rc = CONSPH_ENOMEM;
        goto done;
    }
    for (size_t i = 0; i < n; ++i) {
        double x[CONSPH_MAX_DIM] = {0, 0, 0}, e[CONSPH_MAX_DIM * CONSPH_MAX_DIM];
        for (int a = 0; a < dim; ++a) x[a] = p->x[a][i];
        consph_mfield_value v;
        consph_mfield_eval(s->field, dim, &s->field_params, x, &v);
        for (int c = 0; c < nin; ++c) in[(size_t)c * n + i] = v.f[c];
        consph_approx_exact(s, x, ctx.rho[i], e);
        for (int c = 0; c < nout; ++c) exact[(size_t)c * n + i] = e[c];
        int inside = 1;
        if (s->interior_only)
            for (int a = 0; a < dim; ++a)
                if (!p->box.periodic[a] &&
                    (x[a] - p->box.lo[a] < k.radius || p->box.hi[a] - x[a] < k.radius))
                    inside = 0;
        mask[i] = (unsigned char)inside;
    }
    consph_op_report rep;
    rc = consph_apply(&ctx, s->op.op, s->op.form, s->op.corr, in, out, &rep);
    if (rc) goto done;
    row->seconds = rep.seconds;
    row->fallbacks = rep.fallbacks;
    rc = consph_error_norms_compute(out, exact, n, nout, mask, &row->err);
    if (rc) goto done;
    row->ft_over_fmax = consph_total_force_ratio(out, n, mask);
    row->nbr_mean = mean_neighbours(&sys);
    if (s->timing_runs > 1) rc = time_operator(s, &ctx, in, out, &row->seconds);

done:
    free(in);
    free(out);
    free(exact);
    free(mask);
    if (have_ctx) consph_op_ctx_free(&ctx);
    if (have_sys) consph_sys_free(&sys);
    return rc;
}
