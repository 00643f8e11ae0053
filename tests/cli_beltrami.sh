#!/usr/bin/env bash
# `consph run beltrami` (the 3D problem): a run on the 8³ lattice writes a 3D summary
# (dim 3, momentum_z) and snapshots with a 3-component velocity and vorticity; a checkpointed
# run restarts bit for bit in 3D; 1 and 2 threads give the same bits; the problem is listed
# where an unknown one is refused.
# Usage: bash cli_beltrami.sh PATH-TO-CONSPH SOURCE-DIR
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

r() { "$consph" run beltrami --scheme e-c --nx 8 --steps 12 --threads 1 "$@" >/dev/null; }
r --out "$tmp/full" || bad "beltrami run"
r --checkpoint-every 6 --out "$tmp/ck" || bad "checkpointed run"
"$consph" run --restart "$tmp/ck/checkpoint.ckpt" --out "$tmp/re" --threads 1 >/dev/null ||
    bad "restart"
cmp -s "$tmp/full/snap_000012.vtu" "$tmp/re/snap_000012.vtu" || bad "restarted 3D snapshot differs"
cmp -s "$tmp/full/log.csv" "$tmp/re/log.csv" || bad "restarted 3D log differs"
grep -q '"dim": 3,' "$tmp/full/summary.json" || bad "summary: not dim 3"
grep -q '"n": 512,' "$tmp/full/summary.json" || bad "summary: not 8^3 particles"
grep -q '"momentum_z": ' "$tmp/full/summary.json" || bad "summary: no momentum_z"
# (the velocity under its name of either snapshot naming: u or velocity)
for f in 'u|velocity' vorticity; do
    grep -aEq "Name=\"($f)\" NumberOfComponents=\"3\"" "$tmp/full/snap_000012.vtu" ||
        bad "snapshot: $f is not a 3-component array"
done
# thread-count independence in 3D, above the solver's parallel threshold (4096 particles)
for t in 1 2; do
    "$consph" run beltrami --scheme l-ipst-c --layout lattice --nx 16 --steps 2 --ipst-every 2 \
        --threads $t --out "$tmp/th$t" >/dev/null || bad "16^3 run on $t threads"
done
cmp -s "$tmp/th1/log.csv" "$tmp/th2/log.csv" &&
    cmp -s "$tmp/th1/snap_000002.vtu" "$tmp/th2/snap_000002.vtu" ||
    bad "3D results depend on the thread count"
msg=$("$consph" run nope --scheme e-c 2>&1)
[ $? = 2 ] && echo "$msg" | grep -q 'beltrami' || bad "unknown problem: $msg"
[ $fail = 0 ] && echo "cli_beltrami: ok"
exit $fail
