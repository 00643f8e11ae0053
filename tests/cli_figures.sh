#!/usr/bin/env bash
# Figures say what ran, and the help lists what exists:
# - `consph --help` and `consph run --help` name every problem and every scheme of the registries
#   (read here from src/problems/problems.c and src/schemes/registry.c, not from the binary);
# - a study figure's gnuplot script (run, approx and heat kinds) has a title line with the t_f
#   and the resolutions that ran, a colour and a marker of its own for every series, the paper's
#   values as points with a key entry naming their series, axes cropped to what is drawn, and
#   (heat) slope-1 and slope-2 guides; a title with a quote stays quoted;
# - the vorticity image of the shear layer has axis and colour-bar labels.
# Usage: bash cli_figures.sh PATH-TO-CONSPH SOURCE-DIR
set -u
consph=$1 src=$2
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}

# ---- 1. help lists every problem and scheme of the registries ----
registry() { sed -n "s/^ *X($1_\([a-z0-9_]*\)).*/\1/p" "$2" | tr _ -; }
schemes=$(registry scheme "$src/src/schemes/registry.c")
problems=$(registry problem "$src/src/problems/problems.c")
[ "$(echo "$schemes" | wc -w)" -ge 10 ] && [ "$(echo "$problems" | wc -w)" -ge 4 ] ||
    bad "could not read the registries: schemes '$schemes', problems '$problems'"
"$consph" --help >"$tmp/help" 2>&1 || bad "consph --help failed"
"$consph" run --help >"$tmp/runhelp" 2>&1 || bad "consph run --help failed"
for name in $schemes $problems heat; do
  grep -qE "(^|[ ,(])$name([ ,;)]|$)" "$tmp/help" || bad "consph --help does not list '$name'"
  grep -qE "(^|[ ,(])$name([ ,;)]|$)" "$tmp/runhelp" || bad "consph run --help does not list '$name'"
done

# The series lines of a script: their markers and colours differ.
distinct() { # FILE PATTERN WHAT
  local lines pts cols
  lines=$(grep -E "$2" "$1")
  [ -n "$lines" ] || { bad "$1: no series lines"; return; }
  pts=$(echo "$lines" | grep -o ' pt [0-9]*' | sort | uniq -d)
  cols=$(echo "$lines" | grep -o "lc rgb '#[0-9a-f]*'" | sort | uniq -d)
  [ "$(echo "$lines" | grep -c ' pt [0-9]')" = "$(echo "$lines" | wc -l)" ] || bad "$3: a series without its marker"
  [ -z "$pts" ] || bad "$3: markers repeat: $pts"
  [ -z "$cols" ] || bad "$3: colours repeat: $cols"
}

# ---- 2. a run figure ----
cat >"$tmp/tiny.study" <<'STUDY'
study = tiny
title = tiny Taylor-Green sweep
[figure conv]
title = Taylor-Green's vortex to t = 0.5
kind = run
problem = taylor-green
layout = lattice
c0 = 20
nx = 50,100
quick.nx = 10,14
tf = 0.5
quick.tf = 0.01
tr_ref = E-C
[series E-C]
scheme = e-c
paper.l1_u = 5.11e-05
[series EWCSPH]
scheme = ewcsph
paper.l1_u = 3.25e-05
paper.l1_p = 1.13e-02
STUDY
"$consph" study "$tmp/tiny.study" --quick --out "$tmp/out" >"$tmp/log" 2>&1 || bad "run study: $(cat "$tmp/log")"
gp=$tmp/out/tiny/conv.gp
grep -q "^set multiplot title 'Taylor-Green''s vortex to t = 0.5' \. \"\\\\n\" \. 'ran: t_f = 0.01, nx = 10, 14, c_o = 20 (quick; full study: t_f = 0.5, nx = 50, 100)'" "$gp" ||
    bad "run figure: the title does not say what ran: $(grep 'multiplot title' "$gp")"
distinct "$gp" "conv.dat' index [0-9]+ using 1:2" "run figure, velocity panel"
grep -q "\$paper2_0 with points .* title 'E-C: paper (nx 100)'" "$gp" || bad "run figure: E-C's paper point unlabelled"
grep -q "\$paper2_1 with points .* title 'EWCSPH: paper (nx 100)'" "$gp" || bad "run figure: EWCSPH's paper point unlabelled"
grep -q "\$paper3_1 with points" "$gp" && ! grep -q '$paper3_0' "$gp" || bad "run figure: pressure paper points wrong"
[ "$(grep -c '^set xrange \[' "$gp")" = 2 ] && [ "$(grep -c '^set yrange \[' "$gp")" = 2 ] ||
    bad "run figure: axes not cropped in both panels"
# the x range ends near the paper's nx 100, not at gnuplot's next decade
for hi in $(sed -n 's/^set xrange \[.*:\(.*\)\]$/\1/p' "$gp"); do
  awk -v hi="$hi" 'BEGIN { exit !(hi >= 100 && hi <= 130) }' || bad "run figure: x range ends at $hi"
done
if command -v gnuplot >/dev/null; then
  [ -s "$tmp/out/tiny/conv.svg" ] || bad "run figure: no SVG drawn"
fi

# ---- 3. an approx figure ----
cat >"$tmp/ops.study" <<'STUDY'
study = ops
title = gradient forms
[figure grad]
title = gradient on the lattice
op = grad
layout = lattice
nx = 50,100
quick.nx = 8,12
[series asym]
form = asym
paper.l1 = 1e-3
[series sym1]
form = sym1
[series sym2]
form = sym2
paper.l1 = 2e-3
STUDY
"$consph" study "$tmp/ops.study" --quick --out "$tmp/out" >"$tmp/log" 2>&1 || bad "approx study: $(cat "$tmp/log")"
gp=$tmp/out/ops/grad.gp
grep -q "^set title 'gradient on the lattice' \. \"\\\\n\" \. 'ran: nx = 8, 12 (2D, quick; full study: nx = 50, 100)'" "$gp" ||
    bad "approx figure: the title does not say what ran: $(grep '^set title' "$gp")"
distinct "$gp" "grad.dat' index [0-9]+ using 1:2" "approx figure"
grep -q "title 'asym: paper (nx 100)'" "$gp" && grep -q "title 'sym2: paper (nx 100)'" "$gp" ||
    bad "approx figure: paper points unlabelled"
grep -q '^set xtics (8, 12, 100)$' "$gp" || bad "approx figure: tics not at the resolutions: $(grep xtics "$gp")"

# ---- 4. a heat figure: slope guides ----
cat >"$tmp/heatfig.study" <<'STUDY'
study = heatfig
title = heat
kind = heat
walls = sin
tf = 0.002
nx = 20,40
quick.nx = 6,8,10
[figure h]
title = S3 vs S4
eps = 0
[series S3]
laplacian = s3
hdx = 2.0
[series S4]
laplacian = s4
hdx = 2.0
STUDY
"$consph" study "$tmp/heatfig.study" --quick --out "$tmp/out" >"$tmp/log" 2>&1 || bad "heat study: $(cat "$tmp/log")"
gp=$tmp/out/heatfig/h.gp
grep -q "^set multiplot title 'S3 vs S4' \. \"\\\\n\" \. 'ran: t_f = 0.002, nx = 6, 8, 10 (quick; full study: nx = 20, 40)'" "$gp" ||
    bad "heat figure: the title does not say what ran: $(grep multiplot "$gp")"
[ "$(grep -c "title 'slope 1 (first order)'" "$gp")" = 3 ] && [ "$(grep -c "title 'slope 2 (second order)'" "$gp")" = 3 ] ||
    bad "heat figure: no slope guides in every panel"
distinct "$gp" "h.dat' index [0-9]+ using 1:2" "heat figure"
grep -q "^set xtics ('1/5' 0.2, '1/7' 0.1428571429, '1/9' 0.1111111111)$" "$gp" || bad "heat figure: tics not at the resolutions: $(grep xtics "$gp")"

# ---- 5. the vorticity image ----
"$consph" run shear-layer --scheme e-c --nx 8 --steps 2 --out "$tmp/s" >"$tmp/log" 2>&1 || bad "shear layer: $(cat "$tmp/log")"
for l in xlabel ylabel cblabel; do
  grep -q "^set $l '" "$tmp/s/vorticity.gp" || bad "vorticity image has no $l"
done

[ $fail = 0 ] && echo "cli_figures: all checks passed"
exit $fail
