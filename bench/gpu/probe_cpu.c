/* The GPU probe's host build: the pair loop of probe_iact.h serial and on OpenMP threads, the
 * reference of the CUDA and offload builds, its check against all pairs (--brute), and the
 * comparison of two dumps (`probe_cpu compare A B`). */
#include <omp.h>

#include "probe_host.h"

/* Normwise: max |a - b| over max |a| of each quantity, and how many values differ in any bit. */
static int compare_dumps(const char *pa, const char *pb)
{
    FILE *fa = fopen(pa, "rb"), *fb = fopen(pb, "rb");
    if (!fa || !fb) {
        fprintf(stderr, "compare: cannot read %s\n", !fa ? pa : pb);
        if (fa) fclose(fa);
        if (fb) fclose(fb);
        return 2;
    }
    int32_t ha[2], hb[2];
    if (fread(ha, sizeof ha, 1, fa) != 1 || fread(hb, sizeof hb, 1, fb) != 1 || ha[0] != hb[0] ||
        ha[1] != hb[1]) {
        fprintf(stderr, "compare: %s and %s differ in dimension or N\n", pa, pb);
        fclose(fa);
        fclose(fb);
        return 2;
    }
    const size_t n = (size_t)ha[1];
    const char *names[5] = {"rho_a", "drho_b", "dux_b", "duy_b", "duz_b"};
    double *a = (double *)malloc(sizeof(double) * n), *b = (double *)malloc(sizeof(double) * n);
    long nd_a = 0, nd_b = 0;
    double rel_a = 0.0, rel_b = 0.0;
    int rc = 0;
    for (int q = 0; q < 5; ++q) {
        if (fread(a, sizeof(double), n, fa) != n || fread(b, sizeof(double), n, fb) != n) {
            fprintf(stderr, "compare: short file\n");
            rc = 2;
            break;
        }
        long nd = 0;
        double dmax = 0.0, amax = 0.0;
        for (size_t i = 0; i < n; ++i) {
            nd += memcmp(&a[i], &b[i], sizeof(double)) != 0;
            const double dd = fabs(a[i] - b[i]);
            if (dd > dmax || dd != dd) dmax = dd;
            if (fabs(a[i]) > amax) amax = fabs(a[i]);
        }
        const double rel = amax > 0.0 ? dmax / amax : dmax;
        printf("COMPARE_FIELD %s ndiff=%ld maxrel=%.3e\n", names[q], nd, rel);
        if (q == 0) {
            nd_a += nd;
            rel_a = rel;
        } else {
            nd_b += nd;
            if (rel > rel_b || rel != rel) rel_b = rel;
        }
    }
    if (!rc)
        printf("COMPARE N=%zu values_a=%zu ndiff_a=%ld maxrel_a=%.3e values_b=%zu ndiff_b=%ld "
               "maxrel_b=%.3e\n",
               n, n, nd_a, rel_a, 4 * n, nd_b, rel_b);
    free(a);
    free(b);
    fclose(fa);
    fclose(fb);
    return rc;
}

/* The all-pairs sums in the original order (no cells): density, pair count and rate. */
static int brute_check(const probe_consts *c, const double *pos, const double *vel,
                       const double *rho, const int *idx, const double *rho_a, const double *rate,
                       long pairs)
{
    const long n = c->n;
    double *p = (double *)malloc(sizeof(double) * n);
    for (long i = 0; i < n; ++i) p[i] = probe_tait(c, rho[i]);
    double *rb = (double *)malloc(sizeof(double) * n),
           *qb = (double *)malloc(sizeof(double) * n * 4);
    long bp = 0;
#pragma omp parallel for schedule(static) reduction(+ : bp) num_threads(omp_get_num_procs())
    for (long i = 0; i < n; ++i) {
        double sum = 0.0, out[4] = {0.0, 0.0, 0.0, 0.0}, xi[3] = {0}, ui[3] = {0};
        for (int a = 0; a < c->d; ++a) {
            xi[a] = pos[a * n + i];
            ui[a] = vel[a * n + i];
        }
        for (long j = 0; j < n; ++j) {
            double xij[3] = {0}, uj[3] = {0}, r2 = 0.0;
            for (int a = 0; a < c->d; ++a) {
                xij[a] = probe_min_image(c, xi[a] - pos[a * n + j]);
                r2 += xij[a] * xij[a];
                uj[a] = vel[a * n + j];
            }
            if (!(r2 < c->rc2)) continue;
            sum += c->m * probe_w(c, sqrt(r2));
            if (j == i) continue;
            ++bp;
            double pd, pu[3] = {0};
            probe_rate_pair(c->d, c, rho[i], p[i], ui, rho[j], p[j], uj, xij, r2,
                            probe_dwr(c, sqrt(r2)), &pd, pu);
            out[0] += pd;
            for (int a = 0; a < 3; ++a) out[1 + a] += pu[a];
        }
        rb[i] = sum;
        for (int q = 0; q < 4; ++q) qb[q * n + i] = out[q];
    }
    double rel[5] = {0}, mx[5] = {0};
    for (long k = 0; k < n; ++k) {
        const long i = idx[k];
        const double va[5] = {rho_a[k], rate[k], rate[n + k], rate[2 * n + k], rate[3 * n + k]};
        const double vb[5] = {rb[i], qb[i], qb[n + i], qb[2 * n + i], qb[3 * n + i]};
        for (int q = 0; q < 5; ++q) {
            if (fabs(va[q] - vb[q]) > rel[q] || va[q] != va[q]) rel[q] = fabs(va[q] - vb[q]);
            if (fabs(vb[q]) > mx[q]) mx[q] = fabs(vb[q]);
        }
    }
    double worst = 0.0;
    for (int q = 0; q < 5; ++q) {
        rel[q] = mx[q] > 0.0 ? rel[q] / mx[q] : rel[q];
        if (rel[q] > worst || rel[q] != rel[q]) worst = rel[q];
    }
    const int ok = bp == pairs && worst <= 1e-12;
    printf("BRUTE %s pairs_cells=%ld pairs_brute=%ld maxrel_rho=%.3e maxrel_drho=%.3e "
           "maxrel_du=%.3e,%.3e,%.3e\n",
           ok ? "ok" : "FAIL", pairs, bp, rel[0], rel[1], rel[2], rel[3], rel[4]);
    free(p);
    free(rb);
    free(qb);
    return !ok;
}

int main(int argc, char **argv)
{
    if (argc == 4 && !strcmp(argv[1], "compare")) return compare_dumps(argv[2], argv[3]);
    probe_opts o;
    int rc = probe_parse(argc, argv, &o);
    if (rc) return rc;
    if (o.threads > 0) omp_set_num_threads(o.threads);
    const probe_consts c = probe_setup(&o);
    const long n = c.n, d = c.d;
    double *pos = (double *)malloc(sizeof(double) * d * n);
    double *vel = (double *)malloc(sizeof(double) * d * n);
    double *rho = (double *)malloc(sizeof(double) * n);
    double *spos = (double *)malloc(sizeof(double) * d * n);
    double *svel = (double *)malloc(sizeof(double) * d * n);
    double *srho = (double *)malloc(sizeof(double) * n);
    double *rho_a = (double *)malloc(sizeof(double) * n);
    double *p = (double *)malloc(sizeof(double) * n);
    double *rate = (double *)calloc((size_t)n * 4, sizeof(double));
    int *cell = (int *)malloc(sizeof(int) * n), *idx = (int *)malloc(sizeof(int) * n);
    int *off = (int *)malloc(sizeof(int) * ((size_t)c.ncell + 1));
    if (!pos || !vel || !rho || !spos || !svel || !srho || !rho_a || !p || !rate || !cell || !idx ||
        !off) {
        fprintf(stderr, "probe_cpu: out of memory for N = %ld\n", n);
        return 1;
    }
    probe_init(&c, pos, vel, rho);

    probe_result r = {"cpu", "host", omp_get_max_threads(), 0, 1e30, 1e30, 1e30, 0.0};
    r.bytes_per_particle = (double)(sizeof(double) * (4 * d + 8) + 2 * sizeof(int)) +
                           (double)sizeof(int) * (c.ncell + 1) / n;
    for (int rep = 0; rep < o.reps; ++rep) {
        double t0 = probe_now();
        probe_cells_host(&c, pos, cell, off, idx);
#pragma omp parallel for schedule(static)
        for (long k = 0; k < n; ++k) {
            const long i = idx[k];
            for (int a = 0; a < d; ++a) {
                spos[a * n + k] = pos[a * n + i];
                svel[a * n + k] = vel[a * n + i];
            }
            srho[k] = rho[i];
        }
        double t1 = probe_now();
#pragma omp parallel for schedule(static)
        for (long k = 0; k < n; ++k) rho_a[k] = probe_density(&c, spos, off, (int)k);
        double t2 = probe_now();
#pragma omp parallel for schedule(static)
        for (long k = 0; k < n; ++k) p[k] = probe_tait(&c, srho[k]);
#pragma omp parallel for schedule(static)
        for (long k = 0; k < n; ++k) {
            double out[4];
            probe_rate(&c, spos, svel, srho, p, off, (int)k, out);
            for (int q = 0; q < 4; ++q) rate[q * n + k] = out[q];
        }
        double t3 = probe_now();
        if (t1 - t0 < r.t_cells) r.t_cells = t1 - t0;
        if (t2 - t1 < r.t_a) r.t_a = t2 - t1;
        if (t3 - t2 < r.t_b) r.t_b = t3 - t2;
    }
    long pairs = 0; /* not timed: on all processors, whatever --threads says */
#pragma omp parallel for schedule(static) reduction(+ : pairs) num_threads(omp_get_num_procs())
    for (long k = 0; k < n; ++k) pairs += probe_count(&c, spos, off, (int)k);
    r.pairs = pairs;
    probe_print(&c, &o, &r);
    if (o.dump && probe_dump(o.dump, &c, rho_a, rate)) rc = 1;
    if (o.brute && brute_check(&c, pos, vel, rho, idx, rho_a, rate, pairs)) rc = 1;
    free(pos);
    free(vel);
    free(rho);
    free(spos);
    free(svel);
    free(srho);
    free(rho_a);
    free(p);
    free(rate);
    free(cell);
    free(idx);
    free(off);
    return rc;
}
