#include "consph/core.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

static _Thread_local char last_error[1024];

int consph_fail(int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(last_error, sizeof last_error, fmt, ap);
    va_end(ap);
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
