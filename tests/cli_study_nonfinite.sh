#!/usr/bin/env bash
# A study whose errors are not finite (particles of volume 1e300) exits 3 naming the figure, the
# series, the resolution and the file, before any drawing: the same with gnuplot, without it,
# and with a gnuplot that fails (it cannot draw a figure without a finite point, and its
# "could not draw" with exit 1 hid the verdict).
# Usage: bash cli_study_nonfinite.sh PATH-TO-CONSPH
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

"$consph" layout --kind lattice --dim 2 --nx 8 --out "$tmp/a.csv" >/dev/null || bad "layout"
awk -F, -v OFS=, '/^#/ || /^x/ { print; next } { $NF = "1e300"; print }' "$tmp/a.csv" >"$tmp/huge.csv"
mkdir -p "$tmp/s" "$tmp/nognuplot" "$tmp/failing"
cat >"$tmp/s/nf.study" <<'STUDY'
study = nf
[figure g]
op = grad
form = f2
volume = given
nx = 8
[series f2]
corr = none
STUDY
# a gnuplot that fails and says it was called
printf '#!/bin/sh\ntouch "%s/called"\nexit 1\n' "$tmp" >"$tmp/failing/gnuplot"
chmod +x "$tmp/failing/gnuplot"

k=0
for path in "$PATH" "$tmp/nognuplot" "$tmp/failing"; do
    k=$((k + 1))
    what="PATH $path"
    [ $k = 1 ] && what="installed gnuplot ($(command -v gnuplot || echo none))"
    PATH=$path "$consph" study "$tmp/s/nf.study" --quick --out "$tmp/o$k" --particles "$tmp/huge.csv" \
        >/dev/null 2>"$tmp/err"
    rc=$?
    [ $rc = 3 ] || bad "$what: exit $rc, expected 3: $(cat "$tmp/err")"
    grep -q "figure 'g', series 'f2': nx = 8: the l2 error is inf (a non-finite result) (file .*huge.csv)" "$tmp/err" ||
        bad "$what: figure, series, resolution or file not named: $(cat "$tmp/err")"
    grep -q "could not draw" "$tmp/err" && bad "$what: blamed on gnuplot: $(cat "$tmp/err")"
    ls -R "$tmp/o$k" 2>/dev/null | grep -q '\.tmp\.' && bad "$what: a temporary file left"
done
[ -e "$tmp/called" ] && bad "gnuplot was run on a figure with non-finite errors"

[ $fail -eq 0 ] && echo "cli_study_nonfinite: ok"
exit $fail
