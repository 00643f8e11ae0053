/* The study-file parser on hostile input: names that become file names, duplicate
 * sections, bytes a line cannot hold; the timing repeats behind T_r; and a replay of the study
 * fuzz corpus and of every crash kept in fuzz/regressions/study/. */
#include <dirent.h>
#include <stdlib.h>
#include <string.h>

#include "../fuzz/fuzz_study.h"
#include "check.h"

/* Parses `text`; returns the status and leaves the message in consph_last_error(). */
static int parse(const char *text, size_t size)
{
    consph_study *s = NULL;
    int rc = study_parse("t.study", text, size, &s);
    consph_study_free(s);
    return rc;
}

static void expect_error(const char *text, const char *message)
{
    int rc = parse(text, strlen(text));
    CHECK(rc == CONSPH_EFORMAT, "'%s' accepted", text);
    CHECK(strstr(consph_last_error(), message) != NULL, "'%s': message '%s' lacks '%s'", text,
          consph_last_error(), message);
}

static void test_names(void)
{
    static const char ok[] = "study = a\n[figure f-1_x.2]\nnx = 8\n[series F1 eta=1.5]\n";
    CHECK(parse(ok, strlen(ok)) == CONSPH_OK, "plain names rejected: %s", consph_last_error());
    expect_error("study = a\n[figure ../../escaped]\nnx = 8\n", "t.study:2: figure name");
    expect_error("study = a\n[figure .hidden]\nnx = 8\n", "t.study:2: figure name");
    expect_error("study = a\n[figure a b]\nnx = 8\n", "t.study:2: figure name");
    expect_error("study = a\n[figure a]\n[series x/y]\n", "t.study:3: series name 'x/y'");
    expect_error("study = a\n[figure a]\n[series it's]\n", "t.study:3: series name");
    expect_error("study = ../a\n[figure a]\nnx = 8\n", "t.study:1: study name '../a'");
    char longname[STUDY_NAME_MAX + 32];
    snprintf(longname, sizeof longname, "study = a\n[figure %0*d]\n", STUDY_NAME_MAX + 1, 0);
    expect_error(longname, "t.study:2: figure name");
}

static void test_duplicates(void)
{
    expect_error("study = a\n[figure a]\nnx = 8\n[figure a]\nnx = 9\n",
                 "t.study:4: figure 'a' already defined on line 2");
    expect_error("study = a\n[figure a]\n[series s]\n[series s]\n",
                 "t.study:4: series 's' of figure 'a' already defined on line 3");
    expect_error("study = a\n[figure a]\nnx = 8\nstudy = b\n", "t.study:4: 'study' belongs");
}

static void test_bytes(void)
{
    static const char nul[] = "study = a\n[figure a]\ntitle = x\0y\nnx = 8\n";
    CHECK(parse(nul, sizeof nul - 1) == CONSPH_EFORMAT, "a NUL byte accepted");
    CHECK(strstr(consph_last_error(), "t.study:3: NUL byte") != NULL, "%s", consph_last_error());
    expect_error("study = a\n[figure a]\ntitle = x\033[31m\nnx = 8\n",
                 "t.study:3: control character 0x1b");
    /* A line longer than the limit is refused whole instead of being split into two lines. */
    size_t n = STUDY_LINE_MAX + 64;
    char *text = malloc(n + 64);
    CHECK(text != NULL, "malloc");
    if (!text) return;
    int k = snprintf(text, n + 64, "study = a\n[figure a]\nnx = 8\ntitle = ");
    memset(text + k, 'x', n - (size_t)k);
    snprintf(text + n, 64, "\n");
    expect_error(text, "t.study:4: line longer than");
    free(text);
    /* Windows line ends are blanks, not control characters. */
    static const char crlf[] = "study = a\r\n[figure a]\r\nnx = 8\r\n";
    CHECK(parse(crlf, strlen(crlf)) == CONSPH_OK, "CRLF: %s", consph_last_error());
}

/* Keys no figure would read, lists with holes or repeats, and series without end: each refused with
 * its file:line. */
static void test_ignored_keys(void)
{
    /* Keys read once per figure are refused in a series. */
    expect_error(
        "study = a\n[figure f]\nkind = run\nnx = 8\n[series s]\nscheme = e-c\ntr_ref = s\n",
        "t.study:7: key 'tr_ref' is one per figure");
    expect_error("study = a\n[figure f]\nkind = heat\nnx = 8\n[series s]\nreport = time\n",
                 "t.study:6: key 'report' is one per figure");
    expect_error("study = a\n[figure f]\nnx = 8\n[series s]\nnorm = l2\n",
                 "t.study:5: key 'norm' is one per figure");
    /* Keys of another kind of figure. */
    expect_error("study = a\n[figure f]\nkind = run\nop = grad\nnx = 8\n[series s]\nscheme = e-c\n",
                 "t.study:4: key 'op' does not apply to figure 'f' (kind run)");
    expect_error("study = a\n[figure f]\nkind = heat\nnx = 8\n[series s]\nscheme = e-c\n",
                 "t.study:6: key 'scheme' does not apply to figure 'f' (kind heat)");
    expect_error("study = a\nkind = run\n[figure f]\nseries.op = grad,div\nnx = 8\n",
                 "t.study:4: key 'series.op' does not apply");
    expect_error("study = a\nscheme = e-c\n[figure f]\nnx = 8\n",
                 "t.study:2: key 'scheme' does not apply to any figure of this study");
    expect_error("study = a\n[figure f]\nkind = m0\nnx = 8\n[series a]\n[series b]\n",
                 "t.study:6: figure 'f' (kind m0) has one series");
    /* series.KEY: only on a figure without [series] sections, and only keys a series sets. */
    expect_error("study = a\nseries.kernel = cubic,quintic\n[figure f]\nnx = 8\n",
                 "t.study:2: key 'series.kernel' belongs on a [figure]");
    expect_error("study = a\n[figure f]\nnx = 8\nseries.kernel = cubic,quintic\n[series s]\n",
                 "t.study:4: series.kernel on figure 'f', which has [series] sections (line 5)");
    expect_error("study = a\n[figure f]\nnx = 8\nseries.norm = l1,l2\n",
                 "t.study:4: 'series.norm': 'norm' is not a key a series may set");
    expect_error("study = a\n[figure f]\nnx = 8\nseries.bogus = 1,2\n",
                 "t.study:4: 'series.bogus': 'bogus' is not a key");
    /* Lists: no holes, no repeats (identical labels), a bounded number of series. */
    expect_error("study = a\n[figure f]\nnx = 8\nseries.kernel = cubic,,quintic\n",
                 "t.study:4: series.kernel: value 2 is empty");
    expect_error("study = a\n[figure f]\nnx = 8\nseries.kernel = cubic, quintic,cubic\n",
                 "t.study:4: series.kernel: value 'cubic' given twice (values 1 and 3)");
    char big[4096];
    int k = snprintf(big, sizeof big, "study = a\n[figure f]\nnx = 8\nseries.hdx = 1");
    for (int j = 1; j < 64; ++j) k += snprintf(big + k, sizeof big - (size_t)k, ",1.%02d", j);
    k += snprintf(big + k, sizeof big - (size_t)k, "\nseries.seed = 1");
    for (int j = 2; j <= 5; ++j) k += snprintf(big + k, sizeof big - (size_t)k, ",%d", j);
    snprintf(big + k, sizeof big - (size_t)k, "\n");
    expect_error(big, "t.study:5: the series.KEY lists of figure 'f' make more than 256 series");
    k = snprintf(big, sizeof big, "study = a\n[figure f]\nnx = 8\n");
    for (int j = 0; j <= STUDY_MAX_SERIES && k < (int)sizeof big - 16; ++j)
        k += snprintf(big + k, sizeof big - (size_t)k, "[series %d]\n", j);
    if (k < (int)sizeof big - 16) expect_error(big, "series in figure 'f'");
}

/* Parses and validates `text` (quick); returns the status. */
static int validate(const char *text)
{
    consph_study *s = NULL;
    int rc = study_parse("t.study", text, strlen(text), &s);
    if (rc == CONSPH_OK) rc = consph_study_validate(s, 1);
    consph_study_free(s);
    return rc;
}

static void expect_invalid(const char *text, const char *message)
{
    CHECK(validate(text) == CONSPH_EFORMAT, "'%s' accepted", text);
    CHECK(strstr(consph_last_error(), message) != NULL, "'%s': message '%s' lacks '%s'", text,
          consph_last_error(), message);
}

static void test_validation(void)
{
    expect_invalid("study = a\n[figure f]\nnx = 8,,16\n", "t.study:3: figure 'f', series 'f': "
                                                          "key 'nx': '8,,16' is not a list");
    expect_invalid("study = a\n[figure f]\nnx = 8,16,\n", "key 'nx': '8,16,' is not a list");
    expect_invalid(
        "study = a\n[figure f]\nkind = run\nquick.nx = 8,,16\n[series s]\nscheme = e-c\n",
        "t.study:4:");
    /* A missing required key is reported at its series, not at line 0. */
    expect_invalid("study = a\n[figure f]\nkind = run\nnx = 8\n[series s]\nc0 = 10\n",
                   "t.study:5: figure 'f', series 's': key 'scheme': not given");
    expect_invalid("study = a\n[figure f]\nkind = run\nnx = 8\ntf = 1\n[series s]\nscheme = e-c\n"
                   "steps = 10\n",
                   "t.study:8: figure 'f', series 's': key 'steps': conflicts with 'tf' (line 5)");
    expect_invalid("study = a\n[figure f]\nkind = run\nnx = 8\nquick.tf = 1\nquick.steps = 3\n"
                   "[series s]\nscheme = e-c\n",
                   "key 'quick.steps': conflicts with 'quick.tf' (line 5)");
    expect_invalid("study = a\n[figure f]\nlayout = packed\nperiodic = no\nnx = 8\n",
                   "t.study:4: figure 'f', series 'f': key 'periodic': layout packed needs a "
                   "periodic box");
    CHECK(validate("study = a\n[figure f]\nnx = 8, 16\n") == CONSPH_OK, "%s", consph_last_error());
}

/* The kinds come from one registry: its names list is what `kind` allows, and every kind in it
 * validates a figure of its own (a kind missing from a row or a list would be refused). */
static void test_kind_registry(void)
{
    const char *names = consph_study_kind_names();
    CHECK(strcmp(names, "approx, m0, appc, cauchy, run, heat") == 0, "kinds '%s'", names);
    char expect[160];
    snprintf(expect, sizeof expect, "unknown value 'nope'; allowed: %s", names);
    expect_invalid("study = a\n[figure f]\nkind = nope\nnx = 8\n", expect);
    static const char *const figures[] = {
        "kind = approx\nnx = 8,16\n",
        "kind = m0\nnx = 8,16\n",
        "kind = appc\nnx = 64\nhdelta.values = 0.5,1\n",
        "kind = cauchy\nnx = 8,16,32\n",
        "kind = run\nnx = 8\nsteps = 2\n[series s]\nscheme = e-c\n",
        "kind = heat\nnx = 11\n[series s]\nlaplacian = s4\n",
    };
    for (size_t k = 0; k < sizeof figures / sizeof figures[0]; ++k) {
        char text[256];
        snprintf(text, sizeof text, "study = a\n[figure f]\n%s", figures[k]);
        CHECK(validate(text) == CONSPH_OK, "%s: %s", figures[k], consph_last_error());
    }
}

/* Keys of a cauchy figure that its method or measure does not read are refused at their line;
 * a figure-level one that some series reads is kept. Then the memory, before any work. */
static void test_cauchy_keys(void)
{
    expect_invalid("study = a\nkind = cauchy\n[figure f]\ndim = 1\not_method = exact\n"
                   "directions = 16\nnx = 50,100\n",
                   "t.study:6: figure 'f', series 'f': key 'directions': only with ot_method = "
                   "sliced; ot_method here is exact");
    expect_invalid("study = a\nkind = cauchy\n[figure f]\ndim = 2\not_method = sinkhorn\n"
                   "nx = 8,16\n[series s]\ndirections = 4\n",
                   "t.study:8: figure 'f', series 's': key 'directions': only with ot_method = "
                   "sliced; ot_method here is sinkhorn");
    expect_invalid("study = a\nkind = cauchy\n[figure f]\ndim = 1\not_method = sliced\n"
                   "directions = 16\nnx = 50,100\n",
                   "t.study:6: figure 'f', series 'f': key 'directions': the figure is 1D");
    expect_invalid("study = a\nkind = cauchy\n[figure f]\ndim = 2\nnx = 8,16\n[series p]\n"
                   "grid = 16\n",
                   "t.study:7: figure 'f', series 'p': key 'grid': only with measure = smoothed");
    /* Study level: every cauchy series there compares particles. */
    expect_invalid("study = a\nkind = cauchy\ngrid = 16\n[figure f]\ndim = 2\nnx = 8,16\n",
                   "t.study:3: figure 'f', series 'f': key 'grid': only with measure = smoothed");
    CHECK(validate("study = a\nkind = cauchy\n[figure f]\ndim = 2\nnx = 8,16\ngrid = 16\n"
                   "directions = 8\n[series p]\n[series s]\nmeasure = smoothed\n") == CONSPH_OK,
          "%s", consph_last_error());
    const char *old = getenv("CONSPH_MEMORY_LIMIT");
    setenv("CONSPH_MEMORY_LIMIT", "1M", 1);
    expect_invalid("study = a\nkind = cauchy\n[figure f]\ndim = 2\nnx = 8,16\n[series s]\n"
                   "measure = smoothed\ngrid = 1000\n",
                   "t.study:8: figure 'f', series 's': key 'grid': a comparison needs about");
    expect_invalid("study = a\nkind = cauchy\n[figure f]\ndim = 1\nnx = 50,100000\n",
                   "t.study:5: figure 'f', series 'f': key 'nx': a comparison needs about");
    setenv("CONSPH_MEMORY_LIMIT", "lots", 1);
    CHECK(validate("study = a\nkind = cauchy\n[figure f]\ndim = 1\nnx = 50,100\n") ==
                  CONSPH_EINVAL &&
              strstr(consph_last_error(), "CONSPH_MEMORY_LIMIT='lots' is not a size"),
          "%s", consph_last_error());
    if (old)
        setenv("CONSPH_MEMORY_LIMIT", old, 1);
    else
        unsetenv("CONSPH_MEMORY_LIMIT");
}

/* Every shipped study loads and validates, quick and full: the refusals above must not refuse
 * what the studies/ directory uses. */
static void test_shipped_studies(const char *root)
{
    char dir[1100];
    snprintf(dir, sizeof dir, "%s/studies", root);
    DIR *d = opendir(dir);
    CHECK(d != NULL, "%s missing", dir);
    if (!d) return;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        size_t len = strlen(e->d_name);
        if (len < 7 || strcmp(e->d_name + len - 6, ".study") != 0) continue;
        char path[2400];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        consph_study *s = NULL;
        CHECK(consph_study_load(path, &s) == CONSPH_OK, "%s", consph_last_error());
        for (int quick = 0; s && quick < 2; ++quick)
            CHECK(consph_study_validate(s, quick) == CONSPH_OK, "%s", consph_last_error());
        consph_study_free(s);
        ++n;
    }
    closedir(d);
    CHECK(n >= 20, "%d shipped studies", n);
}

/* Timing repeats (T_r's median) change the seconds and nothing else. */
static void test_timing_runs(void)
{
    consph_approx_spec sp = consph_approx_defaults(2);
    CHECK(sp.timing_runs == 1, "default timing_runs %d", sp.timing_runs);
    CHECK(consph_op_parse("grad", "asym", "bc", 2, &sp.op) == CONSPH_OK, "%s", consph_last_error());
    sp.layout = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, 2, 10);
    sp.layout.box = consph_box_unit(2, 1);
    consph_approx_row one, five;
    CHECK(consph_approx_run(&sp, 16, &one) == CONSPH_OK, "%s", consph_last_error());
    sp.timing_runs = 5;
    CHECK(consph_approx_run(&sp, 16, &five) == CONSPH_OK, "%s", consph_last_error());
    CHECK(memcmp(&one.err, &five.err, sizeof one.err) == 0, "errors differ with timing runs");
    CHECK(one.ft_over_fmax == five.ft_over_fmax && one.nbr_mean == five.nbr_mean &&
              one.fallbacks == five.fallbacks && one.h == five.h && one.n == five.n,
          "row differs with timing runs");
    CHECK(five.seconds > 0 && isfinite(five.seconds), "median time %g", five.seconds);
}

static unsigned char *load(const char *path, size_t *size)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    unsigned char *data = NULL;
    if (fseek(fp, 0, SEEK_END) == 0) {
        long len = ftell(fp);
        rewind(fp);
        data = len >= 0 ? malloc((size_t)len + 1) : NULL;
        *size = data ? fread(data, 1, (size_t)len, fp) : 0;
    }
    fclose(fp);
    return data;
}

/* The seed corpus (the shipped studies) and every kept crash through the fuzz entry point. */
static void test_fuzz_replay(const char *root)
{
    static const char *const dirs[] = {"fuzz/corpus/study", "fuzz/regressions/study"};
    int replayed = 0;
    for (int k = 0; k < 2; ++k) {
        char dir[1200];
        snprintf(dir, sizeof dir, "%s/%s", root, dirs[k]);
        DIR *d = opendir(dir);
        CHECK(d || k == 1, "seed corpus %s missing", dir);
        if (!d) continue;
        struct dirent *e;
        while ((e = readdir(d))) {
            if (e->d_name[0] == '.') continue;
            char path[2400];
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            size_t size = 0;
            unsigned char *data = load(path, &size);
            if (!data) continue;
            consph_fuzz_study(data, size);
            /* The shipped studies themselves parse and validate. */
            if (k == 0) {
                consph_study *s;
                CHECK(study_parse(path, (const char *)data, size, &s) == CONSPH_OK, "%s",
                      consph_last_error());
                CHECK(s && consph_study_validate(s, 1) == CONSPH_OK, "%s", consph_last_error());
                consph_study_free(s);
            }
            free(data);
            ++replayed;
        }
        closedir(d);
    }
    CHECK(replayed >= 11, "replayed %d study files", replayed);
    printf("replayed %d study fuzz corpus and regression files\n", replayed);
}

int main(void)
{
    test_names();
    test_duplicates();
    test_bytes();
    test_timing_runs();
    /* This file is tests/test_studyfile.c in the source tree. */
    char root[1024];
    snprintf(root, sizeof root, "%s", __FILE__);
    char *tests = strstr(root, "/tests/test_studyfile.c");
    if (tests)
        *tests = '\0';
    else
        snprintf(root, sizeof root, "..");
    test_ignored_keys();
    test_validation();
    test_kind_registry();
    test_cauchy_keys();
    test_fuzz_replay(root);
    test_shipped_studies(root);
    return check_summary("test_studyfile");
}
