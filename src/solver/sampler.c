/* A GPU run's log samples on a host thread of their own, beside the device's next steps.
 *
 * On the GPU a step of 250 000 particles takes about 2 ms, and a log sample (the diagnostics and,
 * with --exact both, the weakly-compressible reference at every particle) tens of ms of host work
 * on the particles the step copied back: done in line, the samples were two thirds of 001-table9's
 * largest rows (bench/gpu_study.md). The host's copy of the particles is written only by a copy
 * back, so a sample may read it while the device steps on: the main thread hands the sample to
 * this worker and goes on, and waits for it only where the host's state or the sample's results
 * are read again (the next copy back, the authors' measure, the files, the summary, the API's
 * readers: solver_sample_join).
 *
 * The worker runs solver_sample on a shallow copy of the solver taken at the step, so it reads
 * that step's t, step and log_since whatever the main thread's steps do meanwhile; what a sample
 * writes (the history, the eq. 26 sums, the buffers, the reference, the time parts) is lent to
 * the copy until the join takes it back. One sample at a time, in step order, with the same
 * operations on the same values: the history and every sum are those of samples in line, bit for
 * bit, for any thread count (tests/cli_gpu.sh: the overlapped emulation's files against the
 * CPU's; test_gpu_emul: its history through the API after every step, and its sums). */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gpu/gpu_internal.h"
#include "solver/solver_internal.h"

struct solver_sampler {
    pthread_t thread;
    pthread_mutex_t lock;
    pthread_cond_t wake; /* the worker: a job, or quit */
    pthread_cond_t done; /* the main thread: the job is done */
    int job, quit;       /* a job is handed over (until its join); the worker is to end */
    int finished;        /* the job's sample is done */
    int threads;         /* the job's parallel loops' threads: the main thread's less one */
    consph_solver copy;  /* the solver at the sampled step, holding what the sample writes */
    int status;          /* the last job's; a failure stays, for every later join */
    char message[1024];  /* its error message (the error text is per thread) */
    long jobs;           /* samples taken here */
    double waited;       /* seconds the main thread waited for them at the joins */
};

static void *worker(void *arg)
{
    solver_sampler *w = arg;
    pthread_mutex_lock(&w->lock);
    for (;;) {
        while (!w->quit && !(w->job && !w->finished)) pthread_cond_wait(&w->wake, &w->lock);
        if (w->quit) break;
        pthread_mutex_unlock(&w->lock);
        consph_set_num_threads(w->threads);
        consph_clear_error();
        const int st = solver_sample(&w->copy);
        pthread_mutex_lock(&w->lock);
        w->status = st;
        if (st != CONSPH_OK) snprintf(w->message, sizeof w->message, "%s", consph_last_error());
        w->finished = 1;
        pthread_cond_signal(&w->done);
    }
    pthread_mutex_unlock(&w->lock);
    return NULL;
}

/* CONSPH_SAMPLE_OVERLAP=0 keeps the samples in line, 1 overlaps them on any backend; unset, a
 * GPU's samples overlap its steps, the host emulation's stay in line (its steps take the host's
 * cores, which the worker's loops would share). */
static int overlap_wanted(const consph_solver *s)
{
    if (!s->gpu || s->par) return 0;
    const char *e = getenv("CONSPH_SAMPLE_OVERLAP");
    if (e && strcmp(e, "0") == 0) return 0;
    if (e && strcmp(e, "1") == 0) return 1;
    return !gpu_emulated(s);
}

static solver_sampler *sampler_start(consph_solver *s)
{
    if (s->sampler) return s->sampler;
    solver_sampler *w = calloc(1, sizeof *w);
    if (!w) return NULL;
    if (pthread_mutex_init(&w->lock, NULL) != 0) {
        free(w);
        return NULL;
    }
    if (pthread_cond_init(&w->wake, NULL) != 0) {
        pthread_mutex_destroy(&w->lock);
        free(w);
        return NULL;
    }
    if (pthread_cond_init(&w->done, NULL) != 0) {
        pthread_cond_destroy(&w->wake);
        pthread_mutex_destroy(&w->lock);
        free(w);
        return NULL;
    }
    if (pthread_create(&w->thread, NULL, worker, w) != 0) {
        pthread_cond_destroy(&w->done);
        pthread_cond_destroy(&w->wake);
        pthread_mutex_destroy(&w->lock);
        free(w);
        return NULL;
    }
    s->sampler = w;
    return w;
}

int solver_sample_join(consph_solver *s)
{
    solver_sampler *w = s->sampler;
    if (!w) return CONSPH_OK;
    if (!w->job)
        return w->status == CONSPH_OK ? CONSPH_OK : consph_fail(w->status, "%s", w->message);
    const double t0 = consph_wtime();
    pthread_mutex_lock(&w->lock);
    while (!w->finished) pthread_cond_wait(&w->done, &w->lock);
    w->job = 0;
    w->finished = 0;
    pthread_mutex_unlock(&w->lock);
    w->waited += consph_wtime() - t0;
    /* what the sample wrote comes back; the rest of the copy is the sampled step's and stale */
    const consph_solver *c = &w->copy;
    s->hist = c->hist;
    s->nhist = c->nhist;
    s->caphist = c->caphist;
    s->diag_buf = c->diag_buf;
    s->diag_cap = c->diag_cap;
    s->wc = c->wc;
    s->wc_buf = c->wc_buf;
    s->wc_cap = c->wc_cap;
    s->l1_u_acc = c->l1_u_acc;
    s->l1_p_acc = c->l1_p_acc;
    s->wcs_u_acc = c->wcs_u_acc;
    s->wcs_p_acc = c->wcs_p_acc;
    for (int k = 0; k < SAMPLE_PARTS; ++k) s->sample_seconds[k] += c->sample_seconds[k];
    s->sample_count += c->sample_count;
    if (w->status != CONSPH_OK) return consph_fail(w->status, "%s", w->message);
    return CONSPH_OK;
}

int solver_sample_overlapped(consph_solver *s)
{
    if (!overlap_wanted(s)) return solver_sample(s);
    int st = solver_sample_join(s);
    if (st != CONSPH_OK) return st;
    /* solver_sample's own test: this step is in the history already */
    if (solver_sampled_now(s)) return CONSPH_OK;
    solver_sampler *w = sampler_start(s);
    if (!w) return solver_sample(s); /* no thread: the sample in line, as without overlap */
    w->copy = *s;
    w->copy.sampler = NULL; /* its solver_sample must not wait for itself */
    memset(w->copy.sample_seconds, 0, sizeof w->copy.sample_seconds);
    w->copy.sample_count = 0;
    /* one core stays the main thread's (it launches the steps and waits on the device there):
     * a static loop with one thread time-sliced against it would wait for that thread */
    const int threads = consph_num_threads();
    w->threads = threads > 1 ? threads - 1 : 1;
    /* the next sample's weight starts now, as solver_sample leaves it */
    s->log_since = 0.0;
    pthread_mutex_lock(&w->lock);
    w->job = 1;
    w->finished = 0;
    ++w->jobs;
    pthread_cond_signal(&w->wake);
    pthread_mutex_unlock(&w->lock);
    return CONSPH_OK;
}

void solver_sampler_free(consph_solver *s)
{
    solver_sampler *w = s->sampler;
    if (!w) return;
    (void)solver_sample_join(s);
    if (getenv("CONSPH_SAMPLE_SECONDS"))
        fprintf(stderr, "consph: %ld log samples beside the steps; waited for them %.4f s\n",
                w->jobs, w->waited);
    pthread_mutex_lock(&w->lock);
    w->quit = 1;
    pthread_cond_signal(&w->wake);
    pthread_mutex_unlock(&w->lock);
    pthread_join(w->thread, NULL);
    pthread_cond_destroy(&w->done);
    pthread_cond_destroy(&w->wake);
    pthread_mutex_destroy(&w->lock);
    free(w);
    s->sampler = NULL;
}
