#!/usr/bin/env bash
# Resolution policies (`--h-policy`, study key `h_policy`): h follows the law each names, the
# measured neighbour count grows with the exponent the law implies, and bad combinations are
# refused with exit status 2.
# Usage: bash cli_policies.sh PATH-TO-CONSPH
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
run() { "$consph" approx --op function --layout random --eps 0.3 --format csv "$@"; }
# max over rows of |h - h0 (N/N0)^(-1/beta)| / h: the law, anchored at the first row.
h_law() { awk -F, -v b="$2" 'NR == 2 { n0 = $2; h0 = $3 } NR > 1 { e = $3 / (h0 * ($2 / n0)^(-1 / b)) - 1; if (e < 0) e = -e; if (e > m) m = e } END { printf "%.3g\n", m }' "$1"; }
# The exponent of nbr_mean against N, from the first and last rows.
nbr_exp() { awk -F, 'NR == 2 { n0 = $2; k0 = $4 } NR > 1 { n1 = $2; k1 = $4 } END { printf "%.4f\n", log(k1 / k0) / log(n1 / n0) }' "$1"; }
within() { awk -v v="$1" -v lo="$2" -v hi="$3" 'BEGIN { exit !(v >= lo && v <= hi) }'; }

# zhu: neighbours ∝ N^(1/2), so in 2D h ∝ N^(-1/4); the first row is h = 1.2 dx.
run --h-policy zhu --nx 16,32,64 >"$tmp/zhu.csv" || bad "zhu exit $?"
awk -F, 'NR == 2 && ($3 < 0.0749999 || $3 > 0.0750001) { exit 1 }' "$tmp/zhu.csv" || bad "zhu: first h is not 1.2/16"
e=$(h_law "$tmp/zhu.csv" 4)
within "$e" 0 1e-9 || bad "zhu: h off the law N^(-1/4) by $e"
k=$(nbr_exp "$tmp/zhu.csv")
within "$k" 0.45 0.55 || bad "zhu: neighbours grow as N^$k, not N^0.5"
# beta (004): N ∝ h^(-beta), neighbours ∝ N^(1 - dim/beta); beta = 6 in 2D gives 2/3.
run --h-policy beta --beta 6 --nx 16,32,64 >"$tmp/beta.csv" || bad "beta exit $?"
e=$(h_law "$tmp/beta.csv" 6)
within "$e" 0 1e-9 || bad "beta 6: h off the law N^(-1/6) by $e"
k=$(nbr_exp "$tmp/beta.csv")
within "$k" 0.60 0.73 || bad "beta 6: neighbours grow as N^$k, not N^(2/3)"
# In 1D, beta 2 gives h ∝ N^(-1/2) and neighbours ∝ N^(1/2).
"$consph" approx --op function --dim 1 --layout random --eps 0.3 --format csv --h-policy beta \
  --beta 2 --hdx 3 --nx 100,400,1600 >"$tmp/b1.csv" || bad "beta 1D exit $?"
k=$(nbr_exp "$tmp/b1.csv")
within "$k" 0.45 0.55 || bad "beta 2 in 1D: neighbours grow as N^$k, not N^0.5"
# hdx keeps the neighbour count; scaling is 003's h = N^(-1/6).
run --nx 16,32,64 >"$tmp/hdx.csv" || bad "hdx exit $?"
k=$(nbr_exp "$tmp/hdx.csv")
within "$k" -0.02 0.02 || bad "hdx: neighbours grow as N^$k"
run --h-policy scaling --nx 16,32 >"$tmp/sc.csv" || bad "scaling exit $?"
awk -F, 'NR > 1 { e = $3 / ($2^(-1/6)) - 1; if (e > 1e-9 || e < -1e-9) exit 1 }' "$tmp/sc.csv" || bad "scaling: h != N^(-1/6)"
# JSON names the policy.
"$consph" approx --op function --h-policy zhu --nx 8,16 --format json | grep -q '"h_policy": "zhu"' || bad "json h_policy"

# Refusals: exit 2, one line naming the option.
expect2() { # expect2 WHAT PATTERN ARGS...
  local what=$1 pat=$2
  shift 2
  "$consph" "$@" >"$tmp/o" 2>"$tmp/e"
  local rc=$?
  [ $rc = 2 ] || bad "$what: exit $rc, want 2"
  grep -q -- "$pat" "$tmp/e" || bad "$what: message '$(cat "$tmp/e")' lacks '$pat'"
  [ -s "$tmp/o" ] && bad "$what: wrote to stdout"
}
expect2 "beta without its policy" "--beta" approx --op function --beta 3 --nx 8
expect2 "beta policy without beta" "--beta" approx --op function --h-policy beta --nx 8
expect2 "beta <= dim" "must exceed the dimension" approx --op function --h-policy beta --beta 2 --nx 8
expect2 "unknown policy" "--h-policy" approx --op function --h-policy fixed --nx 8

# A study file: the policy is a key, beta is checked, and the report says how h was chosen.
mkdir -p "$tmp/studies"
cat >"$tmp/studies/pol.study" <<'S'
study = pol
title = resolution policies
[figure f]
op = function
layout = random
quick.nx = 12,24
nx = 12,24
[series Z]
h_policy = zhu
[series B]
h_policy = beta
beta = 5
S
CONSPH_STUDIES=$tmp/studies "$consph" study pol --quick --out "$tmp/out" >"$tmp/slog" 2>&1 || bad "study exit $?: $(tail -3 "$tmp/slog")"
grep -q "Smoothing length: h = hdx·Δs at N = 144, then ∝ N^(-1/4)" "$tmp/out/pol/f.md" || bad "study report does not state the zhu policy"
sed -i 's/^beta = 5$/beta = 1.5/' "$tmp/studies/pol.study"
CONSPH_STUDIES=$tmp/studies "$consph" study pol --quick --out "$tmp/out2" >"$tmp/o" 2>"$tmp/e"
[ $? = 2 ] || bad "study beta 1.5 in 2D: exit not 2"
grep -q "beta" "$tmp/e" || bad "study beta 1.5: message '$(cat "$tmp/e")'"
# A cauchy figure (004): exact transport is 1D only.
cat >"$tmp/studies/cau.study" <<'S'
study = cau
title = cauchy
kind = cauchy
[figure f]
dim = 2
ot_method = exact
nx = 8,16
[series P]
measure = particles
S
CONSPH_STUDIES=$tmp/studies "$consph" study cau --quick --out "$tmp/out3" >"$tmp/o" 2>"$tmp/e"
[ $? = 2 ] || bad "cauchy exact in 2D: exit not 2"
grep -q "ot_method" "$tmp/e" || bad "cauchy exact in 2D: message '$(cat "$tmp/e")'"
sed -i 's/^ot_method = exact$/ot_method = sinkhorn/' "$tmp/studies/cau.study"
CONSPH_STUDIES=$tmp/studies "$consph" study cau --quick --out "$tmp/out3" >"$tmp/o" 2>&1 || bad "cauchy sinkhorn exit $?: $(tail -2 "$tmp/o")"
awk -F, 'NR == 2 { exit !($3 == "sinkhorn" && $11 > 0 && $12 > 0) }' "$tmp/out3/cau/f.csv" || bad "cauchy sinkhorn row: $(sed -n 2p "$tmp/out3/cau/f.csv")"
# With particle files, zhu is anchored at the first file (h = 1.2 Δs there), in m0 figures too.
"$consph" layout --kind quasi-random --dim 2 --nx 20 --out "$tmp/q20.csv" >/dev/null || bad "layout q20"
"$consph" layout --kind quasi-random --dim 2 --nx 30 --out "$tmp/q30.csv" >/dev/null || bad "layout q30"
cat >"$tmp/studies/m0z.study" <<'S'
study = m0z
title = m0 zhu
kind = m0
h_policy = zhu
[figure m]
dim = 2
nx = 8,16
[series m0]
S
CONSPH_STUDIES=$tmp/studies "$consph" study m0z --particles "$tmp/q20.csv,$tmp/q30.csv" --out "$tmp/out4" >"$tmp/o" 2>&1 || bad "m0 zhu with files exit $?: $(tail -2 "$tmp/o")"
awk -F, 'NR == 2 { exit !($3 > 0.0599999 && $3 < 0.0600001) }' "$tmp/out4/m0z/m.csv" || bad "m0 zhu with files: first h $(awk -F, 'NR == 2 { print $3 }' "$tmp/out4/m0z/m.csv"), want 1.2/20"
[ $fail = 0 ] && echo "cli_policies: 1 passed, 0 failed" || echo "cli_policies: 0 passed, 1 failed"
exit $fail
