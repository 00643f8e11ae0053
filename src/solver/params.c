/* The run parameters from one table (params.def): defaults, bounds, the setter by name that
 * consph run, the study reader and the checkpoint reader share, and the checkpoint metadata. */
#include <errno.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "solver/params.h"
#include "solver/solver_internal.h"

/* An enum member is set and read through an int. */
_Static_assert(sizeof(consph_eos_kind) == sizeof(int), "consph_eos_kind is int-sized");
_Static_assert(sizeof(consph_kernel_id) == sizeof(int), "consph_kernel_id is int-sized");

#define PARAM_QUICK CONSPH_PFLAG_QUICK
#define PARAM_NX CONSPH_PFLAG_NX

static const consph_run_param param_table[] = {
#define PARAM_STR(nm, dflt, names_fn, opt, key, own, meta, hlp)                                    \
    {.name = #nm,                                                                                  \
     .type = CONSPH_PTYPE_STRING,                                                                  \
     .option = opt,                                                                                \
     .study_key = key,                                                                             \
     .special = NAN,                                                                               \
     .names = names_fn,                                                                            \
     .owner = own,                                                                                 \
     .metavar = meta,                                                                              \
     .help = hlp,                                                                                  \
     .def_text = dflt,                                                                             \
     .offset = offsetof(consph_run_params, nm),                                                    \
     .size = sizeof(((consph_run_params *)0)->nm)},
#define PARAM_NUM(nm, ty, dflt, l, lopen, h, spec, specname, opt, key, rd, fl, own, meta, hlp)     \
    {.name = #nm,                                                                                  \
     .type = CONSPH_PTYPE_##ty,                                                                    \
     .option = opt,                                                                                \
     .study_key = key,                                                                             \
     .lo = l,                                                                                      \
     .hi = h,                                                                                      \
     .lo_open = lopen,                                                                             \
     .special = spec,                                                                              \
     .special_name = specname,                                                                     \
     .reads = rd,                                                                                  \
     .flags = fl,                                                                                  \
     .owner = own,                                                                                 \
     .metavar = meta,                                                                              \
     .help = hlp,                                                                                  \
     .def = dflt,                                                                                  \
     .offset = offsetof(consph_run_params, nm),                                                    \
     .size = sizeof(((consph_run_params *)0)->nm)},
#define PARAM_ENUM(nm, ty, dflt, chs, fst, opt, key, rd, own, meta, hlp)                           \
    {.name = #nm,                                                                                  \
     .type = CONSPH_PTYPE_##ty,                                                                    \
     .option = opt,                                                                                \
     .study_key = key,                                                                             \
     .special = NAN,                                                                               \
     .choices = chs,                                                                               \
     .first = fst,                                                                                 \
     .reads = rd,                                                                                  \
     .owner = own,                                                                                 \
     .metavar = meta,                                                                              \
     .help = hlp,                                                                                  \
     .def = dflt,                                                                                  \
     .offset = offsetof(consph_run_params, nm),                                                    \
     .size = sizeof(((consph_run_params *)0)->nm)},
#include "solver/params.def"
#undef PARAM_STR
#undef PARAM_NUM
#undef PARAM_ENUM
};
#define PARAM_COUNT ((int)(sizeof param_table / sizeof param_table[0]))

int consph_run_param_count(void)
{
    return PARAM_COUNT;
}

const consph_run_param *consph_run_param_at(int k)
{
    return k >= 0 && k < PARAM_COUNT ? &param_table[k] : NULL;
}

const consph_run_param *consph_run_param_find(const char *name)
{
    for (int k = 0; k < PARAM_COUNT; ++k)
        if (!strcmp(param_table[k].name, name)) return &param_table[k];
    return NULL;
}

static void *member(consph_run_params *prm, const consph_run_param *d)
{
    return (char *)prm + d->offset;
}

static const void *member_c(const consph_run_params *prm, const consph_run_param *d)
{
    return (const char *)prm + d->offset;
}

/* The value of a number or enum member as a double (exact for every allowed value). */
static double member_number(const consph_run_params *prm, const consph_run_param *d)
{
    const void *m = member_c(prm, d);
    switch (d->type) {
    case CONSPH_PTYPE_LONG:
        return (double)*(const long *)m;
    case CONSPH_PTYPE_ULONG:
        return (double)*(const unsigned long *)m;
    case CONSPH_PTYPE_DOUBLE:
        return *(const double *)m;
    default:
        return (double)*(const int *)m;
    }
}

static void member_set_number(consph_run_params *prm, const consph_run_param *d, double v)
{
    void *m = member(prm, d);
    switch (d->type) {
    case CONSPH_PTYPE_LONG:
        *(long *)m = (long)v;
        break;
    case CONSPH_PTYPE_ULONG:
        *(unsigned long *)m = (unsigned long)v;
        break;
    case CONSPH_PTYPE_DOUBLE:
        *(double *)m = v;
        break;
    default:
        *(int *)m = (int)v;
        break;
    }
}

void consph_run_params_default(consph_run_params *prm)
{
    memset(prm, 0, sizeof *prm);
    for (int k = 0; k < PARAM_COUNT; ++k) {
        const consph_run_param *d = &param_table[k];
        if (d->type == CONSPH_PTYPE_STRING)
            snprintf(member(prm, d), d->size, "%s", d->def_text);
        else
            member_set_number(prm, d, d->def);
    }
}

/* Whether `name` is one of the comma-separated `names`. */
static int name_in(const char *name, size_t n, const char *names)
{
    for (const char *c = names; *c;) {
        const char *e = strchr(c, ',');
        size_t len = e ? (size_t)(e - c) : strlen(c);
        if (len == n && strncmp(c, name, n) == 0) return 1;
        if (!e) break;
        c = e + 1;
    }
    return 0;
}

/* The index of `name` among the comma-separated `names`, or -1. */
static int name_index(const char *name, const char *names)
{
    const size_t n = strlen(name);
    int k = 0;
    for (const char *c = names; *c; ++k) {
        const char *e = strchr(c, ',');
        size_t len = e ? (size_t)(e - c) : strlen(c);
        if (len == n && strncmp(c, name, n) == 0) return k;
        if (!e) break;
        c = e + 1;
    }
    return -1;
}

/* consph_kernel_names() with its ", " separators as ","; the radial kernels only. */
static const char *kernel_choices(char *buf, size_t size)
{
    size_t n = 0;
    buf[0] = '\0';
    for (int id = 0; id < CONSPH_KERNEL_COUNT; ++id) {
        const consph_kernel_info *ki = consph_kernel_info_get((consph_kernel_id)id);
        if (!ki || id == CONSPH_KERNEL_M4) continue;
        int w = snprintf(buf + n, size - n, "%s%s", n ? "," : "", ki->name);
        if (w < 0 || (size_t)w >= size - n) break;
        n += (size_t)w;
    }
    return buf;
}

static int kernel_allowed(int id)
{
    return id >= 0 && id < CONSPH_KERNEL_COUNT && id != CONSPH_KERNEL_M4;
}

static int number_allowed(const consph_run_param *d, double v)
{
    if (v == d->special) return 1;
    return isfinite(v) && (d->lo_open ? v > d->lo : v >= d->lo) && v <= d->hi;
}

const char *consph_run_param_allowed(const consph_run_param *d, char *buf, size_t size)
{
    switch (d->type) {
    case CONSPH_PTYPE_STRING:
        snprintf(buf, size, "%s%s", !strcmp(d->name, "integrator") ? "default," : "",
                 d->names ? d->names() : "any name");
        break;
    case CONSPH_PTYPE_ENUM:
        snprintf(buf, size, "%s", d->choices);
        break;
    case CONSPH_PTYPE_KERNEL:
        kernel_choices(buf, size);
        break;
    case CONSPH_PTYPE_LAYOUT:
        snprintf(buf, size, "default,%s", consph_layout_names());
        break;
    default: {
        const int integer = d->type != CONSPH_PTYPE_DOUBLE;
        int w = d->hi == DBL_MAX
                    ? snprintf(buf, size, "%s%c%.15g, inf)", integer ? "an integer in " : "",
                               d->lo_open ? '(' : '[', d->lo)
                    : snprintf(buf, size, "%s%c%.15g, %.15g]", integer ? "an integer in " : "",
                               d->lo_open ? '(' : '[', d->lo, d->hi);
        if (d->special_name && w > 0 && (size_t)w < size)
            snprintf(buf + w, size - (size_t)w, " or %s", d->special_name);
    }
    }
    return buf;
}

/* Integers in a wider type than any member, so that the range check sees the value given. */
static int parse_integer(const char *text, double *out)
{
    char *end;
    errno = 0;
    long long v = strtoll(text, &end, 10);
    if (end != text && *end == '\0' && errno == 0) {
        *out = (double)v;
        return 1;
    }
    /* "1e6": a whole number written as a double, as study files have them */
    errno = 0;
    double d = strtod(text, &end);
    if (end == text || *end || errno || !isfinite(d) || d != floor(d)) return 0;
    *out = d;
    return 1;
}

static int parse_double(const char *text, double *out)
{
    char *end;
    errno = 0;
    *out = strtod(text, &end);
    /* an underflow (ERANGE) still gives the subnormal or zero written, which the bounds judge */
    return end != text && *end == '\0' && (errno == 0 || errno == ERANGE) && isfinite(*out);
}

int consph_run_param_set(consph_run_params *prm, const char *name, const char *text)
{
    const consph_run_param *d = consph_run_param_find(name);
    if (!d) return consph_fail(CONSPH_EINVAL, "no run parameter is named '%.40s'", name);
    char allowed[1024];
    consph_run_param_allowed(d, allowed, sizeof allowed);
    double v;
    switch (d->type) {
    case CONSPH_PTYPE_STRING: {
        const char *t = !strcmp(d->name, "integrator") && !strcmp(text, "default") ? "" : text;
        const size_t n = strlen(t);
        if (n >= d->size ||
            (d->names && (n || strcmp(d->name, "integrator")) && !name_in(t, n, d->names())))
            return consph_fail(CONSPH_EINVAL, "%s '%.40s' is unknown (allowed: %s)", d->name, text,
                               allowed);
        memcpy(member(prm, d), t, n + 1);
        return CONSPH_OK;
    }
    case CONSPH_PTYPE_ENUM: {
        const int k = name_index(text, d->choices);
        if (k < 0)
            return consph_fail(CONSPH_EINVAL, "%s '%.40s' is unknown (allowed: %s)", d->name, text,
                               allowed);
        *(int *)member(prm, d) = d->first + k;
        return CONSPH_OK;
    }
    case CONSPH_PTYPE_KERNEL: {
        consph_kernel_id id;
        if (consph_kernel_lookup(text, &id) != CONSPH_OK || !kernel_allowed((int)id))
            return consph_fail(CONSPH_EINVAL, "%s '%.40s' is unknown or not radial (allowed: %s)",
                               d->name, text, allowed);
        *(int *)member(prm, d) = (int)id;
        return CONSPH_OK;
    }
    case CONSPH_PTYPE_LAYOUT: {
        consph_layout_kind kind;
        if (!strcmp(text, "default")) {
            *(int *)member(prm, d) = -1;
            return CONSPH_OK;
        }
        if (consph_layout_lookup(text, &kind) != CONSPH_OK)
            return consph_fail(CONSPH_EINVAL, "%s '%.40s' is unknown (allowed: %s)", d->name, text,
                               allowed);
        *(int *)member(prm, d) = (int)kind;
        return CONSPH_OK;
    }
    case CONSPH_PTYPE_DOUBLE:
        if (d->special_name && !strcmp(text, d->special_name)) {
            member_set_number(prm, d, d->special);
            return CONSPH_OK;
        }
        if (!parse_double(text, &v))
            return consph_fail(CONSPH_EINVAL, "%s '%.40s' is not a finite number (allowed: %s)",
                               d->name, text, allowed);
        break;
    default:
        if (d->special_name && !strcmp(text, d->special_name)) {
            member_set_number(prm, d, d->special);
            return CONSPH_OK;
        }
        if (!parse_integer(text, &v))
            return consph_fail(CONSPH_EINVAL, "%s '%.40s' is not an integer (allowed: %s)", d->name,
                               text, allowed);
    }
    if (d->flags & CONSPH_PFLAG_NX) {
        if (!(v >= INT_MIN && v <= INT_MAX)) v = v < 0 ? INT_MIN : INT_MAX;
        const int dim = consph_problem_dim(prm->problem);
        int st = consph_run_nx_check((int)v, dim ? dim : 2);
        if (st != CONSPH_OK) return st;
    } else if (!number_allowed(d, v) || v == d->special) {
        return consph_fail(CONSPH_EINVAL, "%s = %.40s is out of range (allowed: %s)", d->name, text,
                           allowed);
    }
    member_set_number(prm, d, v);
    return CONSPH_OK;
}

int consph_run_param_format(const consph_run_params *prm, const char *name, char *buf, size_t size)
{
    const consph_run_param *d = consph_run_param_find(name);
    if (!d) return consph_fail(CONSPH_EINVAL, "no run parameter is named '%.40s'", name);
    const void *m = member_c(prm, d);
    const int iv = *(const int *)m;
    char names[1024], one[64];
    int w;
    if (d->special_name && member_number(prm, d) == d->special)
        return snprintf(buf, size, "%s", d->special_name) < (int)size
                   ? CONSPH_OK
                   : consph_fail(CONSPH_EINVAL, "%s: buffer of %zu bytes too small", d->name, size);
    switch (d->type) {
    case CONSPH_PTYPE_STRING:
        w = snprintf(buf, size, "%s",
                     !strcmp(d->name, "integrator") && !*(const char *)m ? "default"
                                                                         : (const char *)m);
        break;
    case CONSPH_PTYPE_KERNEL:
        if (!kernel_allowed(iv))
            return consph_fail(CONSPH_EINVAL, "%s = %d names no radial kernel", d->name, iv);
        w = snprintf(buf, size, "%s", consph_kernel_info_get((consph_kernel_id)iv)->name);
        break;
    case CONSPH_PTYPE_ENUM:
    case CONSPH_PTYPE_LAYOUT: {
        const char *list = consph_run_param_allowed(d, names, sizeof names);
        const int k = d->type == CONSPH_PTYPE_ENUM ? iv - d->first : iv + 1;
        /* the k-th name of the list */
        const char *c = list;
        for (int j = 0; j < k && c; ++j) {
            c = strchr(c, ',');
            if (c) ++c;
        }
        if (k < 0 || !c || !*c)
            return consph_fail(CONSPH_EINVAL, "%s = %d has no name", d->name, iv);
        size_t len = strcspn(c, ",");
        if (len >= sizeof one) len = sizeof one - 1;
        memcpy(one, c, len);
        one[len] = '\0';
        w = snprintf(buf, size, "%s", one);
        break;
    }
    case CONSPH_PTYPE_INT:
        w = snprintf(buf, size, "%d", iv);
        break;
    case CONSPH_PTYPE_LONG:
        w = snprintf(buf, size, "%ld", *(const long *)m);
        break;
    case CONSPH_PTYPE_ULONG:
        w = snprintf(buf, size, "%lu", *(const unsigned long *)m);
        break;
    default: {
        /* the shortest of 15 and 17 digits that reads back to the same double */
        const double v = *(const double *)m;
        w = snprintf(buf, size, "%.15g", v);
        if (w > 0 && (size_t)w < size && strtod(buf, NULL) != v)
            w = snprintf(buf, size, "%.17g", v);
    }
    }
    if (w < 0 || (size_t)w >= size)
        return consph_fail(CONSPH_EINVAL, "%s: buffer of %zu bytes too small", d->name, size);
    return CONSPH_OK;
}

/* The table's bounds on every member. */
static int params_in_table(const consph_run_params *prm)
{
    char allowed[1024];
    for (int k = 0; k < PARAM_COUNT; ++k) {
        const consph_run_param *d = &param_table[k];
        const void *m = member_c(prm, d);
        const int iv = *(const int *)m;
        int ok;
        switch (d->type) {
        case CONSPH_PTYPE_STRING:
            ok = memchr(m, '\0', d->size) != NULL;
            break;
        case CONSPH_PTYPE_ENUM:
            ok = 1;
            break; /* below */
        case CONSPH_PTYPE_KERNEL:
            ok = kernel_allowed(iv);
            break;
        case CONSPH_PTYPE_LAYOUT:
            ok = iv >= -1 && iv < CONSPH_LAYOUT_COUNT;
            break;
        default:
            /* nx: consph_run_nx_check, which also weighs the memory */
            ok = (d->flags & CONSPH_PFLAG_NX) || number_allowed(d, member_number(prm, d));
        }
        if (d->type == CONSPH_PTYPE_ENUM && ok) {
            /* the value names one of the choices */
            int count = 1;
            for (const char *c = d->choices; *c; ++c) count += *c == ',';
            ok = iv >= d->first && iv < d->first + count;
        }
        if (ok) continue;
        consph_run_param_allowed(d, allowed, sizeof allowed);
        if (d->type == CONSPH_PTYPE_STRING)
            return consph_fail(CONSPH_EINVAL, "%s is not a terminated name", d->name);
        if (d->type == CONSPH_PTYPE_DOUBLE)
            return consph_fail(CONSPH_EINVAL, "%s = %g is out of range (allowed: %s)", d->name,
                               member_number(prm, d), allowed);
        return consph_fail(CONSPH_EINVAL, "%s = %.0f is out of range (allowed: %s)", d->name,
                           member_number(prm, d), allowed);
    }
    return CONSPH_OK;
}

int consph_run_params_check(const consph_run_params *prm)
{
    int st = params_in_table(prm);
    if (st != CONSPH_OK) return st;
    if (!problem_find(prm->problem))
        return consph_fail(CONSPH_EINVAL, "problem '%s' is unknown (allowed: %s)", prm->problem,
                           consph_problem_names());
    if (!scheme_find(prm->scheme))
        return consph_fail(CONSPH_EINVAL, "scheme '%s' is unknown (allowed: %s)", prm->scheme,
                           consph_scheme_names());
    if (prm->integrator[0] &&
        !name_in(prm->integrator, strlen(prm->integrator), consph_integrator_names()))
        return consph_fail(CONSPH_EINVAL, "integrator '%s' is unknown (allowed: %s)",
                           prm->integrator, consph_integrator_names());
    if ((st = consph_run_nx_check(prm->nx, consph_problem_dim(prm->problem))) != CONSPH_OK)
        return st;
    /* rules between parameters */
    if (prm->n > 0) {
        const int dim = consph_problem_dim(prm->problem);
        if (scheme_find(prm->scheme)->needs_lattice)
            return consph_fail(CONSPH_EINVAL,
                               "n = %ld particles, not nx^%d: scheme '%s' remeshes onto a lattice "
                               "of nx^%d particles, so it needs a particle count that is a "
                               "perfect power",
                               prm->n, dim, prm->scheme, dim);
    }
    if (prm->steps == 0 && !(prm->tf > 0.0))
        return consph_fail(CONSPH_EINVAL,
                           "tf = 0 with steps = 0: tf must be a positive time or steps a positive "
                           "count");
    const scheme_def *sd = scheme_find(prm->scheme);
    /* ρ_o means something only where ϱ is evolved and gives p by the EOS */
    if (prm->rho_init == CONSPH_RHO_INIT_RHO0 && (sd->evolve_p || sd->closure))
        return consph_fail(CONSPH_EINVAL,
                           "rho_init rho0 needs a scheme whose pressure comes from its evolved "
                           "density by the EOS, not '%s' (allowed: eos)",
                           prm->scheme);
    /* the wc reference is a Fourier series of smooth data on a 2D periodic box, standing in for
     * an exact solution: the problems whose row says so */
    if (prm->exact != CONSPH_EXACT_INCOMPRESSIBLE && !problem_find(prm->problem)->wc_reference)
        return consph_fail(CONSPH_EINVAL,
                           "exact %s needs a smooth 2D periodic problem with an exact solution "
                           "(taylor-green), not '%s' (allowed: incompressible)",
                           prm->exact == CONSPH_EXACT_WC ? "wc" : "both", prm->problem);
    return CONSPH_OK;
}

int run_params_meta_write(const consph_run_params *prm, char *buf, size_t size, size_t used)
{
    for (int k = 0; k < PARAM_COUNT; ++k) {
        const consph_run_param *d = &param_table[k];
        const void *m = member_c(prm, d);
        if (used >= size) return -1;
        char *o = buf + used;
        const size_t room = size - used;
        int w;
        switch (d->type) {
        case CONSPH_PTYPE_STRING:
            w = snprintf(o, room, "%s=%s\n", d->name, (const char *)m);
            break;
        case CONSPH_PTYPE_LONG:
            w = snprintf(o, room, "%s=%ld\n", d->name, *(const long *)m);
            break;
        case CONSPH_PTYPE_ULONG:
            w = snprintf(o, room, "%s=%lu\n", d->name, *(const unsigned long *)m);
            break;
        case CONSPH_PTYPE_DOUBLE:
            w = snprintf(o, room, "%s=%a\n", d->name, *(const double *)m);
            break;
        default:
            w = snprintf(o, room, "%s=%d\n", d->name, *(const int *)m);
            break;
        }
        if (w < 0 || (size_t)w >= room) return -1;
        used += (size_t)w;
    }
    return (int)used;
}

int run_params_meta_read(consph_run_params *prm, const char *k, const char *v)
{
    const consph_run_param *d = consph_run_param_find(k);
    if (!d) return -1;
    void *m = member(prm, d);
    char *end;
    errno = 0;
    if (d->type == CONSPH_PTYPE_STRING) {
        if (strlen(v) >= d->size) return 0;
        strcpy(m, v);
        return 1;
    }
    if (d->type == CONSPH_PTYPE_DOUBLE) {
        double x = strtod(v, &end);
        if (end == v || *end || errno) return 0;
        *(double *)m = x;
        return 1;
    }
    long l = strtol(v, &end, 10);
    if (end == v || *end || errno) return 0;
    switch (d->type) {
    case CONSPH_PTYPE_LONG:
        *(long *)m = l;
        break;
    case CONSPH_PTYPE_ULONG:
        if (l < 0) return 0;
        *(unsigned long *)m = (unsigned long)l;
        break;
    default:
        if (l < INT_MIN || l > INT_MAX) return 0;
        *(int *)m = (int)l;
    }
    return 1;
}

const consph_run_param *run_param_of_message(const char *msg)
{
    for (int k = 0; k < PARAM_COUNT; ++k) {
        const consph_run_param *d = &param_table[k];
        const size_t n = strlen(d->name);
        if (!strncmp(msg, d->name, n) && (msg[n] == ' ' || msg[n] == ':')) return d;
        const size_t o = d->option ? strlen(d->option) : 0;
        if (o && !strncmp(msg, d->option, o) && (msg[o] == ' ' || msg[o] == '\'')) return d;
    }
    return NULL;
}

int consph_run_params_particles(consph_run_params *prm, size_t count)
{
    const int dim = consph_problem_dim(prm->problem);
    if (!dim)
        return consph_fail(CONSPH_EINVAL, "problem '%s' is unknown (allowed: %s)", prm->problem,
                           consph_problem_names());
    const long nx = count ? lround(pow((double)count, 1.0 / dim)) : 0;
    double power = 1.0; /* nx^dim, exact for any count a run can hold */
    for (int a = 0; a < dim; ++a) power *= (double)nx;
    if (consph_run_nx_check((int)(nx < INT_MAX ? nx : INT_MAX), dim) != CONSPH_OK) {
        char msg[400];
        snprintf(msg, sizeof msg, "%s", consph_last_error());
        return consph_fail(CONSPH_EINVAL, "%zu particles in %dD (nx %ld): %s", count, dim, nx, msg);
    }
    prm->nx = (int)nx;
    prm->n = power == (double)count ? 0 : (long)count;
    return CONSPH_OK;
}
