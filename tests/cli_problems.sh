#!/usr/bin/env bash
# consph run on gresho-chan and shear-layer: gresho-chan writes profile.csv (u_φ(r) against eq. 37)
# and its momentum histories in log.csv; shear-layer reports its errors as n/a / null and exits 0,
# and draws vorticity.png with gnuplot when it is installed; bad viscosity options exit 2.
# Usage: bash cli_problems.sh PATH-TO-CONSPH
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# --- Gresho-Chan: the profile, one row per particle, starts on the exact one ---
"$consph" run gresho-chan --scheme delta-sph --nx 16 --steps 3 --out "$tmp/g" >"$tmp/out" 2>&1 ||
    bad "gresho-chan: exit $?: $(cat "$tmp/out")"
[ -f "$tmp/g/profile.csv" ] || bad "gresho-chan: no profile.csv"
grep -q '^r,u_phi,u_phi_exact$' "$tmp/g/profile.csv" || bad "profile.csv: no header"
rows=$(grep -c '^[0-9]' "$tmp/g/profile.csv")
[ "$rows" -eq 256 ] || bad "profile.csv: $rows rows, expected 256"
# after 3 steps the profile is close to eq. 37 and u_φ peaks near 1 at r = 0.2
awk -F, '/^[0-9]/ { d = $2 - $3; if (d < 0) d = -d; if (d > m) m = d; if ($3 > e) e = $3 }
         END { exit !(m < 0.05 && e > 0.9 && e <= 1.0) }' "$tmp/g/profile.csv" ||
    bad "profile.csv: u_phi far from the exact profile"
head -1 "$tmp/g/log.csv" | grep -q 'momentum_x,momentum_y,momentum_z,angular_momentum' ||
    bad "log.csv: no momentum histories"
grep -q 'gresho-chan delta-sph' "$tmp/out" || bad "gresho-chan: table: $(cat "$tmp/out")"

# --- the shear layer: no exact solution, errors n/a, not a failure ---
"$consph" run shear-layer --scheme e-c --nx 16 --steps 3 --out "$tmp/s" --format json \
    >"$tmp/s.json" 2>"$tmp/err" || bad "shear-layer: exit $?: $(cat "$tmp/err")"
grep -q '"l1_u": null' "$tmp/s.json" || bad "shear-layer: l1_u not null: $(cat "$tmp/s.json")"
grep -q '"kinetic_energy": [0-9]' "$tmp/s.json" || bad "shear-layer: no kinetic energy"
"$consph" run shear-layer --scheme e-c --nx 16 --steps 2 >"$tmp/s.txt" 2>&1 || bad "table exit"
grep -q 'L1(u) n/a' "$tmp/s.txt" || bad "shear-layer table: $(cat "$tmp/s.txt")"
[ -f "$tmp/s/vorticity.gp" ] && [ -f "$tmp/s/vorticity.dat" ] || bad "no vorticity script"
if command -v gnuplot >/dev/null 2>&1; then
    [ -s "$tmp/s/vorticity.png" ] || bad "gnuplot installed but no vorticity.png"
    ls "$tmp/s" | grep -q tmp && bad "a temporary file left: $(ls "$tmp/s")"
fi
# an output directory with shell and gnuplot metacharacters in its name
weird="$tmp/it's \$(touch pwned) \`x\`"
"$consph" run shear-layer --scheme e-c --nx 8 --steps 1 --out "$weird" >/dev/null 2>&1 ||
    bad "odd directory name: exit $?"
[ -e pwned ] || [ -e "$tmp/pwned" ] && bad "a directory name was executed"
if command -v gnuplot >/dev/null 2>&1; then
    [ -s "$weird/vorticity.png" ] || bad "odd directory name: no vorticity.png"
fi

# --- viscosity options ---
expect_usage() {
    local what=$1
    shift
    "$consph" run "$@" --out "$tmp/bad" >"$tmp/o" 2>"$tmp/e"
    local rc=$?
    [ $rc -eq 2 ] || bad "$what: exit $rc, expected 2"
    grep -q -- "$1" "$tmp/e" 2>/dev/null || true
    [ ! -e "$tmp/bad" ] || [ -z "$(ls -A "$tmp/bad")" ] || bad "$what: wrote files"
}
expect_usage "--re with --nu" gresho-chan --re 10 --nu 0.1
grep -q -- '--nu' "$tmp/e" || bad "--re/--nu: option not named: $(cat "$tmp/e")"
expect_usage "negative nu" gresho-chan --nu -1
grep -q -- '--nu' "$tmp/e" || bad "negative nu: option not named: $(cat "$tmp/e")"
expect_usage "alpha" taylor-green --alpha 11
grep -q -- '--alpha' "$tmp/e" || bad "alpha: option not named: $(cat "$tmp/e")"
expect_usage "unknown problem" vortex
grep -q 'shear-layer' "$tmp/e" || bad "unknown problem: names not listed: $(cat "$tmp/e")"
exit $fail
