/* consph._core: the module, its exceptions, the conversions between numpy arrays and particle
 * sets, and the particle files and checkpoints (include/consph/io.h). */
#define PYCONSPH_MODULE_C
#include "pyconsph.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static PyObject *error_base, *error_invalid, *error_failure;

static const char *status_name(int status)
{
    switch (status) {
    case CONSPH_EINVAL:
        return "EINVAL";
    case CONSPH_ENOMEM:
        return "ENOMEM";
    case CONSPH_EIO:
        return "EIO";
    case CONSPH_EFORMAT:
        return "EFORMAT";
    case CONSPH_ENUMERIC:
        return "ENUMERIC";
    default:
        return "EUNKNOWN";
    }
}

PyObject *pyc_raise(int status)
{
    const char *msg = consph_last_error();
    PyObject *cls = status == CONSPH_EINVAL ? error_invalid : error_failure;
    /* a message may quote a file name that is not UTF-8 */
    if (!msg[0]) msg = "consph: unknown failure";
    PyObject *text = PyUnicode_DecodeUTF8(msg, (Py_ssize_t)strlen(msg), "replace");
    PyObject *exc = text ? PyObject_CallOneArg(cls, text) : NULL;
    Py_XDECREF(text);
    if (!exc) return NULL;
    PyObject *st = PyLong_FromLong(status), *code = PyUnicode_FromString(status_name(status));
    if (st && code && PyObject_SetAttrString(exc, "status", st) == 0 &&
        PyObject_SetAttrString(exc, "code", code) == 0)
        PyErr_SetObject(cls, exc);
    Py_XDECREF(st);
    Py_XDECREF(code);
    Py_DECREF(exc);
    return NULL;
}

PyObject *pyc_raise_msg(int status, const char *fmt, ...)
{
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    consph_fail(status, "%s", buf);
    return pyc_raise(status);
}

PyArrayObject *pyc_double_array(PyObject *obj, const char *what)
{
    PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(obj, NPY_DOUBLE, 0, 0,
                                                        NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
    if (!a)
        PyErr_Format(PyExc_TypeError, "%s: expected an array of numbers", what ? what : "argument");
    return a;
}

int pyc_dict_steal(PyObject *dict, const char *key, PyObject *value)
{
    if (!value) return -1;
    int rc = PyDict_SetItemString(dict, key, value);
    Py_DECREF(value);
    return rc;
}

PyObject *pyc_name_list(const char *names)
{
    PyObject *list = PyList_New(0);
    if (!list) return NULL;
    const char *s = names;
    while (s && *s) {
        const char *e = strchr(s, ',');
        size_t len = e ? (size_t)(e - s) : strlen(s);
        while (len && *s == ' ') ++s, --len;
        PyObject *name = PyUnicode_FromStringAndSize(s, (Py_ssize_t)len);
        if (!name || PyList_Append(list, name) < 0) {
            Py_XDECREF(name);
            Py_DECREF(list);
            return NULL;
        }
        Py_DECREF(name);
        s = e ? e + 1 : NULL;
    }
    return list;
}

PyObject *pyc_field_array(const double *data, size_t n, size_t stride, int ncomp,
                          const size_t *order)
{
    npy_intp dims[2] = {(npy_intp)n, ncomp};
    PyArrayObject *a = (PyArrayObject *)PyArray_SimpleNew(ncomp == 1 ? 1 : 2, dims, NPY_DOUBLE);
    if (!a) return NULL;
    double *out = PyArray_DATA(a);
    for (size_t i = 0; i < n; ++i) {
        const size_t src = order ? order[i] : i;
        for (int c = 0; c < ncomp; ++c)
            out[i * (size_t)ncomp + (size_t)c] = data[(size_t)c * stride + src];
    }
    return (PyObject *)a;
}

PyObject *pyc_particles_dict(const consph_particles *p, const size_t *order)
{
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    npy_intp dims[2] = {(npy_intp)p->n, p->dim};
    PyArrayObject *x = (PyArrayObject *)PyArray_SimpleNew(2, dims, NPY_DOUBLE);
    if (!x) goto fail;
    double *xv = PyArray_DATA(x);
    for (size_t i = 0; i < p->n; ++i)
        for (int a = 0; a < p->dim; ++a)
            xv[i * (size_t)p->dim + (size_t)a] = p->x[a][order ? order[i] : i];
    if (pyc_dict_steal(d, "x", (PyObject *)x) < 0) goto fail;
    PyObject *lo = PyTuple_New(p->dim), *hi = PyTuple_New(p->dim), *per = PyTuple_New(p->dim);
    if (!lo || !hi || !per) {
        Py_XDECREF(lo), Py_XDECREF(hi), Py_XDECREF(per);
        goto fail;
    }
    for (int a = 0; a < p->dim; ++a) {
        PyTuple_SET_ITEM(lo, a, PyFloat_FromDouble(p->box.lo[a]));
        PyTuple_SET_ITEM(hi, a, PyFloat_FromDouble(p->box.hi[a]));
        PyTuple_SET_ITEM(per, a, PyBool_FromLong(p->box.periodic[a]));
    }
    if (pyc_dict_steal(d, "lo", lo) < 0 || pyc_dict_steal(d, "hi", hi) < 0 ||
        pyc_dict_steal(d, "periodic", per) < 0 ||
        pyc_dict_steal(d, "spacing", PyFloat_FromDouble(p->spacing)) < 0)
        goto fail;
    PyObject *fields = PyDict_New();
    if (!fields || pyc_dict_steal(d, "fields", fields) < 0) goto fail;
    for (int f = 0; f < p->nfields; ++f) {
        const consph_field *fl = &p->fields[f];
        if (pyc_dict_steal(fields, fl->name,
                           pyc_field_array(fl->data, p->n, p->cap, fl->ncomp, order)) < 0)
            goto fail;
    }
    return d;
fail:
    Py_DECREF(d);
    return NULL;
}

/* A float attribute (or d of them) of the particles' object. */
static int axis_values(PyObject *obj, const char *name, int dim, double *out)
{
    PyObject *v = PyObject_GetAttrString(obj, name);
    if (!v) return -1;
    PyArrayObject *a = pyc_double_array(v, name);
    Py_DECREF(v);
    if (!a) return -1;
    npy_intp m = PyArray_SIZE(a);
    if (m != 1 && m != dim) {
        Py_DECREF(a);
        pyc_raise_msg(CONSPH_EINVAL, "particles: %s has %ld values for %d axes", name, (long)m,
                      dim);
        return -1;
    }
    const double *d = PyArray_DATA(a);
    for (int k = 0; k < dim; ++k) out[k] = d[m == 1 ? 0 : k];
    Py_DECREF(a);
    return 0;
}

int pyc_particles_positions(PyObject *xo, const consph_box *box, consph_particles *p)
{
    memset(p, 0, sizeof *p);
    PyArrayObject *x = pyc_double_array(xo, "particles.x");
    if (!x) return -1;
    const int nd = PyArray_NDIM(x);
    const size_t n = nd >= 1 ? (size_t)PyArray_DIM(x, 0) : 0;
    const int dim = nd == 1 ? 1 : nd == 2 ? (int)PyArray_DIM(x, 1) : 0;
    if (dim < 1 || dim > CONSPH_MAX_DIM || n == 0 || (box && dim != box->dim)) {
        Py_DECREF(x);
        if (box)
            pyc_raise_msg(CONSPH_EINVAL,
                          "particles: x must be an N×%d array with N >= 1 (got %d axes of shape "
                          "%ld×%d)",
                          box->dim, nd, (long)n, dim);
        else
            pyc_raise_msg(CONSPH_EINVAL,
                          "particles: x must be an N×d array with N >= 1 and d in 1..3 (got %d "
                          "axes of shape %ld×%d)",
                          nd, (long)n, dim);
        return -1;
    }
    if (!box) { /* the caller's box follows from the dimension */
        Py_DECREF(x);
        return dim;
    }
    if (consph_particles_init(p, dim, n, box) != CONSPH_OK) {
        Py_DECREF(x);
        pyc_raise(CONSPH_ENOMEM);
        return -1;
    }
    const double *xv = PyArray_DATA(x);
    /* As the file readers do (src/io/particles_read.c): only values outside [lo, hi) move. */
    for (size_t i = 0; i < n; ++i)
        for (int a = 0; a < dim; ++a) {
            double v = xv[i * (size_t)dim + (size_t)a], lo = box->lo[a], hi = box->hi[a];
            if (!isfinite(v)) {
                Py_DECREF(x);
                consph_particles_free(p);
                pyc_raise_msg(CONSPH_EINVAL, "particles: particle %zu: %c = %g is not finite", i,
                              "xyz"[a], v);
                return -1;
            }
            if (box->periodic[a] && !(v >= lo && v < hi)) {
                double len = hi - lo, s = fmod(v - lo, len);
                if (s < 0.0) s += len;
                if (!(s < len)) s = 0.0;
                v = lo + s < hi ? lo + s : lo;
            } else if (!box->periodic[a] && (v < lo || v > hi)) {
                Py_DECREF(x);
                consph_particles_free(p);
                pyc_raise_msg(CONSPH_EINVAL,
                              "particles: particle %zu outside the box: %c = %.17g is not in "
                              "[%.17g, %.17g] and axis %c is not periodic",
                              i, "xyz"[a], v, lo, hi, "xyz"[a]);
                return -1;
            }
            p->x[a][i] = v;
        }
    Py_DECREF(x);
    return dim;
}

int pyc_particles_from(PyObject *obj, consph_particles *p)
{
    memset(p, 0, sizeof *p);
    PyObject *xo = PyObject_GetAttrString(obj, "x");
    if (!xo) {
        PyErr_Clear();
        PyErr_SetString(PyExc_TypeError,
                        "particles: expected a consph.Particles (attributes x, lo, hi, periodic, "
                        "spacing, fields)");
        return -1;
    }
    const int dim = pyc_particles_positions(xo, NULL, p);
    if (dim < 0) {
        Py_DECREF(xo);
        return -1;
    }
    consph_box box;
    memset(&box, 0, sizeof box);
    box.dim = dim;
    double per[CONSPH_MAX_DIM];
    if (axis_values(obj, "lo", dim, box.lo) < 0 || axis_values(obj, "hi", dim, box.hi) < 0 ||
        axis_values(obj, "periodic", dim, per) < 0) {
        Py_DECREF(xo);
        return -1;
    }
    for (int a = 0; a < dim; ++a) box.periodic[a] = per[a] != 0.0;
    if (consph_box_check(&box) != CONSPH_OK) {
        Py_DECREF(xo);
        pyc_raise(CONSPH_EINVAL);
        return -1;
    }
    const int st = pyc_particles_positions(xo, &box, p);
    Py_DECREF(xo);
    if (st < 0) return -1;
    const size_t n = p->n;
    PyObject *sp = PyObject_GetAttrString(obj, "spacing");
    if (!sp) PyErr_Clear();
    if (sp && sp != Py_None) {
        p->spacing = PyFloat_AsDouble(sp);
        if (PyErr_Occurred()) {
            Py_DECREF(sp);
            consph_particles_free(p);
            return -1;
        }
    } else {
        p->spacing = pow(consph_box_volume(&box) / (double)n, 1.0 / dim);
    }
    Py_XDECREF(sp);
    if (!(p->spacing > 0 && isfinite(p->spacing))) {
        consph_particles_free(p);
        pyc_raise_msg(CONSPH_EINVAL, "particles: spacing %g is not a positive number", p->spacing);
        return -1;
    }
    PyObject *fields = PyObject_GetAttrString(obj, "fields");
    if (!fields) PyErr_Clear();
    if (fields && fields != Py_None) {
        if (!PyDict_Check(fields)) {
            Py_DECREF(fields);
            consph_particles_free(p);
            PyErr_SetString(PyExc_TypeError, "particles: fields must be a dict of arrays");
            return -1;
        }
        PyObject *key, *val;
        Py_ssize_t pos = 0;
        while (PyDict_Next(fields, &pos, &key, &val)) {
            const char *name = PyUnicode_AsUTF8(key);
            PyArrayObject *fa = name ? pyc_double_array(val, name) : NULL;
            int ncomp = 0;
            if (fa) {
                const int fnd = PyArray_NDIM(fa);
                if (fnd >= 1 && (size_t)PyArray_DIM(fa, 0) == n && fnd <= 2)
                    ncomp = fnd == 1 ? 1 : (int)PyArray_DIM(fa, 1);
            }
            double *dst = NULL;
            if (fa && ncomp < 1) {
                pyc_raise_msg(CONSPH_EINVAL,
                              "particles: field '%s' must hold N = %zu values or N×k values", name,
                              n);
            } else if (fa && strlen(name) >= CONSPH_FIELD_NAME_MAX) {
                pyc_raise_msg(CONSPH_EINVAL, "particles: field name '%s' is longer than %d bytes",
                              name, CONSPH_FIELD_NAME_MAX - 1);
            } else if (fa && !(dst = consph_particles_field(p, name, ncomp))) {
                pyc_raise(CONSPH_EINVAL);
            }
            if (!dst) {
                Py_XDECREF(fa);
                Py_DECREF(fields);
                consph_particles_free(p);
                return -1;
            }
            const double *src = PyArray_DATA(fa);
            for (size_t i = 0; i < n; ++i)
                for (int c = 0; c < ncomp; ++c)
                    dst[(size_t)c * p->cap + i] = src[i * (size_t)ncomp + (size_t)c];
            Py_DECREF(fa);
        }
    }
    Py_XDECREF(fields);
    return 0;
}

/* ---- particle files and checkpoints ---- */

static int parse_box_option(PyObject *box, int *dim, consph_read_options *ro)
{
    if (box == Py_None) return 0;
    PyArrayObject *a = pyc_double_array(box, "box");
    if (!a) return -1;
    npy_intp m = PyArray_SIZE(a);
    if (m % 2 || m < 2 || m > 6) {
        Py_DECREF(a);
        pyc_raise_msg(CONSPH_EINVAL, "box: expected (lo, hi) pairs per axis, got %ld numbers",
                      (long)m);
        return -1;
    }
    const double *v = PyArray_DATA(a);
    ro->have_box = 1;
    ro->box.dim = (int)(m / 2);
    for (int k = 0; k < ro->box.dim; ++k) {
        ro->box.lo[k] = v[2 * k];
        ro->box.hi[k] = v[2 * k + 1];
    }
    if (*dim == 0) *dim = ro->box.dim;
    Py_DECREF(a);
    return 0;
}

PyDoc_STRVAR(read_particles_doc,
             "read_particles(path, dim=0, box=None, periodic=None)\n"
             "--\n"
             "\n"
             "Returns dict. Reads a particle file (.csv or .vtu: consph layout --out, a run's "
             "snapshot, ...)\n"
             "with the library's reader (consph_read_particles): positions, box, periodicity,\n"
             "spacing and every array as a field. box: ((lo, hi), ...) to replace the file's;\n"
             "periodic: a bool or one per axis to replace the file's. Returns the particle\n"
             "dict (x, lo, hi, periodic, spacing, fields) plus 'time' (a snapshot's TimeValue,\n"
             "None when absent). consph.read_particles wraps it into a consph.Particles.");

static PyObject *py_read_particles(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"path", "dim", "box", "periodic", NULL};
    const char *path;
    int dim = 0;
    PyObject *box = Py_None, *periodic = Py_None;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s|iOO", kwlist, &path, &dim, &box, &periodic))
        return NULL;
    consph_read_options ro;
    memset(&ro, 0, sizeof ro);
    if (parse_box_option(box, &dim, &ro) < 0) return NULL;
    ro.dim = dim;
    if (periodic != Py_None) {
        PyArrayObject *a = pyc_double_array(periodic, "periodic");
        if (!a) return NULL;
        npy_intp m = PyArray_SIZE(a);
        const double *v = PyArray_DATA(a);
        ro.have_periodic = 1;
        for (int k = 0; k < CONSPH_MAX_DIM; ++k)
            ro.periodic[k] = m ? v[m == 1 ? 0 : (k < m ? k : m - 1)] != 0 : 0;
        Py_DECREF(a);
    }
    consph_particles p;
    consph_read_report rep;
    int st;
    PYC_UNLOCKED(st = consph_read_particles(path, &ro, &p, &rep));
    if (st != CONSPH_OK) return pyc_raise(st);
    PyObject *d = pyc_particles_dict(&p, NULL);
    consph_particles_free(&p);
    if (!d) return NULL;
    PyObject *t = rep.has_time ? PyFloat_FromDouble(rep.time) : (Py_INCREF(Py_None), Py_None);
    if (pyc_dict_steal(d, "time", t) < 0) {
        Py_DECREF(d);
        return NULL;
    }
    return d;
}

PyDoc_STRVAR(write_particles_doc,
             "write_particles(path, particles, encoding='zlib')\n"
             "--\n"
             "\n"
             "Writes a consph.Particles to .csv or .vtu (by the extension) as consph layout --out\n"
             "does (consph_write_particles_enc); encoding: ascii, binary or zlib (.vtu only).");

static PyObject *py_write_particles(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"path", "particles", "encoding", NULL};
    const char *path, *enc_name = "zlib";
    PyObject *obj;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "sO|s", kwlist, &path, &obj, &enc_name)) return NULL;
    int enc = -1;
    for (int k = 0; k <= CONSPH_VTU_ZLIB; ++k)
        if (!strcmp(enc_name, consph_vtu_encoding_name((consph_vtu_encoding)k))) enc = k;
    if (enc < 0)
        return pyc_raise_msg(CONSPH_EINVAL, "encoding '%s' is unknown (allowed: %s)", enc_name,
                             consph_vtu_encoding_names());
    consph_particles p;
    if (pyc_particles_from(obj, &p) < 0) return NULL;
    int st;
    PYC_UNLOCKED(st = consph_write_particles_enc(path, &p, (consph_vtu_encoding)enc));
    consph_particles_free(&p);
    if (st != CONSPH_OK) return pyc_raise(st);
    Py_RETURN_NONE;
}

PyDoc_STRVAR(
    read_checkpoint_doc,
    "read_checkpoint(path)\n"
    "--\n"
    "\n"
    "Returns dict. Reads a checkpoint (consph_checkpoint_read: a run's checkpoint.ckpt or\n"
    "Solver.checkpoint's file) without restoring a run: 'meta' (the run's key=value\n"
    "text), 'particles' (the particle dict in the stored order, every field of the\n"
    "run's state included) and 'history' (the raw doubles of the run's history).");

static PyObject *py_read_checkpoint(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"path", NULL};
    const char *path;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s", kwlist, &path)) return NULL;
    char *meta = NULL;
    double *hist = NULL;
    size_t nh = 0;
    consph_particles p;
    int st;
    PYC_UNLOCKED(st = consph_checkpoint_read(path, &meta, &p, &hist, &nh));
    if (st != CONSPH_OK) return pyc_raise(st);
    PyObject *d = PyDict_New();
    npy_intp dims[1] = {(npy_intp)nh};
    PyArrayObject *h = (PyArrayObject *)PyArray_SimpleNew(1, dims, NPY_DOUBLE);
    if (h && nh) memcpy(PyArray_DATA(h), hist, nh * sizeof(double));
    if (!d || pyc_dict_steal(d, "meta", PyUnicode_FromString(meta ? meta : "")) < 0 ||
        pyc_dict_steal(d, "particles", pyc_particles_dict(&p, NULL)) < 0 ||
        pyc_dict_steal(d, "history", (PyObject *)h) < 0) {
        Py_XDECREF(d);
        d = NULL;
    }
    free(meta);
    free(hist);
    consph_particles_free(&p);
    return d;
}

PyDoc_STRVAR(
    set_num_threads_doc,
    "set_num_threads(n, /)\n"
    "--\n"
    "\n"
    "Threads of the library's parallel regions from now on (n > 0;\n"
    "results do not depend on it). import consph sets GOMP_SPINCOUNT=2000 when neither it\n"
    "nor OMP_WAIT_POLICY is set (include/consph/core.h says why).");

static PyObject *py_set_num_threads(PyObject *self, PyObject *args)
{
    (void)self;
    int n;
    if (!PyArg_ParseTuple(args, "i", &n)) return NULL;
    if (n < 1) return pyc_raise_msg(CONSPH_EINVAL, "threads: %d is not a positive count", n);
    consph_set_num_threads(n);
    Py_RETURN_NONE;
}

PyDoc_STRVAR(num_threads_doc,
             "num_threads()\n"
             "--\n"
             "\n"
             "Returns int. Threads a parallel region of the library would use (1 without OpenMP).");

static PyObject *py_num_threads(PyObject *self, PyObject *args)
{
    (void)self;
    (void)args;
    return PyLong_FromLong(consph_num_threads());
}

PyDoc_STRVAR(gpu_doc,
             "gpu()\n"
             "--\n"
             "\n"
             "Returns dict. Whether Solver(device='gpu') and study(device='gpu') can run here\n"
             "(consph_gpu_available): 'available' (bool), 'reason' (why not, else ''), 'schemes'\n"
             "(the schemes the GPU runs, consph_gpu_schemes).");

static PyObject *py_gpu(PyObject *self, PyObject *args)
{
    (void)self;
    (void)args;
    char why[256] = "";
    int ok;
    PYC_UNLOCKED(ok = consph_gpu_available(why, sizeof why));
    PyObject *schemes = PyUnicode_FromString(consph_gpu_schemes());
    PyObject *sep = PyUnicode_FromString(",");
    PyObject *list = schemes && sep ? PyUnicode_Split(schemes, sep, -1) : NULL;
    Py_XDECREF(schemes);
    Py_XDECREF(sep);
    if (!list) return NULL;
    return Py_BuildValue("{s:O,s:s,s:N}", "available", ok ? Py_True : Py_False, "reason",
                         ok ? "" : why, "schemes", list);
}

static PyMethodDef module_methods[] = {
    {"gpu", py_gpu, METH_NOARGS, gpu_doc},
    {"read_particles", (PyCFunction)(void (*)(void))py_read_particles, METH_VARARGS | METH_KEYWORDS,
     read_particles_doc},
    {"write_particles", (PyCFunction)(void (*)(void))py_write_particles,
     METH_VARARGS | METH_KEYWORDS, write_particles_doc},
    {"read_checkpoint", (PyCFunction)(void (*)(void))py_read_checkpoint,
     METH_VARARGS | METH_KEYWORDS, read_checkpoint_doc},
    {"set_num_threads", py_set_num_threads, METH_VARARGS, set_num_threads_doc},
    {"num_threads", py_num_threads, METH_NOARGS, num_threads_doc},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT,
    "consph._core",
    "The C extension behind the consph package: kernels, layouts, operators, the solver,\n"
    "studies and Wasserstein distances of the consph library (import consph; docs/python.md).",
    -1,
    NULL,
    NULL,
    NULL,
    NULL,
    NULL};

static int add_methods(PyObject *m, PyMethodDef *defs)
{
    PyObject *name = PyModule_GetNameObject(m);
    if (!name) return -1;
    for (PyMethodDef *d = defs; d->ml_name; ++d) {
        PyObject *f = PyCFunction_NewEx(d, NULL, name);
        if (!f || PyModule_AddObject(m, d->ml_name, f) < 0) {
            Py_XDECREF(f);
            Py_DECREF(name);
            return -1;
        }
    }
    Py_DECREF(name);
    return 0;
}

PyMODINIT_FUNC PyInit__core(void)
{
    import_array();
    PyObject *m = PyModule_Create(&module_def);
    if (!m) return NULL;
    error_base = PyErr_NewExceptionWithDoc(
        "consph.Error",
        "An error of the consph library; str(e) is consph_last_error()'s message, e.status the\n"
        "library's status code and e.code its name (EINVAL, ENOMEM, EIO, EFORMAT, ENUMERIC).",
        PyExc_Exception, NULL);
    PyObject *b1 = error_base ? Py_BuildValue("(OO)", error_base, PyExc_ValueError) : NULL;
    PyObject *b2 = error_base ? Py_BuildValue("(OO)", error_base, PyExc_RuntimeError) : NULL;
    error_invalid =
        b1 ? PyErr_NewExceptionWithDoc("consph.InvalidArgument",
                                       "A parameter out of its allowed range or an unknown name "
                                       "(CONSPH_EINVAL): a consph.Error and a ValueError.",
                                       b1, NULL)
           : NULL;
    error_failure = b2 ? PyErr_NewExceptionWithDoc(
                             "consph.Failure",
                             "A failure while working (memory, a file, its format, a numerical "
                             "failure or a run that left its model's validity): a consph.Error "
                             "and a RuntimeError.",
                             b2, NULL)
                       : NULL;
    Py_XDECREF(b1);
    Py_XDECREF(b2);
    if (!error_invalid || !error_failure) goto fail;
    Py_INCREF(error_base), Py_INCREF(error_invalid), Py_INCREF(error_failure);
    if (PyModule_AddObject(m, "Error", error_base) < 0 ||
        PyModule_AddObject(m, "InvalidArgument", error_invalid) < 0 ||
        PyModule_AddObject(m, "Failure", error_failure) < 0)
        goto fail;
    if (PyModule_AddStringConstant(m, "__version__", CONSPH_VERSION) < 0) goto fail;
    /* where consph.study looks for a study by name, after $CONSPH_STUDIES and ./studies, as
     * `consph study` does */
    if (PyModule_AddObject(m, "_study_dirs",
                           Py_BuildValue("(ss)", CONSPH_PY_SOURCE_DIR "/studies",
                                         CONSPH_PY_DATA_DIR "/studies")) < 0)
        goto fail;
    if (add_methods(m, module_methods) < 0 || add_methods(m, pyc_kernel_methods) < 0 ||
        add_methods(m, pyc_ops_methods) < 0 || add_methods(m, pyc_study_methods) < 0)
        goto fail;
    if (PyType_Ready(&pyc_solver_type) < 0) goto fail;
    Py_INCREF(&pyc_solver_type);
    if (PyModule_AddObject(m, "Solver", (PyObject *)&pyc_solver_type) < 0) goto fail;
    return m;
fail:
    Py_DECREF(m);
    return NULL;
}
