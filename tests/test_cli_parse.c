/* The CLI option parsers of apps/cli.c through the fuzz entry point: every seed of
 * fuzz/corpus/cli/ and every crash kept in fuzz/regressions/cli/, so that what the fuzzer found
 * once stays fixed. The entry point aborts on any broken invariant. */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>

#include "../fuzz/fuzz_cli.h"
#include "check.h"

/* Feeds every file of `dir` to the entry point; returns how many. */
static int replay_dir(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return -1;
    int count = 0;
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        if (e->d_name[0] == '.') continue;
        char path[2048];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        FILE *f = fopen(path, "rb");
        if (!f) continue;
        uint8_t buf[8192];
        size_t size = fread(buf, 1, sizeof buf, f);
        fclose(f);
        consph_fuzz_cli(buf, size);
        ++count;
    }
    closedir(d);
    return count;
}

int main(void)
{
    int seeds = replay_dir(CONSPH_SOURCE_DIR "/fuzz/corpus/cli");
    CHECK(seeds >= 10, "seed corpus fuzz/corpus/cli: %d files", seeds);
    int kept = replay_dir(CONSPH_SOURCE_DIR "/fuzz/regressions/cli");
    printf("replayed %d seeds and %d regressions\n", seeds, kept < 0 ? 0 : kept);
    return check_summary("test_cli_parse");
}
