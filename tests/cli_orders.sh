#!/usr/bin/env bash
# Fitted orders in `consph approx` and study reports: a non-finite error is an error naming the
# series and the resolution (exit 3), never a row quietly left out of the fit; rows without
# neighbours give "n/a" and a warning instead of "-0.000 +- 0.000"; two resolutions give no
# standard error ("n/a"), never "+- 0.000".
set -u
consph=$1 fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# A periodic 8x8 lattice with given volumes, and a copy where one volume is 1e308: the sums
# overflow and that file's errors are not finite.
"$consph" layout --kind lattice --dim 2 --nx 8 --out "$tmp/a.csv" >/dev/null || bad "layout"
awk -F, -v OFS=, '/^#/ || /^x/ { print; next } { if (++k == 3) $NF = "1e308"; print }' \
  "$tmp/a.csv" >"$tmp/big.csv"
grep -q '^x,y,volume$' "$tmp/a.csv" || bad "layout CSV has no volume column"

for fmt in table csv json; do
  "$consph" approx --op grad --form f2 --particles "$tmp/a.csv,$tmp/big.csv" --format $fmt \
    >"$tmp/out" 2>"$tmp/err"
  rc=$?
  [ $rc = 3 ] || bad "$fmt: non-finite error: exit $rc, expected 3"
  grep -q 'error: grad f2 none, .*big.csv: nx = 8: the l2 error is .*nan' "$tmp/err" ||
    bad "$fmt: the non-finite row is not named: $(cat "$tmp/err")"
done
grep -q '"l2": null' "$tmp/out" || bad "json: non-finite l2 not written as null"
"$consph" approx --op grad --form f2 --particles "$tmp/a.csv" >/dev/null 2>&1 || bad "finite file: exit $?"

# No neighbours within the support at any resolution: a warning and n/a, not -0.000.
"$consph" approx --op grad --nx 10,20,40 --hdx 0.05 >"$tmp/out" 2>"$tmp/err" || bad "hdx 0.05: exit $?"
grep -q 'warning: grad f4 none: nx = 10: no particle has a neighbour' "$tmp/err" ||
  bad "hdx 0.05: no warning: $(cat "$tmp/err")"
grep -q '^order (l1): n/a (no neighbours at nx = 10)$' "$tmp/out" || bad "hdx 0.05: order line"
grep -q '^order.*[0-9]\.[0-9]' "$tmp/out" && bad "hdx 0.05 prints an order: $(grep order "$tmp/out")"

# Two resolutions: an order without a standard error.
"$consph" approx --op grad --nx 10,20 >"$tmp/out" 2>&1 || bad "two resolutions: exit $?"
grep -q '^order (l1): 1\.[0-9]* +- n/a$' "$tmp/out" || bad "two resolutions: $(grep order "$tmp/out")"
grep -q '+- 0\.000' "$tmp/out" && bad "two resolutions print +- 0.000"
"$consph" approx --op grad --nx 10,20 --format json >"$tmp/out" 2>&1 || bad "json: exit $?"
grep -q '"stderr": null' "$tmp/out" || bad "json: two resolutions: stderr not null"

# The study engine: the same verdicts in its markdown, and exit 3 naming figure, series, file.
mkdir -p "$tmp/s"
cat >"$tmp/s/orders.study" <<'STUDY'
study = orders
title = Order verdicts
paper = none

[figure g]
title = f2 gradient with given volumes
op = grad
form = f2
volume = given
nx = 8,16

[series f2]
corr = none

[figure lonely]
title = no neighbours
op = grad
hdx = 0.05
nx = 8,16,24

[series f4]
corr = none
STUDY
"$consph" study "$tmp/s/orders.study" --quick --out "$tmp/o1" >"$tmp/log" 2>&1 || bad "study: exit $?: $(cat "$tmp/log")"
grep -q '^| f2 | 1\.[0-9]* ± n/a |' "$tmp/o1/orders/g.md" || bad "study: two resolutions: $(grep '^| f2 ' "$tmp/o1/orders/g.md" | head -1)"
grep -q '^| f4 | n/a (no neighbours at nx = 8) |' "$tmp/o1/orders/lonely.md" ||
  bad "study: no neighbours: $(grep '^| f4 ' "$tmp/o1/orders/lonely.md" | head -1)"
grep -q "warning: series 'f4': nx = 8: no particle has a neighbour" "$tmp/log" || bad "study: no warning"
"$consph" study "$tmp/s/orders.study" --quick --out "$tmp/o2" --particles "$tmp/a.csv,$tmp/big.csv" \
  >"$tmp/log" 2>"$tmp/err"
rc=$?
[ $rc = 3 ] || bad "study: non-finite error: exit $rc, expected 3"
grep -q "figure 'g', series 'f2': nx = 8: the l2 error is .*nan.*big.csv" "$tmp/err" ||
  bad "study: the non-finite row is not named: $(cat "$tmp/err")"
exit $fail
