/* Every problem of the solver, one line each: the rows live in their own files
 * (src/problems/<name>.c: the exact solution and its const problem_def), are listed once here, and
 * everything that names problems reads this list. Adding a problem is its file and one line of
 * PROBLEMS. */
#include <stdio.h>
#include <string.h>

#include "solver/solver_internal.h"

/* In the order consph_problem_names lists; each line expands to the row's declaration and its
 * entry in the table. */
#define PROBLEMS(X)                                                                                \
    X(problem_taylor_green)                                                                        \
    X(problem_gresho_chan)                                                                         \
    X(problem_shear_layer)                                                                         \
    X(problem_beltrami)

#define DECLARE_PROBLEM(row) extern const problem_def row;
PROBLEMS(DECLARE_PROBLEM)
#undef DECLARE_PROBLEM

#define PROBLEM_ENTRY(row) &row,
static const problem_def *const problems[] = {PROBLEMS(PROBLEM_ENTRY)};
#undef PROBLEM_ENTRY
enum { NPROBLEMS = sizeof problems / sizeof problems[0] };

const problem_def *problem_find(const char *name)
{
    for (size_t k = 0; k < NPROBLEMS; ++k)
        if (strcmp(problems[k]->name, name) == 0) return problems[k];
    return NULL;
}

const char *consph_problem_names(void)
{
    static char names[NPROBLEMS * 32];
    /* filled once, from the table; callers on several threads wait for the first */
#pragma omp critical(consph_problem_names)
    if (!names[0]) {
        size_t len = 0;
        for (size_t k = 0; k < NPROBLEMS; ++k)
            len += (size_t)snprintf(names + len, sizeof names - len, "%s%s", k ? "," : "",
                                    problems[k]->name);
    }
    return names;
}

int consph_run_params_problem(consph_run_params *prm, const char *problem)
{
    const problem_def *pb = problem_find(problem);
    if (!pb || strlen(problem) >= sizeof prm->problem)
        return consph_fail(CONSPH_EINVAL, "problem '%.40s' is unknown (allowed: %s)", problem,
                           consph_problem_names());
    snprintf(prm->problem, sizeof prm->problem, "%s", pb->name);
    prm->tf = pb->tf;
    prm->nu = pb->nu;
    prm->c0 = pb->c0;
    prm->layout = pb->layout;
    return CONSPH_OK;
}
