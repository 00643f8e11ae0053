/* The run-parameter table (src/solver/params.def) walked row by row: every default passes
 * consph_run_params_check; each bound is accepted at its edge and refused just outside, by the
 * setter (by name) and by the check; every parameter round-trips through the setter and through
 * the checkpoint metadata; a study file accepts exactly the table's keys on a run figure. */
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "consph/core.h"
#include "consph/solver.h"
#include "consph/study.h"
#include "solver/params.h"
#include "study/study_internal.h"

static int is_number(const consph_run_param *d)
{
    return d->type == CONSPH_PTYPE_INT || d->type == CONSPH_PTYPE_LONG ||
           d->type == CONSPH_PTYPE_ULONG || d->type == CONSPH_PTYPE_DOUBLE;
}

static void put(consph_run_params *p, const consph_run_param *d, double v)
{
    void *m = (char *)p + d->offset;
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
    }
}

static double get(const consph_run_params *p, const consph_run_param *d)
{
    const void *m = (const char *)p + d->offset;
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

static int same_member(const consph_run_params *a, const consph_run_params *b,
                       const consph_run_param *d)
{
    const char *ma = (const char *)a + d->offset, *mb = (const char *)b + d->offset;
    if (d->type == CONSPH_PTYPE_STRING) return strcmp(ma, mb) == 0;
    return memcmp(ma, mb, d->size) == 0;
}

/* The value as the setter reads it, exact for doubles. */
static void text_of(const consph_run_param *d, double v, char *buf, size_t size)
{
    if (d->type == CONSPH_PTYPE_DOUBLE)
        snprintf(buf, size, "%.17g", v);
    else
        snprintf(buf, size, "%.0f", v);
}

/* One value of a number at the setter and at the check: accepted or refused, and a refusal
 * names the parameter. */
static void expect_number(const consph_run_param *d, double v, int ok)
{
    consph_run_params p;
    consph_run_params_default(&p);
    char text[64];
    text_of(d, v, text, sizeof text);
    int st = consph_run_param_set(&p, d->name, text);
    CHECK((st == CONSPH_OK) == ok && (ok ? get(&p, d) == v : 1), "%s = %s: set %s", d->name, text,
          st == CONSPH_OK ? "accepted" : consph_last_error());
    if (!ok)
        CHECK(strncmp(consph_last_error(), d->name, strlen(d->name)) == 0,
              "%s: message does not name it: %s", d->name, consph_last_error());
    /* the check sees the member itself (an integer member cannot hold some values; the
     * special value is the member's, given to the setter by its name) */
    if (v == d->special) return;
    if (d->type != CONSPH_PTYPE_DOUBLE &&
        !(v >= (d->type == CONSPH_PTYPE_ULONG ? 0.0 : (double)INT_MIN) && v <= (double)INT_MAX))
        return;
    consph_run_params_default(&p);
    put(&p, d, v);
    st = consph_run_params_check(&p);
    CHECK((st == CONSPH_OK) == ok, "%s = %s: check %s", d->name, text,
          st == CONSPH_OK ? "accepted" : consph_last_error());
    if (!ok)
        CHECK(strncmp(consph_last_error(), d->name, strlen(d->name)) == 0,
              "%s: check message does not name it: %s", d->name, consph_last_error());
}

static double below(const consph_run_param *d, double v)
{
    return d->type == CONSPH_PTYPE_DOUBLE ? nextafter(v, -INFINITY) : v - 1.0;
}

static double above(const consph_run_param *d, double v)
{
    return d->type == CONSPH_PTYPE_DOUBLE ? nextafter(v, INFINITY) : v + 1.0;
}

static void test_defaults(void)
{
    consph_run_params p;
    consph_run_params_default(&p);
    CHECK(consph_run_params_check(&p) == CONSPH_OK, "defaults refused: %s", consph_last_error());
    /* 001's Taylor-Green values, as before the table */
    CHECK(!strcmp(p.problem, "taylor-green") && !strcmp(p.scheme, "l-ipst-c") &&
              p.integrator[0] == '\0' && p.nx == 50 && p.layout == -1 && p.seed == 1 &&
              p.hdx == 1.2 && p.kernel == CONSPH_KERNEL_QUINTIC && p.U == 1.0 && p.c0 == 0.0 &&
              p.re == 100.0 && p.nu == -1.0 && p.rho0 == 1.0 && p.gamma == 7.0 &&
              p.eos == CONSPH_EOS_DEFAULT && p.delta == 0.1 && p.alpha == -1.0 && p.tf == 0.5 &&
              p.steps == 0 && p.dt == 0.0 && p.cfl == 0.3 && p.h_dt == 0.0 && p.ipst_every == 10 &&
              p.ipst_max_iter == 10 && p.ipst_tol == 1e-3 && p.rho_init == CONSPH_RHO_INIT_EOS &&
              p.error == CONSPH_ERROR_EQ26 && p.error_times == 50 &&
              p.exact == CONSPH_EXACT_INCOMPRESSIBLE && p.n == 0,
          "a default changed");
    /* every member is a row: the rows' sizes add up to the struct's members */
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        CHECK(consph_run_param_find(d->name) == d, "%s: not found by name", d->name);
        CHECK(d->help && d->owner && d->metavar, "%s: help, owner or metavar missing", d->name);
        for (int j = 0; j < k; ++j)
            CHECK(consph_run_param_at(j)->offset != d->offset, "%s: member twice", d->name);
    }
    CHECK(consph_run_param_count() == 34, "%d rows, 34 members", consph_run_param_count());
    CHECK(!consph_run_param_at(-1) && !consph_run_param_at(consph_run_param_count()) &&
              !consph_run_param_find("nosuch"),
          "out-of-table lookups answered");
}

static void test_bounds(void)
{
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        if (!is_number(d) || (d->flags & CONSPH_PFLAG_NX)) continue;
        if (d->lo_open) {
            expect_number(d, d->lo, 0);
            expect_number(d, above(d, d->lo), 1);
        } else {
            expect_number(d, d->lo, 1);
            if (!(d->type == CONSPH_PTYPE_ULONG && d->lo == 0.0))
                expect_number(d, below(d, d->lo), 0);
        }
        expect_number(d, d->hi, 1);
        if (d->hi < DBL_MAX) expect_number(d, above(d, d->hi), 0);
        /* a special value is given by its name; its number stays refused by the setter */
        if (d->special_name) {
            consph_run_params p;
            consph_run_params_default(&p);
            put(&p, d, d->lo);
            CHECK(consph_run_param_set(&p, d->name, d->special_name) == CONSPH_OK &&
                      get(&p, d) == d->special,
                  "%s: '%s' refused", d->name, d->special_name);
            char text[64];
            text_of(d, d->special, text, sizeof text);
            CHECK(consph_run_param_set(&p, d->name, text) == CONSPH_EINVAL, "%s: %s accepted",
                  d->name, text);
        }
        consph_run_params p;
        consph_run_params_default(&p);
        CHECK(consph_run_param_set(&p, d->name, "x") == CONSPH_EINVAL &&
                  consph_run_param_set(&p, d->name, "") == CONSPH_EINVAL &&
                  consph_run_param_set(&p, d->name, "1x") == CONSPH_EINVAL &&
                  consph_run_param_set(&p, d->name, "nan") == CONSPH_EINVAL,
              "%s: text that is no number accepted", d->name);
        if (d->type != CONSPH_PTYPE_DOUBLE)
            CHECK(consph_run_param_set(&p, d->name, "4.5") == CONSPH_EINVAL,
                  "%s: 4.5 accepted as an integer", d->name);
    }
    /* nx: consph_run_nx_check's bounds */
    consph_run_params p;
    consph_run_params_default(&p);
    CHECK(consph_run_param_set(&p, "nx", "4") == CONSPH_OK && p.nx == 4, "nx 4 refused");
    CHECK(consph_run_param_set(&p, "nx", "3") == CONSPH_EINVAL && p.nx == 4, "nx 3 accepted");
    CHECK(consph_run_param_set(&p, "nx", "10001") == CONSPH_EINVAL, "nx 10001 accepted");
}

/* Names: enums, kernels, layouts and strings accept each allowed name and refuse others. */
static void test_names(void)
{
    consph_run_params p;
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        if (is_number(d)) continue;
        char allowed[1024];
        consph_run_param_allowed(d, allowed, sizeof allowed);
        int n = 0;
        for (char *c = strtok(allowed, ","); c; c = strtok(NULL, ","), ++n) {
            consph_run_params_default(&p);
            if (!strcmp(d->name, "problem")) consph_run_params_problem(&p, c);
            CHECK(consph_run_param_set(&p, d->name, c) == CONSPH_OK, "%s '%s' refused: %s", d->name,
                  c, consph_last_error());
            char back[64];
            CHECK(consph_run_param_format(&p, d->name, back, sizeof back) == CONSPH_OK &&
                      !strcmp(back, c),
                  "%s '%s' formats as '%s'", d->name, c, back);
            if (!strcmp(d->name, "rho_init") && !strcmp(c, "rho0")) continue; /* by scheme */
            CHECK(consph_run_params_check(&p) == CONSPH_OK, "%s '%s': check: %s", d->name, c,
                  consph_last_error());
        }
        CHECK(n >= 2, "%s: %d names", d->name, n);
        consph_run_params_default(&p);
        CHECK(consph_run_param_set(&p, d->name, "nosuch") == CONSPH_EINVAL &&
                  strncmp(consph_last_error(), d->name, strlen(d->name)) == 0 &&
                  strstr(consph_last_error(), "allowed: "),
              "%s: nosuch: %s", d->name, consph_last_error());
        if (d->type == CONSPH_PTYPE_ENUM || d->type == CONSPH_PTYPE_LAYOUT ||
            d->type == CONSPH_PTYPE_KERNEL) {
            const int lo = d->type == CONSPH_PTYPE_KERNEL   ? 0
                           : d->type == CONSPH_PTYPE_LAYOUT ? -1
                                                            : d->first;
            for (int v = lo - 1; v <= lo + n; v += n + 1) {
                consph_run_params_default(&p);
                *(int *)((char *)&p + d->offset) = v;
                CHECK(consph_run_params_check(&p) == CONSPH_EINVAL, "%s = %d accepted", d->name, v);
            }
        }
    }
    consph_run_params_default(&p);
    CHECK(consph_run_param_set(&p, "kernel", "m4") == CONSPH_EINVAL, "kernel m4 accepted");
    p.kernel = CONSPH_KERNEL_M4;
    CHECK(consph_run_params_check(&p) == CONSPH_EINVAL, "kernel m4 passed the check");
}

/* A value of each parameter other than its default (strings and names: the last allowed). */
static void unusual(consph_run_params *p)
{
    consph_run_params_default(p);
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        if (is_number(d)) {
            if (d->flags & CONSPH_PFLAG_NX) {
                put(p, d, 37);
                continue;
            }
            double hi = d->hi < 1e9 ? d->hi : 1e9;
            double v = d->lo + 0.3719 * (hi - d->lo);
            if (d->type != CONSPH_PTYPE_DOUBLE) v = floor(v) > d->lo ? floor(v) : d->lo + 1.0;
            put(p, d, v);
            continue;
        }
        char allowed[1024];
        consph_run_param_allowed(d, allowed, sizeof allowed);
        const char *last = strrchr(allowed, ',');
        consph_run_param_set(p, d->name, last ? last + 1 : allowed);
    }
    p->steps = 0; /* tf gives the end */
}

static void test_round_trips(void)
{
    consph_run_params a, b;
    unusual(&a);
    char meta[4096];
    int len = run_params_meta_write(&a, meta, sizeof meta, 0);
    CHECK(len > 0, "metadata not written");
    if (len <= 0) return;
    memset(&b, 0, sizeof b);
    int lines = 0;
    for (char *line = strtok(meta, "\n"); line; line = strtok(NULL, "\n"), ++lines) {
        char *eq = strchr(line, '=');
        CHECK(eq != NULL, "line '%s' is not key=value", line);
        if (!eq) continue;
        *eq = '\0';
        CHECK(run_params_meta_read(&b, line, eq + 1) == 1, "%s=%s not read back", line, eq + 1);
    }
    CHECK(lines == consph_run_param_count(), "%d lines for %d parameters", lines,
          consph_run_param_count());
    CHECK(run_params_meta_read(&b, "nosuch", "1") == -1 && run_params_meta_read(&b, "nx", "x") == 0,
          "the metadata reader accepted what it should not");
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        CHECK(same_member(&a, &b, d), "%s: not the same after the metadata", d->name);
        /* through the setter: the text of consph_run_param_format */
        consph_run_params c;
        consph_run_params_default(&c);
        if (!strcmp(d->name, "problem")) consph_run_params_problem(&c, a.problem);
        char text[128];
        CHECK(consph_run_param_format(&a, d->name, text, sizeof text) == CONSPH_OK, "%s: format",
              d->name);
        CHECK(consph_run_param_set(&c, d->name, text) == CONSPH_OK && same_member(&a, &c, d),
              "%s: '%s' does not set the same value (%s)", d->name, text, consph_last_error());
        CHECK(consph_run_param_format(&a, d->name, text, 2) == CONSPH_EINVAL || strlen(text) < 2,
              "%s: a short buffer was not refused", d->name);
    }
}

/* A study of one run figure whose series sets `key` = `value` for `scheme` (NULL: one that
 * reads the key); parsed, and validated (plan_build) when `validate`. */
static int study_of(const char *scheme, const char *key, const char *value, int validate)
{
    char text[512];
    if (!scheme)
        scheme = !strcmp(key, "alpha") ? "wcsph" : !strcmp(key, "delta") ? "e-c" : "l-ipst-c";
    snprintf(text, sizeof text,
             "study = t\nkind = run\n[figure f]\nnx = 8\nsteps = 1\n[series a]\nscheme = %s\n%s = "
             "%s\n",
             scheme, key, value);
    consph_study *s = NULL;
    int rc = study_parse("t.study", text, strlen(text), &s);
    if (rc == CONSPH_OK && validate) rc = consph_study_validate(s, 0);
    consph_study_free(s);
    return rc;
}

static int study_with(const char *key, const char *value, int validate)
{
    return study_of(NULL, key, value, validate);
}

static void test_study_keys(void)
{
    consph_run_params def;
    consph_run_params_default(&def);
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        CHECK((d->study_key != NULL) == (d->option != NULL || !strcmp(d->name, "problem")),
              "%s: a study key without an option or the reverse", d->name);
        if (!d->study_key || !strcmp(d->name, "steps") || !strcmp(d->name, "scheme")) continue;
        char v[64];
        consph_run_param_format(&def, d->name, v, sizeof v);
        if (!strcmp(d->name, "tf")) continue;          /* conflicts with the figure's steps */
        if (!strcmp(d->name, "error_times")) continue; /* needs error = authors to do anything */
        int rc = study_with(d->study_key, v, 1);
        CHECK(rc == CONSPH_OK, "key %s = %s refused: %s", d->study_key, v, consph_last_error());
        if (is_number(d) && !(d->flags & CONSPH_PFLAG_NX)) {
            char out[64];
            text_of(d, d->hi < DBL_MAX ? above(d, d->hi) : -1.0, out, sizeof out);
            rc = study_with(d->study_key, out, 1);
            CHECK(rc != CONSPH_OK && strstr(consph_last_error(), d->study_key), "key %s = %s: %s",
                  d->study_key, out, rc == CONSPH_OK ? "accepted" : consph_last_error());
        }
    }
    CHECK(study_with("nosuch", "1", 0) == CONSPH_EFORMAT &&
              strstr(consph_last_error(), "unknown key 'nosuch'"),
          "an unknown key accepted: %s", consph_last_error());
    /* a series' scheme key its scheme does not read is refused, naming where it acts */
    CHECK(study_of("edac", "ipst_tol", "0.01", 1) != CONSPH_OK &&
              strstr(consph_last_error(), "key 'ipst_tol': does nothing for the scheme edac"),
          "ipst_tol on edac: %s", consph_last_error());
    CHECK(study_of("l-ipst-c", "alpha", "0.2", 1) != CONSPH_OK &&
              strstr(consph_last_error(), "(it acts on: wcsph"),
          "alpha on l-ipst-c: %s", consph_last_error());
    CHECK(study_with("ipst_every", "5", 0) == CONSPH_OK, "ipst_every unknown: %s",
          consph_last_error());
    CHECK(study_with("ipst_tol", "0.01", 1) == CONSPH_OK, "ipst_tol on l-ipst-c: %s",
          consph_last_error());
    CHECK(study_with("alpha", "0.2", 0) == CONSPH_OK && study_with("alpha", "0.2", 1) == CONSPH_OK,
          "alpha on wcsph: %s", consph_last_error());
}

int main(void)
{
    test_defaults();
    test_bounds();
    test_names();
    test_round_trips();
    test_study_keys();
    return check_summary("test_params");
}
