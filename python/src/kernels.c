/* consph._core: kernels on arrays (include/consph/kernels.h) and layouts with their statistics
 * (include/consph/layout.h), with the parameters of `consph kernels` and `consph layout`. */
#include "pyconsph.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int bind_kernel(const char *name, int dim, double h, int radial, consph_kernel *k)
{
    consph_kernel_id id;
    if (consph_kernel_lookup(name, &id) != CONSPH_OK) return pyc_raise(CONSPH_EINVAL), -1;
    if (radial && consph_kernel_info_get(id)->tensor) {
        pyc_raise_msg(CONSPH_EINVAL,
                      "kernel '%s' is a tensor-product kernel: W depends on the separation "
                      "vector, not on r alone (use W_vec)",
                      name);
        return -1;
    }
    if (dim < 1 || dim > CONSPH_MAX_DIM) {
        pyc_raise_msg(CONSPH_EINVAL, "dim = %d is out of range (allowed: 1, 2, 3)", dim);
        return -1;
    }
    int st = consph_kernel_init(k, id, dim, h);
    if (st != CONSPH_OK) return pyc_raise(st), -1;
    return 0;
}

PyDoc_STRVAR(kernel_names_doc,
             "kernel_names()\n"
             "--\n"
             "\n"
             "Returns list of str. Every kernel's name, as `consph kernels` lists them.");

static PyObject *py_kernel_names(PyObject *self, PyObject *args)
{
    (void)self;
    (void)args;
    return pyc_name_list(consph_kernel_names());
}

PyDoc_STRVAR(
    kernel_info_doc,
    "kernel_info(name)\n"
    "--\n"
    "\n"
    "Returns dict. What `consph kernels` says of a kernel: name, description, source (paper and\n"
    "equation), support (in units of h), beta_001 (edge smoothness, 001's definition),\n"
    "sigma (the normalisation in 1D, 2D, 3D; 0 where unsupported) and tensor (True for\n"
    "the tensor-product remeshing kernel m4).");

static PyObject *py_kernel_info(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"name", NULL};
    const char *name;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s", kwlist, &name)) return NULL;
    consph_kernel_id id;
    if (consph_kernel_lookup(name, &id) != CONSPH_OK) return pyc_raise(CONSPH_EINVAL);
    const consph_kernel_info *in = consph_kernel_info_get(id);
    return Py_BuildValue("{s:s,s:s,s:s,s:d,s:i,s:(ddd),s:O}", "name", in->name, "description",
                         in->description, "source", in->source, "support", in->support, "beta_001",
                         in->beta_001, "sigma", in->sigma[0], in->sigma[1], in->sigma[2], "tensor",
                         in->tensor ? Py_True : Py_False);
}

enum { EVAL_W, EVAL_DW, EVAL_D2W };

/* W, dW/dr or d²W/dr² of a radial kernel at every r of an array of any shape. */
static PyObject *eval_radial(PyObject *args, PyObject *kw, int what)
{
    static char *kwlist[] = {"r", "kernel", "dim", "h", NULL};
    PyObject *ro;
    const char *name = "quintic";
    int dim = 2;
    double h = 1.0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|sid", kwlist, &ro, &name, &dim, &h)) return NULL;
    consph_kernel k;
    if (bind_kernel(name, dim, h, 1, &k) < 0) return NULL;
    PyArrayObject *r = pyc_double_array(ro, "r");
    if (!r) return NULL;
    PyArrayObject *out =
        (PyArrayObject *)PyArray_SimpleNew(PyArray_NDIM(r), PyArray_DIMS(r), NPY_DOUBLE);
    if (!out) {
        Py_DECREF(r);
        return NULL;
    }
    const double *rv = PyArray_DATA(r);
    double *ov = PyArray_DATA(out);
    const npy_intp n = PyArray_SIZE(r);
    for (npy_intp i = 0; i < n; ++i) {
        if (!(rv[i] >= 0)) {
            Py_DECREF(r);
            Py_DECREF(out);
            return pyc_raise_msg(CONSPH_EINVAL, "r[%ld] = %g: distances must be >= 0", (long)i,
                                 rv[i]);
        }
        ov[i] = what == EVAL_W    ? consph_kernel_w(&k, rv[i])
                : what == EVAL_DW ? consph_kernel_dw(&k, rv[i])
                                  : consph_kernel_d2w(&k, rv[i]);
    }
    Py_DECREF(r);
    return PyArray_Return(out);
}

PyDoc_STRVAR(W_doc, "W(r, kernel='quintic', dim=2, h=1.0)\n"
                    "--\n"
                    "\n"
                    "Returns ndarray. The kernel W(r, h) = sigma_d / h^d f(r/h) at every distance "
                    "r >= 0 (an array\n"
                    "of any shape; include/consph/kernels.h). Radial kernels only.");
PyDoc_STRVAR(dWdr_doc, "dWdr(r, kernel='quintic', dim=2, h=1.0)\n"
                       "--\n"
                       "\n"
                       "Returns ndarray. dW/dr at every distance r >= 0 (radial kernels).");
PyDoc_STRVAR(d2Wdr2_doc, "d2Wdr2(r, kernel='quintic', dim=2, h=1.0)\n"
                         "--\n"
                         "\n"
                         "Returns ndarray. d²W/dr² at every distance r >= 0 (radial kernels).");

static PyObject *py_W(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    return eval_radial(args, kw, EVAL_W);
}
static PyObject *py_dWdr(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    return eval_radial(args, kw, EVAL_DW);
}
static PyObject *py_d2Wdr2(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    return eval_radial(args, kw, EVAL_D2W);
}

/* Separations: an N×dim array (N in 1D). */
static PyArrayObject *separations(PyObject *o, int dim, npy_intp *n)
{
    PyArrayObject *dx = pyc_double_array(o, "dx");
    if (!dx) return NULL;
    const int nd = PyArray_NDIM(dx);
    if (!((nd == 2 && PyArray_DIM(dx, 1) == dim) || (nd == 1 && dim == 1))) {
        Py_DECREF(dx);
        pyc_raise_msg(CONSPH_EINVAL, "dx: expected an N×%d array of separations x_i - x_j", dim);
        return NULL;
    }
    *n = PyArray_DIM(dx, 0);
    return dx;
}

PyDoc_STRVAR(gradW_doc,
             "gradW(dx, kernel='quintic', dim=2, h=1.0)\n"
             "--\n"
             "\n"
             "Returns ndarray. ∇_i W(|x_i - x_j|) = W'(r) x_ij / r for every separation x_ij = x_i "
             "- x_j (an\n"
             "N×dim array; 0 at r = 0), as consph_kernel_grad computes it. Radial kernels.");

static PyObject *py_gradW(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"dx", "kernel", "dim", "h", NULL};
    PyObject *dxo;
    const char *name = "quintic";
    int dim = 2;
    double h = 1.0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|sid", kwlist, &dxo, &name, &dim, &h)) return NULL;
    consph_kernel k;
    if (bind_kernel(name, dim, h, 1, &k) < 0) return NULL;
    npy_intp n;
    PyArrayObject *dx = separations(dxo, dim, &n);
    if (!dx) return NULL;
    PyArrayObject *out =
        (PyArrayObject *)PyArray_SimpleNew(PyArray_NDIM(dx), PyArray_DIMS(dx), NPY_DOUBLE);
    if (!out) {
        Py_DECREF(dx);
        return NULL;
    }
    const double *d = PyArray_DATA(dx);
    double *g = PyArray_DATA(out);
    for (npy_intp i = 0; i < n; ++i) {
        double r2 = 0;
        for (int a = 0; a < dim; ++a) r2 += d[i * dim + a] * d[i * dim + a];
        consph_kernel_grad(&k, d + i * dim, sqrt(r2), g + i * dim);
    }
    Py_DECREF(dx);
    return (PyObject *)out;
}

PyDoc_STRVAR(W_vec_doc, "W_vec(dx, kernel='quintic', dim=2, h=1.0)\n"
                        "--\n"
                        "\n"
                        "Returns ndarray. W of every separation vector (an N×dim array): radial "
                        "and tensor-product (m4)\n"
                        "kernels alike (consph_kernel_w_vec).");

static PyObject *py_W_vec(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"dx", "kernel", "dim", "h", NULL};
    PyObject *dxo;
    const char *name = "quintic";
    int dim = 2;
    double h = 1.0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|sid", kwlist, &dxo, &name, &dim, &h)) return NULL;
    consph_kernel k;
    if (bind_kernel(name, dim, h, 0, &k) < 0) return NULL;
    npy_intp n;
    PyArrayObject *dx = separations(dxo, dim, &n);
    if (!dx) return NULL;
    npy_intp dims[1] = {n};
    PyArrayObject *out = (PyArrayObject *)PyArray_SimpleNew(1, dims, NPY_DOUBLE);
    if (!out) {
        Py_DECREF(dx);
        return NULL;
    }
    const double *d = PyArray_DATA(dx);
    double *w = PyArray_DATA(out);
    for (npy_intp i = 0; i < n; ++i) w[i] = consph_kernel_w_vec(&k, d + i * dim);
    Py_DECREF(dx);
    return (PyObject *)out;
}

/* ---- layouts ---- */

PyDoc_STRVAR(layout_names_doc, "layout_names()\n"
                               "--\n"
                               "\n"
                               "Returns list of str. The layout kinds of consph layout --kind.");

static PyObject *py_layout_names(PyObject *self, PyObject *args)
{
    (void)self;
    (void)args;
    return pyc_name_list(consph_layout_names());
}

static PyObject *packing_report_dict(const consph_packing_report *r)
{
    PyObject *d = Py_BuildValue(
        "{s:i,s:d,s:d,s:d,s:i,s:O,s:d,s:O}", "iterations", r->iterations, "rho_spread_initial",
        r->rho_spread_initial, "rho_spread_final", r->rho_spread_final, "seconds", r->seconds,
        "polish_start", r->polish_start, "converged", r->converged ? Py_True : Py_False,
        "move_final", r->move_final, "from_cache", r->from_cache ? Py_True : Py_False);
    if (!d) return NULL;
    npy_intp dims[1] = {r->nhistory};
    PyArrayObject *it = (PyArrayObject *)PyArray_SimpleNew(1, dims, NPY_LONG);
    PyArrayObject *sp = (PyArrayObject *)PyArray_SimpleNew(1, dims, NPY_DOUBLE);
    if (it && sp)
        for (int k = 0; k < r->nhistory; ++k) {
            ((long *)PyArray_DATA(it))[k] = r->history_iter[k];
            ((double *)PyArray_DATA(sp))[k] = r->history_spread[k];
        }
    if (pyc_dict_steal(d, "history_iter", (PyObject *)it) < 0 ||
        pyc_dict_steal(d, "history_spread", (PyObject *)sp) < 0) {
        Py_DECREF(d);
        return NULL;
    }
    return d;
}

PyDoc_STRVAR(
    layout_doc,
    "layout(kind, dim, nx, periodic=True, seed=1, eps=0.2, kernel='quintic', hdx=1.2,\n"
    "       perturb=0.5, tol=1e-4, move_tol=1e-2, walls=0, max_iter=None, history_every=0,\n"
    "       cache=None)\n"
    "--\n"
    "\n"
    "Returns dict. Generates nx^dim particles in the unit box as `consph layout --kind KIND --dim "
    "D --nx N`\n"
    "does, with its options by the same names (consph_layout_generate): lattice, random,\n"
    "quasi-random, packed, packed-polished. max_iter None is the kind's default; cache: a\n"
    "directory for the cache of packed layouts for this call (None: layout_cache()). Returns the\n"
    "particle dict (x, lo, hi, periodic, spacing, fields with 'volume') and, for the packed\n"
    "kinds, 'report' (iterations, density spread before and after, converged, history).\n"
    "consph.layout wraps it into a consph.Particles.");

static PyObject *py_layout(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {
        "kind",    "dim", "nx",       "periodic", "seed",     "eps",           "kernel", "hdx",
        "perturb", "tol", "move_tol", "walls",    "max_iter", "history_every", "cache",  NULL};
    const char *kind_name, *kernel = "quintic", *cache = NULL;
    int dim, periodic = 1, walls = 0, history_every = 0;
    long nx;
    unsigned long long seed = 1;
    double eps = 0.2, hdx = 1.2, perturb = 0.5, tol = 1e-4, move_tol = 1e-2;
    PyObject *max_iter = Py_None;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "sil|pKdsddddiOiz", kwlist, &kind_name, &dim, &nx,
                                     &periodic, &seed, &eps, &kernel, &hdx, &perturb, &tol,
                                     &move_tol, &walls, &max_iter, &history_every, &cache))
        return NULL;
    consph_layout_kind kind;
    if (consph_layout_lookup(kind_name, &kind) != CONSPH_OK) return pyc_raise(CONSPH_EINVAL);
    if (dim < 1 || dim > 3)
        return pyc_raise_msg(CONSPH_EINVAL,
                             "dim = %d is out of range "
                             "(allowed: 1, 2, 3)",
                             dim);
    if (nx < 1 || nx > 100000)
        return pyc_raise_msg(CONSPH_EINVAL, "nx = %ld is out of range (allowed: 1..100000)", nx);
    const int packed = kind == CONSPH_LAYOUT_PACKED || kind == CONSPH_LAYOUT_PACKED_POLISHED;
    consph_kernel_id kid;
    if (consph_kernel_lookup(kernel, &kid) != CONSPH_OK) return pyc_raise(CONSPH_EINVAL);
    if (packed && consph_kernel_info_get(kid)->tensor)
        return pyc_raise_msg(CONSPH_EINVAL,
                             "kernel '%s' is a tensor-product remeshing kernel; kind %s needs a "
                             "radial kernel",
                             kernel, kind_name);
    if (packed && !periodic)
        return pyc_raise_msg(CONSPH_EINVAL, "periodic: kind %s needs a periodic box; allowed: True",
                             kind_name);
    const int min_walls = (int)ceil(0.5 * consph_kernel_info_get(kid)->support * hdx);
    if (walls < 0 || walls > 8 || (walls > 0 && walls < min_walls))
        return pyc_raise_msg(CONSPH_EINVAL,
                             "walls: %d layers are out of range for %s at h/Δs %g; allowed: 0 or "
                             "%d..8",
                             walls, kernel, hdx, min_walls);
    consph_layout_params lp = consph_layout_defaults(kind, dim, (size_t)nx);
    lp.box = consph_box_unit(dim, periodic);
    lp.seed = (uint64_t)seed;
    lp.eps = eps;
    lp.packing.kernel = kernel;
    lp.packing.hdx = hdx;
    lp.packing.perturb = perturb;
    lp.packing.tol = tol;
    lp.packing.move_tol = move_tol;
    lp.packing.walls = walls;
    lp.packing.history_every = history_every;
    if (max_iter != Py_None) {
        long m = PyLong_AsLong(max_iter);
        if (m == -1 && PyErr_Occurred()) return NULL;
        if (m < 0 || m > 100000000)
            return pyc_raise_msg(CONSPH_EINVAL,
                                 "max_iter = %ld is out of range (allowed: "
                                 "0..100000000)",
                                 m);
        lp.packing.max_iter = (int)m;
    }
    /* the cache is the library's global setting: set for this call only */
    const char *prev = consph_layout_cache_get();
    char *saved = prev ? strdup(prev) : NULL;
    if (cache && consph_layout_cache_set(cache) != CONSPH_OK) {
        free(saved);
        return pyc_raise(CONSPH_EINVAL);
    }
    consph_particles p;
    consph_packing_report rep;
    memset(&rep, 0, sizeof rep);
    int st;
    PYC_UNLOCKED(st = consph_layout_generate(&lp, &p, &rep));
    if (cache) consph_layout_cache_set(saved);
    free(saved);
    if (st != CONSPH_OK) {
        consph_packing_report_free(&rep);
        return pyc_raise(st);
    }
    PyObject *d = pyc_particles_dict(&p, NULL);
    consph_particles_free(&p);
    if (d && packed && pyc_dict_steal(d, "report", packing_report_dict(&rep)) < 0) {
        Py_DECREF(d);
        d = NULL;
    }
    consph_packing_report_free(&rep);
    return d;
}

PyDoc_STRVAR(set_layout_cache_doc,
             "set_layout_cache(path, /)\n--\n\n"
             "Sets the directory of the cache of packed layouts (consph_layout_cache_set, the\n"
             "cache the CLI's --cache names), or turns it off with None. import consph turns it\n"
             "on where the CLI keeps it: $XDG_CACHE_HOME/consph, else ~/.cache/consph. A cached\n"
             "layout is bit for bit the one a fresh packing gives (include/consph/layout.h).");

static PyObject *py_set_layout_cache(PyObject *self, PyObject *args)
{
    (void)self;
    const char *dir = NULL;
    if (!PyArg_ParseTuple(args, "z", &dir)) return NULL;
    int st = consph_layout_cache_set(dir);
    if (st != CONSPH_OK) return pyc_raise(st);
    Py_RETURN_NONE;
}

PyDoc_STRVAR(layout_cache_doc, "layout_cache()\n--\n\n"
                               "Returns str or None. The directory of the cache of packed "
                               "layouts, None when it is off.");

static PyObject *py_layout_cache(PyObject *self, PyObject *args)
{
    (void)self;
    (void)args;
    const char *dir = consph_layout_cache_get();
    if (!dir) Py_RETURN_NONE;
    return PyUnicode_FromString(dir);
}

PyDoc_STRVAR(layout_stats_doc,
             "layout_stats(particles, kernel='quintic', hdx=1.2)\n"
             "--\n"
             "\n"
             "Returns dict. The statistics `consph layout` prints for any particle set: n, "
             "min_spacing (periodic\n"
             "aware), rho_spread = max|rho_i/rho0 - 1| and rho_mean of the summation density with\n"
             "the kernel at h = hdx Δs (consph_layout_stats_compute), and the nearest-neighbour\n"
             "distances nn_min, nn_mean, nn_max, nn_std and the distances to the nearest lattice\n"
             "node disp_mean, disp_max, in units of Δs (consph_layout_nn_stats_compute).");

static PyObject *py_layout_stats(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"particles", "kernel", "hdx", NULL};
    PyObject *obj;
    const char *kernel = "quintic";
    double hdx = 1.2;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|sd", kwlist, &obj, &kernel, &hdx)) return NULL;
    consph_particles p;
    if (pyc_particles_from(obj, &p) < 0) return NULL;
    consph_layout_stats st;
    consph_layout_nn_stats nst;
    int rc;
    PYC_UNLOCKED(rc = consph_layout_stats_compute(&p, kernel, hdx, &st);
                 if (rc == CONSPH_OK) rc = consph_layout_nn_stats_compute(&p, &nst));
    consph_particles_free(&p);
    if (rc != CONSPH_OK) return pyc_raise(rc);
    return Py_BuildValue("{s:n,s:d,s:d,s:d,s:d,s:d,s:d,s:d,s:d,s:d}", "n", (Py_ssize_t)st.n,
                         "min_spacing", st.min_spacing, "rho_spread", st.rho_spread, "rho_mean",
                         st.rho_mean, "nn_min", nst.nn_min, "nn_mean", nst.nn_mean, "nn_max",
                         nst.nn_max, "nn_std", nst.nn_std, "disp_mean", nst.disp_mean, "disp_max",
                         nst.disp_max);
}

#define KW (METH_VARARGS | METH_KEYWORDS)
#define FN(f) (PyCFunction)(void (*)(void))(f)

PyMethodDef pyc_kernel_methods[] = {
    {"kernel_names", py_kernel_names, METH_NOARGS, kernel_names_doc},
    {"kernel_info", FN(py_kernel_info), KW, kernel_info_doc},
    {"W", FN(py_W), KW, W_doc},
    {"dWdr", FN(py_dWdr), KW, dWdr_doc},
    {"d2Wdr2", FN(py_d2Wdr2), KW, d2Wdr2_doc},
    {"gradW", FN(py_gradW), KW, gradW_doc},
    {"W_vec", FN(py_W_vec), KW, W_vec_doc},
    {"layout_names", py_layout_names, METH_NOARGS, layout_names_doc},
    {"layout", FN(py_layout), KW, layout_doc},
    {"layout_stats", FN(py_layout_stats), KW, layout_stats_doc},
    {"set_layout_cache", py_set_layout_cache, METH_VARARGS, set_layout_cache_doc},
    {"layout_cache", py_layout_cache, METH_NOARGS, layout_cache_doc},
    {NULL, NULL, 0, NULL}};
