/* The GPU probe's host side, shared by its three builds (C for probe_cpu.c and probe_omp.c, C++
 * for probe.cu): options, the particle set-up (every build starts from the same host arrays), the
 * cell list's host reference, timing, the result line and the dump of (a) and (b). */
#ifndef PROBE_HOST_H
#define PROBE_HOST_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "probe_iact.h"

typedef struct probe_opts {
    int d, nx, reps, threads;
    const char *dump; /* file for (a) and (b), or NULL */
    int brute;        /* probe_cpu: check against an all-pairs sum */
} probe_opts;

static void probe_usage(const char *prog)
{
    fprintf(stderr,
            "usage: %s [--dim 2|3] [--nx NX] [--reps R] [--threads T] [--dump FILE]%s\n"
            "  N = NX^dim particles on a perturbed lattice in the periodic unit box\n",
            prog, " [--brute]");
}

static int probe_parse(int argc, char **argv, probe_opts *o)
{
    o->d = 2;
    o->nx = 100;
    o->reps = 3;
    o->threads = 0;
    o->dump = NULL;
    o->brute = 0;
    for (int k = 1; k < argc; ++k) {
        const char *a = argv[k];
        const char *v = k + 1 < argc ? argv[k + 1] : NULL;
        if (!strcmp(a, "--brute")) {
            o->brute = 1;
            continue;
        }
        if (!v) {
            fprintf(stderr, "%s: option %s needs a value\n", argv[0], a);
            return 2;
        }
        ++k;
        if (!strcmp(a, "--dim"))
            o->d = atoi(v);
        else if (!strcmp(a, "--nx"))
            o->nx = atoi(v);
        else if (!strcmp(a, "--reps"))
            o->reps = atoi(v);
        else if (!strcmp(a, "--threads"))
            o->threads = atoi(v);
        else if (!strcmp(a, "--dump"))
            o->dump = v;
        else {
            fprintf(stderr, "%s: unknown option %s\n", argv[0], a);
            probe_usage(argv[0]);
            return 2;
        }
    }
    if (o->d != 2 && o->d != 3) {
        fprintf(stderr, "%s: --dim must be 2 or 3 (got %d)\n", argv[0], o->d);
        return 2;
    }
    const double nmax = 2.0e9;
    if (o->nx < 11 || pow((double)o->nx, o->d) > nmax) {
        fprintf(stderr, "%s: --nx must be >= 11 (3 cells a side) with nx^dim <= 2e9 (got %d)\n",
                argv[0], o->nx);
        return 2;
    }
    if (o->reps < 1) o->reps = 1;
    return 0;
}

#define PROBE_PI 3.14159265358979323846

static probe_consts probe_setup(const probe_opts *o)
{
    probe_consts c;
    memset(&c, 0, sizeof c);
    c.d = o->d;
    long n = 1;
    for (int a = 0; a < o->d; ++a) n *= o->nx;
    c.n = (int)n;
    c.L = 1.0;
    c.ds = c.L / o->nx;
    c.h = 1.2 * c.ds;
    c.inv_h = 1.0 / c.h;
    c.rc2 = (PROBE_SUPPORT * c.h) * (PROBE_SUPPORT * c.h);
    const int nc = (int)(c.L / (PROBE_SUPPORT * c.h));
    c.ncell = 1;
    for (int a = 0; a < 3; ++a) {
        c.nc[a] = a < c.d ? nc : 1;
        c.ncell *= c.nc[a];
    }
    c.inv_cw = nc / c.L;
    /* 001 Table 1 (QS): 7/(478π) in 2D, 1/(120π) in 3D (src/kernels/kernels.c) */
    c.sigma = (c.d == 2 ? 7.0 / (478.0 * PROBE_PI) : 1.0 / (120.0 * PROBE_PI)) / pow(c.h, c.d);
    c.rho0 = 1.0;
    c.m = c.rho0 * pow(c.ds, c.d);
    const double c0 = 10.0;
    c.B = c.rho0 * c0 * c0 / 7.0;
    c.nu = 0.01;
    c.eps2 = 0.01 * c.h * c.h;
    return c;
}

/* splitmix64: a counter-based generator, so particle i's values depend on i alone. */
static uint64_t probe_mix(uint64_t z)
{
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}
/* A uniform value in [-1, 1) from particle i's stream k. */
static double probe_uniform(uint64_t i, int k)
{
    const uint64_t z = probe_mix(i * 8 + (uint64_t)k + 0x5eed);
    return (double)(z >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

/* The lattice perturbed by up to 0.25 ds per coordinate, a Taylor-Green velocity with 1 %
 * noise and a density within 1 % of ρ0 (the input of (b), so that (b) is compared alone). */
static void probe_init(const probe_consts *c, double *pos, double *vel, double *rho)
{
    const long n = c->n;
    const int nx = (int)(c->L / c->ds + 0.5);
    for (long i = 0; i < n; ++i) {
        long k = i;
        double x[3] = {0.0, 0.0, 0.0};
        for (int a = 0; a < c->d; ++a) {
            x[a] = ((double)(k % nx) + 0.5 + 0.25 * probe_uniform(i, a)) * c->ds;
            if (x[a] < 0.0) x[a] += c->L;
            if (x[a] >= c->L) x[a] -= c->L;
            k /= nx;
            pos[a * n + i] = x[a];
        }
        const double sx = sin(2.0 * PROBE_PI * x[0]), cx = cos(2.0 * PROBE_PI * x[0]);
        const double sy = sin(2.0 * PROBE_PI * x[1]), cy = cos(2.0 * PROBE_PI * x[1]);
        vel[0 * n + i] = sx * cy + 0.01 * probe_uniform(i, 3);
        vel[1 * n + i] = -cx * sy + 0.01 * probe_uniform(i, 4);
        if (c->d == 3) vel[2 * n + i] = 0.01 * probe_uniform(i, 5);
        rho[i] = c->rho0 * (1.0 + 0.01 * probe_uniform(i, 6));
    }
}

static double probe_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* The results of one build, printed as one line that run_probe.sh reads. */
typedef struct probe_result {
    const char *build; /* cpu, cuda, omp */
    const char *where; /* host, device name, "host-fallback" */
    int threads;
    long pairs;               /* pairs j != i within 3h */
    double t_cells, t_a, t_b; /* minimum over the repetitions, seconds */
    double bytes_per_particle;
} probe_result;

static void probe_print(const probe_consts *c, const probe_opts *o, const probe_result *r)
{
    const double n = (double)c->n, pa = (double)r->pairs + n; /* (a) visits j = i too */
    printf("RESULT build=%s where=%s threads=%d dim=%d nx=%d N=%d reps=%d pairs=%ld "
           "pairs_per_particle=%.2f t_cells=%.6e t_a=%.6e t_b=%.6e pairs_per_s_a=%.4e "
           "pairs_per_s_b=%.4e ns_per_particle_a=%.4f ns_per_particle_b=%.4f "
           "ns_per_particle_cells=%.4f bytes_per_particle=%.1f\n",
           r->build, r->where, r->threads, c->d, o->nx, c->n, o->reps, r->pairs,
           (double)r->pairs / n, r->t_cells, r->t_a, r->t_b, pa / r->t_a, (double)r->pairs / r->t_b,
           1e9 * r->t_a / n, 1e9 * r->t_b / n, 1e9 * r->t_cells / n, r->bytes_per_particle);
    fflush(stdout);
}

/* The dump: a header (d, N) then ρ from (a) and (b)'s dρ, du_x, du_y, du_z, each N values in the
 * sorted (cell, index) order that every build shares. */
static int probe_dump(const char *path, const probe_consts *c, const double *rho_a,
                      const double *rate)
{
    FILE *f = fopen(path, "wb");
    if (!f) {
        fprintf(stderr, "cannot write %s\n", path);
        return 1;
    }
    const int32_t hdr[2] = {c->d, c->n};
    int ok = fwrite(hdr, sizeof hdr, 1, f) == 1;
    ok = ok && fwrite(rho_a, sizeof(double), (size_t)c->n, f) == (size_t)c->n;
    ok = ok && fwrite(rate, sizeof(double), (size_t)c->n * 4, f) == (size_t)c->n * 4;
    ok = (fclose(f) == 0) && ok;
    if (!ok) fprintf(stderr, "short write to %s\n", path);
    return !ok;
}

/* The host's stable counting sort by cell: off[ncell + 1], idx[n] (sorted slot -> particle). */
static void probe_cells_host(const probe_consts *c, const double *pos, int *cell, int *off,
                             int *idx)
{
    for (int k = 0; k <= c->ncell; ++k) off[k] = 0;
    for (int i = 0; i < c->n; ++i) {
        cell[i] = probe_cell_of(c, pos, i);
        ++off[cell[i] + 1];
    }
    for (int k = 0; k < c->ncell; ++k) off[k + 1] += off[k];
    /* off[k] serves as cell k's fill pointer, then is shifted back by one cell */
    for (int i = 0; i < c->n; ++i) idx[off[cell[i]]++] = i;
    for (int k = c->ncell; k > 0; --k) off[k] = off[k - 1];
    off[0] = 0;
}

#endif
