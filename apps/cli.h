/* Declarative option parsing for the consph CLI. Every rejection prints one line naming the
 * command, the option and the allowed values, and the caller exits with status 2. */
#ifndef CONSPH_APPS_CLI_H
#define CONSPH_APPS_CLI_H

#include <stddef.h>

#define CLI_LIST_MAX 64
#define CLI_EXIT_USAGE 2
/* A run whose measured error is not finite: a wrong result (approx and study, in --help). */
#define CLI_EXIT_NONFINITE 3

typedef enum cli_type {
    CLI_FLAG,        /* int: set to 1 */
    CLI_INT,         /* long: integer in [min, max] */
    CLI_DOUBLE,      /* double: finite in [min, max] */
    CLI_STRING,      /* const char *: any non-empty text */
    CLI_CHOICE,      /* int: index into the comma-separated `choices` */
    CLI_INT_LIST,    /* cli_list: comma-separated integers in [min, max] */
    CLI_DOUBLE_LIST, /* cli_list: comma-separated finite numbers in [min, max] */
    CLI_OUT_PATH     /* const char *: a path whose directory exists and is writable */
} cli_type;

typedef struct cli_list {
    int n;
    double v[CLI_LIST_MAX];
} cli_list;

typedef struct cli_opt {
    const char *name; /* "--nx" */
    cli_type type;
    void *dest;
    const char *metavar; /* shown in help, e.g. "N" */
    const char *help;
    const char *choices; /* CLI_CHOICE: "a,b,c"; CLI_OUT_PATH: allowed extensions ".vtu,.csv" */
    double min, max;     /* numeric bounds (inclusive) */
    int given;           /* set by cli_parse */
} cli_opt;

typedef struct cli_command {
    const char *name;    /* "layout" */
    const char *summary; /* one line */
    const char *usage;   /* "consph layout --kind K --dim D --nx N [options]" */
    const char *details; /* free text printed after the options in --help (may be NULL) */
    cli_opt *opts;
    int nopts;
    int npositional; /* positional arguments accepted (0 or more) */
    const char **positional;
} cli_command;

/* Makes stdout a stream that keeps the reason of its first failed write (consph_fdstream), for
 * cli_finish_stdout; line-buffered on a terminal, as before. Call once, before any output. */
void cli_stdout_init(void);
/* Flushes stdout. When any write to it failed, prints "consph[ COMMAND]: cannot write standard
 * output: REASON" and returns 1 if `status` was 0; otherwise returns `status`, so that a command
 * that already failed keeps its own exit status. `command` may be NULL. */
int cli_finish_stdout(const char *command, int status);

/* 1 when files can be written in `dir`, or, when it does not exist yet, in its nearest existing
 * ancestor; else 0 with the reason in `why`. A file is really created, written (a block, so that
 * a full disk fails here rather than after the work) and removed: access() says yes to root on
 * /proc, and a read-only or full file system shows only on writing. */
int cli_dir_writable(const char *dir, char *why, size_t size);
/* cli_dir_writable for the directory `dir` given to `option`: 0, or the rejection naming the
 * option (CLI_EXIT_USAGE). */
int cli_check_out_dir(const cli_command *cmd, const char *option, const char *dir);

/* Parses argv[1..argc) (argv[0] is the command name). Returns 0 on success, 1 when help was
 * printed (exit 0), CLI_EXIT_USAGE after printing an error. */
int cli_parse(cli_command *cmd, int argc, char **argv);
void cli_print_help(const cli_command *cmd);
/* Prints "consph CMD: message" to stderr and returns CLI_EXIT_USAGE. */
int cli_error(const cli_command *cmd, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* Index of `value` in the comma-separated `choices`, or -1. */
int cli_choice_index(const char *choices, const char *value);
/* Copies choice number `index` of `choices` into buf. */
const char *cli_choice_name(const char *choices, int index, char *buf, size_t size);

/* 1 when the comma-separated `text` has no empty item (not "", ",a", "a,", "a,,b"), else 0. */
int cli_list_items_nonempty(const char *text);

struct consph_box;
/* "x0:x1,y0:y1[,z0:z1]" into box->lo/hi/dim (finite bounds, lo < hi, finite length); 0 or -1. */
int cli_parse_box(const char *text, struct consph_box *box);
/* "yes"/"all", "no"/"none", or axis letters such as "x", "xy", "x,z": periodic[a] for axis a;
 * 0 or -1. */
int cli_parse_periodic(const char *text, int periodic[3]);
/* The rejections of those two, one line each naming the option and the allowed values;
 * return CLI_EXIT_USAGE. */
int cli_bad_box(const cli_command *cmd, const char *text);
int cli_bad_periodic(const cli_command *cmd, const char *text);
/* 0 when nx^dim particles can be held; otherwise the rejection naming --nx (CLI_EXIT_USAGE), so
 * that a size the machine cannot hold fails up front instead of at allocation. */
int cli_check_nx(const cli_command *cmd, long nx, long dim);

/* The options of the cache of packed layouts, the same in every command that can generate one
 * (layout, approx, study, run): CLI_CACHE_OPTS(c) in the option table, cli_cache_apply(cmd, &c)
 * once parsed. */
typedef struct cli_cache {
    const char *dir; /* --cache DIR */
    int off;         /* --no-cache */
} cli_cache;
#define CLI_CACHE_OPTS(c)                                                                          \
    {"--cache",                                                                                    \
     CLI_STRING,                                                                                   \
     &(c).dir,                                                                                     \
     "DIR",                                                                                        \
     "directory of the cache of packed layouts (default $XDG_CACHE_HOME/consph, else "             \
     "~/.cache/consph)",                                                                           \
     NULL,                                                                                         \
     0,                                                                                            \
     0,                                                                                            \
     0},                                                                                           \
    {                                                                                              \
        "--no-cache", CLI_FLAG, &(c).off, NULL,                                                    \
            "neither read nor write the cache of packed layouts", NULL, 0, 0, 0                    \
    }
/* Turns the library's layout cache on (--cache DIR, or the default directory) or off
 * (--no-cache, or no default directory: neither XDG_CACHE_HOME nor HOME set). 0, or the
 * rejection naming the option (CLI_EXIT_USAGE). A directory that cannot be written is no error
 * here: the first write warns and the run goes on without the cache. */
int cli_cache_apply(const cli_command *cmd, const cli_cache *c);

struct consph_particles;
struct consph_read_report;
/* After a particle file was read: one line on stderr saying which box and periodicity were
 * assumed, and which options set them, when neither the options (box_given, periodic_given)
 * nor the file did; nothing otherwise. */
void cli_note_read_defaults(const cli_command *cmd, const char *path,
                            const struct consph_particles *p, const struct consph_read_report *rep,
                            int box_given, int periodic_given);
/* Once the dimension is known: rejects --periodic `text` (bad, or naming an axis past `dim`) with
 * one line and CLI_EXIT_USAGE; 0 when it fits. "yes" fits every dimension. */
int cli_check_periodic_dim(const cli_command *cmd, const char *text, int dim);

#endif
