#!/usr/bin/env bash
# Study kind `run` (docs/studies.md): a tiny Taylor-Green sweep of e-c and ewcsph through the
# solver, its report and files; bad run studies are refused with file:line and exit 2; the
# 001 run studies (Tables 8, 9, Fig. 20) and the demo study are valid; x = radius and x = time
# (momentum histories) on a few hundred particles. cli_studies.sh leaves the
# run studies out: their quick runs take minutes.
# Usage: bash cli_run_study.sh PATH-TO-CONSPH SOURCE-DIR
set -u
consph=$1 src=$2
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}

cat >"$tmp/tiny.study" <<'STUDY'
study = tiny
title = tiny Taylor-Green sweep
[figure conv]
kind = run
problem = taylor-green
layout = lattice
c0 = 80
nx = 12,16,24
tf = 0.02
dt_rule = finest
tr_ref = EWCSPH
[series E-C]
scheme = e-c
paper.order_u = 1.94
[series EWCSPH]
scheme = ewcsph
paper.order_u = 1.57
STUDY
"$consph" study "$tmp/tiny.study" --quick --out "$tmp/out" >"$tmp/log" 2>&1
rc=$?
[ $rc = 0 ] || { cat "$tmp/log"; bad "tiny run study: exit $rc"; }
d=$tmp/out/tiny
for f in README.md conv.csv conv.md conv.dat conv.gp; do
  [ -s "$d/$f" ] || bad "missing $f"
done
ls "$d" | grep -q '\.tmp\.' && bad "temporary file left behind"
head -1 "$d/conv.csv" | grep -q '^series,scheme,c0,nx,n,steps,t,dt,h,l1_u,l1_p,linf_u,linf_p,ft_over_fmax,seconds,pairs,regularisations,status$' || bad "conv.csv header"
[ "$(tail -n +2 "$d/conv.csv" | grep -c ',ok$')" = 6 ] || bad "conv.csv: not 6 finished runs"
# The report has both fitted orders with their standard errors for each series, the paper's
# order beside ours, and T_r relative to the named series.
for s in E-C EWCSPH; do
  row=$(grep "^| $s | " "$d/conv.md")
  [ "$(echo "$row" | grep -o '[-0-9.]* ± [0-9.]*' | wc -l)" = 2 ] || bad "$s: orders of u and p with standard errors missing: $row"
done
grep -q '^| E-C | e-c | 80 | .* | 1.94 |' "$d/conv.md" || bad "paper order of E-C not beside ours"
awk -F'|' '$2 == " EWCSPH " { exit !($15 + 0 == 1) }' "$d/conv.md" || bad "T_r of the reference series is not 1"
# E-C converges in velocity (second order in 001; above 1.5 on this tiny sweep).
order=$(awk -F'|' '$2 == " E-C " { split($7, a, " "); print a[1] }' "$d/conv.md")
awk -v o="$order" 'BEGIN { exit !(o > 1.5) }' || bad "E-C velocity order $order, want > 1.5"
# dt_rule = finest: every run steps with 0.3 h/(U + c_o) of the finest resolution, h = 1.2/24.
awk -F, 'NR > 1 { d = $8 / (0.3 * 0.05 / 81) - 1; if (d > 1e-6 || d < -1e-6) bad = 1 } END { exit bad }' "$d/conv.csv" || bad "dt is not the finest resolution's"
# On the lattice the Eulerian schemes exert no net force (001 Table 9: about 1e-14).
awk -F, 'NR > 1 { f = $14 < 0 ? -$14 : $14; if (!(f < 1e-10)) bad = 1 } END { exit bad }' "$d/conv.csv" || bad "F_T/F_max of e-c/ewcsph on the lattice not at round-off"

# One fixed time step as 001 Table 7 (dt, l1 = mean): every run takes that Δt and one step, T_r
# of the reference is 1, and the one-step pressure error of EWCSPH is 001's 2.10e-5 (it does
# not depend on the resolution; eq. 26 without its factor Δt).
cat >"$tmp/one.study" <<'STUDY'
study = one
[figure t7]
kind = run
c0 = 10
nx = 12,16
steps = 1
dt = 6.54e-5
l1 = mean
tr_ref = EWCSPH
[series E-C]
scheme = e-c
[series EWCSPH]
scheme = ewcsph
STUDY
"$consph" study "$tmp/one.study" --quick --out "$tmp/one" >"$tmp/log" 2>&1
rc=$?
[ $rc = 0 ] || { cat "$tmp/log"; bad "one-step study: exit $rc"; }
c=$tmp/one/one/t7.csv
awk -F, 'NR > 1 { if ($6 != 1 || $8 != 6.54e-05 || $18 != "ok") bad = 1; n++ } END { exit bad || n != 4 }' "$c" || bad "one-step study: not 4 runs of one step of 6.54e-5: $(cat "$c")"
awk -F'|' '$2 == " EWCSPH " { exit !($15 + 0 == 1) }' "$tmp/one/one/t7.md" || bad "one-step study: T_r of the reference is not 1"
awk -F, '$1 == "EWCSPH" { if (!($11 > 1.9e-5 && $11 < 2.3e-5)) bad = 1 } END { exit bad }' "$c" || bad "one-step EWCSPH L1(p) not 2.1e-5: $(cat "$c")"
grep -q 'Δt = 6.54e-05 fixed' "$tmp/one/one/t7.md" || bad "one-step study: fixed Δt not reported"

# A problem without an exact solution (shear layer): the study finishes, the outcome table puts
# ours beside paper.outcome, and no figure is attempted (no errors to plot).
cat >"$tmp/kh.study" <<'STUDY'
study = kh
[figure shear]
kind = run
problem = shear-layer
nx = 12
steps = 5
[series E-C]
scheme = e-c
paper.outcome = completes
STUDY
"$consph" study "$tmp/kh.study" --quick --out "$tmp/kh" >"$tmp/log" 2>&1
rc=$?
[ $rc = 0 ] || { cat "$tmp/log"; bad "shear-layer study: exit $rc"; }
grep -q '^| E-C | completed (t = [0-9.e-]*) | completes |$' "$tmp/kh/kh/shear.md" || bad "shear-layer study: no outcome row"
grep -q '^No figure' "$tmp/kh/kh/shear.md" || bad "shear-layer study: report does not say why there is no figure"
[ -e "$tmp/kh/kh/shear.gp" ] && bad "shear-layer study: a plot of no points"
grep -q ', ν 0.0001,' "$tmp/kh/kh/shear.md" || bad "shear-layer study: the problem's ν is not used"

# x = radius (001 Figs. 15-16): u_φ(r) of every particle at the end, beside eq. 37's u_φ = 5r
# inside r = 0.2; after 5 steps L-IPST-C has barely moved from it.
cat >"$tmp/gc.study" <<'STUDY'
study = gc
[figure prof]
kind = run
x = radius
problem = gresho-chan
nx = 16
steps = 5
[series L-IPST-C]
scheme = l-ipst-c
STUDY
"$consph" study "$tmp/gc.study" --quick --out "$tmp/gc" >"$tmp/log" 2>&1
rc=$?
[ $rc = 0 ] || { cat "$tmp/log"; bad "radius study: exit $rc"; }
p=$tmp/gc/gc/prof-profile.dat
awk '!/^#/ && NF == 3 { n++; d = $2 - $3; if (d < 0) d = -d; if (d > m) m = d
     if ($1 < 0.2 && ($3 - 5 * $1 > 1e-7 || 5 * $1 - $3 > 1e-7)) bad = 1 }
     END { exit bad || n != 256 || !(m < 0.05) }' "$p" || bad "radius study: not 256 particles on eq. 37's profile: $(head -3 "$p")"
grep -q "prof-profile.dat' index 0 using 1:2" "$tmp/gc/gc/prof.gp" || bad "radius study: no u_φ(r) plot"

# x = time (001 Figs. 15-17): the momentum history of each series' finest run, a row per step
# (log_every 1) from t = 0 with finite values; a series that diverges (E-C with a time step 10x
# too large) stops at its last finite step; the report's drifts are those of the data.
cat >"$tmp/gm.study" <<'STUDY'
study = gm
[figure mom]
kind = run
x = time
y = momentum_x, angular_momentum
problem = gresho-chan
nx = 16
steps = 20
log_every = 1
[series L-IPST-C]
scheme = l-ipst-c
paper.outcome = completes
[series E-C]
scheme = e-c
dt = 0.02
STUDY
"$consph" study "$tmp/gm.study" --quick --out "$tmp/gm" >"$tmp/log" 2>&1
rc=$?
[ $rc = 0 ] || { cat "$tmp/log"; bad "time study: exit $rc"; }
g=$tmp/gm/gm
h=$g/mom-history.dat
[ -s "$h" ] || bad "time study: no mom-history.dat"
# rows and the time reached per block, every value a finite number, t increasing from 0
awk '/^# / { b++; next } NF == 0 { next }
     { if (NF != 4) bad = 1
       for (i = 1; i <= 4; i++) if ($i !~ /^-?[0-9.]+(e[-+][0-9]+)?$/) bad = 1
       if (n[b] == 0 && $1 != 0) bad = 1
       if (n[b] > 0 && !($1 > t)) bad = 1
       t = $1; n[b]++ }
     END { if (bad || b != 2) exit 1; print n[1], n[2] }' "$h" >"$tmp/rows" || bad "time study: history not 2 blocks of finite rows from t = 0 with t increasing: $(head -3 "$h")"
read -r n1 n2 <"$tmp/rows"
s1=$(awk -F, '$1 == "L-IPST-C" { print $6 }' "$g/mom.csv")
s2=$(awk -F, '$1 == "E-C" && $18 == "diverged" { print $6 }' "$g/mom.csv")
[ "$n1" = 21 ] && [ "$s1" = 20 ] || bad "time study: L-IPST-C has $n1 history rows for $s1 steps, want 21 for 20"
# the diverging step leaves no row: a row per finite step 0 .. steps - 1
[ -n "$s2" ] && [ "$n2" = "$s2" ] && [ "$n2" -lt 21 ] || bad "time study: E-C did not diverge with a row per finite step ($n2 rows, $s2 steps)"
grep -q "mom-history.dat' index 0 using 1:2" "$g/mom.gp" && grep -q "mom-history.dat' index 1 using 1:4" "$g/mom.gp" || bad "time study: not a panel of M_x and one of L"
# max |L(t) - L(0)| of L-IPST-C in the report is that of the data (to the 4 digits printed)
dl=$(awk '/^# / { b++; next } b == 1 && NF == 4 { if (n++ == 0) l0 = $4; d = $4 - l0; if (d < 0) d = -d; if (d > m) m = d } END { printf "%.3e", m }' "$h")
grep -q "^| L-IPST-C | 20 | [0-9.]* | [0-9.e+-]* | [0-9.]* | $dl | [0-9.e+-]* | completes |$" "$g/mom.md" || bad "time study: no momentum row of L-IPST-C with max |ΔL| $dl: $(grep '^| L-IPST-C | 20' "$g/mom.md")"

# Bad run studies: exit 2, one line naming file and line, nothing written.
refuse() { # refuse DESCRIPTION LINE-NUMBER EXPECTED-TEXT STUDY-TEXT
  printf '%s\n' "$4" >"$tmp/broken.study"
  "$consph" study "$tmp/broken.study" --quick --out "$tmp/o2" >/dev/null 2>"$tmp/err"; local rc=$?
  [ $rc = 2 ] || bad "$1: exit $rc"
  grep -q "broken.study:$2.*$3" "$tmp/err" || bad "$1: message $(cat "$tmp/err")"
  [ "$(wc -l <"$tmp/err")" = 1 ] || bad "$1: more than one line"
  [ -e "$tmp/o2" ] && bad "$1: a rejected study created output"
}
head='study = broken
[figure a]
kind = run
nx = 12,16'
refuse "misspelt key" 5 "unknown key 'schme'" "$head
schme = e-c"
refuse "unknown scheme" 5 "scheme 'e-x' is unknown (allowed: .*ewcsph" "$head
scheme = e-x"
refuse "unknown dt_rule" 6 "dt_rule.*allowed: finest, own" "$head
scheme = e-c
dt_rule = coarsest"
refuse "tr_ref naming no series" 6 "no series 'X'" "$head
scheme = e-c
tr_ref = X"
refuse "negative dt" 6 "key 'dt': dt = -1 is out of range (allowed: \\[0," "$head
scheme = e-c
dt = -1"
refuse "unknown l1" 6 "l1.*allowed: integral, mean" "$head
scheme = e-c
l1 = sum"
refuse "unknown y" 7 "key 'y'.*unknown value 'energy'; allowed: momentum_x, momentum_y, angular_momentum" "$head
scheme = e-c
x = time
y = momentum_x, energy"
refuse "y without x = time" 6 "key 'y'.*only with x = time" "$head
scheme = e-c
y = momentum_x"
refuse "decreasing nx" 4 "whole and increasing" "study = broken
[figure a]
kind = run
nx = 16,12
scheme = e-c"

# The shipped run studies are valid and estimate their cost without running.
for s in 001-table7 001-table8 001-table9 001-fig20 001-gresho 001-shear-layer demo-tgv beltrami-3d; do
  CONSPH_STUDIES=$src/studies "$consph" study "$s" --estimate >"$tmp/est" 2>&1 || bad "$s --estimate: $(cat "$tmp/est")"
  grep -q '^estimated run time: [0-9]' "$tmp/est" || bad "$s: no estimate"
done
[ $fail = 0 ] && echo "cli_run_study: ok"
exit $fail
