/* Study kind `appc`: 003 App. C, the discrete error of a 1D Gaussian sum against its closed
 * form (003 eq. C.4), on a periodic lattice (f = 1) and at the centre of a bounded one
 * (f = α + βx). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/pass.h"
#include "study/kinds/kinds.h"

/* The untruncated Gaussian of 003 eq. C.1, cut where it falls below 1e-21 of its peak. */
#define APPC_CUT 7.0

typedef struct appc_job {
    const double *f; /* per particle, in system order */
    double h, spacing, sum;
} appc_job;

static void appc_visit(void *job, const consph_nbhd *nb)
{
    appc_job *a = job;
    double s = 0.0;
    for (size_t k = 0; k < nb->n; ++k) {
        double q = nb->r[k] / a->h;
        s += a->f[nb->j[k]] * a->spacing * exp(-q * q) / (sqrt(M_PI) * a->h);
    }
    a->sum = s;
}

/* The Gaussian sum at the one particle that was `at` in the generated set: a pass over a
 * destination mask of that particle, reading only the distances (the Gaussian is evaluated
 * untruncated, not through the system's kernel, which only sets the search). */
static int appc_sum(consph_sys *sys, size_t at, appc_job *job)
{
    const size_t n = sys->p->n;
    unsigned char *dest = consph_calloc(n, 1);
    if (!dest) return CONSPH_ENOMEM;
    for (size_t i = 0; i < n; ++i) dest[i] = sys->origin[i] == at;
    int rc = consph_sys_set_dest(sys, dest);
    free(dest);
    const consph_pass pass = {"appc Gaussian sum", CONSPH_PASS_NO_DX, appc_visit};
    job->sum = NAN;
    return rc ? rc : consph_pass_run(sys, &pass, job);
}

static int run_appc_figure(const study_job *job, const study_figure *f)
{
    const consph_study *s = job->s;
    const char *dir = job->dir;
    FILE *log = job->log;
    series_plan pl;
    int rc = study_plan_build(s, f, &f->series[0], job->quick, &pl);
    if (rc) return rc;
    size_t nx = pl.nx_fixed;
    double closed[MAX_SWEEP], per[MAX_SWEEP], lin[MAX_SWEEP];
    for (int j = 0; rc == CONSPH_OK && j < pl.nvalues; ++j) {
        double hd = pl.values[j];
        closed[j] = 0.0;
        for (int m = 1; m < 60; ++m) closed[j] += 2.0 * exp(-M_PI * M_PI * m * m * hd * hd);
        /* f = 1 on a periodic lattice: every image within the cut is summed. */
        for (int periodic = 1; periodic >= 0 && rc == CONSPH_OK; --periodic) {
            consph_layout_params lp = consph_layout_defaults(CONSPH_LAYOUT_LATTICE, 1, nx);
            lp.box = consph_box_unit(1, periodic);
            consph_particles p;
            if ((rc = consph_layout_generate(&lp, &p, NULL))) break;
            double h = hd * p.spacing;
            consph_kernel k;
            consph_sys sys;
            memset(&sys, 0, sizeof sys);
            double *fv = NULL;
            appc_job gauss = {NULL, h, p.spacing, NAN};
            rc = consph_kernel_init(&k, CONSPH_KERNEL_GAUSSIAN, 1, h);
            if (rc == CONSPH_OK) rc = consph_sys_init(&sys, &p, &k, APPC_CUT * h);
            if (rc == CONSPH_OK && !(fv = consph_calloc(p.n, sizeof(double)))) rc = CONSPH_ENOMEM;
            if (rc == CONSPH_OK && periodic) {
                for (size_t i = 0; i < p.n; ++i) fv[i] = 1.0;
                gauss.f = fv;
                if ((rc = appc_sum(&sys, 0, &gauss)) == CONSPH_OK) per[j] = gauss.sum - 1.0;
            } else if (rc == CONSPH_OK) {
                /* f = α + βx at the central particle, whose cut support lies inside the box. */
                size_t c = p.n / 2;
                for (size_t i = 0; i < p.n; ++i) fv[i] = 1.0 + 2.0 * sys.p->x[0][i];
                gauss.f = fv;
                if (APPC_CUT * h >= 0.5)
                    rc = consph_fail(CONSPH_EINVAL, "appc: h too large");
                else if ((rc = appc_sum(&sys, c, &gauss)) == CONSPH_OK)
                    lin[j] = gauss.sum / (1.0 + 2.0 * p.x[0][c]) - 1.0;
            }
            free(fv);
            consph_sys_free(&sys);
            consph_particles_free(&p);
        }
        if (log && rc == CONSPH_OK)
            fprintf(log, "  h/Δ=%-5g closed form %.6e, periodic f=1 %.6e, linear f %.6e\n", hd,
                    closed[j], per[j], lin[j]);
    }
    if (rc) return rc;
    consph_outfile of;
    if ((rc = study_open_output(&of, dir, f->id, ".csv"))) return rc;
    fprintf(of.fp, "h_over_delta,closed_form,periodic_const,linear_centre\n");
    for (int j = 0; j < pl.nvalues; ++j)
        fprintf(of.fp, "%g,%.10e,%.10e,%.10e\n", pl.values[j], closed[j], per[j], lin[j]);
    if ((rc = consph_outfile_commit(&of))) return rc;
    if ((rc = study_open_output(&of, dir, f->id, ".md"))) return rc;
    study_report_head(of.fp, s, f);
    fprintf(of.fp,
            "Lattice of %zu particles on [0,1), Gaussian exp(-x²/h²)/(√π h) summed to "
            "%g h. Relative error of the SPH sum against 003 eq. C.4.\n\n",
            nx, APPC_CUT);
    fprintf(of.fp, "| h/Δ | closed form 2Σexp(-π²j²h²/Δ²) | ours, f = 1 periodic | ours, f = α+βx "
                   "| |ours − closed| |\n|---|---|---|---|---|\n");
    for (int j = 0; j < pl.nvalues; ++j)
        fprintf(of.fp, "| %g | %.6e | %.6e | %.6e | %.1e |\n", pl.values[j], closed[j], per[j],
                lin[j], fmax(fabs(per[j] - closed[j]), fabs(lin[j] - closed[j])));
    fprintf(of.fp, "\n");
    study_published_values(s, f, of.fp);
    return consph_outfile_commit(&of);
}

/* No layout of its own to replace and no neighbour pairs worth estimating. */
const study_kind study_kind_appc = {
    .name = "appc",
    .particles = STUDY_PARTICLES_IGNORED,
    .validate = study_validate_plans,
    .run = run_appc_figure,
};
