/* The fuzz entry point of the CLI option parsers (apps/cli.c), shared by the libFuzzer target
 * fuzz/fuzz_cli.c (built by `make fuzz`) and by tests/test_cli_parse.c, which replays the seed
 * corpus and every crash kept in fuzz/regressions/cli/ in the normal (and sanitized) test build.
 *
 * The input is an argument list, one argument per line. It goes through cli_parse with an option
 * of every type, and each argument goes on its own through the list, box and periodic parsers.
 * Whatever the input, a parser either rejects it (status 2, or -1 for the box and periodic
 * parsers) or yields values that satisfy its contract; anything else aborts. */
#ifndef CONSPH_FUZZ_CLI_H
#define CONSPH_FUZZ_CLI_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "consph/core.h"

#define FUZZ_CLI_MAX_ARGS 24

static inline void fuzz_cli_require(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "fuzz invariant violated: %s\n", what);
        abort();
    }
}

static inline int fuzz_cli_commas(const char *s)
{
    int n = 0;
    for (; *s; ++s) n += *s == ',';
    return n;
}

/* The contract of a list that was accepted: one value per comma-separated item, each the number
 * its item spells, in range. */
static inline void fuzz_cli_check_list(const cli_opt *o, const char *text)
{
    const cli_list *l = o->dest;
    fuzz_cli_require(l->n >= 1 && l->n <= CLI_LIST_MAX, "list length in 1..CLI_LIST_MAX");
    fuzz_cli_require(l->n == fuzz_cli_commas(text) + 1, "one value per item, no empty item");
    const char *t = text;
    for (int k = 0; k < l->n; ++k) {
        char *end;
        double v = o->type == CLI_INT_LIST ? (double)strtoll(t, &end, 10) : strtod(t, &end);
        fuzz_cli_require(end > t && (*end == ',' || *end == '\0'), "each item is a number");
        fuzz_cli_require(v == l->v[k], "the value its item spells");
        fuzz_cli_require(isfinite(v) && v >= o->min && v <= o->max, "list value in range");
        t = *end ? end + 1 : end;
    }
}

/* A one-option command on `text` alone. */
static inline void fuzz_cli_list(cli_type type, const char *text)
{
    cli_list l;
    cli_opt o = {"--list", type, &l, "N", "", NULL, 2, 1e5, 0};
    cli_command cmd = {"fuzz", "", "", NULL, &o, 1, 0, NULL};
    char *argv[] = {"fuzz", "--list", (char *)text, NULL};
    int rc = cli_parse(&cmd, 3, argv);
    fuzz_cli_require(rc == 0 || rc == 1 || rc == CLI_EXIT_USAGE, "status 0, 1 or 2");
    if (rc == 0) fuzz_cli_check_list(&o, text);
    if (rc == 0) fuzz_cli_require(cli_list_items_nonempty(text), "an accepted list has no gap");
}

static inline void fuzz_cli_one(const char *text)
{
    fuzz_cli_list(CLI_INT_LIST, text);
    fuzz_cli_list(CLI_DOUBLE_LIST, text);

    /* cli_list_items_nonempty against its definition. */
    size_t len = strlen(text);
    int gap = len == 0 || text[0] == ',' || text[len - 1] == ',' || strstr(text, ",,") != NULL;
    fuzz_cli_require(cli_list_items_nonempty(text) == !gap, "items_nonempty as defined");

    consph_box box;
    if (cli_parse_box(text, &box) == 0) {
        fuzz_cli_require(box.dim >= 1 && box.dim <= CONSPH_MAX_DIM, "box dimension in 1..3");
        fuzz_cli_require(box.dim == fuzz_cli_commas(text) + 1, "one axis per item");
        for (int a = 0; a < box.dim; ++a)
            fuzz_cli_require(isfinite(box.lo[a]) && isfinite(box.hi[a]) && box.lo[a] < box.hi[a] &&
                                 isfinite(box.hi[a] - box.lo[a]),
                             "finite lo < hi");
    }

    int periodic[CONSPH_MAX_DIM];
    cli_command cmd = {"fuzz", "", "", NULL, NULL, 0, 0, NULL};
    int all = !strcmp(text, "yes") || !strcmp(text, "all");
    if (cli_parse_periodic(text, periodic) == 0) {
        fuzz_cli_require(!gap, "periodic axes without an empty item");
        for (int dim = 1; dim <= CONSPH_MAX_DIM; ++dim) {
            int beyond = 0;
            for (int a = dim; a < CONSPH_MAX_DIM; ++a) beyond |= periodic[a];
            int rc = cli_check_periodic_dim(&cmd, text, dim);
            fuzz_cli_require(rc == ((beyond && !all) ? CLI_EXIT_USAGE : 0),
                             "an axis past the dimension is rejected, and only that");
        }
        for (int a = 0; a < CONSPH_MAX_DIM; ++a)
            fuzz_cli_require(periodic[a] == 0 || periodic[a] == 1, "periodic flags are 0 or 1");
    } else {
        fuzz_cli_require(cli_check_periodic_dim(&cmd, text, 3) == CLI_EXIT_USAGE,
                         "a bad value is rejected at every dimension");
    }

    static const char choices[] = "a,bb,ccc";
    int idx = cli_choice_index(choices, text);
    fuzz_cli_require(idx >= -1 && idx <= 2, "choice index in -1..2");
    if (idx >= 0) {
        char name[8];
        fuzz_cli_require(!strcmp(cli_choice_name(choices, idx, name, sizeof name), text),
                         "the choice named by its index");
    }
}

static inline int consph_fuzz_cli(const uint8_t *data, size_t size)
{
    char *buf = malloc(size + 1);
    if (!buf) return 0;
    memcpy(buf, data, size);
    buf[size] = '\0';
    char *argv[FUZZ_CLI_MAX_ARGS + 2] = {"fuzz"};
    int argc = 1;
    for (char *s = buf; argc <= FUZZ_CLI_MAX_ARGS;) {
        char *nl = strchr(s, '\n');
        if (nl) *nl = '\0';
        argv[argc++] = s;
        if (!nl) break;
        s = nl + 1;
    }
    for (int k = 1; k < argc; ++k) fuzz_cli_one(argv[k]);

    long i = -1;
    double d = NAN;
    cli_list il = {0}, dl = {0};
    int choice = -1, flag = 0;
    const char *str = NULL, *out = NULL, *pos[2] = {NULL, NULL};
    cli_opt opts[] = {
        {"--i", CLI_INT, &i, "N", "", NULL, 1, 100000, 0},
        {"--d", CLI_DOUBLE, &d, "X", "", NULL, -10, 10, 0},
        {"--il", CLI_INT_LIST, &il, "N,N", "", NULL, 2, 100000, 0},
        {"--dl", CLI_DOUBLE_LIST, &dl, "X,X", "", NULL, 0, 1e6, 0},
        {"--c", CLI_CHOICE, &choice, "C", "", "a,bb,ccc", 0, 0, 0},
        {"--s", CLI_STRING, &str, "S", "", NULL, 0, 0, 0},
        {"--f", CLI_FLAG, &flag, NULL, "", NULL, 0, 0, 0},
        {"--o", CLI_OUT_PATH, &out, "FILE", "", ".vtu,.csv", 0, 0, 0},
    };
    cli_command cmd = {"fuzz", "", "", NULL, opts, (int)(sizeof opts / sizeof opts[0]), 2, pos};
    int rc = cli_parse(&cmd, argc, argv);
    fuzz_cli_require(rc == 0 || rc == 1 || rc == CLI_EXIT_USAGE, "status 0, 1 or 2");
    if (rc == 0) {
        if (opts[0].given) fuzz_cli_require(i >= 1 && i <= 100000, "--i in range");
        if (opts[1].given) fuzz_cli_require(isfinite(d) && d >= -10 && d <= 10, "--d in range");
        for (int k = 2; k <= 3; ++k) {
            const cli_list *l = opts[k].dest;
            if (!opts[k].given) continue;
            fuzz_cli_require(l->n >= 1 && l->n <= CLI_LIST_MAX, "list length");
            for (int j = 0; j < l->n; ++j)
                fuzz_cli_require(l->v[j] >= opts[k].min && l->v[j] <= opts[k].max &&
                                     (k == 3 || l->v[j] == floor(l->v[j])),
                                 "list value in range");
        }
        if (opts[4].given) fuzz_cli_require(choice >= 0 && choice <= 2, "--c a valid index");
        if (opts[5].given) fuzz_cli_require(str && *str, "--s non-empty");
        if (opts[6].given) fuzz_cli_require(flag == 1, "--f set");
        if (opts[7].given) {
            const char *dot = out ? strrchr(out, '.') : NULL;
            fuzz_cli_require(dot && (!strcmp(dot, ".vtu") || !strcmp(dot, ".csv")),
                             "--o has an allowed extension");
        }
    }
    free(buf);
    return 0;
}

#endif
