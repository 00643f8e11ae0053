/* The lines of a `key = value` text: study files (src/study/studyfile.c) and run parameter
 * files (consph run --config) share this reading, each giving the keys their own meaning. */
#include <ctype.h>
#include <stdlib.h>
#include <string.h>

#include "consph/io.h"

static char *trim(char *s)
{
    while (isspace((unsigned char)*s)) ++s;
    char *e = s + strlen(s);
    while (e > s && isspace((unsigned char)e[-1])) --e;
    *e = '\0';
    return s;
}

/* One line (NUL-terminated in buf): comment, blanks, section header or key = value. */
static int kv_line(char *buf, const char *path, int line, consph_kv_fn each, void *ctx)
{
    char *hash = strchr(buf, '#');
    if (hash) *hash = '\0';
    char *t = trim(buf);
    if (!*t) return CONSPH_OK;
    for (const char *c = t; *c; ++c)
        if ((unsigned char)*c < 0x20 && *c != '\t')
            return consph_fail(CONSPH_EFORMAT, "%s:%d: control character 0x%02x", path, line,
                               (unsigned char)*c);
    if (*t == '[') return each(ctx, line, t, NULL);
    char *eq = strchr(t, '=');
    if (!eq) return consph_fail(CONSPH_EFORMAT, "%s:%d: expected 'key = value'", path, line);
    *eq = '\0';
    return each(ctx, line, trim(t), trim(eq + 1));
}

int consph_kv_parse(const char *path, const char *data, size_t size, size_t line_max,
                    consph_kv_fn each, void *ctx)
{
    char *buf = malloc(line_max + 1);
    if (!buf) return consph_fail(CONSPH_ENOMEM, "out of memory");
    int line = 0, rc = CONSPH_OK;
    size_t pos = 0;
    while (rc == CONSPH_OK && pos < size) {
        ++line;
        const char *nl = memchr(data + pos, '\n', size - pos);
        size_t len = nl ? (size_t)(nl - (data + pos)) : size - pos;
        if (memchr(data + pos, '\0', len)) {
            rc = consph_fail(CONSPH_EFORMAT, "%s:%d: NUL byte", path, line);
        } else if (len > line_max) {
            rc = consph_fail(CONSPH_EFORMAT, "%s:%d: line longer than %zu characters", path, line,
                             line_max);
        } else {
            memcpy(buf, data + pos, len);
            buf[len] = '\0';
            rc = kv_line(buf, path, line, each, ctx);
        }
        pos += len + 1;
    }
    free(buf);
    return rc;
}
