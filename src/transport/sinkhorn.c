/* Entropically regularised optimal transport by Sinkhorn's iteration in the log domain.
 *
 * The plan is π_ij = a_i b_j exp((f_i + g_j − C_ij)/ε) with dual potentials f, g; each half step
 * makes one marginal exact: g_j = −ε log Σ_i a_i exp((f_i − C_ij)/ε), then the same for f. The
 * log-sum-exp is evaluated in one streaming pass with a running maximum, so no exponent
 * overflows however small ε is (the log-domain stabilisation), and the cost C_ij = |x_i − y_j|^p
 * is recomputed on the fly: memory is O(N + M), work O(N·M) per iteration. ε starts at the
 * largest cost C_max and halves stage by stage down to the requested one (ε-continuation), each
 * stage warm-started from the previous potentials; this takes far fewer iterations at small ε
 * than starting there.
 *
 * Error estimate. The final plan π has exact column marginals b and row marginals r with L1
 * violation δ = ‖r − a‖₁. Being of Sinkhorn form, π is the entropic optimum for its own
 * marginals (r, b), so with OT the unregularised cost:
 *     OT(r,b) ≤ ⟨π,C⟩ ≤ OT(r,b) + ε·KL(π*_r ‖ a⊗b) ≤ OT(r,b) + ε·(min(H(r), H(b)) + KL(r ‖ a)),
 * where π*_r is an optimal plan for (r, b) and H the Shannon entropy; and |OT(r,b) − OT(a,b)| ≤
 * C_max·δ/2 (couple the mass that differs at cost at most C_max). Hence
 *     |⟨π,C⟩ − W_p^p| ≤ ε·(min(H(r), H(b)) + KL(r ‖ a)) + C_max·δ/2,
 * an a priori bound (the entropic bias is usually much smaller than ε·H), reported through the
 * p-th root as an error on the distance. Every per-row quantity is a sequential loop over j and
 * rows are combined with consph_sum, so results are independent of the number of threads. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "transport/transport_internal.h"

/* One half step: out_i = −ε log Σ_j w_j exp((pot_j − C_ij)/ε) for every point i of `to`, summing
 * over the points j of `from`. */
static void half_step(const ot_points *to, const ot_points *from, const double *logw_from,
                      const double *pot_from, double eps, int p, double *out)
{
    int dim = to->dim;
    double inv_eps = 1.0 / eps;
    long n = (long)to->n;
#pragma omp parallel for schedule(static)
    for (long i = 0; i < n; ++i) {
        const double *xi = to->x + (size_t)i * (size_t)dim;
        double m = -INFINITY, s = 0.0;
        for (size_t j = 0; j < from->n; ++j) {
            double v = logw_from[j] +
                       (pot_from[j] - ot_cost(xi, from->x + j * (size_t)dim, dim, p)) * inv_eps;
            if (v > m) {
                s = s * exp(m - v) + 1.0;
                m = v;
            } else {
                s += exp(v - m);
            }
        }
        out[i] = -eps * (m + log(s));
    }
}

/* Row sums r_i and row costs Σ_j π_ij C_ij of the plan (f, g). */
static void plan_rows(const ot_points *a, const ot_points *b, const double *f, const double *g,
                      double eps, int p, double *r, double *rc)
{
    int dim = a->dim;
    double inv_eps = 1.0 / eps;
    long n = (long)a->n;
#pragma omp parallel for schedule(static)
    for (long i = 0; i < n; ++i) {
        const double *xi = a->x + (size_t)i * (size_t)dim;
        double s = 0.0, sc = 0.0;
        for (size_t j = 0; j < b->n; ++j) {
            double c = ot_cost(xi, b->x + j * (size_t)dim, dim, p);
            double pij = b->w[j] * exp((f[i] + g[j] - c) * inv_eps);
            s += pij;
            sc += pij * c;
        }
        r[i] = a->w[i] * s;
        rc[i] = a->w[i] * sc;
    }
}

/* An upper bound of the largest cost: the diagonal of the common bounding box, to the p. */
static double cost_bound(const ot_points *a, const ot_points *b, int p)
{
    double d2 = 0.0;
    for (int c = 0; c < a->dim; ++c) {
        double lo = INFINITY, hi = -INFINITY;
        const ot_points *m[2] = {a, b};
        for (int s = 0; s < 2; ++s)
            for (size_t i = 0; i < m[s]->n; ++i) {
                double v = m[s]->x[i * (size_t)a->dim + (size_t)c];
                lo = fmin(lo, v);
                hi = fmax(hi, v);
            }
        d2 += (hi - lo) * (hi - lo);
    }
    return p == 2 ? d2 : sqrt(d2);
}

#define OMEGA 1.8
#define STAGE_ITER_MAX 1000

static double entropy(const double *w, size_t n, double *tmp)
{
    for (size_t i = 0; i < n; ++i) tmp[i] = w[i] > 0.0 ? -w[i] * log(w[i]) : 0.0;
    return consph_sum(tmp, n);
}

int ot_sinkhorn(const ot_points *a, const ot_points *b, const consph_ot_options *opt,
                consph_ot_result *res)
{
    size_t na = a->n, nb = b->n, nmax = na > nb ? na : nb;
    double cmax = cost_bound(a, b, opt->p);
    res->cost_max = cmax;
    if (!(cmax > 0.0)) {
        /* Every point of both measures at one position: nothing to transport. */
        res->converged = 1;
        return CONSPH_OK;
    }
    double *buf = consph_calloc(4 * na + 3 * nb + nmax, sizeof *buf);
    if (!buf) return CONSPH_ENOMEM;
    double *f = buf, *fnew = f + na, *la = fnew + na, *r = la + na;
    double *g = r + na, *lb = g + nb, *rc = lb + nb, *tmp = rc + nb;
    for (size_t i = 0; i < na; ++i) la[i] = log(a->w[i]);
    for (size_t j = 0; j < nb; ++j) lb[j] = log(b->w[j]);

    double hmin = fmin(entropy(a->w, na, tmp), entropy(b->w, nb, tmp));
    double eps_final = opt->eps * cmax, eps = cmax;
    long it = 0;
    double delta = INFINITY;
    int converged = 0;
    for (;;) {
        int last = eps <= eps_final;
        if (last) eps = eps_final;
        /* Below `enough` the marginal term of the error bound, C_max·δ/2, is under 10% of the
         * entropic term ε·H: iterating on cannot make the bound tighter. Sinkhorn approaches
         * non-unique optimal plans (common for W1) sublinearly, so this ends most W1 runs. The
         * same rule ends each ε stage: it tightens with ε, so every stage hands the next
         * potentials accurate to its own scale, and a loose stage tolerance instead leaves an
         * error the small-ε stages correct only by ~ε per iteration. */
        double want = fmax(opt->tol, 0.2 * eps * hmin / cmax);
        double omega = OMEGA, best = INFINITY;
        converged = 0;
        /* A stage only warm-starts the next one, so it gets a bounded share of the
         * iterations: on small discrete problems at ε far below the cost gaps Sinkhorn's rate
         * tends to 1 and one stage could otherwise spend them all. */
        long stop = last ? opt->max_iter : it + STAGE_ITER_MAX;
        if (stop > opt->max_iter) stop = opt->max_iter;
        while (it < stop) {
            half_step(b, a, la, f, eps, opt->p, g);
            half_step(a, b, lb, g, eps, opt->p, fnew);
            ++it;
            /* With g just updated the columns are exact; the rows of the plan (f, g) are
             * r_i = a_i exp((f_i − fnew_i)/ε). */
            for (size_t i = 0; i < na; ++i) tmp[i] = fabs(a->w[i] * expm1((f[i] - fnew[i]) / eps));
            delta = consph_sum(tmp, na);
            if (opt->progress) opt->progress(opt->progress_ctx, it, eps, delta);
            if (delta <= want) {
                converged = 1;
                break;
            }
            /* Stopping here keeps (f, g), whose columns are exact, so δ measures the whole
             * violation of the plan that is reported. */
            if (it >= stop) break;
            /* Over-relaxation f += ω (F(G(f)) − f): the Jacobian of F∘G has real eigenvalues in
             * [0, 1], which ω in (1, 2) maps into (−1, 1], so the fixed point is kept and the
             * slow modes contract faster (Thibault et al. 2017). It is only local theory, so a
             * stage whose δ doubles from its best falls back to the plain step. */
            if (delta > 2.0 * best) omega = 1.0;
            best = fmin(best, delta);
            for (size_t i = 0; i < na; ++i) f[i] += omega * (fnew[i] - f[i]);
        }
        if (last || it >= opt->max_iter) break;
        eps *= 0.5;
    }

    plan_rows(a, b, f, g, eps, opt->p, r, rc);
    double cost = consph_sum(rc, na);
    for (size_t i = 0; i < na; ++i) tmp[i] = fabs(r[i] - a->w[i]);
    delta = consph_sum(tmp, na);
    for (size_t i = 0; i < na; ++i) tmp[i] = r[i] > 0.0 ? r[i] * log(r[i] / a->w[i]) : 0.0;
    double kl = fmax(0.0, consph_sum(tmp, na));
    double hr = entropy(r, na, tmp), hb = entropy(b->w, nb, tmp);
    double bound = eps * (fmin(hr, hb) + kl) + 0.5 * cmax * delta;

    cost = fmax(cost, 0.0);
    if (opt->p == 2) {
        res->distance = sqrt(cost);
        res->error =
            fmax(sqrt(cost + bound) - res->distance, res->distance - sqrt(fmax(0.0, cost - bound)));
    } else {
        res->distance = cost;
        res->error = bound;
    }
    res->marginal_error = delta;
    res->eps_abs = eps;
    res->iterations = it;
    res->converged = converged && eps == eps_final;
    free(buf);
    return CONSPH_OK;
}
