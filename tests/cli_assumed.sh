#!/usr/bin/env bash
# A particle file that does not give its periodicity is read as non-periodic: `approx
# --particles` and `study --particles` say so on stderr (one line from one shared place), with
# the box used and the options that set both; nothing is said when the file or an option did.
set -u
consph=$1 src=$2 fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$consph" layout --kind lattice --dim 2 --nx 8 --out "$tmp/a.csv" >/dev/null || bad "layout"
grep -v '^# periodic' "$tmp/a.csv" >"$tmp/np.csv"
note='note: .*np.csv gives no periodicity .*: using box \[0, 1\]x\[0, 1\] (from the file), periodic none (assumed); --box x0:x1,... and --periodic yes|no|AXES set them$'
for fmt in table csv; do
  "$consph" approx --op grad --particles "$tmp/np.csv" --format $fmt >/dev/null 2>"$tmp/err" || bad "approx $fmt: exit $?"
  [ "$(grep -c 'gives no' "$tmp/err")" = 1 ] && grep -q "^consph approx: $note" "$tmp/err" ||
    bad "approx $fmt: no note: $(cat "$tmp/err")"
done
"$consph" approx --op grad --particles "$tmp/np.csv" --periodic no --format csv >/dev/null 2>"$tmp/err"
grep -q 'gives no' "$tmp/err" && bad "approx --periodic no: note printed"
"$consph" approx --op grad --particles "$tmp/a.csv" --format csv >/dev/null 2>"$tmp/err"
grep -q 'gives no' "$tmp/err" && bad "approx: file with '# periodic': note printed"
"$consph" study "$src/tests/data/engine.study" --quick --out "$tmp/out" \
  --particles "$tmp/np.csv" >/dev/null 2>"$tmp/err"
grep -q "^consph study: $note" "$tmp/err" || bad "study: no note: $(head -3 "$tmp/err")"
exit $fail
