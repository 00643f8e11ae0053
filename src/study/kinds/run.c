/* Study kind `run`: the solver over resolutions (runstudy.c runs it, run_report.c writes it). */
#include "study/kinds/kinds.h"

static int run_estimate(const consph_study *s, const study_figure *f, int quick,
                        const study_files *files, study_estimate *e)
{
    (void)files;
    double steps;
    e->seconds += study_run_estimate(s, f, quick, &steps);
    return CONSPH_OK;
}

static int run_figure(const study_job *job, const study_figure *f)
{
    return study_run_figure(job, f);
}

static int run_rows(const consph_study *s, const study_figure *f, int quick,
                    const study_files *files, double *work)
{
    (void)files;
    return study_run_rows(s, f, quick, work);
}

const study_kind study_kind_run = {
    .name = "run",
    .particles = STUDY_PARTICLES_REFUSED,
    .validate = study_run_validate,
    .estimate = run_estimate,
    .rows = run_rows,
    .run = run_figure,
};
