/* A whole run: the time loop with its files (snapshots and their .pvd index, the per-step log,
 * the JSON summary, checkpoints), stop signals and the progress line. */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/io.h"
#include "schemes/solver_internal.h"

static void json_num(FILE *fp, const char *key, double v, int last)
{
    if (isfinite(v))
        fprintf(fp, "  \"%s\": %.17g%s\n", key, v, last ? "" : ",");
    else
        fprintf(fp, "  \"%s\": null%s\n", key, last ? "" : ",");
}

void consph_run_summary_json(FILE *fp, const consph_run_summary *s)
{
    fprintf(fp, "{\n  \"problem\": \"%s\",\n  \"scheme\": \"%s\",\n  \"integrator\": \"%s\",\n",
            s->problem, s->scheme, s->integrator);
    fprintf(fp, "  \"n\": %zu,\n  \"dim\": %d,\n  \"steps\": %ld,\n", s->n, s->dim, s->steps);
    json_num(fp, "t", s->t, 0);
    json_num(fp, "dt", s->dt, 0);
    json_num(fp, "h", s->h, 0);
    json_num(fp, "c0", s->c0, 0);
    json_num(fp, "l1_u", s->l1_u, 0);
    json_num(fp, "l1_p", s->l1_p, 0);
    json_num(fp, "linf_u", s->linf_u, 0);
    json_num(fp, "linf_p", s->linf_p, 0);
    json_num(fp, "kinetic_energy", s->ke, 0);
    json_num(fp, "momentum_x", s->momentum[0], 0);
    json_num(fp, "momentum_y", s->momentum[1], 0);
    json_num(fp, "angular_momentum", s->angular_momentum, 0);
    json_num(fp, "ft_fmax", s->ft_fmax, 0);
    json_num(fp, "max_divu", s->max_divu, 0);
    json_num(fp, "seconds", s->seconds, 0);
    fprintf(fp, "  \"pairs\": %zu,\n  \"passes_per_stage\": %d,\n  \"passes_min\": %d,\n", s->pairs,
            s->passes_per_stage, s->passes_min);
    fprintf(fp, "  \"regularisations\": %ld\n}\n", s->regularisations);
}

typedef struct run_files {
    const consph_run_output *out;
    char *path; /* scratch for joined paths */
    size_t cap;
    consph_pvd pvd;
    int have_pvd;
} run_files;

static const char *join(run_files *f, const char *name)
{
    size_t need = strlen(f->out->dir) + strlen(name) + 2;
    if (need > f->cap) {
        char *p = realloc(f->path, need);
        if (!p) return NULL;
        f->path = p;
        f->cap = need;
    }
    snprintf(f->path, f->cap, "%s/%s", f->out->dir, name);
    return f->path;
}

static int write_log(const consph_solver *s, run_files *f)
{
    const char *path = join(f, "log.csv");
    if (!path) return consph_fail(CONSPH_ENOMEM, "out of memory");
    consph_outfile of;
    int st = consph_outfile_open(&of, path);
    if (st != CONSPH_OK) return st;
    fprintf(of.fp, "step,t,l1_u,linf_u,l1_p,linf_p,kinetic_energy,momentum_x,momentum_y,"
                   "momentum_z,angular_momentum,ft_fmax,max_divu,dt\n");
    for (size_t r = 0; r < s->nhist; ++r) {
        const double *row = s->hist + r * HIST_COLS;
        fprintf(of.fp, "%.0f", row[0]);
        for (int c = 1; c < HIST_COLS; ++c) fprintf(of.fp, ",%.10e", row[c]);
        fputc('\n', of.fp);
    }
    return consph_outfile_commit(&of);
}

static int write_snapshot(consph_solver *s, run_files *f)
{
    char name[64];
    snprintf(name, sizeof name, "snap_%06ld.vtu", s->step);
    int st = consph_solver_output_fields(s);
    const char *path = join(f, name);
    if (!path) return consph_fail(CONSPH_ENOMEM, "out of memory");
    if (st == CONSPH_OK) st = consph_write_particles(path, s->sys.p);
    if (st == CONSPH_OK) st = consph_pvd_add(&f->pvd, s->t, name);
    return st == CONSPH_OK ? write_log(s, f) : st;
}

static int write_checkpoint(const consph_solver *s, run_files *f)
{
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    int st = consph_solver_checkpoint_meta(s, &meta, &hist, &nh);
    const char *path = st == CONSPH_OK ? join(f, "checkpoint.ckpt") : NULL;
    if (st == CONSPH_OK && !path) st = consph_fail(CONSPH_ENOMEM, "out of memory");
    if (st == CONSPH_OK) st = consph_checkpoint_write(path, meta, s->sys.p, hist, nh);
    free(meta);
    free(hist);
    return st == CONSPH_OK ? write_log(s, f) : st;
}

static int write_summary(const consph_run_summary *sum, run_files *f)
{
    const char *path = join(f, "summary.json");
    if (!path) return consph_fail(CONSPH_ENOMEM, "out of memory");
    consph_outfile of;
    int st = consph_outfile_open(&of, path);
    if (st != CONSPH_OK) return st;
    consph_run_summary_json(of.fp, sum);
    return consph_outfile_commit(&of);
}

int consph_run(consph_solver *s, const consph_run_output *out, consph_run_summary *sum,
               int *stopped_by)
{
    run_files f = {.out = out};
    const int files = out && out->dir;
    int st = CONSPH_OK;
    *stopped_by = 0;
    if (files) {
        const char *pvd = join(&f, "run.pvd");
        if (!pvd) st = consph_fail(CONSPH_ENOMEM, "out of memory");
        /* a restarted run keeps the index up to its checkpoint and rewrites what follows */
        if (st == CONSPH_OK && s->step > 0 && consph_pvd_load(&f.pvd, pvd) == CONSPH_OK) {
            f.have_pvd = 1;
            st = consph_pvd_truncate(&f.pvd, s->t);
        } else if (st == CONSPH_OK) {
            consph_clear_error();
            st = consph_pvd_init(&f.pvd, pvd);
            f.have_pvd = st == CONSPH_OK;
            if (st == CONSPH_OK && s->step == 0) st = write_snapshot(s, &f);
        }
    }
    if (st == CONSPH_OK && out && out->signals) st = consph_stop_install();
    consph_progress pr;
    consph_progress_start(&pr, s->step);
    if (!(out && out->progress)) pr.enabled = 0;
    while (st == CONSPH_OK && !consph_solver_done(s)) {
        st = consph_solver_step(s);
        if (st != CONSPH_OK) break;
        consph_progress_update(&pr, s->step, s->t, s->nsteps, s->nsteps ? 0.0 : s->tf);
        const int last = consph_solver_done(s);
        if (files && (last || (out->snapshot_every > 0 && s->step % out->snapshot_every == 0)))
            st = write_snapshot(s, &f);
        if (st == CONSPH_OK && files && !last && out->checkpoint_every > 0 &&
            s->step % out->checkpoint_every == 0)
            st = write_checkpoint(s, &f);
        int sig = out && out->signals ? consph_stop_requested() : 0;
        if (st == CONSPH_OK && sig && !last) {
            *stopped_by = sig;
            if (files) st = write_checkpoint(s, &f);
            break;
        }
    }
    consph_progress_end(&pr);
    if (out && out->signals) consph_stop_uninstall();
    consph_solver_summary(s, sum);
    if (files && (st == CONSPH_OK || st == CONSPH_ENUMERIC)) {
        /* keep the message of a divergence: the files below must not replace it */
        char msg[512];
        snprintf(msg, sizeof msg, "%s", consph_last_error());
        int wst = write_log(s, &f);
        if (wst == CONSPH_OK && st == CONSPH_OK && !*stopped_by) wst = write_summary(sum, &f);
        if (wst == CONSPH_OK && st == CONSPH_OK && !*stopped_by) wst = problem_outputs(s, out->dir);
        if (st == CONSPH_OK)
            st = wst;
        else
            consph_fail(st, "%s", msg);
    }
    if (f.have_pvd) consph_pvd_free(&f.pvd);
    free(f.path);
    return st;
}

int consph_run_restart(consph_solver **s, const char *checkpoint)
{
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    consph_particles p;
    *s = NULL;
    int st = consph_checkpoint_read(checkpoint, &meta, &p, &hist, &nh);
    if (st != CONSPH_OK) return st;
    st = consph_solver_restore(s, meta, &p, hist, nh);
    free(meta);
    free(hist);
    consph_particles_free(&p);
    return st;
}
