#!/usr/bin/env bash
# The study engine end to end on tests/data/engine.study, and its rejection of bad study files.
set -u
consph=$1 src=$2
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$consph" study "$src/tests/data/engine.study" --quick --out "$tmp/out" >"$tmp/log" 2>&1 || { cat "$tmp/log"; bad "engine study exit $?"; }
d=$tmp/out/engine
for f in README.md grad.csv grad.md grad.gp density.csv density.md m0.csv m0.md appc.csv appc.md; do
  [ -s "$d/$f" ] || bad "missing $f"
done
ls "$d" | grep -q '\.tmp\.' && bad "temporary file left behind"
# The CSV has the documented columns and one row per series and resolution.
head -1 "$d/grad.csv" | grep -q '^series,sweep,kernel,hdx,form,corr,layout,field,nx,n,h,nbr_mean,l1,l2,linf,mae,ft_over_fmax,seconds,fallbacks,bound$' || bad "grad.csv header"
[ "$(tail -n +2 "$d/grad.csv" | wc -l)" = 6 ] || bad "grad.csv rows"
# Bonet-corrected asym gradient: second order on perturbed particles (within 0.3).
order=$(grep '^| asym_bc ' "$d/grad.md" | cut -d'|' -f3 | awk '{print $1}')
awk -v o="$order" 'BEGIN{exit !(o > 1.7 && o < 2.3)}' || bad "asym_bc order $order not within 0.3 of 2"
grep -q '| asym_bc | .* | 2.0 |' "$d/grad.md" || bad "paper order not printed beside ours"
# The sweep over h/dx gives 3 rows per kernel, and the density error of quintic at h/dx=1.2 on the
# lattice is catalogue Z4's 5.62e-5.
[ "$(grep -c '^kernel=' "$d/density.csv")" = 6 ] || bad "density rows"
z4=$(awk -F, '$1=="kernel=quintic" && $2==1.2 {print $13}' "$d/density.csv")
awk -v e="$z4" 'BEGIN{exit !(e > 5.5e-5 && e < 5.75e-5)}' || bad "quintic h/dx=1.2 density error $z4, catalogue Z4 5.62e-5"
# App. C: our sums agree with the closed form to 1e-12.
awk -F, 'NR>1 { d=$3-$2; if (d<0) d=-d; e=$4-$2; if (e<0) e=-e; if (d>1e-12 || e>1e-12) exit 1 }' "$d/appc.csv" || bad "appc differs from closed form"
# Bad study files: exit 2, one line naming the file and line.
printf 'study = broken\n[figure a]\nnx = 10\nfrobnicate = 3\n' >"$tmp/broken.study"
"$consph" study "$tmp/broken.study" --quick --out "$tmp/o2" >/dev/null 2>"$tmp/err"; rc=$?
[ $rc = 2 ] || bad "unknown key: exit $rc"
grep -q "broken.study:4: unknown key 'frobnicate'" "$tmp/err" || bad "unknown key message: $(cat "$tmp/err")"
printf 'study = broken\n[figure a]\nnx = 10\nop = grad\nform = nosuch\n' >"$tmp/broken.study"
"$consph" study "$tmp/broken.study" --quick --out "$tmp/o2" >/dev/null 2>"$tmp/err"; rc=$?
[ $rc = 2 ] || bad "bad form: exit $rc"
grep -q "broken.study:5" "$tmp/err" || bad "bad form message lacks the line: $(cat "$tmp/err")"
[ -e "$tmp/o2" ] && bad "a rejected study created output"
"$consph" study no-such-study >/dev/null 2>&1; [ $? = 2 ] || bad "unknown study name"
# An output directory that cannot be created is refused before anything runs.
: >"$tmp/plainfile"
"$consph" study "$src/tests/data/engine.study" --quick --out "$tmp/plainfile/results" >/dev/null 2>"$tmp/err"; rc=$?
[ $rc = 2 ] || bad "unwritable --out: exit $rc"
grep -q "option --out: cannot write results under" "$tmp/err" || bad "unwritable --out message: $(cat "$tmp/err")"
[ $fail = 0 ] && echo "cli_study: 1 passed, 0 failed" || echo "cli_study: 0 passed, 1 failed"
exit $fail
