"""`import consph` end to end against the CLI it wraps (docs/python.md).

Usage: python3 test_module.py PATH-TO-CONSPH, with PYTHONPATH at the build's python/ folder
(tests/CMakeLists.txt). Exit 77 (skipped) when the module was not built there.

What must hold:
  - a layout equals `consph layout`'s bit for bit, and its statistics the ones it prints;
  - an operator on the user's particles (consph.apply) gives the errors consph.approx reports to
    round-off, and consph.approx the numbers `consph approx` prints to their printed digits;
  - a 20-step run equals `consph run`'s last snapshot bit for bit (positions, id, velocity,
    pressure, density), also across a checkpoint written from Python and continued by the CLI;
  - a run from the user's particles (a layout's) equals `consph run --layout` and `--particles`
    bit for bit, and a run extended past its end (live, or restarted to a later t_f) equals the
    uninterrupted run bit for bit; a run file read from Python equals `consph run --config`;
  - a bad argument raises consph.Error carrying the library's message (the CLI's words);
  - a run on the GPU (the host emulation) equals the CPU's bit for bit, read mid-run, across a
    checkpoint and a move back to the CPU; a study on worker processes, on the GPU, or resumed
    writes the serial study's table;
  - README.md's Python example runs as printed.
"""

import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile

consph_bin = os.path.abspath(sys.argv[1])
build_python = os.path.join(os.path.dirname(consph_bin), "python", "consph")
if not glob.glob(os.path.join(build_python, "_core*.so")):
    print(f"the Python module was not built ({build_python}): skipped")
    sys.exit(77)
sys.path.insert(0, os.path.dirname(build_python))

import numpy as np  # noqa: E402

import consph  # noqa: E402

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAIL:", what)


def cli(*args, ok=True):
    """Runs the CLI with a list argv (never a shell); returns (exit status, stdout, stderr)."""
    r = subprocess.run([consph_bin, *map(str, args)], capture_output=True, text=True)
    if ok and r.returncode != 0:
        failures.append(f"consph {' '.join(map(str, args))}: exit {r.returncode}: {r.stderr}")
        print("FAIL:", failures[-1])
    return r.returncode, r.stdout, r.stderr


def bits_equal(a, b):
    a, b = np.ascontiguousarray(a, dtype=float), np.ascontiguousarray(b, dtype=float)
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


tmp = tempfile.mkdtemp(prefix="consph-py-")

# ---- errors -------------------------------------------------------------------------------
check(issubclass(consph.InvalidArgument, consph.Error), "InvalidArgument is a consph.Error")
check(issubclass(consph.InvalidArgument, ValueError), "InvalidArgument is a ValueError")
check(issubclass(consph.Failure, RuntimeError), "Failure is a RuntimeError")
try:
    consph.Solver("taylor-green", scheme="nosuch", nx=16)
    check(False, "an unknown scheme was accepted")
except consph.Error as e:
    _, _, err = cli("run", "taylor-green", "--scheme", "nosuch", "--nx", 16, ok=False)
    check(isinstance(e, ValueError) and e.code == "EINVAL", f"unknown scheme: {e!r}")
    check(str(e).startswith("scheme 'nosuch' is unknown (allowed: ") and str(e) in err,
          f"the library's message: python {str(e)!r}, CLI {err!r}")
try:
    consph.Solver("taylor-green", scheme="wcsph", nx=16, hdx=9)
    check(False, "hdx 9 was accepted")
except consph.InvalidArgument as e:
    _, _, err = cli("run", "taylor-green", "--scheme", "wcsph", "--nx", 16, "--hdx", 9, ok=False)
    check(str(e).startswith("hdx = 9 is out of range (allowed: ") and str(e) in err,
          f"hdx out of range: python {str(e)!r}, CLI {err!r}")
try:
    consph.Solver("taylor-green", scheme="l-ipst-c", nx=16, alpha=0.2)
    check(False, "alpha for l-ipst-c was accepted")
except consph.InvalidArgument as e:
    check(str(e).startswith("alpha does nothing for scheme l-ipst-c (it acts on: wcsph"), str(e))
try:
    consph.read_particles(os.path.join(tmp, "none.csv"))
    check(False, "a missing file was read")
except consph.Failure as e:
    check(e.code == "EIO" and "none.csv" in str(e), f"missing file: {e!r}")
try:
    consph.W([0.5], kernel="m4")
    check(False, "W of a tensor-product kernel by r")
except consph.InvalidArgument:
    pass

# ---- kernels -------------------------------------------------------------------------------
r = np.linspace(0.0, 3.5, 71)
w = consph.W(r, kernel="cubic", dim=1, h=1.0)
check(abs(w[0] - 2.0 / 3.0) < 1e-15, f"cubic W(0) in 1D = 2/3, got {w[0]!r}")
check(np.all(w[r >= 2.0] == 0.0), "cubic support 2h")
# dW/dr against a centred difference of W, and ∇W = W'(r) x/r
for k in ("quintic", "wendland-c4", "gaussian"):
    h, eps = 0.7, 1e-6
    rr = np.linspace(0.05, 2.0, 40)
    fd = (consph.W(rr + eps, k, 2, h) - consph.W(rr - eps, k, 2, h)) / (2 * eps)
    check(np.allclose(consph.dWdr(rr, k, 2, h), fd, rtol=1e-6, atol=1e-8), f"{k}: dW/dr")
    dx = np.stack([rr * 0.6, rr * 0.8], axis=1)
    g = consph.gradW(dx, k, 2, h)
    check(np.allclose(g, consph.dWdr(rr, k, 2, h)[:, None] * dx / rr[:, None], rtol=1e-13),
          f"{k}: gradW")

# ---- a layout: equal to the CLI's, bit for bit ---------------------------------------------
p = consph.layout("random", dim=2, nx=24, seed=3, eps=0.4)
vtu = os.path.join(tmp, "random.vtu")
_, out, _ = cli("layout", "--kind", "random", "--dim", 2, "--nx", 24, "--seed", 3, "--eps", 0.4,
                "--out", vtu)
q = consph.read_particles(vtu)
check(bits_equal(p.x, q.x), "layout: positions equal consph layout's")
check(p.lo == q.lo and p.hi == q.hi and p.periodic == q.periodic and p.spacing == q.spacing,
      "layout: box, periodicity and spacing")
st = consph.layout_stats(p)
line = [s for s in out.splitlines() if s.startswith("density")][0]
check(f"{st['rho_spread']:.3e}" in line and f"{st['rho_mean']:.9f}" in line,
      f"layout stats {st} against {line!r}")
check(st["n"] == 576 and abs(st["min_spacing"] - float(out.split("min spacing ")[1].split()[0]))
      < 1e-6 * st["min_spacing"], "layout stats: n and min spacing")

# ---- operators: consph.apply on the user's particles, consph.approx, consph approx ---------
cases = [("grad", "f4", "none", "random"), ("laplacian", "cleary", "bc", "random"), ("laplacian", "coupled", "none", "lattice"),
         ("div", "div", "none", "random")]
for op, form, corr, kind in cases:
    nxs = [16, 24]
    res = consph.approx(op, nx=nxs, form=form, corr=corr, layout=kind, seed=5)
    _, out, _ = cli("approx", "--op", op, "--form", form, "--corr", corr, "--layout", kind,
                    "--seed", 5, "--nx", ",".join(map(str, nxs)), "--format", "json")
    js = json.loads(out)
    for k, row in enumerate(js["rows"]):
        for col in ("l1", "l2", "linf", "mae"):
            # JSON writes a NaN (l1 of a field whose exact answer is 0: div of tgv) as null
            a, b = res["rows"][col][k], np.nan if row[col] is None else row[col]
            check(abs(a - b) <= 1e-6 * abs(b) or (np.isnan(a) and np.isnan(b)),
                  f"approx {op} {col} nx={nxs[k]}: {a} vs CLI {b}")
    for norm in ("l1", "linf"):
        theirs = js["order"][norm]  # null where no order can be fitted
        mine = res["order"][norm]["order"]
        check(np.isnan(mine) if theirs is None else abs(mine - theirs["order"]) < 1e-5,
              f"approx {op} order ({norm}): {mine} vs CLI {theirs}")
    # the same measurement by hand: the layout, the field, consph.apply, the norms in numpy
    for k, nx in enumerate(nxs):
        pk = consph.layout(kind, dim=2, nx=nx, seed=5)
        field = "tgv" if op == "div" else "sin2pi"
        fv = consph.field_values(field, pk.x)
        g, rep = consph.apply(pk, op, form=form, corr=corr, field=fv["f"], volume="number",
                              report=True)
        check(rep["fallbacks"] == res["rows"]["fallbacks"][k] and rep["h"] == res["rows"]["h"][k],
              f"apply {op} report {rep}")
        exact = {"grad": fv["grad"], "laplacian": fv["laplacian"], "div": fv["div"]}[op]
        e = np.abs(g - exact) if g.ndim == 1 else np.linalg.norm(g - exact, axis=1)
        ex = np.abs(exact) if exact.ndim == 1 else np.linalg.norm(exact, axis=1)
        mine = {"l1": e.sum() / ex.sum() if ex.sum() > 0 else np.nan, "l2": np.sqrt(np.mean(e * e)), "linf": e.max(),
                "mae": e.mean()}
        for col, v in mine.items():
            ref = res["rows"][col][k]
            check(abs(v - ref) <= 1e-12 * abs(ref) or (np.isnan(v) and np.isnan(ref)),
                  f"apply {op} {col} nx={nx}: {v} vs {ref}")
# the user's particles in any order: the same values, permuted (to round-off: the neighbours'
# order changes the sums)
perm = np.random.default_rng(1).permutation(p.n)
pp = consph.Particles(p.x[perm], p.lo, p.hi, p.periodic, p.spacing)
f = np.sin(2 * np.pi * (p.x[:, 0] + p.x[:, 1]))
g1 = consph.apply(p, "grad", field=f, volume="number")
g2 = consph.apply(pp, "grad", field=f[perm], volume="number")
check(np.allclose(g1[perm], g2, rtol=1e-12, atol=1e-12 * np.abs(g1).max()),
      "apply: a permutation of the particles permutes the result")
try:
    consph.apply(p, "grad", form="div", field=f)
    check(False, "an invalid triple was accepted")
except consph.InvalidArgument as e:
    check("f4" in str(e), f"invalid triple names the valid forms: {e}")

# ---- the solver: 20 steps equal consph run's snapshot bit for bit --------------------------
SNAP = {"u": "velocity", "p": "pressure", "rhof": "density"}
for scheme in ("wcsph", "l-ipst-c", "delta-plus-sph"):
    if scheme not in consph.names("scheme"):
        continue
    opts = {"scheme": scheme, "nx": 20, "steps": 20}
    if "ipst" in scheme:
        opts["ipst_every"] = 5
    s = consph.Solver("taylor-green", **opts)
    s.run()
    check(s.step_count == 20 and s.done, f"{scheme}: 20 steps")
    d = os.path.join(tmp, "run-" + scheme)
    argv = ["run", "taylor-green", "--scheme", scheme, "--nx", 20, "--steps", 20, "--out", d]
    if "ipst" in scheme:
        argv += ["--ipst-every", 5]
    cli(*argv)
    snap = consph.read_particles(os.path.join(d, "snap_000020.vtu"))
    check(snap.time == s.t, f"{scheme}: snapshot time {snap.time} vs {s.t}")
    check(bits_equal(snap.x, s.field("x", order="current")), f"{scheme}: positions")
    check(bits_equal(snap.fields["id"], s.field("id", order="current")), f"{scheme}: id")
    compared = 0
    for mine, theirs in SNAP.items():
        if theirs not in snap.fields:
            continue
        a = s.field(mine, order="current")
        b = snap.fields[theirs][:, :2] if a.ndim == 2 else snap.fields[theirs]
        check(bits_equal(a, b), f"{scheme}: {mine} equals the snapshot's {theirs}")
        compared += 1
    check(compared == 3, f"{scheme}: velocity, pressure and density compared ({compared})")
    check(not bits_equal(snap.fields["velocity"][:, :2], consph.Solver(
        "taylor-green", **opts).field("u", order="current")), f"{scheme}: the run moved u")
    # the run with files (consph_run, as consph run --out): its snapshot holds the CLI's arrays
    d3 = os.path.join(tmp, "py-run-" + scheme)
    check(consph.Solver("taylor-green", **opts).run(out=d3) == 20, f"{scheme}: run(out=...)")
    snap3 = consph.read_particles(os.path.join(d3, "snap_000020.vtu"))
    check(sorted(snap3.fields) == sorted(snap.fields) and bits_equal(snap3.x, snap.x) and all(
        bits_equal(snap3.fields[k], snap.fields[k]) for k in snap.fields),
        f"{scheme}: run(out=...) writes the CLI's snapshot, every array bit for bit")
    # the initial order is the id order
    ids = s.field("id")
    check(np.array_equal(ids, np.arange(s.n)), f"{scheme}: field(order='initial') by id")
    summary = json.load(open(os.path.join(d, "summary.json")))
    check(summary["steps"] == s.summary()["steps"] and summary["t"] == s.t, f"{scheme}: summary")

# a checkpoint from Python, continued by Solver.restart and by consph run --restart
s = consph.Solver("taylor-green", scheme="wcsph", nx=20, steps=20)
s.step(10)
ck = os.path.join(tmp, "half.ckpt")
s.checkpoint(ck)
r = consph.Solver.restart(ck)
check(r.step_count == 10 and r.run_id == s.run_id, "restart: step count and run id")
s.run()
r.run()
for name in ("x", "u", "p", "rhof"):
    check(bits_equal(s.field(name), r.field(name)), f"restart continues bit for bit: {name}")
d = os.path.join(tmp, "cli-restart")
cli("run", "--restart", ck, "--out", d)
snap = consph.read_particles(os.path.join(d, "snap_000020.vtu"))
check(bits_equal(snap.fields["velocity"][:, :2], s.field("u", order="current")),
      "consph run --restart of a Python checkpoint continues bit for bit")
ckd = consph.read_checkpoint(ck)
check(ckd["particles"].n == 400 and "run_id" in ckd["meta"] or "step" in ckd["meta"],
      "read_checkpoint: particles and metadata")
try:
    r.step()
    check(False, "a finished run stepped")
except consph.InvalidArgument:
    pass

# ---- runs from the user's particles (consph_solver_create_from) ----------------------------
def snapshot_equals(snap, solver, what):
    """The solver's state equals a snapshot of consph run bit for bit (cell order)."""
    check(bits_equal(snap.x, solver.field("x", order="current")), f"{what}: positions")
    for mine, theirs in SNAP.items():
        a = solver.field(mine, order="current")
        b = snap.fields[theirs][:, :2] if a.ndim == 2 else snap.fields[theirs]
        check(bits_equal(a, b), f"{what}: {mine} equals the snapshot's {theirs}")


lat = consph.layout("lattice", dim=2, nx=20)
base = {"scheme": "wcsph", "steps": 20}
s_lay = consph.Solver("taylor-green", nx=20, layout="lattice", **base)
s_lay.run()
s_par = consph.Solver("taylor-green", particles=lat, **base)
s_par.run()
s_tup = consph.Solver("taylor-green", particles=(lat.x,), **base)
s_tup.run()
check(s_par.params()["nx"] == "20" and s_par.n == 400, f"particles: nx from N {s_par.params()}")
for name in ("x", "u", "p", "rhof"):
    check(bits_equal(s_lay.field(name), s_par.field(name)), f"particles=layout: {name}")
    check(bits_equal(s_lay.field(name), s_tup.field(name)), f"particles=(x,): {name}")
lat_csv = os.path.join(tmp, "lattice.csv")
consph.write_particles(lat_csv, lat)
for how, extra in (("--layout", ["--nx", 20, "--layout", "lattice"]),
                   ("--particles", ["--particles", lat_csv])):
    d = os.path.join(tmp, "run-from" + how)
    cli("run", "taylor-green", "--scheme", "wcsph", "--steps", 20, *extra, "--out", d)
    snapshot_equals(consph.read_particles(os.path.join(d, "snap_000020.vtu")), s_par,
                    f"particles=layout against consph run {how}")
# the user's own positions, velocity and pressure: as consph run --particles reads them
rng = np.random.default_rng(4)
ux, uu, up = rng.random((300, 2)), 0.1 * rng.normal(size=(300, 2)), rng.normal(size=300)
user = consph.Particles(ux, fields={"u": uu, "p": up})
s_user = consph.Solver("taylor-green", particles=user, scheme="wcsph", steps=5)
check(bits_equal(s_user.field("u"), uu) and bits_equal(s_user.field("p"), up),
      "particles: the given velocity and pressure at t = 0")
s_user.run()
user_csv = os.path.join(tmp, "user.csv")
consph.write_particles(user_csv, user)
d = os.path.join(tmp, "run-user")
cli("run", "taylor-green", "--scheme", "wcsph", "--steps", 5, "--particles", user_csv, "--out", d)
snapshot_equals(consph.read_particles(os.path.join(d, "snap_000005.vtu")), s_user,
                "the user's particles against consph run --particles")
for bad, words in (({"particles": lat, "nx": 20}, "nx: not with particles"),
                   ({"particles": consph.Particles(lat.x, hi=2.0)}, "a run takes its problem's box"),
                   ({"particles": (lat.x, np.ones((lat.n, 3)))}, "has z = 1, but the problem is 2D")):
    try:
        consph.Solver("taylor-green", scheme="wcsph", **bad)
        check(False, f"accepted: {words}")
    except consph.InvalidArgument as e:
        check(words in str(e), f"refusal {words!r}: {e}")

# ---- a run past its end (consph_solver_extend) and a restart to a later t_f ------------------
full = consph.Solver("taylor-green", scheme="wcsph", nx=16, tf=0.04)
full.run()
part = consph.Solver("taylor-green", scheme="wcsph", nx=16, tf=0.02)
part.run(steps=5)
ck = os.path.join(tmp, "early.ckpt")
part.checkpoint(ck)
part.run(tf=0.04)  # past its end: the run's end becomes 0.04
again = consph.Solver.restart(ck)
again.run(tf=0.04)
ended = consph.Solver.restart(ck, tf=0.04)
ended.run()
check(part.t == 0.04 and part.done and full.t == 0.04, f"extended to t_f: {part.t}")
for name in ("x", "u", "p", "rhof"):
    for other, what in ((part, "run(tf) past the end"), (again, "restart, then run(tf)"),
                        (ended, "restart(tf=...)")):
        check(bits_equal(full.field(name), other.field(name)), f"{what}: {name} bit for bit")
more = consph.Solver("taylor-green", scheme="wcsph", nx=16, steps=10)
more.run()
more.run(steps=20)  # a run of steps, finished, extended by steps
ref = consph.Solver("taylor-green", scheme="wcsph", nx=16, steps=20)
ref.run()
check(more.step_count == 20 and bits_equal(more.field("u"), ref.field("u")), "run(steps) extends")
try:
    short = consph.Solver("taylor-green", scheme="wcsph", nx=16, tf=0.02)
    short.run()  # its last step was shortened to land on 0.02
    short.run(tf=0.04)
    check(False, "a run whose last step was shortened was extended")
except consph.InvalidArgument as e:
    check(str(e).startswith("the checkpoint is the end of a run whose last step was shortened"),
          f"extend refused with the library's message: {e}")

# ---- a run parameter file (consph_run_file_load, as consph run --config) ---------------------
case = os.path.join(tmp, "case.run")
with open(case, "w") as f:
    f.write("# Taylor-Green, weakly compressible\nproblem = taylor-green\nscheme = wcsph  # 001\n"
            "nx = 12\nsteps = 6\nlog_every = 2\n")
s_cfg = consph.Solver(config=case)
s_cfg.run()
d = os.path.join(tmp, "run-config")
cli("run", "--config", case, "--out", d)
check(s_cfg.step_count == 6 and s_cfg.params()["log_every"] == "2", "config: steps, log_every")
snapshot_equals(consph.read_particles(os.path.join(d, "snap_000006.vtu")), s_cfg,
                "Solver(config=...) against consph run --config")
s_opt = consph.Solver.from_config(case, nx=14, tf=0.01)  # keywords replace nx and steps
s_opt.run()
check(s_opt.n == 196 and s_opt.t == 0.01, f"from_config: keywords replace keys ({s_opt.n}, {s_opt.t})")
for lines, words in ((["problem = taylor-green", "nxx = 20"], "bad.run:2: unknown key 'nxx'"),
                     (["problem = taylor-green", "tf = 1", "steps = 3"],
                      "bad.run:3: keys 'steps' and 'tf' (line 2) both set the end of the run"),
                     (["scheme = l-ipst-c", "alpha = 0.2"], "bad.run:2: key 'alpha' does nothing"),
                     (["problem = nosuch"], "bad.run:1: key 'problem': problem 'nosuch'")):
    bad = os.path.join(tmp, "bad.run")
    with open(bad, "w") as f:
        f.write("\n".join(lines) + "\n")
    try:
        consph.Solver(config=bad)
        check(False, f"run file accepted: {words}")
    except consph.Error as e:
        check(str(e).startswith(bad[:-len("bad.run")] + words), f"run file refused: {e}")
        if "does nothing" not in words:  # the CLI's own words, but its option names
            _, _, err = cli("run", "--config", bad, ok=False)
            check(str(e) in err, f"run file: python {str(e)!r}, CLI {err!r}")
try:
    consph.Solver(config=case, particles=lat)
    check(False, "a file's nx beside particles")
except consph.InvalidArgument as e:
    check(str(e).startswith(case + ":4: key 'nx': not with particles"), str(e))

# ---- Wasserstein: exact 1D against the sorted-sample formula -------------------------------
rng = np.random.default_rng(2)
a, b = rng.random(200), rng.random(200) + 0.1
w1 = consph.wasserstein(a, b, p=1)["distance"]
check(abs(w1 - np.mean(np.abs(np.sort(a) - np.sort(b)))) < 1e-13, f"W1 1D {w1}")
try:
    consph.wasserstein(a, b, method="exact", directions=8)
    check(False, "directions for exact was accepted")
except consph.InvalidArgument:
    pass

# ---- a study file: its table equals consph.approx's numbers (to the CSV's 7 digits) ----------
study_file = os.path.join(tmp, "pytest.study")
with open(study_file, "w") as f:
    f.write("study = pytest\ntitle = A study run from Python\n[figure grad]\n"
            "title = Gradient on the lattice\nkind = approx\nop = grad\nform = f4\n"
            "nx = 8,16\n[series f4]\nlayout = lattice\n")
tables = consph.study(study_file, out_dir=os.path.join(tmp, "study"))
ref = consph.approx("grad", nx=[8, 16], form="f4")
check(list(tables["grad"]["nx"]) == [8.0, 16.0] and list(tables["grad"]["series"]) == ["f4"] * 2,
      f"study table: {tables['grad']}")
check(np.allclose(tables["grad"]["l1"], ref["rows"]["l1"], rtol=1e-6, atol=0),
      "study table l1 equals approx's")
check(os.path.isfile(os.path.join(tmp, "study", "pytest", "README.md")), "study: README.md")
try:
    consph.study("no-such-study")
    check(False, "an unknown study was found")
except consph.InvalidArgument:
    pass

# ---- the GPU (docs/gpu.md) on the host emulation, which runs the device's code on the CPU ------
# Solver(device='gpu') steps as the CPU's bit for bit; between two log samples its host copy
# lacks what the samples do not read, so field() and checkpoint() copy the state back first
# (consph_solver_sync); set_device moves a run back; restart(device=) continues on the GPU.
os.environ["CONSPH_GPU_BACKEND"] = "emulation"
info = consph.gpu()
check(info["available"] and info["reason"] == "" and "l-ipst-c" in info["schemes"]
      and "wcsph" in info["schemes"], f"consph.gpu() on the emulation: {info}")
for scheme in ("wcsph", "l-ipst-c"):
    opts = {"scheme": scheme, "nx": 16, "steps": 12, "log_every": 100}
    c = consph.Solver("taylor-green", **opts)
    g = consph.Solver("taylor-green", device="gpu", **opts)
    check(c.device == "cpu" and g.device == "gpu", f"{scheme}: device {c.device}, {g.device}")
    c.step(5)
    g.step(5)
    for name in ("x", "u", "p", "rhof"):
        check(bits_equal(c.field(name), g.field(name)), f"{scheme} on the GPU, step 5: {name}")
    sc, sg = c.summary(), g.summary()
    check(all(sc[k] == sg[k] for k in ("pairs", "steps", "t", "ke")), f"{scheme}: summary at 5")
    ck = os.path.join(tmp, f"gpu-{scheme}.ckpt")
    g.checkpoint(ck)
    g.step(2)
    g.set_device("cpu")
    check(g.device == "cpu", f"{scheme}: set_device('cpu')")
    c.run()
    g.run()
    r = consph.Solver.restart(ck, device="gpu")
    check(r.device == "gpu" and r.step_count == 5, f"{scheme}: restart on the GPU")
    r.run()
    for name in ("x", "u", "p", "rhof"):
        check(bits_equal(c.field(name), g.field(name)), f"{scheme}: back on the CPU: {name}")
        check(bits_equal(c.field(name), r.field(name)), f"{scheme}: GPU checkpoint, GPU restart: "
              f"{name}")
for bad, words in (({"device": "tpu"}, "device 'tpu' is unknown (allowed: cpu, gpu)"),
                   ({"device": "gpu", "skin": 0.1}, "--device gpu: --skin must be 0"),
                   ({"device": "gpu", "kernel": "cubic"}, "--device gpu: ")):
    try:
        consph.Solver("taylor-green", scheme="wcsph", nx=16, **bad)
        check(False, f"accepted: {bad}")
    except consph.InvalidArgument as e:
        check(str(e).startswith(words), f"refusal {words!r}: {e}")
del os.environ["CONSPH_GPU_BACKEND"]
# without the emulation: a CUDA device, or the reason there is none, as consph.gpu() says
info = consph.gpu()
try:
    check(consph.Solver("taylor-green", scheme="wcsph", nx=16, device="gpu").device == "gpu"
          and info["available"], f"a GPU run on the device: {info}")
except consph.InvalidArgument as e:
    check(not info["available"] and info["reason"] and str(e) == "--device gpu: " + info["reason"],
          f"no GPU: {e} ({info})")

# ---- studies on worker processes, on the GPU, resumed ----------------------------------------
run_study = os.path.join(tmp, "pyrun.study")
with open(run_study, "w") as f:
    f.write("study = pyrun\ntitle = Two schemes from Python\n[figure tg]\ntitle = Taylor-Green\n"
            "kind = run\nproblem = taylor-green\nc0 = 20\nnx = 8,12\ntf = 0.02\n"
            "[series wcsph]\nscheme = wcsph\n[series E-C]\nscheme = e-c\n")


def same_tables(a, b, what):
    cols = [k for k in a["tg"] if k != "seconds"]
    check(sorted(a["tg"]) == sorted(b["tg"]) and all(
        list(a["tg"][k]) == list(b["tg"][k]) if a["tg"][k].dtype == object
        else np.array_equal(a["tg"][k], b["tg"][k], equal_nan=True) for k in cols),
        f"{what}: the table equals the serial study's")


serial = consph.study(run_study, out_dir=os.path.join(tmp, "st1"))
check(list(serial["tg"]["nx"]) == [8.0, 12.0, 8.0, 12.0], f"study rows {serial['tg']['nx']}")
same_tables(serial, consph.study(run_study, out_dir=os.path.join(tmp, "st2"), jobs=2),
            "jobs=2")
os.environ["CONSPH_GPU_BACKEND"] = "emulation"
on_gpu = consph.study(run_study, out_dir=os.path.join(tmp, "stg"), device="gpu", jobs=2)
same_tables(serial, on_gpu, "device='gpu', jobs=2 (the emulation)")
check("Device: the GPU ran every row." in open(os.path.join(tmp, "stg", "pyrun", "tg.md")).read(),
      "the GPU study's report says where its rows ran")
del os.environ["CONSPH_GPU_BACKEND"]
same_tables(serial, consph.study(run_study, out_dir=os.path.join(tmp, "st1"), resume=True),
            "resume=True on a finished study")
for bad, words in (({"device": "tpu"}, "device 'tpu' is unknown (allowed: cpu, gpu, auto)"),
                   ({"jobs": 0}, "jobs = 0 is out of range"),
                   ({"resume": True}, "resume: give the out_dir"),
                   ({"resume": True, "quick": True, "out_dir": os.path.join(tmp, "st1")},
                    "--resume: the rows in")):
    try:
        consph.study(run_study, **bad)
        check(False, f"study accepted: {bad}")
    except consph.Error as e:
        check(str(e).startswith(words), f"study refusal {words!r}: {e}")

# ---- README.md's Python example runs as printed (from the source tree, as its paths are) ------
source = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
with open(os.path.join(source, "README.md")) as f:
    readme = f.read()
block = readme.split("```python\n", 1)[1].split("```", 1)[0] if "```python\n" in readme else ""
check("consph.Solver" in block, "README.md has its Python example")
r = subprocess.run([sys.executable, "-c", block], cwd=source, capture_output=True, text=True,
                   env=dict(os.environ, PYTHONPATH=os.path.dirname(build_python)), timeout=300)
check(r.returncode == 0, f"README.md's Python example exits 0: {r.stderr[-600:]}")

# ---- make install: the package imports from the prefix -------------------------------------
prefix = os.path.join(tmp, "prefix")
r = subprocess.run(["cmake", "--install", os.path.dirname(consph_bin), "--prefix", prefix],
                   capture_output=True, text=True)
check(r.returncode == 0, f"cmake --install: {r.stderr}")
site = glob.glob(os.path.join(prefix, "lib", "python3*", "*-packages"))
check(len(site) == 1 and os.path.isfile(os.path.join(site[0], "consph", "__init__.py")),
      f"installed package: {site}")
if site:
    env = dict(os.environ, PYTHONPATH=site[0])
    r = subprocess.run([sys.executable, "-c", "import consph; print(consph.__file__); "
                        "print(float(consph.W([0.0], 'cubic', 1)[0]))"],
                       capture_output=True, text=True, env=env, cwd=tmp)
    lines = r.stdout.split()
    check(r.returncode == 0 and len(lines) == 2 and lines[0].startswith(prefix)
          and abs(float(lines[1]) - 2.0 / 3.0) < 1e-15, f"the installed module: {r}")

for f in failures:
    print("FAIL:", f)
print("python module:", "ok" if not failures else f"{len(failures)} failures")
shutil.rmtree(tmp, ignore_errors=True)
sys.exit(1 if failures else 0)
