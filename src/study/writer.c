/* The one writer every study kind shares: output paths and atomic files, the markdown report's
 * head and published values, CSV labels, gnuplot scripts (quoting, head) and their drawing into
 * SVG, the output directory and the study README. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
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

/* After a failed run: the directories it created go, with what it wrote into them. */
void study_remove_created(const char *dir, size_t created)
{
    if (!created) return;
    DIR *d = opendir(dir);
    if (d) {
        struct dirent *e;
        char path[STUDY_PATH_MAX];
        while ((e = readdir(d)))
            if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..") &&
                study_out_path(path, dir, e->d_name, "") == CONSPH_OK)
                remove(path);
        closedir(d);
    }
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

/* The head of every figure script: SVG into `outfile` (ID.svg unless the caller sets it, so the
 * script also runs by hand) and a title. */
int study_gp_head(FILE *o, const char *id, const char *title)
{
    fprintf(o,
            "set terminal svg size 900,640 dynamic\nif (!exists('outfile')) outfile = '%s.svg'\n"
            "set output outfile\nset title ",
            id);
    int rc = study_gp_put(o, title);
    fprintf(o, " noenhanced\nset grid\nset key outside right noenhanced\n");
    return rc;
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
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) continue;
    consph_child_unregister(pid);
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
