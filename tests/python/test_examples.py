"""The paper-figure examples of examples/python/ in their --quick mode (docs/python.md).

Usage: python3 test_examples.py PATH-TO-CONSPH, with PYTHONPATH at the build's python/ folder
(tests/CMakeLists.txt). Exit 77 (skipped) when the module was not built there or matplotlib is
missing.

What must hold for each example: it exits 0, writes its PNG, and the PNG decodes to a drawn
figure (not a blank canvas: many distinct colours, and pixels of each series colour it uses);
for fig1_003.py, every printed MAE lies below its printed bound (003 eqs. 56/57 are upper bounds).
"""

import glob
import os
import subprocess
import sys
import tempfile

consph_bin = os.path.abspath(sys.argv[1])
build_python = os.path.join(os.path.dirname(consph_bin), "python", "consph")
if not glob.glob(os.path.join(build_python, "_core*.so")):
    print(f"the Python module was not built ({build_python}): skipped")
    sys.exit(77)
try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.colors  # noqa: E402
    import matplotlib.image  # noqa: E402
    import numpy as np  # noqa: E402
except ImportError as e:
    print(f"matplotlib or numpy missing ({e}): skipped")
    sys.exit(77)

source = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
examples = os.path.join(source, "examples", "python")
failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        failures.append(what)


def has_colour(img, name, tol=0.06):
    """Whether some pixel is within tol of the named matplotlib colour."""
    rgb = np.array(matplotlib.colors.to_rgb(name))
    return bool((np.abs(img[:, :, :3] - rgb).max(axis=2) < tol).any())


with tempfile.TemporaryDirectory(prefix="consph-examples-") as tmp:
    env = dict(os.environ, PYTHONPATH=os.path.dirname(build_python))
    for script, colours in (("fig1_003.py", ("tab:blue", "tab:red")), ("kernels_003.py", ())):
        png = os.path.join(tmp, script[:-3] + ".png")
        r = subprocess.run([sys.executable, os.path.join(examples, script), png, "--quick"],
                           cwd=tmp, env=env, capture_output=True, text=True, timeout=120)
        check(r.returncode == 0, f"{script} --quick exits 0 (stderr: {r.stderr[-400:]!r})")
        if r.returncode != 0:
            continue
        check(os.path.isfile(png) and os.path.getsize(png) > 20000,
              f"{script} writes {os.path.basename(png)} of more than 20 kB")
        with open(png, "rb") as f:
            check(f.read(8) == b"\x89PNG\r\n\x1a\n", f"{script}: the file is a PNG")
        img = matplotlib.image.imread(png)
        ncolours = len(np.unique((img[:, :, :3] * 255).astype(np.uint8).reshape(-1, 3), axis=0))
        check(img.shape[0] >= 400 and img.shape[1] >= 600 and ncolours > 50,
              f"{script}: a drawn figure ({img.shape[1]}x{img.shape[0]}, {ncolours} colours)")
        for name in colours:
            check(has_colour(img, name), f"{script}: pixels of the series colour {name}")
        if script == "fig1_003.py":
            # the printed rows: "    MAE:   v v ..." then "    bound: v v ..." per dimension
            rows = {}
            for line in r.stdout.splitlines():
                key, _, vals = line.strip().partition(":")
                if key in ("MAE", "bound"):
                    rows.setdefault(key, []).append([float(v) for v in vals.split()])
            ok = len(rows.get("MAE", [])) == 2 and len(rows.get("bound", [])) == 2
            for mae, bound in zip(rows.get("MAE", []), rows.get("bound", [])):
                ok = ok and len(mae) == len(bound) >= 4 and all(
                    0 < m < b for m, b in zip(mae, bound))
            check(ok, "fig1_003.py: 2D and 3D, every MAE positive and below its bound")

if failures:
    print(f"{len(failures)} failure(s)")
    sys.exit(1)
print("all passed")
