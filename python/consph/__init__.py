"""consph: smoothed particle hydrodynamics from Python, over the consph C library.

Numpy arrays in and out; every error of the library is a consph.Error carrying its message
(consph.InvalidArgument, also a ValueError, for a bad parameter or name; consph.Failure, also
a RuntimeError, for anything else). docs/python.md in the repository is the guide.

    >>> import consph
    >>> p = consph.layout("lattice", dim=2, nx=32)
    >>> f = np.sin(2 * np.pi * (p.x[:, 0] + p.x[:, 1]))
    >>> g = consph.apply(p, "grad", form="f4", field=f)        # N×2
    >>> s = consph.Solver("taylor-green", scheme="wcsph", nx=20, steps=20)
    >>> s.run(); u = s.field("u")

Kernels: W, dWdr, d2Wdr2, gradW, W_vec, kernel_names, kernel_info.
Particles: Particles, layout, layout_stats, read_particles, write_particles, read_checkpoint,
layout_cache, set_layout_cache.
Operators: apply, approx, field_values, op_names, form_names, corr_names, valid_forms,
field_names. Runs: Solver, run_params, names. Studies: study, study_path, study_estimate.
Transport: wasserstein.
"""

import csv as _csv
import os as _os
import tempfile as _tempfile

import numpy as _np

# libgomp reads its wait policy once, when it is loaded (with _core, below): left to spin ~7 ms
# at every barrier, its threads take the time the working ones need on a loaded machine; told to
# sleep at once, every fork and join is a wake-up (include/consph/core.h). A short spin serves
# both. The consph CLI sets it for itself the same way, only when neither variable is set; a
# later `import` of another OpenMP library sees it too.
if "OMP_WAIT_POLICY" not in _os.environ and "GOMP_SPINCOUNT" not in _os.environ:
    _os.environ["GOMP_SPINCOUNT"] = "2000"

from . import _core  # noqa: E402
from ._core import (  # noqa: F401,E402  (the public API)
    Error,
    Failure,
    InvalidArgument,
    W,
    W_vec,
    __version__,
    apply,
    approx,
    corr_names,
    d2Wdr2,
    dWdr,
    field_names,
    field_values,
    form_names,
    gpu,
    gradW,
    kernel_info,
    kernel_names,
    layout_cache,
    layout_names,
    names,
    num_threads,
    op_names,
    run_params,
    set_layout_cache,
    set_num_threads,
    valid_forms,
    wasserstein,
    write_particles,
)


def _default_layout_cache():
    """Where the CLI keeps its cache of packed layouts (apps/cli.c, cli_cache_apply)."""
    xdg, home = _os.environ.get("XDG_CACHE_HOME"), _os.environ.get("HOME")
    if xdg and xdg.startswith("/"):  # the XDG rule: a relative path is ignored
        return _os.path.join(xdg, "consph")
    if home:
        return _os.path.join(home, ".cache", "consph")
    return None


# Packed layouts (the start of most of 001's runs) are packed once, as with the CLI.
set_layout_cache(_default_layout_cache())


class Particles:
    """A particle set: positions x (N×d array), the box [lo, hi) per axis, its periodicity, the
    nominal spacing Δs and named fields (a dict of arrays of N or N×k values).

    Particles(x, lo=0.0, hi=1.0, periodic=True, spacing=None, fields=None): lo, hi and periodic
    are one value for every axis or one per axis; spacing None is (box volume / N)^(1/d). This
    is what consph.apply, layout_stats, wasserstein and write_particles take, and what layout,
    read_particles and Solver.particles return (with `time` and `report` where they have one).
    """

    def __init__(self, x, lo=0.0, hi=1.0, periodic=True, spacing=None, fields=None):
        x = _np.asarray(x, dtype=float)
        if x.ndim == 1:
            x = x.reshape(-1, 1)
        self.x = x
        d = x.shape[1]
        self.lo = tuple(float(v) for v in _np.broadcast_to(_np.asarray(lo, dtype=float), (d,)))
        self.hi = tuple(float(v) for v in _np.broadcast_to(_np.asarray(hi, dtype=float), (d,)))
        self.periodic = tuple(bool(v) for v in _np.broadcast_to(_np.asarray(periodic), (d,)))
        if spacing is None:
            volume = float(_np.prod(_np.subtract(self.hi, self.lo)))
            spacing = (volume / max(len(x), 1)) ** (1.0 / d)
        self.spacing = float(spacing)
        self.fields = dict(fields or {})
        self.time = None
        self.report = None

    @property
    def n(self):
        """The number of particles."""
        return self.x.shape[0]

    @property
    def dim(self):
        """The dimension."""
        return self.x.shape[1]

    def __len__(self):
        return self.n

    def __repr__(self):
        axes = " x ".join(f"[{a:g}, {b:g})" for a, b in zip(self.lo, self.hi))
        per = "".join("xyz"[a] for a in range(self.dim) if self.periodic[a]) or "none"
        return (f"Particles(n={self.n}, dim={self.dim}, box {axes}, periodic {per}, "
                f"spacing {self.spacing:g}, fields {sorted(self.fields)})")

    @classmethod
    def _from_dict(cls, d):
        p = cls(d["x"], d["lo"], d["hi"], d["periodic"], d["spacing"], d["fields"])
        p.time = d.get("time")
        p.report = d.get("report")
        return p


def layout(kind, dim, nx, **options):
    """Generates nx^dim particles in the unit box as `consph layout --kind KIND --dim D --nx N`
    does, with its options by the same names: periodic=True, seed=1, eps=0.2 (random),
    kernel='quintic', hdx=1.2, perturb=0.5, tol=1e-4, move_tol=1e-2, walls=0, max_iter=None,
    history_every=0 (packed kinds), cache=None (a directory for the cache of packed layouts for
    this call; None: layout_cache(), on by default where the CLI keeps it).
    kind: lattice, random, quasi-random, packed, packed-polished (layout_names()).
    Returns a Particles with the field 'volume' and, for the packed kinds, .report (the
    packing's iterations, density spread, convergence and history)."""
    return Particles._from_dict(_core.layout(kind, dim, nx, **options))


def layout_stats(particles, kernel="quintic", hdx=1.2):
    """The statistics `consph layout` prints of a particle set: n, min_spacing, rho_spread
    (max|rho/rho0 - 1| of the summation density with `kernel` at h = hdx Δs), rho_mean,
    nn_min, nn_mean, nn_max, nn_std (nearest-neighbour distances / Δs), disp_mean, disp_max
    (distances to the nearest lattice node / Δs), as a dict."""
    return _core.layout_stats(particles, kernel=kernel, hdx=hdx)


def read_particles(path, dim=0, box=None, periodic=None):
    """Reads a .csv or .vtu particle file (consph layout --out, a run's snap_NNNNNN.vtu) with
    the library's reader: a Particles with every array as a field and .time (a snapshot's
    TimeValue, else None). box ((lo, hi) per axis) and periodic (a bool or one per axis)
    replace the file's."""
    return Particles._from_dict(_core.read_particles(path, dim=dim, box=box, periodic=periodic))


def read_checkpoint(path):
    """Reads a checkpoint without restoring the run: a dict with 'meta' (the run's key=value
    text), 'particles' (a Particles in the stored order, every field of the run's state) and
    'history' (the raw doubles of the run's history)."""
    d = _core.read_checkpoint(path)
    d["particles"] = Particles._from_dict(d["particles"])
    return d


class Solver(_core.Solver):
    __doc__ = _core.Solver.__doc__

    @classmethod
    def from_config(cls, path, problem=None, **params):
        """A run from a run parameter file, as `consph run --config PATH` reads it
        (consph_run_file_load: `key = value` lines with '#' comments, the run keys of study
        files: problem, scheme, nx, tf, steps, ...). The keywords are run parameters that replace
        the file's key of the same parameter and the one they clash with (steps its tf, re its
        nu, dt its cfl and h_dt), as consph run's options do; particles=... as for Solver.
        The same as Solver(problem, config=path, **params)."""
        if problem is not None:
            params["problem"] = problem
        return cls(config=path, **params)

    def particles(self, order="initial"):
        """Every field of the run's particles with their positions, box and periodicity, as a
        Particles of copies (order 'initial': by the particles' initial index, the field id;
        'current': the solver's cell order, as its snapshots hold them)."""
        return Particles._from_dict(self._particles(order=order))


def study_path(name):
    """The study file of a study name: NAME.study in $CONSPH_STUDIES, ./studies, the source
    tree's studies/ or the installed share/consph/studies (as `consph study NAME` looks);
    a path to a .study file is returned as is."""
    if name.endswith(".study"):
        return name
    dirs = [_os.environ.get("CONSPH_STUDIES"), "studies"] + list(_core._study_dirs)
    for d in dirs:
        if d and _os.path.isfile(_os.path.join(d, name + ".study")):
            return _os.path.join(d, name + ".study")
    raise InvalidArgument(f"unknown study '{name}' (no {name}.study in "
                          f"{', '.join(d for d in dirs if d)})")


def study_estimate(name, quick=False):
    """The rough run time in seconds of a study (by name or path) before running it."""
    return _core.study_estimate(study_path(name), quick=quick)


def _column(values):
    try:
        return _np.array([float(v) if v not in ("", "nan", "n/a") else _np.nan for v in values])
    except ValueError:
        return _np.array(values, dtype=object)


def read_table(path):
    """A study's FIGURE.csv as a dict of columns: numbers as float arrays, text as arrays of
    str."""
    with open(path, newline="") as f:
        rows = list(_csv.reader(f))
    if not rows:
        return {}
    head, body = rows[0], rows[1:]
    return {h: _column([r[k] if k < len(r) else "" for r in body]) for k, h in enumerate(head)}


def study(name, out_dir=None, quick=False, log=False, jobs=1, device=None, resume=False):
    """Runs one study (a built-in by name, e.g. '003-kernels', or a path to a .study file) as
    `consph study NAME --out OUT_DIR [--quick] [--jobs J] [--device D] [--resume]` does and
    returns its tables: a dict from figure id to a dict of columns (numpy arrays: the figure's
    CSV, one row per measurement), plus the key '_study' holding name, title and the directory
    of the files (FIGURE.csv, .md, .gp, README.md). out_dir None: a temporary directory, removed
    afterwards (the files with it). jobs: the rows on that many worker processes, or threads
    sharing the GPU with device 'gpu' or 'auto' (docs/studies.md); the tables are those of
    jobs=1. device: where the solver rows run, 'cpu', 'gpu' or 'auto' (None: the study file's
    key `device`, else the CPU; docs/gpu.md). resume: keep the rows an earlier, stopped or
    failed, run of the same study left in out_dir (refused when the study file or quick
    differ)."""
    path = study_path(name)
    tmp = None
    if out_dir is None:
        if resume:
            raise InvalidArgument("resume: give the out_dir of the run to go on with")
        tmp = _tempfile.TemporaryDirectory(prefix="consph-study-")
        out_dir = tmp.name
    try:
        info = _core.run_study(path, out_dir, quick=quick, log=log, jobs=jobs, device=device,
                               resume=resume)
        tables = {}
        for fn in sorted(_os.listdir(info["dir"])):
            if fn.endswith(".csv") and not fn.startswith("."):
                tables[fn[:-4]] = read_table(_os.path.join(info["dir"], fn))
        if tmp is not None:
            info["dir"] = None
        tables["_study"] = info
        return tables
    finally:
        if tmp is not None:
            tmp.cleanup()
