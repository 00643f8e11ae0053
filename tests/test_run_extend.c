/* consph_solver_extend on a solver restored in memory (consph_solver_checkpoint_meta, as the
 * library's users checkpoint): a run of steps continued to more steps, or to a t_f, equals the
 * uninterrupted run bit for bit; a checkpoint taken at the end of a --tf run whose last step was
 * shortened to land on t_f is refused (the uninterrupted run would not have taken that step),
 * and so are an end not after the checkpoint and the authors' error measure.
 * consph_solver_create_from with the particles of the layout gives the same run. */
#include <string.h>

#include "check.h"
#include "consph/solver.h"

static consph_run_params params(long steps, double tf)
{
    consph_run_params p;
    consph_run_params_default(&p);
    strcpy(p.scheme, "tvf");
    p.nx = 10;
    p.steps = steps;
    p.tf = tf;
    p.log_every = 1;
    return p;
}

/* Steps to the end. */
static int run_to_end(consph_solver *s)
{
    int st = CONSPH_OK;
    while (st == CONSPH_OK && !consph_solver_done(s)) st = consph_solver_step(s);
    return st;
}

/* A copy of s through its checkpoint's metadata, particles and history. */
static consph_solver *restored(const consph_solver *s)
{
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    consph_solver *r = NULL;
    if (consph_solver_checkpoint_meta(s, &meta, &hist, &nh) == CONSPH_OK)
        CHECK(consph_solver_restore(&r, meta, consph_solver_particles(s), hist, nh) == CONSPH_OK,
              "restore: %s", consph_last_error());
    free(meta);
    free(hist);
    return r;
}

/* Positions, velocity and pressure of a and b are the same bits. */
static int same_state(const consph_solver *a, const consph_solver *b)
{
    const consph_particles *p = consph_solver_particles(a), *q = consph_solver_particles(b);
    if (p->n != q->n || consph_solver_time(a) != consph_solver_time(b) ||
        consph_solver_step_count(a) != consph_solver_step_count(b))
        return 0;
    for (int d = 0; d < p->dim; ++d)
        if (memcmp(p->x[d], q->x[d], p->n * sizeof(double))) return 0;
    static const char *const f[] = {"u", "p"};
    for (int k = 0; k < 2; ++k) {
        const consph_field *fa = consph_particles_find(p, f[k]),
                           *fb = consph_particles_find(q, f[k]);
        if (!fa || !fb) return 0;
        for (int c = 0; c < fa->ncomp; ++c)
            if (memcmp(fa->data + (size_t)c * p->cap, fb->data + (size_t)c * q->cap,
                       p->n * sizeof(double)))
                return 0;
    }
    consph_run_summary sa, sb;
    consph_solver_summary(a, &sa);
    consph_solver_summary(b, &sb);
    return sa.l1_u == sb.l1_u && sa.l1_p == sb.l1_p &&
           consph_solver_history_size(a) == consph_solver_history_size(b);
}

int main(void)
{
    consph_run_params full = params(12, 0.0), part = params(7, 0.0);
    consph_solver *a = NULL, *b = NULL;
    CHECK(consph_solver_create(&a, &full) == CONSPH_OK, "%s", consph_last_error());
    CHECK(consph_solver_create(&b, &part) == CONSPH_OK, "%s", consph_last_error());
    if (!a || !b) return check_summary("test_run_extend");
    run_to_end(a);
    run_to_end(b);
    const double dt = consph_solver_dt(a);

    /* 7 steps, then 12: the uninterrupted 12 */
    consph_solver *r = restored(b);
    CHECK(r && consph_solver_extend(r, 0.0, 12) == CONSPH_OK, "extend: %s", consph_last_error());
    if (r) run_to_end(r);
    CHECK(r && same_state(a, r), "7 + 5 steps differ from 12");
    consph_solver_free(r);

    /* 7 steps, then to t_f = 12 Δt: the run to that t_f (its steps all full but the last) */
    consph_run_params to_t = params(0, 11.5 * dt);
    consph_solver *c = NULL;
    CHECK(consph_solver_create(&c, &to_t) == CONSPH_OK, "%s", consph_last_error());
    if (c) run_to_end(c);
    r = restored(b);
    CHECK(r && consph_solver_extend(r, 11.5 * dt, 0) == CONSPH_OK, "extend to t_f: %s",
          consph_last_error());
    if (r) run_to_end(r);
    CHECK(c && r && same_state(c, r), "7 steps continued to t_f differ from the run to t_f");
    consph_solver_free(r);

    /* the end of that run: its last step was half a Δt */
    r = c ? restored(c) : NULL;
    CHECK(r && consph_solver_extend(r, 20.0 * dt, 0) == CONSPH_EINVAL &&
              strstr(consph_last_error(), "shortened"),
          "a shortened last step continued: %s", consph_last_error());
    consph_solver_free(r);
    /* not after the checkpoint */
    r = restored(b);
    CHECK(r && consph_solver_extend(r, 0.0, 7) == CONSPH_OK, "the same end is no change");
    CHECK(r && consph_solver_extend(r, 0.0, 5) == CONSPH_EINVAL, "an end before the checkpoint");
    CHECK(r && consph_solver_extend(r, 0.5 * dt, 0) == CONSPH_EINVAL, "a t_f before t");
    consph_solver_free(r);
    consph_solver_free(c);

    /* the authors' measure: refused */
    consph_run_params au = params(7, 0.0);
    au.error = CONSPH_ERROR_AUTHORS;
    au.error_times = 4;
    CHECK(consph_solver_create(&c, &au) == CONSPH_OK, "%s", consph_last_error());
    if (c) run_to_end(c);
    r = c ? restored(c) : NULL;
    CHECK(r && consph_solver_extend(r, 0.0, 12) == CONSPH_EINVAL &&
              strstr(consph_last_error(), "authors"),
          "the authors' measure continued: %s", consph_last_error());
    consph_solver_free(r);
    consph_solver_free(c);

    /* the layout's own particles given: the same run */
    consph_layout_params lp;
    consph_particles lay = {0};
    CHECK(consph_run_layout_params(&full, &lp) == CONSPH_OK &&
              consph_layout_generate(&lp, &lay, NULL) == CONSPH_OK,
          "layout: %s", consph_last_error());
    CHECK(consph_solver_create_from(&c, &full, &lay) == CONSPH_OK, "%s", consph_last_error());
    if (c) run_to_end(c);
    CHECK(c && same_state(a, c), "the layout's particles given differ from the layout");
    consph_solver_free(c);
    /* the resolution of a particle count: nx^2 exactly, else nx rounded and n */
    consph_run_params q = full;
    CHECK(consph_run_params_particles(&q, 100) == CONSPH_OK && q.nx == 10 && q.n == 0,
          "100 particles: nx %d, n %ld", q.nx, q.n);
    CHECK(consph_run_params_particles(&q, 90) == CONSPH_OK && q.nx == 9 && q.n == 90,
          "90 particles: nx %d, n %ld", q.nx, q.n);
    CHECK(consph_run_params_particles(&q, 9) == CONSPH_EINVAL, "9 particles accepted");
    /* n particles not nx^d go with nx = n^(1/d) rounded */
    consph_run_params odd = full;
    odd.n = 90;
    CHECK(consph_solver_create_from(&c, &odd, &lay) == CONSPH_EINVAL, "n = 90 with nx = 10");
    consph_particles_free(&lay);
    consph_solver_free(a);
    consph_solver_free(b);
    return check_summary("test_run_extend");
}
