/* A failed write names the file and the reason: consph_fdstream keeps the
 * errno of the first failed write although glibc drops it, and consph_outfile_commit reports
 * "cannot write 'PATH': REASON", leaving neither the file nor its temporary behind. The disk is
 * made full by pointing the stream's descriptor at /dev/full, which fails every write with
 * ENOSPC and needs no privileges. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "consph/io.h"

static int open_full(void)
{
    return open("/dev/full", O_WRONLY | O_CLOEXEC);
}

static int dir_entries(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return -1;
    int n = 0;
    for (struct dirent *e; (e = readdir(d));)
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) ++n;
    closedir(d);
    return n;
}

static void test_fdstream(void)
{
    consph_fdstream s = {open_full(), 0};
    FILE *f = consph_fdstream_open(&s, "w");
    CHECK(f != NULL, "fdstream_open: %s", strerror(errno));
    if (!f) return;
    /* More than a buffer: the write fails inside fprintf, and glibc discards that buffer. */
    for (int k = 0; k < 4000; ++k) fprintf(f, "line %d\n", k);
    CHECK(ferror(f), "writes to /dev/full did not fail");
    fflush(f);
    CHECK(s.err == ENOSPC, "recorded errno %d (%s), want ENOSPC", s.err, strerror(s.err));
    fclose(f);
    close(s.fd);
}

/* size: bytes written before commit; small ones fail only at commit's flush. */
static void test_commit(const char *dir, size_t size)
{
    char path[4096], want[4200];
    snprintf(path, sizeof path, "%s/out_%zu.csv", dir, size);
    consph_outfile of;
    CHECK(consph_outfile_open(&of, path) == CONSPH_OK, "open: %s", consph_last_error());
    int full = open_full();
    CHECK(full >= 0 && dup2(full, of.stream.fd) == of.stream.fd, "dup2 /dev/full");
    close(full);
    for (size_t k = 0; k < size; ++k) fputc('x', of.fp);
    int rc = consph_outfile_commit(&of);
    CHECK(rc == CONSPH_EIO, "commit of %zu bytes onto a full disk returned %d", size, rc);
    snprintf(want, sizeof want, "cannot write '%s': %s", path, strerror(ENOSPC));
    CHECK(strcmp(consph_last_error(), want) == 0, "message '%s', want '%s'", consph_last_error(),
          want);
    CHECK(dir_entries(dir) == 0, "%d files left in %s (the target or its temporary)",
          dir_entries(dir), dir);
}

int main(void)
{
    if (access("/dev/full", W_OK) != 0) {
        printf("test_outfile: no /dev/full, skipped\n");
        return 77;
    }
    char dir[] = "/tmp/consph_test_outfile_XXXXXX";
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    test_fdstream();
    test_commit(dir, 10);
    test_commit(dir, 100000);
    /* consph_outfile_fail: the stream's reason when given none. */
    consph_outfile of;
    char path[4096];
    snprintf(path, sizeof path, "%s/x.vtu", dir);
    CHECK(consph_outfile_open(&of, path) == CONSPH_OK, "open: %s", consph_last_error());
    of.stream.err = EDQUOT;
    CHECK(consph_outfile_fail(&of, 0) == CONSPH_EIO, "outfile_fail code");
    CHECK(strstr(consph_last_error(), "x.vtu': ") && strstr(consph_last_error(), strerror(EDQUOT)),
          "outfile_fail message '%s'", consph_last_error());
    consph_outfile_abort(&of);
    CHECK(dir_entries(dir) == 0, "abort left files in %s", dir);
    rmdir(dir);
    return check_summary("test_outfile");
}
