/* A user-defined pass: summation density and a corrected gradient fused in one traversal.
 *
 * Each visit sums, over the neighbours j of particle i (V_j = m_j/ρ0, ∇W_ij = dwr·x_ij):
 *   ρ_i = Σ m_j W_ij                      (summation density)
 *   G_i = Σ V_j (f_j - f_i) ∇W_ij         (the gradient sum)
 *   M_i = Σ V_j (x_j - x_i) ⊗ ∇W_ij       (the first moment, close to the identity)
 *   S_i = Σ V_j W_ij                      (the Shepard sum)
 * and finalises ∇f_i = M_i⁻¹ G_i. M_i⁻¹ restores the first moment, so the gradient of a linear
 * field is exact on any particles (up to round-off); G_i / S_i, the Shepard-normalised form,
 * restores only the zeroth moment and is printed for comparison.
 * Build: cc density_gradient.c $(pkg-config --cflags --libs consph) -lm -o density_gradient */
#include <consph/consph.h>
#include <math.h>
#include <stdio.h>

typedef struct job {
    const double *f;
    double mass, vol, *rho, *grad, *shepard; /* grad, shepard: 2 components, component-major */
    size_t stride;                           /* of a field's components: the particles' cap */
} job;

static void visit(void *data, const consph_nbhd *nb)
{
    job *jb = data;
    const size_t i = nb->i;
    double rho = 0.0, s = 0.0, g[2] = {0.0, 0.0}, m[2][2] = {{0.0, 0.0}, {0.0, 0.0}};
    for (size_t k = 0; k < nb->n; ++k) {
        const double gw[2] = {nb->dwr[k] * nb->dx[0][k], nb->dwr[k] * nb->dx[1][k]};
        const double df = jb->f[nb->j[k]] - jb->f[i];
        rho += jb->mass * nb->w[k];
        s += jb->vol * nb->w[k];
        for (int a = 0; a < 2; ++a) {
            g[a] += jb->vol * df * gw[a];
            for (int b = 0; b < 2; ++b) m[a][b] -= jb->vol * nb->dx[a][k] * gw[b];
        }
    }
    /* G = Mᵀ ∇f for a linear field: solve with the transpose. */
    const double det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    jb->rho[i] = rho;
    jb->grad[i] = (m[1][1] * g[0] - m[1][0] * g[1]) / det;
    jb->grad[jb->stride + i] = (m[0][0] * g[1] - m[0][1] * g[0]) / det;
    jb->shepard[i] = g[0] / s;
    jb->shepard[jb->stride + i] = g[1] / s;
}

int main(void)
{
    /* 30 x 30 particles in the unit square, each moved by up to 0.2 Δs, walls all round. */
    consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_RANDOM, 2, 30);
    lp.box = consph_box_unit(2, 0);
    lp.eps = 0.2;
    consph_particles src;
    consph_kernel k;
    consph_sys sys;
    if (consph_layout_generate(&lp, &src, NULL) ||
        consph_kernel_init(&k, CONSPH_KERNEL_QUINTIC, 2, 1.2 * src.spacing) ||
        consph_sys_init(&sys, &src, &k, 0.0)) {
        fprintf(stderr, "density_gradient: %s\n", consph_last_error());
        return 1;
    }
    const consph_particles *p = sys.p;
    const size_t n = p->n;
    const double rho0 = 1000.0, vol = p->spacing * p->spacing, gx = 2.0, gy = -3.0;
    double *f = consph_particles_field(sys.p, "f", 1),
           *rho = consph_particles_field(sys.p, "rho", 1);
    double *grad = consph_particles_field(sys.p, "grad_f", 2);
    double *shep = consph_particles_field(sys.p, "grad_f_shepard", 2);
    if (!f || !rho || !grad || !shep) return 1;
    for (size_t i = 0; i < n; ++i) f[i] = 1.0 + gx * p->x[0][i] + gy * p->x[1][i];
    const size_t c = p->cap;
    job jb = {f, rho0 * vol, vol, rho, grad, shep, c};
    const consph_pass pass = {"density + gradient", CONSPH_PASS_W | CONSPH_PASS_DW, visit};
    if (consph_pass_run(&sys, &pass, &jb)) {
        fprintf(stderr, "density_gradient: %s\n", consph_last_error());
        return 1;
    }
    /* Errors over the particles whose support lies inside the walls. */
    double spread = 0.0, err = 0.0, err_shep = 0.0;
    for (size_t i = 0; i < n; ++i) {
        const double x = p->x[0][i], y = p->x[1][i], r = k.radius;
        if (x < r || x > 1.0 - r || y < r || y > 1.0 - r) continue;
        spread = fmax(spread, fabs(rho[i] / rho0 - 1.0));
        err = fmax(err, fmax(fabs(grad[i] - gx), fabs(grad[c + i] - gy)));
        err_shep = fmax(err_shep, fmax(fabs(shep[i] - gx), fabs(shep[c + i] - gy)));
    }
    printf("particles %zu\ndensity_spread %.3e\ngradient_error %.3e\nshepard_gradient_error %.3e\n",
           n, spread, err, err_shep);
    consph_sys_free(&sys);
    consph_particles_free(&src);
    return 0;
}
