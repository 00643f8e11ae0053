/* The CPython extension consph._core over the C library (docs/python.md): shared helpers of its
 * source files. Every file includes this header first; module.c alone imports numpy's C API. */
#ifndef PYCONSPH_H
#define PYCONSPH_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#define PY_ARRAY_UNIQUE_SYMBOL consph_numpy_api
#ifndef PYCONSPH_MODULE_C
#define NO_IMPORT_ARRAY
#endif
#include <numpy/arrayobject.h>

#include "consph/consph.h"
#include "consph/gpu.h"
#include "consph/solver.h"
#include "consph/study.h"
#include "consph/transport.h"

/* Runs `stmt` (library work, no Python calls) with the interpreter's lock released, so that
 * other Python threads go on meanwhile. */
#define PYC_UNLOCKED(stmt)                                                                         \
    do {                                                                                           \
        PyThreadState *pyc_ts_ = PyEval_SaveThread();                                              \
        stmt;                                                                                      \
        PyEval_RestoreThread(pyc_ts_);                                                             \
    } while (0)

/* Raises the exception of a library status with consph_last_error()'s message (InvalidArgument,
 * a ValueError, for CONSPH_EINVAL; Failure, a RuntimeError, otherwise); returns NULL. */
PyObject *pyc_raise(int status);
/* Records `msg` as the library's error (so that it reads the same way) and raises it. */
PyObject *pyc_raise_msg(int status, const char *fmt, ...);

/* A C-contiguous float64 copy-or-view of any array-like (NULL with an exception). */
PyArrayObject *pyc_double_array(PyObject *obj, const char *what);

/* Particles from a Python object with the attributes of consph.Particles: x (N×d, or N in 1D),
 * lo, hi (d numbers), periodic (a bool or d bools), spacing (a number or None) and fields (a
 * dict of arrays of N or N×k values). Positions outside [lo, hi) on a periodic axis are wrapped
 * as the file readers wrap them; outside on another axis is an error. `p` is initialised here;
 * free it with consph_particles_free. Returns 0, or -1 with an exception. */
int pyc_particles_from(PyObject *obj, consph_particles *p);
/* Positions xo (an N×d array-like, or N in 1D) into p, initialised here with `box` (its dim must
 * be d) and no fields, wrapped as pyc_particles_from wraps them. box NULL: only checks the shape
 * (p untouched). Returns d, or -1 with an exception. */
int pyc_particles_positions(PyObject *xo, const consph_box *box, consph_particles *p);
/* A dict {x, lo, hi, periodic, spacing, fields} of copies of p's arrays, particle i of the
 * result being p's order[i] (order NULL: p's own order). */
PyObject *pyc_particles_dict(const consph_particles *p, const size_t *order);
/* A field of k components (component-major, stride `stride` between components) as an N array
 * (k = 1) or an N×k array, rows taken through order (NULL: as stored). */
PyObject *pyc_field_array(const double *data, size_t n, size_t stride, int ncomp,
                          const size_t *order);
/* A list of the names in a comma-separated string. */
PyObject *pyc_name_list(const char *names);
/* Sets dict[key] = value and drops the reference to value; -1 when value is NULL or on error. */
int pyc_dict_steal(PyObject *dict, const char *key, PyObject *value);

/* The method tables and types of each source file, joined by module.c. */
extern PyMethodDef pyc_kernel_methods[];
extern PyMethodDef pyc_ops_methods[];
extern PyMethodDef pyc_study_methods[];
extern PyTypeObject pyc_solver_type;

#endif
