#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "consph/core.h"
#include "consph/io.h"
#include "consph/layout.h"

static consph_fdstream stdout_stream = {STDOUT_FILENO, 0};
static int stdout_wrapped;

void cli_stdout_init(void)
{
    FILE *f = consph_fdstream_open(&stdout_stream, "w");
    /* Without it stdout stays as it was: a failed write is still caught, its reason may not be. */
    if (!f) return;
    setvbuf(f, NULL, isatty(STDOUT_FILENO) ? _IOLBF : _IOFBF, BUFSIZ);
    fflush(stdout);
    stdout = f;
    stdout_wrapped = 1;
}

int cli_finish_stdout(const char *command, int status)
{
    errno = 0;
    if (fflush(stdout) == 0 && !ferror(stdout)) return status;
    int e = stdout_wrapped && stdout_stream.err ? stdout_stream.err : errno;
    fprintf(stderr, "consph%s%s: cannot write standard output: %s\n", command ? " " : "",
            command ? command : "", e ? strerror(e) : "a write failed");
    return status ? status : 1;
}

int cli_error(const cli_command *cmd, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "consph %s: ", cmd->name);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    return CLI_EXIT_USAGE;
}

int cli_dir_writable(const char *dir, char *why, size_t size)
{
    size_t cap = strlen(dir) + 64;
    char *path = malloc(cap);
    if (!path) {
        snprintf(why, size, "out of memory");
        return 0;
    }
    snprintf(path, cap, "%s", *dir ? dir : ".");
    int ok = 0;
    for (;;) {
        struct stat st;
        if (stat(path, &st) == 0) {
            if (!S_ISDIR(st.st_mode)) {
                snprintf(why, size, "'%.200s' is not a directory", path);
                break;
            }
            size_t len = strlen(path);
            snprintf(path + len, cap - len, "/.consph-probe-XXXXXX");
            int fd = mkstemp(path), e = fd < 0 ? errno : 0;
            if (fd >= 0) {
                static const char block[4096];
                ssize_t w = write(fd, block, sizeof block);
                if (w != (ssize_t)sizeof block) e = w < 0 ? errno : ENOSPC;
                if (close(fd) != 0 && !e) e = errno;
                unlink(path);
            }
            path[len] = '\0';
            if (e) snprintf(why, size, "cannot create files in '%.200s': %s", path, strerror(e));
            ok = !e;
            break;
        }
        char *slash = strrchr(path, '/');
        if (!slash)
            snprintf(path, cap, ".");
        else if (slash == path)
            path[1] = '\0';
        else
            *slash = '\0';
    }
    free(path);
    return ok;
}

int cli_check_out_dir(const cli_command *cmd, const char *option, const char *dir)
{
    char why[512];
    if (cli_dir_writable(dir, why, sizeof why)) return 0;
    return cli_error(cmd, "option %s: cannot write results under '%.200s%s': %s", option, dir,
                     strlen(dir) > 200 ? "..." : "", why);
}

int cli_choice_index(const char *choices, const char *value)
{
    size_t len = strlen(value);
    int idx = 0;
    const char *s = choices;
    while (*s) {
        const char *e = strchr(s, ',');
        size_t n = e ? (size_t)(e - s) : strlen(s);
        if (n == len && strncmp(s, value, n) == 0) return idx;
        if (!e) break;
        s = e + 1;
        ++idx;
    }
    return -1;
}

const char *cli_choice_name(const char *choices, int index, char *buf, size_t size)
{
    const char *s = choices;
    for (int k = 0; k < index && s; ++k) {
        s = strchr(s, ',');
        if (s) ++s;
    }
    buf[0] = '\0';
    if (!s) return buf;
    const char *e = strchr(s, ',');
    size_t n = e ? (size_t)(e - s) : strlen(s);
    if (n >= size) n = size - 1;
    memcpy(buf, s, n);
    buf[n] = '\0';
    return buf;
}

static const char *type_word(const cli_opt *o)
{
    switch (o->type) {
    case CLI_INT:
    case CLI_INT_LIST:
        return "integer";
    default:
        return "number";
    }
}

static void describe_range(const cli_opt *o, char *buf, size_t size)
{
    if (o->type == CLI_INT || o->type == CLI_INT_LIST)
        snprintf(buf, size, "%s %.0f..%.0f", type_word(o), o->min, o->max);
    else
        snprintf(buf, size, "%s in [%g, %g]", type_word(o), o->min, o->max);
}

static int parse_number(const cli_command *cmd, const cli_opt *o, const char *text, double *out)
{
    char range[128];
    describe_range(o, range, sizeof range);
    char *end = NULL;
    errno = 0;
    double v;
    if (o->type == CLI_INT || o->type == CLI_INT_LIST) {
        long long iv = strtoll(text, &end, 10);
        v = (double)iv;
    } else {
        v = strtod(text, &end);
    }
    if (end == text || *end != '\0' || errno == ERANGE || !isfinite(v))
        return cli_error(cmd, "option %s: '%s' is not a valid %s; allowed: %s", o->name, text,
                         type_word(o), range);
    if (v < o->min || v > o->max)
        return cli_error(cmd, "option %s: %s is out of range; allowed: %s", o->name, text, range);
    *out = v;
    return 0;
}

static int parse_value(const cli_command *cmd, cli_opt *o, const char *text)
{
    double v;
    switch (o->type) {
    case CLI_FLAG:
        *(int *)o->dest = 1;
        return 0;
    case CLI_INT:
        if (parse_number(cmd, o, text, &v)) return CLI_EXIT_USAGE;
        *(long *)o->dest = (long)v;
        return 0;
    case CLI_DOUBLE:
        if (parse_number(cmd, o, text, &v)) return CLI_EXIT_USAGE;
        *(double *)o->dest = v;
        return 0;
    case CLI_STRING:
        if (!*text) return cli_error(cmd, "option %s: empty value", o->name);
        *(const char **)o->dest = text;
        return 0;
    case CLI_CHOICE: {
        int idx = cli_choice_index(o->choices, text);
        if (idx < 0)
            return cli_error(cmd, "option %s: unknown value '%s'; allowed: %s", o->name, text,
                             o->choices);
        *(int *)o->dest = idx;
        return 0;
    }
    case CLI_INT_LIST:
    case CLI_DOUBLE_LIST: {
        cli_list *l = o->dest;
        l->n = 0;
        char range[128], item[128];
        describe_range(o, range, sizeof range);
        if (!cli_list_items_nonempty(text))
            return cli_error(cmd,
                             "option %s: '%s' has an empty item; allowed: comma-separated, each %s",
                             o->name, text, range);
        /* Split by hand: strtok would skip the empty item of "10,,20". */
        for (const char *t = text;; ++t) {
            const char *comma = strchr(t, ',');
            size_t n = comma ? (size_t)(comma - t) : strlen(t);
            if (l->n == CLI_LIST_MAX)
                return cli_error(cmd, "option %s: at most %d values", o->name, CLI_LIST_MAX);
            if (n >= sizeof item)
                return cli_error(cmd, "option %s: item %d is too long; allowed: %s", o->name,
                                 l->n + 1, range);
            memcpy(item, t, n);
            item[n] = '\0';
            if (parse_number(cmd, o, item, &l->v[l->n])) return CLI_EXIT_USAGE;
            l->n++;
            if (!comma) return 0;
            t = comma;
        }
    }
    case CLI_OUT_PATH: {
        if (o->choices) {
            const char *dot = strrchr(text, '.');
            if (!dot || cli_choice_index(o->choices, dot) < 0)
                return cli_error(cmd, "option %s: '%s' has an unsupported extension; allowed: %s",
                                 o->name, text, o->choices);
        }
        if (consph_path_writable(text) != 0)
            return cli_error(cmd, "option %s: cannot write '%s': %s", o->name, text,
                             consph_last_error());
        /* The directory is probed too: consph_path_writable trusts access(). */
        const char *slash = strrchr(text, '/');
        size_t dlen = !slash ? 0 : slash == text ? 1 : (size_t)(slash - text);
        char why[512], *dir = dlen ? strndup(text, dlen) : strdup(".");
        if (!dir) return cli_error(cmd, "option %s: out of memory", o->name);
        int ok = cli_dir_writable(dir, why, sizeof why);
        free(dir);
        if (!ok) return cli_error(cmd, "option %s: cannot write '%s': %s", o->name, text, why);
        *(const char **)o->dest = text;
        return 0;
    }
    }
    return cli_error(cmd, "option %s: internal error (unknown type)", o->name);
}

void cli_print_help(const cli_command *cmd)
{
    printf("usage: %s\n\n%s\n", cmd->usage, cmd->summary);
    if (cmd->nopts) printf("\noptions:\n");
    for (int k = 0; k < cmd->nopts; ++k) {
        const cli_opt *o = &cmd->opts[k];
        char head[96];
        snprintf(head, sizeof head, "%s%s%s", o->name, o->metavar ? " " : "",
                 o->metavar ? o->metavar : "");
        printf("  %-26s %s", head, o->help);
        char range[128];
        switch (o->type) {
        case CLI_CHOICE:
            printf(" (one of: %s)", o->choices);
            break;
        case CLI_INT:
        case CLI_DOUBLE:
        case CLI_INT_LIST:
        case CLI_DOUBLE_LIST:
            describe_range(o, range, sizeof range);
            printf(" (%s%s)", o->type >= CLI_INT_LIST ? "comma-separated, each " : "", range);
            break;
        case CLI_OUT_PATH:
            if (o->choices) printf(" (extension: %s)", o->choices);
            break;
        default:
            break;
        }
        printf("\n");
    }
    printf("  %-26s %s\n", "--help", "show this help and exit");
    if (cmd->details) printf("\n%s\n", cmd->details);
}

int cli_parse(cli_command *cmd, int argc, char **argv)
{
    int npos = 0;
    for (int k = 0; k < cmd->nopts; ++k) cmd->opts[k].given = 0;
    for (int a = 1; a < argc; ++a) {
        const char *arg = argv[a];
        if (strcmp(arg, "--help") == 0 || strcmp(arg, "-h") == 0) {
            cli_print_help(cmd);
            return 1;
        }
        if (strncmp(arg, "--", 2) != 0) {
            if (npos < cmd->npositional) {
                cmd->positional[npos++] = arg;
                continue;
            }
            return cli_error(cmd, "unexpected argument '%s'; see 'consph %s --help'", arg,
                             cmd->name);
        }
        char name[64];
        const char *eq = strchr(arg, '=');
        size_t nlen = eq ? (size_t)(eq - arg) : strlen(arg);
        if (nlen >= sizeof name) nlen = sizeof name - 1;
        memcpy(name, arg, nlen);
        name[nlen] = '\0';
        cli_opt *o = NULL;
        for (int k = 0; k < cmd->nopts; ++k)
            if (strcmp(cmd->opts[k].name, name) == 0) o = &cmd->opts[k];
        if (!o) {
            char allowed[2048] = "";
            for (int k = 0; k < cmd->nopts; ++k) {
                strncat(allowed, cmd->opts[k].name, sizeof allowed - strlen(allowed) - 3);
                strncat(allowed, ", ", sizeof allowed - strlen(allowed) - 1);
            }
            strncat(allowed, "--help", sizeof allowed - strlen(allowed) - 1);
            return cli_error(cmd, "unknown option '%s'; allowed: %s", name, allowed);
        }
        if (o->given) return cli_error(cmd, "option %s given twice", o->name);
        o->given = 1;
        if (o->type == CLI_FLAG) {
            if (eq) return cli_error(cmd, "option %s takes no value", o->name);
            *(int *)o->dest = 1;
            continue;
        }
        const char *value = eq ? eq + 1 : NULL;
        if (!value) {
            if (a + 1 >= argc) return cli_error(cmd, "option %s needs a value", o->name);
            value = argv[++a];
        }
        int rc = parse_value(cmd, o, value);
        if (rc) return rc;
    }
    for (int k = npos; k < cmd->npositional; ++k) cmd->positional[k] = NULL;
    return 0;
}

int cli_list_items_nonempty(const char *text)
{
    size_t len = strlen(text);
    return len && text[0] != ',' && text[len - 1] != ',' && !strstr(text, ",,");
}

int cli_parse_box(const char *text, consph_box *box)
{
    memset(box, 0, sizeof *box);
    char buf[512];
    size_t len = strlen(text);
    /* strtok below would skip an empty item: ",0:1" and "0:1,,0:1" are not boxes. */
    if (len >= sizeof buf || !cli_list_items_nonempty(text)) return -1;
    strcpy(buf, text);
    char *save = NULL;
    for (char *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        char *colon = strchr(t, ':'), *end;
        if (box->dim == CONSPH_MAX_DIM || !colon) return -1;
        *colon = '\0';
        double lo = strtod(t, &end);
        if (end == t || *end) return -1;
        double hi = strtod(colon + 1, &end);
        if (end == colon + 1 || *end || !isfinite(lo) || !isfinite(hi) || !(lo < hi) ||
            !isfinite(hi - lo))
            return -1;
        box->lo[box->dim] = lo;
        box->hi[box->dim] = hi;
        box->dim++;
    }
    return box->dim ? 0 : -1;
}

int cli_parse_periodic(const char *text, int periodic[3])
{
    for (int a = 0; a < CONSPH_MAX_DIM; ++a) periodic[a] = 0;
    if (!strcmp(text, "yes") || !strcmp(text, "all")) {
        for (int a = 0; a < CONSPH_MAX_DIM; ++a) periodic[a] = 1;
        return 0;
    }
    if (!strcmp(text, "no") || !strcmp(text, "none")) return 0;
    if (!cli_list_items_nonempty(text)) return -1;
    int any = 0;
    for (const char *c = text; *c; ++c) {
        if (*c == ',') continue;
        int a = *c == 'x' ? 0 : *c == 'y' ? 1 : *c == 'z' ? 2 : -1;
        if (a < 0 || periodic[a]) return -1;
        periodic[a] = any = 1;
    }
    return any ? 0 : -1;
}

int cli_bad_box(const cli_command *cmd, const char *text)
{
    return cli_error(cmd,
                     "option --box: '%s' is not a box; allowed: x0:x1,y0:y1[,z0:z1] with finite "
                     "x0 < x1",
                     text);
}

int cli_bad_periodic(const cli_command *cmd, const char *text)
{
    return cli_error(cmd,
                     "option --periodic: unknown value '%s'; allowed: yes, no, or the periodic "
                     "axes (e.g. x, xy, x,z)",
                     text);
}

/* Larger sets exhaust memory long before anything useful happens. */
#define CLI_MAX_PARTICLES 100000000.0

int cli_check_nx(const cli_command *cmd, long nx, long dim)
{
    double total = 1.0;
    for (long a = 0; a < dim; ++a) total *= (double)nx;
    if (total > CLI_MAX_PARTICLES)
        return cli_error(cmd,
                         "option --nx: %ld^%ld = %.0f particles is too many; allowed: at most "
                         "%.0f particles in all",
                         nx, dim, total, CLI_MAX_PARTICLES);
    return 0;
}

void cli_note_read_defaults(const cli_command *cmd, const char *path, const consph_particles *p,
                            const consph_read_report *rep, int box_given, int periodic_given)
{
    /* The reader takes the box and periodicity from the options, else from the file, else (for
     * the periodicity) none: say so when nothing set it, since it changes every result. */
    const int box_assumed = !box_given && !rep->box_from_file;
    const int periodic_assumed = !periodic_given && !rep->periodic_from_file;
    if (!box_assumed && !periodic_assumed) return;
    char box[160] = "";
    size_t len = 0;
    for (int a = 0; a < p->dim && len < sizeof box; ++a)
        len += (size_t)snprintf(box + len, sizeof box - len, "%s[%g, %g]", a ? "x" : "",
                                p->box.lo[a], p->box.hi[a]);
    static const char axis[] = "xyz";
    char per[8] = "";
    for (int a = 0, k = 0; a < p->dim; ++a)
        if (p->box.periodic[a]) per[k++] = axis[a];
    fprintf(stderr,
            "consph %s: note: %s gives no %s%s%s: using box %s (%s), periodic %s (%s); --box "
            "x0:x1,... and --periodic yes|no|AXES set them\n",
            cmd->name, path, box_assumed ? "box" : "",
            box_assumed && periodic_assumed ? " and no " : "",
            periodic_assumed ? "periodicity ('# periodic' line or VTU field 'periodic')" : "", box,
            box_assumed ? "assumed"
            : box_given ? "--box"
                        : "from the file",
            per[0] ? per : "none", periodic_assumed ? "assumed" : "--periodic");
}
int cli_check_periodic_dim(const cli_command *cmd, const char *text, int dim)
{
    int periodic[CONSPH_MAX_DIM];
    if (cli_parse_periodic(text, periodic)) return cli_bad_periodic(cmd, text);
    if (!strcmp(text, "yes") || !strcmp(text, "all")) return 0;
    for (int a = dim; a < CONSPH_MAX_DIM; ++a)
        if (periodic[a])
            return cli_error(cmd,
                             "option --periodic: axis %c, but the particles are %dD; allowed: "
                             "yes, no, or axes among %.*s",
                             "xyz"[a], dim, dim, "xyz");
    return 0;
}

int cli_cache_apply(const cli_command *cmd, const cli_cache *c)
{
    if (c->off && c->dir)
        return cli_error(cmd, "options --cache and --no-cache contradict each other: give one");
    if (c->off) {
        consph_layout_cache_set(NULL);
        return 0;
    }
    char dir[4096];
    const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    int k = -1;
    if (c->dir)
        k = snprintf(dir, sizeof dir, "%s", c->dir);
    else if (xdg && xdg[0] == '/') /* the XDG rule: a relative path is ignored */
        k = snprintf(dir, sizeof dir, "%s/consph", xdg);
    else if (home && *home)
        k = snprintf(dir, sizeof dir, "%s/.cache/consph", home);
    if (k < 0) {
        consph_layout_cache_set(NULL);
        return 0;
    }
    if ((size_t)k >= sizeof dir || consph_layout_cache_set(dir) != 0)
        return cli_error(cmd, "option --cache: the directory name is too long (at most %d bytes)",
                         4000);
    return 0;
}
