/* The GPU probe's OpenMP offload build (gcc -foffload=nvptx-none): the pair loop of probe_iact.h
 * in `target teams distribute parallel for` regions over device-resident arrays, the cell list
 * built on the device as in probe.cu (atomic counts, blocked scan, atomic scatter, each cell
 * sorted by particle index). Without a device (OMP_TARGET_OFFLOAD=DISABLED, no plugin or no
 * driver) the same regions run on the host and must equal probe_cpu bitwise. */
#include <omp.h>

#pragma omp declare target
#include "probe_iact.h"
#pragma omp end declare target
#include "probe_host.h"

int main(int argc, char **argv)
{
    probe_opts o;
    int rc = probe_parse(argc, argv, &o);
    if (rc) return rc;
    if (o.threads > 0) omp_set_num_threads(o.threads);
    const probe_consts c = probe_setup(&o);
    const long n = c.n, d = c.d, nd = d * n, n4 = 4 * n, ncell = c.ncell;
    double *pos = (double *)malloc(sizeof(double) * nd);
    double *vel = (double *)malloc(sizeof(double) * nd);
    double *rho = (double *)malloc(sizeof(double) * n);
    double *spos = (double *)malloc(sizeof(double) * nd);
    double *svel = (double *)malloc(sizeof(double) * nd);
    double *srho = (double *)malloc(sizeof(double) * n);
    double *rho_a = (double *)malloc(sizeof(double) * n);
    double *p = (double *)malloc(sizeof(double) * n);
    double *rate = (double *)malloc(sizeof(double) * n4);
    int *cell = (int *)malloc(sizeof(int) * n), *idx = (int *)malloc(sizeof(int) * n);
    int *count = (int *)malloc(sizeof(int) * ncell), *fill = (int *)malloc(sizeof(int) * ncell);
    int *off = (int *)malloc(sizeof(int) * (ncell + 1));
    int *bsum = (int *)malloc(sizeof(int) * PROBE_SCAN_BLOCKS);
    if (!pos || !vel || !rho || !spos || !svel || !srho || !rho_a || !p || !rate || !cell || !idx ||
        !count || !fill || !off || !bsum) {
        fprintf(stderr, "probe_omp: out of host memory for N = %ld\n", n);
        return 1;
    }
    probe_init(&c, pos, vel, rho);

    const int ndev = omp_get_num_devices();
    int on_device = 0;
#pragma omp target map(from : on_device)
    on_device = !omp_is_initial_device();
    printf("OFFLOAD devices=%d default=%d target_ran_on=%s\n", ndev, omp_get_default_device(),
           on_device ? "device" : "host");
    probe_result r = {"omp", on_device ? "device" : "host-fallback", 1, 0, 1e30, 1e30, 1e30, 0.0};
    if (!on_device) r.threads = omp_get_max_threads();
    r.bytes_per_particle = (double)(sizeof(double) * (4 * d + 8) + 2 * sizeof(int)) +
                           (double)sizeof(int) * (2 * ncell + 1 + PROBE_SCAN_BLOCKS) / n;
    long pairs = 0;
#pragma omp target data map(to                                                                     \
                            : pos [0:nd], vel [0:nd], rho [0:n])                                   \
    map(alloc                                                                                      \
        : spos [0:nd], svel [0:nd], srho [0:n], p [0:n], cell [0:n], idx [0:n], count [0:ncell],   \
          fill [0:ncell], off [0:ncell + 1], bsum [0:PROBE_SCAN_BLOCKS])                           \
        map(from                                                                                   \
            : rho_a [0:n], rate [0:n4])
    {
        for (int rep = -1; rep < o.reps; ++rep) { /* rep -1: warm-up, not timed */
            double t0 = probe_now();
#pragma omp target teams distribute parallel for firstprivate(c)
            for (long k = 0; k < ncell; ++k) {
                count[k] = 0;
                fill[k] = 0;
            }
#pragma omp target teams distribute parallel for firstprivate(c)
            for (long i = 0; i < n; ++i) {
                cell[i] = probe_cell_of(&c, pos, (int)i);
#pragma omp atomic update
                count[cell[i]] += 1;
            }
#pragma omp target teams distribute parallel for firstprivate(c)
            for (int b = 0; b < PROBE_SCAN_BLOCKS; ++b)
                bsum[b] = probe_scan_block_sum(count, (int)ncell, b);
#pragma omp target
            probe_scan_blocks(bsum, off, (int)ncell);
#pragma omp target teams distribute parallel for firstprivate(c)
            for (int b = 0; b < PROBE_SCAN_BLOCKS; ++b)
                probe_scan_block_write(count, bsum, off, (int)ncell, b);
#pragma omp target teams distribute parallel for firstprivate(c)
            for (long i = 0; i < n; ++i) {
                int slot;
#pragma omp atomic capture
                slot = fill[cell[i]]++;
                idx[off[cell[i]] + slot] = (int)i;
            }
#pragma omp target teams distribute parallel for firstprivate(c)
            for (long k = 0; k < ncell; ++k) probe_sort_cell(off, idx, (int)k);
#pragma omp target teams distribute parallel for firstprivate(c)
            for (long k = 0; k < n; ++k) {
                const long i = idx[k];
                for (int a = 0; a < d; ++a) {
                    spos[a * n + k] = pos[a * n + i];
                    svel[a * n + k] = vel[a * n + i];
                }
                srho[k] = rho[i];
            }
            double t1 = probe_now();
#pragma omp target teams distribute parallel for firstprivate(c)
            for (long k = 0; k < n; ++k) rho_a[k] = probe_density(&c, spos, off, (int)k);
            double t2 = probe_now();
#pragma omp target teams distribute parallel for firstprivate(c)
            for (long k = 0; k < n; ++k) p[k] = probe_tait(&c, srho[k]);
#pragma omp target teams distribute parallel for firstprivate(c)
            for (long k = 0; k < n; ++k) {
                double out[4];
                probe_rate(&c, spos, svel, srho, p, off, (int)k, out);
                for (int q = 0; q < 4; ++q) rate[q * n + k] = out[q];
            }
            double t3 = probe_now();
            if (rep < 0) continue;
            if (t1 - t0 < r.t_cells) r.t_cells = t1 - t0;
            if (t2 - t1 < r.t_a) r.t_a = t2 - t1;
            if (t3 - t2 < r.t_b) r.t_b = t3 - t2;
        }
#pragma omp target teams distribute parallel for reduction(+ : pairs) map(tofrom : pairs) firstprivate(c)
        for (long k = 0; k < n; ++k) pairs += probe_count(&c, spos, off, (int)k);
#pragma omp target update from(idx [0:n])
    }
    r.pairs = pairs;
    probe_print(&c, &o, &r);
    if (o.dump && probe_dump(o.dump, &c, rho_a, rate)) rc = 1;
    /* the device's cell order must be the host's stable counting sort */
    int *hcell = (int *)malloc(sizeof(int) * n), *hidx = (int *)malloc(sizeof(int) * n);
    int *hoff = (int *)malloc(sizeof(int) * (ncell + 1));
    probe_cells_host(&c, pos, hcell, hoff, hidx);
    long bad = 0;
    for (long k = 0; k < n; ++k) bad += hidx[k] != idx[k];
    printf("CELLORDER %s mismatches=%ld\n", bad ? "FAIL" : "ok", bad);
    if (bad) rc = 1;
    return rc;
}
