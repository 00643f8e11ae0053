#!/usr/bin/env bash
# `consph run --error authors` reports the measure of 001's authors
# beside eq. 26 (table and JSON; the default run's JSON has no such keys); a bad --error is
# refused with exit 2 naming the allowed values; a run study with `error = authors` reports both
# (eq. 26 columns in its table and CSV); a quick study's title says the t_f and resolutions it
# ran; a study on --particles says so in its title instead of the layout the title names.
# Usage: bash cli_error_measure.sh PATH-TO-CONSPH SOURCE-DIR
set -u
consph=$1 src=$2
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
run="$consph run taylor-green --nx 12 --c0 20 --tf 0.01"

# 1. the run: JSON and table
$run --error authors --error-times 5 --format json >"$tmp/a.json" 2>"$tmp/err" || bad "run --error authors: $(cat "$tmp/err")"
grep -q '"error": "authors"' "$tmp/a.json" && grep -q '"error_samples": 5,' "$tmp/a.json" &&
    grep -q '"l1_u_authors": [0-9]' "$tmp/a.json" && grep -q '"l1_p_authors": [0-9]' "$tmp/a.json" &&
    grep -q '"l1_u": [0-9]' "$tmp/a.json" || bad "summary JSON lacks the authors' measure: $(cat "$tmp/a.json")"
$run --format json >"$tmp/d.json" 2>/dev/null || bad "default run"
grep -q 'authors' "$tmp/d.json" && bad "the default (eq26) run's JSON changed"
$run --error authors --error-times 5 >"$tmp/a.txt" 2>/dev/null || bad "run --error authors (table)"
grep -q "(001's authors: mean over 5 output times)" "$tmp/a.txt" && grep -q '(001 eq. 26)' "$tmp/a.txt" ||
    bad "table lacks one of the two measures: $(cat "$tmp/a.txt")"
$run --error l2 >/dev/null 2>"$tmp/err"
rc=$?
[ $rc = 2 ] && grep -q -- '--error' "$tmp/err" && grep -q 'eq26' "$tmp/err" && grep -q 'authors' "$tmp/err" ||
    bad "--error l2: exit $rc, $(cat "$tmp/err")"
$run --error authors --error-times 1 >/dev/null 2>"$tmp/err"
[ $? = 2 ] || bad "--error-times 1 accepted"
$run --error-times 5 >/dev/null 2>"$tmp/err"
[ $? = 2 ] && grep -q -- '--error authors' "$tmp/err" || bad "--error-times without --error authors: $(cat "$tmp/err")"

# 2. a run study with the authors' measure, quick
cat >"$tmp/tiny.study" <<'STUDY'
study = tiny
title = tiny Taylor-Green sweep
[figure conv]
title = Taylor-Green to t = 0.5
kind = run
problem = taylor-green
layout = lattice
c0 = 20
nx = 50,100
quick.nx = 10,14
tf = 0.5
quick.tf = 0.01
tr_ref = E-C
error = authors
error_times = 6
[series E-C]
scheme = e-c
paper.l1_u = 5.11e-05
STUDY
"$consph" study "$tmp/tiny.study" --quick --out "$tmp/out" >"$tmp/log" 2>&1 || { cat "$tmp/log"; bad "tiny study"; }
md=$tmp/out/tiny/conv.md
grep -q '^## conv: Taylor-Green to t = 0.5 \[quick run: to t = 0.01, nx 10, 14\]$' "$md" ||
    bad "quick title does not say what ran: $(head -1 "$md")"
grep -q 'Run: quick resolutions (nx 10, 14)' "$md" || bad "Run line lacks the resolutions"
grep -q 'mean over 6 output times' "$md" || bad "report does not name the authors' measure"
grep -q '| paper L1(u) | eq. 26 L1(u) | order u |' "$md" || bad "no eq. 26 column beside the paper's"
head -1 "$tmp/out/tiny/conv.csv" | grep -q ',status,l1_u_eq26,l1_p_eq26$' || bad "csv lacks eq. 26"
# the table's L1(u) is the authors' measure, the eq. 26 column the integral
awk -F, 'NR > 1 && $10 == $19 { same = 1 } END { exit same }' "$tmp/out/tiny/conv.csv" ||
    bad "authors' L1 equals eq. 26 in the csv"
grep -q "ran: t_f = 0.01, nx = 10, 14, c_o = [0-9.]* (quick; full study: t_f = 0.5, " "$tmp/out/tiny/conv.gp" ||
    bad "plot title does not say what ran: $(grep 'set multiplot' "$tmp/out/tiny/conv.gp")"

# 3. --particles: the title says the particles came from files
"$consph" layout --kind random --dim 2 --nx 8 --out "$tmp/r8.csv" >/dev/null &&
    "$consph" layout --kind random --dim 2 --nx 12 --out "$tmp/r12.csv" >/dev/null || bad "layout"
"$consph" study "$src/tests/data/engine.study" --quick --out "$tmp/st" \
    --particles "$tmp/r8.csv,$tmp/r12.csv" >"$tmp/st.log" 2>&1 || bad "study --particles: $(tail -3 "$tmp/st.log")"
grep -q '^## grad: .* \[this run: particles from files (--particles), not the layout the title names\]$' \
    "$tmp/st/engine/grad.md" || bad "--particles title: $(head -1 "$tmp/st/engine/grad.md")"
grep -q "Run: the files' resolutions" "$tmp/st/engine/grad.md" || bad "--particles Run line"
"$consph" study "$src/tests/data/engine.study" --quick --out "$tmp/st2" >/dev/null 2>&1
grep -q 'this run: particles' "$tmp/st2/engine/grad.md" && bad "title changed without --particles"
exit $fail
