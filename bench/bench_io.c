/* Writing and reading a large particle file: a layout of NX^DIM particles (default a 3D random
 * layout of 216^3 = 10,077,696, about 10^7) is written as CSV (x,y,z,volume; the format
 * `consph layout` writes) and/or as VTU in an encoding (vtu: the default, zlib), then each is
 * read back in a forked child so that the child's peak resident memory is the reader's own.
 * Prints size and write time, then read time, throughput and peak memory per particle, which
 * shows the readers stream: memory is O(N), near the 32 bytes per particle of the result.
 * With --read, the given files (e.g. written by ParaView or VTK) are read the same way.
 *
 * Usage: bench_io [NX] [csv|vtu|ascii|binary|zlib|both|all] [DIM] [KIND]
 *          (both: csv and vtu; all: csv and every VTU encoding; KIND as `consph layout --kind`;
 *          files go to $TMPDIR or /tmp and are removed)
 *        bench_io --read FILE...         (each read REPEAT times, default 3) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "consph/io.h"
#include "consph/layout.h"

/* n_expected 0: any count. */
static int read_in_child(const char *path, size_t n_expected)
{
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0) return 1;
    if (pid == 0) {
        size_t rss0 = consph_peak_rss();
        double t0 = consph_wtime();
        consph_particles p;
        consph_read_report rep;
        int rc = consph_read_particles(path, NULL, &p, &rep);
        double t = consph_wtime() - t0;
        if (rc) {
            fprintf(stderr, "read failed: %s\n", consph_last_error());
            _exit(1);
        }
        struct stat st;
        stat(path, &st);
        size_t rss = consph_peak_rss();
        printf("read  %-4s %zu particles (%s) in %.2f s: %.1f MB/s, %.2f M particles/s; peak RSS "
               "%.0f MB (%.0f MB at start) = %.1f bytes/particle; %s\n",
               rep.format == CONSPH_FORMAT_CSV ? "csv" : "vtu", p.n,
               rep.format == CONSPH_FORMAT_CSV ? "x,y,z,volume" : rep.encoding, t,
               (double)st.st_size / t / 1e6, (double)p.n / t / 1e6, (double)rss / 1e6,
               (double)rss0 / 1e6, (double)(rss - rss0) / (double)p.n,
               !n_expected || p.n == n_expected ? "count ok" : "COUNT WRONG");
        size_t n = p.n;
        consph_particles_free(&p);
        fflush(stdout);
        _exit(!n_expected || n == n_expected ? 0 : 1);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : 1;
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "--read") == 0) {
        const char *env = getenv("REPEAT");
        int repeat = env ? atoi(env) : 3, rc = 0;
        for (int k = 2; k < argc; ++k)
            for (int r = 0; r < repeat; ++r) rc |= read_in_child(argv[k], 0);
        return rc;
    }
    size_t nx = argc > 1 ? (size_t)atol(argv[1]) : 216;
    const char *which = argc > 2 ? argv[2] : "csv";
    int dim = argc > 3 ? atoi(argv[3]) : 3;
    consph_layout_kind kind = CONSPH_LAYOUT_RANDOM;
    if (nx < 2) nx = 2;
    if (dim < 1 || dim > 3 || (argc > 4 && consph_layout_lookup(argv[4], &kind) != CONSPH_OK)) {
        fprintf(stderr, "bench_io: bad DIM or KIND\n");
        return 2;
    }
    const char *tmp = getenv("TMPDIR");
    if (!tmp) tmp = "/tmp";
    consph_layout_params lp = consph_layout_defaults(kind, dim, nx);
    consph_particles p;
    double t0 = consph_wtime();
    if (consph_layout_generate(&lp, &p, NULL) != CONSPH_OK) {
        fprintf(stderr, "layout: %s\n", consph_last_error());
        return 1;
    }
    size_t n = p.n;
    printf("bench_io: %s %zu^%d = %zu particles generated in %.2f s\n", consph_layout_name(kind),
           nx, dim, n, consph_wtime() - t0);
    /* Outputs: csv, then vtu in each encoding. */
    static const char *const name[4] = {"csv", "ascii", "binary", "zlib"};
    char path[4][512];
    int rc = 0;
    for (int k = 0; k < 4; ++k) {
        path[k][0] = '\0';
        int want = strcmp(which, "all") == 0 || strcmp(which, name[k]) == 0 ||
                   ((strcmp(which, "both") == 0 || strcmp(which, "vtu") == 0) &&
                    k == 1 + CONSPH_VTU_DEFAULT) ||
                   (strcmp(which, "both") == 0 && k == 0);
        if (!want) continue;
        snprintf(path[k], sizeof path[k], "%s/consph_bench_io_%ld_%s.%s", tmp, (long)getpid(),
                 name[k], k ? "vtu" : "csv");
        t0 = consph_wtime();
        if (consph_write_particles_enc(path[k], &p, (consph_vtu_encoding)(k ? k - 1 : 0)) !=
            CONSPH_OK) {
            fprintf(stderr, "write: %s\n", consph_last_error());
            rc = 1;
            path[k][0] = '\0';
            continue;
        }
        struct stat st;
        stat(path[k], &st);
        printf("write %-6s %.1f MB in %.2f s\n", name[k], (double)st.st_size / 1e6,
               consph_wtime() - t0);
    }
    consph_particles_free(&p); /* so that the children start small */
    for (int k = 0; k < 4; ++k) {
        if (!path[k][0]) continue;
        rc |= read_in_child(path[k], n);
        remove(path[k]);
    }
    return rc;
}
