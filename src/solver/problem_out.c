/* The outputs a problem adds to a run's directory at the final time: the velocity profile u_φ(r)
 * of a centred vortex (profile.csv) and, for the shear layer, the vorticity as a gnuplot image
 * map (vorticity.dat, vorticity.gp and, when gnuplot is installed, vorticity.png) of a 2D
 * problem. */
#define _GNU_SOURCE /* posix_spawn_file_actions_addchdir_np */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include "consph/io.h"
#include "io/outfile_internal.h"
#include "solver/solver_internal.h"

static char *join(const char *dir, const char *name)
{
    size_t len = strlen(dir) + strlen(name) + 2;
    char *p = malloc(len);
    if (p) snprintf(p, len, "%s/%s", dir, name);
    return p;
}

/* One row per particle: r, u_φ and the exact u_φ at the particle (001 Figs. 15-16 plot these). */
static int write_profile(consph_solver *s, const char *dir)
{
    const consph_particles *p = s->sys.p;
    const size_t cap = p->cap;
    const double *u = sv_field(s, SF_U, s->dim);
    if (!u) return CONSPH_ENOMEM;
    const double xc = 0.5 * (p->box.lo[0] + p->box.hi[0]), yc = 0.5 * (p->box.lo[1] + p->box.hi[1]);
    char *path = join(dir, "profile.csv");
    if (!path) return consph_fail(CONSPH_ENOMEM, "out of memory");
    consph_outfile of;
    int st = consph_outfile_open(&of, path);
    free(path);
    if (st != CONSPH_OK) return st;
    fprintf(of.fp, "# t = %.10g\nr,u_phi,u_phi_exact\n", s->t);
    for (size_t i = 0; i < p->n; ++i) {
        const double xa[3] = {p->x[0][i], p->x[1][i], 0.0};
        const double x[2] = {xa[0] - xc, xa[1] - yc}, r = hypot(x[0], x[1]);
        double ue[3], pe;
        s->prob->exact(&s->prm, s->t, xa, ue, &pe);
        const double uphi = r > 0.0 ? (x[0] * u[cap + i] - x[1] * u[i]) / r : 0.0;
        const double uphi_e = r > 0.0 ? (x[0] * ue[1] - x[1] * ue[0]) / r : 0.0;
        fprintf(of.fp, "%.10e,%.10e,%.10e\n", r, uphi, uphi_e);
    }
    return consph_outfile_commit(&of);
}

/* Runs `gnuplot vorticity.gp` in dir (no shell: the directory is never parsed) and renames its
 * output into place, so that vorticity.png is either whole or absent. Without gnuplot the script
 * and data stay for later. */
static int draw_vorticity(const char *dir)
{
    char *tmp = join(dir, "vorticity.png.tmp"), *fin = join(dir, "vorticity.png");
    posix_spawn_file_actions_t fa;
    posix_spawnattr_t attr;
    int st = !tmp || !fin ? consph_fail(CONSPH_ENOMEM, "out of memory") : CONSPH_OK;
    if (st != CONSPH_OK || posix_spawn_file_actions_init(&fa) != 0) {
        free(tmp);
        free(fin);
        return st;
    }
    posix_spawn_file_actions_addchdir_np(&fa, dir);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
    char *argv[] = {"gnuplot", "vorticity.gp", NULL};
    extern char **environ;
    pid_t pid;
    /* A signal that ends us kills gnuplot and removes its output with our temporaries
     * (outfile_internal.h); blocked until the child is registered, and unblocked in it. */
    consph_tmp_register(tmp);
    sigset_t mask;
    consph_cleanup_signals_block(&mask);
    int rc = posix_spawnattr_init(&attr);
    if (rc == 0) {
        posix_spawnattr_setsigmask(&attr, &mask);
        posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK);
        rc = posix_spawnp(&pid, "gnuplot", &fa, &attr, argv, environ);
        posix_spawnattr_destroy(&attr);
    }
    if (rc == 0) consph_child_register(pid);
    sigprocmask(SIG_SETMASK, &mask, NULL);
    posix_spawn_file_actions_destroy(&fa);
    int status = 0;
    if (rc == 0) {
        while (waitpid(pid, &status, 0) < 0 && errno == EINTR) continue;
        consph_child_unregister(pid);
    }
    struct stat sb;
    if (rc != 0 || (WIFEXITED(status) && WEXITSTATUS(status) == 127))
        st = CONSPH_OK; /* no gnuplot, or the child could not exec it */
    else if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0 && stat(tmp, &sb) == 0 &&
               sb.st_size > 0) ||
             rename(tmp, fin) != 0)
        st = consph_fail(CONSPH_EIO, "gnuplot could not draw %s; run 'gnuplot vorticity.gp' there",
                         fin);
    if (st != CONSPH_OK) remove(tmp);
    consph_tmp_unregister(tmp);
    free(tmp);
    free(fin);
    return st;
}

/* The vorticity averaged over the particles of each cell of an nx × nx grid (an empty cell: over
 * its 3 × 3 neighbourhood; NaN, which gnuplot leaves blank, if that is empty too), as a gnuplot
 * matrix, and the script that draws it. */
static int write_vorticity(consph_solver *s, const char *dir)
{
    int st = consph_solver_output_fields(s);
    if (st != CONSPH_OK) return st;
    const consph_particles *p = s->sys.p;
    const double *w = sv_field(s, SF_VORT, 1);
    const int nx = s->prm.nx;
    const double lo = s->prob->lo[0], hi = s->prob->hi[0], ds = (hi - lo) / nx;
    double *sum = calloc((size_t)nx * (size_t)nx * 2, sizeof(double)), wmax = 0.0;
    if (!w || !sum) {
        free(sum);
        return consph_fail(CONSPH_ENOMEM, "out of memory");
    }
    double *cnt = sum + (size_t)nx * (size_t)nx;
    for (size_t i = 0; i < p->n; ++i) {
        int cx = (int)floor((p->x[0][i] - lo) / ds);
        int cy = (int)floor((p->x[1][i] - s->prob->lo[1]) / ds);
        cx = cx < 0 ? 0 : cx >= nx ? nx - 1 : cx;
        cy = cy < 0 ? 0 : cy >= nx ? nx - 1 : cy;
        sum[(size_t)cy * nx + cx] += w[i];
        cnt[(size_t)cy * nx + cx] += 1.0;
        wmax = fmax(wmax, fabs(w[i]));
    }
    char *path = join(dir, "vorticity.dat");
    consph_outfile of;
    st = path ? consph_outfile_open(&of, path) : consph_fail(CONSPH_ENOMEM, "out of memory");
    free(path);
    if (st == CONSPH_OK) {
        for (int cy = 0; cy < nx; ++cy)
            for (int cx = 0; cx < nx; ++cx) {
                double sw = 0.0, n = 0.0;
                /* an empty cell (particles leave gaps where they are advected apart) takes the
                 * particles of the 3 × 3 cells around it, wrapped periodically */
                for (int r = 0; r < 2 && n == 0.0; ++r)
                    for (int oy = -r; oy <= r; ++oy)
                        for (int ox = -r; ox <= r; ++ox) {
                            const size_t k =
                                (size_t)((cy + oy + nx) % nx) * nx + (size_t)((cx + ox + nx) % nx);
                            sw += sum[k];
                            n += cnt[k];
                        }
                if (n > 0.0)
                    fprintf(of.fp, "%.6e", sw / n);
                else
                    fputs("NaN", of.fp);
                fputc(cx + 1 < nx ? ' ' : '\n', of.fp);
            }
        st = consph_outfile_commit(&of);
    }
    free(sum);
    path = st == CONSPH_OK ? join(dir, "vorticity.gp") : NULL;
    if (st == CONSPH_OK && !path) st = consph_fail(CONSPH_ENOMEM, "out of memory");
    if (st == CONSPH_OK) st = consph_outfile_open(&of, path);
    free(path);
    if (st != CONSPH_OK) return st;
    if (!(wmax > 0.0)) wmax = 1.0;
    /* every string here comes from consph's own tables (scheme and problem names) */
    fprintf(of.fp,
            "set terminal png size 900,820\nset output 'vorticity.png.tmp'\n"
            "set title '%s, %s, nx %d, t = %.4g: vorticity' noenhanced\n"
            "set size ratio -1\nset xrange [%.17g:%.17g]\nset yrange [%.17g:%.17g]\n"
            "set xlabel 'x'\nset ylabel 'y'\n"
            "set cblabel 'vorticity ω = ∂v/∂x − ∂u/∂y (cell mean over particles)' noenhanced\n"
            "set palette defined (-1 'blue', 0 'white', 1 'red')\nset cbrange [%.6g:%.6g]\n"
            "plot 'vorticity.dat' matrix using (%.17g + ($1 + 0.5) * %.17g):"
            "(%.17g + ($2 + 0.5) * %.17g):3 with image notitle\n",
            s->prob->name, s->scheme->name, nx, s->t, lo, hi, s->prob->lo[1], s->prob->hi[1], -wmax,
            wmax, lo, ds, s->prob->lo[1], ds);
    st = consph_outfile_commit(&of);
    return st == CONSPH_OK ? draw_vorticity(dir) : st;
}

int problem_outputs(consph_solver *s, const char *dir)
{
    int st = CONSPH_OK;
    if (s->prob->radial) st = write_profile(s, dir);
    /* the map is of the scalar vorticity of a square box */
    if (st == CONSPH_OK && s->prob->vorticity_image && s->dim == 2) st = write_vorticity(s, dir);
    return st;
}
