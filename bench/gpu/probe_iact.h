/* The GPU probe's pair terms and per-particle gathers, shared by the host C (probe_cpu.c), CUDA
 * (probe.cu) and OpenMP offload (probe_omp.c) builds: plain C over scalars and arrays, no library
 * type, every function static inline, as the project's src/schemes/(name)/iact.h are. The order
 * of every sum is fixed (neighbour cells in one loop order, particles of a cell in index order), so
 * every build sums the same terms in the same order; only FMA contraction may differ. */
#ifndef PROBE_IACT_H
#define PROBE_IACT_H

#include <math.h>

#if defined(__CUDACC__)
#define PROBE_FN static inline __host__ __device__
#elif defined(__GNUC__)
#define PROBE_FN static inline __attribute__((always_inline))
#else
#define PROBE_FN static inline
#endif

#define PROBE_SUPPORT 3.0 /* the quintic spline's radius, in h */

/* The constants of a probe run: a periodic box [0, L)^d, nc[a] cells per side (each >= 3h). */
typedef struct probe_consts {
    int d, n;         /* dimension, particle count */
    int nc[3], ncell; /* cells per side (1 in unused dimensions) and in all */
    double L, ds;     /* box side, lattice spacing */
    double h, inv_h;  /* smoothing length h = 1.2 ds */
    double rc2;       /* (3h)^2 */
    double inv_cw;    /* cells per unit length */
    double sigma;     /* the quintic normalisation over h^d */
    double m, rho0;   /* particle mass, reference density */
    double B;         /* Tait's ρ0 c0²/γ */
    double nu, eps2;  /* kinematic viscosity; 0.01 h² in Morris's 1/(r² + ε) */
} probe_consts;

PROBE_FN double probe_pow4(double t)
{
    double t2 = t * t;
    return t2 * t2;
}
PROBE_FN double probe_pow5(double t)
{
    double t2 = t * t;
    return t2 * t2 * t;
}
PROBE_FN double probe_positive(double t)
{
    return t > 0.0 ? t : 0.0;
}

/* The quintic spline W(r) (001 Table 1 "QS", src/kernels/kernels.c quintic_f). */
PROBE_FN double probe_w(const probe_consts *c, double r)
{
    const double q = r * c->inv_h;
    const double f = probe_pow5(3.0 - q) - 6.0 * probe_pow5(probe_positive(2.0 - q)) +
                     15.0 * probe_pow5(probe_positive(1.0 - q));
    return q >= PROBE_SUPPORT ? 0.0 : c->sigma * f;
}

/* (1/r) dW/dr, so that ∇W_ij = dwr x_ij; r > 0. */
PROBE_FN double probe_dwr(const probe_consts *c, double r)
{
    const double q = r * c->inv_h;
    const double df = -5.0 * probe_pow4(3.0 - q) + 30.0 * probe_pow4(probe_positive(2.0 - q)) -
                      75.0 * probe_pow4(probe_positive(1.0 - q));
    return q >= PROBE_SUPPORT ? 0.0 : c->sigma * df * c->inv_h / r;
}

/* Tait's equation of state, γ = 7 by multiplication. */
PROBE_FN double probe_tait(const probe_consts *c, double rho)
{
    const double x = rho / c->rho0, x2 = x * x, x4 = x2 * x2;
    return c->B * (x4 * x2 * x - 1.0);
}

/* One pair of the WCSPH-like rate: continuity m u_ij·∇W_ij, the symmetric pressure gradient
 * -m (p_i/ρ_i² + p_j/ρ_j²) ∇W_ij and Morris et al. 1997's laminar viscosity (Cleary's form, as
 * src/schemes/pysph/iact.h pysph_wcsph_pair). */
PROBE_FN void probe_rate_pair(int d, const probe_consts *c, double rhoi, double pi,
                              const double ui[3], double rhoj, double pj, const double uj[3],
                              const double xij[3], double r2, double dwr, double *drho,
                              double du[3])
{
    const double m = c->m, tij = pi / (rhoi * rhoi) + pj / (rhoj * rhoj);
    double uij[3] = {0.0, 0.0, 0.0}, gw[3] = {0.0, 0.0, 0.0}, udw = 0.0, xdw = 0.0;
    for (int a = 0; a < d; ++a) {
        uij[a] = ui[a] - uj[a];
        gw[a] = dwr * xij[a];
        udw += uij[a] * gw[a];
        xdw += xij[a] * gw[a];
    }
    const double visc = m * 4.0 * c->nu * xdw / ((rhoi + rhoj) * (r2 + c->eps2));
    *drho = m * udw;
    for (int a = 0; a < d; ++a) du[a] = -m * tij * gw[a] + visc * uij[a];
}

/* The cell coordinate of x along a (x in [0, L)). */
PROBE_FN int probe_cell_coord(const probe_consts *c, double x, int a)
{
    int k = (int)(x * c->inv_cw);
    if (k < 0) k = 0;
    if (k >= c->nc[a]) k = c->nc[a] - 1;
    return k;
}

/* Particle i's cell; pos is structure of arrays, pos[a n + i]. */
PROBE_FN int probe_cell_of(const probe_consts *c, const double *pos, int i)
{
    int cell = 0;
    for (int a = c->d - 1; a >= 0; --a)
        cell = cell * c->nc[a] + probe_cell_coord(c, pos[(long)a * c->n + i], a);
    return cell;
}

/* The minimum-image x_i - x_j in the periodic box. */
PROBE_FN double probe_min_image(const probe_consts *c, double dx)
{
    const double half = 0.5 * c->L;
    if (dx > half) return dx - c->L;
    if (dx < -half) return dx + c->L;
    return dx;
}

PROBE_FN int probe_wrap(int k, int n)
{
    return k < 0 ? k + n : (k >= n ? k - n : k);
}

/* Neighbour cell b (0 .. 3^d - 1) of the cell with coordinates k, in the fixed order (z, y, x
 * each from -1 to 1, x fastest); every box has at least 3 cells a side, so none repeats. Computed
 * per cell rather than listed, so that a GPU thread keeps no indexed array in local memory. */
PROBE_FN int probe_neighbour_cell(int d, const probe_consts *c, const int k[3], int b)
{
    const int x = probe_wrap(k[0] + b % 3 - 1, c->nc[0]);
    const int y = probe_wrap(k[1] + (b / 3) % 3 - 1, c->nc[1]);
    const int z = d == 3 ? probe_wrap(k[2] + b / 9 - 1, c->nc[2]) : 0;
    return (z * c->nc[1] + y) * c->nc[0] + x;
}

/* The cell coordinates of a point and the number of neighbour cells (9 in 2D, 27 in 3D). */
PROBE_FN int probe_cell_coords(int d, const probe_consts *c, const double xi[3], int k[3])
{
    k[0] = k[1] = k[2] = 0;
    for (int a = 0; a < d; ++a) k[a] = probe_cell_coord(c, xi[a], a);
    return d == 3 ? 27 : 9;
}

/* (a) Summation density ρ_i = Σ_j m W_ij (j = i included), over particles sorted by cell:
 * cell k holds the sorted particles off[k] .. off[k+1]-1. */
PROBE_FN double probe_density_i(int d, const probe_consts *c, const double *pos, const int *off,
                                int i)
{
    const long n = c->n;
    double xi[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) xi[a] = pos[a * n + i];
    int k[3];
    const int nb = probe_cell_coords(d, c, xi, k);
    double rho = 0.0;
    for (int b = 0; b < nb; ++b) {
        const int cell = probe_neighbour_cell(d, c, k, b);
        for (int j = off[cell]; j < off[cell + 1]; ++j) {
            double r2 = 0.0;
            for (int a = 0; a < d; ++a) {
                const double dx = probe_min_image(c, xi[a] - pos[a * n + j]);
                r2 += dx * dx;
            }
            if (r2 < c->rc2) rho += c->m * probe_w(c, sqrt(r2));
        }
    }
    return rho;
}

/* The neighbours j != i within 3h of sorted particle i (the pairs both passes visit). */
PROBE_FN int probe_count_i(int d, const probe_consts *c, const double *pos, const int *off, int i)
{
    const long n = c->n;
    double xi[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) xi[a] = pos[a * n + i];
    int k[3], cnt = 0;
    const int nb = probe_cell_coords(d, c, xi, k);
    for (int b = 0; b < nb; ++b) {
        const int cell = probe_neighbour_cell(d, c, k, b);
        for (int j = off[cell]; j < off[cell + 1]; ++j) {
            double r2 = 0.0;
            for (int a = 0; a < d; ++a) {
                const double dx = probe_min_image(c, xi[a] - pos[a * n + j]);
                r2 += dx * dx;
            }
            cnt += j != i && r2 < c->rc2;
        }
    }
    return cnt;
}

/* (b) The rate of sorted particle i: out[0] = dρ_i/dt, out[1 + a] = du_i/dt along a. */
PROBE_FN void probe_rate_i(int d, const probe_consts *c, const double *pos, const double *vel,
                           const double *rho, const double *p, const int *off, int i, double out[4])
{
    const long n = c->n;
    double xi[3] = {0.0, 0.0, 0.0}, ui[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) {
        xi[a] = pos[a * n + i];
        ui[a] = vel[a * n + i];
    }
    const double rhoi = rho[i], pi = p[i];
    int k[3];
    const int nb = probe_cell_coords(d, c, xi, k);
    double drho = 0.0, du[3] = {0.0, 0.0, 0.0};
    for (int b = 0; b < nb; ++b) {
        const int cell = probe_neighbour_cell(d, c, k, b);
        for (int j = off[cell]; j < off[cell + 1]; ++j) {
            double xij[3] = {0.0, 0.0, 0.0}, uj[3] = {0.0, 0.0, 0.0}, r2 = 0.0;
            for (int a = 0; a < d; ++a) {
                xij[a] = probe_min_image(c, xi[a] - pos[a * n + j]);
                r2 += xij[a] * xij[a];
            }
            if (j == i || !(r2 < c->rc2)) continue;
            for (int a = 0; a < d; ++a) uj[a] = vel[a * n + j];
            double pdrho, pdu[3] = {0.0, 0.0, 0.0};
            probe_rate_pair(d, c, rhoi, pi, ui, rho[j], p[j], uj, xij, r2, probe_dwr(c, sqrt(r2)),
                            &pdrho, pdu);
            drho += pdrho;
            for (int a = 0; a < d; ++a) du[a] += pdu[a];
        }
    }
    out[0] = drho;
    for (int a = 0; a < 3; ++a) out[1 + a] = du[a];
}

/* The gathers with the dimension a constant, so that every loop over a unrolls into registers
 * (a GPU thread's arrays indexed at run time live in its slow local memory). */
PROBE_FN double probe_density(const probe_consts *c, const double *pos, const int *off, int i)
{
    return c->d == 3 ? probe_density_i(3, c, pos, off, i) : probe_density_i(2, c, pos, off, i);
}
PROBE_FN int probe_count(const probe_consts *c, const double *pos, const int *off, int i)
{
    return c->d == 3 ? probe_count_i(3, c, pos, off, i) : probe_count_i(2, c, pos, off, i);
}
PROBE_FN void probe_rate(const probe_consts *c, const double *pos, const double *vel,
                         const double *rho, const double *p, const int *off, int i, double out[4])
{
    if (c->d == 3)
        probe_rate_i(3, c, pos, vel, rho, p, off, i, out);
    else
        probe_rate_i(2, c, pos, vel, rho, p, off, i, out);
}

/* The cell list's exclusive scan in PROBE_SCAN_BLOCKS blocks, so that a device runs it in three
 * parallel steps: each block's sum, a serial scan of the block sums, each block's prefixes. */
#define PROBE_SCAN_BLOCKS 1024
PROBE_FN int probe_scan_block_len(int ncell)
{
    return (ncell + PROBE_SCAN_BLOCKS - 1) / PROBE_SCAN_BLOCKS;
}
PROBE_FN int probe_scan_block_sum(const int *count, int ncell, int b)
{
    const int len = probe_scan_block_len(ncell), lo = b * len;
    const int hi = lo + len < ncell ? lo + len : ncell;
    int s = 0;
    for (int k = lo; k < hi; ++k) s += count[k];
    return s;
}
/* bsum[b] in, block b's exclusive start out, and off[ncell] = the total. */
PROBE_FN void probe_scan_blocks(int *bsum, int *off, int ncell)
{
    int s = 0;
    for (int b = 0; b < PROBE_SCAN_BLOCKS; ++b) {
        const int t = bsum[b];
        bsum[b] = s;
        s += t;
    }
    off[ncell] = s;
}
PROBE_FN void probe_scan_block_write(const int *count, const int *bstart, int *off, int ncell,
                                     int b)
{
    const int len = probe_scan_block_len(ncell), lo = b * len;
    const int hi = lo + len < ncell ? lo + len : ncell;
    int s = bstart[b];
    for (int k = lo; k < hi; ++k) {
        off[k] = s;
        s += count[k];
    }
}

/* Cell k's particles in index order after an unordered (atomic) scatter: an insertion sort of
 * its few entries, which makes the order that of a stable counting sort. */
PROBE_FN void probe_sort_cell(const int *off, int *idx, int k)
{
    for (int s = off[k] + 1; s < off[k + 1]; ++s) {
        const int v = idx[s];
        int t = s - 1;
        while (t >= off[k] && idx[t] > v) {
            idx[t + 1] = idx[t];
            --t;
        }
        idx[t + 1] = v;
    }
}

#endif
