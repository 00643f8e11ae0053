/* Particle files as the measurements take them, and a sweep of one approx spec over resolutions
 * or files: what `consph approx` runs (apps/cmd_approx.c maps its options onto these and
 * writes the rows); `consph study --particles` reads its files here too. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/study.h"

double consph_resolution_of(size_t n, int dim)
{
    double r = pow((double)n, 1.0 / dim), k = floor(r + 0.5), kd = 1.0;
    for (int a = 0; a < dim; ++a) kd *= k;
    return kd == (double)n ? k : r;
}

int consph_particle_input_read(const char *path, const consph_read_options *ro,
                               consph_particle_input *in)
{
    memset(in, 0, sizeof *in);
    in->path = path;
    int rc = consph_read_particles(path, ro, &in->p, &in->rep);
    if (rc) return rc;
    in->nx = consph_resolution_of(in->p.n, in->p.dim);
    if (in->rep.volumes != CONSPH_VOLUMES_NONE) {
        in->volume = CONSPH_VOLUME_GIVEN;
        snprintf(in->volume_text, sizeof in->volume_text, "given (%s)",
                 consph_volume_origin_name(in->rep.volumes));
        return CONSPH_OK;
    }
    /* Given volumes where a measurement asks for them; number (001 eq. 5) otherwise. */
    double *v = consph_particles_field(&in->p, "volume", 1);
    if (!v) {
        rc = consph_fail(CONSPH_EINVAL, "%s: %s", path, consph_last_error());
        consph_particles_free(&in->p);
        return rc;
    }
    const double lattice = consph_box_volume(&in->p.box) / (double)in->p.n;
    for (size_t i = 0; i < in->p.n; ++i) v[i] = lattice;
    in->volume = CONSPH_VOLUME_NUMBER;
    snprintf(in->volume_text, sizeof in->volume_text,
             "number (1/sum W, 001 eq. 5: no volumes in the file)");
    return CONSPH_OK;
}

int consph_particle_input_lattice_volumes(consph_particle_input *in)
{
    double *v = consph_particles_field(&in->p, "volume", 1);
    if (!v) return consph_fail(CONSPH_EINVAL, "%s: %s", in->path, consph_last_error());
    const double lattice = consph_box_volume(&in->p.box) / (double)in->p.n;
    for (size_t i = 0; i < in->p.n; ++i) v[i] = lattice;
    in->volume = CONSPH_VOLUME_GIVEN;
    return CONSPH_OK;
}

void consph_particle_input_free(consph_particle_input *in)
{
    consph_particles_free(&in->p);
    memset(in, 0, sizeof *in);
}

/* The spec of row r: a file's box and volumes, or the spec as given. */
static consph_approx_spec row_spec(const consph_approx_sweep *sw, int r)
{
    consph_approx_spec s = sw->spec;
    if (sw->files) {
        s.layout.box = sw->files[r].p.box;
        s.volume = sw->files[r].volume;
    }
    return s;
}

consph_approx_sweep_cost consph_approx_sweep_estimate(const consph_approx_sweep *sw, int threads)
{
    consph_approx_sweep_cost c;
    memset(&c, 0, sizeof c);
    const int dim = sw->files ? sw->files[0].p.dim : sw->spec.layout.dim;
    for (int r = 0; r < sw->nrows; ++r) {
        const consph_particle_input *in = sw->files ? &sw->files[r] : NULL;
        const size_t n = in ? in->p.n : (size_t)pow(sw->nx[r], (double)dim);
        consph_approx_cost one =
            in ? consph_approx_estimate(&sw->spec, n, consph_box_volume(&in->p.box), in->p.spacing,
                                        threads)
               : consph_approx_estimate(&sw->spec, n, 1.0, 1.0 / sw->nx[r], threads);
        c.seconds += one.seconds;
        if (one.bytes > c.worst.bytes) {
            c.worst = one;
            c.worst_row = r;
        }
    }
    return c;
}

int consph_approx_sweep_check(const consph_approx_sweep *sw)
{
    if (!sw->files) return consph_approx_check(&sw->spec);
    for (int r = 0; r < sw->nrows; ++r) {
        const consph_particle_input *in = &sw->files[r];
        const consph_box *box = &in->p.box;
        if (sw->spec.field != CONSPH_MFIELD_CONST)
            for (int a = 0; a < in->p.dim; ++a) {
                /* Period-1 fields repeat on a periodic axis only when its length is a whole
                 * number. */
                double len = consph_box_length(box, a);
                if (box->periodic[a] && fabs(len - floor(len + 0.5)) > 1e-12 * fmax(1.0, len))
                    return consph_fail(CONSPH_EINVAL,
                                       "%s: field '%s' has period 1 but the periodic axis %c has "
                                       "length %g; allowed: a non-periodic axis, or a box of "
                                       "whole-number length",
                                       in->path, consph_mfield_name(sw->spec.field), "xyz"[a], len);
            }
        consph_approx_spec s = row_spec(sw, r);
        if (consph_approx_check(&s) != CONSPH_OK)
            return consph_fail(CONSPH_EINVAL, "%s: %s", in->path, consph_last_error());
    }
    return CONSPH_OK;
}

int consph_approx_sweep_run(const consph_approx_sweep *sw, consph_approx_row *rows, double *res,
                            consph_approx_row_fn on_row, void *ctx)
{
    for (int r = 0; r < sw->nrows; ++r) {
        int rc;
        if (sw->files) {
            const consph_particle_input *in = &sw->files[r];
            consph_approx_spec s = row_spec(sw, r);
            rc = consph_approx_run_particles(&s, &in->p, (size_t)floor(in->nx + 0.5), &rows[r]);
            if (rc) return consph_fail(rc, "%s: %s", in->path, consph_last_error());
            res[r] = in->nx;
        } else {
            rc = consph_approx_run(&sw->spec, (size_t)sw->nx[r], &rows[r]);
            if (rc) return consph_fail(rc, "nx = %.0f: %s", sw->nx[r], consph_last_error());
            res[r] = (double)rows[r].nx;
        }
        if (on_row) on_row(ctx, r, &rows[r], res[r]);
    }
    return CONSPH_OK;
}

int consph_approx_sweep_fit(const consph_approx_row *rows, const double *res, int nrows,
                            const char *pm, consph_series_order fits[4])
{
    static const char *const norms[4] = {"l1", "l2", "linf", "mae"};
    for (int k = 0; k < 4; ++k) {
        consph_series_order *so = &fits[k];
        int rc = consph_series_fit(rows, res, nrows, norms[k], 3, pm, so);
        if (rc == CONSPH_ENOMEM) return rc;
    }
    return CONSPH_OK;
}
