/* consph._core: the particle operators on the user's particles (consph_apply, include/consph/
 * ops.h), the manufactured fields and `consph approx`'s sweep with its fitted orders
 * (include/consph/study.h). */
#include "pyconsph.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* consph approx's default form of each operator (apps/cmd_approx.c). */
static const char *const default_form[CONSPH_OP_COUNT] = {"standard", "f4", "div", "coupled",
                                                          "korzilius"};

static int parse_volume(const char *name, consph_volume_kind *kind)
{
    if (consph_volume_lookup(name, kind) != CONSPH_OK) {
        pyc_raise(CONSPH_EINVAL);
        return -1;
    }
    return 0;
}

PyDoc_STRVAR(
    apply_doc,
    "apply(particles, op, form=None, corr='none', field=None, kernel='quintic', hdx=1.2,\n"
    "      h=None, volume=None, cond_max=1e8, report=False)\n"
    "--\n"
    "\n"
    "Returns ndarray. Evaluates an operator on the user's particles and field with consph_apply "
    "(the library's\n"
    "one entry point of every (operator, form, correction) of include/consph/ops.h), as\n"
    "`consph approx --particles` measures it:\n"
    "  particles  a consph.Particles (positions N×d, box lo/hi, periodicity, spacing, fields)\n"
    "  op         function, grad, div, laplacian or hessian\n"
    "  form       the discretisation (None: approx's default: standard, f4, div, coupled,\n"
    "             korzilius); an invalid triple raises naming the valid ones\n"
    "  corr       none, bc, lc or fatehi\n"
    "  field      N values (N×d for div)\n"
    "  h          the smoothing length (None: hdx times the particles' spacing)\n"
    "  volume     summation, number or given (None: given when the particles carry a 'volume'\n"
    "             field, else number, the rule of approx's particle files)\n"
    "Returns N values (function, div, laplacian), N×d (grad) or N×d(d+1)/2 (hessian: xx, xy,\n"
    "xz, yy, yz, zz) in the particles' order. The forms asym, sym1, sym2, sym_s1 return ∇p/ρ.\n"
    "report=True returns (values, {n, pairs, fallbacks, max_cond, seconds, h}): the particles\n"
    "whose correction matrix was rejected, the largest accepted condition estimate, the h used.");

static PyObject *py_apply(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"particles", "op", "form",   "corr",     "field",  "kernel",
                             "hdx",       "h",  "volume", "cond_max", "report", NULL};
    PyObject *pobj, *fobj = Py_None, *hobj = Py_None;
    const char *opname, *form = NULL, *corr = "none", *kernel = "quintic", *volume = NULL;
    double hdx = 1.2, cond_max = 1e8;
    int want_report = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "Os|zzOsdOzdp", kwlist, &pobj, &opname, &form, &corr,
                                     &fobj, &kernel, &hdx, &hobj, &volume, &cond_max, &want_report))
        return NULL;
    if (fobj == Py_None)
        return pyc_raise_msg(CONSPH_EINVAL, "field: give the field's values at the particles");
    consph_op op;
    if (consph_op_lookup(opname, &op) != CONSPH_OK) return pyc_raise(CONSPH_EINVAL);
    consph_particles p;
    if (pyc_particles_from(pobj, &p) < 0) return NULL;
    const int dim = p.dim;
    const size_t n = p.n;
    consph_op_spec spec;
    PyArrayObject *fa = NULL;
    PyObject *result = NULL;
    consph_sys sys;
    consph_op_ctx ctx;
    int have_sys = 0, have_ctx = 0, st;
    double *in = NULL, *out = NULL;
    if (consph_op_parse(opname, form ? form : default_form[op], corr, dim, &spec) != CONSPH_OK) {
        pyc_raise(CONSPH_EINVAL);
        goto done;
    }
    consph_volume_kind vk =
        consph_particles_find(&p, "volume") ? CONSPH_VOLUME_GIVEN : CONSPH_VOLUME_NUMBER;
    if (volume && parse_volume(volume, &vk) < 0) goto done;
    double h = hdx * p.spacing;
    if (hobj != Py_None) {
        h = PyFloat_AsDouble(hobj);
        if (PyErr_Occurred()) goto done;
    }
    if (!(h > 0 && isfinite(h))) {
        pyc_raise_msg(CONSPH_EINVAL, "h = %g is not a positive number", h);
        goto done;
    }
    const int nin = consph_op_ncomp_in(op, dim), nout = consph_op_ncomp_out(op, dim);
    fa = pyc_double_array(fobj, "field");
    if (!fa) goto done;
    if (!(PyArray_NDIM(fa) >= 1 && PyArray_SIZE(fa) == (npy_intp)(n * (size_t)nin) &&
          PyArray_DIM(fa, 0) == (npy_intp)n)) {
        pyc_raise_msg(CONSPH_EINVAL, "field: op %s takes %s per particle: %zu%s values", opname,
                      nin == 1 ? "1 value" : "a d-vector", n, nin == 1 ? "" : "×d");
        goto done;
    }
    consph_kernel_id kid;
    consph_kernel k;
    if (consph_kernel_lookup(kernel, &kid) != CONSPH_OK) {
        pyc_raise(CONSPH_EINVAL);
        goto done;
    }
    if (consph_kernel_info_get(kid)->tensor) {
        pyc_raise_msg(CONSPH_EINVAL, "kernel '%s' is a remeshing kernel, not an SPH kernel",
                      kernel);
        goto done;
    }
    if ((st = consph_kernel_init(&k, kid, dim, h)) != CONSPH_OK) {
        pyc_raise(st);
        goto done;
    }
    in = consph_calloc(n * (size_t)nin, sizeof(double));
    out = consph_calloc(n * (size_t)nout, sizeof(double));
    if (!in || !out) {
        pyc_raise(CONSPH_ENOMEM);
        goto done;
    }
    /* As consph_approx_run_particles: a system on a copy in cell order. */
    PYC_UNLOCKED(st = consph_sys_init(&sys, &p, &k, 0.0));
    if (st != CONSPH_OK) {
        pyc_raise(st);
        goto done;
    }
    have_sys = 1;
    if ((st = consph_op_ctx_init_sys(&ctx, &sys, vk)) != CONSPH_OK) {
        pyc_raise(st);
        goto done;
    }
    have_ctx = 1;
    ctx.cond_max = cond_max;
    const double *fv = PyArray_DATA(fa);
    for (size_t i = 0; i < n; ++i)
        for (int c = 0; c < nin; ++c)
            in[(size_t)c * n + i] = fv[sys.origin[i] * (size_t)nin + (size_t)c];
    consph_op_report rep;
    PYC_UNLOCKED(st = consph_apply(&ctx, spec.op, spec.form, spec.corr, in, out, &rep));
    if (st != CONSPH_OK) {
        pyc_raise(st);
        goto done;
    }
    {
        npy_intp dims[2] = {(npy_intp)n, nout};
        PyArrayObject *r = (PyArrayObject *)PyArray_SimpleNew(nout == 1 ? 1 : 2, dims, NPY_DOUBLE);
        if (!r) goto done;
        double *rv = PyArray_DATA(r);
        for (size_t i = 0; i < n; ++i)
            for (int c = 0; c < nout; ++c)
                rv[sys.origin[i] * (size_t)nout + (size_t)c] = out[(size_t)c * n + i];
        result = (PyObject *)r;
        if (want_report)
            result =
                Py_BuildValue("(N{s:n,s:n,s:n,s:d,s:d,s:d})", r, "n", (Py_ssize_t)rep.n, "pairs",
                              (Py_ssize_t)rep.pairs, "fallbacks", (Py_ssize_t)rep.fallbacks,
                              "max_cond", rep.max_cond, "seconds", rep.seconds, "h", h);
    }
done:
    free(in);
    free(out);
    Py_XDECREF(fa);
    if (have_ctx) consph_op_ctx_free(&ctx);
    if (have_sys) consph_sys_free(&sys);
    consph_particles_free(&p);
    return result;
}

PyDoc_STRVAR(field_values_doc,
             "field_values(name, x, sigma=0.1, x0=None)\n"
             "--\n"
             "\n"
             "Returns dict. A manufactured field of the studies (consph_mfield_eval; names: "
             "field_names()) and\n"
             "its exact derivatives at the points x (N×d): 'f' (N, or N×d for a vector field),\n"
             "'grad' (N×d: ∇ of component 0), 'laplacian' (N), 'hessian' (N×d(d+1)/2, the\n"
             "order of op hessian), 'div' (vector fields). sigma, x0: the delta field's width\n"
             "and centre.");

static PyObject *py_field_values(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"name", "x", "sigma", "x0", NULL};
    const char *name;
    PyObject *xo, *x0o = Py_None;
    double sigma = 0.1;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "sO|dO", kwlist, &name, &xo, &sigma, &x0o))
        return NULL;
    consph_mfield_id id;
    if (consph_mfield_lookup(name, &id) != CONSPH_OK) return pyc_raise(CONSPH_EINVAL);
    PyArrayObject *x = pyc_double_array(xo, "x");
    if (!x) return NULL;
    const int dim = PyArray_NDIM(x) == 1 ? 1 : PyArray_NDIM(x) == 2 ? (int)PyArray_DIM(x, 1) : 0;
    if (dim < 1 || dim > 3 || (id == CONSPH_MFIELD_TGV && dim < 2)) {
        Py_DECREF(x);
        return pyc_raise_msg(CONSPH_EINVAL, "x: expected N×d points with d in %s for field %s",
                             id == CONSPH_MFIELD_TGV ? "2..3" : "1..3", name);
    }
    consph_mfield_params prm = consph_mfield_defaults(dim);
    prm.sigma = sigma;
    if (x0o != Py_None) {
        PyArrayObject *c = pyc_double_array(x0o, "x0");
        if (!c) {
            Py_DECREF(x);
            return NULL;
        }
        for (int a = 0; a < dim && a < PyArray_SIZE(c); ++a)
            prm.x0[a] = ((double *)PyArray_DATA(c))[a];
        Py_DECREF(c);
    }
    const npy_intp n = PyArray_DIM(x, 0);
    const int vec = consph_mfield_is_vector(id), nh = dim * (dim + 1) / 2;
    npy_intp df[2] = {n, vec ? dim : 1}, dg[2] = {n, dim}, dh[2] = {n, nh}, d1[1] = {n};
    PyArrayObject *f = (PyArrayObject *)PyArray_SimpleNew(vec ? 2 : 1, df, NPY_DOUBLE);
    PyArrayObject *g = (PyArrayObject *)PyArray_SimpleNew(2, dg, NPY_DOUBLE);
    PyArrayObject *hs = (PyArrayObject *)PyArray_SimpleNew(2, dh, NPY_DOUBLE);
    PyArrayObject *l = (PyArrayObject *)PyArray_SimpleNew(1, d1, NPY_DOUBLE);
    PyArrayObject *dv = (PyArrayObject *)PyArray_SimpleNew(1, d1, NPY_DOUBLE);
    PyObject *d = PyDict_New();
    if (f && g && hs && l && dv && d) {
        const double *xv = PyArray_DATA(x);
        for (npy_intp i = 0; i < n; ++i) {
            double pt[3] = {0, 0, 0};
            for (int a = 0; a < dim; ++a) pt[a] = xv[i * dim + a];
            consph_mfield_value v;
            consph_mfield_eval(id, dim, &prm, pt, &v);
            for (int c = 0; c < (vec ? dim : 1); ++c)
                ((double *)PyArray_DATA(f))[i * (vec ? dim : 1) + c] = v.f[c];
            for (int a = 0; a < dim; ++a) ((double *)PyArray_DATA(g))[i * dim + a] = v.grad[0][a];
            for (int a = 0, k = 0; a < dim; ++a)
                for (int b = a; b < dim; ++b, ++k)
                    ((double *)PyArray_DATA(hs))[i * nh + k] = v.hess[a][b];
            ((double *)PyArray_DATA(l))[i] = v.lap[0];
            ((double *)PyArray_DATA(dv))[i] = v.div;
        }
    }
    Py_DECREF(x);
    if (!d || pyc_dict_steal(d, "f", (PyObject *)f) < 0 ||
        pyc_dict_steal(d, "grad", (PyObject *)g) < 0 ||
        pyc_dict_steal(d, "hessian", (PyObject *)hs) < 0 ||
        pyc_dict_steal(d, "laplacian", (PyObject *)l) < 0 ||
        pyc_dict_steal(d, "div", (PyObject *)dv) < 0) {
        Py_XDECREF(d);
        return NULL;
    }
    return d;
}

/* The rows of a sweep as columns, and the four orders. */
static PyObject *sweep_result(const consph_approx_row *rows, const double *res, int nrows,
                              const consph_series_order fits[4])
{
    static const char *const cols[] = {"nx",           "n",       "h",        "nbr_mean",
                                       "l1",           "l2",      "linf",     "mae",
                                       "ft_over_fmax", "seconds", "fallbacks"};
    const int ncols = (int)(sizeof cols / sizeof cols[0]);
    PyObject *d = PyDict_New(), *table = PyDict_New(), *orders = PyDict_New();
    if (!d || !table || !orders) goto fail;
    for (int c = 0; c < ncols; ++c) {
        npy_intp dims[1] = {nrows};
        const int integer = c == 1 || c == 10;
        PyArrayObject *a =
            (PyArrayObject *)PyArray_SimpleNew(1, dims, integer ? NPY_LONG : NPY_DOUBLE);
        if (!a) goto fail;
        for (int r = 0; r < nrows; ++r) {
            const consph_approx_row *w = &rows[r];
            const double v[] = {res[r],      (double)w->n,        w->h,
                                w->nbr_mean, w->err.l1,           w->err.l2,
                                w->err.linf, w->err.mae,          w->ft_over_fmax,
                                w->seconds,  (double)w->fallbacks};
            if (integer)
                ((long *)PyArray_DATA(a))[r] = c == 1 ? (long)w->n : (long)w->fallbacks;
            else
                ((double *)PyArray_DATA(a))[r] = v[c];
        }
        if (pyc_dict_steal(table, cols[c], (PyObject *)a) < 0) goto fail;
    }
    static const char *const norms[4] = {"l1", "l2", "linf", "mae"};
    for (int k = 0; k < 4; ++k) {
        PyObject *o =
            Py_BuildValue("{s:d,s:d,s:s}", "order",
                          fits[k].status == CONSPH_SERIES_ORDER ? fits[k].fit.order : NAN, "stderr",
                          fits[k].status == CONSPH_SERIES_ORDER ? fits[k].fit.order_stderr : NAN,
                          "text", fits[k].text);
        if (pyc_dict_steal(orders, norms[k], o) < 0) goto fail;
    }
    if (pyc_dict_steal(d, "rows", table) < 0) {
        table = NULL;
        goto fail;
    }
    table = NULL;
    if (pyc_dict_steal(d, "order", orders) < 0) {
        orders = NULL;
        goto fail;
    }
    return d;
fail:
    Py_XDECREF(d);
    Py_XDECREF(table);
    Py_XDECREF(orders);
    return NULL;
}

PyDoc_STRVAR(
    approx_doc,
    "approx(op, nx=None, files=None, form=None, corr='none', kernel='quintic', hdx=1.2,\n"
    "       h_policy='hdx', beta=None, layout='lattice', dim=2, periodic=True, field=None,\n"
    "       volume=None, mask='interior', eps=0.2, seed=1, sigma=0.1, pack_tol=1e-4,\n"
    "       pack_iter=None)\n"
    "--\n"
    "\n"
    "Returns dict. `consph approx`: an operator's accuracy on a manufactured field at several "
    "resolutions\n"
    "(nx: particles per axis of each row, on layouts of the unit box) or on particle files\n"
    "(files: paths, one row each), with the CLI's options by the same names and defaults.\n"
    "periodic: a bool or one per axis. volume None: number for layouts, each file's own rule\n"
    "for files. Returns {'rows': {nx, n, h, nbr_mean, l1, l2, linf, mae, ft_over_fmax,\n"
    "seconds, fallbacks} as arrays, 'order': {l1|l2|linf|mae: {order, stderr, text}}}, the\n"
    "numbers the CLI prints (at full precision).");

static PyObject *py_approx(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"op",       "nx",        "files", "form",   "corr", "kernel",
                             "hdx",      "h_policy",  "beta",  "layout", "dim",  "periodic",
                             "field",    "volume",    "mask",  "eps",    "seed", "sigma",
                             "pack_tol", "pack_iter", NULL};
    const char *opname, *form = NULL, *corr = "none", *kernel = "quintic", *hpol = "hdx";
    const char *layout = "lattice", *field = NULL, *volume = NULL, *mask = "interior";
    PyObject *nxo = Py_None, *fileso = Py_None, *betao = Py_None, *pero = Py_True, *iter = Py_None;
    double hdx = 1.2, eps = 0.2, sigma = 0.1, tol = 1e-4;
    int dim = 2;
    unsigned long long seed = 1;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s|OOzzsdsOsiOzzsdKddO", kwlist, &opname, &nxo,
                                     &fileso, &form, &corr, &kernel, &hdx, &hpol, &betao, &layout,
                                     &dim, &pero, &field, &volume, &mask, &eps, &seed, &sigma, &tol,
                                     &iter))
        return NULL;
    if ((nxo == Py_None) == (fileso == Py_None))
        return pyc_raise_msg(CONSPH_EINVAL, "give nx (a list of particles per axis) or files (a "
                                            "list of particle files), one of them");
    consph_op op;
    if (consph_op_lookup(opname, &op) != CONSPH_OK) return pyc_raise(CONSPH_EINVAL);
    double nx[64];
    int nrows = 0;
    consph_particle_input *in = NULL;
    PyObject *result = NULL;
    int periodic[3] = {0, 0, 0};
    {
        PyArrayObject *pa = pyc_double_array(pero, "periodic");
        if (!pa) return NULL;
        npy_intp m = PyArray_SIZE(pa);
        for (int a = 0; a < 3; ++a)
            periodic[a] =
                m ? ((double *)PyArray_DATA(pa))[m == 1 ? 0 : (a < m ? a : m - 1)] != 0 : 0;
        Py_DECREF(pa);
    }
    const int periodic_given = kw && PyDict_GetItemString(kw, "periodic") != NULL;
    if (nxo != Py_None) {
        PyArrayObject *a = pyc_double_array(nxo, "nx");
        if (!a) return NULL;
        nrows = (int)PyArray_SIZE(a);
        if (nrows < 1 || nrows > 64) {
            Py_DECREF(a);
            return pyc_raise_msg(CONSPH_EINVAL, "nx: give 1 to 64 resolutions");
        }
        for (int r = 0; r < nrows; ++r) {
            nx[r] = ((double *)PyArray_DATA(a))[r];
            if (!(nx[r] >= 2 && nx[r] <= 100000 && nx[r] == floor(nx[r]))) {
                Py_DECREF(a);
                return pyc_raise_msg(CONSPH_EINVAL, "nx = %g is not an integer in [2, 100000]",
                                     nx[r]);
            }
        }
        Py_DECREF(a);
    } else {
        PyObject *seq = PySequence_Fast(fileso, "files: expected a list of paths");
        if (!seq) return NULL;
        nrows = (int)PySequence_Fast_GET_SIZE(seq);
        if (nrows < 1 || nrows > 64) {
            Py_DECREF(seq);
            return pyc_raise_msg(CONSPH_EINVAL, "files: give 1 to 64 files");
        }
        in = calloc((size_t)nrows, sizeof *in);
        consph_read_options ro;
        memset(&ro, 0, sizeof ro);
        if (periodic_given) {
            ro.have_periodic = 1;
            for (int a = 0; a < 3; ++a) ro.periodic[a] = periodic[a];
        }
        for (int r = 0; r < nrows && in; ++r) {
            const char *path = PyUnicode_AsUTF8(PySequence_Fast_GET_ITEM(seq, r));
            int st = path ? consph_particle_input_read(path, &ro, &in[r]) : -1;
            if (st != CONSPH_OK) {
                for (int k = 0; k < r; ++k) {
                    free((char *)in[k].path);
                    consph_particle_input_free(&in[k]);
                }
                free(in);
                Py_DECREF(seq);
                return st < 0 ? NULL : pyc_raise(st);
            }
            /* the path must outlive the sweep: kept as a Python string below */
            in[r].path = strdup(path);
            consph_volume_kind vk;
            if (volume && !strcmp(volume, "lattice")) {
                consph_particle_input_lattice_volumes(&in[r]);
            } else if (volume && !strcmp(volume, "shepard")) {
                in[r].volume = CONSPH_VOLUME_NUMBER;
            } else if (volume) {
                if (consph_volume_lookup(volume, &vk) != CONSPH_OK) {
                    for (int k = 0; k <= r; ++k) {
                        free((char *)in[k].path);
                        consph_particle_input_free(&in[k]);
                    }
                    free(in);
                    Py_DECREF(seq);
                    return pyc_raise(CONSPH_EINVAL);
                }
                in[r].volume = vk;
            }
            nx[r] = in[r].nx;
        }
        Py_DECREF(seq);
        if (!in) return pyc_raise(CONSPH_ENOMEM);
        dim = in[0].p.dim;
    }
    consph_approx_spec s = consph_approx_defaults(dim);
    consph_layout_kind lk;
    consph_h_policy hp;
    int st = CONSPH_OK;
    if (dim < 1 || dim > 3) {
        pyc_raise_msg(CONSPH_EINVAL, "dim = %d is out of range (allowed: 1, 2, 3)", dim);
        goto done;
    }
    if (consph_op_parse(opname, form ? form : default_form[op], corr, dim, &s.op) != CONSPH_OK ||
        consph_kernel_lookup(kernel, &s.kernel) != CONSPH_OK ||
        consph_layout_lookup(layout, &lk) != CONSPH_OK ||
        consph_h_policy_lookup(hpol, &hp) != CONSPH_OK ||
        consph_mfield_lookup(field                 ? field
                             : op == CONSPH_OP_DIV ? "tgv"
                                                   : "sin2pi",
                             &s.field) != CONSPH_OK) {
        pyc_raise(CONSPH_EINVAL);
        goto done;
    }
    if (consph_kernel_info_get(s.kernel)->tensor) {
        pyc_raise_msg(CONSPH_EINVAL, "kernel '%s' is a remeshing kernel, not an SPH kernel",
                      kernel);
        goto done;
    }
    s.hdx = hdx;
    s.h_policy = hp;
    if ((betao != Py_None) != (hp == CONSPH_H_BETA)) {
        pyc_raise_msg(CONSPH_EINVAL, "beta: give it with h_policy 'beta', and only then");
        goto done;
    }
    if (betao != Py_None) {
        s.beta = PyFloat_AsDouble(betao);
        if (PyErr_Occurred()) goto done;
    }
    s.n_ref = in ? (double)in[0].p.n : pow(nx[0], (double)dim);
    s.layout = consph_layout_defaults(lk, dim, 10);
    s.layout.seed = (uint64_t)seed;
    s.layout.eps = eps;
    s.layout.packing.tol = tol;
    if (iter != Py_None) {
        long m = PyLong_AsLong(iter);
        if (m == -1 && PyErr_Occurred()) goto done;
        if (m < 1) {
            pyc_raise_msg(CONSPH_EINVAL, "pack_iter = %ld is out of range (allowed: >= 1)", m);
            goto done;
        }
        s.layout.packing.max_iter = (int)m;
    }
    s.layout.box = consph_box_unit(dim, 0);
    for (int a = 0; a < dim; ++a) s.layout.box.periodic[a] = periodic[a];
    s.field_params.sigma = sigma;
    if (!in) {
        consph_volume_kind vk = CONSPH_VOLUME_NUMBER;
        if (volume && !strcmp(volume, "lattice"))
            vk = CONSPH_VOLUME_GIVEN;
        else if (volume && strcmp(volume, "shepard") && parse_volume(volume, &vk) < 0)
            goto done;
        s.volume = vk;
    }
    if (strcmp(mask, "interior") && strcmp(mask, "all")) {
        pyc_raise_msg(CONSPH_EINVAL, "mask '%s' is unknown (allowed: interior, all)", mask);
        goto done;
    }
    s.interior_only = !strcmp(mask, "interior");
    const consph_approx_sweep sw = {s, nrows, in ? NULL : nx, in};
    if ((st = consph_approx_sweep_check(&sw)) != CONSPH_OK) {
        pyc_raise(st);
        goto done;
    }
    consph_approx_row rows[64];
    double res[64];
    PYC_UNLOCKED(st = consph_approx_sweep_run(&sw, rows, res, NULL, NULL));
    if (st != CONSPH_OK) {
        pyc_raise(st);
        goto done;
    }
    consph_series_order fits[4];
    consph_approx_sweep_fit(rows, res, nrows, "±", fits);
    result = sweep_result(rows, res, nrows, fits);
done:
    if (in) {
        for (int k = 0; k < nrows; ++k) {
            free((char *)in[k].path);
            consph_particle_input_free(&in[k]);
        }
        free(in);
    }
    return result;
}

static PyObject *names_of(const char *(*name)(int), int count)
{
    PyObject *l = PyList_New(count);
    if (!l) return NULL;
    for (int k = 0; k < count; ++k) PyList_SET_ITEM(l, k, PyUnicode_FromString(name(k)));
    return l;
}
static const char *op_name(int k)
{
    return consph_op_name((consph_op)k);
}
static const char *form_name(int k)
{
    return consph_form_name((consph_op_form)k);
}
static const char *corr_name(int k)
{
    return consph_corr_name((consph_op_corr)k);
}

PyDoc_STRVAR(op_names_doc, "op_names()\n"
                           "--\n"
                           "\n"
                           "Returns list of str. The operators of apply and approx.");
PyDoc_STRVAR(
    form_names_doc,
    "form_names()\n"
    "--\n"
    "\n"
    "Returns list of str. Every operator form (which forms each operator takes: valid_forms).");
PyDoc_STRVAR(corr_names_doc, "corr_names()\n"
                             "--\n"
                             "\n"
                             "Returns list of str. The corrections.");
PyDoc_STRVAR(field_names_doc,
             "field_names()\n"
             "--\n"
             "\n"
             "Returns list of str. The manufactured fields of field_values and approx.");

static PyObject *py_op_names(PyObject *self, PyObject *args)
{
    (void)self;
    (void)args;
    return names_of(op_name, CONSPH_OP_COUNT);
}
static PyObject *py_form_names(PyObject *self, PyObject *args)
{
    (void)self;
    (void)args;
    return names_of(form_name, CONSPH_FORM_COUNT);
}
static PyObject *py_corr_names(PyObject *self, PyObject *args)
{
    (void)self;
    (void)args;
    return names_of(corr_name, CONSPH_CORR_COUNT);
}
static PyObject *py_field_names(PyObject *self, PyObject *args)
{
    (void)self;
    (void)args;
    return pyc_name_list(consph_mfield_names());
}

PyDoc_STRVAR(valid_forms_doc, "valid_forms(op, dim=2)\n"
                              "--\n"
                              "\n"
                              "Returns list of (form, [corrections]). Every form of the operator "
                              "with the corrections it takes in that dimension (the\n"
                              "validity table of src/ops/ops_api.c, consph_op_check).");

static PyObject *py_valid_forms(PyObject *self, PyObject *args, PyObject *kw)
{
    (void)self;
    static char *kwlist[] = {"op", "dim", NULL};
    const char *opname;
    int dim = 2;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s|i", kwlist, &opname, &dim)) return NULL;
    consph_op op;
    if (consph_op_lookup(opname, &op) != CONSPH_OK) return pyc_raise(CONSPH_EINVAL);
    PyObject *l = PyList_New(0);
    for (int f = 0; l && f < CONSPH_FORM_COUNT; ++f) {
        PyObject *corrs = PyList_New(0);
        for (int c = 0; corrs && c < CONSPH_CORR_COUNT; ++c)
            if (consph_op_check(op, (consph_op_form)f, (consph_op_corr)c, dim) == CONSPH_OK) {
                PyObject *s = PyUnicode_FromString(consph_corr_name((consph_op_corr)c));
                PyList_Append(corrs, s);
                Py_XDECREF(s);
            }
        if (corrs && PyList_GET_SIZE(corrs)) {
            PyObject *t = Py_BuildValue("(sO)", consph_form_name((consph_op_form)f), corrs);
            PyList_Append(l, t);
            Py_XDECREF(t);
        }
        Py_XDECREF(corrs);
    }
    consph_clear_error();
    return l;
}

#define KW (METH_VARARGS | METH_KEYWORDS)
#define FN(f) (PyCFunction)(void (*)(void))(f)

PyMethodDef pyc_ops_methods[] = {{"apply", FN(py_apply), KW, apply_doc},
                                 {"approx", FN(py_approx), KW, approx_doc},
                                 {"field_values", FN(py_field_values), KW, field_values_doc},
                                 {"op_names", py_op_names, METH_NOARGS, op_names_doc},
                                 {"form_names", py_form_names, METH_NOARGS, form_names_doc},
                                 {"corr_names", py_corr_names, METH_NOARGS, corr_names_doc},
                                 {"field_names", py_field_names, METH_NOARGS, field_names_doc},
                                 {"valid_forms", FN(py_valid_forms), KW, valid_forms_doc},
                                 {NULL, NULL, 0, NULL}};
