/* Stop requests for long runs: SIGINT and SIGTERM only record themselves, so the run can end
 * its step, write a checkpoint and exit 128 + signal; a second signal of the same kind, while
 * the first is still pending, means "now": the process ends as the signal's default action
 * would end it.
 *
 * Interplay with consph_outfile: outfile.c removes its temporary files on SIGINT/SIGTERM/SIGHUP
 * through a handler it installs only where the action is the default. While these handlers are
 * installed, that one is not (for SIGINT and SIGTERM), so the second-signal path here removes
 * the temporary files itself (consph_outfile_remove_temps) before restoring the default action
 * and re-raising. consph_stop_uninstall gives back the previous actions, which may be outfile's
 * cleanup handler (installed before us) or the default (outfile installs its handler again at
 * its next open). */
#include <signal.h>
#include <string.h>

#include "consph/io.h"
#include "io/outfile_internal.h"

static const int stop_signals[] = {SIGINT, SIGTERM};
#define NSTOP (sizeof stop_signals / sizeof stop_signals[0])

static volatile sig_atomic_t stop_first;       /* the first signal received, 0 when none */
static volatile sig_atomic_t stop_seen[NSTOP]; /* received since install, per signal */
static struct sigaction stop_old[NSTOP];
static int stop_installed;

static void on_stop_signal(int sig)
{
    size_t k = 0;
    while (k < NSTOP && stop_signals[k] != sig) ++k;
    if (k == NSTOP) return;
    if (stop_seen[k]) {
        consph_outfile_remove_temps();
        struct sigaction dfl;
        memset(&dfl, 0, sizeof dfl);
        dfl.sa_handler = SIG_DFL;
        sigemptyset(&dfl.sa_mask);
        sigaction(sig, &dfl, NULL);
        /* Blocked while this handler runs: delivered, with the default action, on return. */
        raise(sig);
        return;
    }
    stop_seen[k] = 1;
    if (!stop_first) stop_first = sig;
}

int consph_stop_install(void)
{
    stop_first = 0;
    for (size_t k = 0; k < NSTOP; ++k) stop_seen[k] = 0;
    /* Installing twice would save our own handler as the one to restore. */
    if (stop_installed) return CONSPH_OK;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    /* A signal arriving during a write must not make that write fail with EINTR. */
    sa.sa_flags = SA_RESTART;
    for (size_t k = 0; k < NSTOP; ++k) {
        if (sigaction(stop_signals[k], &sa, &stop_old[k]) != 0) {
            const char *name = stop_signals[k] == SIGINT ? "SIGINT" : "SIGTERM";
            while (k-- > 0) sigaction(stop_signals[k], &stop_old[k], NULL);
            return consph_fail(CONSPH_EIO, "cannot install the %s handler", name);
        }
    }
    stop_installed = 1;
    return CONSPH_OK;
}

int consph_stop_requested(void)
{
    return stop_first;
}

void consph_stop_uninstall(void)
{
    if (!stop_installed) return;
    for (size_t k = 0; k < NSTOP; ++k) sigaction(stop_signals[k], &stop_old[k], NULL);
    stop_installed = 0;
}
