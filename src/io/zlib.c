/* zlib (RFC 1950) streams of the vtkZLibDataCompressor blocks of .vtu files, through the system
 * zlib: inflating one block for the reader, compressing one for the writer. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "io/read_internal.h"

/* Grows *out to hold at least `need` bytes, doubling but never past `limit`. */
static int grow(unsigned char **out, size_t *outcap, size_t need, size_t limit)
{
    if (*outcap >= need) return 0;
    size_t cap = *outcap ? *outcap : 4096;
    while (cap < need) cap = cap > limit / 2 ? limit : 2 * cap;
    unsigned char *b = realloc(*out, cap);
    if (!b) return -1;
    *out = b;
    *outcap = cap;
    return 0;
}

int consph_rd_inflate(const unsigned char *in, size_t inlen, unsigned char **out, size_t *outlen,
                      size_t *outcap, size_t maxout, const char **why)
{
    *outlen = 0;
    *why = "";
    if (inlen > UINT_MAX) {
        *why = "compressed block larger than 4 GiB";
        return -1;
    }
    z_stream z;
    memset(&z, 0, sizeof z);
    if (inflateInit(&z) != Z_OK) {
        *why = "out of memory";
        return -1;
    }
    z.next_in = (unsigned char *)in; /* zlib's API is not const-correct; it only reads */
    z.avail_in = (uInt)inlen;
    /* One byte of room past maxout tells a stream longer than the header says from one that
     * fits exactly. */
    size_t limit = maxout + 1;
    int rc = Z_OK;
    while (rc != Z_STREAM_END && *outlen < limit) {
        size_t room = *outcap - *outlen;
        if (room == 0) {
            size_t want = *outlen + (inlen > 4096 ? 4 * inlen : 4096);
            if (grow(out, outcap, want < limit ? want : limit, limit)) {
                *why = "out of memory";
                break;
            }
            room = *outcap - *outlen;
        }
        if (room > limit - *outlen) room = limit - *outlen;
        if (room > UINT_MAX) room = UINT_MAX;
        z.next_out = *out + *outlen;
        z.avail_out = (uInt)room;
        rc = inflate(&z, Z_NO_FLUSH);
        *outlen += room - z.avail_out;
        if (rc == Z_OK) continue;
        if (rc == Z_STREAM_END) break;
        if (rc == Z_BUF_ERROR && z.avail_out == 0) continue; /* no room: grow and retry */
        if (rc == Z_BUF_ERROR)
            *why = "truncated compressed data";
        else if (rc == Z_NEED_DICT)
            *why = "needs a preset dictionary";
        else if (rc == Z_MEM_ERROR)
            *why = "out of memory";
        else if (z.msg && strstr(z.msg, "incorrect data check"))
            *why = "checksum mismatch";
        else if (z.msg && strstr(z.msg, "header"))
            *why = "not a zlib stream (bad header)";
        else
            *why = "corrupt compressed data";
        break;
    }
    inflateEnd(&z);
    if (*outlen > maxout) {
        *outlen = maxout;
        *why = "more data than the block size in the header";
        return -1;
    }
    if (rc != Z_STREAM_END) {
        if (!(*why)[0]) *why = "truncated compressed data";
        return -1;
    }
    if (z.avail_in != 0) {
        *why = "bytes after the end of the zlib stream";
        return -1;
    }
    return 0;
}
