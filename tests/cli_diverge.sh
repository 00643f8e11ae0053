#!/usr/bin/env bash
# A run that leaves the weakly-compressible model stops with exit 3 and a message naming the
# step, t, the particle, its position, the quantity, its value and the bound (docs/schemes.md,
# "Validity of a run"): every scheme with an unstable Δt, each validity check on its own, the
# verdict independent of the thread count; a Δt above the stability bound is warned about; a
# run study leaves a stopped run out of the fit and says why.
# Usage: bash cli_diverge.sh PATH-TO-CONSPH
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}

num='-?[0-9.]+(e[-+]?[0-9]+)?'
# every scheme, as the registry lists them (consph run --help, --scheme's allowed names)
schemes=$("$consph" run --help 2>&1 | sed -n 's/^ *--scheme S .*(\([a-z0-9,+-]*\); default .*/\1/p' | tr , ' ')
[ -n "$schemes" ] || bad "no scheme list in consph run --help"
# expect_stop WHAT QUANTITY-REGEX ARGS...: exit 3, nothing on stdout, the message's parts
expect_stop() {
    local what=$1 quantity=$2
    shift 2
    "$consph" run "$@" >"$tmp/out" 2>"$tmp/err"
    local rc=$?
    [ $rc -eq 3 ] || { bad "$what: exit $rc, expected 3: $(tail -1 "$tmp/err")"; return; }
    [ -s "$tmp/out" ] && bad "$what: a result on stdout: $(head -1 "$tmp/out")"
    grep -Eq "^consph run: diverged at step [0-9]+ \(t = $num\): particle [0-9]+ at \($num, $num\) .*$quantity" "$tmp/err" ||
        bad "$what: message without step, t, particle, position or '$quantity': $(cat "$tmp/err")"
}

# --- every scheme, a Δt 2400 times its bound: stopped at step 1 by the Mach number (l-rr-c's
# remeshing averages the velocities, not the density) ---
for s in $schemes; do
    q="Mach number \|u\|/c_o = $num, above the bound 1 "
    [ $s = l-rr-c ] && q="density \|rhof/rho_o - 1\| = $num, above the bound 0.3 "
    expect_stop "$s dt 10" "$q" taylor-green --scheme "$s" --nx 8 --dt 10 --steps 5
    grep -q "diverged at step 1 (t = 10)" "$tmp/err" || bad "$s dt 10: not at step 1: $(cat "$tmp/err")"
    grep -q "warning: dt = 10 is above the acoustic stability bound 0.3 h/(U + c_o) = " "$tmp/err" ||
        bad "$s dt 10: no warning naming the bound: $(cat "$tmp/err")"
done
# the viscous bound: ν = 10 makes the default Δt 29 times 0.125 h²/ν; the run goes on
"$consph" run taylor-green --scheme e-c --nx 16 --nu 10 --steps 1 >/dev/null 2>"$tmp/err" ||
    bad "nu 10, one step: exit $?: $(cat "$tmp/err")"
grep -q "warning: dt = 0.00204545 is above the viscous stability bound 0.125 h^2/nu = 7.03125e-05 (h = 0.075, nu = 10)" "$tmp/err" ||
    bad "nu 10: no warning naming the viscous bound: $(cat "$tmp/err")"
# the default Δt is at the acoustic bound, not above it: no warning
"$consph" run taylor-green --scheme e-c --nx 16 --steps 1 >/dev/null 2>"$tmp/err" || bad "default: exit $?"
[ -s "$tmp/err" ] && bad "default dt: a warning: $(cat "$tmp/err")"
# the case that prompted this check: tvf with dt 1e6 ended at (0, 0) with KE 6e22 and exit 0
expect_stop "tvf dt 1e6" "Mach number" taylor-green --scheme tvf --nx 8 --dt 1e6 --steps 5

# --- kinetic energy: wcsph at 4.4 times its default Δt gained energy step by step (1e142 at
# t = 2); it stops when KE exceeds 1.1 KE(0) (0.25 for this Taylor-Green) ---
expect_stop "wcsph dt 0.01" "kinetic energy $num exceeds its initial 0.25.* by $num, above the bound 0.1 " \
    taylor-green --scheme wcsph --nx 16 --dt 0.01 --tf 2
grep -q "at step 13 (t = 0.13)" "$tmp/err" || bad "wcsph dt 0.01: not stopped at step 13: $(cat "$tmp/err")"

# --- compression: Gresho-Chan's absolute pressure (up to 5.78) at c_o = 3 compresses ϱ by 64 %,
# above the bound 0.3, whether ϱ is evolved (e-c) or follows from the evolved p (pe-ipst-c,
# eq. 31); edac's p has no EOS (a uniform offset moves nothing) and is not bounded ---
for s in e-c pe-ipst-c; do
    expect_stop "$s density" "density \|rhof/rho_o - 1\| = 0.64[0-9]*, above the bound 0.3 " \
        gresho-chan --scheme $s --nx 10 --c0 3 --steps 3
done
"$consph" run gresho-chan --scheme edac --nx 10 --c0 3 --steps 3 >/dev/null 2>"$tmp/err" ||
    bad "gresho-chan edac at c_o 3: $(cat "$tmp/err")"
# at c_o = 10 (the default) the same runs are valid
for s in e-c pe-ipst-c; do
    "$consph" run gresho-chan --scheme "$s" --nx 10 --steps 3 >/dev/null 2>"$tmp/err" ||
        bad "gresho-chan $s at c_o 10: $(cat "$tmp/err")"
    [ -s "$tmp/err" ] && bad "gresho-chan $s at c_o 10: a warning: $(cat "$tmp/err")"
done

# --- the same verdict, particle and numbers on 1 and 2 threads (n = 4096 threads the
# integrator's loops) ---
for t in 1 2; do
    "$consph" run taylor-green --scheme wcsph --nx 64 --dt 0.004 --steps 40 --threads $t \
        >/dev/null 2>"$tmp/err$t"
done
grep -q "diverged at step" "$tmp/err1" || bad "nx 64: no stop: $(cat "$tmp/err1")"
cmp -s "$tmp/err1" "$tmp/err2" || bad "1 and 2 threads stop differently: $(cat "$tmp/err1" "$tmp/err2")"

# --- a run study: the stopped runs are marked, left out of the fit, and the report says why ---
cat >"$tmp/dv.study" <<'STUDY'
study = dv
[figure conv]
kind = run
problem = taylor-green
c0 = 10
nx = 6,8,12,16
tf = 0.3
dt = 0.01
[series WCSPH]
scheme = wcsph
[series WCSPH-fine]
scheme = wcsph
nx = 12,16
STUDY
"$consph" study "$tmp/dv.study" --quick --out "$tmp/st" >"$tmp/log" 2>&1
rc=$?
[ $rc = 0 ] || bad "study: exit $rc: $(cat "$tmp/log")"
d=$tmp/st/dv
grep -q "warning: dt = 0.01 is above the acoustic stability bound 0.3 h/(U + c_o) = 0.00545455 (h = 0.2," "$tmp/log" ||
    bad "study: no warning naming the bound of nx 6: $(cat "$tmp/log")"
[ "$(awk -F, '$1 == "WCSPH" { printf "%s ", $NF }' "$d/conv.csv")" = "ok ok diverged diverged " ] ||
    bad "study: rows not ok, ok, diverged, diverged: $(cat "$d/conv.csv")"
# the order of the two runs that completed, fitted on those alone (two points: the slope)
row=$(grep '^| WCSPH | ' "$d/conv.md")
ou=$(awk -F, '$1 == "WCSPH" && $4 <= 8 { x[++n] = log($4); y[n] = log($10) }
     END { printf "%.2f", -(y[2] - y[1]) / (x[2] - x[1]) }' "$d/conv.csv")
echo "$row" | grep -q "| $ou" || bad "study: L1(u) order not that of nx 6 and 8 ($ou): $row"
for nx in 12 16; do
    grep -q "^- WCSPH, nx $nx diverged, left out of the fit: diverged at step [0-9]* .* kinetic energy" "$d/conv.md" ||
        bad "study: nx $nx not said left out with its reason: $(grep '^- ' "$d/conv.md")"
done
grep -q '^| WCSPH-fine | .*n/a (0 of 2 runs completed)' "$d/conv.md" ||
    bad "study: a series with no completed run is not said so: $(grep '^| WCSPH-fine' "$d/conv.md")"

[ $fail -eq 0 ] && echo "cli_diverge: ok"
exit $fail
