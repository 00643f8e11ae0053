/* The cache of packed layouts on disk: consph_layout_generate keeps the result of a packing (the
 * positions and its report) in a file named by a hash of everything that decides the positions,
 * and reads it back instead of packing again.
 *
 * A file holds, in this order: the magic "CONSPHLC", the format version, the key's length and
 * the key in full (text, one "name value" per line), the payload (particle count, dimension,
 * positions, the packing report) and a CRC-32 (zlib) of everything after the magic. A file is
 * used only when its key equals the wanted key byte for byte, its length is exactly what the key
 * and payload say and the checksum matches; otherwise it is ignored with one line on stderr, and
 * the layout is recomputed and the file rewritten. Files are written to a temporary name in the
 * same directory and renamed into place, so that concurrent runs see either no file or a whole
 * one. Only the packed kinds are cached: the others take less time to generate than to read. */
#include <errno.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "layout/layout_internal.h"

/* A note on stderr, at the start of its own line: a study's live progress line may stand there
 * (src/study/engine.c redraws one while a layout is packed), and the note must not be glued to
 * it. */
#if defined(__GNUC__)
__attribute__((format(printf, 1, 2)))
#endif
static void
cache_note(const char *fmt, ...)
{
    va_list ap;
    char text[4608];
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    fprintf(stderr, "%s%s", isatty(STDERR_FILENO) ? "\r\033[K" : "", text);
}

#define CACHE_MAGIC "CONSPHLC"
#define CACHE_FORMAT 1u
#define CACHE_PATH_MAX 4096

static char cache_dir[CACHE_PATH_MAX];
static int cache_on;
static int cache_write_warned;

int consph_layout_cache_set(const char *dir)
{
    cache_write_warned = 0;
    if (!dir || !*dir) {
        cache_on = 0;
        cache_dir[0] = '\0';
        return CONSPH_OK;
    }
    if (strlen(dir) + 64 >= sizeof cache_dir)
        return consph_fail(CONSPH_EINVAL, "layout cache directory '%.80s...' is too long", dir);
    strcpy(cache_dir, dir);
    cache_on = 1;
    return CONSPH_OK;
}

const char *consph_layout_cache_get(void)
{
    return cache_on ? cache_dir : NULL;
}

int layout_cache_enabled(const consph_layout_params *lp)
{
    return cache_on &&
           (lp->kind == CONSPH_LAYOUT_PACKED || lp->kind == CONSPH_LAYOUT_PACKED_POLISHED);
}

/* Appends to the key; 0 when it was truncated. */
#if defined(__GNUC__)
__attribute__((format(printf, 4, 5)))
#endif
static int
key_add(char *key, size_t size, size_t *len, const char *fmt, ...)
{
    if (*len >= size) return 0;
    va_list ap;
    va_start(ap, fmt);
    int k = vsnprintf(key + *len, size - *len, fmt, ap);
    va_end(ap);
    if (k < 0 || (size_t)k >= size - *len) {
        *len = size;
        return 0;
    }
    *len += (size_t)k;
    return 1;
}

int consph_layout_cache_key(const consph_layout_params *lp, char *key, size_t size)
{
    const consph_packing_params *pp = &lp->packing;
    size_t len = 0;
    const uint16_t one = 1;
    unsigned char first;
    memcpy(&first, &one, 1);
    /* The arithmetic of the build: with fused multiply-adds the same code rounds differently. */
#if defined(__FMA__) || defined(__FP_FAST_FMA)
    const char *flavour = "fma";
#else
    const char *flavour = "no-fma";
#endif
    int ok = key_add(key, size, &len, "consph layout cache %u\npacking-version %d\n", CACHE_FORMAT,
                     CONSPH_LAYOUT_PACKING_VERSION);
    ok &= key_add(key, size, &len, "build %s %s-endian double %zu\n", flavour,
                  first ? "little" : "big", sizeof(double));
    ok &= key_add(key, size, &len, "kind %s\ndim %d\nnx", consph_layout_name(lp->kind), lp->dim);
    for (int a = 0; a < lp->dim && a < CONSPH_MAX_DIM; ++a)
        ok &= key_add(key, size, &len, " %zu", lp->nx[a]);
    ok &= key_add(key, size, &len, "\nbox");
    for (int a = 0; a < lp->dim && a < CONSPH_MAX_DIM; ++a)
        ok &= key_add(key, size, &len, " %.17g:%.17g%s", lp->box.lo[a], lp->box.hi[a],
                      lp->box.periodic[a] ? ":periodic" : "");
    ok &= key_add(key, size, &len, "\nseed %llu\nkernel %s\nhdx %.17g\nperturb %.17g\n",
                  (unsigned long long)lp->seed, pp->kernel ? pp->kernel : "quintic", pp->hdx,
                  pp->perturb);
    ok &= key_add(key, size, &len, "max-iter %d\n", pp->max_iter);
    if (lp->kind == CONSPH_LAYOUT_PACKED_POLISHED)
        ok &= key_add(key, size, &len, "tol %.17g\n", pp->tol);
    else
        ok &= key_add(key, size, &len, "move-tol %.17g\n", pp->move_tol);
    /* Only when set, so that the keys (and files) of the periodic packing stay as they were. */
    if (pp->walls > 0) ok &= key_add(key, size, &len, "walls %d\n", pp->walls);
    if (!ok) return consph_fail(CONSPH_EINVAL, "layout cache key longer than %zu bytes", size);
    return CONSPH_OK;
}

/* 64-bit FNV-1a. */
static uint64_t fnv1a(const char *s, size_t n)
{
    uint64_t h = 1469598103934665603ull;
    for (size_t i = 0; i < n; ++i) {
        h ^= (unsigned char)s[i];
        h *= 1099511628211ull;
    }
    return h;
}

static int cache_file_name(const char *dir, const char *key, char *path, size_t size)
{
    size_t n = strlen(key);
    unsigned long crc = crc32(0L, (const Bytef *)key, (uInt)n);
    int k = snprintf(path, size, "%s/layout-%016llx%08lx.bin", dir,
                     (unsigned long long)fnv1a(key, n), crc & 0xffffffffUL);
    if (k < 0 || (size_t)k >= size)
        return consph_fail(CONSPH_EINVAL, "layout cache path too long under '%s'", dir);
    return CONSPH_OK;
}

int consph_layout_cache_path(const consph_layout_params *lp, char *path, size_t size)
{
    if (!cache_on) return consph_fail(CONSPH_EINVAL, "the layout cache is off");
    char key[2048];
    int rc = consph_layout_cache_key(lp, key, sizeof key);
    if (rc) return rc;
    return cache_file_name(cache_dir, key, path, size);
}

/* ---- the payload ---- */

typedef struct buf {
    unsigned char *p;
    size_t len, cap;
    int failed;
} buf;

static void put(buf *b, const void *data, size_t n)
{
    if (b->failed) return;
    if (b->len + n > b->cap) {
        size_t cap = b->cap ? b->cap : 4096;
        while (cap < b->len + n) cap *= 2;
        unsigned char *q = realloc(b->p, cap);
        if (!q) {
            b->failed = 1;
            return;
        }
        b->p = q;
        b->cap = cap;
    }
    memcpy(b->p + b->len, data, n);
    b->len += n;
}

static void put_u32(buf *b, uint32_t v)
{
    put(b, &v, sizeof v);
}
static void put_i32(buf *b, int32_t v)
{
    put(b, &v, sizeof v);
}
static void put_f64(buf *b, double v)
{
    put(b, &v, sizeof v);
}

typedef struct reader {
    const unsigned char *p;
    size_t len, pos;
    int short_read;
} reader;

static void get(reader *r, void *data, size_t n)
{
    if (r->short_read || n > r->len - r->pos) {
        r->short_read = 1;
        memset(data, 0, n);
        return;
    }
    memcpy(data, r->p + r->pos, n);
    r->pos += n;
}
static uint32_t get_u32(reader *r)
{
    uint32_t v;
    get(r, &v, sizeof v);
    return v;
}
static int32_t get_i32(reader *r)
{
    int32_t v;
    get(r, &v, sizeof v);
    return v;
}
static double get_f64(reader *r)
{
    double v;
    get(r, &v, sizeof v);
    return v;
}

/* The whole file in memory (at most `limit` bytes; more is corrupt). NULL when absent. */
static unsigned char *slurp(const char *path, size_t limit, size_t *len, int *absent)
{
    *absent = 0;
    FILE *f = fopen(path, "rb");
    if (!f) {
        *absent = errno == ENOENT;
        return NULL;
    }
    unsigned char *data = malloc(limit + 1);
    size_t n = data ? fread(data, 1, limit + 1, f) : 0;
    fclose(f);
    *len = n;
    return data;
}

int layout_cache_load(const consph_layout_params *lp, consph_particles *p,
                      consph_packing_report *report)
{
    char key[2048], path[CACHE_PATH_MAX + 64];
    if (consph_layout_cache_key(lp, key, sizeof key) ||
        cache_file_name(cache_dir, key, path, sizeof path))
        return 0;
    const size_t keylen = strlen(key);
    const int dim = p->dim;
    const size_t n = p->n;
    /* An upper bound on the file's size for this key: the history has at most max_iter + 2
     * entries. */
    const size_t limit = 64 + keylen + 64 + (size_t)dim * n * sizeof(double) + 64 +
                         ((size_t)lp->packing.max_iter + 2) * 12 + 16;
    size_t len = 0;
    int absent = 0;
    unsigned char *data = slurp(path, limit, &len, &absent);
    if (!data) {
        if (!absent) cache_note("consph: layout cache %s: cannot read it; recomputing\n", path);
        return 0;
    }
    const char *why = NULL;
    reader r = {data, len, 0, 0};
    char magic[8];
    get(&r, magic, sizeof magic);
    const uint32_t format = get_u32(&r), klen = get_u32(&r);
    if (r.short_read || memcmp(magic, CACHE_MAGIC, 8) != 0)
        why = "not a consph layout cache file";
    else if (format != CACHE_FORMAT)
        why = "another format version";
    else if (klen == keylen && klen > len - r.pos)
        why = "truncated";
    else if (klen != keylen || memcmp(data + r.pos, key, keylen) != 0)
        why = "its key is not this layout's";
    if (!why) {
        r.pos += keylen;
        /* The checksum is the file's last 4 bytes, over everything between the magic and it. */
        if (len < r.pos + 4) {
            why = "truncated";
        } else {
            uint32_t stored;
            memcpy(&stored, data + len - 4, 4);
            unsigned long crc = crc32(0L, data + 8, (uInt)(len - 4 - 8));
            if ((uint32_t)crc != stored) why = "checksum mismatch (corrupt or truncated)";
        }
    }
    consph_packing_report rep;
    memset(&rep, 0, sizeof rep);
    if (!why) {
        r.len = len - 4;
        uint32_t fn_lo = get_u32(&r), fn_hi = get_u32(&r);
        int32_t fdim = get_i32(&r);
        size_t fn = (size_t)(((uint64_t)fn_hi << 32) | fn_lo);
        if (r.short_read || fn != n || fdim != dim) why = "particle count or dimension differ";
        for (int a = 0; !why && a < dim; ++a) get(&r, p->x[a], n * sizeof(double));
        rep.iterations = get_i32(&r);
        rep.polish_start = get_i32(&r);
        rep.converged = get_i32(&r);
        const int32_t every = get_i32(&r), nh = get_i32(&r);
        rep.rho_spread_initial = get_f64(&r);
        rep.rho_spread_final = get_f64(&r);
        rep.move_final = get_f64(&r);
        rep.seconds = get_f64(&r);
        if (!why && (r.short_read || nh < 0 || (size_t)nh * 12 != r.len - r.pos))
            why = "truncated or malformed payload";
        if (!why && report) {
            /* The history as recorded, subsampled when the caller asks for a multiple of its
             * cadence; none when the cadences do not fit. */
            const int want = lp->packing.history_every;
            const int usable = want > 0 && every > 0 && want % every == 0;
            int *it = NULL;
            double *sp = NULL;
            if (usable && nh > 0) {
                it = consph_calloc((size_t)nh, sizeof *it);
                sp = consph_calloc((size_t)nh, sizeof *sp);
                if (!it || !sp) {
                    free(it);
                    free(sp);
                    free(data);
                    return 0;
                }
            }
            const size_t at_iter = r.pos, at_spread = r.pos + (size_t)nh * 4;
            for (int k = 0; k < nh && it; ++k) {
                int32_t iter;
                double s;
                memcpy(&iter, data + at_iter + (size_t)k * 4, 4);
                memcpy(&s, data + at_spread + (size_t)k * 8, 8);
                if (iter % want == 0 || k == nh - 1) {
                    it[rep.nhistory] = iter;
                    sp[rep.nhistory] = s;
                    rep.nhistory++;
                }
            }
            rep.history_iter = it;
            rep.history_spread = sp;
        }
    }
    free(data);
    if (why) {
        cache_note("consph: layout cache %s: %s; recomputing it\n", path, why);
        return 0;
    }
    for (int a = 0; a < dim; ++a)
        for (size_t i = 0; i < n; ++i)
            if (!isfinite(p->x[a][i]) || p->x[a][i] < lp->box.lo[a] ||
                !(p->x[a][i] < lp->box.hi[a])) {
                cache_note("consph: layout cache %s: a position outside the box; recomputing it\n",
                           path);
                consph_packing_report_free(&rep);
                return 0;
            }
    rep.from_cache = 1;
    if (report)
        *report = rep;
    else
        consph_packing_report_free(&rep);
    return 1;
}

/* Bytes of the positions read at a time by layout_cache_load_range (a multiple of 8). */
enum { RANGE_BLOCK = 1 << 20 };

/* Reads n bytes into `to` and adds them to the checksum; 0 on a short read. */
static int range_read(FILE *f, void *to, size_t n, uLong *crc)
{
    if (fread(to, 1, n, f) != n) return 0;
    *crc = crc32(*crc, to, (uInt)n);
    return 1;
}

int layout_cache_load_range(const consph_layout_params *lp, size_t n, size_t first,
                            consph_particles *p)
{
    char key[2048], path[CACHE_PATH_MAX + 64];
    if (consph_layout_cache_key(lp, key, sizeof key) ||
        cache_file_name(cache_dir, key, path, sizeof path))
        return 0;
    const size_t keylen = strlen(key), count = p->n;
    const int dim = p->dim;
    FILE *f = fopen(path, "rb");
    struct stat sb;
    if (!f) return 0;
    if (fstat(fileno(f), &sb) != 0) {
        fclose(f);
        return 0;
    }
    /* the file's parts as layout_cache_store writes them: the header with the key, the
     * positions, the report (52 bytes and 12 per history entry, at most max_iter + 2 of them),
     * the checksum */
    const uint64_t size = (uint64_t)sb.st_size, head = 8 + 4 + 4 + (uint64_t)keylen + 12,
                   body = (uint64_t)dim * n * sizeof(double),
                   tail_max = 52 + ((uint64_t)lp->packing.max_iter + 2) * 12;
    const uint64_t tail = size >= head + body + 52 + 4 ? size - head - body - 4 : 0;
    unsigned char hb[8 + 4 + 4 + 2048 + 12];
    unsigned char *tb = tail >= 52 && tail <= tail_max ? malloc(tail) : NULL;
    double *blk = tb ? malloc(RANGE_BLOCK) : NULL;
    uLong crc = crc32(0L, Z_NULL, 0);
    int ok = blk && fread(hb, 1, 8, f) == 8 && !memcmp(hb, CACHE_MAGIC, 8) &&
             range_read(f, hb + 8, head - 8, &crc);
    if (ok) {
        uint32_t format, klen, n_lo, n_hi;
        int32_t fdim;
        memcpy(&format, hb + 8, 4);
        memcpy(&klen, hb + 12, 4);
        memcpy(&n_lo, hb + 16 + keylen, 4);
        memcpy(&n_hi, hb + 20 + keylen, 4);
        memcpy(&fdim, hb + 24 + keylen, 4);
        ok = format == CACHE_FORMAT && klen == keylen && !memcmp(hb + 16, key, keylen) &&
             (((uint64_t)n_hi << 32) | n_lo) == (uint64_t)n && fdim == dim;
    }
    /* every position checked as layout_cache_load checks them; this range's kept */
    const size_t per = RANGE_BLOCK / sizeof(double);
    for (int a = 0; ok && a < dim; ++a)
        for (size_t i = 0; ok && i < n; i += per) {
            const size_t k = n - i < per ? n - i : per;
            ok = range_read(f, blk, k * sizeof(double), &crc);
            for (size_t j = 0; ok && j < k; ++j)
                ok = isfinite(blk[j]) && blk[j] >= lp->box.lo[a] && blk[j] < lp->box.hi[a];
            const size_t lo = first > i ? first : i,
                         hi = first + count < i + k ? first + count : i + k;
            if (ok && lo < hi) memcpy(p->x[a] + (lo - first), blk + (lo - i), (hi - lo) * 8);
        }
    uint32_t stored = 0;
    ok = ok && range_read(f, tb, tail, &crc) && fread(&stored, 1, 4, f) == 4 &&
         (uint32_t)crc == stored;
    if (ok) {
        int32_t nh;
        memcpy(&nh, tb + 16, 4);
        ok = nh >= 0 && (uint64_t)nh * 12 == tail - 52;
    }
    free(tb);
    free(blk);
    fclose(f);
    return ok;
}

/* mkdir -p */
static int make_dirs(const char *dir)
{
    char tmp[CACHE_PATH_MAX];
    size_t n = strlen(dir);
    if (n >= sizeof tmp) return -1;
    memcpy(tmp, dir, n + 1);
    for (size_t i = 1; i <= n; ++i) {
        if (tmp[i] != '/' && tmp[i] != '\0') continue;
        char c = tmp[i];
        tmp[i] = '\0';
        if (mkdir(tmp, 0777) != 0 && errno != EEXIST) return -1;
        tmp[i] = c;
    }
    struct stat st;
    return stat(dir, &st) == 0 && S_ISDIR(st.st_mode) ? 0 : -1;
}

static void warn_unwritable(const char *what)
{
    if (!cache_write_warned)
        cache_note("consph: warning: cannot write the layout cache in %s (%s: %s); going on "
                   "without it\n",
                   cache_dir, what, strerror(errno));
    cache_write_warned = 1;
}

void layout_cache_store(const consph_layout_params *lp, const consph_particles *p,
                        const consph_packing_report *report)
{
    if (cache_write_warned) return;
    char key[2048], path[CACHE_PATH_MAX + 64], tmp[CACHE_PATH_MAX + 64];
    if (consph_layout_cache_key(lp, key, sizeof key) ||
        cache_file_name(cache_dir, key, path, sizeof path))
        return;
    buf b = {NULL, 0, 0, 0};
    put(&b, CACHE_MAGIC, 8);
    put_u32(&b, CACHE_FORMAT);
    put_u32(&b, (uint32_t)strlen(key));
    put(&b, key, strlen(key));
    put_u32(&b, (uint32_t)((uint64_t)p->n & 0xffffffffu));
    put_u32(&b, (uint32_t)((uint64_t)p->n >> 32));
    put_i32(&b, p->dim);
    for (int a = 0; a < p->dim; ++a) put(&b, p->x[a], p->n * sizeof(double));
    put_i32(&b, report->iterations);
    put_i32(&b, report->polish_start);
    put_i32(&b, report->converged);
    put_i32(&b, lp->packing.history_every);
    put_i32(&b, report->nhistory);
    put_f64(&b, report->rho_spread_initial);
    put_f64(&b, report->rho_spread_final);
    put_f64(&b, report->move_final);
    put_f64(&b, report->seconds);
    for (int k = 0; k < report->nhistory; ++k) put_i32(&b, report->history_iter[k]);
    for (int k = 0; k < report->nhistory; ++k) put_f64(&b, report->history_spread[k]);
    if (!b.failed) put_u32(&b, (uint32_t)crc32(0L, b.p + 8, (uInt)(b.len - 8)));
    if (b.failed) {
        free(b.p);
        return;
    }
    if (make_dirs(cache_dir) != 0) {
        warn_unwritable("creating the directory");
        free(b.p);
        return;
    }
    snprintf(tmp, sizeof tmp, "%s/.layout-tmp-XXXXXX", cache_dir);
    int fd = mkstemp(tmp);
    if (fd < 0) {
        warn_unwritable("creating a file");
        free(b.p);
        return;
    }
    size_t done = 0;
    while (done < b.len) {
        ssize_t k = write(fd, b.p + done, b.len - done);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) break;
        done += (size_t)k;
    }
    free(b.p);
    const int closed = close(fd) == 0;
    if (done != b.len || !closed) {
        warn_unwritable("writing a file");
        unlink(tmp);
        return;
    }
    if (rename(tmp, path) != 0) {
        warn_unwritable("renaming a file into place");
        unlink(tmp);
    }
}

int layout_cache_lock(const consph_layout_params *lp)
{
    char key[2048], path[CACHE_PATH_MAX + 64], lock[CACHE_PATH_MAX + 80];
    if (consph_layout_cache_key(lp, key, sizeof key) ||
        cache_file_name(cache_dir, key, path, sizeof path) || make_dirs(cache_dir) != 0)
        return -1;
    /* .layout-<hash>.lock beside layout-<hash>.bin, hidden; left in place, since a process may
     * be waiting on it */
    const char *base = strrchr(path, '/') + 1;
    snprintf(lock, sizeof lock, "%s/.%.*s.lock", cache_dir, (int)(strlen(base) - 4), base);
    int fd = open(lock, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) return -1;
    while (flock(fd, LOCK_EX) != 0)
        if (errno != EINTR) {
            close(fd);
            return -1;
        }
    return fd;
}

void layout_cache_unlock(int fd)
{
    if (fd >= 0) close(fd); /* releases the flock */
}
