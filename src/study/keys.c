/* A study's keys read as numbers, lists and choices, each refused with the file, line, figure,
 * series and key it came from. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "study/study_internal.h"

int study_key_error(const consph_study *s, const study_figure *f, const study_series *r,
                    const char *key, const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* A key that is not set (a required one) is reported where it is missing. */
    int line = study_line(s, f, r, key);
    if (!line) line = r ? r->line : f->line;
    return consph_fail(CONSPH_EFORMAT, "%s:%d: figure '%s', series '%s': key '%s': %s", s->path,
                       line, f->id, r ? r->label : "-", key, msg);
}

int study_get_double(const consph_study *s, const study_figure *f, const study_series *r,
                     const char *key, double def, double lo, double hi, double *out)
{
    const char *v = study_get(s, f, r, key);
    if (!v) {
        *out = def;
        return CONSPH_OK;
    }
    char *end;
    errno = 0;
    double d = strtod(v, &end);
    if (end == v || *end || errno || !isfinite(d) || d < lo || d > hi)
        return study_key_error(s, f, r, key, "'%s' is not a number in [%g, %g]", v, lo, hi);
    *out = d;
    return CONSPH_OK;
}

int study_get_list(const consph_study *s, const study_figure *f, const study_series *r,
                   const char *key, double lo, double hi, double *vals, int *n)
{
    const char *v = study_get(s, f, r, key);
    *n = 0;
    if (!v) return CONSPH_OK;
    /* Every element, empty ones included: `8,,16` is refused as the CLI refuses `10,,20`. */
    for (const char *t = v;; ++t) {
        char *end;
        double d = strtod(t, &end);
        while (*end == ' ' || *end == '\t') ++end;
        if (end == t || (*end && *end != ',') || !isfinite(d) || d < lo || d > hi)
            return study_key_error(s, f, r, key, "'%s' is not a list of numbers in [%g, %g]", v, lo,
                                   hi);
        if (*n == MAX_SWEEP) return study_key_error(s, f, r, key, "more than %d values", MAX_SWEEP);
        vals[(*n)++] = d;
        if (!*end) break;
        t = end;
    }
    return CONSPH_OK;
}

int study_get_choice(const consph_study *s, const study_figure *f, const study_series *r,
                     const char *key, const char *const *choices, int def, int *out)
{
    const char *v = study_get(s, f, r, key);
    if (!v) {
        *out = def;
        return CONSPH_OK;
    }
    char allowed[256] = "";
    for (int k = 0; choices[k]; ++k) {
        if (strcmp(v, choices[k]) == 0) {
            *out = k;
            return CONSPH_OK;
        }
        snprintf(allowed + strlen(allowed), sizeof allowed - strlen(allowed), "%s%s", k ? ", " : "",
                 choices[k]);
    }
    return study_key_error(s, f, r, key, "unknown value '%s'; allowed: %s", v, allowed);
}

const char *study_get_or(const consph_study *s, const study_figure *f, const study_series *r,
                         const char *key, const char *def)
{
    const char *v = study_get(s, f, r, key);
    return v ? v : def;
}

/* A published value that is a plain number (many are prose: "~2 (SOC)"). */
int study_paper_number(const consph_study *s, const study_figure *f, const study_series *r,
                       const char *key, double *out)
{
    const char *v = study_get(s, f, r, key);
    if (!v) return 0;
    char *end;
    double d = strtod(v, &end);
    if (end == v || *end || !isfinite(d)) return 0;
    *out = d;
    return 1;
}
