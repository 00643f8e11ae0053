/* The GPU's per-particle functions of 001's family (src/schemes/negi/): the kit's passes
 * (src/schemes/negi/kit.c: the volumes, pass 1's Bonet matrix and gradients, coupled_bc's
 * Laplacians), the rates (negi_rates_i of src/schemes/negi/iact.h) and IPST
 * (src/regularise/regularise.c's reg_ipst: the volumes with max χ, the shift of 001 eq. 19, the
 * move; then src/solver/solver.c's solver_taylor_update and closure). Part of dev.h (its walk,
 * kernel and view); each sum gathers over the neighbours in the CPU's order, and the pair and
 * per-particle arithmetic of the kit and the rates is the CPU's own code (kit_pair.h, iact.h).
 * The walk is dev.h's by rows of cells (gpu_walkr_*), the neighbours' values read by particle. */
#ifndef CONSPH_GPU_DEV_NEGI_H
#define CONSPH_GPU_DEV_NEGI_H

/* The row walk's next neighbour as a particle index: these passes read their neighbours' values
 * by particle (the arrays of gv), not from records in slot order as edac's and wcsph's do. */
GPU_FN_INLINE int gpu_walkj_next(const gpu_view *v, gpu_walkr *w, const int D, uint32_t *j,
                                 double dx[3], double *r)
{
    uint32_t sl;
    if (!gpu_walkr_next(v, w, D, &sl, dx, r)) return 0;
    *j = GPU_LDG(&v->order[sl]);
    return 1;
}

/* Σ_j W_ij (i itself among the j), in the walk's order; the neighbours in *hits. */
GPU_FN_INLINE double gpu_wsum_d(const gpu_view *v, size_t i, uint32_t *hits, const int D)
{
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, D);
    double s = 0.0, dx[3], r;
    uint32_t sl;
    while (gpu_walkr_next(v, &w, D, &sl, dx, &r)) s += gpu_w(&v->k, r);
    *hits = w.hits;
    return s;
}

GPU_FN double gpu_wsum(const gpu_view *v, size_t i, uint32_t *hits)
{
    return v->d == 2 ? gpu_wsum_d(v, i, hits, 2) : gpu_wsum_d(v, i, hits, 3);
}

/* kit_volumes: ω = 1/Σ W (a pass the CPU counts). */
GPU_FN void dev_negi_volumes(const gpu_view *v, size_t i)
{
    uint32_t hits;
    gv(v, GA_VOL, 0)[i] = 1.0 / gpu_wsum(v, i, &hits);
    gpu_pairs_add(v, i, hits);
}

/* The kit's pass 1 at particle i (kit.c's first_body): the Bonet matrix, and ∇p (P), G (U, with
 * ∇·u stored when DIV) and ∇q (Q). */
GPU_FN_INLINE void dev_negi_first_d(const gpu_view *v, size_t i, const int D, const int P,
                                    const int U, const int Q, const int DIV)
{
    const double *vol = gv(v, GA_VOL, 0), *pf = gv(v, GA_P, 0), *qf = gv(v, GA_Q, 0);
    double sm[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    double su[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    double sp[3] = {0.0, 0.0, 0.0}, sq[3] = {0.0, 0.0, 0.0}, ui[3] = {0.0, 0.0, 0.0};
    const double pi = P ? pf[i] : 0.0, qi = Q ? qf[i] : 0.0;
    if (U)
        for (int a = 0; a < D; ++a) ui[a] = gv(v, GA_U, a)[i];
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, D);
    double x[3], r;
    uint32_t j;
    while (gpu_walkj_next(v, &w, D, &j, x, &r)) {
        double uj[3] = {0.0, 0.0, 0.0};
        if (U)
            for (int a = 0; a < D; ++a) uj[a] = gv(v, GA_U, a)[j];
        kit_first_pair(D, P, U, Q, vol[j], gpu_dwr(&v->k, r), x, P ? pf[j] : 0.0, pi, uj, ui,
                       Q ? qf[j] : 0.0, qi, sm, sp, su, sq);
    }
    gpu_pairs_add(v, i, w.hits);
    double B[9], gp[3], G[9], div = 0.0, gq[3];
    v->bonet_ok[i] = (unsigned char)kit_first_finish(D, P, U, Q, sm, v->cond_max, sp, su, sq, B, gp,
                                                     G, &div, gq);
    for (int e = 0; e < D * D; ++e) gv(v, GA_BONET, e)[i] = B[e];
    if (P)
        for (int a = 0; a < D; ++a) gv(v, GA_GRADP, a)[i] = gp[a];
    if (U)
        for (int e = 0; e < D * D; ++e) gv(v, GA_GRADU, e)[i] = G[e];
    if (U && DIV) gv(v, GA_DIVU, 0)[i] = div;
    if (Q)
        for (int a = 0; a < D; ++a) gv(v, GA_GRADQ, a)[i] = gq[a];
}

/* The two sets of sums L-IPST-C asks for: its rates' (∇p, G, ∇·u) and, before a shift, G and ∇q
 * (negi/scheme.c's gradients_for_shift); with ∇q also in the rates for the schemes that
 * advect or diffuse q. 0: a set this build has no kernel for. */
GPU_FN int gpu_negi_first_known(const gpu_view *v)
{
    return v->kit_u && ((v->kit_p && v->kit_div) || (!v->kit_p && !v->kit_div && v->kit_q));
}

GPU_FN void dev_negi_first_any(const gpu_view *v, size_t i)
{
#define NEGI_FIRST_D(D)                                                                            \
    do {                                                                                           \
        if (v->kit_p && v->kit_q)                                                                  \
            dev_negi_first_d(v, i, D, 1, 1, 1, 1);                                                 \
        else if (v->kit_p)                                                                         \
            dev_negi_first_d(v, i, D, 1, 1, 0, 1);                                                 \
        else                                                                                       \
            dev_negi_first_d(v, i, D, 0, 1, 1, 0);                                                 \
    } while (0)
    if (v->d == 2)
        NEGI_FIRST_D(2);
    else
        NEGI_FIRST_D(3);
#undef NEGI_FIRST_D
}

/* The kit's pass 2 with coupled_bc (kit.c's coupled_body): ∇²u (U) and ∇²q (Q). */
GPU_FN_INLINE void dev_negi_coupled_d(const gpu_view *v, size_t i, const int D, const int U,
                                      const int Q)
{
    const double *vol = gv(v, GA_VOL, 0);
    double B[9], Gi[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, gqi[3] = {0.0, 0.0, 0.0};
    double acc[3] = {0.0, 0.0, 0.0}, accq = 0.0;
    for (int e = 0; e < D * D; ++e) B[e] = gv(v, GA_BONET, e)[i];
    if (U)
        for (int e = 0; e < D * D; ++e) Gi[e] = gv(v, GA_GRADU, e)[i];
    if (Q)
        for (int b = 0; b < D; ++b) gqi[b] = gv(v, GA_GRADQ, b)[i];
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, D);
    double x[3], r;
    uint32_t j;
    while (gpu_walkj_next(v, &w, D, &j, x, &r)) {
        double Gj[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, gqj[3] = {0.0, 0.0, 0.0};
        if (U)
            for (int e = 0; e < D * D; ++e) Gj[e] = gv(v, GA_GRADU, e)[j];
        if (Q)
            for (int b = 0; b < D; ++b) gqj[b] = gv(v, GA_GRADQ, b)[j];
        kit_coupled_pair(D, U, Q, B, gpu_dwr(&v->k, r), x, vol[j], Gj, Gi, gqj, gqi, acc, &accq);
    }
    gpu_pairs_add(v, i, w.hits);
    if (U)
        for (int a = 0; a < D; ++a) gv(v, GA_LAPU, a)[i] = acc[a];
    if (Q) gv(v, GA_LAPQ, 0)[i] = accq;
}

GPU_FN void dev_negi_coupled_any(const gpu_view *v, size_t i)
{
    if (v->d == 2) {
        if (v->lap_q)
            dev_negi_coupled_d(v, i, 2, 1, 1);
        else
            dev_negi_coupled_d(v, i, 2, 1, 0);
    } else {
        if (v->lap_q)
            dev_negi_coupled_d(v, i, 3, 1, 1);
        else
            dev_negi_coupled_d(v, i, 3, 1, 0);
    }
}

/* Cleary's Laplacian as 001's authors run EWCSPH (kit.c's cleary_body), with the B_i of pass 1
 * and ϱ. */
GPU_FN_INLINE void dev_negi_cleary_d(const gpu_view *v, size_t i, const int D)
{
    const double *vol = gv(v, GA_VOL, 0), *rho = gv(v, GA_RHOF, 0);
    double B[9], ui[3] = {0.0, 0.0, 0.0}, acc[3] = {0.0, 0.0, 0.0};
    for (int e = 0; e < D * D; ++e) B[e] = gv(v, GA_BONET, e)[i];
    for (int a = 0; a < D; ++a) ui[a] = gv(v, GA_U, a)[i];
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, D);
    double x[3], r;
    uint32_t j;
    while (gpu_walkj_next(v, &w, D, &j, x, &r)) {
        if (!(r > 1e-14)) continue;
        double uj[3] = {0.0, 0.0, 0.0};
        for (int a = 0; a < D; ++a) uj[a] = gv(v, GA_U, a)[j];
        kit_cleary_pair(D, B, r, gpu_dwr(&v->k, r), x, vol[j], rho[i], rho[j], ui, uj, acc);
    }
    gpu_pairs_add(v, i, w.hits);
    for (int a = 0; a < D; ++a) gv(v, GA_LAPU, a)[i] = acc[a];
}

GPU_BY_DIM(dev_negi_cleary_any, dev_negi_cleary_d)

/* Fatehi_c's Laplacian (kit.c's fatehi_c_matrix and fatehi_body): B̂_i from one walk (the
 * identity where B_i fell back or B̂'s matrix is singular or ill conditioned), ∇²u from another. */
GPU_FN_INLINE void dev_negi_fatehi_d(const gpu_view *v, size_t i, const int D)
{
    const double *vol = gv(v, GA_VOL, 0);
    double Bh[9], G[9], ui[3] = {0.0, 0.0, 0.0}, acc[3] = {0.0, 0.0, 0.0};
    for (int e = 0; e < D * D; ++e) G[e] = gv(v, GA_GRADU, e)[i];
    for (int a = 0; a < D; ++a) ui[a] = gv(v, GA_U, a)[i];
    gpu_walkr w;
    double x[3], r;
    uint32_t j;
    int ok = v->bonet_ok[i];
    if (ok) {
        double B[9], L1[3] = {0.0, 0.0, 0.0}, M[9], cond = 0.0;
        double L2[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, L3[27];
        for (int e = 0; e < 27; ++e) L3[e] = 0.0;
        for (int e = 0; e < D * D; ++e) B[e] = gv(v, GA_BONET, e)[i];
        gpu_walkr_start(v, i, &w, D);
        while (gpu_walkj_next(v, &w, D, &j, x, &r))
            if (r > 0.0) term_fatehi_c_pair(D, r, x, vol[j] * gpu_dwr(&v->k, r), L1, L2, L3);
        term_fatehi_c_finish(D, B, L1, L2, L3, M);
        ok = ops_invert_n(D, M, Bh, v->cond_max, &cond);
    }
    if (!ok)
        for (int a = 0; a < D; ++a)
            for (int b = 0; b < D; ++b) Bh[a * D + b] = a == b ? 1.0 : 0.0;
    gpu_walkr_start(v, i, &w, D);
    while (gpu_walkj_next(v, &w, D, &j, x, &r)) {
        if (!(r > 0.0)) continue;
        double uj[3] = {0.0, 0.0, 0.0};
        for (int a = 0; a < D; ++a) uj[a] = gv(v, GA_U, a)[j];
        kit_fatehi_pair(D, Bh, r, gpu_dwr(&v->k, r), x, vol[j], G, ui, uj, acc);
    }
    gpu_pairs_add(v, i, w.hits); /* the CPU's pass is this walk (B̂ comes within it there) */
    for (int a = 0; a < D; ++a) gv(v, GA_LAPU, a)[i] = acc[a];
}

/* Korzilius' Laplacian (kit.c's korzilius_body), with the B_i of pass 1 and its verdict. */
GPU_FN_INLINE void dev_negi_korzilius_d(const gpu_view *v, size_t i, const int D)
{
    const int P = D * (D + 1) / 2;
    const double *vol = gv(v, GA_VOL, 0);
    int pl[6], pk[6];
    double cq[6];
    for (int a = 0, q = 0; a < D; ++a)
        for (int b = a; b < D; ++b, ++q) {
            pl[q] = a;
            pk[q] = b;
            cq[q] = term_taylor_c(a, b);
        }
    double B[9], G[9], ui[3] = {0.0, 0.0, 0.0};
    for (int e = 0; e < D * D; ++e) {
        B[e] = gv(v, GA_BONET, e)[i];
        G[e] = gv(v, GA_GRADU, e)[i];
    }
    for (int a = 0; a < D; ++a) ui[a] = gv(v, GA_U, a)[i];
    double A[36], Hx[18], Gz[18], rhs[18];
    for (int e = 0; e < 36; ++e) A[e] = 0.0;
    for (int e = 0; e < 18; ++e) Hx[e] = Gz[e] = rhs[e] = 0.0;
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, D);
    double x[3], r;
    uint32_t j;
    while (gpu_walkj_next(v, &w, D, &j, x, &r)) {
        double uj[3] = {0.0, 0.0, 0.0};
        for (int a = 0; a < D; ++a) uj[a] = gv(v, GA_U, a)[j];
        const double dwr = gpu_dwr(&v->k, r);
        const double aee = term_hess_radial(r, dwr, gpu_d2w(&v->k, r));
        kit_korzilius_pair(D, P, pl, pk, cq, vol[j], dwr, aee, x, G, ui, uj, A, Hx, Gz, rhs);
    }
    gpu_pairs_add(v, i, w.hits);
    double lap[3];
    kit_korzilius_finish(D, P, pl, pk, v->bonet_ok[i], Hx, Gz, B, A, rhs, v->cond_max, lap);
    for (int a = 0; a < D; ++a) gv(v, GA_LAPU, a)[i] = lap[a];
}

GPU_BY_DIM(dev_negi_korzilius_any, dev_negi_korzilius_d)

GPU_BY_DIM(dev_negi_fatehi_any, dev_negi_fatehi_d)

/* negi/scheme.c's rates loop: the kit's derivatives at i into negi_rates_i, d known at compile
 * time (the small arrays stay in registers). */
GPU_FN_INLINE void dev_negi_rates_d(const gpu_view *v, size_t i, const int D)
{
    negi_derivs nd;
    nd.rhof = gv(v, GA_RHOF, 0)[i];
    nd.rhom = v->nt.frozen_rho ? gv(v, GA_RHOC, 0)[i] : nd.rhof;
    nd.divu = gv(v, GA_DIVU, 0)[i];
    nd.lapq = v->lap_q ? gv(v, GA_LAPQ, 0)[i] : 0.0;
    for (int a = 0; a < 3; ++a) {
        nd.u[a] = nd.du[a] = nd.gradp[a] = nd.lapu[a] = nd.gradq[a] = 0.0;
        if (a >= D) continue;
        nd.u[a] = gv(v, GA_U, a)[i];
        if (v->nt.transport) nd.du[a] = gv(v, GA_SHIFT, a)[i];
        nd.gradp[a] = gv(v, GA_GRADP, a)[i];
        nd.lapu[a] = gv(v, GA_LAPU, a)[i];
        if (v->nt.advect_q || v->nt.transport) nd.gradq[a] = gv(v, GA_GRADQ, a)[i];
    }
    for (int e = 0; e < 9; ++e) nd.G[e] = e < D * D ? gv(v, GA_GRADU, e)[i] : 0.0;
    double au[3], ax[3], aq;
    negi_rates_i(&v->nt, D, v->nu, v->Dq, v->c2, v->rho0, v->evolve_p, &nd, au, ax, &aq);
    for (int a = 0; a < D; ++a) {
        gv(v, GA_AU, a)[i] = au[a];
        if (v->moves) gv(v, GA_AX, a)[i] = ax[a];
    }
    gv(v, GA_AQ, 0)[i] = aq;
}

GPU_BY_DIM(dev_negi_rates, dev_negi_rates_d)

/* ---- IPST (reg_ipst) ---- */

/* ipst_volumes: ω = 1/Σ W and χ = h^d Σ W (the density pass with mass 1: 1·Σ W is Σ W). */
GPU_FN void dev_ipst_volumes(const gpu_view *v, size_t i)
{
    uint32_t hits; /* reg_ipst's passes are not counted in the CPU's pairs */
    const double s = gpu_wsum(v, i, &hits);
    gv(v, GA_VOL, 0)[i] = 1.0 / s;
    v->chi[i] = v->ipst_hd * s;
}

/* The particles max χ is taken over per thread of dev_chi_max. */
#define GPU_MAX_CHUNK 256

GPU_FN unsigned long long gpu_bits(double x)
{
#if defined(__CUDA_ARCH__)
    return (unsigned long long)__double_as_longlong(x);
#else
    union {
        double d;
        unsigned long long u;
    } b;
    b.d = x;
    return b.u;
#endif
}

GPU_FN void gpu_atomic_max(unsigned long long *p, unsigned long long x)
{
#if defined(__CUDA_ARCH__)
    atomicMax(p, x);
#else
    if (x > *p) *p = x;
#endif
}

/* max χ over particles [t GPU_MAX_CHUNK, (t + 1) GPU_MAX_CHUNK) into *chi_max. χ >= 0 (W >= 0),
 * and the bits of non-negative doubles order as the doubles do; a NaN's bits exceed every
 * number's, so a NaN anywhere gives a NaN, as the CPU's loop. A maximum in any order. */
GPU_FN void dev_chi_max(const gpu_view *v, size_t t)
{
    const size_t i0 = t * GPU_MAX_CHUNK, i1 = i0 + GPU_MAX_CHUNK < v->n ? i0 + GPU_MAX_CHUNK : v->n;
    unsigned long long best = 0;
    for (size_t i = i0; i < i1; ++i) {
        const unsigned long long b = gpu_bits(v->chi[i]);
        if (b > best) best = b;
    }
    gpu_atomic_max(v->chi_max, best);
}

/* 001 eq. 19 (regularise.c's ipst_body): δx_i = h Σ_j (x_ij/r_ij) W_ij ω_j, r_ij > 0. */
GPU_FN_INLINE void dev_ipst_shift_d(const gpu_view *v, size_t i, const int D)
{
    const double *vol = gv(v, GA_VOL, 0);
    double acc[3] = {0.0, 0.0, 0.0};
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, D);
    double x[3], r;
    uint32_t j;
    while (gpu_walkj_next(v, &w, D, &j, x, &r)) {
        if (!(r > 0.0)) continue;
        const double f = gpu_w(&v->k, r) * vol[j] / r;
        for (int c = 0; c < D; ++c) acc[c] += f * x[c];
    }
    for (int c = 0; c < D; ++c) v->step[(size_t)c * v->n + i] = v->ipst_h * acc[c];
}

GPU_BY_DIM(dev_ipst_shift_any, dev_ipst_shift_d)

/* ---- the shifting of Sun et al. (regularise.c's reg_pst_shift with n = 4, no cap) ---- */

/* δr_i = coef Σ_j [1 + R (W_ij/W(Δs))^4] ∇W_ij ω_j (pst_body), into step for the move and, times
 * mul, into the shift field: 1 for L-PST-C's δr, c_o/h for TV-C's δu
 * (solver_shift_velocity_tvc). */
GPU_FN_INLINE void dev_pst_shift_d(const gpu_view *v, size_t i, const int D, double mul)
{
    const double *vol = gv(v, GA_VOL, 0);
    double acc[3] = {0.0, 0.0, 0.0};
    gpu_walkr w;
    gpu_walkr_start(v, i, &w, D);
    double x[3], r;
    uint32_t j;
    while (gpu_walkj_next(v, &w, D, &j, x, &r)) {
        const double t = gpu_w(&v->k, r) * v->pst_inv_wds, t2 = t * t;
        const double f = (1.0 + v->pst_R * (t2 * t2)) * gpu_dwr(&v->k, r) * vol[j];
        for (int c = 0; c < D; ++c) acc[c] += f * x[c];
    }
    double len2 = 0.0;
    for (int c = 0; c < D; ++c) {
        acc[c] *= v->pst_coef;
        len2 += acc[c] * acc[c];
    }
    const double len = sqrt(len2);
    const double scale = len > v->pst_cap ? v->pst_cap / len : 1.0;
    for (int c = 0; c < D; ++c) {
        const double dr = scale * acc[c];
        gv(v, GA_SHIFT, c)[i] = mul == 1.0 ? dr : dr * mul;
        v->step[(size_t)c * v->n + i] = dr;
    }
}

GPU_FN void dev_pst_shift_any(const gpu_view *v, size_t i, double mul)
{
    if (v->d == 2)
        dev_pst_shift_d(v, i, 2, mul);
    else
        dev_pst_shift_d(v, i, 3, mul);
}

/* ---- M4 remeshing (L-RR-C: regularise.c's reg_remesh_m4) ---- */

/* src/kernels/kernels.c's m4_f (001 eq. 32's profile). */
GPU_FN double gpu_m4_f(double q)
{
    double inner = 1.0 - q * q * (2.5 - 1.5 * q);
    double t = 2.0 - q, outer = 0.5 * (1.0 - q) * t * t;
    return q < 1.0 ? inner : q < 2.0 ? outer : 0.0;
}

/* Eq. 33 at lattice point k (remesh_visit): Σ_j φ_j M4_kj / Σ_j M4_kj of u and q over the
 * particles j, in the order of the CPU's joint search of lattice points and particles (cells
 * ascending, each cell's particles by index: its lattice points, first in each cell, are
 * skipped). v is the joint view: its grid, cell lists and slots are the particles' in the joint
 * search, and its x the lattice field, where the walk starts. The result goes to step (u) and
 * chi (q); a lattice point with no particle keeps particle k's values. */
GPU_FN_INLINE void dev_remesh_d(const gpu_view *v, size_t k, const int D)
{
    const size_t n = v->n;
    const double *q = gv(v, GA_Q, 0);
    double out[4] = {0.0, 0.0, 0.0, 0.0}, wsum = 0.0;
    gpu_walkr w;
    gpu_walkr_start(v, k, &w, D);
    double x[3], r;
    uint32_t j;
    while (gpu_walkj_next(v, &w, D, &j, x, &r)) {
        double m = v->m4_norm;
        for (int c = 0; c < D && m != 0.0; ++c) {
            const double qa = fabs(x[c]) * v->m4_inv_h;
            m = qa < v->m4_support ? m * gpu_m4_f(qa) : 0.0;
        }
        if (m == 0.0) continue;
        wsum += m;
        for (int c = 0; c < D; ++c) out[c] += m * gv(v, GA_U, c)[j];
        out[D] += m * q[j];
    }
    if (wsum == 0.0) {
        for (int c = 0; c < D; ++c) v->step[(size_t)c * n + k] = gv(v, GA_U, c)[k];
        v->chi[k] = q[k];
        return;
    }
    for (int c = 0; c < D; ++c) v->step[(size_t)c * n + k] = out[c] / wsum;
    v->chi[k] = out[D] / wsum;
}

GPU_BY_DIM(dev_remesh_any, dev_remesh_d)

/* After the remeshing: u and q the remeshed values, x the lattice point, the closure. */
GPU_FN void dev_remesh_end(const gpu_view *v, size_t k)
{
    const size_t n = v->n;
    for (int c = 0; c < v->d; ++c) {
        gv(v, GA_U, c)[k] = v->step[(size_t)c * n + k];
        gv(v, GA_X, c)[k] = gv(v, GA_LAT, c)[k];
    }
    gv(v, GA_Q, 0)[k] = v->chi[k];
    gpu_close(v, k);
}

/* reg_move: x + δx, wrapped into a periodic box as layout_wrap (src/layout/layout_internal.h)
 * does; the iteration's total += δx. */
GPU_FN void dev_ipst_move(const gpu_view *v, size_t i)
{
    const gpu_grid *g = &v->g;
    for (int a = 0; a < v->d; ++a) {
        const size_t k = (size_t)a * v->n + i;
        double x = gv(v, GA_X, a)[i] + v->step[k];
        if (g->periodic[a]) {
            double s = fmod(x - g->lo[a], g->len[a]);
            if (s < 0.0) s += g->len[a];
            if (!(s < g->len[a])) s = 0.0;
            x = g->lo[a] + s;
        }
        gv(v, GA_X, a)[i] = x;
        v->total[k] += v->step[k];
    }
}

/* After a shift: with add_total (IPST) δr += the iterations' total (the field zeroed before, as
 * negi/scheme.c's zeroed_shift), else δr as dev_pst_shift left it; solver_taylor_update's
 * u += δr·∇u and q += δr·∇q with the gradients of before the shift, and the closure. */
GPU_FN void dev_shift_end(const gpu_view *v, size_t i, int add_total)
{
    const int d = v->d;
    const size_t n = v->n;
    double dr[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < d; ++a) {
        double *sh = gv(v, GA_SHIFT, a);
        if (add_total) sh[i] += v->total[(size_t)a * n + i];
        dr[a] = sh[i];
    }
    double dq = 0.0;
    for (int b = 0; b < d; ++b) dq += dr[b] * gv(v, GA_GRADQ, b)[i];
    gv(v, GA_Q, 0)[i] += dq;
    for (int a = 0; a < d; ++a) {
        double s = 0.0;
        for (int b = 0; b < d; ++b) s += dr[b] * gv(v, GA_GRADU, a * d + b)[i];
        gv(v, GA_U, a)[i] += s;
    }
    gpu_close(v, i);
}

#endif
