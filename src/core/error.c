#include "consph/core.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static _Thread_local char last_error[1024];

int consph_fail(int code, const char *fmt, ...)
{
    /* Callers pass consph_last_error() back as an argument to add context ("%s: %s", file,
     * consph_last_error()); formatting straight into last_error would read it while writing it. */
    char msg[sizeof last_error];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    memcpy(last_error, msg, sizeof msg);
    return code;
}

const char *consph_last_error(void)
{
    return last_error;
}

void consph_clear_error(void)
{
    last_error[0] = '\0';
}

void *consph_calloc(size_t count, size_t size)
{
    if (count == 0 || size == 0) count = size = 1;
    void *p = calloc(count, size);
    if (!p) consph_fail(CONSPH_ENOMEM, "out of memory allocating %zu x %zu bytes", count, size);
    return p;
}
