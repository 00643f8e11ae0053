#!/usr/bin/env bash
# consph run heat (002 §6): the files of a run (snapshots with their .pvd index, the log, the JSON
# summary with l2, linf, ec at t = 0.1), S4 more accurate than S3, and options refused with exit
# status 2 and nothing written: heat options for other problems and WCSPH options for heat.
# Usage: bash cli_heat.sh PATH-TO-CONSPH
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

expect_usage() {
    local what=$1 name=$2
    shift 2
    mkdir -p "$tmp/bad"
    "$consph" run "$@" --out "$tmp/bad" >"$tmp/out" 2>"$tmp/err"
    local rc=$?
    [ $rc -eq 2 ] || bad "$what: exit $rc, expected 2"
    [ "$(wc -l <"$tmp/err")" -eq 1 ] || bad "$what: not one line: $(cat "$tmp/err")"
    grep -q -- "$name" "$tmp/err" || bad "$what: '$name' not named: $(cat "$tmp/err")"
    [ -z "$(ls -A "$tmp/bad")" ] || bad "$what: wrote $(ls "$tmp/bad")"
    rm -rf "$tmp/bad"
}
expect_usage "unknown laplacian" "s3,s4" heat --laplacian s5
expect_usage "eta too small" "--eta" heat --eta 0.5
expect_usage "eps too large" "--eps" heat --eps 2
expect_usage "unknown walls" "sin,linear" heat --walls cos
expect_usage "WCSPH option for heat" "--scheme" heat --scheme l-ipst-c
expect_usage "WCSPH option for heat" "--hdx" heat --hdx 1.2
expect_usage "heat option for taylor-green" "--laplacian" taylor-green --laplacian s4
expect_usage "heat option for taylor-green" "--eta" taylor-green --eta 2

# --- a run with its files ---
"$consph" run heat --laplacian s4 --nx 12 --eta 2 --eps 0.2 --seed 3 --out "$tmp/s4" \
    --snapshot-every 20 --format json >"$tmp/s4.json" || bad "s4 run failed"
for f in run.pvd log.csv summary.json snap_000000.vtu snap_000020.vtu; do
    [ -s "$tmp/s4/$f" ] || bad "missing $f"
done
cmp -s "$tmp/s4.json" "$tmp/s4/summary.json" || bad "stdout JSON differs from summary.json"
grep -q '"t": 0.10000000000000001' "$tmp/s4.json" || bad "did not land on t = 0.1"
for k in l2 linf ec; do
    grep -q "\"$k\": [0-9]" "$tmp/s4.json" || bad "summary lacks $k"
done
head -1 "$tmp/s4/log.csv" | grep -q '^step,t,dt,mean_T,l2,linf,ec$' || bad "log header"
steps=$(sed -n 's/.*"steps": \([0-9]*\).*/\1/p' "$tmp/s4.json")
[ "$(($(wc -l <"$tmp/s4/log.csv") - 2))" = "$steps" ] || bad "log rows vs $steps steps"
last=$(ls "$tmp/s4" | grep -c '^snap_')
[ "$(grep -c '<DataSet' "$tmp/s4/run.pvd")" = "$last" ] || bad "pvd does not index every snapshot"
grep -q 'T_exact' "$tmp/s4/snap_000020.vtu" || bad "snapshot lacks T_exact"

# --- S4 is far more accurate than S3 at η = 1.5 (002 Fig. 1) ---
l2() { "$consph" run heat --laplacian "$1" --nx 20 --eta 1.5 --format json |
    sed -n 's/.*"l2": \(.*\),/\1/p'; }
a=$(l2 s3)
b=$(l2 s4)
awk -v a="$a" -v b="$b" 'BEGIN { exit !(b < 0.1 * a) }' || bad "S4 l2 $b not 10x below S3 $a"

exit $fail
