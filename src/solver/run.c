/* A whole run: the time loop with its files (snapshots and their .pvd index, the per-step log,
 * the JSON summary, checkpoints), stop signals and the progress line. */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "consph/io.h"
#include "consph/par.h"
#include "gpu/gpu_internal.h"
#include "solver/runfiles.h"
#include "solver/solver_internal.h"
#include "par/par_solver.h"

void consph_run_summary_json(FILE *fp, const consph_run_summary *s)
{
    fprintf(fp, "{\n  \"problem\": \"%s\",\n  \"scheme\": \"%s\",\n  \"integrator\": \"%s\",\n",
            s->problem, s->scheme, s->integrator);
    fprintf(fp, "  \"n\": %zu,\n  \"dim\": %d,\n  \"steps\": %ld,\n", s->n, s->dim, s->steps);
    runfiles_json_num(fp, "t", s->t, 0);
    runfiles_json_num(fp, "dt", s->dt, 0);
    runfiles_json_num(fp, "h", s->h, 0);
    runfiles_json_num(fp, "c0", s->c0, 0);
    runfiles_json_num(fp, "l1_u", s->l1_u, 0);
    runfiles_json_num(fp, "l1_p", s->l1_p, 0);
    if (s->error == CONSPH_ERROR_AUTHORS) {
        /* only then: an eq26 run's summary stays as it was */
        fprintf(fp, "  \"error\": \"authors\",\n  \"error_samples\": %d,\n", s->error_samples);
        runfiles_json_num(fp, "l1_u_authors", s->l1n_u, 0);
        runfiles_json_num(fp, "l1_p_authors", s->l1n_p, 0);
    }
    if (s->exact == CONSPH_EXACT_BOTH) {
        /* only then, as the authors' keys */
        runfiles_json_num(fp, "l1_u_wc", s->wc_l1_u, 0);
        runfiles_json_num(fp, "l1_p_wc", s->wc_l1_p, 0);
        if (s->error == CONSPH_ERROR_AUTHORS) {
            runfiles_json_num(fp, "l1_u_authors_wc", s->wc_l1n_u, 0);
            runfiles_json_num(fp, "l1_p_authors_wc", s->wc_l1n_p, 0);
        }
    }
    runfiles_json_num(fp, "linf_u", s->linf_u, 0);
    runfiles_json_num(fp, "linf_p", s->linf_p, 0);
    runfiles_json_num(fp, "kinetic_energy", s->ke, 0);
    runfiles_json_num(fp, "momentum_x", s->momentum[0], 0);
    runfiles_json_num(fp, "momentum_y", s->momentum[1], 0);
    if (s->dim == 3) runfiles_json_num(fp, "momentum_z", s->momentum[2], 0);
    runfiles_json_num(fp, "angular_momentum", s->angular_momentum, 0);
    runfiles_json_num(fp, "ft_fmax", s->ft_fmax, 0);
    runfiles_json_num(fp, "max_divu", s->max_divu, 0);
    runfiles_json_num(fp, "seconds", s->seconds, 0);
    fprintf(fp, "  \"pairs\": %zu,\n  \"passes_per_stage\": %d,\n  \"passes_min\": %d,\n", s->pairs,
            s->passes_per_stage, s->passes_min);
    if (s->nlist_skin > 0.0) {
        runfiles_json_num(fp, "nlist_skin", s->nlist_skin, 0);
        runfiles_json_num(fp, "nlist_bytes_per_particle", s->nlist_bytes, 0);
        fprintf(fp, "  \"nlist_note\": \"%s\",\n", s->nlist_note);
    }
    fprintf(fp, "  \"regularisations\": %ld\n}\n", s->regularisations);
}

static int write_log(const consph_solver *s, runfiles *f)
{
    return runfiles_csv(f, "log.csv",
                        "step,t,l1_u,linf_u,l1_p,linf_p,kinetic_energy,momentum_x,momentum_y,"
                        "momentum_z,angular_momentum,ft_fmax,max_divu,dt",
                        s->hist, s->nhist, HIST_COLS);
}

/* The particles a file is written from: the solver's own, or decomposed over MPI ranks (in
 * par_stream, on rank 0) the whole set's shape with its arrays gathered one at a time in the
 * serial order as the writer reads them (*from), so that rank 0 never holds the whole set. */
static int file_particles(consph_solver *s, const consph_particles **p, io_array_source *src,
                          const io_array_source **from)
{
    *p = s->sys.p;
    *from = NULL;
    if (!s->par) return CONSPH_OK;
    *from = src;
    return par_stream_source(s, p, src);
}

/* The declared output arrays (the same at every step) and the time, then the log. */
static int snapshot_arrays(consph_solver *s, void *f)
{
    consph_vtu_array arr[CONSPH_MAX_FIELDS];
    consph_vtu_content c = {arr, 0, 1, s->t};
    const consph_particles *p;
    io_array_source src;
    const io_array_source *from;
    int st = state_undeclared(s, 0);
    if (st == CONSPH_OK) st = state_snapshot_arrays(s, arr, &c.narrays);
    if (st == CONSPH_OK) st = file_particles(s, &p, &src, &from);
    if (st == CONSPH_OK) st = runfiles_snapshot_content(f, p, &c, s->step, from);
    return st == CONSPH_OK ? write_log(s, f) : st;
}

static int sample_now(consph_solver *s, void *arg)
{
    (void)arg;
    return solver_sample(s);
}

/* solver_sample (which samples only when the history lacks this step); decomposed over MPI
 * ranks, rank 0 tells whether, and the sample is taken on every rank (solver_sample_owned) or
 * gathers only what it reads. */
static int solver_sample_if(consph_solver *s)
{
    if (!s->par) return solver_sample(s);
    if (!par_sample_due(s)) return CONSPH_OK;
    return solver_sample_owned(s) ? solver_sample(s)
                                  : par_global_some(s, sample_now, NULL, solver_sample_fields);
}

/* consph_solver_output_fields; decomposed, every rank computes its own particles' and the
 * ranks agree on the outcome: a rank that failed alone (the weakly-compressible reference of
 * --exact wc|both is made on the ranks other than 0 here, at their first file) must not leave
 * the others waiting in the writer's collectives. */
static int output_fields(consph_solver *s)
{
    const int st = consph_solver_output_fields(s);
    return s->par ? consph_par_agree(st) : st;
}

/* A snapshot; the log gets this instant's diagnostics first, if its cadence had not sampled
 * it. Decomposed over MPI ranks, every rank computes its particles' output fields (each a
 * function of the particle's own state and the time: consph_solver_output_fields), which the
 * checkpoints carry as the serial run's do, and the sample gathers only what it reads. */
static int write_snapshot(consph_solver *s, runfiles *f)
{
    int st = solver_sample_if(s);
    if (st == CONSPH_OK) st = output_fields(s);
    return st == CONSPH_OK ? (s->par ? par_stream(s, snapshot_arrays, f) : snapshot_arrays(s, f))
                           : st;
}

static int checkpoint_whole(consph_solver *s, void *vf)
{
    runfiles *f = vf;
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    const consph_particles *p;
    io_array_source src;
    const io_array_source *from;
    int st = consph_solver_checkpoint_meta(s, &meta, &hist, &nh);
    const char *path = st == CONSPH_OK ? runfiles_join(f, "checkpoint.ckpt") : NULL;
    if (st == CONSPH_OK && !path) st = consph_fail(CONSPH_ENOMEM, "out of memory");
    if (st == CONSPH_OK) st = file_particles(s, &p, &src, &from);
    if (st == CONSPH_OK) st = io_checkpoint_write_source(path, meta, p, from, hist, nh);
    free(meta);
    free(hist);
    return st == CONSPH_OK ? write_log(s, f) : st;
}

/* The output fields are made this step's first, as for a snapshot: a checkpoint between
 * snapshots would otherwise carry the last snapshot's, in the slots of that step's particle order
 * (the re-sorts carry no output field), and a decomposed run's migration would have moved them
 * elsewhere than the serial run's. */
static int write_checkpoint(consph_solver *s, runfiles *f)
{
    /* a GPU run's every array as of this step: its steps copy back only what the log samples
     * and the snapshots read (docs/gpu.md) */
    int st = gpu_download(s);
    if (st == CONSPH_OK) st = output_fields(s);
    if (st != CONSPH_OK) return st;
    return s->par ? par_stream(s, checkpoint_whole, f) : checkpoint_whole(s, f);
}

static void summary_json(FILE *fp, const void *sum)
{
    consph_run_summary_json(fp, sum);
}

static int write_summary(const consph_run_summary *sum, runfiles *f)
{
    return runfiles_text(f, "summary.json", summary_json, sum);
}

static void run_id_text(FILE *fp, const void *id)
{
    fprintf(fp, "%s\n", (const char *)id);
}

/* The run identifier of DIR/run.id into id ("" when the file is missing or not one). */
static void read_run_id(runfiles *f, char *id)
{
    id[0] = '\0';
    const char *path = runfiles_join(f, "run.id");
    FILE *fp = path ? fopen(path, "r") : NULL;
    if (!fp) return;
    char line[64];
    if (fgets(line, sizeof line, fp) && strlen(line) == CONSPH_RUN_ID_LEN + 1 &&
        line[CONSPH_RUN_ID_LEN] == '\n') {
        line[CONSPH_RUN_ID_LEN] = '\0';
        strcpy(id, line);
    }
    fclose(fp);
}

/* The run files in dir: how many, the first few names, whether run.pvd is one; with `remove`,
 * each is unlinked. */
typedef struct dir_scan {
    size_t count;
    char names[160];
    int have_pvd;
} dir_scan;

static int scan_dir(const char *dir, runfiles *f, int remove, dir_scan *sc)
{
    memset(sc, 0, sizeof *sc);
    DIR *d = opendir(dir);
    if (!d) {
        if (errno == ENOENT) return CONSPH_OK;
        return consph_fail(CONSPH_EIO, "cannot list the directory '%s': %s", dir, strerror(errno));
    }
    int st = CONSPH_OK;
    const struct dirent *e;
    while (st == CONSPH_OK && (e = readdir(d)) != NULL) {
        if (!runfiles_is_run_file(e->d_name)) continue;
        const char *path = runfiles_join(f, e->d_name);
        struct stat sb;
        if (!path) {
            st = consph_fail(CONSPH_ENOMEM, "out of memory");
            break;
        }
        /* the run would fail at its first write there, and --overwrite removes files only:
         * refused before any work */
        if (lstat(path, &sb) == 0 && S_ISDIR(sb.st_mode)) {
            st = consph_fail(CONSPH_EFORMAT,
                             "'%s' is a directory named like a run's file: no run can write it "
                             "and --overwrite removes files only; move it away or choose "
                             "another directory",
                             path);
            break;
        }
        size_t len = strlen(sc->names);
        if (sc->count < 3)
            snprintf(sc->names + len, sizeof sc->names - len, "%s%.40s", sc->count ? ", " : "",
                     e->d_name);
        ++sc->count;
        if (!strcmp(e->d_name, "run.pvd")) sc->have_pvd = 1;
        if (!remove) continue;
        if (unlink(path) != 0 && errno != ENOENT)
            st = consph_fail(CONSPH_EIO, "cannot remove '%s': %s", path, strerror(errno));
    }
    closedir(d);
    return st;
}

int consph_run_dir_check(const char *dir, const char *run_id, int overwrite)
{
    if (overwrite && run_id)
        return consph_fail(CONSPH_EINVAL, "a restarted run continues its own files: it does not "
                                          "overwrite a directory");
    runfiles f = {.dir = dir};
    dir_scan sc;
    /* every entry is checked before the first is removed: nothing half-removed */
    int st = scan_dir(dir, &f, 0, &sc);
    if (st == CONSPH_OK && overwrite) st = scan_dir(dir, &f, 1, &sc);
    if (st == CONSPH_OK && sc.count && !overwrite) {
        char what[240];
        snprintf(what, sizeof what, "%s%s (%zu file%s)", sc.names, sc.count > 3 ? ", ..." : "",
                 sc.count, sc.count == 1 ? "" : "s");
        char id[CONSPH_RUN_ID_LEN + 1];
        read_run_id(&f, id);
        if (!run_id)
            st = consph_fail(CONSPH_EINVAL, "'%s' already holds the files of a run: %s", dir, what);
        else if (strcmp(id, run_id))
            st = consph_fail(CONSPH_EINVAL,
                             "'%s' holds the files of another run (%s%s): %s; the checkpoint's "
                             "run is %s",
                             dir, id[0] ? "run " : "no valid run.id", id, what, run_id);
        else if (sc.have_pvd) {
            /* a restart continues this index: one that does not read back is an error, not a
             * file to replace */
            consph_pvd pvd;
            const char *path = runfiles_join(&f, "run.pvd");
            st = path ? consph_pvd_load(&pvd, path) : consph_fail(CONSPH_ENOMEM, "out of memory");
            if (st == CONSPH_OK) {
                consph_pvd_free(&pvd);
            } else if (st == CONSPH_EFORMAT || st == CONSPH_EIO) {
                char msg[512];
                snprintf(msg, sizeof msg, "%s", consph_last_error());
                st = consph_fail(st,
                                 "the run's index, which a restart continues, does not read "
                                 "back (it is not replaced): %s",
                                 msg);
            }
        }
    }
    free(f.path);
    return st;
}

/* The run's directory opened: checked, run.id, the index (a restart's continued). */
static int run_open(consph_solver *s, void *vf)
{
    runfiles *f = vf;
    int st = consph_run_dir_check(f->dir, s->step > 0 ? s->run_id : NULL, 0);
    if (st == CONSPH_OK) st = runfiles_text(f, "run.id", run_id_text, s->run_id);
    const char *pvd = st == CONSPH_OK ? runfiles_join(f, "run.pvd") : NULL;
    if (st == CONSPH_OK && !pvd) st = consph_fail(CONSPH_ENOMEM, "out of memory");
    /* a restarted run keeps the index up to its checkpoint and rewrites what follows */
    if (st == CONSPH_OK && s->step > 0 && access(pvd, F_OK) == 0) {
        st = consph_pvd_load(&f->pvd, pvd);
        f->have_pvd = st == CONSPH_OK;
        /* the snapshots after the checkpoint are rewritten, or stale: those of the run's former
         * end when it continues to another (consph_solver_extend) */
        for (size_t k = 0; st == CONSPH_OK && k < f->pvd.n; ++k) {
            const char *snap = f->pvd.time[k] > s->t ? runfiles_join(f, f->pvd.file[k]) : NULL;
            if (snap && unlink(snap) != 0 && errno != ENOENT)
                st = consph_fail(CONSPH_EIO, "cannot remove '%s': %s", snap, strerror(errno));
        }
        if (st == CONSPH_OK) st = consph_pvd_truncate(&f->pvd, s->t);
    } else if (st == CONSPH_OK) {
        st = runfiles_pvd_init(f);
    }
    return st;
}

typedef struct run_close_arg {
    const consph_run_output *out;
    consph_run_summary *sum;
    runfiles *f;
    int files, stopped;
    int status; /* the run's, before its last files */
} run_close_arg;

/* The summary and the end-of-run files (the log also after a divergence). */
static int run_close(consph_solver *s, void *va)
{
    run_close_arg *a = va;
    const int st = a->status;
    consph_solver_summary(s, a->sum);
    if (!(a->files && (st == CONSPH_OK || st == CONSPH_ENUMERIC))) return st;
    /* keep the message of a divergence: the files below must not replace it */
    char msg[512];
    snprintf(msg, sizeof msg, "%s", consph_last_error());
    int wst = write_log(s, a->f);
    if (wst == CONSPH_OK && st == CONSPH_OK && !a->stopped) wst = write_summary(a->sum, a->f);
    if (wst == CONSPH_OK && st == CONSPH_OK && !a->stopped) wst = problem_outputs(s, a->out->dir);
    if (st == CONSPH_OK) return wst;
    consph_fail(st, "%s", msg);
    return st;
}

int consph_run(consph_solver *s, const consph_run_output *out, consph_run_summary *sum,
               int *stopped_by)
{
    runfiles f = {.dir = out ? out->dir : NULL};
    const int files = out && out->dir;
    int st = CONSPH_OK;
    *stopped_by = 0;
    if (files) {
        /* decomposed, rank 0 writes the files (reading no particle); the others follow its
         * status */
        st = s->par ? par_stream(s, run_open, &f) : run_open(s, &f);
        if (st == CONSPH_OK && s->step == 0) st = write_snapshot(s, &f);
    }
    /* decomposed over MPI ranks, mpirun delivers the signals (a stop checkpoint would need
     * every rank to agree on the step) */
    const int signals = out && out->signals && !s->par;
    const int install = signals && out->signals != CONSPH_RUN_SIGNALS_WATCH;
    if (st == CONSPH_OK && install) st = consph_stop_install();
    /* ∇u (the vorticity, velocity_gradient) is computed only in the steps that end at a
     * snapshot or the end of the run (consph_solver_step) */
    s->grads_lazy = 1;
    s->grads_every = files ? out->snapshot_every : 0;
    consph_progress pr;
    consph_progress_start(&pr, s->step);
    if (!(out && out->progress) || par_rank(s) != 0) pr.enabled = 0;
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
        int sig = signals ? consph_stop_requested() : 0;
        if (st == CONSPH_OK && sig && !last) {
            *stopped_by = sig;
            /* a GPU run's state, for the checkpoint (which copies it back) and the summary */
            st = files ? write_checkpoint(s, &f) : gpu_download(s);
            break;
        }
    }
    consph_progress_end(&pr);
    s->grads_lazy = 0;
    if (install) consph_stop_uninstall();
    run_close_arg ca = {out, sum, &f, files, *stopped_by, st};
    /* decomposed: every rank's summary of its own part, then rank 0's of the whole run, from the
     * history and the positions: no field is gathered but for a problem's own outputs at the
     * end (problem_outputs: 2D profiles and maps, which read the velocity and the output
     * fields) */
    static const char *const no_field[] = {NULL};
    if (s->par) consph_solver_summary(s, sum);
    const int outputs = files && (s->prob->radial || (s->prob->vorticity_image && s->dim == 2));
    st = s->par && !outputs ? par_global_some(s, run_close, &ca, no_field)
                            : solver_global(s, run_close, &ca);
    runfiles_free(&f);
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
    return solver_restore_read(s, checkpoint, meta, &p, hist, nh, NULL);
}

int solver_restore_read(consph_solver **s, const char *checkpoint, char *meta, consph_particles *p,
                        double *hist, size_t nh, const solver_range *range)
{
    int st = solver_restore_range(s, meta, p, hist, nh, range);
    if (st != CONSPH_OK && st != CONSPH_ENOMEM) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", consph_last_error());
        consph_fail(st, "checkpoint '%s': %s", checkpoint, msg);
    }
    free(meta);
    free(hist);
    consph_particles_free(p);
    return st;
}
