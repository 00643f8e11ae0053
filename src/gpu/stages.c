/* The timing backend of stages.h: each timed call between two marks of the timer, the marks
 * kept until collected (the CUDA events are read only then, so the launches stay asynchronous
 * while timed: the marks add an event record each, about a microsecond). */
#include <stdlib.h>
#include <string.h>

#include "consph/core.h"
#include "gpu/stages.h"

const char *const gpu_stage_names[GST_N] = {
    "bin",         "count",         "scan",         "scatter",      "cell_sort",
    "slots",       "permute",       "save",         "advance",      "density",
    "rates",       "negi_volumes",  "negi_first",   "negi_coupled", "negi_cleary",
    "negi_fatehi", "negi_korz",     "negi_rates",   "ipst_volumes", "chi_max",
    "ipst_shift",  "ipst_move",     "pst_shift",    "shift_end",    "remesh",
    "remesh_end",  "delta_volumes", "delta_renorm", "delta_rates",  "other",
    "zero",        "put",           "get"};

/* ---- the host clock ---- */

static double *host_marks;
static int host_used, host_cap;

static int host_mark(void)
{
    if (host_used == host_cap) {
        const int cap = host_cap ? 2 * host_cap : 256;
        double *m = realloc(host_marks, (size_t)cap * sizeof *m);
        if (!m) return -1;
        host_marks = m;
        host_cap = cap;
    }
    host_marks[host_used] = consph_wtime();
    return host_used++;
}
static double host_ms(int a, int b)
{
    return 1e3 * (host_marks[b] - host_marks[a]);
}
static void host_clear(void)
{
    host_used = 0;
}

const gpu_timer gpu_host_timer = {host_mark, host_ms, host_clear};

#ifndef CONSPH_HAVE_CUDA
const gpu_timer *gpu_cuda_timer(void)
{
    return NULL;
}
#endif

/* ---- the wrapper ---- */

typedef struct timed_call {
    int stage, a, b;
} timed_call;

static const gpu_backend *inner;
static const gpu_timer *clock_;
static int enabled, missed;
static timed_call *calls_;
static int ncalls, calls_cap;

static int begin(void)
{
    if (!enabled) return -1;
    const int a = clock_->mark();
    if (a < 0) missed = 1;
    return a;
}
static void end(int stage, int a)
{
    if (a < 0) return;
    const int b = clock_->mark();
    if (b < 0) {
        missed = 1;
        return;
    }
    if (ncalls == calls_cap) {
        const int cap = calls_cap ? 2 * calls_cap : 128;
        timed_call *c = realloc(calls_, (size_t)cap * sizeof *c);
        if (!c) {
            missed = 1;
            return;
        }
        calls_ = c;
        calls_cap = cap;
    }
    calls_[ncalls++] = (timed_call){stage, a, b};
}

static gpu_stage kernel_stage(gpu_kernel k)
{
    switch (k) {
    case GK_BIN:
        return GST_BIN;
    case GK_COUNT:
        return GST_COUNT;
    case GK_SCATTER:
        return GST_SCATTER;
    case GK_CELL_SORT:
        return GST_CELL_SORT;
    case GK_SLOTS:
        return GST_SLOTS;
    case GK_PERMUTE:
        return GST_PERMUTE;
    case GK_SAVE:
        return GST_SAVE;
    case GK_ADVANCE:
    case GK_KDK_DRIFT: /* tvf's integrator */
    case GK_KDK_KICK:
        return GST_ADVANCE;
    case GK_DENSITY:
        return GST_DENSITY;
    case GK_RATES:
        return GST_RATES;
    case GK_NEGI_VOLUMES:
        return GST_NEGI_VOLUMES;
    case GK_NEGI_FIRST:
        return GST_NEGI_FIRST;
    case GK_NEGI_COUPLED:
        return GST_NEGI_COUPLED;
    case GK_NEGI_CLEARY:
        return GST_NEGI_CLEARY;
    case GK_NEGI_FATEHI:
        return GST_NEGI_FATEHI;
    case GK_NEGI_KORZ:
        return GST_NEGI_KORZ;
    case GK_NEGI_RATES:
        return GST_NEGI_RATES;
    case GK_IPST_VOLUMES:
        return GST_IPST_VOLUMES;
    case GK_CHI_MAX:
        return GST_CHI_MAX;
    case GK_IPST_SHIFT:
        return GST_IPST_SHIFT;
    case GK_IPST_MOVE:
        return GST_IPST_MOVE;
    case GK_PST_SHIFT:
        return GST_PST_SHIFT;
    case GK_SHIFT_END:
        return GST_SHIFT_END;
    case GK_REMESH:
        return GST_REMESH;
    case GK_REMESH_END:
        return GST_REMESH_END;
    case GK_DELTA_VOLUMES:
        return GST_DELTA_VOLUMES;
    case GK_DELTA_RENORM:
        return GST_DELTA_RENORM;
    case GK_DELTA_RATES:
        return GST_DELTA_RATES;
    default:
        return GST_OTHER;
    }
}

static int w_alloc(void **p, size_t bytes)
{
    return inner->alloc(p, bytes);
}
static void w_release(void *p)
{
    inner->release(p);
}
static int w_put(void *dev, const void *host, size_t bytes)
{
    const int a = begin(), rc = inner->put(dev, host, bytes);
    end(GST_PUT, a);
    return rc;
}
static int w_get(void *host, const void *dev, size_t bytes)
{
    const int a = begin(), rc = inner->get(host, dev, bytes);
    end(GST_GET, a);
    return rc;
}
static int w_zero(void *dev, size_t bytes)
{
    const int a = begin(), rc = inner->zero(dev, bytes);
    end(GST_ZERO, a);
    return rc;
}
static int w_launch(gpu_kernel k, size_t count, const gpu_view *v, double c)
{
    const int a = begin(), rc = inner->launch(k, count, v, c);
    end(kernel_stage(k), a);
    return rc;
}
static int w_scan(const gpu_view *v)
{
    const int a = begin(), rc = inner->scan(v);
    end(GST_SCAN, a);
    return rc;
}
static const char *w_error(void)
{
    return inner->error();
}

static gpu_backend wrapped;

const gpu_backend *gpu_stages_wrap(const gpu_backend *in, const gpu_timer *timer)
{
    inner = in;
    clock_ = timer;
    enabled = missed = 0;
    ncalls = 0;
    wrapped = (gpu_backend){in->name, w_alloc,  w_release, w_put,  w_get,
                            w_zero,   w_launch, w_scan,    w_error};
    return &wrapped;
}

void gpu_stages_enable(int on)
{
    enabled = on;
}

int gpu_stages_collect(double ms[GST_N], long calls[GST_N])
{
    memset(ms, 0, GST_N * sizeof ms[0]);
    memset(calls, 0, GST_N * sizeof calls[0]);
    for (int k = 0; k < ncalls; ++k) {
        ms[calls_[k].stage] += clock_->ms(calls_[k].a, calls_[k].b);
        ++calls[calls_[k].stage];
    }
    ncalls = 0;
    clock_->clear();
    const int rc = missed;
    missed = 0;
    return rc;
}
