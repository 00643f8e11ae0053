/* consph._core.Solver: the WCSPH solver (include/consph/solver.h) from a problem and the run
 * parameters of its table (src/solver/params.def), stepped from Python, its fields as numpy
 * copies, its summary, checkpoints and restart. */
#include "pyconsph.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

typedef struct {
    PyObject_HEAD consph_solver *s;
    /* 1 + the step count at the last consph_solver_sync (0: none): a GPU run's host copy is
     * whole until its next step */
    long synced_at;
} solver_object;

/* Python's value as the text consph_run_param_set reads; None is "none", the special value of
 * tf and steps. */
static int param_text(PyObject *v, char *buf, size_t size)
{
    if (v == Py_None) {
        snprintf(buf, size, "none");
    } else if (PyBool_Check(v)) {
        PyErr_SetString(PyExc_TypeError, "a run parameter is a number or a name, not a bool");
        return -1;
    } else if (PyUnicode_Check(v)) {
        const char *s = PyUnicode_AsUTF8(v);
        if (!s) return -1;
        snprintf(buf, size, "%s", s);
    } else {
        /* integers (numpy's too) in decimal; other numbers as Python's repr of the float, the
         * shortest text that reads back to the same double, so messages quote what was given */
        PyObject *num = PyIndex_Check(v) ? PyNumber_Index(v) : PyNumber_Float(v);
        PyObject *r = num ? (PyLong_Check(num) ? PyObject_Str(num) : PyObject_Repr(num)) : NULL;
        const char *s = r ? PyUnicode_AsUTF8(r) : NULL;
        if (s) snprintf(buf, size, "%s", s);
        Py_XDECREF(num);
        Py_XDECREF(r);
        if (!s) return -1;
    }
    return 0;
}

/* Whether the parameter `name` is set by a keyword or by a key of the run file that stays (not
 * replaced by a keyword); where into buf ("alpha" or "FILE:LINE: key 'alpha'"). */
static int param_given(PyObject *kw, const consph_run_file *rf, const char *name, char *buf,
                       size_t size)
{
    if (kw && PyDict_GetItemString(kw, name)) {
        snprintf(buf, size, "%s", name);
        return 1;
    }
    const int k = consph_run_file_find(rf, name);
    if (k < 0) return 0;
    snprintf(buf, size, "%s:%d: key '%s'", rf->path, rf->key[k].line, rf->key[k].param->study_key);
    return 1;
}

/* consph_run_file_apply's `given`: the keywords replace the file's keys. */
static int keyword_sets(void *kw, const char *name)
{
    return kw && PyDict_GetItemString(kw, name) != NULL;
}

/* consph_run_params_unread's `given`: a keyword, or a key of the run file that stays. */
typedef struct given_ctx {
    PyObject *kw;
    const consph_run_file *rf;
} given_ctx;

static int given_where(void *ctx, const char *name, char *where, size_t size)
{
    const given_ctx *g = ctx;
    return param_given(g->kw, g->rf, name, where, size);
}

/* A parameter the run's scheme or layout does not read would do nothing: refused as consph run
 * refuses its option. */
static int unread_params(PyObject *kw, const consph_run_file *rf, const consph_run_params *prm)
{
    given_ctx g = {kw, rf};
    if (consph_run_params_unread(prm, given_where, &g, "scheme", "layout") == CONSPH_OK) return 0;
    pyc_raise_msg(CONSPH_EINVAL, "%s", consph_last_error());
    return -1;
}

/* One field of the given particles into given's field `to`: dim components when `vector` (a
 * velocity may carry a third component of 0 in 2D, as a VTU vector does), else 1, read through
 * elem(i, c) = data[i * si + c * sc]; `what` names it in messages. */
static int given_field(consph_particles *given, const char *to, const char *what,
                       const double *data, size_t si, size_t sc, int ncomp, int vector)
{
    const int dim = given->dim, want = vector ? dim : 1;
    const int pad = vector && dim == 2 && ncomp == 3;
    if (ncomp != want && !pad)
        return pyc_raise_msg(CONSPH_EINVAL, "particles: field '%s' has %d components, not %d", what,
                             ncomp, want),
               -1;
    for (size_t i = 0; pad && i < given->n; ++i)
        if (data[i * si + 2 * sc] != 0.0)
            return pyc_raise_msg(CONSPH_EINVAL,
                                 "particles: field '%s' of particle %zu has z = %.17g, but the "
                                 "problem is 2D",
                                 what, i, data[i * si + 2 * sc]),
                   -1;
    double *dst = consph_particles_field(given, to, want);
    if (!dst) return pyc_raise(CONSPH_ENOMEM), -1;
    for (int c = 0; c < want; ++c)
        for (size_t i = 0; i < given->n; ++i)
            dst[(size_t)c * given->cap + i] = data[i * si + (size_t)c * sc];
    return 0;
}

/* A field of a consph.Particles by either of its names (a snapshot's array `name` or a CSV's
 * columns `other`) into given's field `to`; nothing when it has neither, refused when both. */
static int particles_field(const consph_particles *src, consph_particles *given, const char *name,
                           const char *other, const char *to, int vector)
{
    const consph_field *a = consph_particles_find(src, name),
                       *b = consph_particles_find(src, other);
    if (a && b)
        return pyc_raise_msg(CONSPH_EINVAL, "particles has both fields '%s' and '%s': keep one",
                             name, other),
               -1;
    const consph_field *f = a ? a : b;
    if (!f) return 0;
    return given_field(given, to, f->name, f->data, 1, src->cap, f->ncomp, vector);
}

/* An array argument (u or p of a tuple) as a field; None is none. */
static int tuple_field(PyObject *o, consph_particles *given, const char *what, int vector)
{
    if (o == Py_None) return 0;
    PyArrayObject *a = pyc_double_array(o, what);
    if (!a) return -1;
    const int nd = PyArray_NDIM(a);
    int ncomp = nd == 1 ? 1 : nd == 2 ? (int)PyArray_DIM(a, 1) : 0;
    if (nd < 1 || nd > 2 || (size_t)PyArray_DIM(a, 0) != given->n) ncomp = 0;
    int rc = -1;
    if (ncomp < 1)
        pyc_raise_msg(CONSPH_EINVAL, "particles: %s must hold N = %zu values%s", what, given->n,
                      vector ? " × dim" : "");
    else
        rc = given_field(given, what, what, PyArray_DATA(a), (size_t)ncomp, 1, ncomp, vector);
    Py_DECREF(a);
    return rc;
}

static void box_text(const consph_box *b, int dim, char *buf, size_t size)
{
    size_t len = 0;
    buf[0] = '\0';
    for (int a = 0; a < dim && len < size; ++a)
        len += (size_t)snprintf(buf + len, size - len, "%s[%.17g, %.17g]", a ? "x" : "", b->lo[a],
                                b->hi[a]);
    char axes[CONSPH_MAX_DIM + 1] = "";
    for (int a = 0, k = 0; a < dim; ++a)
        if (b->periodic[a]) axes[k++] = "xyz"[a], axes[k] = '\0';
    if (len < size)
        snprintf(buf + len, size - len, axes[0] ? ", periodic %s" : ", not periodic", axes);
}

/* Solver(particles=...): a consph.Particles (its box and periodicity must be the problem's; its
 * fields u or velocity, p or pressure) or a tuple (x, u=None, p=None) in the problem's box, into
 * `given` as consph_solver_create_from takes them (consph run --particles, apps/cmd_run.c). */
static int given_particles(PyObject *obj, const consph_run_params *prm, consph_particles *given)
{
    consph_layout_params lp;
    if (consph_run_layout_params(prm, &lp) != CONSPH_OK) return pyc_raise(CONSPH_EINVAL), -1;
    const int dim = consph_problem_dim(prm->problem);
    consph_box box = lp.box;
    box.dim = dim;
    if (PyTuple_Check(obj) || PyList_Check(obj)) {
        PyObject *t = PySequence_Tuple(obj);
        if (!t) return -1;
        PyObject *xo, *uo = Py_None, *po = Py_None;
        int rc = PyArg_ParseTuple(t, "O|OO:particles (x, u=None, p=None)", &xo, &uo, &po) &&
                         pyc_particles_positions(xo, &box, given) >= 0 &&
                         tuple_field(uo, given, "u", 1) == 0 && tuple_field(po, given, "p", 0) == 0
                     ? 0
                     : -1;
        Py_DECREF(t);
        return rc;
    }
    consph_particles src;
    if (pyc_particles_from(obj, &src) < 0) return -1;
    int bad = src.dim != dim;
    for (int a = 0; a < dim && !bad; ++a)
        bad = src.box.lo[a] != box.lo[a] || src.box.hi[a] != box.hi[a] ||
              !src.box.periodic[a] != !box.periodic[a];
    int rc = -1;
    if (bad) {
        char want[200], have[200];
        box_text(&box, dim, want, sizeof want);
        box_text(&src.box, src.dim, have, sizeof have);
        pyc_raise_msg(CONSPH_EINVAL,
                      "particles: their box is %s (%dD), but problem %s is %s: a run takes its "
                      "problem's box and periodicity",
                      have, src.dim, prm->problem, want);
    } else if (consph_particles_init(given, dim, src.n, &box) != CONSPH_OK) {
        pyc_raise(CONSPH_ENOMEM);
    } else {
        for (int a = 0; a < dim; ++a) memcpy(given->x[a], src.x[a], src.n * sizeof(double));
        rc = particles_field(&src, given, "velocity", "u", "u", 1) < 0 ||
                     particles_field(&src, given, "pressure", "p", "p", 0) < 0
                 ? -1
                 : 0;
    }
    consph_particles_free(&src);
    return rc;
}

/* The run's parameters from the problem's defaults, the run file's keys (rf NULL: none) and the
 * keywords, in that order, with consph run's rules between them (apps/cmd_run.c). */
static int init_params(PyObject *args, PyObject *kw, consph_run_file *rf, consph_run_params *prm)
{
    const char *problem = NULL;
    if (!PyArg_ParseTuple(args, "|s:Solver", &problem)) return -1;
    consph_run_params_default(prm);
    PyObject *pobj = kw ? PyDict_GetItemString(kw, "problem") : NULL;
    if (pobj) {
        if (PyTuple_GET_SIZE(args)) {
            PyErr_SetString(PyExc_TypeError, "Solver: problem given twice");
            return -1;
        }
        problem = PyUnicode_AsUTF8(pobj);
        if (!problem) return -1;
    }
    const int file_problem = problem ? -1 : consph_run_file_find(rf, "problem");
    if (file_problem >= 0) problem = rf->key[file_problem].value;
    if (consph_run_params_problem(prm, problem ? problem : "taylor-green") != CONSPH_OK) {
        if (file_problem < 0) return pyc_raise(CONSPH_EINVAL), -1;
        char why[512];
        snprintf(why, sizeof why, "%s", consph_last_error());
        return pyc_raise_msg(CONSPH_EINVAL, "%s:%d: key 'problem': %s", rf->path,
                             rf->key[file_problem].line, why),
               -1;
    }
    /* every key is a parameter of the table; unknown ones get the library's message */
    PyObject *key, *val;
    Py_ssize_t pos = 0;
    while (kw && PyDict_Next(kw, &pos, &key, &val)) {
        const char *name = PyUnicode_AsUTF8(key);
        if (!name) return -1;
        if (!strcmp(name, "problem") || !strcmp(name, "particles") || !strcmp(name, "config") ||
            !strcmp(name, "device"))
            continue;
        if (!consph_run_param_find(name)) {
            char names[2048] = "";
            for (int k = 0; k < consph_run_param_count(); ++k) {
                size_t len = strlen(names);
                snprintf(names + len, sizeof names - len, "%s%s", k ? ", " : "",
                         consph_run_param_at(k)->name);
            }
            pyc_raise_msg(CONSPH_EINVAL, "no run parameter is named '%.40s' (allowed: %s)", name,
                          names);
            return -1;
        }
    }
    /* the file's keys, those a keyword replaces checked but not applied */
    if (rf && consph_run_file_apply(rf, prm, keyword_sets, kw) != CONSPH_OK)
        return pyc_raise(CONSPH_EINVAL), -1;
    int have_steps = 0, have_tf = 0, have_re = 0, have_nu = 0;
    /* in the table's order, as consph run sets its options */
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        PyObject *v = kw ? PyDict_GetItemString(kw, d->name) : NULL;
        if (!v || !strcmp(d->name, "problem")) continue;
        char text[512];
        if (param_text(v, text, sizeof text) < 0) return -1;
        if (consph_run_param_set(prm, d->name, text) != CONSPH_OK)
            return pyc_raise(CONSPH_EINVAL), -1;
        have_steps |= !strcmp(d->name, "steps") && v != Py_None;
        have_tf |= !strcmp(d->name, "tf") && v != Py_None;
        have_re |= !strcmp(d->name, "re");
        have_nu |= !strcmp(d->name, "nu");
    }
    /* the rules of consph run between its options (apps/cmd_run.c) */
    if (have_steps && have_tf)
        return pyc_raise_msg(CONSPH_EINVAL, "steps and tf both set the end of the run: give one"),
               -1;
    if (have_re && have_nu)
        return pyc_raise_msg(CONSPH_EINVAL, "re and nu both set the viscosity: give one"), -1;
    if (have_re || consph_run_file_find(rf, "re") >= 0) prm->nu = -1.0; /* ν from Re */
    if (have_steps || consph_run_file_find(rf, "steps") >= 0) prm->tf = 0.0;
    char where[320];
    if (prm->dt > 0.0 && (param_given(kw, rf, "cfl", where, sizeof where) ||
                          param_given(kw, rf, "h_dt", where, sizeof where)))
        return pyc_raise_msg(CONSPH_EINVAL,
                             "%s sets the time-step rule, which dt %g replaces: give one", where,
                             prm->dt),
               -1;
    if (param_given(kw, rf, "error_times", where, sizeof where) &&
        prm->error != CONSPH_ERROR_AUTHORS)
        return pyc_raise_msg(CONSPH_EINVAL,
                             "%s counts the output times of error 'authors': give error='authors' "
                             "too",
                             where),
               -1;
    if (consph_run_params_check(prm) != CONSPH_OK) return pyc_raise(CONSPH_EINVAL), -1;
    return unread_params(kw, rf, prm);
}

/* device='cpu' or 'gpu' (None: the CPU) into *dev, as consph run --device reads it. */
static int device_of(PyObject *obj, consph_device *dev)
{
    *dev = CONSPH_DEVICE_CPU;
    if (!obj || obj == Py_None) return 0;
    const char *name = PyUnicode_Check(obj) ? PyUnicode_AsUTF8(obj) : NULL;
    if (!name && PyErr_Occurred()) return -1;
    if (name && !strcmp(name, "gpu")) {
        *dev = CONSPH_DEVICE_GPU;
        return 0;
    }
    if (name && !strcmp(name, "cpu")) return 0;
    PyObject *r = PyObject_Repr(obj);
    const char *text = r ? PyUnicode_AsUTF8(r) : NULL;
    if (text) pyc_raise_msg(CONSPH_EINVAL, "device %.40s is unknown (allowed: cpu, gpu)", text);
    Py_XDECREF(r);
    return -1;
}

/* The solver's steps onto `dev` (docs/gpu.md); its refusal as consph.InvalidArgument. */
static int move_to(consph_solver *s, consph_device dev)
{
    if (dev == consph_solver_device(s)) return 0;
    int st;
    if (dev == CONSPH_DEVICE_GPU && consph_gpu_check(consph_solver_params(s)) != CONSPH_OK)
        return pyc_raise(CONSPH_EINVAL), -1;
    PYC_UNLOCKED(st = consph_solver_set_device(s, dev));
    return st == CONSPH_OK ? 0 : (pyc_raise(st), -1);
}

static int solver_init(PyObject *self, PyObject *args, PyObject *kw)
{
    solver_object *so = (solver_object *)self;
    PyObject *cobj = kw ? PyDict_GetItemString(kw, "config") : NULL;
    consph_run_file *rf = NULL;
    char path[4096]; /* rf->path points here */
    if (cobj && cobj != Py_None) {
        PyObject *bytes = NULL;
        if (!PyUnicode_FSConverter(cobj, &bytes)) return -1;
        snprintf(path, sizeof path, "%s", PyBytes_AS_STRING(bytes));
        Py_DECREF(bytes);
        rf = malloc(sizeof *rf);
        if (!rf) return PyErr_NoMemory(), -1;
        int st;
        PYC_UNLOCKED(st = consph_run_file_load(rf, path));
        if (st != CONSPH_OK) {
            free(rf);
            return pyc_raise(st), -1;
        }
    }
    consph_run_params prm;
    consph_device dev = CONSPH_DEVICE_CPU;
    int rc = init_params(args, kw, rf, &prm);
    if (!rc) rc = device_of(kw ? PyDict_GetItemString(kw, "device") : NULL, &dev);
    /* the GPU's refusals before the set-up's work, as consph run makes them */
    if (!rc && dev == CONSPH_DEVICE_GPU && consph_gpu_check(&prm) != CONSPH_OK) {
        pyc_raise(CONSPH_EINVAL);
        rc = -1;
    }
    PyObject *gobj = kw ? PyDict_GetItemString(kw, "particles") : NULL;
    if (gobj == Py_None) gobj = NULL;
    consph_particles given;
    memset(&given, 0, sizeof given);
    if (!rc && gobj) {
        static const char *const layout_only[] = {"nx", "layout", "seed"};
        char where[320];
        for (size_t k = 0; !rc && k < sizeof layout_only / sizeof layout_only[0]; ++k)
            if (param_given(kw, rf, layout_only[k], where, sizeof where)) {
                pyc_raise_msg(CONSPH_EINVAL,
                              "%s: not with particles (the particles and their count replace "
                              "the layout)",
                              where);
                rc = -1;
            }
        if (!rc) rc = given_particles(gobj, &prm, &given);
        if (!rc && (consph_run_params_particles(&prm, given.n) != CONSPH_OK ||
                    consph_run_params_check(&prm) != CONSPH_OK)) {
            pyc_raise(CONSPH_EINVAL);
            rc = -1;
        }
    }
    free(rf);
    consph_solver *s = NULL;
    int st = CONSPH_OK;
    if (!rc)
        PYC_UNLOCKED(st = gobj ? consph_solver_create_from(&s, &prm, &given)
                               : consph_solver_create(&s, &prm));
    consph_particles_free(&given);
    if (rc) return -1;
    if (st != CONSPH_OK) return pyc_raise(st), -1;
    if (move_to(s, dev) < 0) {
        consph_solver_free(s);
        return -1;
    }
    consph_solver_free(so->s);
    so->s = s;
    so->synced_at = 0;
    return 0;
}

static void solver_dealloc(PyObject *self)
{
    solver_object *so = (solver_object *)self;
    consph_solver_free(so->s);
    Py_TYPE(self)->tp_free(self);
}

static int ready(solver_object *so)
{
    if (so->s) return 1;
    pyc_raise_msg(CONSPH_EINVAL, "Solver: not set up (its creation failed)");
    return 0;
}

/* ready, and the host's copy of every array the current state: a run on the GPU copies back
 * only what its log samples and snapshots read (consph_solver_sync). */
static int ready_synced(solver_object *so)
{
    if (!ready(so)) return 0;
    const long at = consph_solver_step_count(so->s) + 1;
    if (consph_solver_device(so->s) == CONSPH_DEVICE_CPU || so->synced_at == at) return 1;
    int st;
    PYC_UNLOCKED(st = consph_solver_sync(so->s));
    if (st != CONSPH_OK) return pyc_raise(st), 0;
    so->synced_at = at;
    return 1;
}

PyDoc_STRVAR(
    step_doc,
    "step($self, /, n=1)\n"
    "--\n"
    "\n"
    "Advances the run by n time steps (consph_solver_step). A run that leaves its model's\n"
    "validity raises consph.Failure (code ENUMERIC) naming the step, particle and bound;\n"
    "stepping a finished run raises consph.InvalidArgument.");

static PyObject *solver_step(PyObject *self, PyObject *args, PyObject *kw)
{
    solver_object *so = (solver_object *)self;
    static char *kwlist[] = {"n", NULL};
    long n = 1;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "|l", kwlist, &n)) return NULL;
    if (!ready(so)) return NULL;
    so->synced_at = 0; /* a step that fails may have moved the device's state */
    int st = CONSPH_OK;
    PYC_UNLOCKED(for (long k = 0; k < n && st == CONSPH_OK; ++k) st = consph_solver_step(so->s));
    if (st != CONSPH_OK) return pyc_raise(st);
    Py_RETURN_NONE;
}

/* The run to its end with the files of consph run --out DIR (apps/cmd_run.c). */
static PyObject *run_files(solver_object *so, PyObject *tfo, PyObject *stepso, const char *out,
                           long snap_every, long ckpt_every)
{
    if (tfo != Py_None || stepso != Py_None)
        return pyc_raise_msg(CONSPH_EINVAL, "out: a run with files goes to its own end: give "
                                            "tf or steps when creating the Solver, not here");
    if (snap_every < 0 || ckpt_every < 0)
        return pyc_raise_msg(CONSPH_EINVAL, "snapshot_every and checkpoint_every must be >= 0");
    struct stat sb;
    if (stat(out, &sb) != 0 && mkdir(out, 0777) != 0)
        return pyc_raise_msg(CONSPH_EIO, "out: cannot create directory '%s': %s", out,
                             strerror(errno));
    const long step0 = consph_solver_step_count(so->s);
    consph_run_output ro = {out, snap_every, ckpt_every, 0, 0};
    consph_run_summary sum;
    int st, sig = 0;
    PYC_UNLOCKED(st = consph_run(so->s, &ro, &sum, &sig));
    if (st != CONSPH_OK) return pyc_raise(st);
    return PyLong_FromLong(consph_solver_step_count(so->s) - step0);
}

PyDoc_STRVAR(
    run_doc,
    "run($self, /, tf=None, steps=None, out=None, snapshot_every=0, checkpoint_every=0)\n"
    "--\n"
    "\n"
    "Returns int. Steps until the run's own end (its tf or steps), or earlier: until t >= tf, or\n"
    "until step_count reaches steps (a total, not a count from now); give one of them.\n"
    "The run's own last step lands on its final time; tf before it stops at the first\n"
    "step ending at or after it. tf or steps past the run's end becomes its end\n"
    "(consph_solver_extend): the run then continues as one created with that end would,\n"
    "bit for bit, landing on tf. A run whose last step was shortened to land on its tf,\n"
    "or one with error='authors', cannot be extended: consph.InvalidArgument with the\n"
    "library's reason. Returns the steps taken. Interrupt with Ctrl-C between steps.\n"
    "out: a directory (created if missing) where the run goes to its end writing the\n"
    "files of `consph run --out` (consph_run: snapshots every snapshot_every steps\n"
    "(0: the first and the last) indexed by run.pvd, log.csv, summary.json, and\n"
    "checkpoint.ckpt every checkpoint_every steps); not with tf or steps.");

static PyObject *solver_run(PyObject *self, PyObject *args, PyObject *kw)
{
    solver_object *so = (solver_object *)self;
    static char *kwlist[] = {"tf", "steps", "out", "snapshot_every", "checkpoint_every", NULL};
    PyObject *tfo = Py_None, *stepso = Py_None;
    const char *out = NULL;
    long snap_every = 0, ckpt_every = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "|OOzll", kwlist, &tfo, &stepso, &out, &snap_every,
                                     &ckpt_every))
        return NULL;
    if (!ready(so)) return NULL;
    so->synced_at = 0;
    if (out) return run_files(so, tfo, stepso, out, snap_every, ckpt_every);
    double tf = INFINITY;
    long steps = -1;
    if (tfo != Py_None && ((tf = PyFloat_AsDouble(tfo)) == -1.0 && PyErr_Occurred())) return NULL;
    if (stepso != Py_None && ((steps = PyLong_AsLong(stepso)) == -1 && PyErr_Occurred()))
        return NULL;
    if (tfo != Py_None && stepso != Py_None)
        return pyc_raise_msg(CONSPH_EINVAL, "run: tf and steps both say where to stop: give one");
    /* A stop past the run's own end becomes its end (consph_solver_extend), so the run goes on
     * as one created with that end: its last step lands on tf. Every step of a run of steps is
     * a full Δt, so such a run ends at steps·Δt; a run to t_f passes `steps` when that many
     * steps of Δt pass t_f. */
    const consph_run_params *prm = consph_solver_params(so->s);
    const double dt = consph_solver_dt(so->s);
    const long step0 = consph_solver_step_count(so->s);
    const int past =
        tfo != Py_None ? tf > (prm->steps > 0 ? (double)prm->steps * dt : prm->tf)
        : stepso != Py_None
            ? (prm->steps > 0 ? steps > prm->steps
                              : consph_solver_time(so->s) + (double)(steps - step0) * dt > prm->tf)
            : 0;
    if (past && consph_solver_extend(so->s, tfo != Py_None ? tf : 0.0,
                                     tfo != Py_None ? 0 : steps) != CONSPH_OK)
        return pyc_raise(CONSPH_EINVAL);
    long taken = 0;
    while (!consph_solver_done(so->s) && consph_solver_time(so->s) < tf &&
           (steps < 0 || consph_solver_step_count(so->s) < steps)) {
        int st;
        PYC_UNLOCKED(st = consph_solver_step(so->s));
        if (st != CONSPH_OK) return pyc_raise(st);
        ++taken;
        if (PyErr_CheckSignals() < 0) return NULL;
    }
    return PyLong_FromLong(taken);
}

/* The order that puts particles back in their initial order (the field "id"). */
static size_t *initial_order(const consph_particles *p)
{
    const consph_field *id = consph_particles_find(p, "id");
    size_t *order = malloc((p->n ? p->n : 1) * sizeof *order);
    if (!order) return NULL;
    for (size_t i = 0; i < p->n; ++i) order[i] = i;
    if (!id) return order;
    for (size_t i = 0; i < p->n; ++i) {
        const double v = id->data[i];
        if (v >= 0 && v < (double)p->n) order[(size_t)v] = i;
    }
    return order;
}

PyDoc_STRVAR(field_doc,
             "field($self, /, name, order='initial')\n"
             "--\n"
             "\n"
             "Returns ndarray. A copy of one field of the run's particles "
             "(consph_solver_particles): 'x' the\n"
             "positions (N×d), or a particle field by its name in the solver (u, p, rhof,\n"
             "volume, id, u_exact, p_exact, vorticity, ...: field_names()). N values or N×k.\n"
             "order 'initial' puts the particles in their initial order (by the field id);\n"
             "'current' keeps the solver's (cell) order, the order of its snapshots.\n"
             "Copies, not views: they stay valid after further steps and after the solver.\n"
             "u_exact, p_exact and vorticity are refreshed first (consph_solver_output_fields).");

static PyObject *solver_field(PyObject *self, PyObject *args, PyObject *kw)
{
    solver_object *so = (solver_object *)self;
    static char *kwlist[] = {"name", "order", NULL};
    const char *name, *ord = "initial";
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s|s", kwlist, &name, &ord)) return NULL;
    if (!ready_synced(so)) return NULL;
    if (strcmp(ord, "initial") && strcmp(ord, "current"))
        return pyc_raise_msg(CONSPH_EINVAL, "order '%s' is unknown (allowed: initial, current)",
                             ord);
    if (!strcmp(name, "u_exact") || !strcmp(name, "p_exact") || !strcmp(name, "vorticity")) {
        int st = consph_solver_output_fields(so->s);
        if (st != CONSPH_OK) return pyc_raise(st);
    }
    const consph_particles *p = consph_solver_particles(so->s);
    size_t *order = strcmp(ord, "initial") ? NULL : initial_order(p);
    if (!strcmp(ord, "initial") && !order) return PyErr_NoMemory();
    PyObject *r = NULL;
    if (!strcmp(name, "x")) {
        npy_intp dims[2] = {(npy_intp)p->n, p->dim};
        PyArrayObject *a = (PyArrayObject *)PyArray_SimpleNew(2, dims, NPY_DOUBLE);
        if (a)
            for (size_t i = 0; i < p->n; ++i)
                for (int c = 0; c < p->dim; ++c)
                    ((double *)PyArray_DATA(a))[i * (size_t)p->dim + (size_t)c] =
                        p->x[c][order ? order[i] : i];
        r = (PyObject *)a;
    } else {
        const consph_field *f = consph_particles_find(p, name);
        if (!f) {
            char names[1024] = "x";
            for (int k = 0; k < p->nfields; ++k) {
                size_t len = strlen(names);
                snprintf(names + len, sizeof names - len, ", %s", p->fields[k].name);
            }
            pyc_raise_msg(CONSPH_EINVAL, "the run has no field '%.40s' (allowed: %s)", name, names);
        } else {
            r = pyc_field_array(f->data, p->n, p->cap, f->ncomp, order);
        }
    }
    free(order);
    return r;
}

PyDoc_STRVAR(field_names_doc, "field_names($self, /)\n"
                              "--\n"
                              "\n"
                              "Returns list of str. The fields of the run's particles (every "
                              "declared field, state and scratch).");

static PyObject *solver_field_names(PyObject *self, PyObject *args)
{
    (void)args;
    solver_object *so = (solver_object *)self;
    if (!ready(so)) return NULL;
    const consph_particles *p = consph_solver_particles(so->s);
    PyObject *l = PyList_New(p->nfields);
    for (int k = 0; l && k < p->nfields; ++k)
        PyList_SET_ITEM(l, k, PyUnicode_FromString(p->fields[k].name));
    return l;
}

PyDoc_STRVAR(particles_doc,
             "_particles($self, /, order='initial')\n"
             "--\n"
             "\n"
             "Returns dict. Every field of the run's particles and their positions, box and "
             "periodicity as a\n"
             "particle dict (copies; consph.Solver.particles wraps it into a consph.Particles).");

static PyObject *solver_particles(PyObject *self, PyObject *args, PyObject *kw)
{
    solver_object *so = (solver_object *)self;
    static char *kwlist[] = {"order", NULL};
    const char *ord = "initial";
    if (!PyArg_ParseTupleAndKeywords(args, kw, "|s", kwlist, &ord)) return NULL;
    if (!ready_synced(so)) return NULL;
    if (strcmp(ord, "initial") && strcmp(ord, "current"))
        return pyc_raise_msg(CONSPH_EINVAL, "order '%s' is unknown (allowed: initial, current)",
                             ord);
    int st = consph_solver_output_fields(so->s);
    if (st != CONSPH_OK) return pyc_raise(st);
    const consph_particles *p = consph_solver_particles(so->s);
    size_t *order = strcmp(ord, "initial") ? NULL : initial_order(p);
    PyObject *d = pyc_particles_dict(p, order);
    free(order);
    return d;
}

static int dict_double(PyObject *d, const char *k, double v)
{
    return pyc_dict_steal(d, k, PyFloat_FromDouble(v));
}

PyDoc_STRVAR(summary_doc,
             "summary($self, /)\n"
             "--\n"
             "\n"
             "Returns dict. What the run measured so far (consph_solver_summary; the members of\n"
             "consph_run_summary, summary.json's keys): scheme, problem, integrator, n, dim,\n"
             "steps, t, dt, h, c0, l1_u, l1_p (001 eq. 26), linf_u, linf_p, ke, momentum,\n"
             "angular_momentum, ft_fmax, max_divu, seconds, pairs, ... (NaN where not measured).");

static PyObject *solver_summary(PyObject *self, PyObject *args)
{
    (void)args;
    solver_object *so = (solver_object *)self;
    if (!ready_synced(so)) return NULL;
    consph_run_summary s;
    int st = consph_solver_summary(so->s, &s);
    if (st != CONSPH_OK) return pyc_raise(st);
    PyObject *d = Py_BuildValue(
        "{s:s,s:s,s:s,s:n,s:i,s:l,s:i,s:i,s:i,s:i,s:l,s:n,s:l,s:s}", "scheme", s.scheme, "problem",
        s.problem, "integrator", s.integrator, "n", (Py_ssize_t)s.n, "dim", s.dim, "steps", s.steps,
        "error", s.error, "error_samples", s.error_samples, "passes_per_stage", s.passes_per_stage,
        "passes_min", s.passes_min, "regularisations", s.regularisations, "pairs",
        (Py_ssize_t)s.pairs, "nlist_builds", s.nlist_builds, "nlist_note", s.nlist_note);
    if (!d) return NULL;
    const struct {
        const char *k;
        double v;
    } nums[] = {{"t", s.t},
                {"dt", s.dt},
                {"h", s.h},
                {"c0", s.c0},
                {"l1_u", s.l1_u},
                {"l1_p", s.l1_p},
                {"l1n_u", s.l1n_u},
                {"l1n_p", s.l1n_p},
                {"linf_u", s.linf_u},
                {"linf_p", s.linf_p},
                {"ke", s.ke},
                {"angular_momentum", s.angular_momentum},
                {"ft_fmax", s.ft_fmax},
                {"max_divu", s.max_divu},
                {"seconds", s.seconds},
                {"nlist_skin", s.nlist_skin},
                {"nlist_bytes", s.nlist_bytes},
                {"wc_l1_u", s.wc_l1_u},
                {"wc_l1_p", s.wc_l1_p},
                {"wc_l1n_u", s.wc_l1n_u},
                {"wc_l1n_p", s.wc_l1n_p}};
    for (size_t k = 0; k < sizeof nums / sizeof nums[0]; ++k)
        if (dict_double(d, nums[k].k, nums[k].v) < 0) {
            Py_DECREF(d);
            return NULL;
        }
    if (pyc_dict_steal(d, "momentum",
                       Py_BuildValue("(ddd)", s.momentum[0], s.momentum[1], s.momentum[2])) < 0 ||
        pyc_dict_steal(d, "exact", PyLong_FromLong(s.exact)) < 0) {
        Py_DECREF(d);
        return NULL;
    }
    return d;
}

static PyObject *diag_tuple(const consph_step_diag *g)
{
    return Py_BuildValue("(ldddddddddddd)", g->step, g->t, g->l1_u, g->linf_u, g->l1_p, g->linf_p,
                         g->ke, g->mom[0], g->mom[1], g->mom[2], g->ang, g->ft_fmax, g->max_divu);
}

static const char *const diag_columns[] = {
    "step",  "t",     "l1_u",  "linf_u",           "l1_p",    "linf_p",  "ke",
    "mom_x", "mom_y", "mom_z", "angular_momentum", "ft_fmax", "max_divu"};

PyDoc_STRVAR(history_doc,
             "history($self, /)\n"
             "--\n"
             "\n"
             "Returns dict of arrays. The run's history as log.csv holds it "
             "(consph_solver_history_row): one row per\n"
             "sample (t = 0, every log_every steps, the last step), columns step, t, l1_u,\n"
             "linf_u, l1_p, linf_p, ke, mom_x, mom_y, mom_z, angular_momentum, ft_fmax,\n"
             "max_divu.");

static PyObject *solver_history(PyObject *self, PyObject *args)
{
    (void)args;
    solver_object *so = (solver_object *)self;
    if (!ready(so)) return NULL;
    const size_t n = consph_solver_history_size(so->s);
    const int ncol = (int)(sizeof diag_columns / sizeof diag_columns[0]);
    npy_intp dims[1] = {(npy_intp)n};
    PyObject *d = PyDict_New();
    PyArrayObject *cols[13];
    for (int c = 0; c < ncol; ++c)
        cols[c] = (PyArrayObject *)PyArray_SimpleNew(1, dims, NPY_DOUBLE);
    for (size_t k = 0; k < n; ++k) {
        consph_step_diag g;
        if (consph_solver_history_row(so->s, k, &g) != CONSPH_OK) break;
        const double v[] = {(double)g.step, g.t,       g.l1_u,    g.linf_u, g.l1_p,
                            g.linf_p,       g.ke,      g.mom[0],  g.mom[1], g.mom[2],
                            g.ang,          g.ft_fmax, g.max_divu};
        for (int c = 0; c < ncol; ++c)
            if (cols[c]) ((double *)PyArray_DATA(cols[c]))[k] = v[c];
    }
    for (int c = 0; c < ncol; ++c)
        if (!d || pyc_dict_steal(d, diag_columns[c], (PyObject *)cols[c]) < 0) {
            for (int e = c + 1; e < ncol; ++e) Py_XDECREF(cols[e]);
            Py_XDECREF(d);
            return NULL;
        }
    return d;
}

PyDoc_STRVAR(diag_doc, "diag($self, /)\n"
                       "--\n"
                       "\n"
                       "Returns tuple. The diagnostics at this instant (consph_solver_diag): "
                       "(step, t, l1_u, linf_u, l1_p,\n"
                       "linf_p, ke, mom_x, mom_y, mom_z, angular_momentum, ft_fmax, max_divu).");

static PyObject *solver_diag(PyObject *self, PyObject *args)
{
    (void)args;
    solver_object *so = (solver_object *)self;
    if (!ready_synced(so)) return NULL;
    consph_step_diag g;
    int st = consph_solver_diag(so->s, &g);
    if (st != CONSPH_OK) return pyc_raise(st);
    return diag_tuple(&g);
}

PyDoc_STRVAR(params_doc, "params($self, /)\n"
                         "--\n"
                         "\n"
                         "Returns dict. Every run parameter of this run by its table name, as the "
                         "text consph_run_param_set\n"
                         "reads back to the same value (the checkpoint's metadata).");

static PyObject *solver_params(PyObject *self, PyObject *args)
{
    (void)args;
    solver_object *so = (solver_object *)self;
    if (!ready(so)) return NULL;
    const consph_run_params *prm = consph_solver_params(so->s);
    PyObject *d = PyDict_New();
    for (int k = 0; d && k < consph_run_param_count(); ++k) {
        const consph_run_param *r = consph_run_param_at(k);
        char buf[512];
        if (consph_run_param_format(prm, r->name, buf, sizeof buf) != CONSPH_OK) {
            Py_DECREF(d);
            return pyc_raise(CONSPH_EINVAL);
        }
        if (pyc_dict_steal(d, r->name, PyUnicode_FromString(buf)) < 0) {
            Py_DECREF(d);
            return NULL;
        }
    }
    return d;
}

PyDoc_STRVAR(checkpoint_doc,
             "checkpoint($self, /, path)\n"
             "--\n"
             "\n"
             "Writes a checkpoint of the run as consph run does (consph_solver_checkpoint_meta,\n"
             "consph_checkpoint_write, atomically): Solver.restart(path) and `consph run\n"
             "--restart path` continue it bit for bit.");

static PyObject *solver_checkpoint(PyObject *self, PyObject *args, PyObject *kw)
{
    solver_object *so = (solver_object *)self;
    static char *kwlist[] = {"path", NULL};
    const char *path;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s", kwlist, &path)) return NULL;
    if (!ready_synced(so)) return NULL;
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    int st = consph_solver_checkpoint_meta(so->s, &meta, &hist, &nh);
    if (st == CONSPH_OK)
        PYC_UNLOCKED(
            st = consph_checkpoint_write(path, meta, consph_solver_particles(so->s), hist, nh));
    free(meta);
    free(hist);
    if (st != CONSPH_OK) return pyc_raise(st);
    Py_RETURN_NONE;
}

PyDoc_STRVAR(restart_doc,
             "restart($type, /, path, tf=None, steps=None, device=None)\n"
             "--\n"
             "\n"
             "Returns Solver. A solver restored from a checkpoint (consph_run_restart: "
             "Solver.checkpoint's file\n"
             "or a run's checkpoint.ckpt); it continues bit for bit. tf or steps gives it another\n"
             "end after the checkpoint's (consph_solver_extend, as `consph run --restart CKPT\n"
             "--tf T`): it then continues as the uninterrupted run with that end, bit for bit.\n"
             "An end it cannot take raises consph.InvalidArgument with the library's reason.\n"
             "device: 'cpu' (None) or 'gpu', where it continues (as Solver's device).");

static PyObject *solver_restart(PyObject *cls, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", "tf", "steps", "device", NULL};
    const char *path;
    PyObject *tfo = Py_None, *stepso = Py_None, *devo = Py_None;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s|OOO", kwlist, &path, &tfo, &stepso, &devo))
        return NULL;
    consph_device dev;
    if (device_of(devo, &dev) < 0) return NULL;
    double tf = 0.0;
    long steps = 0;
    if (tfo != Py_None && ((tf = PyFloat_AsDouble(tfo)) == -1.0 && PyErr_Occurred())) return NULL;
    if (stepso != Py_None && ((steps = PyLong_AsLong(stepso)) == -1 && PyErr_Occurred()))
        return NULL;
    if (tfo != Py_None && stepso != Py_None)
        return pyc_raise_msg(CONSPH_EINVAL,
                             "restart: tf and steps both set the end of the run: give one");
    consph_solver *s = NULL;
    int st;
    PYC_UNLOCKED(st = consph_run_restart(&s, path));
    if (st != CONSPH_OK) return pyc_raise(st);
    /* the new end, as consph run --restart CKPT --tf T or --steps K */
    if ((tfo != Py_None || stepso != Py_None) &&
        (st = consph_solver_extend(s, tf, steps)) != CONSPH_OK) {
        consph_solver_free(s);
        return pyc_raise(st);
    }
    if (move_to(s, dev) < 0) {
        consph_solver_free(s);
        return NULL;
    }
    solver_object *so = (solver_object *)((PyTypeObject *)cls)->tp_alloc((PyTypeObject *)cls, 0);
    if (!so) {
        consph_solver_free(s);
        return NULL;
    }
    so->s = s;
    return (PyObject *)so;
}

PyDoc_STRVAR(
    dt_warning_doc,
    "dt_warning($self, /)\n"
    "--\n"
    "\n"
    "Returns str or None. The sentence consph run warns with when Δt exceeds a stability bound\n"
    "(consph_solver_dt_warning), None when it does not.");

static PyObject *solver_dt_warning(PyObject *self, PyObject *args)
{
    (void)args;
    solver_object *so = (solver_object *)self;
    if (!ready(so)) return NULL;
    char buf[512];
    if (consph_solver_dt_warning(so->s, buf, sizeof buf)) return PyUnicode_FromString(buf);
    Py_RETURN_NONE;
}

PyDoc_STRVAR(set_device_doc,
             "set_device($self, /, device)\n"
             "--\n"
             "\n"
             "Moves the run's steps to 'gpu' or back to 'cpu' (consph_solver_set_device, "
             "docs/gpu.md)\n"
             "between two steps; the run goes on bit for bit. A run the GPU cannot take, or no "
             "GPU,\n"
             "raises consph.InvalidArgument with the library's reason (consph_gpu_check).");

static PyObject *solver_set_device(PyObject *self, PyObject *args, PyObject *kw)
{
    solver_object *so = (solver_object *)self;
    static char *kwlist[] = {"device", NULL};
    PyObject *devo;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O", kwlist, &devo)) return NULL;
    if (!ready(so)) return NULL;
    consph_device dev;
    if (device_of(devo, &dev) < 0 || move_to(so->s, dev) < 0) return NULL;
    Py_RETURN_NONE;
}

static PyObject *get_device(PyObject *self, void *c)
{
    (void)c;
    solver_object *so = (solver_object *)self;
    if (!ready(so)) return NULL;
    return PyUnicode_FromString(consph_solver_device(so->s) == CONSPH_DEVICE_GPU ? "gpu" : "cpu");
}

static PyObject *get_t(PyObject *self, void *c)
{
    (void)c;
    solver_object *so = (solver_object *)self;
    return ready(so) ? PyFloat_FromDouble(consph_solver_time(so->s)) : NULL;
}
static PyObject *get_step_count(PyObject *self, void *c)
{
    (void)c;
    solver_object *so = (solver_object *)self;
    return ready(so) ? PyLong_FromLong(consph_solver_step_count(so->s)) : NULL;
}
static PyObject *get_dt(PyObject *self, void *c)
{
    (void)c;
    solver_object *so = (solver_object *)self;
    return ready(so) ? PyFloat_FromDouble(consph_solver_dt(so->s)) : NULL;
}
static PyObject *get_done(PyObject *self, void *c)
{
    (void)c;
    solver_object *so = (solver_object *)self;
    return ready(so) ? PyBool_FromLong(consph_solver_done(so->s)) : NULL;
}
static PyObject *get_n(PyObject *self, void *c)
{
    (void)c;
    solver_object *so = (solver_object *)self;
    return ready(so) ? PyLong_FromSize_t(consph_solver_particles(so->s)->n) : NULL;
}
static PyObject *get_dim(PyObject *self, void *c)
{
    (void)c;
    solver_object *so = (solver_object *)self;
    return ready(so) ? PyLong_FromLong(consph_solver_particles(so->s)->dim) : NULL;
}
static PyObject *get_run_id(PyObject *self, void *c)
{
    (void)c;
    solver_object *so = (solver_object *)self;
    return ready(so) ? PyUnicode_FromString(consph_solver_run_id(so->s)) : NULL;
}

static PyGetSetDef solver_getset[] = {
    {"t", get_t, NULL, "the simulated time", NULL},
    {"step_count", get_step_count, NULL, "the steps taken since t = 0", NULL},
    {"dt", get_dt, NULL, "the time step", NULL},
    {"done", get_done, NULL, "True once the run reached its final time or step count", NULL},
    {"n", get_n, NULL, "the number of particles", NULL},
    {"dim", get_dim, NULL, "the dimension", NULL},
    {"run_id", get_run_id, NULL, "the run's identifier (kept by its checkpoints)", NULL},
    {"device", get_device, NULL, "where the steps run: 'cpu' or 'gpu' (set_device)", NULL},
    {NULL, NULL, NULL, NULL, NULL}};

#define KW (METH_VARARGS | METH_KEYWORDS)
#define FN(f) (PyCFunction)(void (*)(void))(f)

static PyMethodDef solver_methods[] = {
    {"step", FN(solver_step), KW, step_doc},
    {"run", FN(solver_run), KW, run_doc},
    {"field", FN(solver_field), KW, field_doc},
    {"field_names", solver_field_names, METH_NOARGS, field_names_doc},
    {"_particles", FN(solver_particles), KW, particles_doc},
    {"summary", solver_summary, METH_NOARGS, summary_doc},
    {"history", solver_history, METH_NOARGS, history_doc},
    {"diag", solver_diag, METH_NOARGS, diag_doc},
    {"params", solver_params, METH_NOARGS, params_doc},
    {"checkpoint", FN(solver_checkpoint), KW, checkpoint_doc},
    {"set_device", FN(solver_set_device), KW, set_device_doc},
    {"dt_warning", solver_dt_warning, METH_NOARGS, dt_warning_doc},
    {"restart", FN(solver_restart), KW | METH_CLASS, restart_doc},
    {NULL, NULL, 0, NULL}};

PyDoc_STRVAR(
    solver_doc,
    "Solver(problem='taylor-green', particles=None, config=None, device=None, **params)\n--\n\n"
    "A weakly-compressible SPH run (consph_solver_create), as `consph run PROBLEM` sets it up:\n"
    "the problem's defaults, then every keyword as the run parameter of that name in the\n"
    "parameter table (consph_run_param_set, in the table's order; the names are the study\n"
    "files' keys: scheme, nx, layout, seed, hdx, kernel, u... see consph.run_params()).\n"
    "Values are numbers or names; a parameter's special value by its name ('none', 're',\n"
    "'default', 'lattice'). As consph run: steps replaces tf, re sets ν (nu) from Re; a bad\n"
    "key or value raises consph.InvalidArgument with the library's message.\n"
    "particles: start from these particles instead of the layout, as `consph run --particles`\n"
    "(consph_solver_create_from): a consph.Particles (its box and periodicity must be the\n"
    "problem's; its fields u or velocity, p or pressure, where present, replace the\n"
    "problem's solution at t = 0) or a tuple (x, u=None, p=None) in the problem's box. Their\n"
    "order is kept; N sets nx (N = nx^d) or the spacing; nx, layout and seed are refused.\n"
    "The particles of consph.layout(K, d, nx) give the run with layout=K, nx=nx bit for bit.\n"
    "config: a run parameter file read as `consph run --config` reads it (consph_run_file_load;\n"
    "its problem key when no problem is given): the problem's defaults, then the file's keys,\n"
    "then the keywords, each replacing the file's key of its parameter and the one it clashes\n"
    "with (steps/tf, re/nu, dt/cfl and h_dt); a bad file raises with FILE:LINE.\n"
    "device: 'cpu' (None, the default) or 'gpu': the steps on the GPU as `consph run --device\n"
    "gpu` (docs/gpu.md), bit for bit the CPU's; field, particles and checkpoint copy the\n"
    "state back first. A run the GPU cannot take, or no GPU, raises consph.InvalidArgument.\n\n"
    "Example: s = consph.Solver('taylor-green', scheme='wcsph', nx=20, steps=20); s.run();\n"
    "u = s.field('u')");

PyTypeObject pyc_solver_type = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "consph.Solver",
    .tp_basicsize = sizeof(solver_object),
    .tp_dealloc = solver_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_BASETYPE,
    .tp_doc = solver_doc,
    .tp_methods = solver_methods,
    .tp_getset = solver_getset,
    .tp_init = solver_init,
    .tp_new = PyType_GenericNew,
};
