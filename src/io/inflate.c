/* zlib/DEFLATE decompression (RFC 1950, RFC 1951) for the vtkZLibDataCompressor blocks of .vtu
 * files, so that reading them needs no library beyond libc. A canonical-Huffman decoder in the
 * manner of Mark Adler's puff.c: small and easy to check rather than fast; every length,
 * distance and table size read from the input is validated before use. */
#include <stdlib.h>
#include <string.h>

#include "io/read_internal.h"

#define MAXBITS 15
#define MAXLCODES 286
#define MAXDCODES 30
#define FIXLCODES 288

typedef struct inf_state {
    const unsigned char *in;
    size_t inlen, inpos;
    uint32_t bitbuf;
    int bitcnt;
    unsigned char **out;
    size_t *outlen, *outcap, maxout;
    int eof; /* the input ran out: every later bit reads as 0 and the caller fails */
    const char *why;
} inf_state;

typedef struct huffman {
    short count[MAXBITS + 1];
    short symbol[FIXLCODES];
} huffman;

static int bits(inf_state *s, int need)
{
    uint32_t val = s->bitbuf;
    while (s->bitcnt < need) {
        if (s->inpos == s->inlen) {
            s->eof = 1;
            return 0;
        }
        val |= (uint32_t)s->in[s->inpos++] << s->bitcnt;
        s->bitcnt += 8;
    }
    s->bitbuf = (uint32_t)(val >> need);
    s->bitcnt -= need;
    return (int)(val & ((1u << need) - 1u));
}

static int put(inf_state *s, unsigned char byte)
{
    if (*s->outlen >= s->maxout) {
        s->why = "more data than the block size in the header";
        return -1;
    }
    if (*s->outlen == *s->outcap) {
        size_t cap = *s->outcap ? 2 * *s->outcap : 4096;
        if (cap > s->maxout) cap = s->maxout;
        unsigned char *b = realloc(*s->out, cap);
        if (!b) {
            s->why = "out of memory";
            return -1;
        }
        *s->out = b;
        *s->outcap = cap;
    }
    (*s->out)[(*s->outlen)++] = byte;
    return 0;
}

static int decode(inf_state *s, const huffman *h)
{
    int code = 0, first = 0, index = 0;
    for (int len = 1; len <= MAXBITS; ++len) {
        code |= bits(s, 1);
        if (s->eof) return -1;
        int count = h->count[len];
        if (code - count < first) return h->symbol[index + (code - first)];
        index += count;
        first += count;
        first <<= 1;
        code <<= 1;
    }
    return -1; /* no code of any length matches: an incomplete code was used */
}

/* Builds the decoding tables from code lengths. Returns 0 for a complete code, > 0 for an
 * incomplete one, < 0 for an over-subscribed one. */
static int construct(huffman *h, const short *length, int n)
{
    short offs[MAXBITS + 1];
    for (int len = 0; len <= MAXBITS; ++len) h->count[len] = 0;
    for (int sym = 0; sym < n; ++sym) h->count[length[sym]]++;
    if (h->count[0] == n) return 0;
    int left = 1;
    for (int len = 1; len <= MAXBITS; ++len) {
        left <<= 1;
        left -= h->count[len];
        if (left < 0) return left;
    }
    offs[1] = 0;
    for (int len = 1; len < MAXBITS; ++len) offs[len + 1] = (short)(offs[len] + h->count[len]);
    for (int sym = 0; sym < n; ++sym)
        if (length[sym] != 0) h->symbol[offs[length[sym]]++] = (short)sym;
    return left;
}

static int stored(inf_state *s)
{
    s->bitbuf = 0;
    s->bitcnt = 0;
    if (s->inlen - s->inpos < 4) {
        s->why = "truncated stored block";
        return -1;
    }
    unsigned len = s->in[s->inpos] | (unsigned)s->in[s->inpos + 1] << 8;
    unsigned nlen = s->in[s->inpos + 2] | (unsigned)s->in[s->inpos + 3] << 8;
    s->inpos += 4;
    if (len != (~nlen & 0xffffu)) {
        s->why = "stored block length does not match its complement";
        return -1;
    }
    if (s->inlen - s->inpos < len) {
        s->why = "truncated stored block";
        return -1;
    }
    for (unsigned k = 0; k < len; ++k)
        if (put(s, s->in[s->inpos++])) return -1;
    return 0;
}

static int codes(inf_state *s, const huffman *lencode, const huffman *distcode)
{
    static const short lbase[29] = {3,  4,  5,  6,  7,  8,  9,  10, 11,  13,  15,  17,  19,  23, 27,
                                    31, 35, 43, 51, 59, 67, 83, 99, 115, 131, 163, 195, 227, 258};
    static const short lext[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2,
                                   2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};
    static const short dbase[30] = {1,    2,    3,    4,    5,    7,    9,    13,    17,    25,
                                    33,   49,   65,   97,   129,  193,  257,  385,   513,   769,
                                    1025, 1537, 2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577};
    static const short dext[30] = {0, 0, 0, 0, 1, 1, 2, 2,  3,  3,  4,  4,  5,  5,  6,
                                   6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13};
    for (;;) {
        int sym = decode(s, lencode);
        if (sym < 0) {
            s->why = s->eof ? "truncated compressed data" : "invalid literal/length code";
            return -1;
        }
        if (sym < 256) {
            if (put(s, (unsigned char)sym)) return -1;
            continue;
        }
        if (sym == 256) return 0;
        sym -= 257;
        if (sym >= 29) {
            s->why = "invalid length symbol";
            return -1;
        }
        int len = lbase[sym] + bits(s, lext[sym]);
        int dsym = decode(s, distcode);
        if (dsym < 0 || dsym >= 30) {
            s->why = s->eof ? "truncated compressed data" : "invalid distance code";
            return -1;
        }
        size_t dist = (size_t)dbase[dsym] + (size_t)bits(s, dext[dsym]);
        if (s->eof) {
            s->why = "truncated compressed data";
            return -1;
        }
        if (dist > *s->outlen) {
            s->why = "distance too far back";
            return -1;
        }
        for (int k = 0; k < len; ++k)
            if (put(s, (*s->out)[*s->outlen - dist])) return -1;
    }
}

/* The fixed codes of RFC 1951 section 3.2.6, built per block: cheap, and no shared state
 * between threads. */
static int fixed(inf_state *s)
{
    huffman lencode, distcode;
    short lengths[FIXLCODES];
    int sym = 0;
    for (; sym < 144; ++sym) lengths[sym] = 8;
    for (; sym < 256; ++sym) lengths[sym] = 9;
    for (; sym < 280; ++sym) lengths[sym] = 7;
    for (; sym < FIXLCODES; ++sym) lengths[sym] = 8;
    construct(&lencode, lengths, FIXLCODES);
    for (sym = 0; sym < MAXDCODES; ++sym) lengths[sym] = 5;
    construct(&distcode, lengths, MAXDCODES);
    return codes(s, &lencode, &distcode);
}

static int dynamic(inf_state *s)
{
    static const short order[19] = {16, 17, 18, 0, 8,  7, 9,  6, 10, 5,
                                    11, 4,  12, 3, 13, 2, 14, 1, 15};
    short lengths[MAXLCODES + MAXDCODES];
    huffman lencode, distcode;
    int nlen = bits(s, 5) + 257;
    int ndist = bits(s, 5) + 1;
    int ncode = bits(s, 4) + 4;
    if (s->eof) {
        s->why = "truncated compressed data";
        return -1;
    }
    if (nlen > MAXLCODES || ndist > MAXDCODES) {
        s->why = "bad code counts";
        return -1;
    }
    int index;
    for (index = 0; index < ncode; ++index) lengths[order[index]] = (short)bits(s, 3);
    for (; index < 19; ++index) lengths[order[index]] = 0;
    if (s->eof) {
        s->why = "truncated compressed data";
        return -1;
    }
    if (construct(&lencode, lengths, 19) != 0) {
        s->why = "incomplete code-length code";
        return -1;
    }
    index = 0;
    while (index < nlen + ndist) {
        int sym = decode(s, &lencode);
        if (sym < 0) {
            s->why = s->eof ? "truncated compressed data" : "invalid code-length code";
            return -1;
        }
        if (sym < 16) {
            lengths[index++] = (short)sym;
            continue;
        }
        short len = 0;
        int rep;
        if (sym == 16) {
            if (index == 0) {
                s->why = "repeat with no first length";
                return -1;
            }
            len = lengths[index - 1];
            rep = 3 + bits(s, 2);
        } else if (sym == 17) {
            rep = 3 + bits(s, 3);
        } else {
            rep = 11 + bits(s, 7);
        }
        if (index + rep > nlen + ndist) {
            s->why = "too many code lengths";
            return -1;
        }
        while (rep--) lengths[index++] = len;
    }
    if (s->eof) {
        s->why = "truncated compressed data";
        return -1;
    }
    if (lengths[256] == 0) {
        s->why = "no end-of-block code";
        return -1;
    }
    int err = construct(&lencode, lengths, nlen);
    if (err && (err < 0 || nlen != lencode.count[0] + lencode.count[1])) {
        s->why = "incomplete literal/length code";
        return -1;
    }
    err = construct(&distcode, lengths + nlen, ndist);
    if (err && (err < 0 || ndist != distcode.count[0] + distcode.count[1])) {
        s->why = "incomplete distance code";
        return -1;
    }
    return codes(s, &lencode, &distcode);
}

static uint32_t adler32(const unsigned char *p, size_t n)
{
    uint32_t a = 1, b = 0;
    while (n > 0) {
        size_t run = n < 5552 ? n : 5552; /* the largest run before b can overflow */
        n -= run;
        while (run--) {
            a += *p++;
            b += a;
        }
        a %= 65521u;
        b %= 65521u;
    }
    return b << 16 | a;
}

int consph_rd_inflate(const unsigned char *in, size_t inlen, unsigned char **out, size_t *outlen,
                      size_t *outcap, size_t maxout, const char **why)
{
    *outlen = 0;
    *why = "";
    if (inlen < 6) {
        *why = "too short for a zlib stream";
        return -1;
    }
    unsigned cmf = in[0], flg = in[1];
    if ((cmf & 0x0f) != 8 || (cmf >> 4) > 7 || (cmf * 256 + flg) % 31 != 0 || (flg & 0x20)) {
        *why = "not a zlib stream (bad header)";
        return -1;
    }
    inf_state s;
    memset(&s, 0, sizeof s);
    s.in = in;
    s.inlen = inlen - 4; /* the Adler-32 trailer */
    s.inpos = 2;
    s.out = out;
    s.outlen = outlen;
    s.outcap = outcap;
    s.maxout = maxout;
    int last;
    do {
        last = bits(&s, 1);
        int type = bits(&s, 2);
        if (s.eof) {
            *why = "truncated compressed data";
            return -1;
        }
        int rc = type == 0   ? stored(&s)
                 : type == 1 ? fixed(&s)
                 : type == 2 ? dynamic(&s)
                             : (s.why = "invalid block type", -1);
        if (rc) {
            *why = s.why;
            return -1;
        }
    } while (!last);
    const unsigned char *t = in + inlen - 4;
    uint32_t want = (uint32_t)t[0] << 24 | (uint32_t)t[1] << 16 | (uint32_t)t[2] << 8 | t[3];
    if (adler32(*out, *outlen) != want) {
        *why = "checksum mismatch";
        return -1;
    }
    return 0;
}
