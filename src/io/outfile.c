#define _GNU_SOURCE /* fopencookie */
#include "consph/io.h"
#include "io/outfile_internal.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

/* Temporary files being written, so that SIGINT/SIGTERM/SIGHUP do not leave a half-written
 * file of hundreds of megabytes behind. The handler may only use async-signal-safe calls, so the
 * registry is fixed storage: a slot's path is copied in before its state becomes TMP_LIVE, and
 * the handler unlinks only live slots. */
#define TMP_SLOTS 16
#define TMP_PATH_MAX 4096
enum { TMP_FREE, TMP_CLAIMED, TMP_LIVE };
static atomic_int tmp_state[TMP_SLOTS];
static char tmp_paths[TMP_SLOTS][TMP_PATH_MAX];
static const int tmp_signals[] = {SIGINT, SIGTERM, SIGHUP};

/* A directory being filled (a study's), removed with its files on a signal, and its parents
 * back to the first one created (the one whose path is made_keep characters long). */
static char made_dir[TMP_PATH_MAX];
static size_t made_keep;
static atomic_int made_state;

/* The files in made_dir, then made_dir and the parents that were created, with
 * async-signal-safe calls only (no opendir: it allocates). */
static void remove_made_dir(void)
{
    int fd = open(made_dir, O_RDONLY | O_DIRECTORY | O_NOFOLLOW);
    if (fd >= 0) {
        char buf[4096];
        ssize_t got;
        while ((got = getdents64(fd, buf, sizeof buf)) > 0) {
            for (ssize_t at = 0; at < got;) {
                const struct dirent64 *e = (const struct dirent64 *)(buf + at);
                if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) unlinkat(fd, e->d_name, 0);
                at += e->d_reclen;
            }
        }
        close(fd);
    }
    char path[TMP_PATH_MAX];
    memcpy(path, made_dir, sizeof path);
    for (size_t k = strlen(path); k >= made_keep && k > 0; --k) {
        if (path[k] != '/' && path[k] != '\0') continue;
        path[k] = '\0';
        if (rmdir(path) != 0 && errno != ENOENT) break;
    }
}

/* Children writing a temporary file for us (gnuplot), 0 where free. */
#define CHILD_SLOTS 4
static atomic_int child_pids[CHILD_SLOTS];

void consph_outfile_remove_temps(void)
{
    int saved = errno;
    /* SIGKILL, not SIGTERM: a child that ignored SIGTERM would hang the waitpid below, and its
     * output is about to be removed anyway. Waited for so that it writes nothing after the
     * unlinks and does not outlive us. */
    for (int k = 0; k < CHILD_SLOTS; ++k) {
        pid_t pid = (pid_t)atomic_exchange(&child_pids[k], 0);
        if (pid <= 0) continue;
        kill(pid, SIGKILL);
        while (waitpid(pid, NULL, 0) < 0 && errno == EINTR) continue;
    }
    for (int k = 0; k < TMP_SLOTS; ++k)
        if (atomic_load(&tmp_state[k]) == TMP_LIVE) unlink(tmp_paths[k]);
    if (atomic_exchange(&made_state, TMP_FREE) == TMP_LIVE) remove_made_dir();
    errno = saved;
}

static void remove_tmp_on_signal(int sig)
{
    consph_outfile_remove_temps();
    /* SA_RESETHAND has restored the default action: the signal, delivered once this handler
     * returns, ends the process with the status it would have had without the handler. */
    raise(sig);
}

/* Installs the handler on the signals whose action is the default: an application's own
 * handlers are left alone. Checked at every open, not once per process, because an action can
 * return to the default later (consph_stop_uninstall restores it after a run), and a file
 * opened then must still be cleaned up. Two threads installing the same handler at once is
 * harmless. */
static void install_signal_cleanup(void)
{
    for (size_t k = 0; k < sizeof tmp_signals / sizeof tmp_signals[0]; ++k) {
        struct sigaction old, sa;
        if (sigaction(tmp_signals[k], NULL, &old) != 0 || old.sa_handler != SIG_DFL) continue;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = remove_tmp_on_signal;
        sigemptyset(&sa.sa_mask);
        sa.sa_flags = SA_RESETHAND;
        sigaction(tmp_signals[k], &sa, NULL);
    }
}

/* A path too long for a slot, or more than TMP_SLOTS files at once, is written without the
 * signal cleanup; everything else about it is unchanged. */
void consph_tmp_register(const char *path)
{
    if (strlen(path) >= TMP_PATH_MAX) return;
    install_signal_cleanup();
    for (int k = 0; k < TMP_SLOTS; ++k) {
        int expected = TMP_FREE;
        if (atomic_compare_exchange_strong(&tmp_state[k], &expected, TMP_CLAIMED)) {
            strcpy(tmp_paths[k], path);
            atomic_store(&tmp_state[k], TMP_LIVE);
            return;
        }
    }
}

void consph_tmp_unregister(const char *path)
{
    for (int k = 0; k < TMP_SLOTS; ++k)
        if (atomic_load(&tmp_state[k]) == TMP_LIVE && strcmp(tmp_paths[k], path) == 0) {
            atomic_store(&tmp_state[k], TMP_FREE);
            return;
        }
}

/* Makes a completed rename durable; a file system that cannot sync a directory loses nothing
 * the rename had not already risked, so its failure is not an error. */
static void sync_dir(const char *dir)
{
    int fd = open(dir, O_RDONLY | O_DIRECTORY);
    if (fd < 0) return;
    fsync(fd);
    close(fd);
}

void consph_made_dir_register(const char *dir, size_t created)
{
    int expected = TMP_FREE;
    if (!created || strlen(dir) >= TMP_PATH_MAX ||
        !atomic_compare_exchange_strong(&made_state, &expected, TMP_CLAIMED))
        return;
    install_signal_cleanup();
    strcpy(made_dir, dir);
    made_keep = created;
    atomic_store(&made_state, TMP_LIVE);
}

void consph_made_dir_unregister(void)
{
    int expected = TMP_LIVE;
    atomic_compare_exchange_strong(&made_state, &expected, TMP_FREE);
}

void consph_child_register(pid_t pid)
{
    install_signal_cleanup();
    for (int k = 0; k < CHILD_SLOTS; ++k) {
        int expected = 0;
        if (atomic_compare_exchange_strong(&child_pids[k], &expected, (int)pid)) return;
    }
}

void consph_child_unregister(pid_t pid)
{
    for (int k = 0; k < CHILD_SLOTS; ++k) {
        int expected = (int)pid;
        if (atomic_compare_exchange_strong(&child_pids[k], &expected, 0)) return;
    }
}

void consph_cleanup_signals_block(sigset_t *old)
{
    sigset_t set;
    sigemptyset(&set);
    for (size_t k = 0; k < sizeof tmp_signals / sizeof tmp_signals[0]; ++k)
        sigaddset(&set, tmp_signals[k]);
    sigprocmask(SIG_BLOCK, &set, old);
}

void consph_cleanup_signals_default(void)
{
    /* Handlers only: a signal ignored (nohup, a background job) stays so, as exec keeps it. */
    for (size_t k = 0; k < sizeof tmp_signals / sizeof tmp_signals[0]; ++k) {
        struct sigaction old;
        if (sigaction(tmp_signals[k], NULL, &old) == 0 && old.sa_handler != SIG_IGN &&
            old.sa_handler != SIG_DFL)
            signal(tmp_signals[k], SIG_DFL);
    }
}

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

static ssize_t fdstream_write(void *cookie, const char *buf, size_t size)
{
    consph_fdstream *s = cookie;
    for (size_t done = 0; done < size;) {
        ssize_t w = write(s->fd, buf + done, size - done);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) {
            if (!s->err) s->err = w < 0 ? errno : EIO;
            return -1;
        }
        done += (size_t)w;
    }
    return (ssize_t)size;
}

/* A failed seek is not recorded: its caller sees it, and it is not why a write failed. */
static int fdstream_seek(void *cookie, off64_t *offset, int whence)
{
    const consph_fdstream *s = cookie;
    off_t at = lseek(s->fd, (off_t)*offset, whence);
    if (at < 0) return -1;
    *offset = at;
    return 0;
}

FILE *consph_fdstream_open(consph_fdstream *s, const char *mode)
{
    s->err = 0;
    cookie_io_functions_t io = {
        .read = NULL, .write = fdstream_write, .seek = fdstream_seek, .close = NULL};
    return fopencookie(s, mode, io);
}

int consph_outfile_fail(const consph_outfile *of, int err)
{
    if (!err) err = of->stream.err ? of->stream.err : EIO;
    return consph_fail(CONSPH_EIO, "cannot write '%s': %s", of->path, strerror(err));
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
    /* Registered before it exists: a signal between open and registration would leave it. */
    consph_tmp_register(of->tmp_path);
    /* O_CLOEXEC: a child (gnuplot) must not keep a temporary file open. O_NOFOLLOW: a link
     * planted at the temporary name must not redirect the write. */
    of->stream.fd = open(of->tmp_path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOFOLLOW, 0666);
    if (of->stream.fd >= 0) {
        of->fp = consph_fdstream_open(&of->stream, "wb");
        if (!of->fp) {
            int e = errno;
            close(of->stream.fd);
            errno = e;
        }
    }
    if (!of->fp) {
        int e = errno;
        consph_outfile_abort(of);
        return consph_fail(CONSPH_EIO, "cannot create '%s': %s", path, strerror(e));
    }
    return CONSPH_OK;
}

int consph_outfile_commit(consph_outfile *of)
{
    /* bad: a write failed, its reason in the stream; e: a failure of fsync or close. */
    int e = 0, bad = fflush(of->fp) != 0 || ferror(of->fp);
    /* The data must be on disk before the rename makes it the file: otherwise a crash soon after
     * can leave a complete-looking name with empty or partial content. */
    if (!bad && fsync(of->stream.fd) != 0) e = errno;
    if (fclose(of->fp) != 0) bad = 1;
    if (close(of->stream.fd) != 0 && !e) e = errno;
    of->fp = NULL;
    if (bad || e) {
        int rc = consph_outfile_fail(of, bad ? 0 : e);
        consph_outfile_abort(of);
        return rc;
    }
    if (rename(of->tmp_path, of->path) != 0) {
        e = errno;
        int rc = consph_fail(CONSPH_EIO, "cannot rename into '%s': %s", of->path, strerror(e));
        consph_outfile_abort(of);
        return rc;
    }
    consph_tmp_unregister(of->tmp_path);
    char *dir = dir_of(of->path);
    if (dir) sync_dir(dir);
    free(dir);
    free(of->path);
    free(of->tmp_path);
    memset(of, 0, sizeof *of);
    return CONSPH_OK;
}

void consph_outfile_abort(consph_outfile *of)
{
    if (of->fp) {
        fclose(of->fp);
        close(of->stream.fd);
        of->fp = NULL;
    }
    if (of->tmp_path) {
        remove(of->tmp_path);
        consph_tmp_unregister(of->tmp_path);
    }
    free(of->path);
    free(of->tmp_path);
    memset(of, 0, sizeof *of);
}
