#!/usr/bin/env bash
# `consph kernels` and `consph kernel`: listing, tables, and rejection of bad input.
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
out=$("$consph" kernels) || bad "kernels exit $?"
for k in cubic quintic gaussian super-gaussian lucy wendland-c2 wendland-c4 wendland-c6 \
         wendland-c2:h wendland-c4:h wendland-c6:h m4; do
  echo "$out" | grep -q "^$k " || bad "kernels does not list $k"
done
"$consph" kernels --format csv | head -1 | grep -q "^name,support" || bad "kernels csv header"
# The table: first row at q = 0, last at the support edge where W = 0.
t=$("$consph" kernel cubic --dim 1 --points 3 --format csv) || bad "kernel csv exit $?"
[ "$(echo "$t" | grep -vc '^#')" = 4 ] || bad "kernel --points 3 gives $(echo "$t" | grep -vc '^#') lines"
echo "$t" | tail -1 | grep -q '^2\(\.0*\)\?\(e+00\)\?,0' || bad "cubic table does not end at q = 2 with W = 0: $(echo "$t" | tail -1)"
# W(0) of the 1D cubic spline is sigma_1 = 2/3.
echo "$t" | grep -v '^#' | sed -n 2p | cut -d, -f2 | awk '{exit !($1 > 0.6666666666666 && $1 < 0.6666666666667)}' || bad "cubic 1D W(0) != 2/3"
check2() { # description, then the command
  local what=$1; shift
  "$@" >/dev/null 2>/tmp/cli_kernels.$$.err; local rc=$?
  [ $rc = 2 ] || bad "$what: exit $rc, want 2"
  [ "$(wc -l </tmp/cli_kernels.$$.err)" = 1 ] || bad "$what: message is not one line"
}
check2 "unknown kernel" "$consph" kernel nosuch --dim 2
grep -q "allowed: cubic" /tmp/cli_kernels.$$.err || bad "unknown kernel message lacks allowed names"
check2 "dim 4" "$consph" kernel cubic --dim 4
grep -q -- "--dim" /tmp/cli_kernels.$$.err || bad "dim message does not name --dim"
check2 "malformed points" "$consph" kernel cubic --dim 2 --points 12x
check2 "negative h" "$consph" kernel cubic --dim 2 --h -1
check2 "bad format" "$consph" kernels --format xml
rm -f /tmp/cli_kernels.$$.err
[ $fail = 0 ] && echo "cli_kernels: 1 passed, 0 failed" || echo "cli_kernels: 0 passed, 1 failed"
exit $fail
