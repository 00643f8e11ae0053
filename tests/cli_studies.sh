#!/usr/bin/env bash
# Every study in studies/ but the solver ones (kind = run) runs with --quick and writes its
# README.md and, per figure, a .csv and a .md; a few numbers of the quick runs are checked against
# the papers and docs/reference-values.md.
# Usage: bash cli_studies.sh PATH-TO-CONSPH SOURCE-DIR
set -u
consph=$1
src=$2
studies=$src/studies
[ -d "$studies" ] || { echo "cli_studies: no $studies"; exit 77; }
out=$(mktemp -d /tmp/cli_studies.XXXXXX)
trap 'rm -rf "$out"' EXIT
# The packing and operator loops open many short parallel regions; on a shared, oversubscribed
# machine spinning OpenMP threads make them 10x slower. Results do not depend on this setting.
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
# Generous per-study limit: a quick study is meant to take under a minute on 2 idle cores.
limit=${CONSPH_STUDY_LIMIT:-240}
pass=0
fail=0
ok() { pass=$((pass + 1)); }
bad() {
  echo "FAIL: $*"
  fail=$((fail + 1))
}

# Values of column NAME in the CSV rows whose first column is SERIES (one per line), optionally
# only where column KEY equals VALUE.
csv_col() { # csv_col FILE SERIES NAME [KEY VALUE]
  awk -F, -v s="$2" -v name="$3" -v key="${4:-}" -v val="${5:-}" '
    NR == 1 { for (i = 1; i <= NF; ++i) { if ($i == name) c = i; if ($i == key) k = i }; next }
    c && $1 == s && (key == "" || (k && $k == val)) { print $c }' "$1"
}
# Least-squares slope of -log(Y) against log(X) over the rows of SERIES: the order of convergence.
csv_order() { # csv_order FILE SERIES XNAME YNAME
  awk -F, -v s="$2" -v xn="$3" -v yn="$4" '
    NR == 1 { for (i = 1; i <= NF; ++i) { if ($i == xn) cx = i; if ($i == yn) cy = i }; next }
    cx && cy && $1 == s && $cy > 0 { x = log($cx); y = log($cy); n++; sx += x; sy += y; sxx += x*x; sxy += x*y }
    END { if (n < 2) { print "nan"; exit } printf "%.4f\n", -(n*sxy - sx*sy) / (n*sxx - sx*sx) }' "$1"
}
# True (exit 0) when the awk expression holds for the number v.
holds() { awk -v v="$1" "BEGIN { exit !($2) }"; }
check() { # check DESCRIPTION VALUE AWK-CONDITION-ON-v
  if [ -z "$2" ] || [ "$2" = nan ]; then
    bad "$1: no value"
  elif holds "$2" "$3"; then
    ok
  else
    bad "$1: got $2, want $3"
  fi
}
# Every value (at least one) satisfies the condition.
check_all() { # check_all DESCRIPTION "VALUES" AWK-CONDITION-ON-v
  [ -n "$2" ] || { bad "$1: no values"; return; }
  local v
  for v in $2; do check "$1" "$v" "$3"; done
}

# ---- every study runs and writes its files ----
listed=$(CONSPH_STUDIES=$studies "$consph" study --list 2>&1) || bad "study --list: $listed"
total_start=$(date +%s)
for file in "$studies"/*.study; do
  name=$(basename "$file" .study)
  echo "$listed" | grep -q "^$name " || bad "study --list does not name $name"
  # Solver studies (kind = run) take minutes even quick; cli_run_study.sh checks them.
  grep -q '^[[:space:]]*kind[[:space:]]*=[[:space:]]*run\b' "$file" && continue
  # The heat study's quick run costs minutes under the sanitizers; cli_heat and test_heat run
  # the heat code there, and the normal build runs this study here.
  if [ "${CONSPH_SANITIZED:-0}" = 1 ] && grep -q '^[[:space:]]*kind[[:space:]]*=[[:space:]]*heat\b' "$file"; then
    echo "  $name: skipped in the sanitizer build"
    continue
  fi
  t0=$(date +%s)
  if ! CONSPH_STUDIES=$studies timeout "$limit" "$consph" study "$name" --quick --out "$out" \
    >"$out/$name.log" 2>&1; then
    bad "study $name --quick failed or ran past ${limit}s:"
    tail -5 "$out/$name.log"
    continue
  fi
  echo "  $name: $(($(date +%s) - t0)) s"
  if [ -s "$out/$name/README.md" ]; then ok; else bad "$name: no README.md"; fi
  figs=$(sed -n 's/^[[:space:]]*\[figure[[:space:]]\{1,\}\([^]]*\)\].*/\1/p' "$file")
  [ -n "$figs" ] || bad "$name: no [figure] found in $file"
  for fig in $figs; do
    for ext in csv md; do
      if [ -s "$out/$name/$fig.$ext" ]; then ok; else bad "$name: no $fig.$ext"; fi
    done
    grep -q "^## $fig:" "$out/$name/README.md" || bad "$name: README.md lacks figure $fig"
  done
done
echo "  all studies: $(($(date +%s) - total_start)) s"

# ---- numbers of the quick runs ----
d=$out
have() { [ -f "$1" ] || { bad "missing ${1#"$out"/}"; return 1; }; }
# 001 Fig. 2 against the lattice sums of docs/reference-values.md: QS at h/Δs = 1.2 and WQ4 at 2.5.
f=$d/001-fig2/fig2.csv
if have "$f"; then
  v=$(csv_col "$f" QS linf sweep 1.2)
  check "001-fig2 QS h/Δs=1.2 |rho-1| vs lattice sum 5.62e-05" "$v" "v > 5.56e-5 && v < 5.68e-5"
  v=$(csv_col "$f" WQ4 linf sweep 2.5)
  check "001-fig2 WQ4 h/Δs=2.5 |rho-1| vs lattice sum 8.83e-05" "$v" "v > 8.74e-5 && v < 8.92e-5"
fi
# 001 Table 3 on packed particles: asym_bc and sym1_lc are second order (published 1.99);
# sym1 conserves the total force to round-off (published -2.53e-11).
f=$d/001-table3/table3.csv
if have "$f"; then
  check "001-table3 asym_bc order (PP)" "$(csv_order "$f" asym_bc nx l1)" "v > 1.7 && v < 2.3"
  check "001-table3 sym1_lc order (PP)" "$(csv_order "$f" sym1_lc nx l1)" "v > 1.7 && v < 2.3"
  check_all "001-table3 sym1 F_T/F_max (PP)" "$(csv_col "$f" sym1 ft_over_fmax)" "v < 1e-9 && v > -1e-9"
fi
# 001 Fig. 10: the divergence of the Taylor-Green field vanishes on the lattice.
f=$d/001-figs9-10/fig10_up.csv
if have "$f"; then
  check_all "001-fig10 div of tgv on UP" "$(csv_col "$f" div mae)" "v < 1e-12"
fi
# 001 Table 5: coupled_bc (published 1.95) converges at about second order on packed particles.
f=$d/001-table5/table5.csv
if have "$f"; then
  check "001-table5 coupled_bc order (PP)" "$(csv_order "$f" coupled_bc nx l1)" "v > 1.65 && v < 2.25"
fi
# 002: S4 is exact for quadratics on perturbed particles; F4 is exact only for linear fields but
# on the regular lattice the symmetric sums make it exact for quadratics too.
f=$d/002-derivatives/lap_quadratic_eps04.csv
if have "$f"; then
  check_all "002 S4 quadratic eps 0.4" "$(csv_col "$f" "S4 eta=2.0" linf)" "v < 1e-8"
fi
f=$d/002-derivatives/grad_quadratic_regular.csv
if have "$f"; then
  check_all "002 F4 quadratic regular" "$(csv_col "$f" "F4 eta=1.5" linf)" "v < 1e-9"
fi
# 003 Table 1: the 2D bound at 25² is 2.537 (docs/reference-values.md) and the MAE lies under
# the bound.
f=$d/003-table1/table1_2d.csv
if have "$f"; then
  v=$(csv_col "$f" C4_2D bound nx 25)
  check "003-table1 bound at 25² vs 2.537" "$v" "v > 2.532 && v < 2.542"
  paste -d' ' <(csv_col "$f" C4_2D mae) <(csv_col "$f" C4_2D bound) >"$out/mae_bound"
  v=$(awk '!($1 < $2) { n++ } END { print (NR ? n + 0 : "") }' "$out/mae_bound")
  check "003-table1 2D rows with the MAE above the bound" "$v" "v == 0"
fi
# 003 Fig. 2: σ(M0) of the interior particles falls about as 𝒩^-1 (Zhu, low-discrepancy sets).
f=$d/003-m0/fig2_2d.csv
if have "$f"; then
  awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) { if ($i == "nbr_mean") a = i; if ($i == "m0_std_interior") b = i }
    print "series,nbr,std"; next } { print "m0," $a "," $b }' "$f" >"$out/m0.csv"
  v=$(csv_order "$out/m0.csv" m0 nbr std)
  check "003-m0 2D order of σ(M0) in 𝒩" "$v" "v > 0.75 && v < 1.35"
fi
# 003 App. C: the direct sums equal the closed form to round-off.
f=$d/003-appc/appc.csv
if have "$f"; then
  v=$(awk -F, 'NR > 1 { a = $3 - $2; b = $4 - $2; a = a < 0 ? -a : a; b = b < 0 ? -b : b;
    m = a > m ? a : m; m = b > m ? b : m } END { print (NR > 1 ? m + 0 : "") }' "$f")
  check "003-appc max |ours - closed form|" "$v" "v < 1e-12"
fi
# 004-cauchy: exact W1 between successive perturbed 1D lattices falls like Δs (rate 1), and the
# sliced W2 rows carry a positive Monte Carlo error.
f=$d/004-cauchy/w1_1d.csv
if have "$f"; then
  check "004-cauchy 1D particle W1 rate" "$(csv_order "$f" particles nx1 distance)" "v > 0.9 && v < 1.1"
  check_all "004-cauchy 1D W1 falls between successive resolutions" \
    "$(awk -F, '$1 == "particles" && NR > 2 { print (p > $11) } $1 == "particles" { p = $11 }' "$f")" "v == 1"
fi
f=$d/004-cauchy/sw2_2d.csv
have "$f" && check_all "004-cauchy sliced W2 errors" "$(awk -F, 'NR > 1 { print $12 }' "$f")" "v > 0"

echo "cli_studies: $pass passed, $fail failed"
[ $fail = 0 ]
