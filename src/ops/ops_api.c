/* Names of operators, forms and corrections, the table of valid (op, form, corr) triples and the
 * single entry point consph_apply. */
#include <stdio.h>
#include <string.h>

#include "ops/ops_internal.h"

static const char *op_names[CONSPH_OP_COUNT] = {
    [CONSPH_OP_FUNCTION] = "function",   [CONSPH_OP_GRAD] = "grad",       [CONSPH_OP_DIV] = "div",
    [CONSPH_OP_LAPLACIAN] = "laplacian", [CONSPH_OP_HESSIAN] = "hessian",
};

static const char *form_names[CONSPH_FORM_COUNT] = {
    [CONSPH_FORM_STANDARD] = "standard",
    [CONSPH_FORM_SHEPARD] = "shepard",
    [CONSPH_FORM_FPM] = "fpm",
    [CONSPH_FORM_MSPH] = "msph",
    [CONSPH_FORM_CSHEPARD] = "cshepard",
    [CONSPH_FORM_F1] = "f1",
    [CONSPH_FORM_F2] = "f2",
    [CONSPH_FORM_F3] = "f3",
    [CONSPH_FORM_F4] = "f4",
    [CONSPH_FORM_ASYM] = "asym",
    [CONSPH_FORM_SYM1] = "sym1",
    [CONSPH_FORM_SYM2] = "sym2",
    [CONSPH_FORM_SYM_S1] = "sym_s1",
    [CONSPH_FORM_CSPM] = "cspm",
    [CONSPH_FORM_IAD] = "iad",
    [CONSPH_FORM_DIV] = "div",
    [CONSPH_FORM_S1] = "s1",
    [CONSPH_FORM_S1_DIFF] = "s1_diff",
    [CONSPH_FORM_S1_SUM] = "s1_sum",
    [CONSPH_FORM_S2] = "s2",
    [CONSPH_FORM_S2_DIFF] = "s2_diff",
    [CONSPH_FORM_S2_SUM] = "s2_sum",
    [CONSPH_FORM_CLEARY] = "cleary",
    [CONSPH_FORM_TVF] = "tvf",
    [CONSPH_FORM_COUPLED] = "coupled",
    [CONSPH_FORM_FATEHI] = "fatehi",
    [CONSPH_FORM_FATEHI_C] = "fatehi_c",
    [CONSPH_FORM_KORZILIUS] = "korzilius",
};

static const char *corr_names[CONSPH_CORR_COUNT] = {
    [CONSPH_CORR_NONE] = "none",
    [CONSPH_CORR_BC] = "bc",
    [CONSPH_CORR_LC] = "lc",
    [CONSPH_CORR_FATEHI] = "fatehi",
};

static const char *volume_names[CONSPH_VOLUME_COUNT] = {
    [CONSPH_VOLUME_SUMMATION] = "summation",
    [CONSPH_VOLUME_NUMBER] = "number",
    [CONSPH_VOLUME_GIVEN] = "given",
};

#define N (1u << CONSPH_CORR_NONE)
#define BC (1u << CONSPH_CORR_BC)
#define LC (1u << CONSPH_CORR_LC)
#define FA (1u << CONSPH_CORR_FATEHI)

typedef struct op_rule {
    consph_op op;
    consph_op_form form;
    unsigned corr; /* bit c: correction c is valid */
} op_rule;

/* The triples the seed papers define (001 Tables 2 and 4, App. A; 002 §2, §5; 000 §3-§4):
 * corrections apply where a paper applies them; forms that carry their own correction (f4, fpm,
 * msph, cspm, iad, sym_s1, fatehi_c, korzilius) take "none". */
static const op_rule rules[] = {
    {CONSPH_OP_FUNCTION, CONSPH_FORM_STANDARD, N},
    {CONSPH_OP_FUNCTION, CONSPH_FORM_SHEPARD, N},
    {CONSPH_OP_FUNCTION, CONSPH_FORM_CSPM, N},
    {CONSPH_OP_FUNCTION, CONSPH_FORM_FPM, N},
    {CONSPH_OP_FUNCTION, CONSPH_FORM_MSPH, N},
    {CONSPH_OP_FUNCTION, CONSPH_FORM_CSHEPARD, N},
    {CONSPH_OP_GRAD, CONSPH_FORM_F1, N},
    {CONSPH_OP_GRAD, CONSPH_FORM_F2, N},
    {CONSPH_OP_GRAD, CONSPH_FORM_F3, N},
    {CONSPH_OP_GRAD, CONSPH_FORM_F4, N},
    {CONSPH_OP_GRAD, CONSPH_FORM_ASYM, N | BC | LC},
    {CONSPH_OP_GRAD, CONSPH_FORM_SYM1, N | BC | LC},
    {CONSPH_OP_GRAD, CONSPH_FORM_SYM2, N | BC | LC},
    {CONSPH_OP_GRAD, CONSPH_FORM_SYM_S1, N},
    {CONSPH_OP_GRAD, CONSPH_FORM_CSPM, N},
    {CONSPH_OP_GRAD, CONSPH_FORM_IAD, N},
    {CONSPH_OP_GRAD, CONSPH_FORM_FPM, N},
    {CONSPH_OP_GRAD, CONSPH_FORM_MSPH, N},
    {CONSPH_OP_GRAD, CONSPH_FORM_CSHEPARD, N},
    {CONSPH_OP_DIV, CONSPH_FORM_DIV, N | BC | LC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S1, N},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S1_DIFF, N},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S1_SUM, N},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S2, N},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S2_DIFF, N},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_S2_SUM, N},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_CLEARY, N | BC | LC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_TVF, N | BC | LC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_COUPLED, N | BC | LC},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI, N | FA},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_FATEHI_C, N},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_KORZILIUS, N},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_CSPM, N},
    {CONSPH_OP_LAPLACIAN, CONSPH_FORM_MSPH, N},
    {CONSPH_OP_HESSIAN, CONSPH_FORM_KORZILIUS, N},
    {CONSPH_OP_HESSIAN, CONSPH_FORM_CSPM, N},
    {CONSPH_OP_HESSIAN, CONSPH_FORM_MSPH, N},
};
#define NRULES (sizeof rules / sizeof rules[0])

static int valid_index(int v, int count)
{
    return v >= 0 && v < count;
}

const char *consph_op_name(consph_op op)
{
    return valid_index((int)op, CONSPH_OP_COUNT) ? op_names[op] : "?";
}
const char *consph_form_name(consph_op_form form)
{
    return valid_index((int)form, CONSPH_FORM_COUNT) ? form_names[form] : "?";
}
const char *consph_corr_name(consph_op_corr corr)
{
    return valid_index((int)corr, CONSPH_CORR_COUNT) ? corr_names[corr] : "?";
}
const char *consph_volume_name(consph_volume_kind kind)
{
    return valid_index((int)kind, CONSPH_VOLUME_COUNT) ? volume_names[kind] : "?";
}

static void join_names(const char *const *names, int count, char *buf, size_t size)
{
    size_t used = 0;
    buf[0] = '\0';
    for (int k = 0; k < count && used < size; ++k)
        used += (size_t)snprintf(buf + used, size - used, "%s%s", k ? ", " : "", names[k]);
}

static int lookup(const char *what, const char *name, const char *const *names, int count, int *out)
{
    for (int k = 0; k < count; ++k)
        if (name && strcmp(name, names[k]) == 0) {
            *out = k;
            return CONSPH_OK;
        }
    char list[512];
    join_names(names, count, list, sizeof list);
    return consph_fail(CONSPH_EINVAL, "unknown %s '%s'; allowed: %s", what, name ? name : "", list);
}

int consph_op_lookup(const char *name, consph_op *op)
{
    int k = 0;
    int st = lookup("operator", name, op_names, CONSPH_OP_COUNT, &k);
    if (st == CONSPH_OK) *op = (consph_op)k;
    return st;
}
int consph_form_lookup(const char *name, consph_op_form *form)
{
    int k = 0;
    int st = lookup("form", name, form_names, CONSPH_FORM_COUNT, &k);
    if (st == CONSPH_OK) *form = (consph_op_form)k;
    return st;
}
int consph_corr_lookup(const char *name, consph_op_corr *corr)
{
    int k = 0;
    int st = lookup("correction", name, corr_names, CONSPH_CORR_COUNT, &k);
    if (st == CONSPH_OK) *corr = (consph_op_corr)k;
    return st;
}
int consph_volume_lookup(const char *name, consph_volume_kind *kind)
{
    int k = 0;
    int st = lookup("volume", name, volume_names, CONSPH_VOLUME_COUNT, &k);
    if (st == CONSPH_OK) *kind = (consph_volume_kind)k;
    return st;
}

static void corr_list(unsigned mask, char *buf, size_t size)
{
    size_t used = 0;
    buf[0] = '\0';
    int first = 1;
    for (int c = 0; c < CONSPH_CORR_COUNT && used < size; ++c) {
        if (!(mask & (1u << c))) continue;
        used += (size_t)snprintf(buf + used, size - used, "%s%s", first ? "" : "|", corr_names[c]);
        first = 0;
    }
}

const char *consph_op_describe(consph_op op, char *buf, size_t size)
{
    size_t used = 0;
    if (size == 0) return buf;
    buf[0] = '\0';
    for (size_t k = 0; k < NRULES && used < size; ++k) {
        if (rules[k].op != op) continue;
        char corr[64];
        corr_list(rules[k].corr, corr, sizeof corr);
        used += (size_t)snprintf(buf + used, size - used, "%s%s[%s]", used ? " " : "",
                                 form_names[rules[k].form], corr);
    }
    return buf;
}

int consph_op_check(consph_op op, consph_op_form form, consph_op_corr corr, int dim)
{
    if (dim < 1 || dim > CONSPH_MAX_DIM)
        return consph_fail(CONSPH_EINVAL, "dimension %d is not 1, 2 or 3", dim);
    if (!valid_index((int)op, CONSPH_OP_COUNT) || !valid_index((int)form, CONSPH_FORM_COUNT) ||
        !valid_index((int)corr, CONSPH_CORR_COUNT))
        return consph_fail(CONSPH_EINVAL, "operator, form or correction out of range");
    for (size_t k = 0; k < NRULES; ++k) {
        if (rules[k].op != op || rules[k].form != form) continue;
        if (rules[k].corr & (1u << corr)) return CONSPH_OK;
        char list[64];
        corr_list(rules[k].corr, list, sizeof list);
        return consph_fail(CONSPH_EINVAL, "%s form '%s' does not take correction '%s'; valid: %s",
                           op_names[op], form_names[form], corr_names[corr], list);
    }
    char list[512];
    consph_op_describe(op, list, sizeof list);
    return consph_fail(CONSPH_EINVAL, "%s has no form '%s'; valid form[corrections]: %s",
                       op_names[op], form_names[form], list);
}

int consph_op_parse(const char *op, const char *form, const char *corr, int dim,
                    consph_op_spec *spec)
{
    int st = consph_op_lookup(op, &spec->op);
    if (st == CONSPH_OK) st = consph_form_lookup(form, &spec->form);
    if (st == CONSPH_OK) {
        if (corr)
            st = consph_corr_lookup(corr, &spec->corr);
        else
            spec->corr = CONSPH_CORR_NONE;
    }
    if (st == CONSPH_OK) st = consph_op_check(spec->op, spec->form, spec->corr, dim);
    return st;
}

int consph_op_ncomp_in(consph_op op, int dim)
{
    return op == CONSPH_OP_DIV ? dim : 1;
}

int consph_op_ncomp_out(consph_op op, int dim)
{
    switch (op) {
    case CONSPH_OP_GRAD:
        return dim;
    case CONSPH_OP_HESSIAN:
        return ops_npairs(dim);
    default:
        return 1;
    }
}

int consph_apply(consph_op_ctx *ctx, consph_op op, consph_op_form form, consph_op_corr corr,
                 const double *in, double *out, consph_op_report *rep)
{
    double t0 = consph_wtime();
    if (!ctx || !ctx->cache) return consph_fail(CONSPH_EINVAL, "operator context not initialised");
    int st = consph_op_check(op, form, corr, ctx->dim);
    if (st != CONSPH_OK) return st;
    if ((!in || !out) && ctx->n > 0)
        return consph_fail(CONSPH_EINVAL, "%s: NULL input or output array", op_names[op]);
    ops_call call = {0, 0};
    if (op == CONSPH_OP_LAPLACIAN || op == CONSPH_OP_HESSIAN)
        st = ops_second(ctx, op, form, corr, in, out, &call);
    else if (op == CONSPH_OP_GRAD && form == CONSPH_FORM_CSHEPARD)
        st = ops_grad_cshepard(ctx, in, out, &call);
    else
        st = ops_first(ctx, op, form, corr, in, out, &call);
    if (st == CONSPH_OK) ops_report_fill(ctx, &call, t0, rep);
    return st;
}
