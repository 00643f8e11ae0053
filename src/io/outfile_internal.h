/* What src/io/stop.c and the gnuplot drawing of studies need of the outfile registry; not part
 * of the public API. */
#ifndef CONSPH_IO_OUTFILE_INTERNAL_H
#define CONSPH_IO_OUTFILE_INTERNAL_H

#include <signal.h>
#include <sys/types.h>

/* Kills and reaps the registered children, then unlinks the temporary file of every
 * consph_outfile still open and every registered one, and removes the registered directory.
 * Async-signal-safe: for a signal handler
 * that is about to end the process. */
void consph_outfile_remove_temps(void);

/* The same registry for a temporary file another process writes for us (gnuplot's output):
 * removed on SIGINT/SIGTERM/SIGHUP as an outfile's is. */
void consph_tmp_register(const char *path);
void consph_tmp_unregister(const char *path);

/* A directory being filled with outputs (a study's): on those signals its files are removed,
 * then the directory and its parents down to the first `created` characters of `dir` (the part
 * that existed before; 0: nothing was created, nothing is registered). One at a time. */
void consph_made_dir_register(const char *dir, size_t created);
void consph_made_dir_unregister(void);

/* A child writing such a file: on those signals it is killed and waited for before the files
 * are removed, so that it neither writes after the removal nor outlives us. A signal between
 * fork and registration would miss it: block them first (consph_cleanup_signals_block, *old
 * gets the mask to restore in both processes), and in the child restore the default actions
 * (consph_cleanup_signals_default: handlers only, ignored signals stay ignored) before
 * restoring the mask, so that our handlers do not run
 * in the child before its exec. */
void consph_child_register(pid_t pid);
void consph_child_unregister(pid_t pid);
void consph_cleanup_signals_block(sigset_t *old);
void consph_cleanup_signals_default(void);

#endif
