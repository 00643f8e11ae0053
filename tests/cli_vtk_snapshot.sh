#!/usr/bin/env bash
# A run's snapshots as ParaView sees them, read with VTK's own XML reader: one scheme of each
# family (and tvf, whose density is a summation) writes exactly the arrays docs/solver-files.md
# lists, with their components (vectors 3, the velocity gradient 9 with the z row and column
# zero in 2D), the same arrays at every step, and a FieldData TimeValue equal to the time
# run.pvd gives the file. Exit 77 (skipped) without the Python VTK module (python3-vtk9).
# Usage: cli_vtk_snapshot.sh <path-to-consph> <source-dir>
set -u
bin=$1
py=/usr/bin/python3
if ! "$py" -c 'import vtk' >/dev/null 2>&1; then
    echo "python3 VTK module not available; skipping" >&2
    exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMP_NUM_THREADS=1
for s in l-ipst-c wcsph tvf delta-plus-sph; do
    "$bin" run taylor-green --scheme $s --nx 8 --steps 2 --snapshot-every 1 --out "$work/$s" \
        >/dev/null || { echo "FAIL: run $s"; exit 1; }
done
"$py" - "$work" <<'EOF'
import re
import sys

import vtk

work = sys.argv[1]
core = [("id", 1), ("velocity", 3), ("pressure", 1)]
tail = [("velocity_gradient", 9), ("vorticity", 1), ("velocity_exact", 3), ("pressure_exact", 1)]
expect = {
    "l-ipst-c": core + [("density", 1), ("volume", 1)] + tail,
    "wcsph": core + [("density", 1)] + tail,
    "tvf": core + [("summation_density", 1)] + tail,
    "delta-plus-sph": core + [("density", 1), ("volume", 1)] + tail + [("mass", 1)],
}
failures = []
for scheme, want in expect.items():
    pvd = open(f"{work}/{scheme}/run.pvd").read()
    entries = re.findall(r'timestep="([^"]*)" file="([^"]*)"', pvd)
    if len(entries) != 3:
        failures.append(f"{scheme}: {len(entries)} snapshots, expected 3")
    for t, name in entries:
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(f"{work}/{scheme}/{name}")
        r.Update()
        g = r.GetOutput()
        pd = g.GetPointData()
        have = [(pd.GetArrayName(k), pd.GetArray(k).GetNumberOfComponents())
                for k in range(pd.GetNumberOfArrays())]
        if have != want:
            failures.append(f"{scheme} {name}: arrays {have}, documented {want}")
            continue
        tv = g.GetFieldData().GetArray("TimeValue")
        if tv is None or tv.GetNumberOfTuples() != 1 or tv.GetValue(0) != float(t):
            failures.append(f"{scheme} {name}: TimeValue {tv and tv.GetValue(0)}, run.pvd {t}")
        n = g.GetNumberOfPoints()
        u, G = pd.GetArray("velocity"), pd.GetArray("velocity_gradient")
        if n != 64 or any(u.GetComponent(i, 2) != 0.0 for i in range(n)) or any(
                G.GetComponent(i, c) != 0.0 for i in range(n) for c in (2, 5, 6, 7, 8)):
            failures.append(f"{scheme} {name}: {n} points, or a z component not zero in 2D")
        if all(G.GetComponent(i, 1) == 0.0 for i in range(n)):
            failures.append(f"{scheme} {name}: the velocity gradient's du/dy is zero everywhere")
for f in failures:
    print("FAIL:", f, file=sys.stderr)
sys.exit(1 if failures else 0)
EOF
rc=$?
[ $rc = 0 ] && echo "cli_vtk_snapshot: all checks passed"
exit $rc
