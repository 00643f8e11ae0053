#!/usr/bin/env bash
# Every `--format json` output the CLI can produce (only `consph approx` has one: from layouts
# and from particle files, with finite and non-finite values, every operator, 1D to 3D) parses
# with a strict JSON parser: Python's json module, refusing NaN and Infinity, which JSON lacks.
set -u
consph=$1
py=$(command -v python3) || { echo "skipped: python3 not installed"; exit 77; }
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

cat >"$tmp/check.py" <<'PY'
import json, sys
def no_constant(name):
    raise ValueError("bare " + name + " is not JSON")
doc = json.loads(open(sys.argv[1]).read(), parse_constant=no_constant)
rows = doc["rows"]
assert rows, "no rows"
for r in rows:
    for k in ("nx", "n", "h", "l1", "l2", "linf", "mae", "ft_over_fmax", "seconds", "fallbacks"):
        assert k in r, "row lacks " + k
for k, v in doc["order"].items():
    assert v is None or isinstance(v["order"], float), k
PY
# json FILE ARGS...: runs approx with ARGS --format json into FILE and parses it; the exit
# status may be 3 (a non-finite error), the output must still be JSON.
json() {
  local out=$1; shift
  "$consph" approx "$@" --format json >"$out" 2>"$tmp/err"
  local rc=$?
  if [ $rc != 0 ] && [ $rc != 3 ]; then bad "approx $* --format json: exit $rc: $(cat "$tmp/err")"; return; fi
  "$py" "$tmp/check.py" "$out" 2>"$tmp/pyerr" || bad "approx $* --format json: $(tail -1 "$tmp/pyerr")"
}

n=0
for op in function grad div laplacian hessian; do
  json "$tmp/$((n += 1)).json" --op $op --nx 8,12,16
done
# div of tgv: l1 is undefined (0/0) in every row; no neighbours: F_T/F_max is 0/0; two rows: no
# standard error.
json "$tmp/$((n += 1)).json" --op div --nx 8,12
json "$tmp/$((n += 1)).json" --op grad --nx 8,12,16 --hdx 0.05
for lay in random quasi-random packed; do
  json "$tmp/$((n += 1)).json" --op grad --layout $lay --nx 8,10 --pack-iter 50
done
json "$tmp/$((n += 1)).json" --op laplacian --dim 1 --nx 16,32
json "$tmp/$((n += 1)).json" --op grad --dim 3 --nx 5,6 --hdx 0.8
json "$tmp/$((n += 1)).json" --op grad --periodic no --nx 12,16 --field linear
grep -q '"l1": null' "$tmp/6.json" || bad "div: undefined l1 not written as null"
grep -q '"ft_over_fmax": null' "$tmp/7.json" || bad "no neighbours: F_T/F_max not written as null"

# Particle files, one with a name JSON must escape, and one whose errors are not finite.
"$consph" layout --kind random --dim 2 --nx 8 --out "$tmp/a.csv" >/dev/null || bad "layout csv"
"$consph" layout --kind lattice --dim 2 --nx 8 --out "$tmp/b.vtu" >/dev/null || bad "layout vtu"
cp "$tmp/a.csv" "$tmp/q\"uo\\te.csv"
awk -F, -v OFS=, '/^#/ || /^x/ { print; next } { if (++k == 3) $NF = "1e308"; print }' \
  "$tmp/a.csv" >"$tmp/big.csv"
json "$tmp/f1.json" --op grad --particles "$tmp/a.csv,$tmp/b.vtu,$tmp/q\"uo\\te.csv"
json "$tmp/f2.json" --op grad --form f2 --particles "$tmp/a.csv,$tmp/big.csv"
json "$tmp/f3.json" --op function --particles "$tmp/a.csv" --volume lattice
grep -q 'q\\"uo\\\\te.csv' "$tmp/f1.json" || bad "file name not escaped: $(grep -o '"file": "[^,]*' "$tmp/f1.json")"
grep -q '"l2": null' "$tmp/f2.json" || bad "non-finite l2 not written as null"
exit $fail
