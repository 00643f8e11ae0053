#include "consph/io.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char *dup_str(const char *s)
{
    char *d = malloc(strlen(s) + 1);
    if (d) strcpy(d, s);
    return d;
}

/* The directory part of `path` ("." when none), in a buffer the caller frees. */
static char *dir_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    if (!slash) return dup_str(".");
    if (slash == path) return dup_str("/");
    char *d = malloc((size_t)(slash - path) + 1);
    if (!d) return NULL;
    memcpy(d, path, (size_t)(slash - path));
    d[slash - path] = '\0';
    return d;
}

int consph_path_writable(const char *path)
{
    if (!path || !*path) return consph_fail(CONSPH_EINVAL, "empty path");
    size_t len = strlen(path);
    if (path[len - 1] == '/') return consph_fail(CONSPH_EINVAL, "'%s' names a directory", path);
    struct stat st;
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode))
        return consph_fail(CONSPH_EINVAL, "'%s' is a directory", path);
    char *dir = dir_of(path);
    if (!dir) return consph_fail(CONSPH_ENOMEM, "out of memory");
    int rc = CONSPH_OK;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        rc = consph_fail(CONSPH_EIO, "directory '%s' does not exist", dir);
    else if (access(dir, W_OK | X_OK) != 0)
        rc = consph_fail(CONSPH_EIO, "directory '%s' is not writable", dir);
    free(dir);
    return rc;
}

int consph_outfile_open(consph_outfile *of, const char *path)
{
    memset(of, 0, sizeof *of);
    int rc = consph_path_writable(path);
    if (rc) return rc;
    size_t len = strlen(path);
    of->path = dup_str(path);
    of->tmp_path = malloc(len + 32);
    if (!of->path || !of->tmp_path) {
        consph_outfile_abort(of);
        return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    /* Same directory as the target so the final rename is atomic. */
    snprintf(of->tmp_path, len + 32, "%s.tmp.%ld", path, (long)getpid());
    of->fp = fopen(of->tmp_path, "wb");
    if (!of->fp) {
        int e = errno;
        consph_outfile_abort(of);
        return consph_fail(CONSPH_EIO, "cannot create '%s': %s", path, strerror(e));
    }
    return CONSPH_OK;
}

int consph_outfile_commit(consph_outfile *of)
{
    int bad = ferror(of->fp);
    if (fclose(of->fp) != 0) bad = 1;
    of->fp = NULL;
    if (bad) {
        int e = errno;
        remove(of->tmp_path);
        consph_outfile_abort(of);
        return consph_fail(CONSPH_EIO, "write error: %s", strerror(e));
    }
    if (rename(of->tmp_path, of->path) != 0) {
        int e = errno;
        char msg[256];
        snprintf(msg, sizeof msg, "cannot rename into '%s': %s", of->path, strerror(e));
        remove(of->tmp_path);
        consph_outfile_abort(of);
        return consph_fail(CONSPH_EIO, "%s", msg);
    }
    free(of->path);
    free(of->tmp_path);
    memset(of, 0, sizeof *of);
    return CONSPH_OK;
}

void consph_outfile_abort(consph_outfile *of)
{
    if (of->fp) {
        fclose(of->fp);
        of->fp = NULL;
    }
    if (of->tmp_path) remove(of->tmp_path);
    free(of->path);
    free(of->tmp_path);
    memset(of, 0, sizeof *of);
}
