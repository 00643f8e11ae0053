/* Declared state: the solver, the integrator and each scheme list the fields they use
 * (solver_internal.h, field_decl); set-up creates them all, sv_field hands out only those, and a
 * snapshot writes the ones that name an output array (docs/solver-files.md, "Snapshot arrays"). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "solver/solver_internal.h"

const field_decl solver_fields[] = {
    {SF_ID, FIELD_SCALAR, FIELD_STATE, "id"},
    {SF_U, FIELD_VECTOR, FIELD_STATE, "velocity"},
    {SF_P, FIELD_SCALAR, FIELD_STATE, "pressure"},
    /* named by each scheme: evolved, from p by eq. 31, or a summation */
    {SF_RHOF, FIELD_SCALAR, FIELD_STATE, NULL},
    /* the layout's Δs^d, or the ω or m/ϱ a scheme's right-hand side sets (which then names it) */
    {SF_VOL, FIELD_SCALAR, FIELD_DERIVED, NULL},
    /* of the last right-hand side: the vorticity and max ∇·u read them */
    {SF_GRADU, FIELD_TENSOR, FIELD_DERIVED, "velocity_gradient"},
    {SF_DIVU, FIELD_SCALAR, FIELD_DERIVED, NULL},
    /* consph_solver_output_fields, before each snapshot */
    {SF_VORT, FIELD_CURL, FIELD_OUTPUT, "vorticity"},
    {SF_UEX, FIELD_VECTOR, FIELD_OUTPUT, "velocity_exact"},
    {SF_PEX, FIELD_SCALAR, FIELD_OUTPUT, "pressure_exact"},
    FIELD_END};

/* The integrator's (one list for rk2, euler, kdk and pec; an integrator table can hold its own
 * and state_lists take it from there). The rates are carried from step to step (pec and kdk
 * start a step from the last ones, so a checkpoint holds them); the start-of-step copies live
 * within a step only. */
const field_decl integrator_fields[] = {{SF_AX, FIELD_VECTOR, FIELD_DERIVED, NULL},
                                        {SF_AU, FIELD_VECTOR, FIELD_DERIVED, NULL},
                                        {SF_AQ, FIELD_SCALAR, FIELD_DERIVED, NULL},
                                        {SF_X0, FIELD_VECTOR, FIELD_SCRATCH, NULL},
                                        {SF_U0, FIELD_VECTOR, FIELD_SCRATCH, NULL},
                                        {SF_Q0, FIELD_SCALAR, FIELD_SCRATCH, NULL},
                                        FIELD_END};

/* A moving scheme's neighbour list with a skin: the positions of its last build, which a
 * checkpoint must carry for a restart to rebuild the same list (src/pass/nlist.c). */
static const field_decl nlist_fields[] = {{SF_XB, FIELD_VECTOR, FIELD_STATE, NULL}, FIELD_END};

int solver_nlist_start(consph_solver *s, int resume)
{
    const double skin = s->scheme->moves ? s->prm.skin : 0.0;
    return consph_sys_nlist(&s->sys, skin, skin > 0.0 ? SF_XB : NULL, resume);
}

void solver_nlist_summary(const consph_solver *s, consph_run_summary *sum)
{
    consph_nlist_info info;
    consph_sys_nlist_info(&s->sys, &info);
    sum->nlist_skin = s->scheme->moves ? s->prm.skin : 0.0;
    sum->nlist_bytes = info.bytes;
    sum->nlist_builds = (long)info.builds;
    snprintf(sum->nlist_note, sizeof sum->nlist_note, "%s", info.note);
}

int field_ncomp(field_shape shape, int d)
{
    switch (shape) {
    case FIELD_VECTOR:
        return d;
    case FIELD_TENSOR:
        return d * d;
    case FIELD_CURL:
        return d == 3 ? 3 : 1;
    default:
        return 1;
    }
}

/* The lists of a solver, in the order their fields are created and written. */
static int state_lists(const consph_solver *s, const field_decl *lists[4])
{
    int nl = 0;
    lists[nl++] = solver_fields;
    lists[nl++] = integrator_fields;
    if (s->scheme->fields) lists[nl++] = s->scheme->fields;
    if (s->scheme->moves && s->prm.skin > 0.0) lists[nl++] = nlist_fields;
    return nl;
}

/* The first declaration of `name` (NULL: none) and, in *output, the output name any
 * declaration of it gives. */
static const field_decl *declared(const consph_solver *s, const char *name, const char **output)
{
    const field_decl *lists[4], *first = NULL;
    const int nl = state_lists(s, lists);
    if (output) *output = NULL;
    for (int l = 0; l < nl; ++l)
        for (const field_decl *f = lists[l]; f->name; ++f)
            if (!strcmp(f->name, name)) {
                if (!first) first = f;
                if (output && f->output && !*output) *output = f->output;
            }
    return first;
}

double *sv_field(consph_solver *s, const char *name, int ncomp)
{
    const consph_field *f = consph_particles_find(s->sys.p, name);
    if (!f || !declared(s, name, NULL)) {
        consph_fail(CONSPH_EINVAL,
                    "field '%s' is not declared by scheme '%s' (nor by the solver or the "
                    "integrator: solver_internal.h, field_decl)",
                    name, s->scheme->name);
        return NULL;
    }
    if (f->ncomp != ncomp) {
        consph_fail(CONSPH_EINVAL, "field '%s' of scheme '%s' has %d components, not %d", name,
                    s->scheme->name, f->ncomp, ncomp);
        return NULL;
    }
    return f->data;
}

int state_carried(const consph_solver *s, const char *name)
{
    /* pec's step starts with the update of ϱ, u and x from the last rates, then the EOS gives p
     * from ϱ: nothing reads the p of the step before (every scheme whose p is its EOS of ϱ:
     * wcsph, the δ-SPH family, tv-c, e-c, ewcsph) */
    if (!strcmp(name, SF_P) && s->reuse_rates && !s->scheme->closure && !s->scheme->evolve_p)
        return 0;
    const field_decl *lists[4];
    const int nl = state_lists(s, lists);
    int found = 0;
    for (int l = 0; l < nl; ++l)
        for (const field_decl *f = lists[l]; f->name; ++f)
            if (!strcmp(f->name, name)) {
                if (f->role == FIELD_STEP || (f->role == FIELD_GRADS && !s->grads_skip)) return 0;
                if (f->role != FIELD_SCRATCH && f->role != FIELD_OUTPUT) found = 2;
                if (!found) found = 1;
            }
    return found != 1; /* an undeclared field is carried: nothing says it is dead */
}

int state_create(consph_solver *s)
{
    const field_decl *lists[4];
    const int nl = state_lists(s, lists);
    for (int l = 0; l < nl; ++l)
        for (const field_decl *f = lists[l]; f->name; ++f) {
            const char *out;
            const field_decl *first = declared(s, f->name, &out);
            if (first->shape != f->shape || (f->output && strcmp(f->output, out)) ||
                (f->output && f->role == FIELD_SCRATCH))
                return consph_fail(CONSPH_EINVAL,
                                   "scheme '%s': field '%s' is declared twice with different "
                                   "shapes or output names, or as scratch with an output",
                                   s->scheme->name, f->name);
            const int ncomp = field_ncomp(f->shape, s->dim);
            const consph_field *have = consph_particles_find(s->sys.p, f->name);
            if (have && have->ncomp != ncomp)
                return consph_fail(CONSPH_EFORMAT,
                                   "field '%s' has %d components; scheme '%s' declares %d", f->name,
                                   have->ncomp, s->scheme->name, ncomp);
            if (!have && !consph_particles_field(s->sys.p, f->name, ncomp)) return CONSPH_ENOMEM;
        }
    consph_vtu_array arr[CONSPH_MAX_FIELDS];
    int narr;
    int st = state_snapshot_arrays(s, arr, &narr);
    for (int a = 0; a < narr && st == CONSPH_OK; ++a)
        for (int b = 0; b < a; ++b)
            if (!strcmp(arr[a].name, arr[b].name))
                return consph_fail(CONSPH_EINVAL,
                                   "scheme '%s': snapshot array '%s' is given to '%s' and '%s'",
                                   s->scheme->name, arr[a].name, arr[b].field, arr[a].field);
    return st;
}

int state_undeclared(consph_solver *s, int drop)
{
    consph_particles *p = s->sys.p;
    for (int k = 0; k < p->nfields;) {
        if (declared(s, p->fields[k].name, NULL)) {
            ++k;
            continue;
        }
        if (!drop)
            return consph_fail(CONSPH_EINVAL,
                               "field '%s' was created but is not declared by scheme '%s' (nor "
                               "by the solver or the integrator)",
                               p->fields[k].name, s->scheme->name);
        free(p->fields[k].data);
        memmove(&p->fields[k], &p->fields[k + 1],
                (size_t)(p->nfields - k - 1) * sizeof p->fields[0]);
        --p->nfields;
    }
    return CONSPH_OK;
}

int state_snapshot_arrays(const consph_solver *s, consph_vtu_array *arr, int *narr)
{
    const field_decl *lists[4];
    const int nl = state_lists(s, lists);
    *narr = 0;
    for (int l = 0; l < nl; ++l)
        for (const field_decl *f = lists[l]; f->name; ++f) {
            const char *out;
            if (declared(s, f->name, &out) != f || !out) continue; /* written once, where first */
            if (*narr == CONSPH_MAX_FIELDS)
                return consph_fail(CONSPH_EINVAL, "more than %d snapshot arrays",
                                   CONSPH_MAX_FIELDS);
            consph_array_kind kind = f->shape == FIELD_SCALAR   ? CONSPH_ARRAY_SCALAR
                                     : f->shape == FIELD_VECTOR ? CONSPH_ARRAY_VECTOR
                                     : f->shape == FIELD_TENSOR ? CONSPH_ARRAY_TENSOR
                                     : s->dim == 3              ? CONSPH_ARRAY_VECTOR
                                                                : CONSPH_ARRAY_SCALAR;
            arr[(*narr)++] = (consph_vtu_array){out, f->name, kind};
        }
    return CONSPH_OK;
}
