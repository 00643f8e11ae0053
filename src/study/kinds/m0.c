/* Study kind `m0`: distributions of the volume estimate M0 = Σ_j V_j W_ij over resolutions
 * (003 section 6.2, Figs. 2-3), their spread against the neighbour count, and the histograms. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "consph/ops.h"
#include "consph/pass.h"
#include "study/kinds/kinds.h"

static double smoothing_length(const consph_approx_spec *sp, const consph_particles *p)
{
    return consph_approx_h(sp, p->n, consph_box_volume(&p->box), p->spacing);
}

typedef struct m0_row {
    size_t nx, n;
    double h, nbr, mean, std, mean_in, std_in, peak;
    size_t *counts;
} m0_row;

static int m0_measure(const series_plan *pl, const consph_particles *src, size_t nx, int nbins,
                      double lo, double hi, m0_row *row)
{
    consph_kernel k;
    consph_sys sys;
    int have_sys = 0;
    consph_op_ctx ctx;
    int have_ctx = 0;
    double *m0 = NULL, *inner = NULL;
    int rc;
    row->nx = nx;
    row->n = src->n;
    row->h = smoothing_length(&pl->spec, src);
    if ((rc = consph_kernel_init(&k, pl->spec.kernel, src->dim, row->h))) goto done;
    if ((rc = consph_sys_init(&sys, src, &k, 0.0))) goto done;
    have_sys = 1;
    const consph_particles *p = sys.p;
    if ((rc = consph_op_ctx_init_sys(&ctx, &sys, pl->spec.volume))) goto done;
    have_ctx = 1;
    m0 = consph_calloc(p->n, sizeof(double));
    inner = consph_calloc(p->n, sizeof(double));
    if (!m0 || !inner) {
        rc = CONSPH_ENOMEM;
        goto done;
    }
    consph_op_report rep;
    if ((rc = consph_op_moments(&ctx, m0, NULL, NULL, NULL, &rep))) goto done;
    row->nbr = (double)rep.pairs / (double)p->n - 1.0;
    if ((rc = consph_histogram(m0, p->n, lo, hi, nbins, row->counts, NULL, NULL, &row->mean,
                               &row->std)))
        goto done;
    size_t m = 0;
    for (size_t i = 0; i < p->n; ++i) {
        int in = 1;
        for (int a = 0; a < p->dim; ++a)
            if (!p->box.periodic[a] &&
                (p->x[a][i] - p->box.lo[a] < k.radius || p->box.hi[a] - p->x[a][i] < k.radius))
                in = 0;
        if (in) inner[m++] = m0[i];
    }
    row->mean_in = row->std_in = NAN;
    size_t one_bin;
    if (m)
        rc = consph_histogram(inner, m, lo, hi, 1, &one_bin, NULL, NULL, &row->mean_in,
                              &row->std_in);
    int best = 0;
    for (int b = 1; b < nbins; ++b)
        if (row->counts[b] > row->counts[best]) best = b;
    row->peak = lo + (best + 0.5) * (hi - lo) / nbins;
done:
    free(m0);
    free(inner);
    if (have_ctx) consph_op_ctx_free(&ctx);
    if (have_sys) consph_sys_free(&sys);
    return rc;
}

static int run_m0_figure(const study_job *job, const study_figure *f)
{
    const consph_study *s = job->s;
    const int quick = job->quick;
    const char *dir = job->dir;
    const study_files *files = job->files;
    layout_cache *cache = job->cache;
    FILE *log = job->log;
    const study_series *r = &f->series[0];
    series_plan pl;
    int rc = study_plan_build(s, f, r, quick, &pl);
    if (rc) return rc;
    double nbins_d, lo = 0.9, hi = 1.1;
    if ((rc = study_get_double(s, f, r, "bins", 60, 2, 10000, &nbins_d))) return rc;
    const char *range = study_get(s, f, r, "range");
    if (range && (sscanf(range, "%lf:%lf", &lo, &hi) != 2 || !(hi > lo)))
        return study_key_error(s, f, r, "range", "'%s' is not lo:hi with lo < hi", range);
    int nbins = (int)nbins_d;
    m0_row rows[MAX_SWEEP];
    memset(rows, 0, sizeof rows);
    int nrows = 0;
    if (files) study_plan_take_files(&pl, files);
    for (int j = 0; rc == CONSPH_OK && j < pl.nvalues; ++j) {
        size_t nx;
        const consph_particles *p;
        if ((rc = study_plan_particles(&pl, j, files, cache, log, &p, &nx))) break;
        rows[j].counts = consph_calloc((size_t)nbins, sizeof(size_t));
        if (!rows[j].counts) {
            rc = CONSPH_ENOMEM;
            break;
        }
        nrows = j + 1;
        if ((rc = m0_measure(&pl, p, nx, nbins, lo, hi, &rows[j]))) break;
        if (log)
            fprintf(log, "  nx=%-6zu N=%-8zu nbr=%-9.1f M0 mean %.6f std %.3e (interior %.3e)\n",
                    nx, rows[j].n, rows[j].nbr, rows[j].mean, rows[j].std, rows[j].std_in);
    }
    consph_outfile of;
    if (rc == CONSPH_OK) rc = study_open_output(&of, dir, f->id, ".csv");
    if (rc == CONSPH_OK) {
        fprintf(of.fp, "nx,n,h,nbr_mean,m0_mean,m0_std,m0_mean_interior,m0_std_interior,m0_peak\n");
        for (int j = 0; j < nrows; ++j)
            fprintf(of.fp, "%zu,%zu,%.10g,%.6g,%.10g,%.6e,%.10g,%.6e,%.6g\n", rows[j].nx, rows[j].n,
                    rows[j].h, rows[j].nbr, rows[j].mean, rows[j].std, rows[j].mean_in,
                    rows[j].std_in, rows[j].peak);
        rc = consph_outfile_commit(&of);
    }
    if (rc == CONSPH_OK) rc = study_open_output(&of, dir, f->id, ".dat");
    if (rc == CONSPH_OK) {
        for (int j = 0; j < nrows; ++j) {
            fprintf(of.fp, "# nx = %zu: M0, fraction of particles per unit M0\n", rows[j].nx);
            for (int b = 0; b < nbins; ++b) {
                double w = (hi - lo) / nbins;
                fprintf(of.fp, "%.8g %.8g\n", lo + (b + 0.5) * w,
                        (double)rows[j].counts[b] / ((double)rows[j].n * w));
            }
            fprintf(of.fp, "\n\n");
        }
        rc = consph_outfile_commit(&of);
    }
    char tbuf[640];
    if (rc == CONSPH_OK) rc = study_open_output(&of, dir, f->id, ".md");
    if (rc == CONSPH_OK) {
        FILE *o = of.fp;
        char htext[160];
        study_report_head_as(o, s, f, study_files_title(s, f, files != NULL, tbuf, sizeof tbuf));
        fprintf(o, "Run: %s resolutions; kernel `%s`, layout `%s`, dim %d, volumes `%s`, h %s.\n\n",
                study_resolutions_text(files != NULL, quick), pl.kernel_name,
                files ? "particle files" : consph_layout_name(pl.spec.layout.kind),
                pl.spec.layout.dim, consph_volume_name(pl.spec.volume),
                study_h_policy_text(&pl.spec, htext, sizeof htext));
        fprintf(o, "| nx | N | h | neighbours | mean M0 | σ(M0) all | mean M0 interior | σ(M0) "
                   "interior | peak |\n|---|---|---|---|---|---|---|---|---|\n");
        double xs[MAX_SWEEP], ys[MAX_SWEEP];
        for (int j = 0; j < nrows; ++j) {
            fprintf(o, "| %zu | %zu | %.4g | %.1f | %.6f | %.3e | %.6f | %.3e | %.4f |\n",
                    rows[j].nx, rows[j].n, rows[j].h, rows[j].nbr, rows[j].mean, rows[j].std,
                    rows[j].mean_in, rows[j].std_in, rows[j].peak);
            xs[j] = rows[j].nbr;
            ys[j] = rows[j].std_in;
        }
        consph_order_fit fit;
        char ptext[64];
        if (consph_fit_order(xs, ys, nrows, &fit) == CONSPH_OK)
            fprintf(o,
                    "\nFitted σ(M0, interior) ∝ 𝒩^-p with p = %s (Zhu et al., quoted by "
                    "003/000: p = 1 for low-discrepancy sets, 1/2 for random ones).\n\n",
                    consph_order_text(&fit, 2, "±", ptext, sizeof ptext));
        study_published_values(s, f, o);
        study_md_figure(o, f->id);
        rc = consph_outfile_commit(&of);
    }
    if (rc == CONSPH_OK) rc = study_open_output(&of, dir, f->id, ".gp");
    if (rc == CONSPH_OK) {
        FILE *o = of.fp;
        char ran[512];
        double nxs[MAX_SWEEP];
        size_t len = (size_t)snprintf(ran, sizeof ran, "ran: ");
        for (int j = 0; j < nrows; ++j) nxs[j] = (double)rows[j].nx;
        study_list_text(ran, sizeof ran, &len, "nx", nxs, nrows);
        if (len < sizeof ran)
            snprintf(ran + len, sizeof ran - len, " (%s, %dD)",
                     files   ? "particle files"
                     : quick ? "quick"
                             : "the paper's",
                     pl.spec.layout.dim);
        rc =
            study_gp_head(o, f->id, study_files_title(s, f, files != NULL, tbuf, sizeof tbuf), ran);
        fprintf(o, "set xlabel 'M0'\nset ylabel 'particles (density)'\nplot");
        for (int j = 0; j < nrows; ++j) {
            /* a marker every twelfth of the bins, the interval differing per series so that
             * the markers of overlapping curves fall apart */
            fprintf(o, "%s '%s.dat' index %d using 1:2 with linespoints pi %d",
                    j ? ", \\\n    " : " ", f->id, j, (nbins > 12 ? nbins / 12 : 1) + j);
            study_gp_style(o, j);
            fprintf(o, " title 'N = %zu'", rows[j].n);
        }
        fprintf(o, "\n");
        rc = study_gp_finish(&of, rc, dir, f->id);
    }
    for (int j = 0; j < nrows; ++j) free(rows[j].counts);
    return rc;
}

const study_kind study_kind_m0 = {
    .name = "m0",
    .particles = STUDY_PARTICLES_USED,
    .validate = study_validate_plans,
    .estimate = study_estimate_plans,
    .run = run_m0_figure,
};
