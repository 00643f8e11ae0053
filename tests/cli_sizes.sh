#!/usr/bin/env bash
# Sizes the machine cannot hold are rejected before anything is allocated, by `approx` as by
# `layout` (one shared check): exit 2 and one line naming --nx, instead of exit 1 at allocation.
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
err=$(mktemp)
trap 'rm -f "$err"' EXIT
for args in "approx --op grad --nx 10,100000" "approx --op function --dim 3 --nx 500" \
  "layout --kind lattice --dim 3 --nx 500"; do
  timeout 60 "$consph" $args >/dev/null 2>"$err"
  rc=$?
  [ $rc = 2 ] || bad "$args: exit $rc, expected 2"
  [ "$(wc -l <"$err")" = 1 ] && grep -q 'option --nx: .* particles is too many' "$err" ||
    bad "$args: message: $(cat "$err")"
done
exit $fail
