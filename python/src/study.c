/* consph._core: studies (include/consph/study.h, docs/studies.md), Wasserstein distances
 * (include/consph/transport.h) and the run parameter table. */
#include "pyconsph.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

PyDoc_STRVAR(run_study_doc,
             "run_study(path, out_dir, quick=False, log=False, jobs=1, device=None, "
             "resume=False)\n"
             "--\n"
             "\n"
             "Returns dict. Loads, validates and runs a study file (consph_study_load, "
             "consph_study_validate,\n"
             "consph_study_run) as `consph study FILE --out OUT_DIR [--quick] [--jobs J] "
             "[--device D]\n"
             "[--resume]` does, writing OUT_DIR/NAME/FIGURE.csv, .md, .gp per figure and "
             "README.md.\n"
             "log: progress lines on stderr. jobs: the rows on that many forked processes (on "
             "the CPU)\n"
             "or threads sharing the GPU (device 'gpu' or 'auto'). device: 'cpu', 'gpu', 'auto' "
             "or None\n"
             "(the study file's key `device`, else the CPU); a row the GPU cannot run raises "
             "before\n"
             "anything runs. resume: keep the rows an earlier run of the same study and options "
             "left in\n"
             "OUT_DIR/NAME. Returns {'name', 'title', 'dir'}; consph.study reads the tables "
             "back.");

/* device=None, 'cpu', 'gpu' or 'auto' as a consph_study_device (`consph study --device`). */
static int study_device_of(PyObject *obj, int *device)
{
    static const char *const names[] = {"cpu", "gpu", "auto"};
    *device = CONSPH_STUDY_DEVICE_DEFAULT;
    if (obj == Py_None) return 0;
    const char *name = PyUnicode_Check(obj) ? PyUnicode_AsUTF8(obj) : NULL;
    if (!name && PyErr_Occurred()) return -1;
    for (int k = 0; name && k < 3; ++k)
        if (!strcmp(name, names[k])) {
            *device = CONSPH_STUDY_DEVICE_CPU + k;
            return 0;
        }
    PyObject *r = PyObject_Repr(obj);
    const char *text = r ? PyUnicode_AsUTF8(r) : NULL;
    if (text)
        pyc_raise_msg(CONSPH_EINVAL, "device %.40s is unknown (allowed: cpu, gpu, auto)", text);
    Py_XDECREF(r);
    return -1;
}

static PyObject *py_run_study(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"path", "out_dir", "quick", "log", "jobs", "device", "resume", NULL};
    const char *path, *out_dir;
    int quick = 0, log = 0, jobs = 1, resume = 0, device;
    PyObject *devo = Py_None;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "ss|ppiOp", kwlist, &path, &out_dir, &quick, &log,
                                     &jobs, &devo, &resume))
        return NULL;
    if (jobs < 1 || jobs > 256)
        return pyc_raise_msg(CONSPH_EINVAL, "jobs = %d is out of range (allowed: 1..256)", jobs);
    if (study_device_of(devo, &device) < 0) return NULL;
    consph_study *s = NULL;
    int st = consph_study_load(path, &s);
    if (st == CONSPH_OK) st = consph_study_validate(s, quick);
    /* the device before anything runs, as consph study checks it */
    if (st == CONSPH_OK) {
        device = consph_study_device_of(s, device);
        st = consph_study_device_check(s, quick, device);
    }
    if (st != CONSPH_OK) {
        consph_study_free(s);
        return pyc_raise(st);
    }
    char resume_cmd[1024];
    snprintf(resume_cmd, sizeof resume_cmd, "consph.study('%s', out_dir='%s'%s, resume=True)", path,
             out_dir, quick ? ", quick=True" : "");
    consph_study_options opt;
    memset(&opt, 0, sizeof opt);
    opt.quick = quick;
    opt.out_dir = out_dir;
    opt.log = log ? stderr : NULL;
    opt.resume = resume;
    opt.resume_cmd = resume_cmd;
    opt.jobs = jobs;
    opt.device = device;
    PYC_UNLOCKED(st = consph_study_run(s, &opt));
    PyObject *r = NULL;
    if (st != CONSPH_OK) {
        pyc_raise(st);
    } else {
        const char *name = consph_study_name(s), *title = consph_study_title(s);
        PyObject *dir = PyUnicode_FromFormat("%s/%s", out_dir, name);
        r = dir ? Py_BuildValue("{s:s,s:s,s:N}", "name", name, "title", title ? title : "", "dir",
                                dir)
                : NULL;
    }
    consph_study_free(s);
    return r;
}

PyDoc_STRVAR(study_estimate_doc, "study_estimate(path, quick=False)\n"
                                 "--\n"
                                 "\n"
                                 "Returns float. The study's rough run-time estimate in seconds "
                                 "(consph_study_estimate), before running it.");

static PyObject *py_study_estimate(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"path", "quick", NULL};
    const char *path;
    int quick = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s|p", kwlist, &path, &quick)) return NULL;
    consph_study *s = NULL;
    int st = consph_study_load(path, &s);
    if (st == CONSPH_OK) st = consph_study_validate(s, quick);
    double est = NAN;
    if (st == CONSPH_OK) PYC_UNLOCKED(est = consph_study_estimate(s, quick));
    consph_study_free(s);
    if (st != CONSPH_OK) return pyc_raise(st);
    return PyFloat_FromDouble(est);
}

/* A measure from an array of points (N, or N×d) or a consph.Particles (its masses, when wa is
 * None); `keep` holds what the measure points into until the caller frees it. */
typedef struct measure_src {
    consph_measure mu;
    consph_particles p;
    int have_p;
    PyArrayObject *x, *w;
    double *coords, *scratch;
} measure_src;

static void measure_free(measure_src *m)
{
    if (m->have_p) consph_particles_free(&m->p);
    Py_XDECREF(m->x);
    Py_XDECREF(m->w);
    free(m->coords);
    free(m->scratch);
}

static int measure_of(PyObject *obj, PyObject *wobj, const char *what, measure_src *m)
{
    memset(m, 0, sizeof *m);
    if (PyObject_HasAttrString(obj, "x") && PyObject_HasAttrString(obj, "lo")) {
        if (pyc_particles_from(obj, &m->p) < 0) return -1;
        m->have_p = 1;
        consph_mass_origin origin;
        int st = consph_measure_from_particles(&m->p, &m->mu, &m->scratch, &origin);
        if (st != CONSPH_OK) {
            pyc_raise(st);
            return -1;
        }
    } else {
        m->x = pyc_double_array(obj, what);
        if (!m->x) return -1;
        const int nd = PyArray_NDIM(m->x);
        const int dim = nd == 1 ? 1 : nd == 2 ? (int)PyArray_DIM(m->x, 1) : 0;
        const size_t n = nd >= 1 ? (size_t)PyArray_DIM(m->x, 0) : 0;
        if (dim < 1 || dim > 3) {
            pyc_raise_msg(CONSPH_EINVAL, "%s: expected N points (1D) or an N×d array, d in 1..3",
                          what);
            return -1;
        }
        m->coords = malloc((n ? n : 1) * (size_t)dim * sizeof(double));
        if (!m->coords) return PyErr_NoMemory(), -1;
        const double *xv = PyArray_DATA(m->x);
        for (size_t i = 0; i < n; ++i)
            for (int a = 0; a < dim; ++a)
                m->coords[(size_t)a * n + i] = xv[i * (size_t)dim + (size_t)a];
        m->mu.dim = dim;
        m->mu.n = n;
        for (int a = 0; a < dim; ++a) m->mu.x[a] = m->coords + (size_t)a * n;
    }
    if (wobj != Py_None) {
        m->w = pyc_double_array(wobj, "weights");
        if (!m->w) return -1;
        if ((size_t)PyArray_SIZE(m->w) != m->mu.n) {
            pyc_raise_msg(CONSPH_EINVAL, "%s: %ld weights for %zu points", what,
                          (long)PyArray_SIZE(m->w), m->mu.n);
            return -1;
        }
        m->mu.w = PyArray_DATA(m->w);
    }
    return 0;
}

PyDoc_STRVAR(
    wasserstein_doc,
    "wasserstein(a, b, wa=None, wb=None, method='exact', p=1, directions=64, seed=1,\n"
    "            eps=1e-3, tol=1e-6, max_iter=20000)\n"
    "--\n"
    "\n"
    "Returns dict. The Wasserstein distance W_p between two weighted point sets "
    "(consph_wasserstein,\n"
    "docs/wasserstein.md): a, b are N points (1D), N×d arrays or consph.Particles (whose\n"
    "'mass' field, or volume × rho, weighs them); wa, wb weights (None: equal, or the\n"
    "particles' masses), normalised to sum 1. method: exact (1D), sliced (directions, seed) or\n"
    "sinkhorn (eps relative to the largest cost, tol, max_iter). Returns distance, error (the\n"
    "method's own estimate), and for sinkhorn marginal_error, eps_abs, cost_max, iterations,\n"
    "converged. Options a method does not read raise, as the CLI refuses them.");

static PyObject *py_wasserstein(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"a",          "b",    "wa",  "wb",  "method",   "p",
                             "directions", "seed", "eps", "tol", "max_iter", NULL};
    PyObject *ao, *bo, *wa = Py_None, *wb = Py_None;
    PyObject *diro = Py_None, *seedo = Py_None, *epso = Py_None, *tolo = Py_None, *itero = Py_None;
    const char *method = "exact";
    int p = 1;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OO|OOsiOOOOO", kwlist, &ao, &bo, &wa, &wb, &method,
                                     &p, &diro, &seedo, &epso, &tolo, &itero))
        return NULL;
    consph_ot_options opt = consph_ot_defaults();
    opt.p = p;
    if (!strcmp(method, "exact"))
        opt.method = CONSPH_OT_EXACT;
    else if (!strcmp(method, "sliced"))
        opt.method = CONSPH_OT_SLICED;
    else if (!strcmp(method, "sinkhorn"))
        opt.method = CONSPH_OT_SINKHORN;
    else
        return pyc_raise_msg(CONSPH_EINVAL,
                             "method '%s' is unknown (allowed: exact, sliced, sinkhorn)", method);
    measure_src a, b;
    if (measure_of(ao, wa, "a", &a) < 0) {
        measure_free(&a);
        return NULL;
    }
    if (measure_of(bo, wb, "b", &b) < 0) {
        measure_free(&a);
        measure_free(&b);
        return NULL;
    }
    const struct {
        PyObject *v;
        const char *name;
        consph_ot_param param;
    } tune[] = {{diro, "directions", CONSPH_OT_PARAM_DIRECTIONS},
                {seedo, "seed", CONSPH_OT_PARAM_SEED},
                {epso, "eps", CONSPH_OT_PARAM_EPS},
                {tolo, "tol", CONSPH_OT_PARAM_TOL},
                {itero, "max_iter", CONSPH_OT_PARAM_MAX_ITER}};
    PyObject *r = NULL;
    for (size_t k = 0; k < sizeof tune / sizeof tune[0]; ++k) {
        if (tune[k].v == Py_None) continue;
        if (!consph_ot_param_read(opt.method, a.mu.dim, tune[k].param)) {
            pyc_raise_msg(CONSPH_EINVAL, "%s does nothing for method %s in %dD", tune[k].name,
                          method, a.mu.dim);
            goto done;
        }
        const double v = PyFloat_AsDouble(tune[k].v);
        if (v == -1.0 && PyErr_Occurred()) goto done;
        switch (tune[k].param) {
        case CONSPH_OT_PARAM_DIRECTIONS:
            opt.directions = (int)v;
            break;
        case CONSPH_OT_PARAM_SEED:
            opt.seed = (uint64_t)v;
            break;
        case CONSPH_OT_PARAM_EPS:
            opt.eps = v;
            break;
        case CONSPH_OT_PARAM_TOL:
            opt.tol = v;
            break;
        case CONSPH_OT_PARAM_MAX_ITER:
            opt.max_iter = (long)v;
            break;
        }
    }
    consph_ot_result res;
    int st;
    PYC_UNLOCKED(st = consph_wasserstein(&a.mu, &b.mu, &opt, &res));
    if (st != CONSPH_OK) {
        pyc_raise(st);
        goto done;
    }
    r = Py_BuildValue("{s:d,s:d,s:d,s:d,s:d,s:l,s:O}", "distance", res.distance, "error", res.error,
                      "marginal_error", res.marginal_error, "eps_abs", res.eps_abs, "cost_max",
                      res.cost_max, "iterations", res.iterations, "converged",
                      res.converged ? Py_True : Py_False);
done:
    measure_free(&a);
    measure_free(&b);
    return r;
}

PyDoc_STRVAR(run_params_doc,
             "run_params()\n"
             "--\n"
             "\n"
             "Returns list of dict. The run parameter table (src/solver/params.def): per parameter "
             "its name (the key\n"
             "of consph.Solver and of study files), option (consph run's), study_key, owner,\n"
             "allowed (text), default (text) and help.");

static PyObject *py_run_params(PyObject *self, PyObject *args)
{
    (void)self;
    (void)args;
    consph_run_params def;
    consph_run_params_default(&def);
    PyObject *l = PyList_New(0);
    for (int k = 0; l && k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        char allowed[512], dflt[128];
        consph_run_param_allowed(d, allowed, sizeof allowed);
        if (consph_run_param_format(&def, d->name, dflt, sizeof dflt) != CONSPH_OK) dflt[0] = 0;
        PyObject *e = Py_BuildValue("{s:s,s:z,s:z,s:s,s:s,s:s,s:s}", "name", d->name, "option",
                                    d->option, "study_key", d->study_key, "owner", d->owner,
                                    "allowed", allowed, "default", dflt, "help", d->help);
        if (!e || PyList_Append(l, e) < 0) {
            Py_XDECREF(e);
            Py_DECREF(l);
            return NULL;
        }
        Py_DECREF(e);
    }
    consph_clear_error();
    return l;
}

PyDoc_STRVAR(
    name_lists_doc,
    "names(what, /)\n"
    "--\n"
    "\n"
    "Returns list of str. The allowed names of 'problem', 'scheme', 'integrator' or 'study_kind'.");

static PyObject *py_names(PyObject *self, PyObject *args)
{
    (void)self;
    const char *what;
    if (!PyArg_ParseTuple(args, "s", &what)) return NULL;
    if (!strcmp(what, "problem")) return pyc_name_list(consph_problem_names());
    if (!strcmp(what, "scheme")) return pyc_name_list(consph_scheme_names());
    if (!strcmp(what, "integrator")) return pyc_name_list(consph_integrator_names());
    if (!strcmp(what, "study_kind")) return pyc_name_list(consph_study_kind_names());
    return pyc_raise_msg(CONSPH_EINVAL,
                         "names: '%s' is unknown (allowed: problem, scheme, integrator, "
                         "study_kind)",
                         what);
}

#define KW (METH_VARARGS | METH_KEYWORDS)
#define FN(f) (PyCFunction)(void (*)(void))(f)

PyMethodDef pyc_study_methods[] = {
    {"run_study", FN(py_run_study), KW, run_study_doc},
    {"study_estimate", FN(py_study_estimate), KW, study_estimate_doc},
    {"wasserstein", FN(py_wasserstein), KW, wasserstein_doc},
    {"run_params", py_run_params, METH_NOARGS, run_params_doc},
    {"names", py_names, METH_VARARGS, name_lists_doc},
    {NULL, NULL, 0, NULL}};
