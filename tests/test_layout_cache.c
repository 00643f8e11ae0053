/* The cache of packed layouts (src/layout/cache.c): a hit gives the positions of a fresh
 * generation bit for bit, a damaged file is detected and rewritten, different parameters have
 * different keys and files, and nothing is written with the cache off. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "check.h"
#include "consph/layout.h"

static int same_positions(const consph_particles *a, const consph_particles *b)
{
    if (a->n != b->n || a->dim != b->dim) return 0;
    for (int d = 0; d < a->dim; ++d)
        if (memcmp(a->x[d], b->x[d], a->n * sizeof(double)) != 0) return 0;
    return 1;
}

static long file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

/* Generates lp, returning its report's from_cache flag (-1 on failure). */
static int generate(const consph_layout_params *lp, consph_particles *p)
{
    consph_packing_report rep;
    if (consph_layout_generate(lp, p, &rep) != CONSPH_OK) return -1;
    int hit = rep.from_cache;
    consph_packing_report_free(&rep);
    return hit;
}

static void test_hit_and_damage(const char *dir)
{
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, 12);
    lp.packing.max_iter = 300;
    consph_particles fresh, miss, hit, again;
    CHECK(consph_layout_cache_set(NULL) == CONSPH_OK && !consph_layout_cache_get(), "cache off");
    CHECK(generate(&lp, &fresh) == 0, "fresh generation");
    CHECK(consph_layout_cache_set(dir) == CONSPH_OK, "cache on");
    char path[4200];
    CHECK(consph_layout_cache_path(&lp, path, sizeof path) == CONSPH_OK, "path");
    CHECK(file_size(path) < 0, "no file before the first generation");
    CHECK(generate(&lp, &miss) == 0, "a miss packs");
    CHECK(file_size(path) > 0, "the miss wrote %s", path);
    CHECK(generate(&lp, &hit) == 1, "the second generation reads the cache");
    CHECK(same_positions(&fresh, &miss) && same_positions(&fresh, &hit),
          "cached positions equal a fresh generation bit for bit");

    /* Flip one byte in the middle (the positions), then truncate: each is detected (from_cache
     * 0, positions those of a fresh generation) and the file rewritten (the next one hits). */
    const long size = file_size(path);
    FILE *f = fopen(path, "r+b");
    CHECK(f != NULL, "open %s", path);
    if (f) {
        fseek(f, size / 2, SEEK_SET);
        int c = fgetc(f);
        fseek(f, size / 2, SEEK_SET);
        fputc(c ^ 0x10, f);
        fclose(f);
    }
    CHECK(generate(&lp, &again) == 0, "a flipped byte is not trusted");
    CHECK(same_positions(&fresh, &again), "recomputed after a flipped byte");
    consph_particles_free(&again);
    CHECK(generate(&lp, &again) == 1 && same_positions(&fresh, &again), "rewritten, hits again");
    consph_particles_free(&again);
    CHECK(truncate(path, size - 7) == 0, "truncate");
    CHECK(generate(&lp, &again) == 0 && same_positions(&fresh, &again),
          "a truncated file is not trusted");
    CHECK(file_size(path) == size, "rewritten whole after truncation");
    consph_particles_free(&again);
    CHECK(truncate(path, 20) == 0, "truncate to the header");
    CHECK(generate(&lp, &again) == 0 && same_positions(&fresh, &again),
          "a file cut inside its key is not trusted");
    consph_particles_free(&again);

    /* Another key in this file's place (a hash collision, or a file copied by hand). */
    consph_layout_params other = lp;
    other.seed = 2;
    char other_path[4200];
    CHECK(consph_layout_cache_path(&other, other_path, sizeof other_path) == CONSPH_OK, "path 2");
    CHECK(generate(&other, &again) == 0, "seed 2 packs");
    consph_particles_free(&again);
    CHECK(rename(other_path, path) == 0, "move seed 2's file into seed 1's place");
    CHECK(generate(&lp, &again) == 0 && same_positions(&fresh, &again),
          "a file holding another key is not used");
    consph_particles_free(&again);

    /* Invalid parameters are refused as without the cache. */
    consph_layout_params bad = lp;
    bad.packing.hdx = -1.0;
    CHECK(consph_layout_generate(&bad, &again, NULL) == CONSPH_EINVAL, "bad hdx still refused");

    consph_particles_free(&fresh);
    consph_particles_free(&miss);
    consph_particles_free(&hit);
}

/* Every parameter that moves the positions changes the key and the file name; one that does
 * not (history_every; eps, which only random uses) does not. */
static void test_keys(const char *dir)
{
    CHECK(consph_layout_cache_set(dir) == CONSPH_OK, "cache on");
    consph_layout_params base = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, 20);
    consph_layout_params v[12];
    int k = 0;
    for (int m = 0; m < 12; ++m) v[m] = base;
    v[k++].kind = CONSPH_LAYOUT_PACKED_POLISHED;
    v[k].nx[0] = v[k].nx[1] = 21, ++k;
    v[k++].seed = 2;
    v[k++].packing.kernel = "wendland-c4";
    v[k++].packing.hdx = 1.3;
    v[k++].packing.perturb = 0.4;
    v[k++].packing.max_iter = 1000;
    v[k++].packing.move_tol = 2e-2;
    v[k++].packing.walls = 3;
    v[k].dim = 3, v[k].nx[2] = 20, v[k].box = consph_box_unit(3, 1), ++k;
    v[k].box.hi[0] = 2.0, v[k].nx[0] = 40, ++k;
    const int nvariants = k;
    char key0[2048], path0[4200], key[2048], path[4200];
    CHECK(consph_layout_cache_key(&base, key0, sizeof key0) == CONSPH_OK, "key");
    CHECK(consph_layout_cache_path(&base, path0, sizeof path0) == CONSPH_OK, "path");
    CHECK(strncmp(path0, dir, strlen(dir)) == 0 && strlen(path0) == strlen(dir) + 1 + 35,
          "name = layout-<24 hex>.bin under the directory: %s", path0);
    for (int m = 0; m < nvariants; ++m) {
        CHECK(consph_layout_cache_key(&v[m], key, sizeof key) == CONSPH_OK &&
                  strcmp(key, key0) != 0,
              "variant %d has its own key", m);
        CHECK(consph_layout_cache_path(&v[m], path, sizeof path) == CONSPH_OK &&
                  strcmp(path, path0) != 0,
              "variant %d has its own file", m);
    }
    consph_layout_params same = base;
    same.packing.history_every = 7;
    same.eps = 0.4;
    same.packing.tol = 1e-3; /* packed-polished's; packed ignores it */
    CHECK(consph_layout_cache_key(&same, key, sizeof key) == CONSPH_OK && strcmp(key, key0) == 0,
          "history_every, eps and tol do not change packed's key");
    CHECK(strstr(key0, "packing-version") != NULL, "the key names the packing version:\n%s", key0);
}

/* Off: nothing is written; lattice-based cheap kinds are never cached. */
static void test_off_and_cheap(const char *dir)
{
    char sub[4200];
    snprintf(sub, sizeof sub, "%s/off", dir);
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_PACKED, 2, 8);
    lp.packing.max_iter = 50;
    consph_particles p;
    CHECK(consph_layout_cache_set(NULL) == CONSPH_OK, "off");
    CHECK(generate(&lp, &p) == 0, "packs");
    consph_particles_free(&p);
    CHECK(file_size(sub) < 0, "nothing written with the cache off");
    CHECK(consph_layout_cache_set(sub) == CONSPH_OK, "on");
    consph_layout_params rnd = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, 2, 8);
    CHECK(consph_layout_generate(&rnd, &p, NULL) == CONSPH_OK, "random");
    consph_particles_free(&p);
    CHECK(file_size(sub) < 0, "random is not cached");
    CHECK(consph_layout_generate(&lp, &p, NULL) == CONSPH_OK, "packed with a NULL report");
    consph_particles_free(&p);
    CHECK(file_size(sub) > 0, "a packed layout created the directory");
    CHECK(consph_layout_cache_set("") == CONSPH_OK && !consph_layout_cache_get(), "\"\" is off");
}

int main(void)
{
    char dir[] = "/tmp/consph-test-cache-XXXXXX";
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    check_set_threads(1);
    char sub[4200];
    snprintf(sub, sizeof sub, "%s/a/b", dir); /* created on the first write */
    test_hit_and_damage(sub);
    test_keys(sub);
    test_off_and_cheap(dir);
    consph_layout_cache_set(NULL);
    char cmd[4300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", dir);
    return check_summary("test_layout_cache");
}
