#!/usr/bin/env bash
# Writes .vtu files with `consph layout` and reads them back with VTK's own XML reader
# (vtkXMLUnstructuredGridReader): point count, coordinates of a few points, the "volume" array,
# the vertex cells; every --vtu-encoding (ascii, binary, zlib) to the last bit.
# Exit 77 (skipped) when the Python VTK module is not installed (Debian package python3-vtk9).
# Usage: cli_vtu_reader.sh <path-to-consph> <source-dir>
set -u
bin=$1
py=/usr/bin/python3
# A bad --vtu-encoding, or one for a file that is not .vtu: exit 2, one line naming the option
# and what is allowed, no file (checked before the skip: it needs no VTK).
bad_dir=$(mktemp -d)
for args in "--out $bad_dir/b.vtu --vtu-encoding gzip" "--out $bad_dir/b.csv --vtu-encoding zlib" \
    "--vtu-encoding ascii"; do
    # shellcheck disable=SC2086
    "$bin" layout --kind lattice --dim 2 --nx 4 $args >"$bad_dir/out" 2>"$bad_dir/err"
    rc=$?
    if [ $rc -ne 2 ] || [ "$(wc -l <"$bad_dir/err")" -ne 1 ] ||
        ! grep -q -- "--vtu-encoding.*allowed: " "$bad_dir/err" || [ -e "$bad_dir/b.vtu" ] ||
        [ -e "$bad_dir/b.csv" ]; then
        echo "FAIL: layout $args: exit $rc, stderr: $(cat "$bad_dir/err")" >&2
        rm -rf "$bad_dir"
        exit 1
    fi
done
rm -rf "$bad_dir"
if ! "$py" -c 'import vtk' >/dev/null 2>&1; then
    echo "python3 VTK module not available; skipping" >&2
    exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMP_NUM_THREADS=1

"$bin" layout --kind lattice --dim 2 --nx 5 --out "$work/lattice2.vtu" >/dev/null || exit 1
"$bin" layout --kind lattice --dim 3 --nx 4 --out "$work/lattice3.vtu" >/dev/null || exit 1
"$bin" layout --kind quasi-random --dim 2 --nx 6 --out "$work/halton.vtu" >/dev/null || exit 1
for enc in ascii binary zlib; do
    "$bin" layout --kind random --dim 2 --nx 6 --seed 4 --eps 0.4 --out "$work/random_$enc.vtu" \
        --periodic no --vtu-encoding $enc >/dev/null || exit 1
done
# More values than one zlib block of the writer (2^18 bytes) in the points and volume arrays.
"$bin" layout --kind random --dim 3 --nx 40 --seed 2 --out "$work/big.vtu" >/dev/null || exit 1
"$bin" layout --kind random --dim 3 --nx 40 --seed 2 --out "$work/big.csv" >/dev/null || exit 1
"$bin" layout --kind random --dim 2 --nx 6 --seed 4 --eps 0.4 --out "$work/random.csv" \
    --periodic no >/dev/null || exit 1

"$py" - "$work" <<'EOF'
import sys
import vtk

work = sys.argv[1]
failures = []


def check(cond, what):
    if not cond:
        failures.append(what)


def read(name):
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(f"{work}/{name}")
    r.Update()
    return r.GetOutput()


def close(a, b, tol=1e-15):
    return abs(a - b) <= tol


# 2D lattice, 5x5 on [0,1)^2: Δs = 0.2, x = (i + 1/2) Δs with axis 0 varying fastest.
g = read("lattice2.vtu")
check(g.GetNumberOfPoints() == 25, f"lattice2: {g.GetNumberOfPoints()} points, expected 25")
check(g.GetNumberOfCells() == 25, "lattice2: one vertex cell per point")
for idx, expect in [(0, (0.1, 0.1, 0.0)), (1, (0.3, 0.1, 0.0)), (5, (0.1, 0.3, 0.0)),
                    (24, (0.9, 0.9, 0.0))]:
    p = g.GetPoint(idx)
    check(all(close(a, b) for a, b in zip(p, expect)), f"lattice2 point {idx}: {p} != {expect}")
vol = g.GetPointData().GetArray("volume")
check(vol is not None, "lattice2: no 'volume' array")
if vol is not None:
    check(vol.GetNumberOfTuples() == 25, "lattice2: volume tuples")
    check(all(close(vol.GetValue(i), 0.04) for i in range(25)), "lattice2: volume != 1/25")
fd = g.GetFieldData()
box = fd.GetArray("box")
check(box is not None and [box.GetComponent(0, c) for c in range(4)] == [0, 1, 0, 1],
      "lattice2: box field data")

# 3D lattice, 4^3: Δs = 0.25.
g = read("lattice3.vtu")
check(g.GetNumberOfPoints() == 64, f"lattice3: {g.GetNumberOfPoints()} points")
for idx, expect in [(0, (0.125, 0.125, 0.125)), (63, (0.875, 0.875, 0.875)),
                    (1 + 4 * 2 + 16 * 3, (0.375, 0.625, 0.875))]:
    p = g.GetPoint(idx)
    check(all(close(a, b) for a, b in zip(p, expect)), f"lattice3 point {idx}: {p} != {expect}")
vol = g.GetPointData().GetArray("volume")
check(vol is not None and close(vol.GetValue(10), 1 / 64), "lattice3: volume")

# Halton points: index 1, 2, 3 in bases 2 and 3.
g = read("halton.vtu")
check(g.GetNumberOfPoints() == 36, "halton: 36 points")
for idx, expect in [(0, (0.5, 1 / 3)), (1, (0.25, 2 / 3)), (2, (0.75, 1 / 9))]:
    p = g.GetPoint(idx)
    check(close(p[0], expect[0]) and close(p[1], expect[1], 1e-15),
          f"halton point {idx}: {p[:2]} != {expect}")

# The .vtu (in every encoding) and the .csv of the same random layout hold the same coordinates
# and volumes to the last bit, and one vertex cell per particle.
def same_as_csv(vtu, csv, count, dim):
    g = read(vtu)
    rows = [l for l in open(f"{work}/{csv}") if not l.startswith("#")][1:]
    check(g.GetNumberOfPoints() == len(rows) == count, f"{vtu}: point count")
    check(g.GetNumberOfCells() == count, f"{vtu}: cell count")
    vol = g.GetPointData().GetArray("volume")
    check(vol is not None, f"{vtu}: no 'volume' array")
    for i, row in enumerate(rows):
        t = [float(t) for t in row.split(",")]
        p = g.GetPoint(i)
        if list(p[:dim]) != t[:dim] or any(c != 0.0 for c in p[dim:]):
            check(False, f"{vtu} point {i}: vtu {p} != csv {t[:dim]}")
            break
        if vol is not None and vol.GetValue(i) != t[dim]:
            check(False, f"{vtu} volume {i}: vtu {vol.GetValue(i)!r} != csv {t[dim]!r}")
            break
    for i in sorted({0, 1, count // 2, count - 1}):
        c = g.GetCell(i)
        check(c.GetCellType() == vtk.VTK_VERTEX and c.GetNumberOfPoints() == 1 and
              c.GetPointId(0) == i, f"{vtu}: cell {i} is not the vertex of point {i}")


for enc in ("ascii", "binary", "zlib"):
    same_as_csv(f"random_{enc}.vtu", "random.csv", 36, 2)
same_as_csv("big.vtu", "big.csv", 64000, 3)

if failures:
    for f in failures:
        print("FAIL:", f, file=sys.stderr)
    sys.exit(1)
print("vtu reader: all checks passed")
EOF
