/* The one writer every study kind shares: output paths and atomic files, the markdown report's
 * head and published values, CSV labels, gnuplot scripts (quoting, head) and their drawing into
 * SVG, the output directory and the study README. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "consph/io.h"
#include "io/outfile_internal.h"
#include "study/kinds/kinds.h"

int study_kv_has(const study_kvlist *l, const char *key)
{
    for (int k = 0; k < l->n; ++k)
        if (strcmp(l->items[k].key, key) == 0) return 1;
    return 0;
}

/* A figure's own note: the study's note is printed once, in the study README. */
const char *study_figure_note(const study_figure *f)
{
    for (int k = 0; k < f->keys.n; ++k)
        if (strcmp(f->keys.items[k].key, "note") == 0) return f->keys.items[k].value;
    return NULL;
}

void study_report_head(FILE *o, const consph_study *s, const study_figure *f)
{
    study_report_head_as(o, s, f, study_get_or(s, f, NULL, "title", f->id));
}

/* The figure's title; with --particles the layout it names (e.g. "unperturbed lattice (UP)")
 * is not what ran, and it says so. */
const char *study_files_title(const consph_study *s, const study_figure *f, int files, char *buf,
                              size_t size)
{
    const char *title = study_get_or(s, f, NULL, "title", f->id);
    if (!files) return title;
    int len = snprintf(buf, size,
                       "%s [this run: particles from files (--particles), not the layout the "
                       "title names]",
                       title);
    return len > 0 && (size_t)len < size ? buf : title;
}

void study_report_head_as(FILE *o, const consph_study *s, const study_figure *f, const char *title)
{
    (void)s;
    fprintf(o, "## %s: %s\n\n", f->id, title);
    const char *note = study_figure_note(f);
    if (note) fprintf(o, "%s\n\n", note);
}

void study_published_values(const consph_study *s, const study_figure *f, FILE *o)
{
    int any = 0;
    for (int r = 0; r < f->nseries; ++r) {
        const study_series *ser = &f->series[r];
        const study_kvlist *lists[3] = {&s->keys, &f->keys, &ser->keys};
        char line[1024] = "";
        for (int l = 0; l < 3; ++l)
            for (int k = 0; k < lists[l]->n; ++k) {
                const char *key = lists[l]->items[k].key;
                if (strncmp(key, "paper.", 6) != 0) continue;
                if (l < 2 && study_kv_has(&ser->keys, key)) continue;
                if (l == 0 && study_kv_has(&f->keys, key)) continue;
                size_t len = strlen(line);
                snprintf(line + len, sizeof line - len, "%s%s = %s", len ? "; " : "", key + 6,
                         lists[l]->items[k].value);
            }
        if (!line[0]) continue;
        if (!any) fprintf(o, "Published values (as the paper prints them):\n\n");
        any = 1;
        fprintf(o, "- %s: %s\n", ser->label, line);
    }
    if (any) fprintf(o, "\n");
}

/* DIR/NAME.EXT into buf (STUDY_PATH_MAX bytes), refused rather than truncated. */
int study_out_path(char *buf, const char *dir, const char *name, const char *ext)
{
    int n = snprintf(buf, STUDY_PATH_MAX, "%s/%s%s", dir, name, ext);
    if (n < 0 || n >= STUDY_PATH_MAX)
        return consph_fail(CONSPH_EINVAL, "output path '%s/%s%s' is too long", dir, name, ext);
    return CONSPH_OK;
}

int study_open_output(consph_outfile *of, const char *dir, const char *id, const char *ext)
{
    char path[STUDY_PATH_MAX];
    int rc = study_out_path(path, dir, id, ext);
    return rc ? rc : consph_outfile_open(of, path);
}

/* Creates `path` and its missing parents; *created is the length of the shortest prefix of
 * path this call created (0: none), so that a failed run can remove what it made. */
int study_mkdir_p(const char *path, size_t *created)
{
    char buf[STUDY_PATH_MAX];
    *created = 0;
    if (snprintf(buf, sizeof buf, "%s", path) >= (int)sizeof buf)
        return consph_fail(CONSPH_EINVAL, "output path '%s' is too long", path);
    size_t len = strlen(buf);
    for (size_t k = 1; k <= len; ++k) {
        if (buf[k] != '/' && buf[k] != '\0') continue;
        char c = buf[k];
        buf[k] = '\0';
        if (mkdir(buf, 0777) == 0) {
            if (!*created) *created = k;
        } else if (errno != EEXIST) {
            return consph_fail(CONSPH_EIO, "cannot create directory '%s': %s", buf,
                               strerror(errno));
        }
        buf[k] = c;
    }
    return CONSPH_OK;
}

void study_remove_files(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char path[STUDY_PATH_MAX];
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..") &&
            study_out_path(path, dir, e->d_name, "") == CONSPH_OK)
            remove(path);
    closedir(d);
}

/* After a failed run: the directories it created go, with what it wrote into them. */
void study_remove_created(const char *dir, size_t created)
{
    if (!created) return;
    study_remove_files(dir);
    char buf[STUDY_PATH_MAX];
    snprintf(buf, sizeof buf, "%s", dir);
    for (size_t k = strlen(buf); k >= created; --k) {
        if (buf[k] != '/' && buf[k] != '\0') continue;
        buf[k] = '\0';
        if (rmdir(buf) != 0 && errno != ENOENT) break;
    }
}

/* A CSV-safe copy of a label (no commas or quotes). */
const char *study_csv_label(const char *label, char *buf, size_t size)
{
    snprintf(buf, size, "%s", label);
    for (char *c = buf; *c; ++c)
        if (*c == ',' || *c == '"') *c = ';';
    return buf;
}

int study_have_gnuplot(void)
{
    static int cached = -1;
    if (cached < 0) cached = system("command -v gnuplot >/dev/null 2>&1") == 0;
    return cached;
}

/* Writes `text` to a gnuplot script as a single-quoted string, the one form gnuplot never
 * interprets (no backquote commands, macros or escapes; '' is a quote). Every user string that
 * meets gnuplot goes through here; control characters cannot be quoted and are refused. */
int study_gp_put(FILE *o, const char *text)
{
    for (const char *c = text; *c; ++c)
        if ((unsigned char)*c < 0x20 || *c == 0x7f)
            return consph_fail(CONSPH_EFORMAT,
                               "'%s' cannot go into a gnuplot script (control character 0x%02x)",
                               text, (unsigned char)*c);
    fputc('\'', o);
    for (const char *c = text; *c; ++c) {
        if (*c == '\'') fputc('\'', o);
        fputc(*c, o);
    }
    fputc('\'', o);
    return CONSPH_OK;
}

/* A figure's title as one gnuplot string expression: the study file's title, then on a second
 * line `ran` (what this run was: its t_f and resolutions), each quoted by study_gp_put. */
int study_gp_title(FILE *o, const char *title, const char *ran)
{
    int rc = study_gp_put(o, title);
    if (rc == CONSPH_OK && ran && ran[0]) {
        fprintf(o, " . \"\\n\" . ");
        rc = study_gp_put(o, ran);
    }
    return rc;
}

/* The head of every figure script: SVG into `outfile` (ID.svg unless the caller sets it, so the
 * script also runs by hand) and a title that says what ran. */
int study_gp_head(FILE *o, const char *id, const char *title, const char *ran)
{
    fprintf(o,
            "set terminal svg size 900,640 dynamic\nif (!exists('outfile')) outfile = '%s.svg'\n"
            "set output outfile\nset title ",
            id);
    int rc = study_gp_title(o, title, ran);
    fprintf(o, " noenhanced\nset grid\nset key outside right noenhanced\n");
    return rc;
}

/* Series styles: gnuplot's default colours repeat after 8, and a figure of 001 has up to 12
 * schemes, so each series takes a colour of its own from 16 and a marker from 15 (filled and
 * open alternating); the pair differs for every series up to 240, and past the 16 colours the
 * line is dashed as well. */
static const char *const gp_colours[] = {
    "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
    "#000000", "#bcbd22", "#7f7f7f", "#393b79", "#843c39", "#637939", "#ff9896", "#98df8a"};
static const int gp_points[] = {7, 5, 9, 11, 13, 15, 6, 4, 8, 10, 12, 14, 1, 2, 3};
#define GP_NCOLOURS ((int)(sizeof gp_colours / sizeof gp_colours[0]))
#define GP_NPOINTS ((int)(sizeof gp_points / sizeof gp_points[0]))

const char *study_gp_colour(int k)
{
    return gp_colours[(k < 0 ? 0 : k) % GP_NCOLOURS];
}

int study_gp_point(int k)
{
    return gp_points[(k < 0 ? 0 : k) % GP_NPOINTS];
}

void study_gp_style(FILE *o, int k)
{
    fprintf(o, " lc rgb '%s' pt %d", study_gp_colour(k), study_gp_point(k));
    if (k >= GP_NCOLOURS) fprintf(o, " dt %d", 1 + k / GP_NCOLOURS);
}

/* The paper's value of series k: the open form of the series' marker, larger, in its colour. */
void study_gp_paper_style(FILE *o, int k)
{
    int pt = study_gp_point(k);
    /* gnuplot's filled markers 5, 7, ..., 15 are the open 4, 6, ..., 14 filled */
    if (pt >= 5 && pt % 2 == 1) pt -= 1;
    fprintf(o, " lc rgb '%s' pt %d ps 2.4 lw 2", study_gp_colour(k), pt);
}

void study_extent_init(study_extent *e)
{
    e->lo = INFINITY;
    e->hi = -INFINITY;
}

/* A value joins the extent when it can be drawn: finite, and positive on a log axis. */
void study_extent_add(study_extent *e, double v, int log)
{
    if (!isfinite(v) || (log && !(v > 0))) return;
    e->lo = fmin(e->lo, v);
    e->hi = fmax(e->hi, v);
}

/* `set Xrange` to the extent with a margin of 4 % of its span each side (of its decades on a
 * log axis, at least a factor 1.15), so that the axes end at the data and the paper's points
 * rather than at gnuplot's next round tic; autoscale when the extent is empty. */
void study_gp_range(FILE *o, const char *axis, const study_extent *e, int log)
{
    if (!(e->lo <= e->hi)) {
        fprintf(o, "set autoscale %s\n", axis);
        return;
    }
    if (log) {
        const double f = fmax(1.15, pow(e->hi / e->lo, 0.04)), lo = e->lo / f, hi = e->hi * f;
        fprintf(o, "set %srange [%.10g:%.10g]\n", axis, lo, hi);
        /* Under two decades gnuplot labels one tic or none: 1-2-5 tics instead. */
        if (hi / lo < 100.0) {
            char tics[256];
            size_t len = 0;
            for (double d = pow(10.0, floor(log10(lo))); d <= hi; d *= 10.0)
                for (int m = 0; m < 3 && len < sizeof tics; ++m) {
                    const double t = d * (m == 0 ? 1.0 : m == 1 ? 2.0 : 5.0);
                    if (t >= lo && t <= hi)
                        len += (size_t)snprintf(tics + len, sizeof tics - len, "%s%.6g",
                                                len ? ", " : "", t);
                }
            if (len && len < sizeof tics) fprintf(o, "set %stics (%s)\n", axis, tics);
        }
    } else {
        double pad = e->hi > e->lo ? 0.04 * (e->hi - e->lo) : fmax(1e-12, 0.05 * fabs(e->hi));
        fprintf(o, "set %srange [%.10g:%.10g]\n", axis, e->lo - pad, e->hi + pad);
    }
}

/* Tics at the given values (the resolutions that ran and the paper's), sorted, each once; left
 * to gnuplot when there are more than 12. */
void study_gp_tics(FILE *o, const char *axis, const double *v, int n)
{
    double t[12];
    int m = 0;
    for (int j = 0; j < n; ++j) {
        if (!isfinite(v[j]) || !(v[j] > 0)) continue;
        int k = 0;
        while (k < m && t[k] < v[j]) ++k;
        if (k < m && t[k] == v[j]) continue;
        if (m == 12) return;
        memmove(t + k + 1, t + k, (size_t)(m - k) * sizeof *t);
        t[k] = v[j];
        ++m;
    }
    if (m == 0) return;
    fprintf(o, "set %stics (", axis);
    for (int k = 0; k < m; ++k) fprintf(o, "%s%.6g", k ? ", " : "", t[k]);
    fprintf(o, ")\n");
}

/* "NAME = v1, v2, v3" appended to buf at *len (NAME omitted when NULL), at most 8 values shown
 * (the first six, an ellipsis and the last). */
void study_list_text(char *buf, size_t size, size_t *len, const char *name, const double *v, int n)
{
    if (*len >= size) return;
    if (name) *len += (size_t)snprintf(buf + *len, size - *len, "%s = ", name);
    for (int j = 0; j < n && *len < size; ++j) {
        if (n > 8 && j == 6) {
            *len += (size_t)snprintf(buf + *len, size - *len, ", ...");
            j = n - 1;
        }
        *len += (size_t)snprintf(buf + *len, size - *len, "%s%g", j ? ", " : "", v[j]);
    }
}

/* Draws DIR/ID.gp into DIR/ID.svg through a temporary file, so that a figure either is drawn
 * whole or leaves no SVG; gnuplot failing is an error. Without gnuplot: a warning, once. */
int study_render_figure(const char *dir, const char *id)
{
    static int warned;
    if (!study_have_gnuplot()) {
        if (!warned)
            fprintf(stderr,
                    "consph study: warning: gnuplot not found, so figures are left as "
                    "FIGURE.gp scripts without SVG (Debian: apt-get install gnuplot-nox)\n");
        warned = 1;
        return CONSPH_OK;
    }
    char tmp[STUDY_PATH_MAX], final[STUDY_PATH_MAX], script[STUDY_PATH_MAX / 4],
        setout[STUDY_PATH_MAX / 4];
    char tmp_name[STUDY_PATH_MAX / 4];
    snprintf(tmp_name, sizeof tmp_name, "%s.svg.tmp.%ld", id, (long)getpid());
    snprintf(script, sizeof script, "%s.gp", id);
    int rc = study_out_path(tmp, dir, tmp_name, "");
    if (rc == CONSPH_OK) rc = study_out_path(final, dir, id, ".svg");
    if (rc) return rc;
    FILE *mem = fmemopen(setout, sizeof setout, "w");
    if (!mem) return consph_fail(CONSPH_ENOMEM, "out of memory");
    fprintf(mem, "outfile = ");
    rc = study_gp_put(mem, tmp_name);
    fclose(mem);
    if (rc) return rc;
    fflush(NULL);
    /* SIGINT/SIGTERM while gnuplot draws: the child is killed and its output removed with the
     * other temporary files (src/io/outfile.c). */
    consph_tmp_register(tmp);
    sigset_t mask;
    consph_cleanup_signals_block(&mask);
    /* fork and exec rather than system(): the output directory never passes through a shell. */
    pid_t pid = fork();
    if (pid == 0) {
        consph_cleanup_signals_default();
        sigprocmask(SIG_SETMASK, &mask, NULL);
        int null = open("/dev/null", O_WRONLY);
        if (null >= 0) {
            dup2(null, 1);
            dup2(null, 2);
        }
        if (chdir(dir) == 0) execlp("gnuplot", "gnuplot", "-e", setout, script, (char *)NULL);
        _exit(127);
    }
    int fork_errno = errno;
    if (pid > 0) consph_child_register(pid);
    sigprocmask(SIG_SETMASK, &mask, NULL);
    if (pid < 0) {
        consph_tmp_unregister(tmp);
        return consph_fail(CONSPH_EIO, "cannot start gnuplot: %s", strerror(fork_errno));
    }
    /* Polled rather than waited for: a stop request (consph_stop_install records SIGINT and
     * SIGTERM) ends the drawing at once, as the signal's default action would. */
    int status = 0, stopped = 0;
    for (;;) {
        pid_t w = waitpid(pid, &status, WNOHANG);
        if (w == pid || (w < 0 && errno != EINTR)) break;
        if (!stopped && consph_stop_requested()) {
            stopped = 1;
            kill(pid, SIGKILL);
        }
        if (w == 0) nanosleep(&(struct timespec){0, 10000000L}, NULL);
    }
    consph_child_unregister(pid);
    if (stopped) {
        remove(tmp);
        consph_tmp_unregister(tmp);
        return STUDY_STOPPED;
    }
    struct stat st;
    int drawn =
        WIFEXITED(status) && WEXITSTATUS(status) == 0 && stat(tmp, &st) == 0 && st.st_size > 0;
    if (drawn && rename(tmp, final) == 0) {
        consph_tmp_unregister(tmp);
        return CONSPH_OK;
    }
    remove(tmp);
    consph_tmp_unregister(tmp);
    return consph_fail(CONSPH_EIO,
                       "gnuplot could not draw %s (exit status %d); run 'gnuplot %s' there to see "
                       "why",
                       final, WIFEXITED(status) ? WEXITSTATUS(status) : -1, script);
}

/* The study's README: title, then every figure's report in order. */
int study_write_readme(const consph_study *s, int quick, int files, const char *dir)
{
    char path[STUDY_PATH_MAX];
    consph_outfile of;
    int rc = study_out_path(path, dir, "README", ".md");
    if (rc == CONSPH_OK) rc = consph_outfile_open(&of, path);
    if (rc) return rc;
    fprintf(of.fp, "# %s: %s\n\n", consph_study_name(s), consph_study_title(s));
    const char *note = study_get(s, NULL, NULL, "note");
    if (note) fprintf(of.fp, "%s\n\n", note);
    fprintf(of.fp, "Generated by `consph study %s%s%s` (consph %s).\n\n", consph_study_name(s),
            quick ? " --quick" : "", files ? " --particles ..." : "", CONSPH_VERSION);
    for (int k = 0; k < s->nfigs; ++k) {
        char md[STUDY_PATH_MAX], buf[4096];
        if (study_out_path(md, dir, s->figs[k].id, ".md") != CONSPH_OK) continue;
        FILE *in = fopen(md, "r");
        if (!in) continue;
        size_t got;
        while ((got = fread(buf, 1, sizeof buf, in)) > 0) fwrite(buf, 1, got, of.fp);
        fclose(in);
    }
    return consph_outfile_commit(&of);
}

const char *study_resolutions_text(int files, int quick)
{
    return files ? "the files'" : quick ? "quick" : "full (paper)";
}

int study_close_output(consph_outfile *of, int rc)
{
    if (rc) {
        consph_outfile_abort(of);
        return rc;
    }
    return consph_outfile_commit(of);
}

void study_md_figure(FILE *o, const char *id)
{
    if (study_have_gnuplot()) fprintf(o, "![%s](%s.svg)\n\n", id, id);
}

int study_gp_finish(consph_outfile *of, int rc, const char *dir, const char *id)
{
    rc = study_close_output(of, rc);
    return rc ? rc : study_render_figure(dir, id);
}

/* ---- rows: progress, the store that --resume reads ---- */

/* DIR/.FIGURE.sK.rJ.row: hidden beside the figure's outputs, so that a failed run's cleanup
 * (study_remove_created) takes it with them and a listing of the results does not show it. */
static int row_path(char *buf, const study_job *job, const study_figure *f, int k, int j)
{
    char name[STUDY_NAME_MAX + 48];
    snprintf(name, sizeof name, ".%s.s%d.r%d", f->id, k, j);
    return study_out_path(buf, job->dir, name, ".row");
}

#define ROW_MAGIC "consph-study-row 1"

int study_row_load(const study_job *job, const study_figure *f, int k, int j, void *row,
                   size_t size, double **extra, size_t *nextra)
{
    if (extra) *extra = NULL;
    if (nextra) *nextra = 0;
    if (!job->rows) return 0;
    char path[STUDY_PATH_MAX];
    if (row_path(path, job, f, k, j) != CONSPH_OK) return 0;
    FILE *in = fopen(path, "rb");
    if (!in) return 0;
    /* Two text lines, then the bytes: fgets, as a scanf "\n" would skip bytes of the row that
     * look like white space. */
    char magic[32], counts[64];
    unsigned long long got_size = 0, got_extra = 0;
    int ok = fgets(magic, sizeof magic, in) && strcmp(magic, ROW_MAGIC "\n") == 0 &&
             fgets(counts, sizeof counts, in) &&
             sscanf(counts, "%llu %llu", &got_size, &got_extra) == 2 && got_size == size &&
             (extra || got_extra == 0);
    double *x = NULL;
    if (ok && got_extra) {
        x = malloc((size_t)got_extra * sizeof *x);
        ok = x != NULL;
    }
    ok = ok && fread(row, 1, size, in) == size &&
         (!got_extra || fread(x, sizeof *x, (size_t)got_extra, in) == (size_t)got_extra);
    fclose(in);
    if (!ok) {
        free(x);
        return 0;
    }
    if (extra) *extra = x;
    if (nextra) *nextra = (size_t)got_extra;
    return 1;
}

/* "mm:ss", "h:mm:ss", or days and hours when long; "--" when unknown. */
const char *consph_study_duration_text(double seconds, char *buf, size_t size)
{
    if (!(seconds >= 0) || !isfinite(seconds)) {
        snprintf(buf, size, "--");
        return buf;
    }
    if (seconds >= 2 * 86400.0) {
        snprintf(buf, size, "%.1f days", seconds / 86400.0);
        return buf;
    }
    long s = (long)(seconds + 0.5);
    if (s >= 3600)
        snprintf(buf, size, "%ld:%02ld:%02ld", s / 3600, s / 60 % 60, s % 60);
    else
        snprintf(buf, size, "%02ld:%02ld", s / 60, s % 60);
    return buf;
}

/* The due packings the cache holds now (a row of some process made them), counted. */
static int due_made(study_rows *r)
{
    int n = 0;
    for (int q = 0; q < r->ndue; ++q) {
        if (!r->due[q].made && access(r->due[q].path, R_OK) == 0) r->due[q].made = 1;
        n += r->due[q].made;
    }
    return n;
}

/* Seconds still to go: the remaining work at the rate of the rows this process ran (their wall
 * time includes reading their layouts, not packing them: a row that packed is left out of the
 * rate), before the first at the estimate's rate (model_per_work), and the packings still due at
 * the packing model's price; unknown without a rate. */
double study_rows_eta(const study_rows *r)
{
    const double left = r->work_total - (r->shared ? (double)__atomic_load_n(&r->shared->work_done,
                                                                             __ATOMIC_RELAXED)
                                                   : r->work_done);
    double seconds;
    if (r->work_run > 0 && r->seconds_run > 0) {
        seconds = left * r->seconds_run / r->work_run;
        /* the workers together, each at this one's rate */
        if (r->shared) seconds /= r->share_size;
    } else if (isfinite(r->model_per_work)) {
        /* the model's rate is the whole machine's */
        seconds = left * r->model_per_work;
    } else {
        return NAN;
    }
    for (int q = 0; q < r->ndue; ++q)
        if (!r->due[q].made) seconds += r->due[q].seconds;
    return fmax(0.0, seconds);
}

/* The log written since the last call, below the live line (which it clears first). */
static void rows_pass_log(study_rows *r)
{
    if (!r->mem) return;
    fflush(r->mem);
    if (r->memlen > r->memdone && r->out) {
        fprintf(stderr, "\r\033[K");
        fflush(stderr);
        fwrite(r->membuf + r->memdone, 1, r->memlen - r->memdone, r->out);
        fflush(r->out);
    }
    r->memdone = r->memlen;
}

static void rows_line(study_rows *r, int done_line, int stored)
{
    rows_pass_log(r);
    if (!r->print) return;
    char el[32], eta[32];
    consph_study_duration_text(consph_wtime() - r->t0, el, sizeof el);
    consph_study_duration_text(study_rows_eta(r), eta, sizeof eta);
    /* One fprintf per line: stderr is unbuffered, and a line must not be torn by others. */
    /* with --jobs, the rows every worker finished (a finished row: the count it made) */
    const int done = !r->shared  ? r->done
                     : done_line ? r->shared_done
                                 : __atomic_load_n(&r->shared->done, __ATOMIC_RELAXED);
    if (r->tty) {
        fprintf(stderr, "\rrow %d/%d  %s  elapsed %s  ETA %s\033[K", done + !done_line, r->total,
                r->current, el, eta);
        /* A solver row's own line (consph_run) keeps the row in view. */
        char prefix[256];
        snprintf(prefix, sizeof prefix, "row %d/%d %.40s | ", done + !done_line, r->total,
                 r->current);
        consph_progress_prefix(prefix);
    } else if (done_line)
        fprintf(stderr, "study: row %d/%d %s: %s (elapsed %s, ETA %s)\n", done, r->total,
                stored ? "kept from the earlier run" : "done", r->current, el, eta);
    fflush(stderr);
}

void study_row_begin(const study_job *job, const study_figure *f, int k, const char *what,
                     double work)
{
    study_rows *r = job->rows;
    if (!r) return;
    if (k >= 0)
        snprintf(r->current, sizeof r->current, "%s, %s, %s", f->id, f->series[k].label, what);
    else
        snprintf(r->current, sizeof r->current, "%s", f->id);
    r->row_t0 = consph_wtime();
    r->row_work = work;
    r->row_made = due_made(r);
    if (r->tty) rows_line(r, 0, 0);
}

int study_row_finish(const study_job *job, const study_figure *f, int k, int j, const void *row,
                     size_t size, const double *extra, size_t nextra, int stored)
{
    study_rows *r = job->rows;
    if (!r) return CONSPH_OK;
    if (!stored && row) {
        char path[STUDY_PATH_MAX];
        consph_outfile of;
        int rc = row_path(path, job, f, k, j);
        if (rc == CONSPH_OK) rc = consph_outfile_open(&of, path);
        if (rc) return rc;
        fprintf(of.fp, "%s\n%llu %llu\n", ROW_MAGIC, (unsigned long long)size,
                (unsigned long long)nextra);
        fwrite(row, 1, size, of.fp);
        if (nextra) fwrite(extra, sizeof *extra, nextra, of.fp);
        if ((rc = consph_outfile_commit(&of))) return rc;
        /* From the first kept row on, a signal (a second SIGINT, SIGHUP) leaves the directory
         * and its rows for --resume; a failure still removes it (study_remove_created). */
        consph_made_dir_unregister();
    }
    r->done++;
    r->work_done += r->row_work;
    if (r->shared) {
        r->shared_done = __atomic_add_fetch(&r->shared->done, 1, __ATOMIC_RELAXED);
        __atomic_add_fetch(&r->shared->work_done, llround(r->row_work), __ATOMIC_RELAXED);
    }
    if (!stored) {
        r->run_now++;
        /* a row that packed its layout: its time is the packing's more than its work's */
        if (due_made(r) == r->row_made) {
            r->work_run += r->row_work;
            r->seconds_run += consph_wtime() - r->row_t0;
        }
        if (r->stop_after > 0 && r->run_now == r->stop_after) raise(SIGINT);
    }
    rows_line(r, 1, stored);
    return r->share_size > 1 && r->fig_met >= r->fig_rows ? STUDY_SHARED : CONSPH_OK;
}

void study_rows_flush(study_rows *r)
{
    rows_pass_log(r);
}

int study_rows_stop(const study_job *job)
{
    study_rows *r = job->rows;
    if (!r) return 0;
    if (!r->stopped) r->stopped = consph_stop_requested();
    return r->stopped;
}
