/* The diagnostics' cadence (log_every, src/solver/diag.c): the solution does not depend on it
 * (final particles bit for bit for K = 1 and K = 7, the authors' measure too), the history holds
 * t = 0, the multiples of K, every snapshot and the last step and nothing else, a restart from a
 * checkpoint between samples writes the log and summary of the uninterrupted run byte for byte,
 * and a checkpoint of format 3 (every step sampled) still restores. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "consph/io.h"
#include "consph/solver.h"

static consph_run_params params(const char *scheme, int log_every)
{
    consph_run_params p;
    consph_run_params_default(&p);
    snprintf(p.scheme, sizeof p.scheme, "%s", scheme);
    p.nx = 16;
    p.steps = 23;
    p.tf = 0.0;
    p.ipst_every = 4;
    p.log_every = log_every;
    return p;
}

static int run_steps(consph_solver *s)
{
    while (!consph_solver_done(s)) {
        int st = consph_solver_step(s);
        if (st != CONSPH_OK) return st;
    }
    return CONSPH_OK;
}

static int same_double(double a, double b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

/* K = 1 and K = 7 step the same particles; the history of K = 7 is steps 0, 7, 14, 21 and 23
 * (the last), each row equal to K = 1's row of that step; the authors' measure, sampled at its
 * own output times, is the same. */
static void test_cadence(const char *scheme)
{
    consph_solver *s[2] = {NULL, NULL};
    const int ks[2] = {1, 7};
    for (int k = 0; k < 2; ++k) {
        consph_run_params p = params(scheme, ks[k]);
        p.error = CONSPH_ERROR_AUTHORS;
        p.error_times = 5;
        int st = consph_solver_create(&s[k], &p);
        if (st == CONSPH_OK) st = run_steps(s[k]);
        CHECK(st == CONSPH_OK, "%s, K = %d: %s", scheme, ks[k], consph_last_error());
        if (st != CONSPH_OK) goto done;
    }
    CHECK(check_particles_equal(consph_solver_particles(s[0]), consph_solver_particles(s[1])),
          "%s: the final particles of K = 1 and K = 7 differ", scheme);
    static const long want[] = {0, 7, 14, 21, 23};
    const size_t nw = sizeof want / sizeof want[0];
    CHECK(consph_solver_history_size(s[0]) == 24, "%s: K = 1 has %zu rows", scheme,
          consph_solver_history_size(s[0]));
    CHECK(consph_solver_history_size(s[1]) == nw, "%s: K = 7 has %zu rows, not %zu", scheme,
          consph_solver_history_size(s[1]), nw);
    for (size_t r = 0; r < nw && r < consph_solver_history_size(s[1]); ++r) {
        consph_step_diag a, b;
        consph_solver_history_row(s[1], r, &b);
        consph_solver_history_row(s[0], (size_t)want[r], &a);
        CHECK(b.step == want[r], "%s: K = 7 row %zu is step %ld, not %ld", scheme, r, b.step,
              want[r]);
        CHECK(same_double(a.t, b.t) && same_double(a.l1_u, b.l1_u) &&
                  same_double(a.linf_p, b.linf_p) && same_double(a.ke, b.ke) &&
                  same_double(a.mom[0], b.mom[0]) && same_double(a.ft_fmax, b.ft_fmax),
              "%s: K = 7's row of step %ld differs from K = 1's", scheme, b.step);
    }
    consph_run_summary a, b;
    consph_solver_summary(s[0], &a);
    consph_solver_summary(s[1], &b);
    CHECK(a.error_samples == 5 && b.error_samples == 5 && same_double(a.l1n_u, b.l1n_u) &&
              same_double(a.l1n_p, b.l1n_p),
          "%s: the authors' measure depends on K: %d %.17g, %d %.17g", scheme, a.error_samples,
          a.l1n_u, b.error_samples, b.l1n_u);
    /* eq. 26 over coarser samples: the same integral to the quadrature's accuracy */
    CHECK(fabs(b.l1_u - a.l1_u) <= 0.3 * a.l1_u && b.l1_u > 0.0, "%s: eq. 26 %g (K = 7) vs %g",
          scheme, b.l1_u, a.l1_u);
done:
    consph_solver_free(s[0]);
    consph_solver_free(s[1]);
}

/* The whole file, or NULL; the line holding "seconds" (wall time) dropped. */
static char *slurp(const char *dir, const char *name)
{
    char path[256];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *fp = fopen(path, "r");
    if (!fp) return NULL;
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap), line[1024];
    while (buf && fgets(line, sizeof line, fp)) {
        if (strstr(line, "\"seconds\"")) continue;
        size_t len = strlen(line);
        if (n + len + 1 > cap) break;
        memcpy(buf + n, line, len);
        n += len;
    }
    if (buf) buf[n] = '\0';
    fclose(fp);
    return buf;
}

static void remove_run(const char *dir)
{
    static const char *const names[] = {"log.csv", "summary.json", "checkpoint.ckpt",
                                        "run.id",  "run.pvd",      "profile.csv"};
    for (size_t k = 0; k < sizeof names / sizeof names[0]; ++k) {
        char path[256];
        snprintf(path, sizeof path, "%s/%s", dir, names[k]);
        remove(path);
    }
    for (int k = 0; k <= 23; ++k) {
        char path[256];
        snprintf(path, sizeof path, "%s/snap_%06d.vtu", dir, k);
        remove(path);
    }
    rmdir(dir);
}

/* A run with K = 7, snapshots every 5 steps and a checkpoint every 9 (the last at step 18, three
 * steps after the sample of step 15's snapshot), and its restart from that checkpoint into
 * another directory: the same log.csv and summary.json. */
static void test_restart(const char *scheme)
{
    char a[] = "/tmp/consph_logk_XXXXXX", b[] = "/tmp/consph_logk_XXXXXX";
    if (!mkdtemp(a) || !mkdtemp(b)) {
        CHECK(0, "mkdtemp");
        return;
    }
    consph_run_params p = params(scheme, 7);
    consph_solver *s = NULL, *r = NULL;
    consph_run_summary sum;
    int stopped = 0;
    consph_run_output out = {a, 5, 9, 0, 0};
    int st = consph_solver_create(&s, &p);
    if (st == CONSPH_OK) st = consph_run(s, &out, &sum, &stopped);
    CHECK(st == CONSPH_OK, "%s: run: %s", scheme, consph_last_error());
    static const long want[] = {0, 5, 7, 10, 14, 15, 20, 21, 23};
    const size_t nw = sizeof want / sizeof want[0];
    CHECK(s && consph_solver_history_size(s) == nw, "%s: %zu rows, not %zu", scheme,
          s ? consph_solver_history_size(s) : 0, nw);
    for (size_t k = 0; s && k < nw && k < consph_solver_history_size(s); ++k) {
        consph_step_diag d;
        consph_solver_history_row(s, k, &d);
        CHECK(d.step == want[k], "%s: row %zu is step %ld, not %ld", scheme, k, d.step, want[k]);
    }
    char ck[256];
    snprintf(ck, sizeof ck, "%s/checkpoint.ckpt", a);
    if (st == CONSPH_OK) st = consph_run_restart(&r, ck);
    CHECK(st == CONSPH_OK && consph_solver_step_count(r) == 18, "%s: restart: %s", scheme,
          consph_last_error());
    out.dir = b;
    if (st == CONSPH_OK) st = consph_run(r, &out, &sum, &stopped);
    CHECK(st == CONSPH_OK, "%s: restarted run: %s", scheme, consph_last_error());
    static const char *const files[] = {"log.csv", "summary.json"};
    for (int f = 0; st == CONSPH_OK && f < 2; ++f) {
        char *x = slurp(a, files[f]), *y = slurp(b, files[f]);
        CHECK(x && y && !strcmp(x, y), "%s: the restarted run's %s differs:\n%s\nvs\n%s", scheme,
              files[f], x ? x : "(none)", y ? y : "(none)");
        free(x);
        free(y);
    }
    consph_solver_free(s);
    consph_solver_free(r);
    remove_run(a);
    remove_run(b);
}

/* meta with the line `key=...` replaced by `repl` (NULL: removed), into buf. */
static void meta_edit(char *buf, size_t size, const char *meta, const char *key, const char *repl)
{
    size_t klen = strlen(key), n = 0;
    buf[0] = '\0';
    for (const char *line = meta; *line;) {
        const char *nl = strchr(line, '\n');
        size_t len = nl ? (size_t)(nl - line) + 1 : strlen(line);
        const int hit = !strncmp(line, key, klen) && line[klen] == '=';
        if (!hit)
            n += (size_t)snprintf(buf + n, size - n, "%.*s", (int)len, line);
        else if (repl)
            n += (size_t)snprintf(buf + n, size - n, "%s\n", repl);
        line += len;
    }
}

/* A format-3 checkpoint (no log_every, no log_since; every step in the history) restores as
 * K = 1 and continues as the run it came from; format 3 with a key it did not have, or a
 * history that lacks a sample of the cadence, is refused. */
static void test_format3(void)
{
    consph_run_params p = params("e-c", 1);
    consph_solver *s = NULL, *r = NULL;
    char *meta = NULL, buf[8192], tmp[8192];
    double *hist = NULL;
    size_t nh = 0;
    int st = consph_solver_create(&s, &p);
    for (int k = 0; k < 4 && st == CONSPH_OK; ++k) st = consph_solver_step(s);
    if (st == CONSPH_OK) st = consph_solver_checkpoint_meta(s, &meta, &hist, &nh);
    CHECK(st == CONSPH_OK, "set-up: %s", consph_last_error());
    if (st != CONSPH_OK) goto done;
    meta_edit(tmp, sizeof tmp, meta, "format", "format=consph-solver-3");
    meta_edit(buf, sizeof buf, tmp, "log_since", NULL);
    meta_edit(tmp, sizeof tmp, buf, "log_every", NULL);
    meta_edit(buf, sizeof buf, tmp, "skin", NULL);
    meta_edit(tmp, sizeof tmp, buf, "ipst_h_dt", NULL);
    meta_edit(buf, sizeof buf, tmp, "ipst_chi0", NULL);
    st = consph_solver_restore(&r, buf, consph_solver_particles(s), hist, nh);
    CHECK(st == CONSPH_OK && consph_solver_params(r)->log_every == 1, "format 3: %s",
          consph_last_error());
    if (st == CONSPH_OK) {
        st = run_steps(s);
        if (st == CONSPH_OK) st = run_steps(r);
        consph_run_summary a, b;
        consph_solver_summary(s, &a);
        consph_solver_summary(r, &b);
        CHECK(st == CONSPH_OK && same_double(a.l1_u, b.l1_u) && same_double(a.l1_p, b.l1_p) &&
                  consph_solver_history_size(r) == 24,
              "format 3 continued: %s", consph_last_error());
    }
    consph_solver_free(r);
    r = NULL;
    meta_edit(buf, sizeof buf, meta, "format", "format=consph-solver-3");
    CHECK(consph_solver_restore(&r, buf, consph_solver_particles(s), hist, nh) == CONSPH_EFORMAT &&
              strstr(consph_last_error(), "not one of format consph-solver-3"),
          "format 3 with log_every: %s", consph_last_error());
    /* step 4 with K = 2: the history 0..4 holds every sample; 0..2 lacks step 4's */
    meta_edit(buf, sizeof buf, meta, "log_every", "log_every=2");
    CHECK(consph_solver_restore(&r, buf, consph_solver_particles(s), hist, nh) == CONSPH_OK,
          "K = 2, every step in the history: %s", consph_last_error());
    consph_solver_free(r);
    r = NULL;
    CHECK(consph_solver_restore(&r, buf, consph_solver_particles(s), hist, nh - 2 * 14) ==
                  CONSPH_EFORMAT &&
              strstr(consph_last_error(), "lacks samples of log_every = 2"),
          "history lacking step 4: %s", consph_last_error());
    /* the last row is this step's: nothing can be pending */
    meta_edit(tmp, sizeof tmp, buf, "log_since", "log_since=0x1p-10");
    CHECK(consph_solver_restore(&r, tmp, consph_solver_particles(s), hist, nh) == CONSPH_EFORMAT &&
              strstr(consph_last_error(), "log_since"),
          "pending time after the last row of this step: %s", consph_last_error());
    meta_edit(tmp, sizeof tmp, meta, "log_since", "log_since=-0x1p-10");
    CHECK(consph_solver_restore(&r, tmp, consph_solver_particles(s), hist, nh) == CONSPH_EFORMAT &&
              strstr(consph_last_error(), "key 'log_since' = -0.000976562 is not a time"),
          "negative log_since: %s", consph_last_error());
    meta_edit(tmp, sizeof tmp, meta, "log_since", "log_since=0x1p+4");
    CHECK(consph_solver_restore(&r, tmp, consph_solver_particles(s), hist, nh) == CONSPH_EFORMAT &&
              strstr(consph_last_error(), "key 'log_since' = 16 is not a time"),
          "log_since past t: %s", consph_last_error());
    p.log_every = 0;
    CHECK(consph_run_params_check(&p) == CONSPH_EINVAL && strstr(consph_last_error(), "log_every"),
          "log_every = 0: %s", consph_last_error());
done:
    free(meta);
    free(hist);
    consph_solver_free(s);
    consph_solver_free(r);
}

int main(void)
{
    test_cadence("wcsph");    /* moves, Tait */
    test_cadence("l-ipst-c"); /* IPST every 4 steps */
    test_cadence("e-c");
    test_restart("tvf");
    test_restart("l-ipst-c");
    test_restart("ewcsph"); /* its frozen ϱ_c (state field rhoc) travels in the checkpoint */
    test_format3();
    return check_summary("test_log_every");
}
