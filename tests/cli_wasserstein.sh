#!/usr/bin/env bash
# consph wasserstein on particle files:
# 1. Known answers: a 1D lattice and its translate (W1 = W2 = |shift|, CSV against VTU); masses
#    from the m column, from volume*rho, and equal weights (each changes the answer as it must);
#    a 2D translate by Sinkhorn (within its own bound) and by the sliced distance (SW2 = |s|/√2
#    within 4 standard errors); sliced = exact in 1D; a lattice against the uniform density
#    (W1 = Δs/4, W2 = Δs/√12 within the reported grid error); the cubic spline smoothing a
#    periodic lattice gives the uniform density (its B-spline partition of unity), and smoothing
#    a perturbed lattice brings it closer to uniform.
# 2. The same JSON (all but the time) on 1 and 2 threads.
# 3. Bad input: exit status 2, one line naming the option and the allowed values, nothing on
#    stdout.
# Usage: cli_wasserstein.sh <path-to-consph> <source-dir>
set -u
bin=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
pass=0
fail=0
ok() { pass=$((pass + 1)); }
bad() {
    echo "FAIL: $*"
    fail=$((fail + 1))
}
# field NAME < json: the number after "NAME":
field() { sed -n "s/.*\"$1\": \([-0-9.eE+]*\).*/\1/p" | head -1; }
# near A B TOL: |A - B| <= TOL
near() { awk -v a="$1" -v b="$2" -v t="$3" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(d <= t) }'; }

# ---- 1. known answers ---------------------------------------------------------------------
"$bin" layout --kind lattice --dim 1 --nx 200 --out "$work/lat.csv" >/dev/null || bad "layout lat"
"$bin" layout --kind random --dim 1 --nx 200 --eps 0.4 --out "$work/rnd.csv" >/dev/null ||
    bad "layout rnd"
"$bin" layout --kind lattice --dim 1 --nx 100 --out "$work/l.csv" >/dev/null || bad "layout 1D"
# The same lattice moved by 0.25 inside the box [0, 2), written as VTU by the converter.
{
    echo "# box 0:2"
    echo "x"
    for i in $(seq 0 99); do awk -v i="$i" 'BEGIN { printf "%.17g\n", (i + 0.5) / 100 + 0.25 }'; done
} >"$work/shift.csv"
"$bin" layout --in "$work/shift.csv" --out "$work/shift.vtu" >/dev/null || bad "convert to vtu"
for p in 1 2; do
    out=$("$bin" wasserstein "$work/l.csv" "$work/shift.vtu" --p "$p" --format json)
    d=$(echo "$out" | field distance)
    near "$d" 0.25 1e-14 && ok || bad "1D translate p=$p: $d, want 0.25"
    s=$(OMP_NUM_THREADS=1 "$bin" wasserstein "$work/l.csv" "$work/shift.vtu" --p "$p" \
        --method sliced --format json | field distance)
    [ "$s" = "$d" ] && ok || bad "sliced $s != exact $d in 1D"
done

# Masses: A has mass 3 at 0 and 1 at 1, B all its mass at 0: W1 = 1/4 (the quarter at 1 moves).
printf '# box 0:2\nx,m\n0,3\n1,1\n' >"$work/m.csv"
printf '# box 0:2\nx,volume,rho\n0,1.5,2\n1,0.5,2\n' >"$work/vr.csv"
printf '# box 0:2\nx\n0\n1\n' >"$work/eq.csv"
printf '# box 0:2\nx\n0\n' >"$work/zero.csv"
for f in m:0.25 vr:0.25 eq:0.5; do
    d=$("$bin" wasserstein "$work/${f%%:*}.csv" "$work/zero.csv" --format json | field distance)
    near "$d" "${f##*:}" 1e-15 && ok || bad "masses ${f%%:*}: W1 $d, want ${f##*:}"
done
"$bin" wasserstein "$work/m.csv" "$work/zero.csv" | grep -q "masses mass column" && ok ||
    bad "table does not say where the masses came from"

# 2D: a packed set and its translate by s = (0.3, 0.4), |s| = 0.5.
"$bin" layout --kind random --dim 2 --nx 8 --eps 0.4 --out "$work/r.csv" >/dev/null || bad "layout 2D"
awk -F, '/^#/ { next } /^x/ { print "# box 0:2 0:2"; print "x,y"; next }
         { printf "%.17g,%.17g\n", $1 + 0.3, $2 + 0.4 }' "$work/r.csv" >"$work/rs.csv"
for p in 1 2; do
    out=$("$bin" wasserstein "$work/r.csv" "$work/rs.csv" --method sinkhorn --p "$p" --eps 1e-4 \
        --format json)
    d=$(echo "$out" | field distance)
    e=$(echo "$out" | field error)
    near "$d" 0.5 "$e" && ok || bad "2D sinkhorn p=$p: $d outside 0.5 +- $e"
    near "$e" 0 0.02 && ok || bad "2D sinkhorn p=$p: bound $e is not informative"
done
out=$("$bin" wasserstein "$work/r.csv" "$work/rs.csv" --p 2 --directions 4000 --format json)
d=$(echo "$out" | field distance)
e=$(echo "$out" | field error)
want=$(awk 'BEGIN { printf "%.17g", 0.5 / sqrt(2) }')
near "$d" "$want" "$(awk -v e="$e" 'BEGIN { print 4 * e }')" && ok ||
    bad "2D sliced p=2: $d vs $want, SE $e"

# Continuous densities: the 200-particle lattice of [0, 1) against the uniform density.
for pw in "1 0.00125" "2 $(awk 'BEGIN { printf "%.17g", 0.005 / sqrt(12) }')"; do
    set -- $pw
    out=$("$bin" wasserstein "$work/lat.csv" uniform --grid 20000 --p "$1" --format json)
    d=$(echo "$out" | field distance)
    g=$(echo "$out" | field grid_error)
    near "$d" "$2" "$g" && ok || bad "lattice vs uniform p=$1: $d, want $2 +- $g"
done
out=$("$bin" wasserstein "$work/lat.csv" uniform --grid 20000 --smooth cubic --hdx 2 --format json)
d=$(echo "$out" | field distance)
g=$(echo "$out" | field grid_error)
near "$d" 0 "$g" && ok || bad "smoothed periodic lattice vs uniform: $d > grid error $g"
raw=$("$bin" wasserstein "$work/rnd.csv" uniform --grid 20000 --format json | field distance)
smo=$("$bin" wasserstein "$work/rnd.csv" uniform --grid 20000 --smooth cubic --hdx 2 \
    --format json | field distance)
awk -v r="$raw" -v s="$smo" 'BEGIN { exit !(s < r / 3) }' && ok ||
    bad "smoothing a perturbed lattice: W1 $smo, unsmoothed $raw"

# ---- 2. threads ---------------------------------------------------------------------------
for m in sliced "sinkhorn --eps 1e-2"; do
    # shellcheck disable=SC2086
    a=$(OMP_NUM_THREADS=1 "$bin" wasserstein "$work/r.csv" "$work/rs.csv" --method $m \
        --format json | sed 's/"seconds".*//')
    # shellcheck disable=SC2086
    b=$(OMP_NUM_THREADS=2 "$bin" wasserstein "$work/r.csv" "$work/rs.csv" --method $m \
        --format json | sed 's/"seconds".*//')
    [ -n "$a" ] && [ "$a" = "$b" ] && ok || bad "$m differs between 1 and 2 threads"
done

# ---- 3. bad input -------------------------------------------------------------------------
# rejects "ARGS" PATTERN: exit 2, nothing on stdout, one stderr line matching PATTERN.
rejects() {
    local args=$1 pat=$2
    # shellcheck disable=SC2086
    "$bin" wasserstein $args >"$work/out" 2>"$work/err"
    local rc=$?
    [ $rc -eq 2 ] || { bad "'$args': exit $rc, want 2"; return; }
    [ -s "$work/out" ] && { bad "'$args': wrote to stdout"; return; }
    [ "$(wc -l <"$work/err")" -eq 1 ] || { bad "'$args': stderr is not one line"; return; }
    grep -q -- "$pat" "$work/err" && ok || bad "'$args': stderr lacks '$pat': $(cat "$work/err")"
}
rejects "$work/l.csv $work/shift.vtu --method nosuch" "exact,sliced,sinkhorn"
rejects "$work/l.csv $work/shift.vtu --p 3" "1..2"
rejects "$work/l.csv $work/shift.vtu --directions 1" "directions"
rejects "$work/l.csv $work/shift.vtu --eps 0" "eps"
rejects "$work/l.csv $work/shift.vtu --format xml" "table,json"
rejects "$work/r.csv $work/rs.csv --method exact" "allowed here: sliced, sinkhorn"
rejects "$work/l.csv $work/r.csv" "must share a dimension"
rejects "$work/l.csv" "two particle files"
rejects "$work/l.csv $work/none.csv" "none.csv"
rejects "$work/l.csv $work/l.txt" ".vtu, .csv"
printf '# dim 1\nx\n0.5\n' >"$work/nobox.csv"
rejects "$work/l.csv $work/nobox.csv" "box"
d=$("$bin" wasserstein "$work/l.csv" "$work/nobox.csv" --box 0:1 --format json | field distance)
near "$d" 0.25 1e-15 && ok || bad "--box: W1 of the lattice against its centre is $d, want 0.25"
rejects "$work/l.csv $work/nobox.csv --box 1:0" "box"
rejects "$work/l.csv uniform" "option --grid: needed"
rejects "$work/l.csv $work/l.csv --smooth cubic" "option --grid: needed"
rejects "$work/l.csv $work/l.csv --hdx 2" "only with --smooth"
rejects "$work/l.csv uniform --grid 10 --smooth nosuch" "allowed: cubic"
rejects "$work/l.csv uniform --grid 0" "1..100000000"
# Options the chosen method does not read are refused, naming the option and the method;
# l.csv is 1D (default exact), r.csv 2D (default sliced).
rejects "$work/r.csv $work/rs.csv --method sliced --eps 1e-2" "option --eps: only with --method sinkhorn; the method here is sliced,"
rejects "$work/r.csv $work/rs.csv --tol 1e-3" "option --tol: only with --method sinkhorn; the method here is sliced (the default)"
rejects "$work/r.csv $work/rs.csv --max-iter 10" "option --max-iter: only with --method sinkhorn"
rejects "$work/r.csv $work/rs.csv --method sinkhorn --directions 8" "option --directions: only with --method sliced; the method here is sinkhorn"
rejects "$work/r.csv $work/rs.csv --method sinkhorn --seed 3" "option --seed: only with --method sliced"
rejects "$work/l.csv $work/shift.vtu --directions 8" "option --directions: only with --method sliced; the method here is exact (the default)"
rejects "$work/l.csv $work/shift.vtu --method exact --eps 1e-2" "option --eps: only with --method sinkhorn; the method here is exact,"
rejects "$work/l.csv $work/shift.vtu --method sliced --seed 2" "option --seed: the particles are 1D"
rejects "$work/l.csv $work/shift.vtu --grid 10" "option --grid: only with --smooth KERNEL or B = uniform"

# ---- 4. costs ----------------------------------------------------------------------------
# What cannot fit in memory is refused before any work, naming --grid (or the files), the
# estimate and the limit; CONSPH_MEMORY_LIMIT lowers the cap. The case behind it: 2D against a
# uniform grid of 10000² cells, 8 to 11 GB on 1 or 2 threads, over the 4 GiB cap.
rejects "$work/r.csv uniform --grid 10000" "option --grid: 10000 cells per axis (1e+08 cells in 2D) need about .* GB.*the limit is"
CONSPH_MEMORY_LIMIT=1M rejects "$work/r.csv uniform --grid 300" "option --grid: 300 cells per axis .*the limit is 1.0 MB"
CONSPH_MEMORY_LIMIT=2K rejects "$work/r.csv $work/rs.csv" "r.csv and .*rs.csv: 64 and 64 points need about"
CONSPH_MEMORY_LIMIT=lots rejects "$work/r.csv $work/rs.csv" "CONSPH_MEMORY_LIMIT='lots' is not a size"
# Long work is announced on stderr with its estimate (Sinkhorn: per iteration and at the cap),
# stdout unchanged: 1600 against 1024 points.
"$bin" layout --kind random --dim 2 --nx 40 --eps 0.4 --out "$work/r40.csv" >/dev/null || bad "layout 40"
"$bin" layout --kind random --dim 2 --nx 32 --eps 0.4 --out "$work/r32.csv" >/dev/null || bad "layout 32"
OMP_NUM_THREADS=1 "$bin" wasserstein "$work/r40.csv" "$work/r32.csv" --method sinkhorn --max-iter 1 \
    --format json >"$work/out" 2>"$work/err"
grep -q '^consph wasserstein: estimate (rough, 1 thread): memory .*, [0-9.e+-]* s per Sinkhorn iteration ([0-9]* s at --max-iter 1); progress is shown on a terminal$' "$work/err" &&
    ok || bad "no estimate before a long Sinkhorn: $(cat "$work/err")"
grep -q '"distance"' "$work/out" && ok || bad "the estimated run wrote no result"

echo "cli_wasserstein: $pass passed, $fail failed"
[ $fail -eq 0 ]
