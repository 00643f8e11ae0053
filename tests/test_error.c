/* consph_fail and consph_last_error: the message survives being passed back as an argument, as
 * the callers that add a file name or line to a lower-level message do. */
#include <string.h>

#include "check.h"
#include "consph/core.h"

int main(void)
{
    consph_clear_error();
    CHECK(consph_last_error()[0] == '\0', "cleared: '%s'", consph_last_error());

    int rc = consph_fail(CONSPH_EINVAL, "periodic axis x has length %g", 1.5);
    CHECK(rc == CONSPH_EINVAL, "returns the code: %d", rc);
    rc = consph_fail(CONSPH_EFORMAT, "%s: %s", "q.csv", consph_last_error());
    CHECK(rc == CONSPH_EFORMAT, "returns the code: %d", rc);
    CHECK(!strcmp(consph_last_error(), "q.csv: periodic axis x has length 1.5"),
          "own buffer as the second argument: '%s'", consph_last_error());

    /* Twice in a row, the message as the first and only argument, and after the text. */
    consph_fail(CONSPH_EIO, "%s (line %d)", consph_last_error(), 7);
    consph_fail(CONSPH_EIO, "read: %s", consph_last_error());
    CHECK(!strcmp(consph_last_error(), "read: q.csv: periodic axis x has length 1.5 (line 7)"),
          "nested: '%s'", consph_last_error());

    /* A message longer than the buffer is cut, terminated, and still starts with the prefix. */
    char longtext[3000];
    memset(longtext, 'a', sizeof longtext - 1);
    longtext[sizeof longtext - 1] = '\0';
    consph_fail(CONSPH_EIO, "%s", longtext);
    size_t len = strlen(consph_last_error());
    CHECK(len > 0 && len < sizeof longtext, "truncated: length %zu", len);
    consph_fail(CONSPH_EIO, "prefix %s", consph_last_error());
    const char *m = consph_last_error();
    CHECK(!strncmp(m, "prefix aaaa", 11) && strlen(m) == len, "long self-reference: '%.20s' %zu", m,
          strlen(m));
    return check_summary("test_error");
}
