#!/usr/bin/env bash
# The top-level CLI: help, version, unknown commands.
set -u
consph=$1
fail=0
expect() { # expect STATUS DESCRIPTION -- command...
  local want=$1 what=$2; shift 3
  "$@" >/tmp/cli_main.$$.out 2>/tmp/cli_main.$$.err
  local got=$?
  if [ "$got" != "$want" ]; then echo "FAIL: $what: exit $got, want $want"; cat /tmp/cli_main.$$.err; fail=1; fi
}
expect 0 "--help" -- "$consph" --help
grep -q "commands:" /tmp/cli_main.$$.out || { echo "FAIL: --help lists no commands"; fail=1; }
expect 0 "--version" -- "$consph" --version
grep -q "^consph [0-9]" /tmp/cli_main.$$.out || { echo "FAIL: --version"; fail=1; }
expect 2 "no command" -- "$consph"
expect 2 "unknown command" -- "$consph" frobnicate
grep -q "unknown command 'frobnicate'; allowed:" /tmp/cli_main.$$.err || { echo "FAIL: unknown command message"; fail=1; }
for cmd in $("$consph" --help | awk '/^commands:/{f=1;next} f&&!NF{exit} f{print $1}'); do
  expect 0 "$cmd --help" -- "$consph" "$cmd" --help
  grep -q "^usage: consph $cmd" /tmp/cli_main.$$.out || { echo "FAIL: $cmd --help has no usage line"; fail=1; }
  expect 2 "$cmd unknown option" -- "$consph" "$cmd" --no-such-option
  [ "$(wc -l </tmp/cli_main.$$.err)" = 1 ] || { echo "FAIL: $cmd: error is not one line"; fail=1; }
  grep -q -- "--no-such-option" /tmp/cli_main.$$.err || { echo "FAIL: $cmd: error does not name the option"; fail=1; }
done
rm -f /tmp/cli_main.$$.out /tmp/cli_main.$$.err
[ $fail = 0 ] && echo "cli_main: 1 passed, 0 failed" || echo "cli_main: 0 passed, 1 failed"
exit $fail
