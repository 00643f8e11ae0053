/* One-line progress display of a run on stderr. Only a terminal gets it: in a log file or a
 * pipe, carriage returns and escape sequences would be noise, and ctest or a study collecting
 * stderr must see only real messages. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "consph/io.h"

/* Seconds between redraws: fast enough to look live, slow enough to cost nothing. */
#define PROGRESS_PERIOD 0.25

/* A study's row ("row 3/12  tgv, EWCSPH, nx=40 | "), shown before the run's own line. */
static char progress_prefix[256];

void consph_progress_prefix(const char *text)
{
    snprintf(progress_prefix, sizeof progress_prefix, "%s", text ? text : "");
}

void consph_progress_start(consph_progress *pr, long step0)
{
    memset(pr, 0, sizeof *pr);
    pr->enabled = isatty(STDERR_FILENO) == 1;
    pr->t0 = consph_wtime();
    pr->last = -INFINITY;
    pr->step0 = step0;
}

/* "mm:ss" (minutes may pass 99), or "--:--" when unknown. */
static void format_eta(char *buf, size_t size, double seconds)
{
    if (!(seconds >= 0) || seconds > 1e7) {
        snprintf(buf, size, "--:--");
        return;
    }
    long s = (long)(seconds + 0.5);
    snprintf(buf, size, "%02ld:%02ld", s / 60, s % 60);
}

void consph_progress_update(consph_progress *pr, long step, double t, long steps_end, double t_end)
{
    if (!pr->enabled) return;
    double now = consph_wtime();
    if (!pr->have_first) {
        pr->have_first = 1;
        pr->step_first = step;
        pr->t_first = t;
        pr->wall_first = now;
    }
    if (now - pr->last < PROGRESS_PERIOD) return;
    pr->last = now;
    double elapsed = now - pr->t0;
    double rate = elapsed > 0 ? (double)(step - pr->step0) / elapsed : 0.0;
    double eta = -1.0;
    if (steps_end > 0 && rate > 0)
        eta = (double)(steps_end - step) / rate;
    else if (t_end > 0 && t > pr->t_first)
        eta = (t_end - t) * (now - pr->wall_first) / (t - pr->t_first);
    char etabuf[32];
    format_eta(etabuf, sizeof etabuf, eta);
    /* \033[K clears what a longer previous line left to the right. */
    fprintf(stderr, "\r%sstep %ld  t=%.6g  %.*f steps/s  ETA %s\033[K", progress_prefix, step, t,
            rate < 10 ? 2 : 0, rate, etabuf);
    fflush(stderr);
}

void consph_progress_end(consph_progress *pr)
{
    if (!pr->enabled) return;
    fprintf(stderr, "\r\033[K");
    fflush(stderr);
    pr->enabled = 0;
}
