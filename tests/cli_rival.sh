#!/usr/bin/env bash
# consph run with the established schemes: every kernel name is a --kernel choice,
# the default kernel is the quintic (a run without --kernel equals one with --kernel quintic and
# differs from --kernel cubic), --alpha is range-checked, and wcsph/tvf/edac run from the CLI
# and restart bit for bit.
# Usage: bash cli_rival.sh PATH-TO-CONSPH
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# L1(u) and L1(p) of a 3-step run, as JSON numbers
errs() {
    "$consph" run taylor-green --nx 16 --steps 3 --format json "$@" 2>"$tmp/err" |
        grep -E '"(l1_u|l1_p)"' | tr -d ' \n'
}

for k in quintic cubic wendland-c2; do
    "$consph" run taylor-green --nx 8 --steps 1 --kernel "$k" >/dev/null 2>"$tmp/err" ||
        bad "--kernel $k refused: $(cat "$tmp/err")"
done
for s in wcsph tvf edac; do
    def=$(errs --scheme "$s")
    [ -n "$def" ] || bad "$s: no result: $(cat "$tmp/err")"
    [ "$def" = "$(errs --scheme "$s" --kernel quintic)" ] || bad "$s: default kernel is not quintic"
    [ "$def" != "$(errs --scheme "$s" --kernel cubic)" ] || bad "$s: --kernel cubic has no effect"
done

# checkpoint and restart bit for bit: the schemes' own fields (summation density, ũ - u of the
# last right-hand side, p̄) travel in the particle set
for s in wcsph tvf edac; do
    r() { "$consph" run taylor-green --nx 16 --scheme "$s" --steps 24 "$@" >/dev/null; }
    r --out "$tmp/full-$s" || bad "$s: full run"
    r --checkpoint-every 12 --out "$tmp/ck-$s" || bad "$s: checkpointed run"
    "$consph" run --restart "$tmp/ck-$s/checkpoint.ckpt" --out "$tmp/re-$s" >/dev/null ||
        bad "$s: restart"
    cmp -s "$tmp/full-$s/snap_000024.vtu" "$tmp/re-$s/snap_000024.vtu" ||
        bad "$s: restarted final snapshot differs"
done

mkdir -p "$tmp/bad"
"$consph" run taylor-green --scheme wcsph --alpha 11 --out "$tmp/bad" >/dev/null 2>"$tmp/err"
rc=$?
[ $rc -eq 2 ] || bad "--alpha 11: exit $rc, expected 2"
grep -q -- "--alpha" "$tmp/err" || bad "--alpha 11: option not named: $(cat "$tmp/err")"
[ -z "$(ls -A "$tmp/bad")" ] || bad "--alpha 11: wrote $(ls "$tmp/bad")"

[ $fail -eq 0 ] && echo "cli_rival: ok"
exit $fail
