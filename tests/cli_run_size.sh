#!/usr/bin/env bash
# consph run's size cap (issue 23 item 7): --nx past CONSPH_RUN_NX_MAX, or an estimate past the
# machine's memory, is refused before any set-up (exit 2 naming --nx, the estimate and the
# limit), in a study too (file:line naming the key). test_solver checks the memory rule itself.
# Usage: bash cli_run_size.sh PATH-TO-CONSPH
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# refused PATTERN ARGS...: exit 2 within seconds (the pre-change consph spent them allocating),
# the message matching PATTERN, nothing written
refused() {
    local pattern=$1
    shift
    mkdir -p "$tmp/o"
    timeout 20 "$consph" "$@" >"$tmp/out" 2>"$tmp/err"
    local rc=$?
    [ $rc -eq 2 ] || bad "$*: exit $rc, expected 2"
    grep -q -- "$pattern" "$tmp/err" || bad "$*: message '$(cat "$tmp/err")' lacks '$pattern'"
    [ -z "$(ls -A "$tmp/o")" ] || bad "$*: wrote $(ls "$tmp/o")"
    rm -rf "$tmp/o"
}
refused "--nx must be an integer in \[4, 10000\].*not 100000 (1e+10 particles, about .* GiB)" \
    run taylor-green --nx 100000 --steps 1 --out "$tmp/o"
refused "--nx must be an integer in \[4, 10000\].*not 20000" run taylor-green --scheme e-c --nx 20000 --steps 1
refused "--nx .*10001" run gresho-chan --nx 10001 --steps 1 --out "$tmp/o"

# run heat: its estimate (512 bytes per particle) against this machine's memory, where the
# 20000² particles cannot fit (191 GiB)
mem_kib=$(awk '/^MemTotal:/ { print $2 }' /proc/meminfo 2>/dev/null)
if [ -n "$mem_kib" ] && [ "$mem_kib" -lt 190000000 ]; then
    refused "option --nx 20000: 4e+08 particles need about 191 GiB" run heat --nx 20000 --out "$tmp/o"
fi

cat >"$tmp/big.study" <<'STUDY'
study = big
title = a quick resolution that cannot be held
[figure conv]
kind = run
problem = taylor-green
layout = lattice
nx = 12,16
quick.nx = 16,100000
steps = 1
[series E-C]
scheme = e-c
STUDY
refused "big.study:8: .*quick.nx.*--nx must be an integer in \[4, 10000\]" \
    study "$tmp/big.study" --quick --out "$tmp/o"

[ $fail -eq 0 ] && echo "cli_run_size: ok"
exit $fail
