#!/usr/bin/env bash
# consph run's parameter options come from the run-parameter table (src/solver/params.def): every
# option whose help line gives the table's allowed values and default parses through the
# table's setter, so a value it does not allow is refused with exit 2 naming the option and the
# allowed values; a special value goes by its name (--nu re), its number stays refused; an
# option outside the table is refused.
# Usage: bash cli_params.sh PATH-TO-CONSPH
set -u
consph=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$(dirname "$0")/lib_cli.sh"

"$consph" run --help >"$work/help" 2>&1 || bad "run --help failed"
opts=$(grep -E '^  --[a-z0-9-]+ .*; default [^;]*\)$' "$work/help" | awk '{print $1}')
n=$(echo "$opts" | wc -w)
# the table's rows with an option (all but problem, rho0, gamma)
[ "$n" = 30 ] || bad "$n table options in the help, want 30: $opts"
for o in $opts; do
    failing 2 "option $o: " "$work/out" -- "$consph" run taylor-green "$o" "@" &&
        grep -qF "allowed: " "$work/err" && pass=$((pass + 1)) ||
        bad "$o @: allowed values not named: $(cat "$work/err")"
done
failing 2 "option --nu: nu = -1 is out of range (allowed: [0, 1000000] or re)" "$work/out" -- \
    "$consph" run gresho-chan --nx 8 --steps 1 --nu -1 && pass=$((pass + 1))
"$consph" run gresho-chan --nx 8 --steps 1 --nu re --format json >"$work/a" &&
    "$consph" run gresho-chan --nx 8 --steps 1 --re 100 --format json >"$work/b" &&
    [ "$(grep -v seconds "$work/a")" = "$(grep -v seconds "$work/b")" ] && pass=$((pass + 1)) ||
    bad "--nu re is not --re 100 (the default Re)"
failing 2 "option --alpha: alpha = -1 is out of range" "$work/out" -- \
    "$consph" run taylor-green --scheme wcsph --nx 8 --steps 1 --alpha -1 && pass=$((pass + 1))
failing 2 "option --cfl: cfl = 0 is out of range (allowed: (0, 2])" "$work/out" -- \
    "$consph" run taylor-green --nx 8 --steps 1 --cfl 0 && pass=$((pass + 1))
"$consph" run taylor-green --nx 8 --steps 1 --cfl 2 >/dev/null 2>&1 && pass=$((pass + 1)) ||
    bad "--cfl 2 (the edge) refused"
failing 2 "unknown option '--rho0'" "$work/out" -- \
    "$consph" run taylor-green --nx 8 --steps 1 --rho0 2 && pass=$((pass + 1))
failing 2 "option --exact: exact wc needs a smooth 2D periodic problem" "$work/out" -- \
    "$consph" run gresho-chan --nx 8 --steps 1 --exact wc && pass=$((pass + 1))
"$consph" run taylor-green --nx 8 --steps 2 --exact wc >"$work/wc" 2>&1 &&
    grep -q "(001 eq. 26, against wc)" "$work/wc" && pass=$((pass + 1)) ||
    bad "--exact wc: the table does not say so: $(cat "$work/wc")"
summary cli_params
